//! A species' replay buffer in the checkpoint, as segments written once: each checkpoint hard-links the
//! previous checkpoint's segments the buffer still holds and adds one with the transitions since
//! (`checkpoint.rs` module docs).

use super::manifest::{Digest, Hashing, Manifest};
use super::names::{checkpoint_dir, parse_segment_name, segment_name};
use super::tensors::{f32_tensor, metadata, metadata_json, padded, parse, read_as, sealed, Expected};
use crate::io::Existing;
use crate::learning::replay::ReplayBuffer;
use std::path::{Path, PathBuf};

/// Frees a finished run's replay buffers: removes every replay segment of its checkpoint (~0.45 GB a run
/// of the standard scene) and returns the bytes freed. Only resumed training reads them; evaluation,
/// cross-play and the viewer need the networks alone. A run resumed without them refills its buffers
/// and says so ([`load`]), as with a checkpoint of an older coevo.
pub(crate) fn drop_replay(run: &Path) -> std::io::Result<u64> {
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
pub(super) struct Segment {
    pub(super) from: u64,
    pub(super) to: u64,
    pub(super) path: PathBuf,
}

/// The replay segments of `species` in a checkpoint folder, by first transition.
pub(super) fn segments(dir: &Path, species: &str) -> Vec<Segment> {
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
pub(super) fn chain(segments: &[Segment], from: u64, to: u64) -> Option<Vec<Segment>> {
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
pub(super) fn write_segment(
    path: &Path,
    species: &str,
    buf: &ReplayBuffer,
    from: u64,
    to: u64,
) -> std::io::Result<Digest> {
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
        // The values go out in blocks: written and hashed a value at a time, a checkpoint of the standard
        // scene spent more time in BLAKE3's and the writer's per-call overhead than in hashing itself.
        let mut block = Vec::with_capacity(SEGMENT_BLOCK + 4 * d.max(a));
        for part in 0..4 {
            for k in from..to {
                let (o, act, r, o2) = buf.transition(k);
                let values = match part {
                    0 => o,
                    1 => act,
                    2 => std::slice::from_ref(&r),
                    _ => o2,
                };
                block.extend(values.iter().flat_map(|v| v.to_le_bytes()));
                if block.len() >= SEGMENT_BLOCK {
                    w.write_all(&block)?;
                    block.clear();
                }
            }
        }
        w.write_all(&block)?;
        digest = w.digest();
        Ok(())
    })?;
    Ok(digest)
}

/// Bytes of a replay segment gathered before each write ([`write_segment`]): many BLAKE3 chunks (1 KiB
/// each) at once, so the hasher takes its SIMD path over several chunks, while the block stays in cache.
const SEGMENT_BLOCK: usize = 1 << 16;

/// Saves a species' buffer into the checkpoint being written (`tmp`): the segments of the current
/// checkpoint (`dir`) that still hold transitions of the buffer are hard-linked (copied where links
/// are not possible), the transitions since go into one new segment. Returns every segment's name and
/// digest (a linked one's from the current checkpoint's manifest, `previous`, where it has one).
pub(super) fn save_replay(
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
pub(super) fn load_replay(
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
