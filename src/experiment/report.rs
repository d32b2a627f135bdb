//! What an experiment reports, and the orchestration of `--experiment` and `--plot`: REPRODUCTION.md over
//! the project's experiment files, an experiment's own summaries and figures otherwise.

use super::claims::{p_shown, quantity_name, ClaimResult};
use super::file::{Experiment, Quantity, EVAL_ORDER, EVAL_ORDER_DIGITS, EVAL_ORDER_LABELS};
use super::runner;
use super::{aggregate, data, figures, summary};
use crate::io::Existing;
use crate::sim::metrics::Swarming;
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// Where experiments are read and their runs written.
const EXPERIMENTS: &str = "experiments";
const RESULTS: &str = "results";

/// What `--experiment` was asked.
pub struct Request<'a> {
    /// An experiment file, or `all` of `experiments/`.
    pub which: &'a str,
    /// Runs at a time [default 2].
    pub jobs: Option<usize>,
    /// Only this run (a Slurm array task).
    pub task: Option<usize>,
    /// Write Slurm scripts instead of running.
    pub emit_slurm: bool,
    pub quiet: bool,
}

/// `--experiment FILE|all`: run, evaluate and aggregate; then REPRODUCTION.md from every experiment's
/// results so far (the project's experiment files), or the experiment's own summaries (any other file).
pub fn experiment(request: &Request) -> crate::error::Result<()> {
    let which = request.which;
    let files = match which {
        "all" => Experiment::files(Path::new(EXPERIMENTS))?,
        file => vec![PathBuf::from(file)],
    };
    let experiments = files.iter().map(|f| Experiment::load(f, Path::new(RESULTS))).collect::<Result<Vec<_>, _>>()?;
    if request.jobs == Some(0) {
        return Err("--jobs: must be ≥ 1 (got 0)".into());
    }
    if let Some(task) = request.task {
        match experiments.as_slice() {
            [exp] if task < exp.runs.len() => {}
            [exp] => {
                return Err(format!("--task {task}: {} has runs 0 to {}", exp.file.display(), exp.runs.len() - 1).into())
            }
            _ => return Err("--task: names a run of one experiment file, not of `all`".into()),
        }
    }
    if request.emit_slurm {
        if request.task.is_some() {
            return Err("--task: not used by --emit-slurm, which writes a job for every run".into());
        }
        let exe = std::env::current_exe().map_err(|e| format!("cannot find the coevo binary: {e}"))?;
        for exp in &experiments {
            let dir = runner::emit_slurm(exp, &exe)?;
            // Quoted as the scripts quote it, so the line can be pasted into a shell as it is.
            let submit = dir.join("submit.sh").to_string_lossy().into_owned();
            let submit = shlex::try_quote(&submit).map_or(submit.clone(), |q| q.into_owned());
            crate::outln!("{}: {} runs; submit with: bash {submit}", exp.name, exp.runs.len())?;
        }
        return Ok(());
    }
    let opts = runner::RunnerOptions {
        exe: std::env::current_exe().map_err(|e| format!("cannot find the coevo binary: {e}"))?,
        jobs: request.jobs.unwrap_or(2),
        progress: !request.quiet,
    };
    // Every experiment is attempted; the one error line names the first failure.
    let failed: Vec<crate::error::Error> =
        experiments.iter().filter_map(|exp| runner::run(exp, &opts, request.task).err()).collect();
    if let Some(first) = failed.first() {
        let others = match failed.len() {
            1 => String::new(),
            n => format!("; {} more experiments failed", n - 1),
        };
        let kept = if which == "all" { " (REPRODUCTION.md left as it was)" } else { "" };
        return Err(format!("{first}{others}{kept}").into());
    }
    if request.task.is_some() {
        return Ok(());
    }
    // REPRODUCTION.md is the suite's: written when asked for `all`; one experiment reports alone.
    if which == "all" {
        return write_reproduction();
    }
    for exp in experiments {
        let data = data::load(&exp)?;
        report(exp, &data)?;
    }
    Ok(())
}

