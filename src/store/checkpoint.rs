//! Checkpoints, in `RUN/checkpoint/`:
//!
//! - `<species>-actor.safetensors`: the actor, f32, named as PyTorch's
//!   `nn.Sequential(Linear, ReLU, Linear, ReLU, Linear, ReLU, Linear, Tanh)`: `0.weight` (64, d_o),
//!   `0.bias` (64), `2.weight` (64, 64), `2.bias`, `4.weight` (64, 64), `4.bias`, `6.weight` (2, 64),
//!   `6.bias` (2). `model.load_state_dict(safetensors.torch.load_file(path))` loads it.
//! - `<species>-training.safetensors`: `critic.*`, `target_actor.*`, `target_critic.*` (same naming) and the
//!   Adam moments `actor_adam.m.*`, `actor_adam.v.*`, `critic_adam.m.*`, `critic_adam.v.*`.
//! - `<species>-replay-<from>-<to>.safetensors`: the replay buffer's transitions `from..to` (indices among
//!   every transition the species ever stored), tensors `obs` (n, d_o), `actions` (n, 2), `rewards` (n),
//!   `next_from` (n, I64: the row whose `obs` is row i's next observation, or −1) and `next_obs` (the rows
//!   marked −1, d_o): a next observation that is the same agent's next observation is not stored twice
//!   (segments of an older coevo hold `next_obs` (n, d_o) for every row, and still load). Together the segments cover what the buffer holds (its last `buffer_capacity`
//!   transitions), so a resumed run samples exactly the mini-batches the uninterrupted run would.
//! - `state.ron`: the scene, episodes done, RNG states (environment as it stood before the current
//!   population was spawned, each species), exploration σ/ε, Adam step counts, transitions stored. Of a
//!   constant size: the metrics live in `metrics.csv` alone (checkpoints of a coevo before manifests
//!   carried a copy of them here).
//! - `manifest.ron`: the size and BLAKE3 hash of every file above, of the run's snapshots and of
//!   `metrics.csv` up to the checkpoint's episode, checked by whatever reads the checkpoint
//!   ([`super::manifest`]).
//!
//! Every safetensors file names in its metadata what it is (`species`, `role`: actor, training or
//! replay; `scene`: the run's scene, [`super::tensors::scene_id`]), so a file put in another's place is refused by name.
//!
//! Snapshots, in `RUN/snapshots/` (not part of the checkpoint: kept for the whole run):
//!
//! - `<species>-ep<NNNNN>.safetensors`: the species' actor after NNNNN episodes (00000: as initialised),
//!   named as the checkpoint's actor, every `snapshot_every` episodes ([`super::snapshots`]).
//!
//! Everything a run's future depends on is here, so a run killed at any moment and resumed equals the
//! uninterrupted run (every `metrics.csv` column but the wall clock, and the checkpoint bytes).
//!
//! The folder is written whole as `checkpoint.tmp/` and then swapped in, so a run killed at any moment
//! leaves either the previous checkpoint or the new one, never a mix. Replay segments are written once:
//! each checkpoint hard-links the previous checkpoint's segments that the buffer still holds and adds one
//! segment with the transitions since, so a checkpoint costs the new data only, and the folder holds at
//! most one buffer's worth plus one segment (~0.12 GB per species of the standard scene). An experiment
//! removes a run's segments once it is trained ([`super::replay_segments::drop_replay`]) unless its file says
//! `keep_replay: true`.
//!
//! The files' names are `names.rs`; the safetensors format (metadata, names as PyTorch's, finite F32
//! tensors) `tensors.rs`; the replay segments `replay_segments.rs`; snapshots `snapshots.rs`.

