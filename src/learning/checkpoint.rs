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
//!   population was spawned, each species), exploration σ/ε, Adam step counts, transitions stored. Of a
//!   constant size: the metrics live in `metrics.csv` alone (checkpoints of a coevo before manifests
//!   carried a copy of them here).
//! - `manifest.ron`: the size and BLAKE3 hash of every file above, of the run's snapshots and of
//!   `metrics.csv` up to the checkpoint's episode, checked by whatever reads the checkpoint
//!   ([`super::manifest`]).
//!
//! Every safetensors file names in its metadata what it is (`species`, `role`: actor, training or
//! replay; `scene`: the run's scene, [`scene_id`]), so a file put in another's place is refused by name.
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
use super::learner::SpeciesLearner;
use super::manifest::{Digest, Hashing, Manifest, SpeciesEntry, MANIFEST};
use super::nets::Mlp;
use super::replay::ReplayBuffer;
use crate::error::{Kind, ResultExt};
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
    /// metrics.csv as it stood at this checkpoint, in checkpoints of a coevo before manifests (empty, and
    /// not written, since: the manifest hashes `metrics.csv` itself up to the checkpoint).
    #[serde(default, skip_serializing_if = "String::is_empty")]
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
    run.join(SNAPSHOTS).join(snapshot_name(species, episode))
}

/// The episode of a snapshot's file name (`<species>-ep<NNNNN>.safetensors`), with its species.
fn parse_snapshot_name(name: &str) -> Option<(&str, usize)> {
    let (species, digits) = name.strip_suffix(".safetensors")?.rsplit_once("-ep")?;
    digits.bytes().all(|b| b.is_ascii_digit()).then(|| Some((species, digits.parse().ok()?))).flatten()
}

/// A scene's identity in the metadata of the networks trained on it: the first 16 hex digits of the
/// BLAKE3 hash of its resolved RON.
pub fn scene_id(scene: &Scene) -> String {
    blake3::hash(scene.to_ron().as_bytes()).to_hex()[..16].to_string()
}

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

/// What a safetensors file of coevo says it is: `species`, `role` and the `scene` it was trained on.
fn metadata(species: &str, role: &str, scene: Option<&Scene>) -> Metadata {
    let mut m = Metadata::from([("species".to_string(), species.to_string()), ("role".to_string(), role.to_string())]);
    if let Some(scene) = scene {
        m.insert("scene".into(), scene_id(scene));
    }
    m
}

/// Sorted, so a file's bytes are a function of its contents.
type Metadata = std::collections::BTreeMap<String, String>;

/// Refuses a safetensors file whose metadata names another species or role (or, given, another scene)
/// than the file is read as. Files without coevo's metadata (older checkpoints, actors exported from
/// Python, shipped runs) pass.
fn check_metadata(
    path: &Path,
    bytes: &[u8],
    species: &str,
    roles: &[&str],
    scene: Option<&str>,
) -> crate::error::Result<()> {
    let Ok((_, meta)) = SafeTensors::read_metadata(bytes) else { return Ok(()) };
    let Some(meta) = meta.metadata().as_ref() else { return Ok(()) };
    let field = |k: &str| meta.get(k).map(String::as_str);
    if let Some(theirs) = field("species").filter(|s| *s != species) {
        return Err(format!(
            "{}: holds a network of {theirs}, not of {species}; files were swapped or copied in",
            path.display()
        )
        .into());
    }
    if let Some(theirs) = field("role").filter(|r| !roles.contains(r)) {
        return Err(format!(
            "{}: holds a {theirs} file, not {}; files were swapped or copied in",
            path.display(),
            roles.join(" or ")
        )
        .into());
    }
    if let (Some(theirs), Some(ours)) = (field("scene"), scene) {
        if theirs != ours {
            return Err(format!(
                "{}: trained on another scene (scene {theirs}) than the run's (scene {ours}); snapshots of one run are not another's",
                path.display()
            )
            .into());
        }
    }
    Ok(())
}

