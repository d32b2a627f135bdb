//! A run folder: the one owner of its names, of what may be written into it, and of who may write.
//!
//! ```text
//! RUN/
//!   scene.ron          the resolved scene the run was trained on
//!   provenance.ron     what made it: coevo's version and the species plugins the run needs
//!   metrics.csv        one row per training episode
//!   checkpoint/        networks, optimizer moments, RNG states, replay buffers (store::checkpoint)
//!   snapshots/         each learning species' actor every `snapshot_every` episodes (store::checkpoint)
//!   eval*.csv          evaluations (`--eval`), each with -nn, -correlation and -confusion files beside
//!   coevo.lock         while a process trains or evaluates it: that process's PID
//! ```
//!
//! User-chosen outputs (`--eval-out`, an experiment's evaluation names) never take a reserved name, and a
//! second process on the same run is refused while the first is alive ([`RunLock`]).

use super::provenance::{binary, Provenance};
use super::schema;
use crate::error::{Kind, ResultExt};
use crate::io::{process_alive, register_temporary, unregister_temporary, Existing};
use std::io::Write;
use std::path::{Path, PathBuf};

/// The trained run shipped with coevo: the default scene's actors (see its README), so a trained swarm is
/// one click away before anything has been trained here.
pub const SHIPPED_RUN: &str = "assets/trained-standard";

/// Every shipped run, first in the picker: the default scene's, then learned prey fleeing rule-based
/// predators in a box (`scenes/confined.ron`).
#[cfg(feature = "viewer")]
pub(crate) const SHIPPED_RUNS: [&str; 2] = [SHIPPED_RUN, "assets/trained-confined"];

pub(crate) const SCENE: &str = "scene.ron";
pub(crate) const PROVENANCE: &str = "provenance.ron";
pub(crate) const METRICS: &str = "metrics.csv";
/// The default evaluation output.
pub(crate) const EVAL: &str = "eval.csv";
pub(crate) const LOCK: &str = "coevo.lock";
/// The run's figures folder.
pub(crate) const FIGURES: &str = "figures";
/// The stem every cross-play output begins with.
pub(crate) const CROSSPLAY: &str = "crossplay";
/// The stem of the cross-play read-outs (`crossplay-readouts.csv`).
pub(crate) const CROSSPLAY_READOUTS: &str = "crossplay-readouts";
/// The stem of every snapshot's rating from the cross-play matrix (`crossplay-ratings.csv`).
pub(crate) const CROSSPLAY_RATINGS: &str = "crossplay-ratings";
/// The checkpoint folders are the checkpoint's own (`store::checkpoint`).
pub(crate) use super::names::{CHECKPOINT, CHECKPOINT_OLD, CHECKPOINT_TMP, SNAPSHOTS};
/// The rules `--distill` fitted to the run's actors (`analysis::distill`).
pub(crate) const DISTILLED: &str = "distilled.ron";
/// The files an evaluation writes beside its per-step CSV (`OUT-nn.csv`, ...); the confusion curve last.
pub(crate) const EVAL_BESIDE: [&str; 4] = ["nn", "correlation", "pursuit", "confusion"];
/// The file a perturbed evaluation writes beside the others (`OUT-perturbation.csv`, [`perturb`]).
pub(crate) const PERTURBATION: &str = "perturbation";

/// The files and folders coevo writes in a run folder and owns.
const RUN_FILES: [&str; 4] = [SCENE, PROVENANCE, METRICS, EVAL];
/// The folders of networks coevo writes in a run folder (safetensors and its state file only).
const CHECKPOINT_DIRS: [&str; 4] = [CHECKPOINT, CHECKPOINT_TMP, CHECKPOINT_OLD, SNAPSHOTS];

/// Whether a file of a run folder is one of the outputs coevo writes there besides the run's own files:
/// evaluations under coevo's names (`eval.csv`, `eval-<name>.csv` and the files beside them) and
/// cross-play (`crossplay*.csv`).
fn outputs_of_the_run(name: &str) -> bool {
    if name == DISTILLED {
        return true;
    }
    let (Some(stem), Some(eval)) = (name.strip_suffix(".csv"), EVAL.strip_suffix(".csv")) else { return false };
    stem == eval || stem.strip_prefix(eval).is_some_and(|rest| rest.starts_with('-')) || stem.starts_with(CROSSPLAY)
}

