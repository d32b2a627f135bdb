//! Records which commit a binary was built from (`git describe --always --dirty`), for the provenance
//! of every run it makes (`src/run/mod.rs`, `provenance.ron`); "unknown" outside a git checkout.
//! No rerun-if-changed lines: Cargo reruns this whenever a file of the package changes, so the commit
//! (and whether the tree was dirty) is current in every build.

fn main() {
    let commit = std::process::Command::new("git")
        .args(["describe", "--always", "--dirty", "--abbrev=12"])
        .output()
        .ok()
        .filter(|o| o.status.success())
        .and_then(|o| String::from_utf8(o.stdout).ok())
        .map(|s| s.trim().to_string())
        .filter(|s| !s.is_empty())
        .unwrap_or_else(|| "unknown".into());
    println!("cargo:rustc-env=COEVO_GIT_COMMIT={commit}");
}
