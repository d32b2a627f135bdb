//! `--experiment` and `--plot`: their flags, and the orchestration: run an experiment's runs
//! ([`super::runner`]), load what they wrote ([`super::data`]), aggregate it ([`super::aggregate`]) and
//! write each experiment's REPORT.md and REPRODUCTION.md ([`super::report`]).

use super::file::Experiment;
use super::report::{experiment_report, reproduction, Reported, EXPERIMENTS, REPORT, RESULTS};
use super::runner;
use super::summary::Summary;
use super::{aggregate, data, family, figures, paper_table};
use crate::io::Existing;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// `--experiment FILE|all` and its own flags.
#[derive(clap::Args, Debug, Clone, Default)]
pub(crate) struct ExperimentArgs {
    /// Run an experiment file (experiments/*.ron), or `all` of them: every preset × variant × seed as a
    /// run under results/, resuming killed runs and skipping finished ones, then evaluations, summaries,
    /// figures and results/NAME/REPORT.md (claims and verdicts); `all` also rewrites REPRODUCTION.md.
    #[arg(long, help_heading = "Modes", value_name = "FILE|all")]
    pub(crate) experiment: Option<String>,
    /// --experiment: runs at a time, sharing the cores (--threads / J each) [default: 2].
    #[arg(long, help_heading = "Experiments", value_name = "J", value_parser = crate::run::args::at_least_one)]
    pub(crate) jobs: Option<usize>,
    /// --experiment: only run index N of the experiment (what a Slurm array task runs).
    #[arg(long, help_heading = "Experiments", value_name = "N")]
    pub(crate) task: Option<usize>,
    /// --experiment: write a Slurm job array and a dependent aggregate job instead of running.
    #[arg(long, help_heading = "Experiments")]
    pub(crate) emit_slurm: bool,
    /// --experiment: make a pinned experiment's runs (results/NAME/binary/pin.ron) with this build of its
    /// commit instead of rebuilding it; used only if it reproduces the pin's fingerprint.
    #[arg(long, help_heading = "Experiments", value_name = "PATH")]
    pub(crate) pinned_binary: Option<PathBuf>,
}

impl crate::run::args::Mode for ExperimentArgs {
    const MODE: &'static str = "experiment";
    const TAKES: &'static [&'static str] = &["quiet"];
}

/// What `--experiment` was asked.
pub(crate) struct Request<'a> {
    /// An experiment file, or `all` of `experiments/`.
    pub(crate) which: &'a str,
    /// Runs at a time [default 2].
    pub(crate) jobs: Option<usize>,
    /// Only this run (a Slurm array task).
    pub(crate) task: Option<usize>,
    /// Write Slurm scripts instead of running.
    pub(crate) emit_slurm: bool,
    /// A build of a pinned experiment's commit (`--pinned-binary`).
    pub(crate) pinned_binary: Option<&'a Path>,
    pub(crate) quiet: bool,
}

impl ExperimentArgs {
    pub(crate) fn request<'a>(&'a self, which: &'a str, shared: &crate::run::args::Shared) -> Request<'a> {
        Request {
            which,
            jobs: self.jobs,
            task: self.task,
            emit_slurm: self.emit_slurm,
            pinned_binary: self.pinned_binary.as_deref(),
            quiet: shared.common.quiet,
        }
    }
}

/// `--plot DIR|all` and its own flag.
#[derive(clap::Args, Debug, Clone, Default)]
pub(crate) struct PlotArgs {
    /// Regenerate summaries, figures and REPORT.md from CSV files alone: an experiment's results folder
    /// (results/NAME, with experiments/NAME.ron), one run folder, or `all` (every experiment, and
    /// REPRODUCTION.md; an experiment whose run folders are not all here keeps its summaries, and its
    /// figures are redrawn from its committed figure-data.ron.gz).
    #[arg(long, help_heading = "Modes", value_name = "DIR")]
    pub(crate) plot: Option<PathBuf>,
    /// --plot: draw a run stopped after its last checkpoint, or an experiment whose runs are not all
    /// finished, from what there is (marked partial) instead of refusing.
    #[arg(long, help_heading = "Experiments")]
    pub(crate) partial: bool,
}

