//! A checkpoint's proof of integrity, `RUN/checkpoint/manifest.ron`: the BLAKE3 hash (`blake3` crate) and
//! size of every file of the checkpoint, of every snapshot of the run up to the checkpoint's episode, and
//! of `metrics.csv` up to that episode, with the species, network shapes and transitions it holds.
//!
//! It is written last into `checkpoint.tmp/` (atomically), so a checkpoint folder is swapped in only with
//! its manifest. Whatever reads a checkpoint (`--resume`, `--eval`, `--watch`, `--record --run`,
//! `--crossplay`) checks each file it reads against it: a file changed by one byte, two files swapped, a
//! file copied in from another run, or a metrics row edited is one error line naming the file. Checkpoints
//! of a coevo before manifests (their `state.ron` still carries the metrics) are read as before, and so
//! are folders that hold actors only (a run shipped or exported from Python).

use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::Path;

/// The manifest's file name, in the checkpoint folder.
pub const MANIFEST: &str = "manifest.ron";

/// The size and BLAKE3 hash of some bytes.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Digest {
    pub(crate) bytes: u64,
    pub(crate) blake3: String,
}

impl Digest {
    pub(crate) fn of(bytes: &[u8]) -> Digest {
        Digest { bytes: bytes.len() as u64, blake3: blake3::hash(bytes).to_hex().to_string() }
    }

    /// The digest of what `hasher` was fed, `bytes` long.
    pub(crate) fn of_hasher(hasher: &blake3::Hasher, bytes: u64) -> Digest {
        Digest { bytes, blake3: hasher.finalize().to_hex().to_string() }
    }

    /// The digest of a file as it is on disk, streamed through BLAKE3's own buffer (wide enough for its
    /// SIMD path; a file is never read whole into memory: an executable with its line tables is ~75 MB).
    pub fn of_file(path: &Path) -> std::io::Result<Digest> {
        let mut hasher = blake3::Hasher::new();
        hasher.update_reader(crate::io::open_input(path)?)?;
        Ok(Digest::of_hasher(&hasher, hasher.count()))
    }
}

/// What a checkpoint holds of one learning species.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub(crate) struct SpeciesEntry {
    pub(crate) name: String,
    /// d_o, the actor's input.
    pub(crate) observation: usize,
    pub(crate) hidden: usize,
    /// Transitions `from..to` (among all the species ever stored) its replay segments hold.
    pub(crate) transitions: Option<(u64, u64)>,
}

/// `checkpoint/manifest.ron`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Manifest {
    pub(crate) episodes_done: usize,
    /// The run's scene ([`super::tensors::scene_id`]): every network file and snapshot names it too.
    pub(crate) scene: String,
    pub(crate) species: Vec<SpeciesEntry>,
    /// Every file of the checkpoint folder but the manifest, by name.
    pub(crate) files: BTreeMap<String, Digest>,
    /// Every snapshot of the run (`snapshots/`) of an episode up to `episodes_done`, by name.
    pub snapshots: BTreeMap<String, Digest>,
    /// `metrics.csv`'s first `bytes` bytes: its header and the rows of episodes up to `episodes_done`.
    pub metrics: Digest,
}

impl Manifest {
    /// The manifest of the checkpoint folder `dir`, None where it has none.
    pub fn read(dir: &Path) -> crate::error::Result<Option<Manifest>> {
        let path = dir.join(MANIFEST);
        if std::fs::symlink_metadata(&path).is_err() {
            return Ok(None);
        }
        let text = crate::io::read_text(&path, crate::io::MAX_TEXT_BYTES)?;
        Ok(Some(ron::from_str(&text).map_err(|e| format!("{}: damaged checkpoint manifest ({e})", path.display()))?))
    }

    /// The manifest as written, one file per line of `files` and `snapshots`.
    pub fn to_ron(&self) -> String {
        let text = ron::ser::to_string_pretty(self, ron::ser::PrettyConfig::new().struct_names(false))
            .expect("a manifest serializes");
        format!("{text}\n")
    }

    /// Checks `bytes`, read from `path`, against the entry `name` of `entries` (the checkpoint's files or
    /// the run's snapshots): listed, of that size and hash.
    pub(crate) fn check(
        entries: &BTreeMap<String, Digest>,
        name: &str,
        path: &Path,
        bytes: &[u8],
    ) -> crate::error::Result<()> {
        let Some(expected) = entries.get(name) else {
            return Err(format!(
                "{}: not in the checkpoint's manifest ({MANIFEST}): not written by this run's training (copied from another run, or left by a run stopped after its last checkpoint); remove it, or resume the run",
                path.display()
            )
            .into());
        };
        let found = Digest::of(bytes);
        if &found != expected {
            let what = if found.bytes != expected.bytes {
                format!("{} bytes, the manifest says {}", found.bytes, expected.bytes)
            } else {
                "its BLAKE3 hash differs from the manifest's".to_string()
            };
            return Err(format!(
                "{}: changed since the checkpoint was written ({what}); the checkpoint is damaged: restore the file or train the run again",
                path.display()
            )
            .into());
        }
        Ok(())
    }
}

/// A writer that hashes what passes through it (a replay segment is hashed as it is streamed to disk).
pub(crate) struct Hashing<W> {
    pub(crate) inner: W,
    pub(crate) hasher: blake3::Hasher,
    pub(crate) bytes: u64,
}

impl<W> Hashing<W> {
    pub(crate) fn new(inner: W) -> Hashing<W> {
        Hashing { inner, hasher: blake3::Hasher::new(), bytes: 0 }
    }

    pub(crate) fn digest(&self) -> Digest {
        Digest::of_hasher(&self.hasher, self.bytes)
    }
}

impl<W: std::io::Write> std::io::Write for Hashing<W> {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        let n = self.inner.write(buf)?;
        self.hasher.update(&buf[..n]);
        self.bytes += n as u64;
        Ok(n)
    }

    fn flush(&mut self) -> std::io::Result<()> {
        self.inner.flush()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_changed_swapped_or_unlisted_file_is_refused() {
        let files: BTreeMap<String, Digest> =
            [("a".to_string(), Digest::of(b"first")), ("b".to_string(), Digest::of(b"other"))].into();
        let path = Path::new("ck/a");
        assert!(Manifest::check(&files, "a", path, b"first").is_ok());
        let changed = Manifest::check(&files, "a", path, b"firsT").unwrap_err().to_string();
        assert!(changed.starts_with("ck/a: changed since") && changed.contains("hash"), "{changed}");
        // Same size, another file's bytes (two files swapped).
        assert!(Manifest::check(&files, "a", path, b"other").is_err());
        assert!(Manifest::check(&files, "a", path, b"firs").unwrap_err().to_string().contains("4 bytes"));
        assert!(Manifest::check(&files, "c", Path::new("ck/c"), b"x").unwrap_err().to_string().contains("not in"));
    }

    #[test]
    fn a_hashing_writer_hashes_what_it_writes() {
        use std::io::Write;
        let mut w = Hashing::new(Vec::new());
        w.write_all(b"some bytes").unwrap();
        assert_eq!(w.digest(), Digest::of(b"some bytes"));
        assert_eq!(w.inner, b"some bytes");
    }
}