pub(crate) fn io_err(path: &Path) -> impl Fn(std::io::Error) -> String + '_ {
    move |e| format!("{}: {e}", path.display())
}

/// The file name of an experiment's evaluation named `slug` (a name made folder-safe) in a run folder:
/// `eval-<slug>.csv`, beside the run's own `eval.csv`.
pub(crate) fn evaluation_file_name(slug: &str) -> String {
    format!("{}-{slug}.csv", EVAL.trim_end_matches(".csv"))
}

/// A run folder.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RunDir {
    path: PathBuf,
}

impl RunDir {
    pub fn new(path: impl Into<PathBuf>) -> RunDir {
        RunDir { path: path.into() }
    }

    pub fn path(&self) -> &Path {
        &self.path
    }

    pub fn scene(&self) -> PathBuf {
        self.path.join(SCENE)
    }

    pub fn metrics(&self) -> PathBuf {
        self.path.join(METRICS)
    }

    pub fn checkpoint(&self) -> PathBuf {
        self.path.join(CHECKPOINT)
    }

    /// A species' trained actor in the checkpoint.
    pub fn actor(&self, species: &str) -> PathBuf {
        self.checkpoint().join(super::names::actor_name(species))
    }

    pub(crate) fn provenance(&self) -> PathBuf {
        self.path.join(PROVENANCE)
    }

    /// Figures of the run (`--plot RUN`, `--crossplay RUN`).
    pub(crate) fn figures(&self) -> PathBuf {
        self.path.join(FIGURES)
    }

    /// The file of a named evaluation of an experiment ([`evaluation_file_name`]).
    pub fn evaluation(&self, slug: &str) -> PathBuf {
        self.path.join(evaluation_file_name(slug))
    }

    /// A cross-play output, `<stem>.csv` (`analysis::crossplay`); stems begin with `crossplay`.
    pub(crate) fn crossplay(&self, stem: &str) -> PathBuf {
        debug_assert!(stem.starts_with(CROSSPLAY));
        self.path.join(format!("{stem}.csv"))
    }

    /// The rules fitted to the run's actors ([`DISTILLED`]).
    pub(crate) fn distilled(&self) -> PathBuf {
        self.path.join(DISTILLED)
    }

    pub(crate) fn snapshots(&self) -> PathBuf {
        self.path.join(SNAPSHOTS)
    }

    /// The checkpoint's state (`store::checkpoint::TrainingState`).
    pub(crate) fn state(&self) -> PathBuf {
        self.checkpoint().join(super::names::STATE)
    }

    /// `metrics.csv`'s rows up to the checkpoint whose manifest gives `expected` (the digest of its first
    /// `expected.bytes` bytes): refused in one line where they differ from what was trained (edited, cut
    /// or lost since). Rows after them (episodes trained after the checkpoint) are not returned.
    pub(crate) fn metrics_up_to(&self, expected: &super::manifest::Digest) -> crate::error::Result<String> {
        let text = crate::io::read_text(&self.metrics(), crate::io::MAX_TEXT_BYTES)?;
        Ok(self.rows_as_trained(&text, expected)?.to_string())
    }

