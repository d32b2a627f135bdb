//! Perceiving a state, once per state: index the agents on cell grids, detect contacts (the Hooke
//! forces f_a of Eq. 1 and the catches that rewards count), and write every agent's observation vector
//! into its species' batch.
//!
//! This runs as its own schedule, [`Perceive`], at the end of every step (on the state the step produced)
//! and after every spawn, so each state is perceived exactly once and the next step's Decide and Physics
//! read the forces and observations of the state they start from.
//!
//! Observation of an agent of species s (Appendix B; `parameters.md`, "Observation"):
//! `[x, y, v_x, v_y, h_x, h_y]`, then for every species t in registry order `topological_limit(s)` slots of
//! `[Δx, Δy, h_jx − h_ix, h_jy − h_iy]`: the agents of t within the perception radius R of s, nearest first,
//! Δ the minimum-image displacement, never itself; empty slots are zeros. For the paper's predators and
//! prey with limit 6 that is 6 + 4·(6 + 6) = 54 numbers. A species may observe fewer of one species
//! (`topological_limit_of`), and a scene may order the parts as the authors' code does
//! (`observation_layout: Authors`; [`crate::scene::layout::Layout`] says where each part sits).

use super::schedule::ActiveScene;
use crate::scene::{ObservationFrame, Scene};
use crate::sim::components::*;
use crate::sim::physics::FULL_ENERGY;
use crate::sim::space::{Arena, CellGrid};
use crate::sim::species::{SpeciesRegistry, ACTION_DIM, NEIGHBOUR_DIM, OWN_STATE_DIM};
use bevy::ecs::schedule::ScheduleLabel;
use bevy::math::DVec2;
use bevy::prelude::*;
use std::ops::Range;

/// The schedule that perceives the current state.
#[derive(ScheduleLabel, Clone, Debug, PartialEq, Eq, Hash)]
pub struct Perceive;

/// The stages of perceiving, in order.
#[derive(SystemSet, Clone, Debug, PartialEq, Eq, Hash)]
pub enum PerceiveSet {
    /// Gather agents into [`Population`], sorted by species then id, and rebuild the grids.
    Index,
    /// Hooke contact forces and contact counts.
    Contacts,
    /// Observation vectors into [`Batches`].
    Observe,
}

/// The perceived state: every agent's data in flat arrays, sorted by (species, id). `Slot::index`
/// points here; species s occupies `ranges[s]`.
#[derive(Resource, Default, Debug)]
pub struct Population {
    pub(crate) entity: Vec<Entity>,
    pub id: Vec<AgentId>,
    pub(crate) species: Vec<usize>,
    pub position: Vec<DVec2>,
    pub(crate) velocity: Vec<DVec2>,
    /// Unit heading vectors h.
    pub heading: Vec<DVec2>,
    pub(crate) radius: Vec<f64>,
    /// The turn command of each agent's last action, normalized to [−1, 1] (its "turn state").
    pub(crate) turn: Vec<f64>,
    /// The authors' energy budget of each agent ([`FULL_ENERGY`] for an agent without one).
    pub(crate) energy: Vec<f64>,
    pub ranges: Vec<Range<usize>>,
    /// One grid per species over its slots.
    pub(crate) grids: Vec<CellGrid>,
    /// Largest body radius per species (bounds the contact search).
    pub(crate) max_radius: Vec<f64>,
    /// The nearest other agent of the same species, when observation found one within the perception
    /// radius (it is then the positionally nearest kin, which DoS/DoA need: metrics reuse it).
    pub nearest_kin: Vec<Option<u32>>,
}

impl Population {
    pub(crate) fn len(&self) -> usize {
        self.entity.len()
    }

    /// Number of agents of species s.
    pub(crate) fn count(&self, s: usize) -> usize {
        self.ranges.get(s).map_or(0, |r| r.len())
    }
}

/// Per-species batches, row r = the r-th agent of the species in (id) order: what a network consumes.
#[derive(Resource, Default, Debug)]
pub struct Batches {
    pub species: Vec<SpeciesBatch>,
}

/// One species' contiguous `[n × d_o]` observations, `[n × 2]` normalized actions and `[n]` rewards.
#[derive(Default, Debug, Clone)]
pub struct SpeciesBatch {
    pub n: usize,
    pub obs_dim: usize,
    pub observations: Vec<f32>,
    /// Actions in [−1, 1]²: thrust maps to [0, max_thrust], turn rate to [−max, max].
    pub actions: Vec<f32>,
    pub rewards: Vec<f32>,
}

impl SpeciesBatch {
    pub fn observation(&self, row: usize) -> &[f32] {
        &self.observations[row * self.obs_dim..(row + 1) * self.obs_dim]
    }

