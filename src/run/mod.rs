//! Run modes and their run folders: `folder.rs` owns a run folder (its names, what may be written into
//! it, who may write); `train.rs` (its flags in `train_args.rs`, its closing report in `explain.rs`), `evaluate.rs`, `record.rs`, `animate.rs`, `bench.rs` are the modes,
//! `schema.rs` their CSV columns, `provenance.rs` what made a run, `env.rs` coevo stepped from outside,
//! `progress.rs` costly calls' notices, `args.rs` the flags several modes share (each mode's own flags sit
//! beside it), `deploy.rs` what `--record` and `--animate` show.

pub mod animate;
pub mod args;
pub mod bench;
pub(crate) mod bench_against;
pub(crate) mod deploy;
pub mod env;
pub mod evaluate;
pub(crate) mod explain;
pub mod live;
pub mod movement;
pub(crate) mod perturb;
mod pool;
pub(crate) mod progress;
pub(crate) mod record;
mod simulation;
pub mod train;
pub(crate) mod train_args;

pub use progress::{announce_cost, step_bar};
pub use simulation::simulation;
pub(crate) use simulation::simulation_with;
