//! The `coevo` binary: the command line of [`coevo::cli`] with no species beyond the presets'.

fn main() -> std::process::ExitCode {
    coevo::cli::main(coevo::sim::species::SpeciesPlugins::new())
}