    pub(crate) fn action(&self, row: usize) -> [f32; ACTION_DIM] {
        [self.actions[row * ACTION_DIM], self.actions[row * ACTION_DIM + 1]]
    }

    fn resize(&mut self, n: usize, obs_dim: usize) {
        self.n = n;
        self.obs_dim = obs_dim;
        self.observations.resize(n * obs_dim, 0.0);
        self.actions.resize(n * ACTION_DIM, 0.0);
        self.rewards.resize(n, 0.0);
    }
}

pub(crate) struct PerceptionPlugin;

impl Plugin for PerceptionPlugin {
    fn build(&self, app: &mut App) {
        app.init_resource::<Population>().init_resource::<Batches>();
        app.init_schedule(Perceive);
        app.configure_sets(Perceive, (PerceiveSet::Index, PerceiveSet::Contacts, PerceiveSet::Observe).chain());
        app.add_systems(
            Perceive,
            (
                index_population.in_set(PerceiveSet::Index),
                detect_contacts.in_set(PerceiveSet::Contacts),
                observe.in_set(PerceiveSet::Observe),
            ),
        );
    }
}

/// Runs [`Perceive`] from inside another schedule (the step's `SimSet::Perceive`).
pub(crate) fn run_perceive(world: &mut World) {
    world.run_schedule(Perceive);
}

type IndexQuery<'w, 's> = Query<
    'w,
    's,
    (
        Entity,
        &'static AgentId,
        &'static SpeciesId,
        &'static Position,
        &'static Velocity,
        &'static Heading,
        &'static Body,
        &'static Action,
        Option<&'static Energy>,
        &'static mut Slot,
    ),
>;

fn index_population(
    mut pop: ResMut<Population>,
    mut batches: ResMut<Batches>,
    registry: Res<SpeciesRegistry>,
    arena: Res<Arena>,
    mut agents: IndexQuery,
) {
    let turn_of = |s: usize, a: &Action| {
        let max = registry.defs[s].max_turn_rate;
        if max > 0.0 {
            a.turn_rate / max
        } else {
            0.0
        }
    };
    // Each agent with its place in the query's order, which the second pass below repeats.
    let mut order: Vec<_> = agents
        .iter()
        .enumerate()
        .map(|(q, (e, id, s, x, v, h, body, a, energy, _))| {
            let energy = energy.map_or(FULL_ENERGY, |e| e.0);
            ((s.0, *id), q, e, x.0, v.0, h.unit(), body.radius, turn_of(s.0, a), energy)
        })
        .collect();
    order.sort_unstable_by_key(|a| a.0);
    let p = &mut *pop;
    for v in [&mut p.position, &mut p.velocity, &mut p.heading] {
        v.clear();
    }
    p.entity.clear();
    p.id.clear();
    p.species.clear();
    p.radius.clear();
    p.turn.clear();
    p.energy.clear();
    p.nearest_kin.clear();
    p.nearest_kin.resize(order.len(), None);
    let n_species = registry.len();
    // Refilled in place, here and below: a vector replaced every step would free the parked world's
    // old one, which a thousand worlds stepped in turn keep cold (run::env::pool).
    p.ranges.clear();
    p.ranges.resize(n_species, 0..0);
    p.max_radius.clear();
    p.max_radius.resize(n_species, 0.0);
    let mut slot_of = vec![Slot { index: 0, row: 0 }; order.len()];
    for ((s, id), q, e, x, v, h, radius, turn, energy) in order {
        let slot = p.entity.len();
        if p.ranges[s].is_empty() {
            p.ranges[s] = slot..slot;
        }
        p.ranges[s].end = slot + 1;
        p.entity.push(e);
        p.id.push(id);
        p.species.push(s);
        p.position.push(x);
        p.velocity.push(v);
        p.heading.push(h);
        p.radius.push(radius);
        p.turn.push(turn);
        p.energy.push(energy);
        p.max_radius[s] = p.max_radius[s].max(radius);
        slot_of[q] = Slot { index: slot as u32, row: (slot - p.ranges[s].start) as u32 };
    }
    // The same query, unchanged since, iterates in the same order.
    for (q, (.., mut slot)) in agents.iter_mut().enumerate() {
        *slot = slot_of[q];
    }
    p.grids.resize_with(n_species, CellGrid::default);
    for s in 0..n_species {
        let range = p.ranges[s].clone();
        p.grids[s].rebuild(&arena, &p.position, range);
    }
    batches.species.resize_with(n_species, SpeciesBatch::default);
    for s in 0..n_species {
        batches.species[s].resize(p.count(s), registry.observation_dim(s));
    }
}