use super::manifest::{Digest, Manifest, SpeciesEntry, MANIFEST};
use super::names::*;
use super::replay_segments::{load_replay, save_replay, segments};
use super::tensors::*;
use crate::error::{Kind, ResultExt};
use crate::io::Existing;
use crate::learning::ddpg::Ddpg;
use crate::learning::learner::SpeciesLearner;
use crate::learning::nets::Mlp;
use crate::scene::Scene;
use dfdx::shapes::HasShape;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// Everything but the networks that a run needs to resume.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct TrainingState {
    pub(crate) scene: Scene,
    pub(crate) episodes_done: usize,
    pub(crate) sim_rng: ChaCha8Rng,
    /// The environment stream as it stood before the next episode's population was spawned: a resume
    /// spawns that population again from it (absent in checkpoints of coevo before exact resumes, which
    /// spawn from `sim_rng`).
    #[serde(default)]
    pub(crate) spawn_rng: Option<ChaCha8Rng>,
    pub(crate) species: Vec<Option<SpeciesState>>,
    /// metrics.csv as it stood at this checkpoint, in checkpoints of a coevo before manifests (empty, and
    /// not written, since: the manifest hashes `metrics.csv` itself up to the checkpoint).
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub(crate) metrics_csv: String,
    /// Opponents from the past (`learning.opponents`): the league's draws and record; absent in runs
    /// without a pool, so their checkpoints are as before.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(crate) league: Option<crate::learning::league::LeagueState>,
}

#[derive(Clone, Debug, Serialize, Deserialize)]
pub(crate) struct SpeciesState {
    pub(crate) name: String,
    pub(crate) noise_std: f64,
    pub(crate) epsilon: f64,
    pub(crate) actor_adam_step: u64,
    pub(crate) critic_adam_step: u64,
    /// The species' exploration and sampling stream (absent in checkpoints of coevo before per-species
    /// streams: a resumed run then continues on a fresh stream of the seed).
    #[serde(default)]
    pub(crate) rng: Option<ChaCha8Rng>,
    /// Transitions the species has stored so far; its replay segments hold the last ones (absent in
    /// checkpoints of coevo before saved buffers: a resumed run then refills its buffer).
    #[serde(default)]
    pub(crate) transitions: Option<u64>,
    /// Transitions offered to the buffer, kept or not, where they differ from those stored (the authors'
    /// replay window, `learning.replay_window`); absent otherwise.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(crate) offered: Option<u64>,
}

/// The manifest of a checkpoint folder, and a damaged checkpoint where it should have one: its
/// `state.ron` is of a coevo that writes manifests (no metrics copy in it). None for checkpoints of an
/// older coevo, and for folders of actors only.
pub(super) fn run_manifest(dir: &Path) -> crate::error::Result<Option<Manifest>> {
    if let Some(m) = Manifest::read(dir)? {
        return Ok(Some(m));
    }
    let state = dir.join(STATE);
    if state.exists() && read_state(&state)?.metrics_csv.is_empty() {
        return Err(format!(
            "{}: missing, so the checkpoint cannot be checked; it is damaged: restore it or train the run again",
            dir.join(MANIFEST).display()
        )
        .into());
    }
    Ok(None)
}

/// Loads a species' actor from a run folder into `like` (which fixes the expected shapes), checked
/// against the checkpoint's manifest and the file's metadata.
pub(crate) fn load_actor(run: &Path, species: &str, like: &Mlp) -> crate::error::Result<Mlp> {
    (|| -> crate::error::Result<Mlp> {
        let dir = checkpoint_dir(run);
        let path = dir.join(actor_name(species));
        let manifest = run_manifest(&dir)?;
        // The scene the manifest names is the one the actor's metadata names (as `load` checks): an
        // edited manifest is refused, not trusted.
        let scene = manifest.as_ref().map(|m| m.scene.as_str());
        let bytes = read_as(&path, &Expected { species, roles: &["actor"], scene })?;
        let net = mlp_from(&path, &bytes, like)?;
        sealed(&path, &bytes, manifest.as_ref().map(|m| &m.files))?;
        Ok(net)
    })()
    .kind(Kind::Checkpoint)
}

