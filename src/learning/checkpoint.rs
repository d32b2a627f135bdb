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
//!   `next_obs` (n, d_o). Together the segments cover what the buffer holds (its last `buffer_capacity`
//!   transitions), so a resumed run samples exactly the mini-batches the uninterrupted run would.
//! - `state.ron`: the scene, episodes done, RNG states (environment as it stood before the current
//!   population was spawned, each species), exploration σ/ε, Adam step counts, transitions stored,
//!   metrics so far.
//!
//! Snapshots, in `RUN/snapshots/` (not part of the checkpoint: kept for the whole run):
//!
//! - `<species>-ep<NNNNN>.safetensors`: the species' actor after NNNNN episodes (00000: as initialised),
//!   named as the checkpoint's actor, every `snapshot_every` episodes ([`save_snapshot`]).
//!
//! Everything a run's future depends on is here, so a run killed at any moment and resumed equals the
//! uninterrupted run (every `metrics.csv` column but the wall clock, and the checkpoint bytes).
//!
//! The folder is written whole as `checkpoint.tmp/` and then swapped in, so a run killed at any moment
//! leaves either the previous checkpoint or the new one, never a mix. Replay segments are written once:
//! each checkpoint hard-links the previous checkpoint's segments that the buffer still holds and adds one
//! segment with the transitions since, so a checkpoint costs the new data only, and the folder holds at
//! most one buffer's worth plus one segment (~0.22 GB per species of the standard scene). An experiment
//! removes a run's segments once it is trained ([`drop_replay`]) unless its file says `keep_replay: true`.

use super::ddpg::Ddpg;
use super::nets::Mlp;
use super::replay::ReplayBuffer;
use super::SpeciesLearner;
use crate::io::Existing;
use crate::scene::Scene;
use dfdx::shapes::HasShape;
use rand_chacha::ChaCha8Rng;
use safetensors::tensor::{Dtype, SafeTensors, TensorView};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// Everything but the networks that a run needs to resume.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct TrainingState {
    pub scene: Scene,
    pub episodes_done: usize,
    pub sim_rng: ChaCha8Rng,
    /// The environment stream as it stood before the next episode's population was spawned: a resume
    /// spawns that population again from it (absent in checkpoints of coevo before exact resumes, which
    /// spawn from `sim_rng`).
    #[serde(default)]
    pub spawn_rng: Option<ChaCha8Rng>,
    pub species: Vec<Option<SpeciesState>>,
    /// metrics.csv as it stood at this checkpoint.
    pub metrics_csv: String,
}

#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct SpeciesState {
    pub name: String,
    pub noise_std: f64,
    pub epsilon: f64,
    pub actor_adam_step: u64,
    pub critic_adam_step: u64,
    /// The species' exploration and sampling stream (absent in checkpoints of coevo before per-species
    /// streams: a resumed run then continues on a fresh stream of the seed).
    #[serde(default)]
    pub rng: Option<ChaCha8Rng>,
    /// Transitions the species has stored so far; its replay segments hold the last ones (absent in
    /// checkpoints of coevo before saved buffers: a resumed run then refills its buffer).
    #[serde(default)]
    pub transitions: Option<u64>,
}

/// The checkpoint folder of a run, the one being written, and the previous one during the swap.
pub const CHECKPOINT: &str = "checkpoint";
pub const CHECKPOINT_TMP: &str = "checkpoint.tmp";
pub const CHECKPOINT_OLD: &str = "checkpoint.old";
/// Everything but the networks and buffers ([`TrainingState`]).
pub const STATE: &str = "state.ron";

pub fn checkpoint_dir(run: &Path) -> PathBuf {
    run.join(CHECKPOINT)
}

/// The folder of a run's actor snapshots.
pub const SNAPSHOTS: &str = "snapshots";

fn snapshot_path(run: &Path, species: &str, episode: usize) -> PathBuf {
    run.join(SNAPSHOTS).join(format!("{species}-ep{episode:05}.safetensors"))
}

/// Keeps `species`' actor as it is after `episode` episodes. Written whole or not at all; a resumed run
/// writes the same bytes again for the episodes it replays, so snapshots survive kills unchanged.
pub fn save_snapshot(run: &Path, species: &str, episode: usize, actor: &Mlp) -> std::io::Result<()> {
    let path = snapshot_path(run, species, episode);
    std::fs::create_dir_all(path.parent().expect("a snapshot lives in a folder"))?;
    write_actor(&path, actor)
}

