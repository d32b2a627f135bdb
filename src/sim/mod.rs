//! The simulation core: the environment of the paper (Eq. 1, perception, rewards, metrics, episodes) as
//! Bevy plugins and the headless [`Simulation`]. It knows nothing of learning, run modes or screens; the
//! learning plugin and the viewer add their systems to its sets.
//!
//! One fixed step, top to bottom (the sets of [`SimSet`], chained in `FixedUpdate`):
//!
//! | set        | what happens                                                      | file              |
//! |------------|-------------------------------------------------------------------|-------------------|
//! | `Decide`   | each species' policy fills its batch of normalized actions        | `policy.rs`, `learning/` |
//! | `Act`      | actions rescaled to thrust a_F (N) and turn rate a_R (rad/s)      | `policy.rs`       |
//! | `Physics`  | Eq. (1): heading, velocity, speed clip, position, periodic wrap   | `physics.rs`      |
//! | `Perceive` | the new state: cell grids, Hooke contacts, observation vectors    | `perception.rs`   |
//! | `Reward`   | survival reward per contact pair, energy cost, wall penalty        | `reward.rs`       |
//! | `Measure`  | DoS, DoA, order parameters (`order.rs`, `collective.rs`), catches   | `metrics.rs`      |
//! | `Learn`    | Algorithm 1: replay buffers and DDPG updates                       | `learning/`       |
//! | `Episode`  | end of episode: summary, respawn                                  | `episode.rs`      |

pub(crate) mod classic;
pub(crate) mod clock;
pub(crate) mod collective;
pub mod components;
pub(crate) mod episode;
pub mod metrics;
pub(crate) mod order;
pub mod perception;
pub mod physics;
pub mod policy;
pub mod reward;
pub(crate) mod rules;
pub(crate) mod schedule;
pub mod space;
pub mod species;

use crate::scene::Scene;
use bevy::ecs::schedule::{ScheduleLabel, SingleThreadedExecutor};
use bevy::prelude::*;
use clock::Episode;
use episode::{EpisodePlugin, SimRng};
use metrics::MetricsPlugin;
use perception::PerceptionPlugin;
use physics::PhysicsPlugin;
use policy::PolicyPlugin;
use reward::RewardPlugin;
pub use schedule::{ActiveScene, SimSet};

/// The simulation: every stage's plugin, the scene's resources and the step's order.
pub(crate) struct SimulationPlugin {
    pub(crate) scene: Scene,
}

impl Plugin for SimulationPlugin {
    fn build(&self, app: &mut App) {
        insert_scene(app.world_mut(), &self.scene);
        // One thread, in declaration order: the same seed gives the same run whether or not Bevy's
        // multi-threaded executor is compiled in (the viewer's window features turn it on).
        for schedule in [FixedUpdate.intern(), perception::Perceive.intern()] {
            app.edit_schedule(schedule, |s| {
                s.set_executor(SingleThreadedExecutor::new());
            });
        }
        app.configure_sets(
            FixedUpdate,
            (
                SimSet::Decide,
                SimSet::Act,
                SimSet::Physics,
                SimSet::Perceive,
                SimSet::Reward,
                SimSet::Measure,
                SimSet::Learn,
                SimSet::Episode,
            )
                .chain(),
        );
        app.add_plugins((PerceptionPlugin, PolicyPlugin, PhysicsPlugin, RewardPlugin, MetricsPlugin, EpisodePlugin));
        app.add_systems(FixedUpdate, perception::run_perceive.in_set(SimSet::Perceive));
        // Species of this program's plugins (species::SpeciesPlugins::register), in every simulation.
        species::catalog::build_plugins(app);
    }
}