impl crate::run::args::Mode for PlotArgs {
    const MODE: &'static str = "plot";
    const TAKES: &'static [&'static str] = &[];
}

/// The suite's report of every claim, at the repository's top.
const REPRODUCTION: &str = "REPRODUCTION.md";

/// `--experiment FILE|all`: run, evaluate and aggregate; then REPRODUCTION.md from every experiment's
/// results so far (the project's experiment files), or the experiment's own summaries (any other file).
pub(crate) fn experiment(request: &Request) -> crate::error::Result<()> {
    let which = request.which;
    let files = match which {
        "all" => Experiment::files(Path::new(EXPERIMENTS))?,
        file => vec![PathBuf::from(file)],
    };
    let experiments = files.iter().map(|f| Experiment::load(f, Path::new(RESULTS))).collect::<Result<Vec<_>, _>>()?;
    // What the runs end in, checked before the first trains: a refusal never follows a training.
    for exp in &experiments {
        exp.check_outputs()?;
    }
    let unchecked = check_registered(&experiments)?;
    if which == "all" && request.task.is_none() {
        check_reproduction_targets()?;
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
            // A pinned experiment with runs left is built and checked here, once, so that its tasks find
            // the build verified; it (or the one --pinned-binary names) is handed on to them.
            let pending = runner::pending(exp, &super::carry::finished_elsewhere(exp)?, None);
            let pinned = match pending || request.pinned_binary.is_some() {
                true => Some(super::pin::executable(exp, request.pinned_binary)?.path).filter(|p| *p != exe),
                false => None,
            };
            let dir = runner::emit_slurm(exp, &exe, pinned.as_deref())?;
            // Quoted as the scripts quote it, so the line can be pasted into a shell as it is.
            let submit = dir.join("submit.sh").to_string_lossy().into_owned();
            let submit = shlex::try_quote(&submit).map_or(submit.clone(), |q| q.into_owned());
            crate::outln!("{}: {} runs; submit with: bash {submit}", exp.name, exp.runs.len())?;
        }
        return Ok(());
    }
    let opts = runner::RunnerOptions {
        pinned_binary: request.pinned_binary.map(Path::to_path_buf),
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
        return write_reproduction(false);
    }
    for mut exp in experiments {
        // As the runs left it: a verified rebuild may have joined the pin.
        exp.pin = super::pin::Pin::read(&exp.root)?;
        let data = data::load(&exp)?;
        let carried = data::check_complete(&exp, &data)?;
        check_trainings_once(&exp, &data)?;
        report_alone(exp, &data, carried)?;
    }
    unchecked.say()
}

/// Refuses, before one experiment is aggregated, a training held twice without `shared_from` or
/// `same_training_as` ([`super::trainings::check_once`]): among its own runs (`data` and its committed
/// rows) and, for a file of `experiments/`, against the other files' committed summaries.
fn check_trainings_once(exp: &Experiment, data: &BTreeMap<usize, super::results::RunData>) -> crate::error::Result<()> {
    let mut trainings = Vec::new();
    if in_suite(exp) {
        for file in Experiment::files(Path::new(EXPERIMENTS))? {
            let other = Experiment::load(&file, Path::new(RESULTS))?;
            if other.name == exp.name {
                trainings.extend(super::trainings::before_aggregation(exp, data)?);
            } else {
                trainings.extend(super::trainings::before_aggregation(&other, &BTreeMap::new())?);
            }
        }
    } else {
        trainings = super::trainings::before_aggregation(exp, data)?;
    }
    super::trainings::check_once(&trainings)
}