/// Summaries, figures and REPORT.md of every experiment of `experiments/`, and REPRODUCTION.md over all of
/// them.
pub fn write_reproduction() -> crate::error::Result<()> {
    // Everything loaded and checked before anything is written.
    let mut loaded = Vec::new();
    for file in Experiment::files(Path::new(EXPERIMENTS))? {
        let exp = Experiment::load(&file, Path::new(RESULTS))?;
        // An experiment whose file asks for evaluations other than its runs hold is reported from its
        // committed summary until it is run again; the others are still reported.
        let mut data = match runner::first_stale(&exp) {
            Some(stale) => {
                crate::errln!(
                    "coevo: {stale}; run `coevo --experiment {}` to redo it (reported from the committed summary)",
                    exp.file.display()
                )?;
                BTreeMap::new()
            }
            None => data::load(&exp)?,
        };
        // An experiment being re-run (fewer run folders than its committed summary holds) is reported from
        // its committed summary.csv, and its files are left as they are, until its runs are all back.
        if let Err(e) = data::check_complete(&exp, &data) {
            crate::errln!("coevo: {e} (reported from the committed summary)")?;
            data.clear();
        }
        loaded.push((exp, data));
    }
    let mut all = Vec::new();
    for (exp, data) in loaded {
        all.push(report(exp, &data)?);
    }
    crate::io::write_file(Path::new("REPRODUCTION.md"), Existing::Replace, reproduction(&all).as_bytes())?;
    crate::errln!("coevo: wrote REPRODUCTION.md")?;
    Ok(())
}

/// One experiment's claims checked, from its run folders (writing its summaries and figures) or, in a
/// clone without them, from its committed summary.csv; then its REPORT.md, which holds only what the
/// summary holds, so a clone regenerates it byte for byte. Says on stderr exactly what it wrote.
fn report(exp: Experiment, data: &BTreeMap<usize, super::claims::RunData>) -> crate::error::Result<Reported> {
    let aggregate::Aggregated { results, summary, figures, from_folders } = aggregate::aggregate(&exp, data)?;
    let wall = summary.columns.iter().position(|c| c == "wall_seconds");
    // + 0.0: an empty f64 sum is −0.0, which would print as "-0.0 h".
    // Shared runs are another experiment's trainings: counted there.
    let own = || summary.rows.iter().filter(|r| r.shared_from.is_empty());
    let seconds: f64 = own().filter_map(|r| wall.map(|i| r.values[i])).filter(|x| x.is_finite()).sum::<f64>() + 0.0;
    let shared = summary.rows.len() - own().count();
    let mut binaries: Vec<String> = summary.rows.iter().flat_map(|r| r.binary.split(' ').map(String::from)).collect();
    binaries.sort();
    binaries.dedup();
    let reported = Reported { finished: summary.rows.len(), shared, exp, results, seconds, binaries, summary };
    let root = &reported.exp.root;
    let path = root.join(REPORT);
    std::fs::create_dir_all(root).map_err(|e| format!("{}: {e}", root.display()))?;
    crate::io::write_file(&path, Existing::Replace, experiment_report(&reported).as_bytes())?;
    let drawn = |n: usize| {
        format!("{n} figure{} (.svg and .png) in {}/figures/", if n == 1 { "" } else { "s" }, root.display())
    };
    match (from_folders, figures) {
        (true, n) => crate::errln!(
            "coevo: wrote {0}/summary.csv, {0}/summary-mean.csv, {0}/{1}, {0}/{REPORT} and {2} ({3} claims checked)",
            root.display(),
            super::figure_data::FILE,
            drawn(n.unwrap_or(0)),
            reported.results.len()
        )?,
        (false, Some(n)) => crate::errln!(
            "coevo: wrote {} and {} from the committed summary.csv and {} (its runs' folders are not all here: the summaries left as they are)",
            path.display(),
            drawn(n),
            super::figure_data::FILE
        )?,
        (false, None) => crate::errln!(
            "coevo: wrote {} from the committed summary.csv (its runs' folders are not all here, and it has no {}: summaries and figures left as they are)",
            path.display(),
            super::figure_data::FILE
        )?,
    }
    Ok(reported)
}