/// Saves learners and state into `run/checkpoint/`, atomically as a folder, its manifest written last
/// ([`Manifest`]): `metrics` is the digest of `metrics.csv` as it stands (its rows up to this checkpoint).
pub(crate) fn save(
    run: &Path,
    learners: &[Option<SpeciesLearner>],
    names: &[String],
    state: &TrainingState,
    metrics: Digest,
) -> std::io::Result<()> {
    let dir = checkpoint_dir(run);
    let tmp = run.join(CHECKPOINT_TMP);
    let old = run.join(CHECKPOINT_OLD);
    // One step a signal lets finish: the handler never removes the folder being written or swapped.
    let _writing = crate::io::Writing::begin();
    let _ = std::fs::remove_dir_all(&tmp);
    std::fs::create_dir(&tmp)?;
    crate::io::register_temporary(&tmp);
    let written = write_checkpoint(run, &tmp, learners, names, state, metrics);
    if written.is_err() {
        let _ = std::fs::remove_dir_all(&tmp);
        crate::io::unregister_temporary(&tmp);
        return written;
    }
    // Swap: the old checkpoint stays until the new one is in place; `load` falls back to `.old`.
    remove_if_present(&old)?;
    if dir.exists() {
        std::fs::rename(&dir, &old)?;
    }
    std::fs::rename(&tmp, &dir)?;
    crate::io::unregister_temporary(&tmp);
    // The new checkpoint is whole: an old one that cannot be removed (a folder made read-only) is an
    // error, not a `checkpoint.old/` left behind by a run that reports success.
    remove_if_present(&old).map_err(|e| std::io::Error::new(e.kind(), format!("{}: {e}", old.display())))
}

/// Removes a folder and what it holds; a folder that is not there is no error.
fn remove_if_present(dir: &Path) -> std::io::Result<()> {
    match std::fs::remove_dir_all(dir) {
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(()),
        other => other,
    }
}

/// Completes a checkpoint swap that a kill cut short ([`save`]): where `checkpoint/` is whole (its state
/// file is there) a leftover `checkpoint.old/` is removed; where it is missing, `checkpoint.old/` is put
/// back. Only with the run's lock held.
pub(crate) fn finish_swap(run: &Path) {
    let (dir, old) = (checkpoint_dir(run), run.join(CHECKPOINT_OLD));
    if !old.exists() {
        return;
    }
    if dir.join(STATE).exists() {
        let _ = std::fs::remove_dir_all(&old);
    } else if !dir.exists() {
        let _ = std::fs::rename(&old, &dir);
    }
}

/// Every file of a checkpoint, into `tmp`, the manifest last.
fn write_checkpoint(
    run: &Path,
    tmp: &Path,
    learners: &[Option<SpeciesLearner>],
    names: &[String],
    state: &TrainingState,
    metrics: Digest,
) -> std::io::Result<()> {
    let dir = checkpoint_dir(run);
    // The current checkpoint's manifest gives the digests of the segments linked from it (None for a
    // checkpoint of an older coevo: they are hashed from disk once).
    let previous = Manifest::read(&dir).ok().flatten();
    let mut manifest =
        Manifest { episodes_done: state.episodes_done, scene: scene_id(&state.scene), metrics, ..Manifest::default() };
    for (learner, name) in learners.iter().zip(names) {
        let Some(l) = learner else { continue };
        if !l.frozen {
            manifest.files.extend(save_replay(&dir, tmp, name, &l.buffer, previous.as_ref())?);
        }
        let d = &l.ddpg;
        let actor = write_actor(&tmp.join(actor_name(name)), &d.actor, &metadata(name, "actor", Some(&state.scene)))?;
        manifest.files.insert(actor_name(name), actor);
        let mut training = named("critic.", d.critic.parameters(), &d.critic);
        training.extend(named("target_actor.", d.target_actor.parameters(), &d.target_actor));
        training.extend(named("target_critic.", d.target_critic.parameters(), &d.target_critic));
        training.extend(named("actor_adam.m.", d.actor_opt.m.clone(), &d.actor));
        training.extend(named("actor_adam.v.", d.actor_opt.v.clone(), &d.actor));
        training.extend(named("critic_adam.m.", d.critic_opt.m.clone(), &d.critic));
        training.extend(named("critic_adam.v.", d.critic_opt.v.clone(), &d.critic));
        let bytes = serialize(&training, &metadata(name, "training", Some(&state.scene)));
        crate::io::write_atomically(&tmp.join(training_name(name)), Existing::Replace, |w| {
            std::io::Write::write_all(w, &bytes)
        })?;
        manifest.files.insert(training_name(name), Digest::of(&bytes));
        manifest.species.push(SpeciesEntry {
            name: name.clone(),
            observation: d.actor.layers[0].weight.shape().1,
            hidden: d.actor.layers[0].weight.shape().0,
            transitions: (!l.frozen).then(|| (l.buffer.first_held(), l.buffer.pushed)),
        });
    }
    let ron = ron::ser::to_string_pretty(state, ron::ser::PrettyConfig::new().struct_names(false))
        .map_err(|e| std::io::Error::other(e.to_string()))?;
    crate::io::write_atomically(&tmp.join(STATE), Existing::Replace, |w| std::io::Write::write_all(w, ron.as_bytes()))?;
    manifest.files.insert(STATE.to_string(), Digest::of(ron.as_bytes()));
    manifest.snapshots = snapshot_digests(run, state.episodes_done, previous.as_ref())?;
    crate::io::write_atomically(&tmp.join(MANIFEST), Existing::Replace, |w| {
        std::io::Write::write_all(w, manifest.to_ron().as_bytes())
    })
}

