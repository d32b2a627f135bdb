//! Snapshots: a species' actor every `snapshot_every` episodes, in `RUN/snapshots/`, kept for the whole
//! run (not part of the checkpoint; the checkpoint's manifest hashes those up to it).

use super::checkpoint::run_manifest;
use super::names::{checkpoint_dir, parse_snapshot_name, snapshot_path, SNAPSHOTS};
use super::tensors::{metadata, mlp_from, read_as, sealed, write_actor, Expected};
use crate::error::{Kind, ResultExt};
use crate::learning::nets::Mlp;
use crate::scene::Scene;
use std::path::Path;

/// Keeps `species`' actor as it is after `episode` episodes of training on `scene`. Written whole or not
/// at all; a resumed run writes the same bytes again for the episodes it replays, so snapshots survive
/// kills unchanged.
pub fn save_snapshot(
    run: &Path,
    scene: &Scene,
    species: &str,
    episode: usize,
    actor: &Mlp,
) -> crate::error::Result<()> {
    let path = snapshot_path(run, species, episode);
    crate::io::own_dir(&run.join(SNAPSHOTS))?;
    // The role of the checkpoint's actor: the last snapshot is that actor, byte for byte.
    write_actor(&path, actor, &metadata(species, "actor", Some(scene)))
        .map(drop)
        .map_err(|e| format!("{}: cannot save snapshot: {e}", path.display()).into())
}

/// The episodes of `species`' snapshots in a run, ascending.
pub fn snapshot_episodes(run: &Path, species: &str) -> Vec<usize> {
    let mut found: Vec<usize> = std::fs::read_dir(run.join(SNAPSHOTS))
        .into_iter()
        .flatten()
        .flatten()
        .filter_map(|e| {
            let name = e.file_name().to_string_lossy().into_owned();
            parse_snapshot_name(&name).filter(|(s, _)| *s == species).map(|(_, episode)| episode)
        })
        .collect();
    found.sort_unstable();
    found
}

/// Loads `species`' actor as it was after `episode` episodes into `like` (which fixes the shapes).
pub fn load_snapshot(run: &Path, species: &str, episode: usize, like: &Mlp) -> crate::error::Result<Mlp> {
    (|| -> crate::error::Result<Mlp> {
        let path = snapshot_path(run, species, episode);
        if !path.exists() {
            let kept = snapshot_episodes(run, species);
            return Err(format!(
                "{}: no snapshot of {species} after {episode} episodes; the run keeps {}",
                run.display(),
                match kept.is_empty() {
                    true => format!("none of {species} (trained before snapshots, or snapshot_every: 0)"),
                    false => format!("episodes {}", kept.iter().map(usize::to_string).collect::<Vec<_>>().join(", ")),
                }
            )
            .into());
        }
        let manifest = run_manifest(&checkpoint_dir(run))?;
        let scene = manifest.as_ref().map(|m| m.scene.as_str());
        let bytes = read_as(&path, &Expected { species, roles: &["actor"], scene })?;
        let net = mlp_from(&path, &bytes, like)?;
        sealed(&path, &bytes, manifest.as_ref().map(|m| &m.snapshots))?;
        Ok(net)
    })()
    .kind(Kind::Checkpoint)
}
