//! coevo as an environment for learners outside it (the Rust side of the Python package): the
//! very `FixedUpdate` schedule `--train` steps, with the scene's `Learned` species decided from outside.
//!
//! [`Env`] is one world: `reset` gives every external agent's observation (coevo's observation vector,
//! the scene's frame and layout), `step` takes their normalized actions in [−1, 1]² (thrust, turn, as the
//! actors output them) and returns the next observations, the rewards coevo's learners get, whether the
//! episode was truncated (at `episode_steps`) and the step's DoS, DoA and catches. Species with any other
//! policy (rule-based, `Frozen` runs, plugins) keep acting inside. [`VecEnv`] steps many worlds at once on
//! flat arrays, on all cores, and starts a world's next episode by itself when one ends.
//!
//! Agents are ordered by species (the scene's order) and, within a species, as coevo numbers them; they
//! are named `<species>_<k>`.
//!
//! An [`ObservationControl`] (`blind:prey:prey`, …, as `coevo --eval --control`) alters the observations
//! handed out exactly as it alters what coevo's actors are given, so an outside learner's policies can be
//! put through the flocking/herding controls. Finished episodes are summarised as `metrics.csv` rows
//! ([`VecEnv::take_episode_rows`]), so an outside learner writes the run files `coevo --plot` reads.
//!
//! Coevolution across the border ([`Coevolve`]): learned species named there stay coevo's, trained inside
//! the world by its own Algorithm 1 (exploration, replay, updates, as `--train` trains them) while the
//! outside learner decides the others, frozen or learning on a [`Schedule`]; their run (metrics, snapshots,
//! checkpoint) is saved as a run folder by [`Env::save_run`].

mod many;
mod pool;
mod world;

pub use many::{world_seed, VecEnv, VecStep, WorldSeeds};
pub use world::{Coevolve, Env, Schedule, StepResult, STATE_DIM};
