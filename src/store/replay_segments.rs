//! A species' replay buffer in the checkpoint, as segments written once: each checkpoint hard-links the
//! previous checkpoint's segments the buffer still holds and adds one with the transitions since
//! (`checkpoint.rs` module docs).

use super::manifest::{Digest, Hashing, Manifest};
use super::names::{checkpoint_dir, parse_segment_name, segment_name};
use super::tensors::{f32_tensor, metadata, metadata_json, padded, parse, read_as, sealed, Expected};
use crate::io::Existing;
use crate::learning::replay::ReplayBuffer;
use safetensors::Dtype;
use std::path::{Path, PathBuf};

/// Frees a finished run's replay buffers: removes every replay segment of its checkpoint (~0.25 GB a run
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
/// a whole buffer, ~0.1 GB, which is never copied in memory) and hashed as it goes; its digest.
///
/// A transition's next observation is most often the observation of the same agent's next transition,
/// `stride` rows on (the species' agents each store one a step): such rows are not written twice.
/// `next_from[i]` (I64) is the row of the segment whose `obs` is row i's next observation, found equal
/// to the bit before it is used, or −1 for a row kept in `next_obs` (in order: an episode's last step, a
/// segment's last step), which then has as many rows as there are −1s. Segments written before this
/// have `next_obs` for every row and no `next_from`; both are read ([`load_replay`]).
pub(super) fn write_segment(
    path: &Path,
    species: &str,
    buf: &ReplayBuffer,
    from: u64,
    to: u64,
) -> std::io::Result<Digest> {
    let n = (to - from) as usize;
    let (d, a) = (buf.obs_dim, buf.act_dim);
    let next_from: Vec<i64> = match stride(buf, from, to) {
        Some(c) => (from..to)
            .map(|k| match k + c < to && same_bits(buf.transition(k).3, buf.transition(k + c).0) {
                true => (k + c - from) as i64,
                false => -1,
            })
            .collect(),
        None => vec![-1; n],
    };
    let kept = next_from.iter().filter(|&&r| r < 0).count();
    let header = header(
        &metadata_json(&metadata(species, "replay", None)),
        &[
            ("obs", Dtype::F32, vec![n, d]),
            ("actions", Dtype::F32, vec![n, a]),
            ("rewards", Dtype::F32, vec![n]),
            ("next_from", Dtype::I64, vec![n]),
            ("next_obs", Dtype::F32, vec![kept, d]),
        ],
    );
    let mut digest = Digest::default();
    crate::io::write_atomically(path, Existing::Replace, |w| {
        use std::io::Write;
        let mut w = Hashing::new(w);
        w.write_all(&(header.len() as u64).to_le_bytes())?;
        w.write_all(header.as_bytes())?;
        // Each column goes out as it lies in the buffer (in two runs where the ring wraps), a block at a
        // time: the kernel's copy brings a block into cache and BLAKE3 hashes it there, many chunks at once.
        // (Whole columns in one write each took more system time than the copies this saves.)
        let mut write_blocks = |bytes: &[u8]| bytes.chunks(SEGMENT_BLOCK).try_for_each(|b| w.write_all(b));
        for column in 0..3 {
            for run in buf.runs(from, to) {
                write_blocks(le_bytes([run.obs, run.actions, run.rewards][column]))?;
            }
        }
        write_blocks(le_bytes(&next_from))?;
        // The next observations kept (an episode's and the segment's last steps), gathered in blocks.
        let mut block = Vec::with_capacity(SEGMENT_BLOCK + 4 * d);
        for (k, _) in (from..to).zip(&next_from).filter(|(_, &r)| r < 0) {
            block.extend_from_slice(le_bytes(buf.transition(k).3));
            if block.len() >= SEGMENT_BLOCK {
                w.write_all(&block)?;
                block.clear();
            }
        }
        w.write_all(&block)?;
        digest = w.digest();
        Ok(())
    })?;
    Ok(digest)
}