/// The digests of the run's snapshots up to `episodes_done`: those the current checkpoint's manifest
/// already holds carried over, the newer ones (written since) hashed from disk.
fn snapshot_digests(
    run: &Path,
    episodes_done: usize,
    previous: Option<&Manifest>,
) -> std::io::Result<std::collections::BTreeMap<String, Digest>> {
    let mut digests = std::collections::BTreeMap::new();
    let entries = match std::fs::read_dir(run.join(SNAPSHOTS)) {
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(digests),
        entries => entries?,
    };
    for entry in entries {
        let entry = entry?;
        let name = entry.file_name().to_string_lossy().into_owned();
        if parse_snapshot_name(&name).is_none_or(|(_, e)| e > episodes_done) {
            continue;
        }
        let digest = match previous.and_then(|m| m.snapshots.get(&name)) {
            Some(d) => d.clone(),
            None => Digest::of_file(&entry.path())?,
        };
        digests.insert(name, digest);
    }
    Ok(digests)
}

/// Reads a checkpoint's state file.
pub(crate) fn read_state(path: &Path) -> crate::error::Result<TrainingState> {
    let text = crate::io::read_text(path, crate::io::MAX_TEXT_BYTES)?;
    state_from(path, &text)
}

fn state_from(path: &Path, text: &str) -> crate::error::Result<TrainingState> {
    Ok(ron::from_str(text).map_err(|e| format!("{}: corrupt checkpoint state ({e})", path.display()))?)
}

/// The checkpoint's state file, checked against its manifest, and the manifest (None for a checkpoint of
/// a coevo before manifests): what `--resume` continues from and what `--plot` counts rows against.
pub(crate) fn read_checked_state(dir: &Path) -> crate::error::Result<(TrainingState, Option<Manifest>)> {
    (|| -> crate::error::Result<(TrainingState, Option<Manifest>)> {
        let path = dir.join(STATE);
        let manifest = run_manifest(dir)?;
        let bytes = read_file(&path)?;
        if let Some(m) = &manifest {
            Manifest::check(&m.files, STATE, &path, &bytes)?;
        }
        let text = String::from_utf8(bytes)
            .map_err(|_| format!("{}: corrupt checkpoint state (not UTF-8)", path.display()))?;
        let state = state_from(&path, &text)?;
        if let Some(m) = &manifest {
            if m.episodes_done != state.episodes_done {
                return Err(format!(
                    "{}: holds {} episodes, its manifest {}; the checkpoint is damaged",
                    path.display(),
                    state.episodes_done,
                    m.episodes_done
                )
                .into());
            }
        }
        Ok((state, manifest))
    })()
    .kind(Kind::Checkpoint)
}