/// `--plot DIR`: an experiment's summaries, figures and REPORT.md, or one run's learning curves, from CSVs
/// alone.
/// With `partial`, a run stopped after its last checkpoint, or an experiment whose runs are not all
/// finished, is drawn from what there is (marked partial); without, either is refused.
pub fn plot(dir: &Path, partial: bool) -> crate::error::Result<()> {
    if dir == Path::new("all") {
        return write_reproduction();
    }
    if crate::run::is_run(dir) {
        let path = figures::plot_run(dir, partial)?;
        crate::errln!("coevo: wrote {} and its .svg", path.display())?;
        return Ok(());
    }
    let name = dir.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    let file = Path::new(EXPERIMENTS).join(format!("{name}.ron"));
    if !file.exists() {
        return Err(format!(
            "--plot {}: neither a run folder nor the results of an experiment file {}",
            dir.display(),
            file.display()
        )
        .into());
    }
    let results = dir.parent().unwrap_or(Path::new("."));
    let exp = Experiment::load(&file, results)?;
    let data = data::load(&exp)?;
    data::check_complete(&exp, &data)?;
    if !partial && !data.is_empty() && data.len() < exp.runs.len() {
        return Err(format!(
            "--plot {}: only {} of the {} runs of {} are finished here; nothing written: finish them with `coevo --experiment {}`, or --partial summarises the finished ones (its report says how many)",
            dir.display(),
            data.len(),
            exp.runs.len(),
            file.display(),
            file.display()
        )
        .into());
    }
    // Without run folders (a clone), the committed figure data redraws the figures.
    if data.is_empty() && !exp.root.join(super::figure_data::FILE).exists() {
        return Err(format!(
            "--plot {}: no finished run of {} there, and no {}; nothing written",
            dir.display(),
            file.display(),
            super::figure_data::FILE
        )
        .into());
    }
    report(exp, &data)?;
    Ok(())
}

/// How a report names an experiment's file and results folder: `experiments/NAME.ron` and `results/NAME`
/// when that is where they are, however the command spelled them (`./experiments/…`, a trailing `/`), so
/// a tracked report never changes with the spelling; as given otherwise.
fn shown_paths(exp: &Experiment) -> (PathBuf, PathBuf) {
    let same = |a: &Path, b: &Path| match (std::fs::canonicalize(a), std::fs::canonicalize(b)) {
        (Ok(a), Ok(b)) => a == b,
        _ => false,
    };
    let file = Path::new(EXPERIMENTS).join(format!("{}.ron", exp.name));
    let root = Path::new(RESULTS).join(&exp.name);
    let file = if same(&exp.file, &file) { file } else { exp.file.clone() };
    let root = if same(&exp.root, &root) { root } else { exp.root.clone() };
    (file, root)
}

/// An experiment's own report, beside its summaries.
pub const REPORT: &str = "REPORT.md";

/// One experiment as REPRODUCTION.md reports it.
pub struct Reported {
    pub exp: Experiment,
    pub results: Vec<ClaimResult>,
    /// Training time summed over its own runs, how many runs finished, and how many of those are shared
    /// from another experiment (trained and timed there).
    pub seconds: f64,
    pub finished: usize,
    pub shared: usize,
    /// The executables that made its runs (`unknown` for runs made before provenance files).
    pub binaries: Vec<String>,
    /// The per-run values its claims were computed from.
    pub summary: summary::Summary,
}

/// How every number of a report is computed and what its verdicts mean (REPRODUCTION.md's preamble, and
/// each REPORT.md's).
const METHOD: &str = "Each number is the mean over seeds of the prey's 100-episode means (first or last 100 \
     episodes of training; measured with exploration noise on) or of an evaluation's last 50 steps, ± the half-width of its \
     95 % confidence interval (Student t over seeds). A quantity *of `X` minus `Y` (Welch)* is the difference of two \
     variants' means with Welch's 95 % interval (seeds: the smaller count). *Seeing minus* a control is the part of the \
     trained actors' alignment that the control removes, computed run by run. Nothing in the metrics, rewards or physics \
     was tuned toward a claim.\n\n\
     **Verdicts.** An *effect* (a change over training, what a control removes, a difference of two variants) is \
     *detected* when its two-sided t test gives p < 0.05 after Holm's adjustment over every effect of its experiment \
     (both presets; the column *p (Holm)*), which implies that its 95 % interval excludes 0. A claim of the paper is \
     **reproduced** when the claimed effect is detected in the claimed direction, or, for a level, when the paper's value \
     is inside the interval and chance is not (DoA by chance: 2/π ≈ 0.637; DoS by chance: uniform random positions at \
     the same density, e.g. 0.227 for 10 prey and 0.100 for 50 in the 2 m torus; the mean edge rank of caught prey by \
     chance: 0.5; C_nn by chance: 0); **not reproduced** when the effect is \
     detected the other way or the interval excludes the paper's value; **inconclusive** when the data are compatible with \
     both, with the smallest effect the seeds could detect (80 % power at α = 0.05 before the adjustment) and the seeds the paper's effect would need. A \
     claim of no effect is tested for equivalence within the margin its experiment file states (TOST: the 90 % interval \
     inside ± margin). For a quantity the paper gives no number of, the verdict says whether an effect was detected or \
     the level differs from chance; *no effect detected* is not evidence of no effect.\n\n";

