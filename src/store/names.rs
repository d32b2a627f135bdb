//! The names of the files learning writes in a run folder: the checkpoint folder and its swap, the state,
//! each species' actor, training and replay-segment files, and the snapshots. `store::RunDir` gives the
//! paths of the run folder to everything above `learning/`; these are the names below it.

use std::path::{Path, PathBuf};

/// The checkpoint folder of a run, the one being written, and the previous one during the swap.
pub(crate) const CHECKPOINT: &str = "checkpoint";

pub(crate) const CHECKPOINT_TMP: &str = "checkpoint.tmp";

pub(crate) const CHECKPOINT_OLD: &str = "checkpoint.old";

/// Everything but the networks and buffers ([`TrainingState`]).
pub(crate) const STATE: &str = "state.ron";

pub(crate) fn checkpoint_dir(run: &Path) -> PathBuf {
    run.join(CHECKPOINT)
}

/// The folder of a run's actor snapshots.
pub(crate) const SNAPSHOTS: &str = "snapshots";

pub(super) fn snapshot_path(run: &Path, species: &str, episode: usize) -> PathBuf {
    run.join(SNAPSHOTS).join(snapshot_name(species, episode))
}

/// The episode of a snapshot's file name (`<species>-ep<NNNNN>.safetensors`), with its species.
pub(super) fn parse_snapshot_name(name: &str) -> Option<(&str, usize)> {
    let (species, digits) = name.strip_suffix(".safetensors")?.rsplit_once("-ep")?;
    digits.bytes().all(|b| b.is_ascii_digit()).then(|| Some((species, digits.parse().ok()?))).flatten()
}

pub(super) fn snapshot_name(species: &str, episode: usize) -> String {
    format!("{species}-ep{episode:05}.safetensors")
}

pub(super) fn segment_name(species: &str, from: u64, to: u64) -> String {
    format!("{species}-replay-{from}-{to}.safetensors")
}

/// The species and transitions `from..to` a replay segment's file name holds ([`segment_name`]'s inverse).
pub(super) fn parse_segment_name(name: &str) -> Option<(&str, u64, u64)> {
    let (species, range) = name.strip_suffix(".safetensors")?.rsplit_once("-replay-")?;
    let (from, to) = range.split_once('-')?;
    let (from, to) = (from.parse().ok()?, to.parse().ok()?);
    (from < to).then_some((species, from, to))
}

/// The file name of a species' actor in a checkpoint (and in a run trained outside coevo).
pub(crate) fn actor_name(species: &str) -> String {
    format!("{species}-actor.safetensors")
}

pub(super) fn training_name(species: &str) -> String {
    format!("{species}-training.safetensors")
}
