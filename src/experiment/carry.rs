//! Finished runs carried from machine to machine. Run folders are not committed (they are one machine's),
//! so what outlives a machine is an experiment's committed `summary.csv` (a row per finished run) and
//! `figure-data.ron.gz` (its curves). `runs.csv` beside them records the scene each row was trained on
//! and the evaluations it holds ([`identity`]).
//! A run whose folder is not here but whose row is committed, of the scene the experiment file gives it
//! now, is finished: the runner skips it, and aggregation carries its row and curves, byte for byte,
//! beside the rows it writes from the folders that are here. An experiment run over several sessions or
//! machines thus loses nothing it finished, and its summary is the one a single machine would write.

use super::figure_data::{self, FigureData};
use super::file::Experiment;
use super::results::RunData;
use super::summary::{csv_text, Summary};
use std::collections::{BTreeMap, BTreeSet};
use std::fmt::Write as _;

/// The record of which scene each committed row was trained on, beside `summary.csv`.
pub(crate) const FILE: &str = "runs.csv";

/// What a committed row is a row of, as one word: the first 16 hex digits of the BLAKE3 hash of the run's
/// scene (seed included) and of what the experiment asks of a finished run: each evaluation's name,
/// episodes, what its actors see, whether it deploys untrained actors, its perturbation and the scene it
/// is evaluated in, and the cross-play's episodes. A row is carried only while the experiment file asks for the same.
pub(crate) fn identity(exp: &Experiment, run: &super::file::Run) -> String {
    let mut what = run.scene.to_ron();
    for e in &exp.spec.evaluations {
        // Added to the words only when set, so the identities of rows recorded before it stay valid.
        if e.untrained {
            what.push_str("\nuntrained");
        }
        let mut evaluated = run.scene.clone();
        // The overrides were applied when the experiment was loaded: they cannot fail here.
        let _ = e.overrides().apply(&mut evaluated, std::path::Path::new(""));
        write!(
            what,
            "\nevaluation {:?}: {} episodes, {:?}, {:?} at {:?}\n{}",
            e.name,
            e.episodes,
            e.control,
            e.perturb,
            e.perturb_step,
            evaluated.to_ron()
        )
        .unwrap();
    }
    if let Some(c) = &exp.spec.crossplay {
        write!(what, "\ncross-play: {} episodes", c.episodes).unwrap();
    }
    blake3::hash(what.as_bytes()).to_hex()[..16].to_string()
}

/// `runs.csv` for the rows of a summary (`runs`: indices into the experiment's runs, in the summary's
/// order, each with the family of matrix-product kernels it ran on, empty when not known): each run's key,
/// the identity of its scene and its kernels.
pub(crate) fn text(exp: &Experiment, runs: impl Iterator<Item = (usize, String)>) -> String {
    let mut out = String::from("preset,variant,seed,scene,kernels\n");
    for (i, kernels) in runs {
        let r = &exp.runs[i];
        let (preset, variant, scene) = (csv_text(&r.preset), csv_text(&r.variant), identity(exp, r));
        writeln!(out, "{preset},{variant},{},{scene},{}", r.seed, csv_text(&kernels)).unwrap();
    }
    out
}

/// What `runs.csv` records of a committed run.
#[derive(Clone, Debug, Default, PartialEq)]
pub(crate) struct Record {
    /// Its [`identity`].
    pub(crate) scene: String,
    /// The family of matrix-product kernels it ran on; empty when not recorded (a `runs.csv` written
    /// before the column).
    pub(crate) kernels: String,
}

/// What `runs.csv` records of each committed run, by run index; empty without the file.
fn recorded(exp: &Experiment) -> crate::error::Result<BTreeMap<usize, Record>> {
    let path = exp.root.join(FILE);
    if !path.exists() {
        return Ok(BTreeMap::new());
    }
    let text = crate::io::read_text(&path, crate::io::MAX_TEXT_BYTES)?;
    let bad = |e: csv::Error| format!("{}: {e}", path.display());
    let mut out = BTreeMap::new();
    for record in csv::Reader::from_reader(text.as_bytes()).records() {
        let record = record.map_err(bad)?;
        let (Some(preset), Some(variant), Some(seed), Some(scene)) =
            (record.get(0), record.get(1), record.get(2), record.get(3))
        else {
            return Err(format!("{}: a row without preset, variant, seed and scene", path.display()).into());
        };
        let seed: u64 = seed.parse().map_err(|_| format!("{}: seed {seed:?}", path.display()))?;
        if let Some(i) = exp.runs.iter().position(|r| r.preset == preset && r.variant == variant && r.seed == seed) {
            let kernels = record.get(4).unwrap_or_default().to_string();
            out.insert(i, Record { scene: scene.to_string(), kernels });
        }
    }
    Ok(out)
}

