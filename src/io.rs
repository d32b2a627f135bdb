//! The output-safety layer: every file coevo writes goes through here.
//!
//! - A file is written whole or not at all: into a temporary file beside the target, synced, then renamed
//!   over it, so a crash or SIGKILL never leaves a half-written file behind ([`AtomicFile`]).
//! - Only regular files are ever replaced: a target that is a symlink, a device, a folder or a pipe is
//!   refused, never swapped for a file ([`check_target`]).
//! - A file the user names (`--record OUT.csv`, `--screenshot`) is never overwritten unless they say
//!   `--overwrite` ([`Existing`]); coevo's own files inside a run folder (metrics, checkpoints, eval) are
//!   replaced as the run goes.
//! - Inputs are read with a size limit, so a scene path pointing at something endless (`/dev/zero`) stops
//!   with an error instead of filling memory ([`read_text`]).

use std::fs::File;
use std::io::{self, BufWriter, Read, Write};
use std::path::{Path, PathBuf};

/// What to do when the target of a write already exists.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Existing {
    /// Refuse: a file the user named, which they did not ask to replace.
    Refuse,
    /// Replace it (if it is a regular file): coevo's own files, or `--overwrite`.
    Replace,
}

/// Refuses a target that exists and is not a regular file, or that exists at all under `Existing::Refuse`.
pub fn check_target(path: &Path, existing: Existing) -> io::Result<()> {
    match std::fs::symlink_metadata(path) {
        Err(e) if e.kind() == io::ErrorKind::NotFound => Ok(()),
        Err(e) => Err(e),
        Ok(meta) if !meta.file_type().is_file() => Err(io::Error::other(
            "exists and is not a regular file (a link, folder or device); coevo writes only new or regular files",
        )),
        Ok(_) if existing == Existing::Refuse => {
            Err(io::Error::other("already exists; choose a new name or pass --overwrite"))
        }
        Ok(_) => Ok(()),
    }
}

/// A file being written: all writes go to a temporary file beside the target, which [`AtomicFile::commit`]
/// renames over it. Dropped without a commit (an error, a panic), the temporary is removed and the target
/// is untouched.
pub struct AtomicFile {
    target: PathBuf,
    tmp: PathBuf,
    out: Option<BufWriter<File>>,
}

impl AtomicFile {
    /// Starts writing `path`, after checking that it may be written ([`check_target`]).
    pub fn create(path: &Path, existing: Existing) -> io::Result<AtomicFile> {
        check_target(path, existing)?;
        let tmp = temporary_beside(path);
        let out = BufWriter::new(File::create(&tmp)?);
        Ok(AtomicFile { target: path.to_path_buf(), tmp, out: Some(out) })
    }

    /// The writer.
    pub fn writer(&mut self) -> &mut BufWriter<File> {
        self.out.as_mut().expect("an uncommitted file has its writer")
    }

    /// Flushes, syncs and renames the temporary over the target.
    pub fn commit(mut self) -> io::Result<()> {
        let mut out = self.out.take().expect("commit once");
        out.flush()?;
        out.get_ref().sync_all()?;
        drop(out);
        std::fs::rename(&self.tmp, &self.target)
    }
}

impl Drop for AtomicFile {
    fn drop(&mut self) {
        if self.out.take().is_some() {
            let _ = std::fs::remove_file(&self.tmp);
        }
    }
}

/// Writes `path` atomically with `write`; on error the target is untouched and the temporary removed.
pub fn write_atomically(
    path: &Path,
    existing: Existing,
    write: impl FnOnce(&mut BufWriter<File>) -> io::Result<()>,
) -> io::Result<()> {
    let mut file = AtomicFile::create(path, existing)?;
    write(file.writer())?;
    file.commit()
}

/// [`write_atomically`] of whole bytes, with the error as one line naming the file.
/// The file written beside `path` under the same stem: `OUT.csv` → `OUT-{what}.csv` (an evaluation's
/// distributions, a record's order parameters).
pub fn beside(path: &Path, what: &str) -> PathBuf {
    let stem = path.file_stem().unwrap_or_default().to_string_lossy();
    path.with_file_name(format!("{stem}-{what}.csv"))
}

