//! What an experiment states and how each statement is judged: the experiment file's schema ([`file`]:
//! its variants, evaluations and claims), what each quantity is per run ([`quantity`], [`curves`]), the
//! per-run table (`summary.csv`, [`summary`]) and committed curves ([`figure_data`]), the tests and their
//! verdicts ([`verdict`], [`family`], [`grid`]), each claim's registration fingerprint ([`registry`]), and
//! the reports written from them ([`report`]). It reads numbers, never runs anything: running, loading
//! and assembling experiments is [`crate::experiment`]'s, above it.

// The single-run analyses the claims read and draw with, from the room below.
pub(crate) use crate::analysis::{crossplay_matrix, crossplay_readouts, distill, plot, stats};
pub(crate) mod curves;
pub(crate) mod family;
pub(crate) mod figure_data;
pub(crate) mod file;
pub(crate) mod grid;
pub mod pin;
pub(crate) mod quantity;
pub(crate) mod registry;
pub(crate) mod report;
pub(crate) mod results;
pub mod summary;
pub(crate) mod trainings;
pub(crate) mod verdict;

pub use file::*;
pub use results::{ClaimResult, RunData};