    /// The first `expected.bytes` bytes of `text` (the run's `metrics.csv` as read), refused unless they
    /// hash to `expected` ([`RunDir::metrics_up_to`]).
    fn rows_as_trained<'t>(&self, text: &'t str, expected: &super::manifest::Digest) -> crate::error::Result<&'t str> {
        let head = text.get(..expected.bytes as usize).unwrap_or(text);
        if super::manifest::Digest::of(head.as_bytes()) != *expected {
            return Err(format!(
                "{}: its rows up to the checkpoint differ from what was trained (changed, cut or lost since: the checkpoint's manifest hashes them); restore the file or train the run again",
                self.metrics().display()
            )).kind(Kind::RunFolder);
        }
        Ok(head)
    }

    /// The run's `metrics.csv` for plots and summaries, refused in one line unless it is the run's whole
    /// record: every row complete and finite, episodes in order ([`schema::Table::metrics_of`]), the rows
    /// up to the checkpoint as trained ([`RunDir::metrics_up_to`]) and exactly as many as the checkpoint's
    /// episodes. With `partial`, rows after the checkpoint (a run stopped before its next one, or still
    /// without one) and a last row cut short are accepted, and the second value says so.
    pub(crate) fn checked_metrics(&self, partial: bool) -> crate::error::Result<(schema::Table, Option<String>)> {
        (|| -> crate::error::Result<(schema::Table, Option<String>)> {
            // Read once: parsed into the table, and its bytes checked against the manifest.
            let text = crate::io::read_text(&self.metrics(), crate::io::MAX_TEXT_BYTES)?;
            let table = schema::Table::metrics_of(&text, &self.metrics(), partial)?;
            let rows = table.rows.len();
            let shown = self.metrics().display().to_string();
            // A run trained outside coevo (python/examples/ippo.py) has no training state to count against:
            // its rows are whole when every line is.
            if !self.state().exists() && !self.provenance().exists() {
                return Ok((table, None));
            }
            if !self.state().exists() {
                return match partial {
                    true => Ok((table, Some(format!("partial: {rows} episodes, no checkpoint yet")))),
                    false => Err(format!("{shown}: the run has no checkpoint to count its {rows} rows against (stopped before its first); --partial draws them, marked partial").into()),
                };
            }
            let (state, manifest) = super::checkpoint::read_checked_state(&self.checkpoint())?;
            let done = state.episodes_done;
            // The count first (the plainer message), then the rows' bytes against the manifest.
            let counted: crate::error::Result<Option<String>> = match rows.cmp(&done) {
                std::cmp::Ordering::Less => Err(format!(
                    "{shown}: holds {rows} episodes but the checkpoint {done}: rows were lost; restore the file or train the run again"
                )
                .into()),
                std::cmp::Ordering::Greater if !partial => Err(format!(
                    "{shown}: holds {rows} episodes but the checkpoint only {done} (a run stopped after its last checkpoint, or rows added by hand): --resume {} finishes it; --partial draws the rows as they are, marked partial",
                    self.path.display()
                )
                .into()),
                std::cmp::Ordering::Greater => Ok(Some(format!("partial: episodes {done}..{rows} after the last checkpoint"))),
                std::cmp::Ordering::Equal => Ok(None),
            };
            let counted = counted?;
            if let Some(m) = &manifest {
                self.rows_as_trained(&text, &m.metrics)?;
            }
            Ok((table, counted))
        })()
        .kind(Kind::RunFolder)
    }

    /// Whether the run has trained actors to deploy: its scene and a checkpoint (what `--watch` and the
    /// viewer's run picker offer).
    pub(crate) fn has_actors(&self) -> bool {
        self.checkpoint().is_dir() && self.scene().is_file()
    }

    /// Whether the folder holds a run (any of coevo's run files).
    pub(crate) fn is_run(&self) -> bool {
        RUN_FILES.iter().chain(&CHECKPOINT_DIRS).any(|f| self.path.join(f).exists())
    }

    /// The per-step file of an evaluation named `file_name` by the user (default [`EVAL`]): a plain
    /// `NAME.csv` inside the run that takes none of the run's own names, nor the name of another
    /// evaluation's distribution files.
    pub fn eval_output(&self, file_name: Option<&str>) -> crate::error::Result<PathBuf> {
        (|| -> crate::error::Result<PathBuf> {
            let name = file_name.unwrap_or(EVAL);
            let refuse = |why: &str| Err(format!("--eval-out {name}: {why}").into());
            let Some(stem) = name.strip_suffix(".csv") else {
                return refuse("must be a plain file name ending in .csv (written inside the run folder)");
            };
            if let Err(why) = check_name(stem) {
                return refuse(&why.to_string());
            }
            // Reserved by stem, so no output reads as one of the run's own files (scene.csv, checkpoint.csv).
            let stem_of = |f: &str| f.split('.').next().unwrap_or(f).to_string();
            let reserved = RUN_FILES.iter().chain(&CHECKPOINT_DIRS).chain(&[LOCK]).filter(|f| **f != EVAL);
            if reserved.map(|f| stem_of(f)).any(|s| s == stem) {
                return refuse("is one of the run's own files; choose another name");
            }
            if stem.starts_with(CROSSPLAY) {
                return refuse("begins with crossplay, the name of the cross-play files; choose another name");
            }
            if let Some(suffix) = EVAL_BESIDE.iter().chain(&[PERTURBATION]).find(|s| stem.ends_with(&format!("-{s}"))) {
                return refuse(&format!(
                    "ends in -{suffix}, the name of another evaluation's {suffix} file; choose another name"
                ));
            }
            Ok(self.path.join(name))
        })()
        .kind(Kind::Input)
    }

    /// Checks that the folder may receive a new run, changing nothing: a new or empty folder, or (with
    /// `overwrite`) one that holds a run whose checkpoint folders hold only coevo's files.
    pub fn check_new(&self, overwrite: bool) -> crate::error::Result<()> {
        (|| -> crate::error::Result<()> {
            let shown = self.path.display();
            match std::fs::symlink_metadata(&self.path) {
                Err(_) => return Ok(()),
                Ok(m) if !m.is_dir() => return Err(format!("{shown}: exists and is not a folder").into()),
                Ok(_) => {}
            }
            let mut entries = std::fs::read_dir(&self.path).map_err(io_err(&self.path))?;
            if entries.all(|e| e.is_ok_and(|e| e.file_name() == LOCK)) {
                return Ok(());
            }
            if !self.is_run() {
                return Err(format!(
                    "{shown}: is not empty and holds no coevo run; coevo writes runs only into new or empty folders"
                )
                .into());
            }
            if !overwrite {
                return Err(format!(
                    "{shown}: already holds a run; continue it with --resume {shown}, or replace it with --overwrite"
                )
                .into());
            }
            // Outputs of the run being replaced: coevo's own (evaluations, cross-play, figures) go with it;
            // a CSV of another name may be an evaluation saved under a name of the user's, which would
            // describe a run that no longer exists, so it must be moved first.
            for entry in std::fs::read_dir(&self.path).map_err(io_err(&self.path))? {
                let entry = entry.map_err(io_err(&self.path))?;
                let name = entry.file_name().to_string_lossy().into_owned();
                if name.ends_with(".csv") && !RUN_FILES.contains(&name.as_str()) && !outputs_of_the_run(&name) {
                    return Err(format!(
                        "{}: may be an evaluation of the run --overwrite replaces (coevo cannot tell); move it first",
                        entry.path().display()
                    )
                    .into());
                }
            }
            let figures = self.path.join(FIGURES);
            if figures.is_dir() {
                for entry in std::fs::read_dir(&figures).map_err(io_err(&figures))? {
                    let entry = entry.map_err(io_err(&figures))?;
                    let name = entry.file_name().to_string_lossy().into_owned();
                    if !(entry.file_type().is_ok_and(|t| t.is_file())
                        && (name.ends_with(".svg") || name.ends_with(".png")))
                    {
                        return Err(format!(
                            "{}: not a figure coevo drew; --overwrite removes only coevo's files, so move it first",
                            entry.path().display()
                        )
                        .into());
                    }
                }
            }
            for dir in CHECKPOINT_DIRS.iter().map(|d| self.path.join(d)).filter(|d| d.exists()) {
                for entry in std::fs::read_dir(&dir).map_err(io_err(&dir))? {
                    let entry = entry.map_err(io_err(&dir))?;
                    let name = entry.file_name().to_string_lossy().into_owned();
                    let ours = entry.file_type().is_ok_and(|t| t.is_file())
                        && (name.ends_with(".safetensors")
                            || name == super::names::STATE
                            || name == super::manifest::MANIFEST
                            || (name.starts_with('.') && name.ends_with(".tmp")));
                    if !ours {
                        return Err(format!(
                            "{}: not a file coevo wrote; --overwrite removes only coevo's files, so move it first",
                            entry.path().display()
                        )
                        .into());
                    }
                }
            }
            Ok(())
        })()
        .kind(Kind::RunFolder)
    }

    /// Removes the run's own files (after [`RunDir::check_new`] with `overwrite`), keeping the lock.
    pub(crate) fn clear(&self) -> crate::error::Result<()> {
        for dir in CHECKPOINT_DIRS.iter().map(|d| self.path.join(d)).filter(|d| d.exists()) {
            std::fs::remove_dir_all(&dir).map_err(io_err(&dir))?;
        }
        for file in RUN_FILES.iter().map(|f| self.path.join(f)).filter(|f| f.exists()) {
            std::fs::remove_file(&file).map_err(io_err(&file))?;
        }
        // The old run's evaluations, cross-play and figures: they describe a run that is gone.
        for entry in std::fs::read_dir(&self.path).map_err(io_err(&self.path))? {
            let path = entry.map_err(io_err(&self.path))?.path();
            let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
            if outputs_of_the_run(&name) {
                std::fs::remove_file(&path).map_err(io_err(&path))?;
            }
        }
        let figures = self.path.join(FIGURES);
        if figures.is_dir() {
            std::fs::remove_dir_all(&figures).map_err(io_err(&figures))?;
        }
        Ok(())
    }

    /// Refuses a shipped run where it was shipped ([`Provenance::shipped`]): the folder sits at that path
    /// under a source tree (a `Cargo.toml` there). Read leniently, so a damaged `provenance.ron` is left
    /// to whoever reads it for its own purpose (and `--overwrite` may still replace it).
    pub(crate) fn refuse_if_shipped(&self) -> crate::error::Result<()> {
        (|| -> crate::error::Result<()> {
            let Some(at) = self.read_provenance().ok().flatten().and_then(|p| p.shipped) else { return Ok(()) };
            let at_path = Path::new(&at);
            let plain = at_path.components().all(|c| matches!(c, std::path::Component::Normal(_)));
            let Ok(here) = std::fs::canonicalize(&self.path) else { return Ok(()) };
            let root = here.ancestors().nth(at_path.components().count());
            if !plain || !here.ends_with(at_path) || !root.is_some_and(|r| r.join("Cargo.toml").is_file()) {
                return Ok(());
            }
            let shown = self.path.display();
            Err(format!(
                "{shown}: a run shipped with coevo ({at}), kept as committed, so nothing writes into it; copy it \
                 and use the copy, e.g. mkdir -p runs && cp -r {shown} runs/"
            )
            .into())
        })()
        .kind(Kind::RunFolder)
    }

    /// Takes the run's lock for this process (creating the folder if needed), after removing what a
    /// killed process left: a stale lock, temporaries of dead PIDs, a half-written `checkpoint.tmp/`.
    /// Every writer of an existing run takes it, so it refuses a shipped run ([`RunDir::refuse_if_shipped`]).
    pub fn lock(&self) -> crate::error::Result<RunLock> {
        (|| -> crate::error::Result<RunLock> {
            self.refuse_if_shipped()?;
            self.refuse_links()?;
            std::fs::create_dir_all(&self.path).map_err(io_err(&self.path))?;
            let path = self.path.join(LOCK);
            for _ in 0..2 {
                let writing = crate::io::Writing::begin();
                match std::fs::OpenOptions::new().write(true).create_new(true).open(&path) {
                    Ok(mut f) => {
                        register_temporary(&path);
                        if let Err(e) = writeln!(f, "{}", std::process::id()).and_then(|()| f.sync_all()) {
                            // A lock without its PID (a full disk) is not left behind.
                            let _ = std::fs::remove_file(&path);
                            unregister_temporary(&path);
                            return Err(io_err(&path)(e).into());
                        }
                        drop(writing);
                        self.remove_leftovers();
                        return Ok(RunLock { path });
                    }
                    Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {
                        let owner = std::fs::read_to_string(&path).ok().and_then(|t| t.trim().parse::<u32>().ok());
                        match owner {
                            Some(pid) if process_alive(pid) => {
                                return Err(format!(
                                    "{}: in use by coevo process {pid} ({}); wait for it to end, or end it",
                                    self.path.display(),
                                    path.display()
                                )
                                .into())
                            }
                            // A lock of a process that is gone (or half-written by one killed at once): stale.
                            _ => std::fs::remove_file(&path).map_err(io_err(&path))?,
                        }
                    }
                    Err(e) => return Err(io_err(&path)(e).into()),
                }
            }
            Err(format!("{}: could not take the run's lock", path.display()).into())
        })()
        .kind(Kind::RunFolder)
    }

    /// Refuses, before any training, a run whose folders a resumed training rewrites (the run's own,
    /// `checkpoint/` and `snapshots/`) cannot be written: the first checkpoint swap would fail after the
    /// episodes it cost, or leave a `checkpoint.old/` behind. Probed by making and removing a file in
    /// each, which asks the file system itself (permissions, ACLs, a read-only mount), not the mode bits.
    pub(crate) fn check_writable(&self) -> crate::error::Result<()> {
        let probe = format!(".coevo-probe-{}", std::process::id());
        for dir in [self.path.clone(), self.checkpoint(), self.snapshots()] {
            if !dir.is_dir() {
                continue;
            }
            let path = dir.join(&probe);
            let made = std::fs::OpenOptions::new().write(true).create_new(true).open(&path);
            let result = made.and_then(|_| std::fs::remove_file(&path));
            if let Err(e) = result {
                let _ = std::fs::remove_file(&path);
                return Err(format!(
                    "{}: cannot be written ({e}); resuming replaces the checkpoint there: make it writable (chmod -R u+w {})",
                    dir.display(),
                    self.path.display()
                ))
                .kind(Kind::RunFolder);
            }
        }
        Ok(())
    }

    /// Refuses a run whose own folders (checkpoints, snapshots, figures) are symbolic links: coevo writes
    /// into them, and would write into whatever they point to (another run, a user's folder).
    fn refuse_links(&self) -> crate::error::Result<()> {
        for name in CHECKPOINT_DIRS.iter().chain(&[FIGURES]) {
            let path = self.path.join(name);
            if std::fs::symlink_metadata(&path).is_ok_and(|m| m.file_type().is_symlink()) {
                return Err(format!(
                    "{}: is a symbolic link; coevo writes only into real folders it owns, never through a link: remove the link",
                    path.display()
                )
                .into());
            }
        }
        Ok(())
    }

    /// What killed processes left behind (only called with the lock held, so nobody is writing): a
    /// half-written `checkpoint.tmp/`, a `checkpoint.old/` of a swap cut short (put back where the
    /// checkpoint is missing, removed where the new one is whole), temporaries of dead PIDs.
    fn remove_leftovers(&self) {
        let _ = std::fs::remove_dir_all(self.path.join(CHECKPOINT_TMP));
        super::checkpoint::finish_swap(&self.path);
        crate::io::remove_stale_temporaries(&self.path, None);
        crate::io::remove_stale_temporaries(&self.checkpoint(), None);
        crate::io::remove_stale_temporaries(&self.path.join(SNAPSHOTS), None);
    }

    /// Writes what made the run: the version and the species plugins its scene needs.
    pub(crate) fn write_provenance(&self, scene: &crate::scene::Scene) -> crate::error::Result<()> {
        let provenance = Provenance::of(scene);
        let text = ron::ser::to_string_pretty(&provenance, ron::ser::PrettyConfig::new().struct_names(false))
            .map_err(|e| format!("{}: {e}", self.provenance().display()))?;
        crate::io::write_file(&self.provenance(), Existing::Replace, format!("{text}\n").as_bytes())
    }

    /// The run's provenance, None for runs older than provenance files.
    pub(crate) fn read_provenance(&self) -> crate::error::Result<Option<Provenance>> {
        let path = self.provenance();
        if !path.exists() {
            return Ok(None);
        }
        let text = crate::io::read_text(&path, crate::io::MAX_TEXT_BYTES)?;
        Ok(Some(ron::from_str(&text).map_err(|e| format!("{}: damaged ({e})", path.display()))?))
    }

    /// Records that this executable, not the run's creator, resumes or evaluates the run (once per
    /// executable). Runs older than provenance files are left alone.
    pub(crate) fn note_binary(&self) -> crate::error::Result<()> {
        let Some(mut p) = self.read_provenance()? else { return Ok(()) };
        if p.binaries().contains(&binary()) {
            return Ok(());
        }
        p.also_by.push(binary().to_string());
        let text = ron::ser::to_string_pretty(&p, ron::ser::PrettyConfig::new().struct_names(false))
            .map_err(|e| format!("{}: {e}", self.provenance().display()))?;
        crate::io::write_file(&self.provenance(), Existing::Replace, format!("{text}\n").as_bytes())
    }

    /// Refuses to continue training on another family of matrix-product kernels than the run began on:
    /// the continuation would differ in the last bits from the uninterrupted run.
    pub(crate) fn check_kernels(&self) -> crate::error::Result<()> {
        (|| -> crate::error::Result<()> {
            use crate::learning::nets::Kernels;
            let now = crate::learning::nets::kernels();
            match self.read_provenance()? {
                Some(p) if !p.kernels.is_empty() && Kernels::parse(&p.kernels) != Some(now) => Err(format!(
                    "{}: the run was trained on {} kernels and this machine runs {now}; continued here it would differ from an uninterrupted run (provenance.ron)",
                    self.path.display(),
                    p.kernels
                )
                .into()),
                _ => Ok(()),
            }
        })()
        .kind(Kind::RunFolder)
    }

    /// Refuses a run that needs species plugins this program does not have (resumed or evaluated by a
    /// binary without the plugin, its species would lose their systems). Runs older than provenance files
    /// need none.
    pub(crate) fn check_plugins(&self) -> crate::error::Result<()> {
        (|| -> crate::error::Result<()> {
            let Some(p) = self.read_provenance()? else { return Ok(()) };
            match p.plugins.iter().find(|name| crate::sim::species::catalog::get(name).is_none()) {
                Some(name) => Err(format!(
                    "{}: the run needs the species plugin {name:?}, which this program does not have; use the program that trained it (e.g. cargo run --release --example {name})",
                    self.path.display()
                ).into()),
                None => Ok(()),
            }
        })()
        .kind(Kind::RunFolder)
    }
}