/// An actor as its own safetensors file, named as PyTorch's `nn.Sequential` (module docs); its digest.
fn write_actor(path: &Path, actor: &Mlp, meta: &Metadata) -> std::io::Result<Digest> {
    let bytes = serialize(&named("", actor.parameters(), actor), meta);
    crate::io::write_atomically(path, Existing::Replace, |w| std::io::Write::write_all(w, &bytes))?;
    Ok(Digest::of(&bytes))
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

fn snapshot_name(species: &str, episode: usize) -> String {
    format!("{species}-ep{episode:05}.safetensors")
}

/// The manifest of a checkpoint folder, and a damaged checkpoint where it should have one: its
/// `state.ron` is of a coevo that writes manifests (no metrics copy in it). None for checkpoints of an
/// older coevo, and for folders of actors only.
fn run_manifest(dir: &Path) -> crate::error::Result<Option<Manifest>> {
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

/// Writes transitions `from..to` of `species`' buffer as one safetensors file, streamed (a segment can hold
/// a whole buffer, ~0.2 GB, which is never copied in memory) and hashed as it goes; its digest.
fn write_segment(path: &Path, species: &str, buf: &ReplayBuffer, from: u64, to: u64) -> std::io::Result<Digest> {
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
    let meta = metadata_json(&metadata(species, "replay", None));
    let header = padded(format!("{{\"__metadata__\":{meta},{}}}", entries.join(",")));
    let mut digest = Digest::default();
    crate::io::write_atomically(path, Existing::Replace, |w| {
        use std::io::Write;
        let mut w = Hashing::new(w);
        w.write_all(&(header.len() as u64).to_le_bytes())?;
        w.write_all(header.as_bytes())?;
        let put = |w: &mut Hashing<&mut std::io::BufWriter<std::fs::File>>, values: &[f32]| {
            values.iter().try_for_each(|v| w.write_all(&v.to_le_bytes()))
        };
        for part in 0..4 {
            for k in from..to {
                let (o, act, r, o2) = buf.transition(k);
                match part {
                    0 => put(&mut w, o)?,
                    1 => put(&mut w, act)?,
                    2 => put(&mut w, &[r])?,
                    _ => put(&mut w, o2)?,
                }
            }
        }
        digest = w.digest();
        Ok(())
    })?;
    Ok(digest)
}

/// Saves a species' buffer into the checkpoint being written (`tmp`): the segments of the current
/// checkpoint (`dir`) that still hold transitions of the buffer are hard-linked (copied where links
/// are not possible), the transitions since go into one new segment. Returns every segment's name and
/// digest (a linked one's from the current checkpoint's manifest, `previous`, where it has one).
fn save_replay(
    dir: &Path,
    tmp: &Path,
    species: &str,
    buf: &ReplayBuffer,
    previous: Option<&Manifest>,
) -> std::io::Result<Vec<(String, Digest)>> {
    let (first, pushed) = (buf.first_held(), buf.pushed);
    let existing = segments(dir, species);
    let mut covered = first;
    let mut written = Vec::new();
    for s in &existing {
        if s.from <= covered && s.to > covered && s.to <= pushed {
            let name = s.path.file_name().expect("a segment file").to_string_lossy().into_owned();
            let to = tmp.join(&name);
            if std::fs::hard_link(&s.path, &to).is_err() {
                std::fs::copy(&s.path, &to)?;
            }
            let digest = match previous.and_then(|m| m.files.get(&name)) {
                Some(d) => d.clone(),
                None => Digest::of_file(&to)?,
            };
            written.push((name, digest));
            covered = s.to;
        }
    }
    if covered < pushed {
        let name = segment_name(species, covered, pushed);
        let digest = write_segment(&tmp.join(&name), species, buf, covered, pushed)?;
        written.push((name, digest));
    }
    Ok(written)
}

/// The buffer a checkpoint saved: `transitions` stored in all, the held ones read back from the segments.
/// Each segment is checked against the manifest (where the checkpoint has one) and its metadata, and its
/// values must be finite.
fn load_replay(
    dir: &Path,
    species: &str,
    like: &ReplayBuffer,
    transitions: u64,
    manifest: Option<&Manifest>,
) -> crate::error::Result<ReplayBuffer> {
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
        let bytes = read_as(&s.path, &Expected { species, roles: &["replay"], scene: None })?;
        let st = parse(&s.path, &bytes)?;
        let n = (s.to - s.from) as usize;
        let tensor = |name: &str, shape: Vec<usize>| f32_tensor(&s.path, &st, name, &shape, ("expected", ""));
        let (obs, actions, rewards, next_obs) = (
            tensor("obs", vec![n, d])?,
            tensor("actions", vec![n, a])?,
            tensor("rewards", vec![n])?,
            tensor("next_obs", vec![n, d])?,
        );
        sealed(&s.path, &bytes, manifest.map(|m| &m.files))?;
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

/// The safetensors file of `tensors` with `meta` as its `__metadata__`, first in the header with its keys
/// sorted (safetensors' own writer orders metadata as a hash map iterates, which differs between
/// processes, and checkpoints must be the same bytes in every process).
fn serialize(tensors: &[(String, Vec<usize>, Vec<f32>)], meta: &Metadata) -> Vec<u8> {
    let plain = serialize_plain(tensors);
    let n = u64::from_le_bytes(plain[..8].try_into().expect("8 bytes")) as usize;
    let header = std::str::from_utf8(&plain[8..8 + n]).expect("a JSON header").trim_end();
    let tensors_json = header.strip_prefix('{').expect("a JSON object");
    let header = padded(format!("{{\"__metadata__\":{},{tensors_json}", metadata_json(meta)));
    [&(header.len() as u64).to_le_bytes()[..], header.as_bytes(), &plain[8 + n..]].concat()
}

fn metadata_json(meta: &Metadata) -> String {
    serde_json::to_string(meta).expect("strings serialize")
}

/// A header padded to 8 bytes with spaces, as safetensors' own writer does.
fn padded(mut header: String) -> String {
    while !header.len().is_multiple_of(8) {
        header.push(' ');
    }
    header
}

fn serialize_plain(tensors: &[(String, Vec<usize>, Vec<f32>)]) -> Vec<u8> {
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
            f32_tensor(file, st, &name, &shape, ("this scene needs", " (observation size or hidden width differ)"))
        })
        .collect()
}

/// The values of tensor `name` of a safetensors file, refused unless it is F32 of `shape` (`expected`: the
/// words before and after the shape in the error) and finite: no network or transition of a sound run
/// holds a NaN or an infinity.
fn f32_tensor(
    file: &Path,
    st: &SafeTensors,
    name: &str,
    shape: &[usize],
    expected: (&str, &str),
) -> crate::error::Result<Vec<f32>> {
    let t = st.tensor(name).map_err(|_| format!("{}: no tensor {name:?}", file.display()))?;
    if t.dtype() != Dtype::F32 || t.shape() != shape {
        let (before, after) = expected;
        return Err(format!(
            "{}: tensor {name} is {:?} {:?}, {before} F32 {shape:?}{after}",
            file.display(),
            t.dtype(),
            t.shape()
        )
        .into());
    }
    let values: Vec<f32> = t.data().chunks_exact(4).map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]])).collect();
    match values.iter().position(|v| !v.is_finite()) {
        Some(i) => Err(format!(
            "{}: tensor {name} holds a non-finite value ({} at index {i}); refusing a broken checkpoint",
            file.display(),
            values[i]
        )
        .into()),
        None => Ok(values),
    }
}

