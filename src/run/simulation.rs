//! A simulation as a run mode starts it: the learning plugin with its learners, and the trained actors
//! the scene names (`Frozen(path)` species, and for an evaluation every `Learned` species of its run)
//! loaded from disk ([`crate::store`]).

use crate::learning::{Learners, Mode};
use crate::scene::Scene;
use crate::sim::Simulation;
use bevy::prelude::App;
use std::path::Path;

/// A simulation with the learning plugin, frozen actors loaded (`Frozen(path)` species, and with `eval_run`
/// every `Learned` species from that run).
pub fn simulation(scene: Scene, mode: Mode, eval_run: Option<&Path>) -> crate::error::Result<Simulation> {
    simulation_with(scene, mode, eval_run, |_| {})
}

/// [`simulation`] with more plugins (a species of your own) added by `extra`.
pub(crate) fn simulation_with(
    scene: Scene,
    mode: Mode,
    eval_run: Option<&Path>,
    extra: impl FnOnce(&mut App),
) -> crate::error::Result<Simulation> {
    let mut learners = Learners::new(&scene, mode);
    crate::store::load_actors(&mut learners, &scene, eval_run)?;
    crate::learning::simulation_of(scene, learners, extra)
}