/// Why a committed run cannot be carried; None when it can (its row is of the scene the experiment file
/// gives it now).
fn uncarriable(exp: &Experiment, i: usize, recorded: &BTreeMap<usize, Record>) -> Option<String> {
    let key = figure_data::key(&exp.runs[i]);
    match recorded.get(&i) {
        None => Some(format!(
            "{key} has a committed row but no line in {} (aggregated by a coevo before it), so which scene it was trained on is not known",
            FILE
        )),
        Some(r) if r.scene != identity(exp, &exp.runs[i]) => Some(format!(
            "{key}'s committed row is of another scene or evaluations than {} asks for now",
            exp.file.display()
        )),
        Some(_) => None,
    }
}

/// A run finished on another machine: the binaries that made it and the kernels it ran on (empty when
/// not recorded).
#[derive(Clone, Debug)]
pub(crate) struct Elsewhere {
    pub(crate) binary: String,
    pub(crate) kernels: String,
}

/// The runs finished on another machine: a committed row of the scene and evaluations the experiment
/// file gives it now, with its curves in the committed figure data, and no folder here (a folder here is
/// resumed or rerun, and aggregated when it is finished). An experiment whose committed rows cannot be
/// carried has none, so the runner runs them again.
pub(crate) fn finished_elsewhere(exp: &Experiment) -> crate::error::Result<BTreeMap<usize, Elsewhere>> {
    let Some(summary) = Summary::read(&exp.summary_path())? else { return Ok(BTreeMap::new()) };
    // A summary without every column written now (an older coevo's) carries nothing: its runs are rerun.
    let header = super::summary::header(&super::summary::columns(exp));
    if header.iter().any(|c| !summary.columns.contains(c)) {
        return Ok(BTreeMap::new());
    }
    let recorded = recorded(exp)?;
    let elsewhere: BTreeMap<usize, Elsewhere> = summary
        .runs(exp)
        .into_iter()
        .filter(|&(i, _)| !crate::store::is_run(&exp.runs[i].dir) && uncarriable(exp, i, &recorded).is_none())
        .map(|(i, row)| (i, Elsewhere { binary: row.binary.clone(), kernels: recorded[&i].kernels.clone() }))
        .collect();
    let indices: Vec<usize> = elsewhere.keys().copied().collect();
    match figure_data::read(exp, &indices) {
        Ok(Some(_)) => Ok(elsewhere),
        _ if indices.is_empty() => Ok(elsewhere),
        _ => Ok(BTreeMap::new()),
    }
}

/// The committed runs of the experiment file (rows of its committed summary.csv), by run index.
pub(crate) fn committed_runs(exp: &Experiment) -> crate::error::Result<BTreeSet<usize>> {
    Ok(Summary::read(&exp.summary_path())?
        .map_or(BTreeSet::new(), |s| s.runs(exp).into_iter().map(|(i, _)| i).collect()))
}

/// What aggregation carries of the committed results: the summary line and the figure data of each
/// committed run whose folder is not among `data`, by run index.
#[derive(Default)]
pub(crate) struct Carried {
    pub(crate) lines: BTreeMap<usize, String>,
    pub(crate) figures: BTreeMap<usize, FigureData>,
    /// The kernels each ran on, as `runs.csv` records them.
    pub(crate) kernels: BTreeMap<usize, String>,
}