/// Summaries, figures and REPORT.md of every experiment of `experiments/`, and REPRODUCTION.md over all of
/// them. An experiment some but not all of whose runs are finished (in its run folders, or in its
/// committed summary) is refused unless `partial`, and then its reports say "partial".
pub(crate) fn write_reproduction(partial: bool) -> crate::error::Result<()> {
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
        let carried = match data::check_complete(&exp, &data) {
            Ok(carried) => carried,
            Err(e) => {
                crate::errln!("coevo: {e} (reported from the committed summary)")?;
                data.clear();
                Default::default()
            }
        };
        if !partial {
            check_whole(&exp, &data, "--plot all")?;
        }
        exp.check_outputs()?;
        loaded.push((exp, data, carried));
    }
    let unchecked = check_registered(loaded.iter().map(|(exp, _, _)| exp))?;
    check_reproduction_targets()?;
    let mut trainings = Vec::new();
    for (exp, data, _) in &loaded {
        trainings.extend(super::trainings::before_aggregation(exp, data)?);
    }
    super::trainings::check_once(&trainings)?;
    let mut aggregated = Vec::new();
    for (exp, data, carried) in loaded {
        let a = aggregate::aggregate(&exp, &data, carried)?;
        aggregated.push((exp, a));
    }
    // Now that every training is summarized, a declared re-training by another binary is checked number by
    // number (before aggregation a run folder's numbers are not at hand), before any report is written.
    let summarized: Vec<_> =
        aggregated.iter().flat_map(|(exp, a)| super::trainings::from_summary(exp, &a.summary)).collect();
    super::trainings::check_once(&summarized)?;
    // The families span the files: every experiment's tests adjusted together, then each reported.
    let counts: Vec<usize> = aggregated.iter().map(|(_, a)| a.results.len()).collect();
    let mut results: Vec<_> = aggregated.iter_mut().flat_map(|(_, a)| std::mem::take(&mut a.results)).collect();
    family::adjust(&mut results);
    let mut all = Vec::new();
    for ((exp, mut a), n) in aggregated.into_iter().zip(counts) {
        a.results = results.drain(..n).collect();
        all.push(report(exp, a)?);
    }
    let results: Vec<_> = all.iter().flat_map(|r| r.results.iter().cloned()).collect();
    // Within REPRODUCTION.md an experiment's evidence is its section; from the book, its results folder (the
    // book links no Markdown outside itself: mdbook would turn it into a missing page).
    let here = paper_table::table(&results, &|e: &str| format!("[{e}](#{e})"), "docs/src/reference/definitions.md")?;
    let book = paper_table::table(
        &results,
        &|e: &str| format!("[{e}](../../../results/{e}/)"),
        "../reference/definitions.md",
    )?;
    crate::io::write_file(Path::new(REPRODUCTION), Existing::Replace, reproduction(&all, here.as_deref()).as_bytes())?;
    crate::errln!("coevo: wrote {REPRODUCTION}")?;
    // The book's first results page, where the book is (a clone of the repository).
    let page = Path::new(paper_table::BOOK_PAGE);
    if let Some(book) = book.filter(|_| page.parent().is_some_and(Path::is_dir)) {
        crate::io::write_file(page, Existing::Replace, paper_table::book_page(&book).as_bytes())?;
        crate::errln!("coevo: wrote {}", page.display())?;
    }
    // The book's pages that show a report's table, where the book is.
    for page in paper_table::INLINING_PAGES.map(Path::new).into_iter().filter(|p| p.is_file()) {
        let text = crate::io::read_text(page, crate::io::MAX_TEXT_BYTES)?;
        let read = |report: &str| crate::io::read_text(Path::new(report), crate::io::MAX_TEXT_BYTES).ok();
        let inlined = paper_table::inline_tables(&text, &read).map_err(|m| format!("{}: {m}", page.display()))?;
        if inlined != text {
            crate::io::write_file(page, Existing::Replace, inlined.as_bytes())?;
            crate::errln!("coevo: wrote {}", page.display())?;
        }
    }
    unchecked.say()
}