/// A segment's safetensors header: its metadata (as JSON) and its tensors (name, dtype, shape), laid out
/// one after another in that order.
fn header(meta: &str, tensors: &[(&str, Dtype, Vec<usize>)]) -> String {
    let mut offset = 0usize;
    let entries: Vec<String> = tensors
        .iter()
        .map(|(name, dtype, shape)| {
            let bytes = dtype.size() * shape.iter().product::<usize>();
            let shape: Vec<String> = shape.iter().map(usize::to_string).collect();
            // safetensors names a dtype as its variant is spelt ("F32", "I64").
            let entry = format!(
                "\"{name}\":{{\"dtype\":\"{dtype:?}\",\"shape\":[{}],\"data_offsets\":[{offset},{}]}}",
                shape.join(","),
                offset + bytes
            );
            offset += bytes;
            entry
        })
        .collect();
    padded(format!("{{\"__metadata__\":{meta},{}}}", entries.join(",")))
}

/// Feeds `hasher` a replay segment as a segment with every next observation (`next_obs` (n, d_o), no
/// `next_from`) would be written, byte for byte: what a run's fingerprint hashes
/// ([`super::provenance::fingerprint`]), so that storing a next observation once changed no
/// fingerprint, and runs of binaries from before it and after it are told the same when they computed
/// the same. A segment that cannot be read is fed as its bytes.
pub(crate) fn hash_with_every_next_observation(path: &Path, hasher: &mut blake3::Hasher) -> std::io::Result<()> {
    let bytes = std::fs::read(path)?;
    let decoded = (|| {
        let st = safetensors::SafeTensors::deserialize(&bytes).ok()?;
        st.tensor("next_from").ok()?;
        let (_, meta) = safetensors::SafeTensors::read_metadata(&bytes).ok()?;
        let meta: super::tensors::Metadata = meta.metadata().clone()?.into_iter().collect();
        let shape = st.tensor("obs").ok()?.shape().to_vec();
        let (n, d) = (shape[0], *shape.get(1)?);
        let a = *st.tensor("actions").ok()?.shape().get(1)?;
        let tensor = |name: &str, shape: &[usize]| f32_tensor(path, &st, name, shape, ("expected", "")).ok();
        let obs = tensor("obs", &[n, d])?;
        let next = next_observations(path, &st, &obs, n, d).ok()?;
        let parts = [obs, tensor("actions", &[n, a])?, tensor("rewards", &[n])?, next];
        Some((metadata_json(&meta), n, d, a, parts))
    })();
    let Some((meta, n, d, a, parts)) = decoded else {
        hasher.update(&bytes);
        return Ok(());
    };
    let header = header(
        &meta,
        &[
            ("obs", Dtype::F32, vec![n, d]),
            ("actions", Dtype::F32, vec![n, a]),
            ("rewards", Dtype::F32, vec![n]),
            ("next_obs", Dtype::F32, vec![n, d]),
        ],
    );
    hasher.update(&(header.len() as u64).to_le_bytes());
    hasher.update(header.as_bytes());
    for part in parts {
        hasher.update(le_bytes(&part));
    }
    Ok(())
}

/// The rows between one agent's transition and its next in `from..to`: the smallest c with a next
/// observation equal to the bit to the observation c rows on, looked for from the segment's first rows
/// (at most 64 of them, c up to 4 096); None when none is found (every next observation is then kept).
fn stride(buf: &ReplayBuffer, from: u64, to: u64) -> Option<u64> {
    (from..to.min(from + 64)).find_map(|k| {
        (1..=4096u64).take_while(|c| k + c < to).find(|&c| same_bits(buf.transition(k).3, buf.transition(k + c).0))
    })
}

/// Two observations equal to the bit (−0 is not 0 here: a row stands for another only if it reads back
/// as the very same numbers).
fn same_bits(x: &[f32], y: &[f32]) -> bool {
    le_bytes(x) == le_bytes(y)
}

