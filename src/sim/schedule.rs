//! What every stage of the step names: the order of the stages ([`SimSet`]) and the scene being run
//! ([`ActiveScene`]). Its own module, below the stages, so the stages import it and not their parent (as
//! avian keeps its sets in `schedule`).

use crate::scene::Scene;
use bevy::prelude::*;

/// The scene the world runs, as resolved from its file and preset.
#[derive(Resource, Clone, Debug)]
pub struct ActiveScene(pub Scene);

/// The stages of one fixed step, in order (chained in `FixedUpdate` by [`super::SimulationPlugin`]; the
/// table of the module above says what each does).
#[derive(SystemSet, Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum SimSet {
    Decide,
    Act,
    Physics,
    Perceive,
    Reward,
    Measure,
    Learn,
    Episode,
}