/// REPRODUCTION.md and the book's page of the table, as `--plot all` writes them: regular files or new.
fn check_reproduction_targets() -> crate::error::Result<()> {
    crate::io::check_targets(
        &[PathBuf::from(REPRODUCTION), PathBuf::from(paper_table::BOOK_PAGE)],
        crate::io::Existing::Replace,
    )
}

/// One experiment reported on its own ([`report`]): its tests adjusted together with the tests of its named
/// families in the other experiment files of `experiments/`, read from their committed summaries (a family
/// spans files), when the file is one of them; alone otherwise.
fn report_alone(
    exp: Experiment,
    data: &BTreeMap<usize, super::results::RunData>,
    carried: super::carry::Carried,
) -> crate::error::Result<Reported> {
    let mut a = aggregate::aggregate(&exp, data, carried)?;
    let named = exp.spec.claims.iter().any(|c| c.family.is_some());
    if named && in_suite(&exp) {
        // Every file's tests in the files' order, as the suite adjusts them (the first of a repeated test
        // is the one tested), this experiment's own among them.
        let own = std::mem::take(&mut a.results);
        let (mut all, mut at) = (Vec::new(), None);
        for file in Experiment::files(Path::new(EXPERIMENTS))? {
            let other = Experiment::load(&file, Path::new(RESULTS))?;
            if other.name == exp.name {
                at = Some(all.len());
                all.extend(own.iter().cloned());
            } else {
                all.extend(aggregate::committed_tests(&other)?);
            }
        }
        let at = at.unwrap_or_else(|| {
            all.extend(own.iter().cloned());
            all.len() - own.len()
        });
        family::adjust(&mut all);
        a.results = all.drain(at..at + own.len()).collect();
    } else {
        family::adjust(&mut a.results);
    }
    report(exp, a)
}

/// Whether an experiment's file is one of `experiments/`, the suite whose files share named families.
fn in_suite(exp: &Experiment) -> bool {
    let dir = exp.file.parent().filter(|d| !d.as_os_str().is_empty()).unwrap_or(Path::new("."));
    matches!((std::fs::canonicalize(dir), std::fs::canonicalize(EXPERIMENTS)), (Ok(a), Ok(b)) if a == b)
}

