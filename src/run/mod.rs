//! Run modes and their run folders: `folder.rs` owns a run folder (its names, what may be written into
//! it, who may write); `train.rs`, `evaluate.rs`, `record.rs`, `animate.rs`, `bench.rs` are the modes,
//! `schema.rs` their CSV columns, `provenance.rs` what made a run, `env.rs` coevo stepped from outside,
//! `progress.rs` costly calls' notices.

pub mod animate;
pub mod bench;
pub mod env;
pub mod evaluate;
pub mod folder;
pub mod live;
pub mod perturb;
pub mod progress;
pub mod provenance;
pub mod record;
pub mod schema;
pub mod train;

pub use folder::*;
pub use progress::{announce_cost, step_bar};
pub use provenance::{binary, Provenance};