/// Whether a folder holds a run.
pub(crate) fn is_run(dir: &Path) -> bool {
    RunDir::new(dir).is_run()
}

/// A run's lock, held while this process writes the run; removed when dropped (and on a signal).
#[derive(Debug)]
pub struct RunLock {
    path: PathBuf,
}

impl RunLock {
    /// Whether the run folder is still the one this lock was taken in: its lock file there, holding this
    /// process's PID. A folder removed (or replaced) under a training would otherwise be recreated with
    /// only what is written after, a folder that is no run.
    pub(crate) fn held(&self) -> crate::error::Result<()> {
        let ours = match std::fs::read_to_string(&self.path) {
            Ok(text) => text.trim() == std::process::id().to_string(),
            // A lock that cannot be read (no file descriptor left, say) is not a lock that is gone.
            Err(e) if e.kind() != std::io::ErrorKind::NotFound => {
                return Err(crate::error::Error::from(format!("{}: {e}", self.path.display())).of_kind(Kind::Io))
            }
            Err(_) => false,
        };
        if ours {
            return Ok(());
        }
        let run = self.path.parent().unwrap_or(Path::new("."));
        Err(crate::error::Error::from(format!(
            "{}: removed or replaced while this process was writing it (its lock {} is gone); stopped, nothing more written",
            run.display(),
            self.path.display()
        ))
        .of_kind(Kind::RunFolder))
    }
}

