//! The headless integration tests, one binary: each test binary links the whole crate, Bevy included,
//! so one link instead of fourteen (from a clean coevo, `cargo test --no-run` took 107 s against 115 s
//! here). Two stay apart, each for a reason of its own: `tests/species_plugin.rs` registers species
//! plugins process-wide, which would add them to every simulation of the other tests; `tests/viewer.rs`
//! needs the `viewer` feature and a display.

#[path = "../common/mod.rs"]
mod common;

mod animate;
mod bad_inputs;
mod classic;
mod crossplay;
mod distill;
mod docs;
mod env;
mod errors;
mod experiment;
mod layers;
mod learning;
mod metrics;
mod observation;
mod perturb;
mod physics;
mod record;
mod resume;
mod scenes;
mod slurm;
mod threads;
