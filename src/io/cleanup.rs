//! What a process must not leave behind: its temporary files and lock files are registered while they live
//! and removed on SIGINT, SIGTERM and SIGHUP, after the step of writing under way finishes ([`Writing`]);
//! those of a killed process (its PID no longer alive) are removed by the next write of the same target;
//! and the viewer's process ends without running exit handlers ([`end_process`]).

use std::io::{self, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::Mutex;

/// Temporary files and folders of this process that a signal must not leave behind.
pub(super) static LIVE_TEMPORARIES: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

/// Registers a temporary file or folder (and the lock files of [`crate::store`]) for removal on a signal.
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
pub(super) fn remove_each(paths: &mut Vec<PathBuf>) {
    for path in paths.drain(..) {
        match std::fs::symlink_metadata(&path) {
            Ok(m) if m.is_dir() => drop(std::fs::remove_dir_all(&path)),
            Ok(_) => drop(std::fs::remove_file(&path)),
            Err(_) => {}
        }
    }
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
pub(super) static EXITING: AtomicBool = AtomicBool::new(false);
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
}
