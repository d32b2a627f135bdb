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
//!
//! Four concerns, a file each: writing and reading files ([`files`]), what a process must not leave
//! behind (registered temporaries, signals, the end of the process: [`cleanup`]), the memory it may use
//! ([`memory`]), and printing that fails instead of panicking ([`print`]).

mod cleanup;
mod files;
mod memory;
mod print;

#[cfg(feature = "viewer")]
pub(crate) use cleanup::end_process;
pub(crate) use cleanup::{
    install_signal_cleanup, process_alive, register_temporary, remove_stale_temporaries, unregister_temporary, Writing,
};
pub(crate) use files::{
    beside, check_own_dir, check_target, check_targets, open_input, own_dir, write_atomically, AtomicFile,
};
pub use files::{read_text, write_file, Existing, MAX_TEXT_BYTES};
pub(crate) use memory::memory_bytes;
pub use memory::{bytes_shown, CheckedAlloc};
pub(crate) use print::{err_text, out_text};
