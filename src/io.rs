//! The output-safety layer: every file coevo writes goes through here.
//!
//! - A file is written whole or not at all: into a temporary file beside the target, synced, then renamed
//!   over it, so a crash or SIGKILL never leaves a half-written file behind ([`AtomicFile`]).
//! - Only regular files are ever replaced: a target that is a symlink, a device, a folder or a pipe is
//!   refused, never swapped for a file ([`check_target`]).
//! - A file the user names (`--record OUT.csv`, `--screenshot`) is never overwritten unless they say
//!   `--overwrite` ([`Existing`]); coevo's own files inside a run folder (metrics, checkpoints, eval) are
//!   replaced as the run goes.
//! - Inputs are read with a size limit, and only from regular files, so a scene path pointing at something
//!   endless (`/dev/zero`) or blocking (a FIFO) stops with an error instead of filling memory or hanging
//!   ([`read_text`]).
//! - Temporaries are registered while they live: SIGINT, SIGTERM and SIGHUP remove them before coevo exits
//!   ([`install_signal_cleanup`]), and those of a killed process (its PID no longer alive) are removed by the
//!   next write of the same target ([`AtomicFile::create`]) or the next use of a run folder.

use crate::error::ResultExt;
use std::fs::File;
use std::io::{self, BufWriter, Read, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::Mutex;

/// Temporary files and folders of this process that a signal must not leave behind.
static LIVE_TEMPORARIES: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

/// Registers a temporary file or folder (and the lock files of [`crate::run`]) for removal on a signal.
pub(crate) fn register_temporary(path: &Path) {
    LIVE_TEMPORARIES.lock().unwrap_or_else(|e| e.into_inner()).push(path.to_path_buf());
}

/// Forgets a temporary: it was renamed into place or removed.
pub(crate) fn unregister_temporary(path: &Path) {
    LIVE_TEMPORARIES.lock().unwrap_or_else(|e| e.into_inner()).retain(|p| p != path);
}

/// Removes every registered temporary (folders whole).
fn remove_live_temporaries() {
    remove_each(&mut LIVE_TEMPORARIES.lock().unwrap_or_else(|e| e.into_inner()));
}

/// Removes these files and folders (folders whole), forgetting them; what is already gone is no error.
fn remove_each(paths: &mut Vec<PathBuf>) {
    for path in paths.drain(..) {
        match std::fs::symlink_metadata(&path) {
            Ok(m) if m.is_dir() => drop(std::fs::remove_dir_all(&path)),
            Ok(_) => drop(std::fs::remove_file(&path)),
            Err(_) => {}
        }
    }
}

/// The system allocator, except that an allocation the system refuses (a memory limit: `ulimit -v`, a
/// cgroup, the machine) ends the process as a signal does, with one line and its temporaries and lock
/// files removed ([`out_of_memory`]), where Rust's default would abort and leave them behind. Installed
/// by the `coevo` binary (`#[global_allocator]`); every allocation that scales with input is checked
/// against the memory estimate before it is made, so this is the backstop for the rest.
pub struct CheckedAlloc;

// SAFETY: every call is forwarded to the system allocator unchanged; only a null result is acted on.
unsafe impl std::alloc::GlobalAlloc for CheckedAlloc {
    unsafe fn alloc(&self, layout: std::alloc::Layout) -> *mut u8 {
        checked(unsafe { std::alloc::System.alloc(layout) }, layout.size())
    }
    unsafe fn alloc_zeroed(&self, layout: std::alloc::Layout) -> *mut u8 {
        checked(unsafe { std::alloc::System.alloc_zeroed(layout) }, layout.size())
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: std::alloc::Layout, new_size: usize) -> *mut u8 {
        checked(unsafe { std::alloc::System.realloc(ptr, layout, new_size) }, new_size)
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: std::alloc::Layout) {
        unsafe { std::alloc::System.dealloc(ptr, layout) }
    }
}

fn checked(ptr: *mut u8, bytes: usize) -> *mut u8 {
    if ptr.is_null() {
        out_of_memory(bytes);
    }
    ptr
}

/// Ends the process after an allocation of `bytes` was refused: the temporaries and lock files removed
/// (small allocations still succeed when a large one failed; a second failure meanwhile aborts), one
/// line, exit code 1. Formats nothing on the heap.
fn out_of_memory(bytes: usize) -> ! {
    static ONCE: AtomicBool = AtomicBool::new(false);
    if ONCE.swap(true, Ordering::SeqCst) {
        std::process::abort();
    }
    EXITING.store(true, Ordering::SeqCst);
    // try_lock: the refused allocation may have been this very list's, under its lock.
    if let Ok(mut live) = LIVE_TEMPORARIES.try_lock() {
        remove_each(&mut live);
    }
    let _ = writeln!(
        io::stderr(),
        "coevo: error: out of memory: {} MB more could not be allocated (a memory limit such as ulimit -v or the cgroup's, or the machine's); temporary files removed",
        bytes.div_ceil(1_000_000)
    );
    // SAFETY: _exit ends the process at once, running nothing that could allocate.
    unsafe { libc::_exit(1) }
}

/// Ends the process at once with `code`, after flushing standard output and error. No exit handlers and no
/// C++ static destructors run: the viewer's renderer threads (Mesa's llvmpipe) may still be compiling or
/// drawing, and `exit`'s destructors pulling LLVM from under them aborted the process ("LLVM ERROR: Do not
/// know how to split the result of this operator!", exit 134) after its work was finished and written.
#[cfg_attr(not(feature = "viewer"), allow(dead_code))]
pub(crate) fn end_process(code: i32) -> ! {
    let _ = io::stdout().flush();
    let _ = io::stderr().flush();
    // SAFETY: _exit takes no pointers and does not return; every file coevo wrote is already closed or
    // synced by its writer, and the kernel keeps what was written.
    unsafe { libc::_exit(code) }
}

/// Set by the signal handler: no new step of file writing starts ([`Writing::begin`] waits for the exit).
static EXITING: AtomicBool = AtomicBool::new(false);
/// Steps of file writing under way ([`Writing`]), which the signal handler lets finish.
static WRITING: AtomicUsize = AtomicUsize::new(0);

thread_local! {
    /// How deep this thread is in nested [`Writing`] steps (an inner step never waits for the exit).
    static DEPTH: std::cell::Cell<usize> = const { std::cell::Cell::new(0) };
}

/// A step of file writing that a signal must not cut in two: creating a temporary and registering it,
/// renaming it into place, swapping a checkpoint folder, taking a lock. While one is under way the signal
/// handler waits for it; once a signal has come, no new one starts (the thread waits for the exit). So the
/// handler never removes a temporary that a writer is about to rename or write into, and a writer never
/// creates one after the handler has cleaned up. Long streaming writes (a record of many steps) hold none
/// between their steps, so a signal still stops them at once.
pub(crate) struct Writing(());

impl Writing {
    pub(crate) fn begin() -> Writing {
        DEPTH.with(|depth| {
            if depth.get() == 0 {
                loop {
                    if !EXITING.load(Ordering::SeqCst) {
                        WRITING.fetch_add(1, Ordering::SeqCst);
                        if !EXITING.load(Ordering::SeqCst) {
                            break;
                        }
                        WRITING.fetch_sub(1, Ordering::SeqCst);
                    }
                    // The handler is cleaning up and will end the process.
                    std::thread::park_timeout(std::time::Duration::from_secs(1));
                }
            } else {
                WRITING.fetch_add(1, Ordering::SeqCst);
            }
            depth.set(depth.get() + 1);
        });
        Writing(())
    }
}

impl Drop for Writing {
    fn drop(&mut self) {
        DEPTH.with(|depth| depth.set(depth.get() - 1));
        WRITING.fetch_sub(1, Ordering::SeqCst);
    }
}

/// The longest the signal handler waits for a step of writing to finish (a checkpoint of the largest
/// buffers takes a second or two).
const WRITING_GRACE: std::time::Duration = std::time::Duration::from_secs(60);

/// On SIGINT, SIGTERM or SIGHUP: let the step of file writing under way finish ([`Writing`]), remove
/// this process's temporaries and lock files, then exit with 130 (the shell's code for an interrupted
/// command). Headless modes only: the viewer keeps Bevy's handler.
pub(crate) fn install_signal_cleanup() {
    let _ = ctrlc::set_handler(|| {
        EXITING.store(true, Ordering::SeqCst);
        let waited = std::time::Instant::now();
        while WRITING.load(Ordering::SeqCst) > 0 && waited.elapsed() < WRITING_GRACE {
            std::thread::sleep(std::time::Duration::from_millis(1));
        }
        remove_live_temporaries();
        // Not eprintln!: stderr may be a pipe to a parent that is gone, and a panic here would keep the
        // process alive without its handler.
        let _ = writeln!(io::stderr(), "coevo: interrupted; temporary files removed, finished work kept");
        std::process::exit(130);
    });
}

/// Writes to standard output; a closed or full stream is an error (one line, a non-zero exit), never a
/// panic as `print!` would give ([`outln!`](crate::outln)).
pub(crate) fn out_text(args: std::fmt::Arguments) -> crate::error::Result<()> {
    let mut out = io::stdout().lock();
    write!(out, "{args}").and_then(|()| out.flush()).map_err(|e| format!("standard output: {e}").into())
}

/// Writes to standard error (what coevo says besides its results); a closed or full stream is an error,
/// never a panic as `eprintln!` would give ([`errln!`](crate::errln)).
pub(crate) fn err_text(args: std::fmt::Arguments) -> crate::error::Result<()> {
    let mut err = io::stderr().lock();
    write!(err, "{args}").and_then(|()| err.flush()).map_err(|e| format!("standard error: {e}").into())
}

/// `println!` that returns an error instead of panicking on a closed or full standard output.
#[macro_export]
macro_rules! outln {
    ($($arg:tt)*) => { $crate::io::out_text(format_args!("{}\n", format_args!($($arg)*))) };
}

/// `eprintln!` that returns an error instead of panicking on a closed or full standard error.
#[macro_export]
macro_rules! errln {
    ($($arg:tt)*) => { $crate::io::err_text(format_args!("{}\n", format_args!($($arg)*))) };
}

/// Whether a process with this PID is alive (a PID that is ours is alive; `kill(pid, 0)` asks without
/// sending anything, EPERM means it exists under another user). A zombie, a process that has ended but
/// that its parent has not reaped yet (a runner's child killed with SIGKILL, for about a second), exists
/// for `kill` but holds nothing: `/proc/PID/stat` names its state, and Z or X is no owner.
pub(crate) fn process_alive(pid: u32) -> bool {
    if pid == std::process::id() {
        return true;
    }
    let Ok(id) = libc::pid_t::try_from(pid) else { return false };
    // SAFETY: signal 0 only checks that the process exists.
    let r = unsafe { libc::kill(id, 0) };
    let exists = r == 0 || io::Error::last_os_error().raw_os_error() == Some(libc::EPERM);
    exists && !process_ended(pid)
}

/// Whether `/proc` says the process has ended (a zombie or dead). Without `/proc` (another system), no.
fn process_ended(pid: u32) -> bool {
    let Ok(stat) = std::fs::read_to_string(format!("/proc/{pid}/stat")) else { return false };
    // "PID (COMMAND) STATE ...": the command may hold spaces and parentheses, so the state follows the last ')'.
    let state = stat.rfind(')').and_then(|end| stat[end + 1..].split_whitespace().next());
    matches!(state, Some("Z" | "X" | "x"))
}

/// The PID in a temporary's name `.NAME.PID.tmp` ([`temporary_beside`]), with NAME.
fn temporary_owner(file_name: &str) -> Option<(&str, u32)> {
    let rest = file_name.strip_prefix('.')?.strip_suffix(".tmp")?;
    let (name, pid) = rest.rsplit_once('.')?;
    Some((name, pid.parse().ok()?))
}

/// Removes the temporaries in `dir` left by processes that no longer run (killed mid-write), for every
/// target, or only for `target` (a file name) when given. Returns how many were removed.
pub(crate) fn remove_stale_temporaries(dir: &Path, target: Option<&str>) -> usize {
    let mut removed = 0;
    // An unreadable folder holds nothing to remove.
    for entry in std::fs::read_dir(dir).into_iter().flatten().flatten() {
        let name = entry.file_name().to_string_lossy().into_owned();
        let Some((of, pid)) = temporary_owner(&name) else { continue };
        let is_file = entry.file_type().is_ok_and(|t| t.is_file());
        if is_file
            && target.is_none_or(|t| t == of)
            && !process_alive(pid)
            && std::fs::remove_file(entry.path()).is_ok()
        {
            removed += 1;
        }
    }
    removed
}

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

/// A size in bytes as a reader takes it in: GB, MB or kB, so no figure prints as "0.0 GB".
pub fn bytes_shown(bytes: f64) -> String {
    match bytes {
        b if b >= 1e9 => format!("{:.1} GB", b / 1e9),
        b if b >= 1e6 => format!("{:.1} MB", b / 1e6),
        b => format!("{:.0} kB", (b / 1e3).ceil()),
    }
}

/// The memory coevo may use, in bytes: the least of what the machine has free (`MemAvailable`), the
/// limit of its cgroup (v2 `memory.max`, v1 `memory.limit_in_bytes`) and the address space left under
/// `ulimit -v` (`RLIMIT_AS` minus what the process already maps), or 1 TB where none can be read. Sizes
/// are validated against it before anything is allocated, so a limit is one error line, never an abort.
pub(crate) fn memory_bytes() -> f64 {
    [mem_available(), cgroup_limit(), address_space_left()].into_iter().flatten().fold(1e12, f64::min)
}

/// A `Key: N kB` line of a /proc file, in bytes.
fn proc_kib(file: &str, key: &str) -> Option<f64> {
    let text = std::fs::read_to_string(file).ok()?;
    let line = text.lines().find(|l| l.starts_with(key))?;
    Some(line.split_whitespace().nth(1)?.parse::<f64>().ok()? * 1024.0)
}

fn mem_available() -> Option<f64> {
    proc_kib("/proc/meminfo", "MemAvailable:")
}

/// The memory limit of this process's cgroup, where it has one.
fn cgroup_limit() -> Option<f64> {
    let groups = std::fs::read_to_string("/proc/self/cgroup").ok()?;
    let read = |file: String| std::fs::read_to_string(file).ok()?.trim().parse::<f64>().ok();
    groups.lines().find_map(|line| {
        let mut parts = line.splitn(3, ':');
        let (_, controllers, path) = (parts.next()?, parts.next()?, parts.next()?);
        match controllers {
            // cgroup v2: "max" (no limit) does not parse.
            "" => read(format!("/sys/fs/cgroup{path}/memory.max")),
            c if c.split(',').any(|c| c == "memory") => {
                read(format!("/sys/fs/cgroup/memory{path}/memory.limit_in_bytes")).filter(|&b| b < 1e18)
            }
            _ => None,
        }
    })
}

/// What `ulimit -v` leaves this process to map.
fn address_space_left() -> Option<f64> {
    let mut limit = libc::rlimit { rlim_cur: 0, rlim_max: 0 };
    // SAFETY: getrlimit writes the struct it is given.
    if unsafe { libc::getrlimit(libc::RLIMIT_AS, &mut limit) } != 0 || limit.rlim_cur == libc::RLIM_INFINITY {
        return None;
    }
    let mapped = proc_kib("/proc/self/status", "VmSize:").unwrap_or(0.0);
    Some((limit.rlim_cur as f64 - mapped).max(0.0))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_zombie_is_not_alive() {
        // A child that has exited and is not reaped yet: `kill` still finds it, the lock must not.
        let mut child = std::process::Command::new("true").spawn().unwrap();
        let pid = child.id();
        let deadline = std::time::Instant::now() + std::time::Duration::from_secs(10);
        while !process_ended(pid) {
            assert!(std::time::Instant::now() < deadline, "the child never became a zombie");
            std::thread::sleep(std::time::Duration::from_millis(5));
        }
        assert!(!process_alive(pid));
        child.wait().unwrap();
        let mut running = std::process::Command::new("sleep").arg("5").spawn().unwrap();
        assert!(process_alive(running.id()));
        running.kill().unwrap();
        running.wait().unwrap();
    }

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