/// Hooke contacts between every overlapping pair (f = k·overlap along the line of centres, pushing
/// apart), counted as catches where one species catches the other; walls touched. Each agent sums its
/// own forces, so a pair's forces are equal and opposite by construction.
fn detect_contacts(
    pop: Res<Population>,
    registry: Res<SpeciesRegistry>,
    arena: Res<Arena>,
    scene: Res<ActiveScene>,
    mut agents: Query<(&Slot, &mut ContactForce, &mut Contacts)>,
    mut found: Local<Vec<(DVec2, ContactCounts)>>,
) {
    let k = scene.0.world.contact_stiffness;
    let (pop, registry, arena) = (&*pop, &*registry, &*arena);
    // By slot, each agent alone, then into the components; only large populations are split over the
    // cores (crate::parallel::ALONE_UP_TO). Each agent alone, so the split never changes a number.
    found.clear();
    found.resize(pop.len(), (DVec2::ZERO, ContactCounts::default()));
    let chunk = crate::parallel::chunk_len(pop.len());
    crate::parallel::for_each_chunk(&mut found, chunk, |c, out| {
        for (n, out) in out.iter_mut().enumerate() {
            *out = contacts_of(pop, registry, arena, k, c * chunk + n);
        }
    });
    for (slot, mut force, mut contacts) in &mut agents {
        let (f, counts) = found[slot.index as usize];
        force.0 = f;
        contacts.before = contacts.now;
        contacts.now = counts;
    }
}

/// The Hooke force on the agent in slot `i` (stiffness `k`) and its contact counts.
fn contacts_of(
    pop: &Population,
    registry: &SpeciesRegistry,
    arena: &Arena,
    k: f64,
    i: usize,
) -> (DVec2, ContactCounts) {
    let (xi, ri, si) = (pop.position[i], pop.radius[i], pop.species[i]);
    let mut f = DVec2::ZERO;
    let mut counts = ContactCounts::default();
    for (t, grid) in pop.grids.iter().enumerate() {
        grid.for_each_near(xi, ri + pop.max_radius[t], |j, xj| {
            let j = j as usize;
            if j == i {
                return;
            }
            let d = arena.delta(xi, xj);
            let reach = ri + pop.radius[j];
            if d.length_squared() >= reach * reach {
                return;
            }
            let dist = d.length();
            let overlap = reach - dist;
            // Coincident centres have no line of centres: separate them along x, by slot order.
            let away = if dist > 0.0 { -d / dist } else { DVec2::X * if i < j { -1.0 } else { 1.0 } };
            f += k * overlap * away;
            if registry.catches[si][t] {
                counts.catching += 1;
                counts.contact_reward += registry.contact_reward[si][t].0;
            }
            if registry.catches[t][si] {
                counts.caught += 1;
                counts.contact_reward += registry.contact_reward[t][si].1;
            }
        });
    }
    counts.walls = arena.wall_contact(xi, DVec2::ZERO, ri, 0.0, 0.0).1;
    (f, counts)
}

/// Agents observed per parallel task: populations up to this size are observed on the calling thread;
/// larger ones in chunks of this many rows on all worker threads (each row is computed alone, so the
/// result does not depend on the chunking or the thread count).
const OBSERVE_CHUNK: usize = 512;

fn observe(
    mut pop: ResMut<Population>,
    registry: Res<SpeciesRegistry>,
    arena: Res<Arena>,
    scene: Res<ActiveScene>,
    mut batches: ResMut<Batches>,
) {
    let frame = scene.0.observation_frame;
    // Taken out while the rows that fill it borrow the rest of the population.
    let mut nearest_kin = std::mem::take(&mut pop.nearest_kin);
    let mut kin_rest: &mut [Option<u32>] = &mut nearest_kin;
    let mut tasks = Vec::new();
    for (s, batch) in batches.species.iter_mut().enumerate() {
        let dim = batch.obs_dim;
        let (kin, rest) = std::mem::take(&mut kin_rest).split_at_mut(pop.ranges[s].len());
        kin_rest = rest;
        let rows = batch.observations.chunks_mut(OBSERVE_CHUNK * dim.max(1)).zip(kin.chunks_mut(OBSERVE_CHUNK));
        for (c, (obs, kin)) in rows.enumerate() {
            tasks.push((s, pop.ranges[s].start + c * OBSERVE_CHUNK, obs, kin));
        }
    }
    let (registry, arena, population) = (&*registry, &*arena, &*pop);
    let observe = |(s, first, obs, kin): &mut (usize, usize, &mut [f32], &mut [Option<u32>])| {
        observe_rows(population, registry, arena, frame, *s, *first, obs, kin);
    };
    if population.len() > OBSERVE_CHUNK {
        crate::parallel::for_each_mut(&mut tasks, observe);
    } else {
        tasks.iter_mut().for_each(observe); // a thread would cost more than the whole step
    }
    drop(tasks);
    pop.nearest_kin = nearest_kin;
}