/// An actor as its own safetensors file, named as PyTorch's `nn.Sequential` (module docs).
fn write_actor(path: &Path, actor: &Mlp) -> std::io::Result<()> {
    let tensors = named("", actor.parameters(), actor);
    crate::io::write_atomically(path, Existing::Replace, |w| std::io::Write::write_all(w, &serialize(&tensors)))
}

/// The episodes of `species`' snapshots in a run, ascending.
pub fn snapshot_episodes(run: &Path, species: &str) -> Vec<usize> {
    let prefix = format!("{species}-ep");
    let mut found: Vec<usize> = std::fs::read_dir(run.join(SNAPSHOTS))
        .into_iter()
        .flatten()
        .flatten()
        .filter_map(|e| {
            let name = e.file_name().to_string_lossy().into_owned();
            let digits = name.strip_prefix(&prefix)?.strip_suffix(".safetensors")?;
            digits.bytes().all(|b| b.is_ascii_digit()).then(|| digits.parse().ok()).flatten()
        })
        .collect();
    found.sort_unstable();
    found
}

/// Loads `species`' actor as it was after `episode` episodes into `like` (which fixes the shapes).
pub fn load_snapshot(run: &Path, species: &str, episode: usize, like: &Mlp) -> crate::error::Result<Mlp> {
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
    load_mlp(&path, like)
}

/// Frees a finished run's replay buffers: removes every replay segment of its checkpoint (~0.45 GB a run
/// of the standard scene) and returns the bytes freed. Only resumed training reads them; evaluation,
/// cross-play and the viewer need the networks alone. A run resumed without them refills its buffers
/// and says so ([`load`]), as with a checkpoint of an older coevo.
pub fn drop_replay(run: &Path) -> std::io::Result<u64> {
    let dir = checkpoint_dir(run);
    let entries = match std::fs::read_dir(&dir) {
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(0),
        entries => entries?,
    };
    let mut freed = 0;
    for entry in entries {
        let entry = entry?;
        if parse_segment_name(&entry.file_name().to_string_lossy()).is_some() {
            freed += entry.metadata()?.len();
            std::fs::remove_file(entry.path())?;
        }
    }
    Ok(freed)
}

/// A replay segment: transitions `from..to` of a species, in `path`.
#[derive(Clone, Debug, PartialEq)]
struct Segment {
    from: u64,
    to: u64,
    path: PathBuf,
}

fn segment_name(species: &str, from: u64, to: u64) -> String {
    format!("{species}-replay-{from}-{to}.safetensors")
}

/// The species and transitions `from..to` a replay segment's file name holds ([`segment_name`]'s inverse).
fn parse_segment_name(name: &str) -> Option<(&str, u64, u64)> {
    let (species, range) = name.strip_suffix(".safetensors")?.rsplit_once("-replay-")?;
    let (from, to) = range.split_once('-')?;
    let (from, to) = (from.parse().ok()?, to.parse().ok()?);
    (from < to).then_some((species, from, to))
}

/// The replay segments of `species` in a checkpoint folder, by first transition.
fn segments(dir: &Path, species: &str) -> Vec<Segment> {
    let mut found: Vec<Segment> = std::fs::read_dir(dir)
        .into_iter()
        .flatten()
        .flatten()
        .filter_map(|e| {
            let name = e.file_name().to_string_lossy().into_owned();
            let (of, from, to) = parse_segment_name(&name)?;
            (of == species).then(|| Segment { from, to, path: e.path() })
        })
        .collect();
    found.sort_by_key(|s| (s.from, s.to));
    found
}

/// The segments that tile `from..to` in order, or None where a transition is missing.
fn chain(segments: &[Segment], from: u64, to: u64) -> Option<Vec<Segment>> {
    let (mut covered, mut out) = (from, Vec::new());
    while covered < to {
        let next =
            segments.iter().filter(|s| s.from <= covered && s.to > covered && s.to <= to).max_by_key(|s| s.to)?;
        covered = next.to;
        out.push(next.clone());
    }
    Some(out)
}