/// Restores learners from `run/checkpoint/` (or `checkpoint.old` after a kill mid-swap), every file
/// checked against the checkpoint's manifest, and returns the state with the manifest.
pub fn load(
    run: &Path,
    learners: &mut [Option<SpeciesLearner>],
    names: &[String],
) -> crate::error::Result<(TrainingState, Option<Manifest>)> {
    (|| -> crate::error::Result<(TrainingState, Option<Manifest>)> {
        let mut dir = checkpoint_dir(run);
        let old = run.join(CHECKPOINT_OLD);
        if !dir.join(STATE).exists() && old.join(STATE).exists() {
            // Killed mid-swap: the old checkpoint is whole; put it back, so the next save links from it.
            if !dir.exists() && std::fs::rename(&old, &dir).is_err() {
                dir = old;
            }
        }
        let state_path = dir.join(STATE);
        if !state_path.exists() {
            return Err(format!("{}: no checkpoint to resume", state_path.display()).into());
        }
        let (mut state, manifest) = read_checked_state(&dir)?;
        let manifest = manifest.as_ref();
        let mut dropped = Vec::new();
        for (learner, name) in learners.iter_mut().zip(names) {
            let Some(l) = learner else { continue };
            let s = state
                .species
                .iter()
                .flatten()
                .find(|s| &s.name == name)
                .ok_or_else(|| format!("{}: no species {name:?} in the checkpoint", state_path.display()))?;
            let actor_path = dir.join(actor_name(name));
            // The scene the manifest names (as a snapshot's is checked): an id recomputed from the scene
            // read back would change with the scene's serialized form, refusing every older checkpoint.
            let scene = manifest.map(|m| m.scene.as_str());
            let expected = |roles| Expected { species: name, roles, scene };
            let actor_bytes = read_as(&actor_path, &expected(&["actor"]))?;
            let st = parse(&actor_path, &actor_bytes)?;
            let actor = read_into(&actor_path, &st, "", &l.ddpg.actor)?;
            let path = dir.join(training_name(name));
            let bytes = read_as(&path, &expected(&["training"]))?;
            let st = parse(&path, &bytes)?;
            let d: &mut Ddpg = &mut l.ddpg;
            let critic = read_into(&path, &st, "critic.", &d.critic)?;
            let target_actor = read_into(&path, &st, "target_actor.", &d.actor)?;
            let target_critic = read_into(&path, &st, "target_critic.", &d.critic)?;
            let actor_m = read_into(&path, &st, "actor_adam.m.", &d.actor)?;
            let actor_v = read_into(&path, &st, "actor_adam.v.", &d.actor)?;
            let critic_m = read_into(&path, &st, "critic_adam.m.", &d.critic)?;
            let critic_v = read_into(&path, &st, "critic_adam.v.", &d.critic)?;
            sealed(&actor_path, &actor_bytes, manifest.map(|m| &m.files))?;
            sealed(&path, &bytes, manifest.map(|m| &m.files))?;
            (d.actor_opt.m, d.actor_opt.v, d.critic_opt.m, d.critic_opt.v) = (actor_m, actor_v, critic_m, critic_v);
            d.actor.set_parameters(&actor);
            d.critic.set_parameters(&critic);
            d.target_actor.set_parameters(&target_actor);
            d.target_critic.set_parameters(&target_critic);
            d.actor_opt.step = s.actor_adam_step;
            d.critic_opt.step = s.critic_adam_step;
            l.noise_std = s.noise_std;
            l.epsilon = s.epsilon;
            if let Some(rng) = &s.rng {
                l.rng = rng.clone();
            }
            if let (Some(transitions), false) = (s.transitions, l.frozen) {
                // Segments removed by hand (to free space) leave the buffer to be refilled, as in checkpoints
                // of an older coevo; some of them missing is damage.
                if transitions > 0 && segments(&dir, name).is_empty() {
                    dropped.push(name.clone());
                } else {
                    l.buffer = load_replay(&dir, name, &l.buffer, transitions, manifest)?;
                }
            }
            l.offered = s.offered.unwrap_or(l.buffer.pushed);
        }
        for s in state.species.iter_mut().flatten().filter(|s| dropped.contains(&s.name)) {
            s.transitions = None;
        }
        Ok((state, manifest.cloned()))
    })()
    .kind(Kind::Checkpoint)
}
