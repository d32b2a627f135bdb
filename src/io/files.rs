//! Writing a file whole or not at all, only ever replacing a regular file, never a user's unless asked;
//! reading inputs with a size limit and only from regular files (the module docs of [`crate::io`]).

use crate::error::ResultExt;
use std::fs::File;
use std::io::{self, BufWriter, Read, Write};
use std::path::{Path, PathBuf};

use super::cleanup::{register_temporary, remove_stale_temporaries, unregister_temporary, Writing};

/// What to do when the target of a write already exists.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Existing {
    /// Refuse: a file the user named, which they did not ask to replace.
    Refuse,
    /// Replace it (if it is a regular file): coevo's own files, or `--overwrite`.
    Replace,
}

/// Refuses a target that exists and is not a regular file, or that exists at all under `Existing::Refuse`.
pub(crate) fn check_target(path: &Path, existing: Existing) -> io::Result<()> {
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

/// [`check_target`] of every file a mode will write, before its work: one line naming the first refused.
pub(crate) fn check_targets(paths: &[PathBuf], existing: Existing) -> crate::error::Result<()> {
    for path in paths {
        check_target(path, existing).map_err(|e| format!("{}: {e}", path.display())).kind(crate::error::Kind::Io)?;
    }
    Ok(())
}

/// A file being written: all writes go to a temporary file beside the target, which [`AtomicFile::commit`]
/// renames over it. Dropped without a commit (an error, a panic), the temporary is removed and the target
/// is untouched.
pub(crate) struct AtomicFile {
    target: PathBuf,
    tmp: PathBuf,
    existing: Existing,
    out: Option<BufWriter<File>>,
}

impl AtomicFile {
    /// Starts writing `path`, after checking that it may be written ([`check_target`]).
    pub(crate) fn create(path: &Path, existing: Existing) -> io::Result<AtomicFile> {
        check_target(path, existing)?;
        let _writing = Writing::begin();
        if let Some(name) = path.file_name() {
            let dir = path.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new("."));
            remove_stale_temporaries(dir, Some(&name.to_string_lossy()));
        }
        let tmp = temporary_beside(path);
        // create_new: never through a link or over a file someone else placed at the temporary's name.
        let _ = std::fs::remove_file(&tmp);
        let out = BufWriter::new(File::options().write(true).create_new(true).open(&tmp)?);
        register_temporary(&tmp);
        Ok(AtomicFile { target: path.to_path_buf(), tmp, existing, out: Some(out) })
    }

    /// The writer.
    pub(crate) fn writer(&mut self) -> &mut BufWriter<File> {
        self.out.as_mut().expect("an uncommitted file has its writer")
    }

    /// Flushes, syncs and renames the temporary over the target. A target the caller may not replace
    /// ([`Existing::Refuse`]) is still refused if another process created it meanwhile: the rename then
    /// does not replace ([`rename_new`]), so of two processes writing one new file only one succeeds.
    pub(crate) fn commit(mut self) -> io::Result<()> {
        let mut out = self.out.take().expect("commit once");
        out.flush()?;
        out.get_ref().sync_all()?;
        drop(out);
        let _writing = Writing::begin();
        let renamed = match self.existing {
            // A replaced file keeps its permissions (a user's 0600 record stays private).
            Existing::Replace => check_target(&self.target, Existing::Replace)
                .and_then(|()| match std::fs::metadata(&self.target) {
                    Ok(old) => std::fs::set_permissions(&self.tmp, old.permissions()),
                    Err(_) => Ok(()),
                })
                .and_then(|()| std::fs::rename(&self.tmp, &self.target)),
            Existing::Refuse => rename_new(&self.tmp, &self.target),
        };
        if renamed.is_err() {
            let _ = std::fs::remove_file(&self.tmp);
        }
        unregister_temporary(&self.tmp);
        renamed
    }
}

impl Drop for AtomicFile {
    fn drop(&mut self) {
        if self.out.take().is_some() {
            let _writing = Writing::begin();
            let _ = std::fs::remove_file(&self.tmp);
            unregister_temporary(&self.tmp);
        }
    }
}

/// Renames `from` to `to` unless `to` exists (Linux `renameat2(RENAME_NOREPLACE)`; elsewhere, or on a
/// file system without it, a hard link and an unlink, which fail the same way).
fn rename_new(from: &Path, to: &Path) -> io::Result<()> {
    let taken =
        || io::Error::new(io::ErrorKind::AlreadyExists, "already exists; choose a new name or pass --overwrite");
    #[cfg(target_os = "linux")]
    {
        use std::os::unix::ffi::OsStrExt;
        let c = |p: &Path| std::ffi::CString::new(p.as_os_str().as_bytes()).map_err(io::Error::other);
        let (a, b) = (c(from)?, c(to)?);
        // SAFETY: two NUL-terminated paths that live across the call.
        let r =
            unsafe { libc::renameat2(libc::AT_FDCWD, a.as_ptr(), libc::AT_FDCWD, b.as_ptr(), libc::RENAME_NOREPLACE) };
        if r == 0 {
            return Ok(());
        }
        let e = io::Error::last_os_error();
        match e.raw_os_error() {
            Some(libc::EEXIST) => return Err(taken()),
            Some(libc::EINVAL) | Some(libc::ENOSYS) => {}
            _ => return Err(e),
        }
    }
    match std::fs::hard_link(from, to) {
        Ok(()) => std::fs::remove_file(from),
        Err(e) if e.kind() == io::ErrorKind::AlreadyExists => Err(taken()),
        Err(e) => Err(e),
    }
}