/// Puts a scene into a world, replacing the scene before: the scene itself, the episode clock, the
/// environment's random stream, arena, species and cleared metrics. Agents are spawned separately
/// ([`episode::spawn_population`]), and learners by the learning plugin ([`learning::Learners::new`]).
pub(crate) fn insert_scene(world: &mut World, scene: &Scene) {
    world.insert_resource(ActiveScene(scene.clone()));
    world.insert_resource(Episode { index: 0, step: 0, length: scene.episode_steps, auto_reset: true });
    world.insert_resource(SimRng(SimRng::stream(scene.seed, 0)));
    world.insert_resource(metrics::EpisodeLog::default());
    world.insert_resource(metrics::SwarmMetrics::default());
    world.insert_resource(metrics::Confusion::default());
    world.insert_resource(physics::StateFault::default());
    perception::insert_scene_resources(world, scene);
}

/// A headless simulation: the app, its schedule driven directly one fixed step at a time, as fast as it
/// goes (not paced by wall-clock time).
pub struct Simulation {
    pub(crate) app: App,
}

impl Simulation {
    /// The simulation of a scene with the core plugins only. Panics on a scene with a `Plugin(name)`
    /// policy (nothing here decides it); programs use [`Simulation::try_with_plugins`].
    pub fn new(scene: Scene) -> Self {
        Self::with_plugins(scene, |_| {})
    }

    /// [`Simulation::try_with_plugins`] for scenes known to be complete (tests, benchmarks): panics where
    /// that returns an error.
    pub fn with_plugins(scene: Scene, extra: impl FnOnce(&mut App)) -> Self {
        Self::try_with_plugins(scene, extra).unwrap_or_else(|e| panic!("{e}"))
    }

    /// The simulation of a scene, with more plugins (learning, a species of your own) added by `extra`.
    /// Err when a species' `Plugin(name)` policy is decided by none of them.
    pub fn try_with_plugins(scene: Scene, extra: impl FnOnce(&mut App)) -> crate::error::Result<Self> {
        let mut app = App::new();
        app.add_plugins(SimulationPlugin { scene: scene.clone() });
        extra(&mut app);
        app.world().resource::<policy::PolicyPlugins>().check(&scene)?;
        app.finish();
        app.cleanup();
        episode::spawn_population(app.world_mut());
        Ok(Simulation { app })
    }

    /// One environment step t → t+1.
    pub fn step(&mut self) {
        step_world(self.app.world_mut());
    }

    pub fn world(&self) -> &World {
        self.app.world()
    }

    pub fn world_mut(&mut self) -> &mut World {
        self.app.world_mut()
    }

    pub fn episode(&self) -> Episode {
        *self.world().resource::<Episode>()
    }

    /// One line when the last step left the physically possible ([`physics::StateFault`]): every run mode
    /// checks after every step and stops, so no NaN or escaped body ever reaches a result file.
    pub fn check(&self) -> crate::error::Result<()> {
        check_state(self.world())
    }
}

/// One step of a world that runs the simulation without Bevy's app loop ([`Simulation::step`], the
/// Python env): the `FixedUpdate` schedule, then what `App::update` does after every frame, clearing the
/// world's trackers. Without it the removed-component records of every despawned agent (a respawn every
/// episode) are never dropped: a 20 000-episode run grew by ~2.6 kB an episode. Nothing in the step reads
/// change or removal trackers, so the step computes the same either way.
pub(crate) fn step_world(world: &mut World) {
    world.run_schedule(FixedUpdate);
    world.clear_trackers();
}

/// [`Simulation::check`] for any world running the simulation (the viewer's too).
pub(crate) fn check_state(world: &World) -> crate::error::Result<()> {
    let Some(f) = &world.resource::<physics::StateFault>().0 else {
        return Ok(());
    };
    let name = &world.resource::<species::SpeciesRegistry>().defs[f.species].name;
    use crate::error::ResultExt;
    Err(format!(
        "episode {}, step {}: agent {} ({name}): {}; the integrator is unstable for this scene \
             (check world.dt, world.contact_stiffness, world.wall_stiffness and species[{name}].mass)",
        f.episode, f.step, f.agent, f.what
    ))
    .kind(crate::error::Kind::Simulation)
}