/// The head of the contents table of experiments ([`contents_row`]).
const CONTENTS: &str =
    "| experiment | what | command | runs finished | training time (sum over runs) | binary |\n|---|---|---|---|---|---|\n";

/// REPRODUCTION.md: every claim of the experiments, the paper's number, ours with its interval, the
/// command that produced it and the verdict.
pub fn reproduction(experiments: &[Reported]) -> String {
    let mut md = String::from(
        "# Reproduction of Li, Li & Zhao (NJP 2023)\n\n\
         Generated by `coevo --experiment all` or `coevo --plot all` from the runs' CSV files under `results/` (each \
         experiment's section is also its `results/<experiment>/REPORT.md`); do not edit by hand. ",
    );
    md.push_str(METHOD);
    // Contents first: each experiment, what it tests, how far it got and the command that continues it.
    md.push_str(CONTENTS);
    for r in experiments {
        contents_row(&mut md, r);
    }
    // Then per experiment: its claims, and its figures.
    for r in experiments {
        section(&mut md, r, &shown_paths(&r.exp).1.join("figures"));
    }
    let (seconds, finished, runs) = experiments.iter().fold((0.0, 0, 0), |(s, f, r), e| {
        let own = e.exp.runs.iter().filter(|run| run.shared_from.is_none()).count();
        (s + e.seconds, f + e.finished - e.shared, r + own)
    });
    writeln!(
        md,
        "\n## The whole suite\n\n`coevo --experiment all --jobs 2`: {finished} of {runs} trainings finished, {:.1} h of training summed over \
         runs, each timed by its own `metrics.csv` (`wall_seconds`, the run's own wall clock). A run shared between \
         experiments (`shared_from`) is one training, counted and timed once; runs copied by hand before shared runs existed \
         still count once per experiment that holds a copy.",
        seconds / 3600.0
    )
    .unwrap();
    md
}

/// `results/<experiment>/REPORT.md`: one experiment's claims and verdicts, as REPRODUCTION.md gives them,
/// with its figures linked from beside them.
pub fn experiment_report(r: &Reported) -> String {
    let (file, root) = shown_paths(&r.exp);
    let mut md = format!(
        "# {}\n\nGenerated by `coevo --experiment {}` (finished runs are not run again) from the runs' CSV files under \
         `{}/`; do not edit by hand. ",
        r.exp.name,
        file.display(),
        root.display()
    );
    md.push_str(METHOD);
    md.push_str(CONTENTS);
    contents_row(&mut md, r);
    section(&mut md, r, Path::new("figures"));
    collective(&mut md, r);
    md
}

/// Every evaluation's order parameters (`sim::metrics`, `sim::collective`) per preset and variant, mean ±
/// 95 % CI over seeds (n), between mdBook anchors so the book includes the table rather than copying its
/// numbers (`{{#include ../../../results/NAME/REPORT.md:collective}}`).
fn collective(md: &mut String, Reported { exp, summary, .. }: &Reported) {
    if summary.rows.is_empty() || exp.spec.evaluations.is_empty() {
        return;
    }
    md.push_str(
        "\n## Collective measures\n\nEach evaluation of the trained actors: means over its last 50 steps (edge rank: the \
         mean over the steps with a ranked catch of each step's mean), then mean ± 95 % CI over seeds (seeds). `clusters` counts groups; `largest` is the \
         largest group's fraction of the headline species.\n\n<!-- ANCHOR: collective -->\n\
         ",
    );
    let labels = Swarming::LABELS[..2].iter().chain(&EVAL_ORDER_LABELS);
    let columns = ["preset", "variant", "evaluation"].iter().chain(labels).copied().collect::<Vec<_>>();
    writeln!(md, "| {} |\n|{}", columns.join(" | "), "---|".repeat(columns.len())).unwrap();
    for preset in &exp.spec.presets {
        for v in &exp.spec.variants {
            for e in &exp.spec.evaluations {
                let shown = |q: Quantity, digits: usize| {
                    estimate_shown(super::stats::estimate(&summary.values(exp, preset, &v.name, &q)), digits)
                };
                let mut cells = vec![
                    shown(Quantity::EvalDos(e.name.clone()), Swarming::DIGITS[0]),
                    shown(Quantity::EvalDoa(e.name.clone()), Swarming::DIGITS[1]),
                ];
                cells.extend(
                    EVAL_ORDER
                        .iter()
                        .zip(EVAL_ORDER_DIGITS)
                        .map(|(name, digits)| shown(Quantity::EvalOrder(e.name.clone(), name.to_string()), digits)),
                );
                if cells.iter().all(|c| c == "–") {
                    continue;
                }
                writeln!(md, "| {preset} | {} | {} | {} |", cell(&v.name), cell(&e.name), cells.join(" | ")).unwrap();
            }
        }
    }
    md.push_str("<!-- ANCHOR_END: collective -->\n");
}

