//! The `coevo` binary: the command line of [`coevo::cli`] with no species beyond the presets'.

/// An allocation the system refuses ends the run in one line, its temporaries removed ([`coevo::io::CheckedAlloc`]).
#[global_allocator]
static ALLOCATOR: coevo::io::CheckedAlloc = coevo::io::CheckedAlloc;

fn main() -> std::process::ExitCode {
    coevo::cli::main(coevo::sim::species::SpeciesPlugins::new())
}