/// Values as a safetensors file holds them, little-endian: as they lie in memory on the CPUs coevo
/// builds for.
fn le_bytes<T: bytemuck::Pod>(values: &[T]) -> &[u8] {
    bytemuck::cast_slice(values)
}
#[cfg(not(target_endian = "little"))]
compile_error!("replay segments are written as the values lie in memory, which must be little-endian");

/// Bytes of a replay segment in each write ([`write_segment`]): many BLAKE3 chunks (1 KiB each) at once,
/// so the hasher takes its SIMD path over several chunks, while the block stays in cache.
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
        let (obs, actions, rewards) =
            (tensor("obs", vec![n, d])?, tensor("actions", vec![n, a])?, tensor("rewards", vec![n])?);
        let next_obs = match st.tensor("next_from") {
            // Written before `next_from`: every next observation in `next_obs`.
            Err(_) => tensor("next_obs", vec![n, d])?,
            Ok(_) => next_observations(&s.path, &st, &obs, n, d)?,
        };
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

/// A segment's next observations from `next_from` and the rows kept in `next_obs` ([`write_segment`]),
/// refusing indices outside the segment and a count of kept rows that does not match.
fn next_observations(
    path: &Path,
    st: &safetensors::SafeTensors,
    obs: &[f32],
    n: usize,
    d: usize,
) -> crate::error::Result<Vec<f32>> {
    let damaged = |what: &str| format!("{}: {what}; the checkpoint is damaged", path.display());
    let t = st.tensor("next_from").map_err(|_| damaged("no tensor next_from"))?;
    if t.dtype() != Dtype::I64 || t.shape() != [n] {
        return Err(damaged(&format!("tensor next_from is {:?} {:?}, not I64 [{n}]", t.dtype(), t.shape())).into());
    }
    let from: Vec<i64> = t.data().chunks_exact(8).map(|c| i64::from_le_bytes(c.try_into().expect("8 bytes"))).collect();
    let kept_rows = from.iter().filter(|&&r| r < 0).count();
    let kept = f32_tensor(path, st, "next_obs", &[kept_rows, d], ("expected", ""))?;
    let (mut out, mut k) = (Vec::with_capacity(n * d), 0);
    for &r in &from {
        match r {
            r if r < 0 => {
                out.extend_from_slice(&kept[k * d..(k + 1) * d]);
                k += 1;
            }
            r if (r as usize) < n => out.extend_from_slice(&obs[r as usize * d..(r as usize + 1) * d]),
            r => return Err(damaged(&format!("next_from names row {r} of {n}")).into()),
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A buffer as a species of 3 agents fills it over two episodes of 4 steps: each agent's next
    /// observation is its observation of the next step, but at an episode's end (a new population).
    fn filled() -> ReplayBuffer {
        filled_into(100)
    }

    /// [`filled`] into a buffer of `capacity` transitions (24 are pushed).
    fn filled_into(capacity: usize) -> ReplayBuffer {
        let (agents, d) = (3, 5);
        let obs = |episode: usize, step: usize, agent: usize| -> Vec<f32> {
            (0..d).map(|j| (episode * 1000 + step * 10 + agent) as f32 + j as f32 / 8.0).collect()
        };
        let mut buf = ReplayBuffer::new(capacity, d, 2);
        for episode in 0..2 {
            for step in 0..4 {
                for agent in 0..agents {
                    let next = if step == 3 { vec![-1.5; d] } else { obs(episode, step + 1, agent) };
                    buf.push(&obs(episode, step, agent), &[0.25, -0.5], step as f32, &next);
                }
            }
        }
        buf
    }

    fn same(a: &ReplayBuffer, b: &ReplayBuffer) -> bool {
        (a.first_held()..a.pushed).all(|k| {
            let (x, y) = (a.transition(k), b.transition(k));
            x.0 == y.0 && x.1 == y.1 && x.2.to_bits() == y.2.to_bits() && x.3 == y.3
        })
    }

    #[test]
    fn a_segment_stores_a_next_observation_once_and_reads_back_to_the_bit() {
        let dir = tempfile::tempdir().unwrap();
        let buf = filled();
        let path = dir.path().join(segment_name("prey", 0, 24));
        write_segment(&path, "prey", &buf, 0, 24).unwrap();
        let bytes = std::fs::read(&path).unwrap();
        let st = parse(&path, &bytes).unwrap();
        // Kept: the last step of each episode (3 agents × 2), which is also the segment's last step.
        assert_eq!(st.tensor("next_obs").unwrap().shape(), [6, 5]);
        let back = load_replay(dir.path(), "prey", &ReplayBuffer::new(100, 5, 2), 24, None).unwrap();
        assert!(same(&buf, &back));
    }

    #[test]
    fn a_segment_across_the_ring_s_wrap_reads_back_to_the_bit() {
        // 24 pushed into 20 slots: transitions 4..24 held, 4..20 in slots 4..20 and 20..24 in slots 0..4.
        let dir = tempfile::tempdir().unwrap();
        let buf = filled_into(20);
        assert_eq!(buf.runs(4, 24).count(), 2);
        write_segment(&dir.path().join(segment_name("prey", 4, 24)), "prey", &buf, 4, 24).unwrap();
        let back = load_replay(dir.path(), "prey", &ReplayBuffer::new(20, 5, 2), 24, None).unwrap();
        assert!(same(&buf, &back));
    }

    #[test]
    fn a_fingerprint_hashes_a_segment_as_written_with_every_next_observation() {
        // The segment of the test below as this coevo writes it, hashed, equals the older layout's bytes.
        let dir = tempfile::tempdir().unwrap();
        let buf = filled();
        let new = dir.path().join("new.safetensors");
        write_segment(&new, "prey", &buf, 0, 24).unwrap();
        let old = dir.path().join("old.safetensors");
        let old_bytes = old_layout(&buf);
        std::fs::write(&old, &old_bytes).unwrap();
        let hash = |path: &Path| {
            let mut h = blake3::Hasher::new();
            hash_with_every_next_observation(path, &mut h).unwrap();
            h.finalize()
        };
        assert_eq!(hash(&new), blake3::hash(&old_bytes));
        assert_eq!(hash(&old), blake3::hash(&old_bytes));
        assert!(std::fs::metadata(&new).unwrap().len() < old_bytes.len() as u64);
    }

    /// Transitions 0..24 of `buf` as coevo wrote segments before `next_from`, with its metadata.
    fn old_layout(buf: &ReplayBuffer) -> Vec<u8> {
        let rows = |part: usize| -> Vec<u8> {
            (0..24u64)
                .flat_map(|k| {
                    let (o, a, r, o2) = buf.transition(k);
                    match part {
                        0 => o.to_vec(),
                        1 => a.to_vec(),
                        2 => vec![r],
                        _ => o2.to_vec(),
                    }
                })
                .flat_map(f32::to_le_bytes)
                .collect()
        };
        let header = header(
            &metadata_json(&metadata("prey", "replay", None)),
            &[
                ("obs", Dtype::F32, vec![24, 5]),
                ("actions", Dtype::F32, vec![24, 2]),
                ("rewards", Dtype::F32, vec![24]),
                ("next_obs", Dtype::F32, vec![24, 5]),
            ],
        );
        let mut bytes = (header.len() as u64).to_le_bytes().to_vec();
        bytes.extend(header.as_bytes());
        (0..4).for_each(|part| bytes.extend(rows(part)));
        bytes
    }

    #[test]
    fn a_segment_with_every_next_observation_still_loads() {
        // As coevo wrote segments before `next_from`: `next_obs` for every row.
        let dir = tempfile::tempdir().unwrap();
        let buf = filled();
        std::fs::write(dir.path().join(segment_name("prey", 0, 24)), old_layout(&buf)).unwrap();
        let back = load_replay(dir.path(), "prey", &ReplayBuffer::new(100, 5, 2), 24, None).unwrap();
        assert!(same(&buf, &back));
    }
}
