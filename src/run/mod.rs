//! Run modes: `train.rs` (its flags in `train_args.rs`, its closing report in `explain.rs`), `evaluate.rs`,
//! `record.rs`, `animate.rs` and `bench.rs` are the modes; `env/` is coevo stepped from outside (one world,
//! many, and many parked on shared apps); `progress.rs` costly calls' notices, `args.rs` the flags several
//! modes share (each mode's own flags sit beside it), `deploy.rs` what `--record` and `--animate` show.
//! What a run leaves on disk (its folder, provenance, CSV columns, checkpoints) is [`crate::store`]'s.

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
pub(crate) mod progress;
pub(crate) mod record;
mod simulation;
pub mod train;
pub(crate) mod train_args;

pub use progress::{announce_cost, step_bar};
pub use simulation::simulation;
pub(crate) use simulation::simulation_with;
