//! What made a run (`RUN/provenance.ron`): coevo's version and commit, the kernels, the species plugins
//! it needs, and every executable that wrote into it, so "runs of one binary" can be checked.

use serde::{Deserialize, Serialize};

/// What made a run (`provenance.ron`), written when the run is created. Fields a coevo before them did
/// not write read as empty.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct Provenance {
    pub(crate) coevo_version: String,
    /// The commit the binary was built from (`git describe --always --dirty`).
    #[serde(default)]
    pub(crate) git_commit: String,
    /// The matrix-product kernels it ran on ([`crate::learning::nets::kernels`]).
    #[serde(default)]
    pub(crate) kernels: String,
    /// Worker threads when the run was created (results never depend on them).
    #[serde(default)]
    pub(crate) threads: usize,
    /// Species of the scene that come from species plugins of the program that trained it.
    pub(crate) plugins: Vec<String>,
    /// The executable that created the run ([`binary`]).
    #[serde(default)]
    pub(crate) binary: String,
    /// Other executables that later resumed or evaluated it, in order: a run with any is not a run of
    /// one binary, which the experiment layer refuses to compare unless told (`mixed_binaries`).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub(crate) also_by: Vec<String>,
    /// Where a run shipped with coevo sits in the source tree (`assets/trained-standard`): there it is
    /// kept as committed, so nothing writes into it (evaluations, cross-play, resumed training and
    /// `--plot` refuse it, [`RunDir::refuse_if_shipped`]); a copy anywhere else is an ordinary run.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(crate) shipped: Option<String>,
}

/// The running executable's identity: the first 16 hex digits of the BLAKE3 hash of its file (`blake3`
/// crate), or `unknown` where it cannot be read. Two builds differ here even when their commit names agree
/// (a `-dirty` tree), so "one binary" means one file.
pub fn binary() -> &'static str {
    static BINARY: std::sync::OnceLock<String> = std::sync::OnceLock::new();
    BINARY.get_or_init(|| std::env::current_exe().and_then(|exe| file_hash(&exe)).unwrap_or_else(|_| "unknown".into()))
}

/// The first 16 hexadecimal digits of a file's BLAKE3 hash: how provenance names an executable (and a
/// pinned experiment its binaries and `Cargo.lock`).
pub(crate) fn file_hash(path: &std::path::Path) -> std::io::Result<String> {
    Ok(super::manifest::Digest::of_file(path)?.blake3[..16].to_string())
}

impl Provenance {
    /// Every executable that wrote into the run: its creator, then the others.
    pub(crate) fn binaries(&self) -> Vec<&str> {
        let creator = if self.binary.is_empty() { "unknown" } else { self.binary.as_str() };
        std::iter::once(creator).chain(self.also_by.iter().map(String::as_str)).collect()
    }

    pub(crate) fn of(scene: &crate::scene::Scene) -> Provenance {
        Provenance {
            binary: binary().to_string(),
            also_by: vec![],
            shipped: None,
            coevo_version: crate::VERSION.to_string(),
            git_commit: crate::GIT_COMMIT.to_string(),
            kernels: crate::learning::nets::kernels().to_string(),
            threads: crate::parallel::threads(),
            plugins: scene
                .species
                .iter()
                .filter(|d| crate::sim::species::catalog::get(&d.name).is_some())
                .map(|d| d.name.clone())
                .collect(),
        }
    }
}

/// How a printed command should spell coevo so that it runs where the user is: `coevo` when that name on
/// the `PATH` is this executable (installed with `cargo install`), else this executable's path, relative
/// to the working folder when inside it (`target/release/coevo` after `cargo run --release`).
pub(crate) fn spelled() -> String {
    let Some(exe) = std::env::current_exe().ok().and_then(|e| std::fs::canonicalize(e).ok()) else {
        return "coevo".into();
    };
    let on_path = std::env::var_os("PATH").is_some_and(|path| {
        std::env::split_paths(&path).any(|dir| std::fs::canonicalize(dir.join("coevo")).is_ok_and(|found| found == exe))
    });
    if on_path {
        return "coevo".into();
    }
    let here = std::env::current_dir().ok().and_then(|d| std::fs::canonicalize(d).ok());
    let shown = here.and_then(|d| exe.strip_prefix(d).ok().map(std::path::Path::to_path_buf)).unwrap_or(exe);
    let shown = shown.to_string_lossy().into_owned();
    shlex::try_quote(&shown).map_or(shown.clone(), |q| q.into_owned())
}

/// A run's behavioural fingerprint: the first 16 hex digits of a BLAKE3 hash over its `metrics.csv` with
/// the `wall_seconds` column left out and over every file of its checkpoint but the manifest (which hashes
/// the metrics with their wall clock), by name; a replay segment as written with every next observation
/// (`replay_segments::hash_with_every_next_observation`), however it is stored. Two binaries built from one commit differ as files (codegen
/// is not byte-reproducible) but compute the same numbers; the same short training by both gives the same
/// fingerprint, which is how a pinned experiment's binary is rebuilt instead of kept in git
/// (docs/src/guide/experiments.md, "Pinned binaries").
pub fn fingerprint(run: &std::path::Path) -> crate::error::Result<String> {
    let dir = super::RunDir::new(run);
    if !dir.is_run() {
        return Err(format!("{}: holds no coevo run to fingerprint", run.display()).into());
    }
    let mut hasher = blake3::Hasher::new();
    let metrics = crate::io::read_text(&dir.metrics(), crate::io::MAX_TEXT_BYTES)?;
    let mut lines = metrics.lines();
    let header: Vec<&str> = lines.next().unwrap_or_default().split(',').collect();
    let wall = header.iter().position(|c| *c == super::schema::WALL_SECONDS);
    for line in std::iter::once(header.join(",")).chain(lines.map(str::to_string)) {
        let kept: Vec<&str> = line.split(',').enumerate().filter(|(i, _)| Some(*i) != wall).map(|(_, c)| c).collect();
        hasher.update(kept.join(",").as_bytes());
        hasher.update(b"\n");
    }
    let checkpoint = dir.checkpoint();
    let mut files: Vec<std::path::PathBuf> = std::fs::read_dir(&checkpoint)
        .map_err(|e| format!("{}: {e}", checkpoint.display()))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.is_file() && p.file_name().is_some_and(|n| n != super::manifest::MANIFEST))
        .collect();
    files.sort();
    for path in files {
        hasher.update(path.file_name().unwrap_or_default().as_encoded_bytes());
        let cannot = |e: std::io::Error| format!("{}: cannot read: {e}", path.display());
        let name = path.file_name().unwrap_or_default().to_string_lossy();
        if super::names::parse_segment_name(&name).is_some() {
            // As written with every next observation, whichever way it is stored.
            super::replay_segments::hash_with_every_next_observation(&path, &mut hasher).map_err(cannot)?;
            continue;
        }
        let mut file = crate::io::open_input(&path).map_err(cannot)?;
        std::io::copy(&mut file, &mut hasher).map_err(cannot)?;
    }
    Ok(hasher.finalize().to_hex()[..16].to_string())
}