/// Writes transitions `from..to` of a buffer as one safetensors file, streamed (a segment can hold a
/// whole buffer, ~0.2 GB, which is never copied in memory).
fn write_segment(path: &Path, buf: &ReplayBuffer, from: u64, to: u64) -> std::io::Result<()> {
    let n = (to - from) as usize;
    let (d, a) = (buf.obs_dim, buf.act_dim);
    let sizes = [("obs", vec![n, d]), ("actions", vec![n, a]), ("rewards", vec![n]), ("next_obs", vec![n, d])];
    let mut offset = 0usize;
    let entries: Vec<String> = sizes
        .iter()
        .map(|(name, shape)| {
            let bytes = 4 * shape.iter().product::<usize>();
            let shape: Vec<String> = shape.iter().map(usize::to_string).collect();
            let entry = format!(
                "\"{name}\":{{\"dtype\":\"F32\",\"shape\":[{}],\"data_offsets\":[{offset},{}]}}",
                shape.join(","),
                offset + bytes
            );
            offset += bytes;
            entry
        })
        .collect();
    let mut header = format!("{{{}}}", entries.join(","));
    // Padded to 8 bytes with spaces, as safetensors' own writer does.
    while header.len() % 8 != 0 {
        header.push(' ');
    }
    crate::io::write_atomically(path, Existing::Replace, |w| {
        use std::io::Write;
        w.write_all(&(header.len() as u64).to_le_bytes())?;
        w.write_all(header.as_bytes())?;
        let put = |w: &mut std::io::BufWriter<std::fs::File>, values: &[f32]| {
            values.iter().try_for_each(|v| w.write_all(&v.to_le_bytes()))
        };
        for part in 0..4 {
            for k in from..to {
                let (o, act, r, o2) = buf.transition(k);
                match part {
                    0 => put(w, o)?,
                    1 => put(w, act)?,
                    2 => put(w, &[r])?,
                    _ => put(w, o2)?,
                }
            }
        }
        Ok(())
    })
}

/// Saves a species' buffer into the checkpoint being written (`tmp`): the segments of the current
/// checkpoint (`dir`) that still hold transitions of the buffer are hard-linked (copied where links
/// are not possible), the transitions since go into one new segment.
fn save_replay(dir: &Path, tmp: &Path, species: &str, buf: &ReplayBuffer) -> std::io::Result<()> {
    let (first, pushed) = (buf.first_held(), buf.pushed);
    let existing = segments(dir, species);
    let mut covered = first;
    for s in &existing {
        if s.from <= covered && s.to > covered && s.to <= pushed {
            let to = tmp.join(s.path.file_name().expect("a segment file"));
            if std::fs::hard_link(&s.path, &to).is_err() {
                std::fs::copy(&s.path, &to)?;
            }
            covered = s.to;
        }
    }
    if covered < pushed {
        write_segment(&tmp.join(segment_name(species, covered, pushed)), buf, covered, pushed)?;
    }
    Ok(())
}

/// The buffer a checkpoint saved: `transitions` stored in all, the held ones read back from the segments.
fn load_replay(dir: &Path, species: &str, like: &ReplayBuffer, transitions: u64) -> crate::error::Result<ReplayBuffer> {
    let mut buf = ReplayBuffer::restoring(like.capacity, like.obs_dim, like.act_dim, transitions);
    let (d, a) = (like.obs_dim, like.act_dim);
    let Some(parts) = chain(&segments(dir, species), buf.first_held(), transitions) else {
        return Err(format!(
            "{}: the replay buffer of {species} is incomplete (transitions {}..{transitions} are not all in its segments); the checkpoint is damaged",
            dir.display(),
            buf.first_held()
        ).into());
    };
    for s in parts {
        let bytes = read_file(&s.path)?;
        let st = parse(&s.path, &bytes)?;
        let n = (s.to - s.from) as usize;
        let tensor = |name: &str, shape: Vec<usize>| -> crate::error::Result<Vec<f32>> {
            let t = st.tensor(name).map_err(|_| format!("{}: no tensor {name:?}", s.path.display()))?;
            if t.dtype() != Dtype::F32 || t.shape() != shape.as_slice() {
                return Err(format!(
                    "{}: tensor {name} is {:?} {:?}, expected F32 {shape:?}",
                    s.path.display(),
                    t.dtype(),
                    t.shape()
                )
                .into());
            }
            Ok(t.data().chunks_exact(4).map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]])).collect())
        };
        let (obs, actions, rewards, next_obs) = (
            tensor("obs", vec![n, d])?,
            tensor("actions", vec![n, a])?,
            tensor("rewards", vec![n])?,
            tensor("next_obs", vec![n, d])?,
        );
        for k in s.from.max(buf.first_held())..s.to {
            let i = (k - s.from) as usize;
            buf.put(
                k,
                &obs[i * d..(i + 1) * d],
                &actions[i * a..(i + 1) * a],
                rewards[i],
                &next_obs[i * d..(i + 1) * d],
            );
        }
    }
    Ok(buf)
}

