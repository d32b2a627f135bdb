//! The clock of a run: which episode, which step of it (Algorithm 1's two loops). Its own file because
//! every stage reads it (physics labels a fault with it, episodes advance it, learning and metrics close
//! an episode on it) while it depends on nothing.

use bevy::prelude::*;

/// Where the run is: episode index (from 0) and steps done in it.
#[derive(Resource, Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Episode {
    pub index: usize,
    pub step: usize,
    pub(crate) length: usize,
    /// Respawn when an episode ends (off while recording one continuous trajectory).
    pub(crate) auto_reset: bool,
}

impl Episode {
    /// True during the step that completes the episode (from Measure on).
    pub(crate) fn is_done(&self) -> bool {
        self.step == self.length
    }
}