pub fn write_file(path: &Path, existing: Existing, bytes: &[u8]) -> Result<(), String> {
    write_atomically(path, existing, |w| w.write_all(bytes)).map_err(|e| format!("{}: {e}", path.display()))
}

fn temporary_beside(path: &Path) -> PathBuf {
    let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    path.with_file_name(format!(".{name}.{}.tmp", std::process::id()))
}

/// The largest text file coevo reads (a scene, an experiment, a checkpoint's state): far more than any
/// real one, far less than memory.
pub const MAX_TEXT_BYTES: u64 = 64 << 20;

/// Reads a UTF-8 text file of at most `limit` bytes; a leading byte-order mark is dropped. Errors say
/// what is wrong in a user's words.
pub fn read_text(path: &Path, limit: u64) -> Result<String, String> {
    let file = File::open(path).map_err(|e| format!("cannot read: {e}"))?;
    let mut bytes = Vec::new();
    file.take(limit + 1).read_to_end(&mut bytes).map_err(|e| format!("cannot read: {e}"))?;
    if bytes.len() as u64 > limit {
        return Err(format!("is larger than {} MiB; not a file coevo reads", limit >> 20));
    }
    let text = String::from_utf8(bytes).map_err(|e| {
        format!("is not UTF-8 text (invalid byte at offset {}); save it as UTF-8", e.utf8_error().valid_up_to())
    })?;
    Ok(text.strip_prefix('\u{feff}').map(str::to_string).unwrap_or(text))
}

/// This machine's memory in bytes (`MemTotal` of /proc/meminfo), or 1 TB where that cannot be read:
/// what sizes are validated against before anything is allocated.
pub fn memory_bytes() -> f64 {
    std::fs::read_to_string("/proc/meminfo")
        .ok()
        .and_then(|m| {
            m.lines()
                .find(|l| l.starts_with("MemTotal:"))
                .and_then(|l| l.split_whitespace().nth(1)?.parse::<f64>().ok())
        })
        .map_or(1e12, |kib| kib * 1024.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_uncommitted_file_leaves_the_target_untouched() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("out.csv");
        std::fs::write(&path, "before").unwrap();
        {
            let mut f = AtomicFile::create(&path, Existing::Replace).unwrap();
            f.writer().write_all(b"half").unwrap();
        }
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "before");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1, "the temporary is gone");
        write_atomically(&path, Existing::Replace, |w| w.write_all(b"after")).unwrap();
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "after");
    }

    #[test]
    fn links_folders_and_existing_user_files_are_refused() {
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("file");
        std::fs::write(&file, "keep").unwrap();
        assert!(check_target(&file, Existing::Refuse).unwrap_err().to_string().contains("already exists"));
        assert!(check_target(dir.path(), Existing::Replace).unwrap_err().to_string().contains("not a regular file"));
        #[cfg(unix)]
        {
            let link = dir.path().join("link");
            std::os::unix::fs::symlink(&file, &link).unwrap();
            assert!(write_atomically(&link, Existing::Replace, |w| w.write_all(b"x")).is_err());
            assert_eq!(std::fs::read_to_string(&file).unwrap(), "keep");
            assert!(std::fs::symlink_metadata(&link).unwrap().file_type().is_symlink());
        }
    }

    #[test]
    fn text_is_read_with_a_limit_and_without_a_byte_order_mark() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("s.ron");
        std::fs::write(&path, "\u{feff}(seed: 1)").unwrap();
        assert_eq!(read_text(&path, 100).unwrap(), "(seed: 1)");
        assert!(read_text(&path, 4).unwrap_err().contains("larger than"));
        std::fs::write(&path, [0xff, 0xfe, 0x00]).unwrap();
        assert!(read_text(&path, 100).unwrap_err().contains("not UTF-8"));
    }
}
