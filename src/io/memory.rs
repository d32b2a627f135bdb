//! The memory coevo may use: what is free, the cgroup's limit and `ulimit -v` ([`memory_bytes`]), sizes
//! said as a reader takes them in, and the allocator that ends the process cleanly when one is refused.

use std::io::{self, Write};
use std::sync::atomic::{AtomicBool, Ordering};

use super::cleanup::{remove_each, EXITING, LIVE_TEMPORARIES};

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
