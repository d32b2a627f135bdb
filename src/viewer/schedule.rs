//! The stages of a viewer frame ([`ViewerSet`]), in their own module below the stages that use them, so
//! no stage imports its parent (as `sim::schedule` does for the step).

use bevy::prelude::*;

/// The stages of a viewer frame, in order.
#[derive(SystemSet, Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub(crate) enum ViewerSet {
    Control,
    Step,
    Draw,
}