/// Creates the folder `dir` (and its parents) where coevo writes its own files inside a run or results
/// folder (`figures/`, `snapshots/`, `slurm/`), and refuses it unless it is a real folder: a symbolic link
/// there would send coevo's writes into whatever folder it points to.
pub(crate) fn own_dir(dir: &Path) -> crate::error::Result<()> {
    if check_own_dir(dir)? {
        return Ok(());
    }
    let _writing = Writing::begin();
    std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display())).kind(crate::error::Kind::Io)
}

/// [`own_dir`]'s refusals without making anything: a symbolic link, or something other than a folder,
/// where coevo will write a folder of its own. Whether the folder is there already.
pub(crate) fn check_own_dir(dir: &Path) -> crate::error::Result<bool> {
    match std::fs::symlink_metadata(dir) {
        Ok(m) if m.file_type().is_symlink() => Err(format!(
            "{}: is a symbolic link; coevo writes only into real folders it owns, never through a link: remove the link",
            dir.display()
        )),
        Ok(m) if !m.is_dir() => Err(format!("{}: exists and is not a folder", dir.display())),
        Ok(_) => Ok(true),
        Err(_) => Ok(false),
    }
    .kind(crate::error::Kind::Io)
}

/// Writes `path` atomically with `write`; on error the target is untouched and the temporary removed.
pub(crate) fn write_atomically(
    path: &Path,
    existing: Existing,
    write: impl FnOnce(&mut BufWriter<File>) -> io::Result<()>,
) -> io::Result<()> {
    let mut file = AtomicFile::create(path, existing)?;
    write(file.writer())?;
    file.commit()
}

/// The file written beside `path` under the same stem: `OUT.csv` → `OUT-{what}.csv` (an evaluation's
/// distributions, a record's order parameters).
pub(crate) fn beside(path: &Path, what: &str) -> PathBuf {
    let stem = path.file_stem().unwrap_or_default().to_string_lossy();
    path.with_file_name(format!("{stem}-{what}.csv"))
}

/// [`write_atomically`] of whole bytes, with the error as one line naming the file.
pub fn write_file(path: &Path, existing: Existing, bytes: &[u8]) -> crate::error::Result<()> {
    write_atomically(path, existing, |w| w.write_all(bytes))
        .map_err(|e| format!("{}: {e}", path.display()))
        .kind(crate::error::Kind::Io)
}

fn temporary_beside(path: &Path) -> PathBuf {
    let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    path.with_file_name(format!(".{name}.{}.tmp", std::process::id()))
}

/// The largest text file coevo reads (a scene, an experiment, a checkpoint's state): far more than any
/// real one, far less than memory.
pub const MAX_TEXT_BYTES: u64 = 64 << 20;

/// Reads a UTF-8 text file of at most `limit` bytes; a leading byte-order mark is dropped. Errors name the
/// file and say what is wrong in a user's words.
pub fn read_text(path: &Path, limit: u64) -> crate::error::Result<String> {
    read_text_unnamed(path, limit).map_err(|e| e.in_file(path))
}

/// Why an input that is not a regular file is refused ([`open_input`]).
const NOT_REGULAR: &str = "is not a regular file (a folder, pipe or device); coevo reads its inputs from files";

/// Opens an input file, every input's one way in: asked first whether it is a regular file, since opening
/// a FIFO blocks until a writer comes and a device may never end (refused as `InvalidInput`, its message
/// saying so). A missing file is the `NotFound` error it is, for callers to whom absent is an answer.
pub(crate) fn open_input(path: &Path) -> io::Result<File> {
    if !std::fs::metadata(path)?.is_file() {
        return Err(io::Error::new(io::ErrorKind::InvalidInput, NOT_REGULAR));
    }
    File::open(path)
}

fn read_text_unnamed(path: &Path, limit: u64) -> crate::error::Result<String> {
    // Only the system's refusals are I/O errors; a file of the wrong sort or content is left unclassified,
    // for the concern that reads it to classify (a damaged manifest is a checkpoint error).
    let cannot = |e: io::Error| crate::error::Error::from(format!("cannot read: {e}")).of_kind(crate::error::Kind::Io);
    let file = open_input(path).map_err(|e| match e.kind() {
        io::ErrorKind::InvalidInput => crate::error::Error::from(NOT_REGULAR),
        _ => cannot(e),
    })?;
    let mut bytes = Vec::new();
    file.take(limit + 1).read_to_end(&mut bytes).map_err(cannot)?;
    if bytes.len() as u64 > limit {
        return Err(format!("is larger than {} MiB; not a file coevo reads", limit >> 20).into());
    }
    let text = String::from_utf8(bytes).map_err(|e| {
        format!("is not UTF-8 text (invalid byte at offset {}); save it as UTF-8", e.utf8_error().valid_up_to())
    })?;
    Ok(text.strip_prefix('\u{feff}').map(str::to_string).unwrap_or(text))
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
        assert!(read_text(&path, 4).unwrap_err().to_string().contains("larger than"));
        std::fs::write(&path, [0xff, 0xfe, 0x00]).unwrap();
        assert!(read_text(&path, 100).unwrap_err().to_string().contains("not UTF-8"));
    }
}