/// One experiment's line of the contents: what it tests, how far it got and the command that continues it.
fn contents_row(md: &mut String, Reported { exp, seconds, finished, shared, binaries, .. }: &Reported) {
    let command = format!("`coevo --experiment {} --jobs 2`", shown_paths(exp).0.display());
    let (name, runs, hours) = (&exp.name, exp.runs.len(), seconds / 3600.0);
    let binary = match &binaries[..] {
        [] => "–".to_string(),
        [one] if one == "unknown" => "before provenance files".to_string(),
        [one] => format!("`{one}`"),
        many => format!("{} binaries", many.len()),
    };
    writeln!(
        md,
        "| [{name}](#{name}) | {} | {command} | {finished} of {runs}{} | {hours:.1} h | {binary} |",
        exp.spec.description,
        if *shared > 0 { format!(" ({shared} shared)") } else { String::new() }
    )
    .unwrap();
}

/// One experiment's section: its claims, and its figures (the comparison of variants and the learning
/// curves shown, the rest linked), the figures' links under `figures` (they are looked up in the
/// experiment's own figures folder).
fn section(md: &mut String, Reported { exp, results, .. }: &Reported, figures: &Path) {
    let what = if exp.spec.description.is_empty() { String::new() } else { format!("{}. ", exp.spec.description) };
    let (file, root) = shown_paths(exp);
    writeln!(md, "\n## {}\n\n{what}`{}`, results in `{}/`.\n", exp.name, file.display(), root.display()).unwrap();
    if !results.is_empty() {
        md.push_str("| preset | claim (the paper) | quantity | paper | coevo (mean ± 95 % CI, seeds) | p (Holm) | verdict |\n|---|---|---|---|---|---|---|\n");
    }
    for r in results {
        let ours = estimate_shown(r.estimate, 3);
        let paper = r.claim.paper.map_or("–".into(), |p| format!("{p:.3}"));
        let of = match &r.claim.versus {
            Some(base) => format!("`{}` minus `{base}` (Welch)", r.claim.variant),
            None => format!("`{}`", r.claim.variant),
        };
        let p = r.p_holm.map_or("–".into(), p_shown);
        writeln!(
            md,
            "| {} | {} | {} of {of} | {paper} | {ours} | {p} | {} |",
            r.preset,
            cell(&r.claim.text),
            cell(&quantity_name(&r.claim.quantity)),
            cell(&r.verdict)
        )
        .unwrap();
    }
    for preset in &exp.spec.presets {
        let shown: Vec<String> = ["variants", "training"]
            .iter()
            .map(|what| format!("{preset}-{what}.svg"))
            .filter(|file| exp.root.join("figures").join(file).exists())
            .map(|file| format!("![{}]({})", file.trim_end_matches(".svg"), figures.join(&file).display()))
            .collect();
        if !shown.is_empty() {
            writeln!(md, "\n{}\n", shown.join("\n")).unwrap();
        }
    }
}

/// An estimate as the reports show it: "mean ± half-width (seeds)" to `digits` decimals, "–" without one.
fn estimate_shown(e: Option<super::stats::Estimate>, digits: usize) -> String {
    match e {
        Some(e) => {
            format!("{:.digits$}{} ({})", e.mean, e.ci.map_or(String::new(), |c| format!(" ± {c:.digits$}")), e.n)
        }
        None => "–".into(),
    }
}

/// Text as one Markdown table cell: a `|` would end the cell.
fn cell(text: &str) -> String {
    text.replace('|', "\\|")
}
