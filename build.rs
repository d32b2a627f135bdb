//! Records which commit a binary was built from (`git describe --always --dirty`), for the provenance
//! of every run it makes (`src/run/mod.rs`, `provenance.ron`); "unknown" outside a git checkout.
//! Reruns when the sources change and when git's HEAD, refs or index do (a commit changes no source
//! file, but the name of the tree the binary is built from), so the name is current in every build.

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
    for path in ["src", "vendor", "Cargo.toml", "Cargo.lock", "build.rs"] {
        println!("cargo:rerun-if-changed={path}");
    }
    for path in [".git/HEAD", ".git/index", ".git/refs", ".git/packed-refs"] {
        if std::path::Path::new(path).exists() {
            println!("cargo:rerun-if-changed={path}");
        }
    }
}