/// Observations of the consecutive agents of species `s` from slot `first` on, one row of `observations`
/// each, and each one's nearest kin.
#[allow(clippy::too_many_arguments)]
fn observe_rows(
    pop: &Population,
    registry: &SpeciesRegistry,
    arena: &Arena,
    frame: ObservationFrame,
    s: usize,
    first: usize,
    observations: &mut [f32],
    nearest_kin: &mut [Option<u32>],
) {
    let layout = &registry.layouts[s];
    let (radii, blind) = (&registry.perception_radii[s], &registry.blind[s]);
    let dim = layout.dim();
    let mut nearest = Vec::with_capacity(layout.slots.iter().copied().max().unwrap_or(0));
    for (row, (obs, kin)) in observations.chunks_exact_mut(dim).zip(nearest_kin.iter_mut()).enumerate() {
        let i = first + row;
        obs.fill(0.0);
        let (x, v, h) = (pop.position[i], pop.velocity[i], pop.heading[i]);
        // World frame: vectors as they are. Body frame: components along the heading and to its left.
        let left = DVec2::new(-h.y, h.x);
        let seen = |w: DVec2| match frame {
            ObservationFrame::World => w,
            ObservationFrame::Body => DVec2::new(w.dot(h), w.dot(left)),
        };
        let own = match frame {
            ObservationFrame::World => [x.x, x.y, v.x, v.y, h.x, h.y],
            ObservationFrame::Body => {
                let (v, wall) = (seen(v), seen(nearest_wall(arena, x)));
                [v.x, v.y, pop.turn[i], wall.x, wall.y, 0.0]
            }
        };
        // The energy input of the authors' order: 2·E/E_max − 1.
        layout.place_own(obs, own.map(|c| c as f32), (2.0 / FULL_ENERGY * pop.energy[i] - 1.0) as f32);
        let own_heading = seen(h);
        for (t, grid) in pop.grids.iter().enumerate() {
            let view = registry.view[s][t];
            match view {
                None => grid.k_nearest(arena, x, layout.slots[t], radii[t], i as u32, &mut nearest),
                // A blind sector behind (`field_of_view`): the nearest agents in view.
                Some(cos_half) => {
                    let in_view = |j: u32| {
                        let d = arena.delta(x, pop.position[j as usize]);
                        d.dot(h) >= cos_half * d.length()
                    };
                    grid.k_nearest_where(arena, x, layout.slots[t], radii[t], i as u32, in_view, &mut nearest)
                }
            }
            if t == s {
                // The nearest kin is measured (C_nn) all around, whatever the species is allowed to see:
                // the first of the nearest found, or, behind a blind sector, the nearest found anew.
                *kin = match view {
                    None => nearest.first().map(|&(_, j)| j),
                    Some(_) => {
                        let mut all = Vec::with_capacity(1);
                        // None when the species keeps no slot of its own kind, as all around.
                        grid.k_nearest(arena, x, layout.slots[t].min(1), radii[t], i as u32, &mut all);
                        all.first().map(|&(_, j)| j)
                    }
                };
            }
            if blind[t] {
                // `blind_to`: the block stays zero.
                continue;
            }
            let block = layout.block(t).start;
            for (n, &(_, j)) in nearest.iter().enumerate() {
                let j = j as usize;
                let d = seen(arena.delta(x, pop.position[j]));
                let dh = seen(pop.heading[j]) - own_heading;
                let at = block + n * NEIGHBOUR_DIM;
                obs[at..at + NEIGHBOUR_DIM].copy_from_slice(&[d.x, d.y, dh.x, dh.y].map(|c| c as f32));
            }
        }
    }
}