/// What a safetensors file is read as: whose, which roles, trained on which scene (None: any).
struct Expected<'a> {
    species: &'a str,
    roles: &'a [&'a str],
    scene: Option<&'a str>,
}

/// A safetensors file's bytes, checked against what it is read as (its metadata). Its tensors are then
/// read (names, shapes, finite values) and last it is checked against the manifest ([`sealed`]), so a
/// file that is wrong in a way one can name is refused with that name, any other change by the manifest.
fn read_as(path: &Path, expected: &Expected) -> crate::error::Result<Vec<u8>> {
    let bytes = read_file(path)?;
    check_metadata(path, &bytes, expected.species, expected.roles, expected.scene)?;
    Ok(bytes)
}

/// Checks a file's `bytes` against `entries` of the checkpoint's manifest, where it has one.
fn sealed(
    path: &Path,
    bytes: &[u8],
    entries: Option<&std::collections::BTreeMap<String, Digest>>,
) -> crate::error::Result<()> {
    match entries {
        Some(entries) => {
            let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
            Manifest::check(entries, &name, path, bytes)
        }
        None => Ok(()),
    }
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

/// Loads a species' actor from a run folder into `like` (which fixes the expected shapes), checked
/// against the checkpoint's manifest and the file's metadata.
pub fn load_actor(run: &Path, species: &str, like: &Mlp) -> crate::error::Result<Mlp> {
    (|| -> crate::error::Result<Mlp> {
        let dir = checkpoint_dir(run);
        let path = dir.join(actor_name(species));
        let manifest = run_manifest(&dir)?;
        let bytes = read_as(&path, &Expected { species, roles: &["actor"], scene: None })?;
        let net = mlp_from(&path, &bytes, like)?;
        sealed(&path, &bytes, manifest.as_ref().map(|m| &m.files))?;
        Ok(net)
    })()
    .kind(Kind::Checkpoint)
}

fn actor_name(species: &str) -> String {
    format!("{species}-actor.safetensors")
}

fn training_name(species: &str) -> String {
    format!("{species}-training.safetensors")
}

/// An actor file's bytes (as PyTorch names it) loaded into `like`.
fn mlp_from(path: &Path, bytes: &[u8], like: &Mlp) -> crate::error::Result<Mlp> {
    let st = parse(path, bytes)?;
    let mut net = like.clone();
    net.set_parameters(&read_into(path, &st, "", like)?);
    Ok(net)
}

/// Saves learners and state into `run/checkpoint/`, atomically as a folder, its manifest written last
/// ([`Manifest`]): `metrics` is the digest of `metrics.csv` as it stands (its rows up to this checkpoint).
pub fn save(
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
    let _ = std::fs::remove_dir_all(&old);
    if dir.exists() {
        std::fs::rename(&dir, &old)?;
    }
    std::fs::rename(&tmp, &dir)?;
    crate::io::unregister_temporary(&tmp);
    let _ = std::fs::remove_dir_all(&old);
    Ok(())
}

/// Completes a checkpoint swap that a kill cut short ([`save`]): where `checkpoint/` is whole (its state
/// file is there) a leftover `checkpoint.old/` is removed; where it is missing, `checkpoint.old/` is put
/// back. Only with the run's lock held.
pub fn finish_swap(run: &Path) {
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
pub fn read_state(path: &Path) -> crate::error::Result<TrainingState> {
    let text = crate::io::read_text(path, crate::io::MAX_TEXT_BYTES)?;
    state_from(path, &text)
}

fn state_from(path: &Path, text: &str) -> crate::error::Result<TrainingState> {
    Ok(ron::from_str(text).map_err(|e| format!("{}: corrupt checkpoint state ({e})", path.display()))?)
}

/// The checkpoint's state file, checked against its manifest, and the manifest (None for a checkpoint of
/// a coevo before manifests): what `--resume` continues from and what `--plot` counts rows against.
pub fn read_checked_state(dir: &Path) -> crate::error::Result<(TrainingState, Option<Manifest>)> {
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
        }
        for s in state.species.iter_mut().flatten().filter(|s| dropped.contains(&s.name)) {
            s.transitions = None;
        }
        Ok((state, manifest.cloned()))
    })()
    .kind(Kind::Checkpoint)
}
