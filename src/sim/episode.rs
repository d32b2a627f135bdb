//! Episodes: spawn the population (Algorithm 1: "randomly spawn n_0 predators and n_1 prey"), count steps,
//! and at the end of an episode log its summary and respawn.
//!
//! Spawning: positions uniform over the arena (inset by the body radius with walls, so no body starts
//! inside a wall), headings uniform in (−π, π], velocities zero. Overlaps at spawn are allowed; the
//! contact springs separate them. The paper is silent on this. The authors' code differs (difference 7 of
//! docs/src/results/authors-code.md): it insets every position by the largest body radius on either boundary and draws the whole
//! population again until no two bodies overlap: `world.spawn: AuthorsNoOverlap`.

use super::schedule::{ActiveScene, SimSet};
use crate::scene::{Boundary, Spawn};
use crate::sim::clock::Episode;
use crate::sim::components::*;
use crate::sim::metrics::{EpisodeLog, SwarmMetrics};
use crate::sim::perception::Perceive;
use crate::sim::physics::{PhysicsSet, FULL_ENERGY};
use crate::sim::space::Arena;
use crate::sim::species::SpeciesRegistry;
use bevy::math::DVec2;
use bevy::prelude::*;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::f64::consts::PI;

/// The environment's random stream (spawning, random policies), seeded from the scene.
#[derive(Resource, Clone, Debug)]
pub(crate) struct SimRng(pub ChaCha8Rng);

impl SimRng {
    /// Independent streams per purpose, so that e.g. exploration noise never shifts the spawn positions.
    pub(crate) fn stream(seed: u64, stream: u64) -> ChaCha8Rng {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        rng.set_stream(stream);
        rng
    }
}

/// The environment stream as it stood before the current population was spawned: with it, a resumed run
/// spawns exactly the population the uninterrupted run had (`store::checkpoint`).
#[derive(Resource, Clone, Debug)]
pub(crate) struct SpawnedFrom(pub ChaCha8Rng);

pub(crate) struct EpisodePlugin;

impl Plugin for EpisodePlugin {
    fn build(&self, app: &mut App) {
        // The clock advances with the physics: after the move, the step has happened.
        app.add_systems(
            FixedUpdate,
            (advance_clock.in_set(SimSet::Physics).after(PhysicsSet::Boundary), end_episode.in_set(SimSet::Episode)),
        );
    }
}

fn advance_clock(mut episode: ResMut<Episode>) {
    episode.step += 1;
}

/// Logs a finished episode and, with auto-reset, respawns.
fn end_episode(world: &mut World) {
    let episode = *world.resource::<Episode>();
    if !episode.is_done() {
        return;
    }
    let summary = world.resource_mut::<SwarmMetrics>().finish_episode(episode.index);
    world.resource_mut::<EpisodeLog>().episodes.push(summary);
    if episode.auto_reset {
        next_episode(world);
    }
}

/// Starts the next episode: the clock at its step 0 and a fresh population (what auto-reset does at the
/// end of an episode; runs that read the last step's state first call it themselves).
pub(crate) fn next_episode(world: &mut World) {
    let mut e = world.resource_mut::<Episode>();
    e.index += 1;
    e.step = 0;
    spawn_population(world);
}

/// The authors' spawn (`gym/envs/pps/pps.py`, `reset()`): every position uniform in the arena inset by
/// the largest body radius of the population, the whole population drawn again until no two bodies
/// overlap (centres closer than the sum of their radii, across the periodic edges on a torus), at most
/// 100 times, the last draw kept as the authors' code keeps it. Headings are drawn after, per agent.
fn authors_positions(registry: &SpeciesRegistry, arena: &Arena, rng: &mut ChaCha8Rng) -> Vec<DVec2> {
    let radii: Vec<f64> = registry.defs.iter().flat_map(|d| std::iter::repeat_n(d.radius, d.count)).collect();
    let reach = arena.half() - radii.iter().copied().fold(0.0, f64::max);
    let mut positions = Vec::new();
    for _ in 0..100 {
        positions =
            radii.iter().map(|_| DVec2::new(rng.gen_range(-reach..reach), rng.gen_range(-reach..reach))).collect();
        let overlap = (0..positions.len())
            .any(|i| (0..i).any(|j| arena.delta(positions[i], positions[j]).length() < radii[i] + radii[j]));
        if !overlap {
            break;
        }
    }
    positions
}

/// Despawns every agent, spawns the scene's population anew and perceives the new state.
pub(crate) fn spawn_population(world: &mut World) {
    let agents: Vec<Entity> = world.query_filtered::<Entity, With<AgentId>>().iter(world).collect();
    for e in agents {
        world.despawn(e);
    }
    let registry = world.resource::<SpeciesRegistry>().clone();
    let arena = *world.resource::<Arena>();
    let (energy_budget, spawn) = {
        let w = &world.resource::<ActiveScene>().0.world;
        (w.energy_budget, w.spawn)
    };
    let mut bundles = Vec::new();
    let before = world.resource::<SimRng>().0.clone();
    world.insert_resource(SpawnedFrom(before));
    {
        let mut rng = world.resource_mut::<SimRng>();
        let placed = match spawn {
            Spawn::Anywhere => None,
            Spawn::AuthorsNoOverlap => Some(authors_positions(&registry, &arena, &mut rng.0)),
        };
        for (s, def) in registry.defs.iter().enumerate() {
            let margin = if arena.boundary == Boundary::Walls { def.radius } else { 0.0 };
            let reach = arena.half() - margin;
            for _ in 0..def.count {
                let x = match &placed {
                    Some(placed) => placed[bundles.len()],
                    None => DVec2::new(rng.0.gen_range(-reach..reach), rng.0.gen_range(-reach..reach)),
                };
                let theta = crate::sim::physics::wrap_angle(rng.0.gen_range(-PI..PI));
                bundles.push(AgentBundle {
                    id: AgentId(bundles.len() as u32),
                    species: SpeciesId(s),
                    position: Position(x),
                    velocity: Velocity::default(),
                    heading: Heading(theta),
                    body: Body { mass: def.mass, radius: def.radius },
                    action: Action::default(),
                    reward: Reward::default(),
                    contact_force: ContactForce::default(),
                    contacts: Contacts::default(),
                    slot: Slot::default(),
                });
            }
        }
    }
    for b in bundles {
        let mut e = world.spawn(b);
        if energy_budget {
            e.insert(Energy(FULL_ENERGY));
        }
    }
    world.insert_resource(SwarmMetrics::default());
    world.run_schedule(Perceive);
}
