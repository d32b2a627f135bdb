//! What a run leaves on disk, in one room: the run folder (its names, reserved outputs, lock, provenance,
//! the CSV columns of its metrics and evaluations) and the checkpoint format under it (state, actors and
//! training files as safetensors, replay segments, snapshots, the manifest that seals them).
//!
//! It stands above `learning/`, whose networks, optimizer moments and replay buffers it writes and reads,
//! and below the run modes (`run/`), which ask it to save and load: the learning plugin itself knows no
//! file, as the simulation knows no learning.
//!
//! | file | what |
//! |---|---|
//! | `folder.rs` | a run folder: [`RunDir`], its names, what may be written into it, [`RunLock`] |
//! | `provenance.rs` | `provenance.ron`: what made a run ([`Provenance`]) |
//! | `schema.rs` | the columns of `metrics.csv` and the evaluation files, read back as [`schema::Table`] |
//! | `names.rs` | the file names under `checkpoint/` and `snapshots/` |
//! | `checkpoint.rs` | a checkpoint written whole and swapped in, loaded into learners |
//! | `tensors.rs` | the safetensors files: PyTorch's names, metadata, the same bytes in every process |
//! | `replay_segments.rs` | a replay buffer as segments written once |
//! | `snapshots.rs` | an actor every `snapshot_every` episodes |
//! | `manifest.rs` | the sizes and BLAKE3 hashes that seal a checkpoint |
//! | `actors.rs` | trained actors and snapshots into a simulation's learners |

mod actors;
pub mod checkpoint;
pub(crate) mod folder;
pub mod manifest;
pub(crate) mod names;
pub mod provenance;
pub(crate) mod replay_segments;
pub mod schema;
pub mod snapshots;
pub(crate) mod tensors;

pub use actors::load_actors;
pub(crate) use actors::load_snapshots;
pub use folder::*;
pub use provenance::{binary, Provenance};