/// One experiment's claims, estimated ([`aggregate::aggregate`]: from its run folders, writing its
/// summaries and figures, or in a clone without them from its committed summary.csv) and judged
/// ([`aggregate::adjust`]); then its REPORT.md, which holds only what the summary holds, so a clone
/// regenerates it byte for byte. Says on stderr exactly what it wrote.
fn report(exp: Experiment, aggregated: aggregate::Aggregated) -> crate::error::Result<Reported> {
    let aggregate::Aggregated { results, summary, figures, from_folders, extended } = aggregated;
    if extended {
        crate::errln!(
            "coevo: extended {}/summary.csv with the training curves' shape columns, from {} (every byte it held kept)",
            exp.root.display(),
            super::figure_data::FILE
        )?;
    }
    let wall = summary.columns.iter().position(|c| c == "wall_seconds");
    // + 0.0: an empty f64 sum is −0.0, which would print as "-0.0 h".
    // Shared runs are another experiment's trainings: counted there.
    let own = || summary.rows.iter().filter(|r| r.shared_from.is_empty());
    let seconds: f64 = own().filter_map(|r| wall.map(|i| r.values[i])).filter(|x| x.is_finite()).sum::<f64>() + 0.0;
    let shared = summary.rows.len() - own().count();
    let mut binaries: Vec<String> = summary.rows.iter().flat_map(|r| r.binary.split(' ').map(String::from)).collect();
    binaries.sort();
    binaries.dedup();
    // Rows of runs the file still has (a summary may hold runs of seeds since removed from the file).
    let finished = summary.runs(&exp).len();
    let reported = Reported { finished, shared, exp, results, seconds, binaries, summary };
    let root = &reported.exp.root;
    let path = root.join(REPORT);
    std::fs::create_dir_all(root).map_err(|e| format!("{}: {e}", root.display()))?;
    crate::io::write_file(&path, Existing::Replace, experiment_report(&reported).as_bytes())?;
    let in_progress = aggregate::in_progress(&reported.exp, &reported.summary);
    let drawn = |n: usize| match in_progress {
        true => "no figure (in progress: drawn when all its runs are finished)".to_string(),
        false => format!("{n} figure{} (.svg and .png) in {}/figures/", if n == 1 { "" } else { "s" }, root.display()),
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
pub(crate) fn plot(dir: &Path, partial: bool) -> crate::error::Result<()> {
    if dir == Path::new("all") {
        return write_reproduction(partial);
    }
    if crate::store::is_run(dir) {
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
    let carried = data::check_complete(&exp, &data)?;
    if !partial {
        check_whole(&exp, &data, &format!("--plot {}", dir.display()))?;
    }
    // Without run folders (a clone), the committed figure data redraws the figures.
    if data.is_empty() && !super::figure_data::present(&exp)? {
        return Err(format!(
            "--plot {}: no finished run of {} there, and no {}; nothing written",
            dir.display(),
            file.display(),
            super::figure_data::FILE
        )
        .into());
    }
    let unchecked = check_registered([&exp])?;
    check_trainings_once(&exp, &data)?;
    report_alone(exp, &data, carried)?;
    unchecked.say()
}

/// Refuses a claim stated after the first committed row it judges ([`super::registration`]); where no
/// history can be read, the reason, which the caller says once its work is done (a refusal stays one line).
fn check_registered<'a>(experiments: impl IntoIterator<Item = &'a Experiment>) -> crate::error::Result<Unchecked> {
    Ok(Unchecked(match super::registration::check(experiments)? {
        super::registration::Checked::Yes => None,
        super::registration::Checked::Not(why) => Some(why),
    }))
}

/// Why the order of registration and data was not checked, if it was not ([`check_registered`]).
#[must_use]
struct Unchecked(Option<String>);

impl Unchecked {
    fn say(self) -> crate::error::Result<()> {
        match self.0 {
            Some(why) => crate::errln!("coevo: whether claims were stated before their results is not checked: {why}"),
            None => Ok(()),
        }
    }
}

/// How many of the experiment's runs are finished: its run folders here (`data`) and the committed runs
/// finished elsewhere ([`super::carry`]), or, with no folder here (a clone), the rows of its committed summary.csv that are runs of the file.
fn finished(exp: &Experiment, data: &BTreeMap<usize, super::results::RunData>) -> crate::error::Result<usize> {
    if !data.is_empty() {
        // With the committed runs not finished here, which aggregation carries.
        let committed = super::carry::committed_runs(exp)?;
        return Ok(data.len() + committed.iter().filter(|i| !data.contains_key(i)).count());
    }
    Ok(Summary::read(&exp.summary_path())?.map_or(0, |s| s.runs(exp).len()))
}

/// Refuses (`what`: the call, for the error line) an experiment some but not all of whose runs are
/// finished: its claims would be judged on part of their seeds with nothing saying so. None finished is
/// "not run yet", which every report says.
fn check_whole(
    exp: &Experiment,
    data: &BTreeMap<usize, super::results::RunData>,
    what: &str,
) -> crate::error::Result<()> {
    let (done, runs) = (finished(exp, data)?, exp.runs.len());
    // An experiment judged when complete shows nothing of a part of its runs: nothing partial to refuse.
    if done == 0 || done == runs || exp.spec.judged_when_complete {
        return Ok(());
    }
    let from = if data.is_empty() { format!("{}/summary.csv holds", exp.root.display()) } else { "here are".into() };
    Err(format!(
        "{what}: {from} {done} of the {runs} runs of {file}; nothing written: finish them with `coevo --experiment {file}`, or add --partial to report the finished ones, marked partial",
        file = exp.file.display()
    )
    .into())
}