/// Names of an MLP's tensors as in PyTorch's `nn.Sequential` with activations between the layers.
fn named(prefix: &str, values: Vec<Vec<f32>>, net: &Mlp) -> Vec<(String, Vec<usize>, Vec<f32>)> {
    net.layers
        .iter()
        .enumerate()
        .flat_map(|(i, l)| {
            let (o, n) = *l.weight.shape();
            [(format!("{prefix}{}.weight", 2 * i), vec![o, n]), (format!("{prefix}{}.bias", 2 * i), vec![o])]
        })
        .zip(values)
        .map(|((name, shape), v)| (name, shape, v))
        .collect()
}

fn serialize(tensors: &[(String, Vec<usize>, Vec<f32>)]) -> Vec<u8> {
    let bytes: Vec<Vec<u8>> =
        tensors.iter().map(|(_, _, v)| v.iter().flat_map(|x| x.to_le_bytes()).collect()).collect();
    let views: Vec<(String, TensorView)> = tensors
        .iter()
        .zip(&bytes)
        .map(|((name, shape, _), b)| {
            (name.clone(), TensorView::new(Dtype::F32, shape.clone(), b).expect("shape matches data"))
        })
        .collect();
    safetensors::serialize(views, &None).expect("f32 tensors serialize")
}

/// Reads the tensors `net` needs under `prefix` from a safetensors file, checking names and shapes.
fn read_into(file: &Path, st: &SafeTensors, prefix: &str, like: &Mlp) -> crate::error::Result<Vec<Vec<f32>>> {
    named(prefix, like.parameters(), like)
        .into_iter()
        .map(|(name, shape, _)| {
            let t = st.tensor(&name).map_err(|_| format!("{}: no tensor {name:?}", file.display()))?;
            if t.dtype() != Dtype::F32 || t.shape() != shape.as_slice() {
                return Err(format!(
                    "{}: tensor {name} is {:?} {:?}, this scene needs F32 {shape:?} (observation size or hidden width differ)",
                    file.display(),
                    t.dtype(),
                    t.shape()
                ).into());
            }
            let values: Vec<f32> = t.data().chunks_exact(4).map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]])).collect();
            match values.iter().position(|v| !v.is_finite()) {
                Some(i) => Err(format!("{}: tensor {name} holds a non-finite value ({} at index {i}); refusing a broken network", file.display(), values[i]).into()),
                None => Ok(values),
            }
        })
        .collect()
}

fn read_file(path: &Path) -> crate::error::Result<Vec<u8>> {
    match std::fs::metadata(path) {
        Ok(m) if !m.is_file() => Err(format!("{}: not a regular file, not a checkpoint", path.display()).into()),
        Ok(_) => Ok(std::fs::read(path).map_err(|e| format!("{}: cannot read checkpoint: {e}", path.display()))?),
        Err(e) => Err(format!("{}: cannot read checkpoint: {e}", path.display()).into()),
    }
}

fn parse<'a>(path: &Path, bytes: &'a [u8]) -> crate::error::Result<SafeTensors<'a>> {
    Ok(SafeTensors::deserialize(bytes)
        .map_err(|e| format!("{}: not a valid safetensors file ({e:?})", path.display()))?)
}

/// Loads a species' actor from a run folder into `like` (which fixes the expected shapes).
pub fn load_actor(run: &Path, species: &str, like: &Mlp) -> crate::error::Result<Mlp> {
    load_mlp(&checkpoint_dir(run).join(format!("{species}-actor.safetensors")), like)
}

/// An actor file (as PyTorch names it) loaded into `like`.
fn load_mlp(path: &Path, like: &Mlp) -> crate::error::Result<Mlp> {
    let bytes = read_file(path)?;
    let st = parse(path, &bytes)?;
    let mut net = like.clone();
    net.set_parameters(&read_into(path, &st, "", like)?);
    Ok(net)
}

/// Saves learners and state into `run/checkpoint/`, atomically as a folder.
pub fn save(
    run: &Path,
    learners: &[Option<SpeciesLearner>],
    names: &[String],
    state: &TrainingState,
) -> std::io::Result<()> {
    let dir = checkpoint_dir(run);
    let tmp = run.join(CHECKPOINT_TMP);
    let old = run.join(CHECKPOINT_OLD);
    let _ = std::fs::remove_dir_all(&tmp);
    std::fs::create_dir_all(&tmp)?;
    crate::io::register_temporary(&tmp);
    let written = write_checkpoint(&dir, &tmp, learners, names, state);
    if written.is_err() {
        let _ = std::fs::remove_dir_all(&tmp);
        crate::io::unregister_temporary(&tmp);
        return written;
    }
    // Swap: the old checkpoint stays until the new one is in place; `load` falls back to `.old`.
    let _ = std::fs::remove_dir_all(&old);
    if dir.exists() {
        std::fs::rename(&dir, &old)?;
    }
    std::fs::rename(&tmp, &dir)?;
    crate::io::unregister_temporary(&tmp);
    let _ = std::fs::remove_dir_all(&old);
    Ok(())
}