/// The largest magnitude each number of an observation of species `s` can take ([`observe_rows`]), so an
/// environment can declare its bounds: every observation lies in [−high, high]. Positions lie in the arena
/// (with walls, at most as far into a wall as a centre may sink before the state is refused as escaped,
/// `physics::apply_boundary`); velocities within the speed clip (the last change of a step's velocity);
/// headings are unit vectors and the turn command and the energy input lie in [−1, 1]; displacements within the minimum
/// image on the torus (both centres' reach with walls); heading differences within 2. In the body frame a
/// vector's rotated components are bounded by its length. With walls every neighbour block takes the bound
/// of the farthest-reaching species (one bound for every observed species); a margin of 1e-6 covers
/// rounding.
/// How far from the arena's centre an agent of species `t` can be along an axis, in metres: half the edge
/// on the torus; with walls, a little beyond it (its radius and two steps at top speed of overshoot).
fn reach(scene: &Scene, registry: &SpeciesRegistry, t: usize) -> f64 {
    let (w, d) = (&scene.world, &registry.defs[t]);
    match w.boundary {
        crate::scene::Boundary::Walls => w.arena_edge / 2.0 + d.radius + d.max_speed * w.dt * 2.0,
        _ => w.arena_edge / 2.0,
    }
}

/// The largest magnitude of each of an agent of species `t`'s numbers in the world frame: position x, y,
/// velocity x, y, unit heading x, y (a speed clipped per component or as a norm stays within the top
/// speed along each axis). The world-frame observation's own state, and the global state's per agent.
pub(crate) fn state_high(scene: &Scene, registry: &SpeciesRegistry, t: usize) -> [f64; 6] {
    let (reach, speed) = (reach(scene, registry, t), registry.defs[t].max_speed);
    [reach, reach, speed, speed, 1.0, 1.0]
}

pub(crate) fn observation_high(scene: &Scene, registry: &SpeciesRegistry, s: usize) -> Vec<f32> {
    let w = &scene.world;
    let half = w.arena_edge / 2.0;
    let walls = w.boundary == crate::scene::Boundary::Walls;
    let reach = |t: usize| reach(scene, registry, t);
    let far = (0..registry.len()).map(reach).fold(0.0, f64::max);
    let offset = if walls { reach(s) + far } else { half };
    let speed = registry.defs[s].max_speed;
    let own: [f64; OWN_STATE_DIM] = match scene.observation_frame {
        ObservationFrame::World => state_high(scene, registry, s),
        ObservationFrame::Body => {
            // Per-component clipping allows a speed of √2 times the limit along the diagonal.
            let v = match w.speed_clip {
                crate::scene::SpeedClip::Norm => speed,
                crate::scene::SpeedClip::PerComponent => speed * std::f64::consts::SQRT_2,
            };
            let wall = if walls { reach(s) } else { 0.0 };
            [v, v, 1.0, wall, wall, 0.0]
        }
    };
    let slot: [f64; NEIGHBOUR_DIM] = match scene.observation_frame {
        ObservationFrame::World => [offset, offset, 2.0, 2.0],
        ObservationFrame::Body => [offset * std::f64::consts::SQRT_2; 2]
            .into_iter()
            .chain([2.0, 2.0])
            .collect::<Vec<_>>()
            .try_into()
            .expect("four"),
    };
    let layout = &registry.layouts[s];
    let mut high = vec![0.0; layout.dim()];
    for chunk in high[layout.neighbours()].chunks_exact_mut(NEIGHBOUR_DIM) {
        chunk.copy_from_slice(&slot);
    }
    layout.place_own(&mut high, own, 1.0);
    high.into_iter().map(|x| (x * (1.0 + 1e-6)) as f32).collect()
}

/// The displacement from `x` to the nearest point of the walls; zero on the torus, which has none.
pub(crate) fn nearest_wall(arena: &Arena, x: DVec2) -> DVec2 {
    if arena.boundary == crate::scene::Boundary::Periodic {
        return DVec2::ZERO;
    }
    let h = arena.half();
    [DVec2::new(-h - x.x, 0.0), DVec2::new(h - x.x, 0.0), DVec2::new(0.0, -h - x.y), DVec2::new(0.0, h - x.y)]
        .into_iter()
        .min_by(|a, b| a.length_squared().total_cmp(&b.length_squared()))
        .expect("four walls")
}

/// Slot `n` of the `species` block in an observation of an `observer`; None when masked (empty).
pub(crate) fn neighbour_slot(
    obs: &[f32],
    registry: &SpeciesRegistry,
    observer: usize,
    species: usize,
    n: usize,
) -> Option<[f32; 4]> {
    if n >= registry.slots(observer, species) {
        return None;
    }
    let at = registry.block_offset(observer, species) + n * NEIGHBOUR_DIM;
    let slot: [f32; 4] = obs[at..at + NEIGHBOUR_DIM].try_into().ok()?;
    (slot != [0.0; 4]).then_some(slot)
}

/// Inserts the resources perception needs for a scene.
pub(crate) fn insert_scene_resources(world: &mut World, scene: &Scene) {
    world.insert_resource(Arena { edge: scene.world.arena_edge, boundary: scene.world.boundary });
    world.insert_resource(SpeciesRegistry::from_scene(scene));
}