impl Drop for RunLock {
    fn drop(&mut self) {
        let _writing = crate::io::Writing::begin();
        let _ = std::fs::remove_file(&self.path);
        unregister_temporary(&self.path);
    }
}

/// Checks that a user-chosen name (an experiment, a variant's or an evaluation's folder-safe slug, an
/// output stem) is one safe path component: not empty, no separator, no leading dot (so never `.`, `..`
/// or a hidden file), no control character.
pub(crate) fn check_name(name: &str) -> crate::error::Result<()> {
    if name.is_empty() {
        return Err("must not be empty".into());
    }
    if name.contains(['/', '\\']) || name.chars().any(char::is_control) {
        return Err("must be a single name: no path separator or control character".into());
    }
    if name.starts_with('.') {
        return Err(
            "must not start with a dot (., .. and hidden names would leave or hide in the results folder)".into()
        );
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn eval_outputs_never_take_the_runs_own_names() {
        let run = RunDir::new("/tmp/some-run");
        assert_eq!(run.eval_output(None).unwrap(), Path::new("/tmp/some-run/eval.csv"));
        assert!(run.eval_output(Some("eval-50-prey.csv")).is_ok());
        for bad in [
            "metrics.csv",
            "scene.csv",
            "checkpoint.csv",
            "coevo.csv",
            "x-confusion.csv",
            "x-nn.csv",
            "../x.csv",
            ".x.csv",
            "x.ron",
            "a/b.csv",
            ".csv",
        ] {
            assert!(run.eval_output(Some(bad)).is_err(), "{bad}");
        }
    }

    #[test]
    fn a_second_lock_is_refused_and_a_stale_one_taken_over() {
        let dir = tempfile::tempdir().unwrap();
        let run = RunDir::new(dir.path().join("run"));
        let held = run.lock().unwrap();
        assert!(run.lock().unwrap_err().to_string().contains("in use by coevo process"));
        drop(held);
        assert!(!dir.path().join("run").join(LOCK).exists());
        // A PID that cannot be alive.
        std::fs::write(dir.path().join("run").join(LOCK), "4294967295\n").unwrap();
        std::fs::write(dir.path().join("run").join(".metrics.csv.4294967295.tmp"), "half").unwrap();
        let _held = run.lock().unwrap();
        assert!(
            !dir.path().join("run").join(".metrics.csv.4294967295.tmp").exists(),
            "a dead process's temporary is removed"
        );
    }
}