/// Every file of a checkpoint, into `tmp`.
fn write_checkpoint(
    dir: &Path,
    tmp: &Path,
    learners: &[Option<SpeciesLearner>],
    names: &[String],
    state: &TrainingState,
) -> std::io::Result<()> {
    for (learner, name) in learners.iter().zip(names) {
        let Some(l) = learner else { continue };
        if !l.frozen {
            save_replay(dir, tmp, name, &l.buffer)?;
        }
        let d = &l.ddpg;
        write_actor(&tmp.join(format!("{name}-actor.safetensors")), &d.actor)?;
        let mut training = named("critic.", d.critic.parameters(), &d.critic);
        training.extend(named("target_actor.", d.target_actor.parameters(), &d.target_actor));
        training.extend(named("target_critic.", d.target_critic.parameters(), &d.target_critic));
        training.extend(named("actor_adam.m.", d.actor_opt.m.clone(), &d.actor));
        training.extend(named("actor_adam.v.", d.actor_opt.v.clone(), &d.actor));
        training.extend(named("critic_adam.m.", d.critic_opt.m.clone(), &d.critic));
        training.extend(named("critic_adam.v.", d.critic_opt.v.clone(), &d.critic));
        crate::io::write_atomically(&tmp.join(format!("{name}-training.safetensors")), Existing::Replace, |w| {
            std::io::Write::write_all(w, &serialize(&training))
        })?;
    }
    let ron = ron::ser::to_string_pretty(state, ron::ser::PrettyConfig::new().struct_names(false))
        .map_err(|e| std::io::Error::other(e.to_string()))?;
    crate::io::write_atomically(&tmp.join(STATE), Existing::Replace, |w| std::io::Write::write_all(w, ron.as_bytes()))
}

/// Reads a checkpoint's state file.
pub fn read_state(path: &Path) -> crate::error::Result<TrainingState> {
    let text = crate::io::read_text(path, crate::io::MAX_TEXT_BYTES).map_err(|e| format!("{}: {e}", path.display()))?;
    Ok(ron::from_str(&text).map_err(|e| format!("{}: corrupt checkpoint state ({e})", path.display()))?)
}

/// Restores learners from `run/checkpoint/` (or `checkpoint.old` after a kill mid-swap) and returns the state.
pub fn load(
    run: &Path,
    learners: &mut [Option<SpeciesLearner>],
    names: &[String],
) -> crate::error::Result<TrainingState> {
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
    let mut state = read_state(&state_path)?;
    let mut dropped = Vec::new();
    for (learner, name) in learners.iter_mut().zip(names) {
        let Some(l) = learner else { continue };
        let s = state
            .species
            .iter()
            .flatten()
            .find(|s| &s.name == name)
            .ok_or_else(|| format!("{}: no species {name:?} in the checkpoint", state_path.display()))?;
        let actor_path = dir.join(format!("{name}-actor.safetensors"));
        let bytes = read_file(&actor_path)?;
        let st = parse(&actor_path, &bytes)?;
        let actor = read_into(&actor_path, &st, "", &l.ddpg.actor)?;
        let path = dir.join(format!("{name}-training.safetensors"));
        let bytes = read_file(&path)?;
        let st = parse(&path, &bytes)?;
        let d: &mut Ddpg = &mut l.ddpg;
        let critic = read_into(&path, &st, "critic.", &d.critic)?;
        let target_actor = read_into(&path, &st, "target_actor.", &d.actor)?;
        let target_critic = read_into(&path, &st, "target_critic.", &d.critic)?;
        d.actor_opt.m = read_into(&path, &st, "actor_adam.m.", &d.actor)?;
        d.actor_opt.v = read_into(&path, &st, "actor_adam.v.", &d.actor)?;
        d.critic_opt.m = read_into(&path, &st, "critic_adam.m.", &d.critic)?;
        d.critic_opt.v = read_into(&path, &st, "critic_adam.v.", &d.critic)?;
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
                l.buffer = load_replay(&dir, name, &l.buffer, transitions)?;
            }
        }
    }
    for s in state.species.iter_mut().flatten().filter(|s| dropped.contains(&s.name)) {
        s.transitions = None;
    }
    Ok(state)
}