/// The committed runs of `exp` that `data` (the run folders here) lacks, carried as [`Carried`] into a
/// summary of columns `header`. Refused, in one line naming the run and why, when one cannot be carried
/// (no record of its scene, another scene, a column or figure data missing, another binary or family of
/// kernels): then aggregating would drop a finished run or mix it with others.
pub(crate) fn carried(
    exp: &Experiment,
    data: &BTreeMap<usize, RunData>,
    header: &[String],
) -> crate::error::Result<Carried> {
    let path = exp.summary_path();
    if data.is_empty() || !path.exists() {
        return Ok(Carried::default());
    }
    let text = crate::io::read_text(&path, crate::io::MAX_TEXT_BYTES)?;
    let summary = Summary::parse(&text, &path)?;
    // A run twice in the summary (two machines' rows merged by hand) is carried once.
    let missing: Vec<usize> = summary
        .runs(exp)
        .into_iter()
        .map(|(i, _)| i)
        .filter(|i| !data.contains_key(i))
        .collect::<BTreeSet<usize>>()
        .into_iter()
        .collect();
    if missing.is_empty() {
        return Ok(Carried::default());
    }
    let refuse = |why: String| -> crate::error::Error {
        format!(
            "{}: holds {} runs not finished here (no folder, or evaluations still to come), and {why}; nothing written: run `coevo --experiment {}` to rebuild them, or move the summary away",
            path.display(),
            missing.len(),
            exp.file.display()
        )
        .into()
    };
    let recorded = recorded(exp)?;
    if let Some(why) = missing.iter().find_map(|&i| uncarriable(exp, i, &recorded)) {
        return Err(refuse(why));
    }
    // The same runs (one binary), unless the experiment allows more.
    if !exp.spec.mixed_binaries {
        let here: BTreeSet<&str> = data.values().flat_map(|d| d.binaries.iter().map(String::as_str)).collect();
        for (i, row) in summary.runs(exp).into_iter().filter(|(i, _)| missing.contains(i)) {
            let pin = exp.pin.as_ref();
            if let Some(other) = row.binary.split(' ').find(|b| !here.iter().any(|h| super::pin::Pin::same(pin, h, b)))
            {
                return Err(format!(
                    "{}: runs of more than one binary (the committed {} by {other}, the run folders here by {}); rerun them with one coevo or set mixed_binaries: true",
                    exp.file.display(),
                    figure_data::key(&exp.runs[i]),
                    here.iter().copied().collect::<Vec<_>>().join(" ")
                )
                .into());
            }
        }
        // And the same kernels: one binary computes other numbers on another family (a variant on its own
        // family, `kernels:`, is held to that one when aggregated).
        let here: BTreeSet<&str> = data
            .iter()
            .filter(|&(&i, d)| !d.kernels.is_empty() && exp.runs[i].kernels.is_none())
            .map(|(_, d)| d.kernels.as_str())
            .collect();
        for &i in missing.iter().filter(|&&i| exp.runs[i].kernels.is_none()) {
            let theirs = recorded[&i].kernels.as_str();
            if !theirs.is_empty() && here.iter().any(|k| *k != theirs) {
                return Err(format!(
                    "{}: runs on more than one family of matrix-product kernels (the committed {} on {theirs}, the run folders here on {}); continue on one (COEVO_KERNELS or --kernels) or set mixed_binaries: true",
                    exp.file.display(),
                    figure_data::key(&exp.runs[i]),
                    here.iter().copied().collect::<Vec<_>>().join(" ")
                )
                .into());
            }
        }
    }
    // Each carried line in the columns written now, its cells as committed (names quoted as written).
    let mut reader = csv::Reader::from_reader(text.as_bytes());
    let committed: Vec<String> =
        reader.headers().map_err(|e| format!("{}: {e}", path.display()))?.iter().map(String::from).collect();
    let at: Vec<usize> = header
        .iter()
        .map(|c| {
            committed
                .iter()
                .position(|k| k == c)
                .ok_or_else(|| refuse(format!("its summary has no column {c} (written by another coevo)")))
        })
        .collect::<crate::error::Result<_>>()?;
    let rows = summary.runs(exp);
    let mut lines = BTreeMap::new();
    for (record, row) in reader.records().zip(&summary.rows) {
        let record = record.map_err(|e| format!("{}: {e}", path.display()))?;
        let Some(&(i, _)) = rows.iter().find(|(_, r)| std::ptr::eq(*r, row)) else { continue };
        if !missing.contains(&i) {
            continue;
        }
        let cells: Vec<String> = header.iter().zip(&at).map(|(_, &k)| csv_text(&record[k])).collect();
        lines.insert(i, cells.join(","));
    }
    let figures = figure_data::read(exp, &missing)
        .map_err(|e| refuse(e.to_string()))?
        .ok_or_else(|| refuse(format!("there is no {} to carry their curves from", figure_data::FILE)))?;
    let kernels = missing.iter().map(|&i| (i, recorded[&i].kernels.clone())).collect();
    Ok(Carried { lines, figures, kernels })
}
