//! What an experiment reports: its REPORT.md, and REPRODUCTION.md over the project's experiment files
//! (written by `--experiment` and `--plot`, [`super::command`]).

use super::file::{Experiment, Quantity, EVAL_ORDER, EVAL_ORDER_DIGITS, EVAL_ORDER_LABELS};
use super::quantity::quantity_name;
use super::results::ClaimResult;
use super::summary;
use super::verdict::p_shown;
use crate::sim::metrics::Swarming;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// Where experiments are read and their runs written.
pub(crate) const EXPERIMENTS: &str = "experiments";
pub(crate) const RESULTS: &str = "results";

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
pub(crate) const REPORT: &str = "REPORT.md";

/// One experiment as REPRODUCTION.md reports it.
pub(crate) struct Reported {
    pub(crate) exp: Experiment,
    pub(crate) results: Vec<ClaimResult>,
    /// Training time summed over its own runs, how many runs finished, and how many of those are shared
    /// from another experiment (trained and timed there).
    pub(crate) seconds: f64,
    pub(crate) finished: usize,
    pub(crate) shared: usize,
    /// The executables that made its runs (`unknown` for runs made before provenance files).
    pub(crate) binaries: Vec<String>,
    /// The per-run values its claims were computed from.
    pub(crate) summary: summary::Summary,
}

/// How every number of a report is computed and what its verdicts mean (REPRODUCTION.md's preamble, and
/// each REPORT.md's).
const METHOD: &str = "Each number is the mean over seeds of the prey's 100-episode means (first or last 100 \
     episodes of training; measured with exploration noise on) or of an evaluation's last 50 steps, ± the half-width of its \
     95 % confidence interval (Student t over seeds). A quantity *of `X` minus `Y` (Welch)* is the difference of two \
     variants' means with Welch's 95 % interval (seeds: the smaller count). *Seeing minus* a control is the part of the \
     trained actors' alignment that the control removes, computed run by run. Over a grid of variants (one or two \
     parameters, each at several levels), a *trend* is the least-squares slope of every run's value on its level's \
     position along an axis (seeds are the replicates; HC3 standard errors, n − 2 degrees of freedom), tested as an \
     effect; a *boundary* is where the mean over seeds first falls (or, as stated, rises) through a stated value \
     along an axis (linear between levels), with a bootstrap over seeds within each cell (2000 resamples): it is **located** when the test of no \
     crossing within the axis (p: the share of resamples that do not cross) is detected after Holm, its interval the \
     resamples' percentiles at that level; its *shift* is the least-squares slope of the boundary on the other axis, \
     by the same bootstrap. Nothing in the metrics, rewards or physics was tuned toward a claim.\n\n\
     **Verdicts.** An *effect* (a change over training, what a control removes, a difference of two variants, or a number tested against zero: a claim that states only its direction, or none within a margin) is \
     *detected* when its two-sided t test gives p < 0.05 after Holm's adjustment over its family (the column *p (Holm)*). \
     A family is named by its hypotheses, not by its file, and spans every experiment file that names it (column \
     *family*, with how many tests it holds): **the paper's claims** (the paper's own statements, in its setting), \
     **mechanism and controls** (the controls that ask why, e.g. flocking or herding), **exploratory** (questions the \
     paper does not ask and findings seen before they were stated: reported, never counted as confirmations), and \
     each pre-registered confirmatory test's own family; a claim of a file that names no family is that file's. A \
     test that repeats another of its family on the same runs (a shared variant) is that test, counted once. Each \
     claim's statement (text, variants, quantity, the paper's value, margin, baseline) and family are recorded in \
     `results/<experiment>/claims.csv` when its runs start (results aggregated before coevo kept this record start it \
     with the claims as they stood then), and never rewritten: a claim edited, added or moved to another family after \
     its results existed is flagged post hoc beside its hypothesis. What a claim tests (all of its statement but its \
     words) must be in a commit of its experiment file before the first commit holding a per-run row it judges (a \
     row of its or a shared variant's `summary.csv`), or the claim is marked **exploratory** and its verdict says so; \
     `coevo --plot` reads this from git and refuses an unmarked claim stated later. Its interval is \
     shown at the level Holm's procedure tested it at (*level*: 0.05/k, Bonferroni's for the smallest p-value; from the \
     first test Holm does not reject on, that test's level), so **the interval excludes 0 exactly when the effect is \
     detected**; the plain 95 % interval is beside it, secondary, and never a result. For an effect the paper states: \
     **reproduced** when it is detected in the paper's direction and the paper's value is inside the adjusted interval; \
     **direction reproduced, smaller (larger) than the paper** when it is detected in the paper's direction but the \
     paper's value is outside; **not reproduced** when it is detected the other way; otherwise **inconclusive**, saying \
     whether the paper's value is outside the adjusted interval (an effect of its size excluded) and the smallest effect \
     the seeds detect with 80 % power at the level used. A direction the project states itself, for a question the \
     paper does not ask (hypothesis marked *the project's*), is **detected as hypothesised**, **detected opposite to \
     the hypothesis** or **inconclusive**, and never called reproduced. The family-wise guarantee covers the detections; the \
     comparisons of size (smaller or larger than the paper, an effect of its size excluded) read the same intervals \
     and are descriptive, since stepped intervals are not simultaneous ones. A claim of no effect is tested for equivalence within the \
     margin its experiment file states (TOST, its p-value in the family like any test): **equivalent within ±m** when \
     the (1 − 2α) interval at its level lies inside ± m, **not reproduced** when the interval lies beyond the margin, \
     otherwise **inconclusive**, saying the margin the data would support (the farther end of that interval). A *level* \
     with the paper's value is **reproduced** when it is equivalent to that value within a tolerance (TOST at 5 %: \
     its 90 % interval lies inside the paper's value ± the tolerance), **not reproduced** when its 95 % interval lies \
     outside that band, and **inconclusive** otherwise. The tolerance is half the smallest difference between two \
     levels the paper states for the same order parameter, so that a level within it is nearer the paper's number than \
     any other level the paper tells it apart from: ±0.005 for DoS (the paper's 22, 20.5, 19, 18, 17 and 15 %) and \
     ±0.015 for DoA (0.65, 0.75, 0.82, 0.85 and 0.96). This rule was fixed after the results below existed, once, \
     from the paper's numbers alone; it replaced a test of whether the 95 % interval reached the paper's value at the \
     precision it is printed with, which favoured few seeds. Level verdicts are per test: they enter no family and are \
     not adjusted for multiplicity, so among many levels some are expected to be decided by chance alone. Each level also says whether it is told apart from chance \
     (DoA by chance: 2/π ≈ 0.637; DoS by chance: uniform random positions at \
     the same density, e.g. 0.226 for 10 prey and 0.100 for 50 in the 2 m torus; the mean edge rank of caught prey by \
     chance: 0.5; C_nn by chance: 0). Where one sentence of the paper gives a level \
     and the contrast it implies (a variant against its base, the same quantity), the contrast is the primary test and the \
     level a secondary row: when one is reproduced and the other is not, both rows say that they disagree and that the \
     contrast decides. For a \
     quantity the paper gives no number of, the verdict says whether an effect was detected or the level differs from \
     chance; *no effect detected* is not evidence of no effect: only an equivalence verdict is. The paper's per-step \
     levels of trained prey (DoS about 15 %, DoA about 0.96) are judged at the training density, 10 prey, and the \
     50-prey evaluation is a secondary row without the paper's number: DoS depends on density (uniform random \
     positions give 0.226 at 10 prey and 0.100 at 50, so a DoS of 15 % is clustering at 10 prey but more spread than \
     random at 50), and the paper's values match its 10-prey state.\n\n";

/// The head of the contents table of experiments ([`contents_row`]).
const CONTENTS: &str =
    "| experiment | what | command | runs finished | training time (sum over runs) | binary |\n|---|---|---|---|---|---|\n";

/// REPRODUCTION.md: every claim of the experiments, the paper's number, ours with its interval, the
/// command that produced it and the verdict.
pub(crate) fn reproduction(experiments: &[Reported], the_paper: Option<&str>) -> String {
    let mut md = String::from(
        "# Reproduction of Li, Li & Zhao (NJP 2023)\n\n\
         Generated by `coevo --experiment all` or `coevo --plot all` from the runs' CSV files under `results/` (each \
         experiment's section is also its `results/<experiment>/REPORT.md`); do not edit by hand.\n\n",
    );
    // The answer first: the paper's statements and what became of each; then how every number is made.
    if let Some(table) = the_paper {
        writeln!(md, "## The paper, claim by claim\n\n{table}\n## Every claim\n").unwrap();
    }
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
    let runs: usize = experiments.iter().map(|e| e.exp.runs.iter().filter(|r| r.shared_from.is_none()).count()).sum();
    let all: Vec<_> = experiments.iter().flat_map(|e| super::trainings::from_summary(&e.exp, &e.summary)).collect();
    let (finished, distinct, seconds) = super::trainings::count(&all);
    writeln!(
        md,
        "\n## The whole suite\n\n`coevo --experiment all --jobs 2`: {finished} of {runs} trainings finished, of which {distinct} \
         distinct, {:.1} h of training summed over the distinct ones, each timed by its own `metrics.csv` (`wall_seconds`, \
         the run's own wall clock). A run shared between experiments (`shared_from`) is one training, counted and timed \
         once; so is a run trained again, from the same resolved scene and seed by the same binary or by another \
         that gives every training number of it to the bit (a deterministic re-training: {}), which its file \
         declares (`same_training_as`; an undeclared one by the same binary is refused, a declared one that \
         differs too).",
        seconds / 3600.0,
        match finished - distinct {
            0 => "none".to_string(),
            1 => "1 run".to_string(),
            n => format!("{n} runs"),
        }
    )
    .unwrap();
    let same = super::trainings::same_outcomes(&all);
    if !same.is_empty() {
        let list: Vec<String> = same
            .iter()
            .map(|((a, b), n)| format!("`{a}` and `{b}`, {n} seed{}", if *n == 1 { "" } else { "s" }))
            .collect();
        writeln!(
            md,
            "\nDistinct trainings of another scene that gave every training number of a training of the same preset \
             and seed to the bit (a switch that never acted): {}. Each is one training of its own scene, and a \
             comparison of the two is not a test (one sample, not two).",
            list.join("; ")
        )
        .unwrap();
    }
    md
}

/// `results/<experiment>/REPORT.md`: one experiment's claims and verdicts, as REPRODUCTION.md gives them,
/// with its figures linked from beside them.
pub(crate) fn experiment_report(r: &Reported) -> String {
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
fn collective(md: &mut String, Reported { exp, summary, finished, .. }: &Reported) {
    // An experiment judged when complete shows no number of its runs before (no interim analysis).
    let in_progress = exp.spec.judged_when_complete && *finished < exp.runs.len();
    if summary.rows.is_empty() || exp.spec.evaluations.is_empty() || in_progress {
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
                        .map(|(o, digits)| shown(Quantity::EvalOrder(e.name.clone(), *o), digits)),
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
fn section(md: &mut String, Reported { exp, results, finished, summary, .. }: &Reported, figures: &Path) {
    let what = if exp.spec.description.is_empty() { String::new() } else { format!("{}. ", exp.spec.description) };
    let (file, root) = shown_paths(exp);
    writeln!(md, "\n## {}\n\n{what}`{}`, results in `{}/`.\n", exp.name, file.display(), root.display()).unwrap();
    if (1..exp.runs.len()).contains(finished) && exp.spec.judged_when_complete {
        writeln!(
            md,
            "**In progress: {finished} of the {} runs are finished** (their rows are committed, so no machine loses \
             them). Its claims are judged when all are: no estimate, verdict or figure before then (no interim \
             analysis; the seeds were fixed beforehand).\n",
            exp.runs.len()
        )
        .unwrap();
    } else if (1..exp.runs.len()).contains(finished) {
        writeln!(
            md,
            "**Partial: {finished} of the {} runs are finished.** Every number, verdict and figure of this experiment \
             is from those runs alone and provisional until the rest finish (reported with `--partial`).\n",
            exp.runs.len()
        )
        .unwrap();
    }
    // Runs shorter than two windows: every first- and last-100 value reads overlapping episodes.
    let shortest = exp
        .spec
        .presets
        .iter()
        .flat_map(|p| exp.spec.variants.iter().filter_map(move |v| summary.episodes(p, &v.name)))
        .min();
    if let Some(n) = shortest.filter(|&n| n < 2 * super::results::WINDOW) {
        writeln!(
            md,
            "**Runs of {n} episodes:** shorter than {} episodes, so their first and last {} episodes overlap: every \
             first- or last-100 value below reads overlapping episodes (all of them, at {} episodes or fewer), and changes \
             over training are not measured.\n",
            2 * super::results::WINDOW,
            super::results::WINDOW,
            super::results::WINDOW
        )
        .unwrap();
    }
    if !results.is_empty() {
        md.push_str("| preset | claim | quantity | paper | coevo (mean ± adjusted CI, seeds) | level | unadjusted 95 % CI | p (Holm) | verdict | hypothesis | family |\n|---|---|---|---|---|---|---|---|---|---|---|\n");
    }
    for r in results {
        let ours = match (r.estimate, r.shown_half_width()) {
            (Some(e), Some(h)) => format!("{:.3} ± {h:.3} ({})", e.mean, e.n),
            (e, _) => estimate_shown(e, 3),
        };
        let ours = match r.uninformative() {
            Some(why) => format!("{ours}, {why}"),
            None => ours,
        };
        // The level the interval is shown at: the Holm step's for a test (TOST: twice it, one-sided
        // each way), 95 % for a level; the plain 95 % interval beside it, secondary.
        let level = match (r.level, r.claim.margin) {
            (Some(l), Some(_)) => format!("TOST, α = {}", super::verdict::alpha_shown(l)),
            (Some(l), None) => format!("α = {}", super::verdict::alpha_shown(l)),
            // An effect not tested (not run yet, one seed, identical runs) has no level.
            (None, _) if super::results::is_effect(&r.claim) => "–".into(),
            (None, _) => "95 %".into(),
        };
        let plain = match r.estimate.and_then(|e| e.ci.map(|c| (e.mean, c))) {
            Some((m, c)) if r.level.is_some() => format!("[{:.3}, {:.3}]", m - c, m + c),
            _ => "–".into(),
        };
        let paper = r.claim.paper.filter(|_| !r.claim.ours).map_or("–".into(), |p| format!("{p:.3}"));
        let of = match (&r.claim.grid, &r.claim.versus) {
            (Some(test), _) => super::grid::describe(test),
            (None, Some(base)) => format!("`{}` minus `{base}` (Welch)", r.claim.variant),
            (None, None) => format!("`{}`", r.claim.variant),
        };
        let p = r.p_holm.map_or("–".into(), p_shown);
        writeln!(
            md,
            "| {} | {} | {} of {of} | {paper} | {ours} | {level} | {plain} | {p} | {} | {} | {} |",
            r.preset,
            cell(&r.claim.text),
            cell(&match r.claim.scale {
                super::file::Scale::Linear => quantity_name(&r.claim.quantity),
                super::file::Scale::Log1p if r.claim.grid.is_some() =>
                    format!("ln(1 + {})", quantity_name(&r.claim.quantity)),
                super::file::Scale::Log1p =>
                    format!("ln(1 + {}), Welch on the log scale", quantity_name(&r.claim.quantity)),
            }),
            cell(r.verdict_text()),
            cell(&format!("{}{}", super::verdict::hypothesis(&r.claim, r.baseline), r.stated.flag())),
            {
                let size = match r.family_tests {
                    0 => String::new(),
                    1 => " (1 test)".into(),
                    n => format!(" ({n} tests)"),
                };
                match (&r.claim.family, r.p.is_some()) {
                    (Some(name), _) => format!("{}{size}", cell(name)),
                    (None, true) => format!("this file's{size}"),
                    (None, false) => "–".to_string(),
                }
            }
        )
        .unwrap();
    }
    // No figure of an experiment judged when complete before it is (figures of an earlier look may remain).
    let in_progress = exp.spec.judged_when_complete && *finished < exp.runs.len();
    for preset in exp.spec.presets.iter().filter(|_| !in_progress) {
        let shown: Vec<String> = ["variants", "training"]
            .iter()
            .map(|what| format!("{preset}-{what}.svg"))
            .filter(|file| exp.figures_dir().join(file).exists())
            .map(|file| format!("![{}]({})", file.trim_end_matches(".svg"), figures.join(&file).display()))
            .collect();
        if !shown.is_empty() {
            writeln!(md, "\n{}\n", shown.join("\n")).unwrap();
        }
    }
}

/// An estimate as the reports show it: "mean ± half-width (seeds)" to `digits` decimals, "–" without one;
/// an interval from fewer than [`INFORMATIVE_SEEDS`](super::verdict::INFORMATIVE_SEEDS) seeds is marked
/// uninformative.
fn estimate_shown(e: Option<super::stats::Estimate>, digits: usize) -> String {
    match e {
        Some(e) => {
            let mark = match e.ci.is_some() && e.n < super::verdict::INFORMATIVE_SEEDS {
                true => ", uninformative",
                false => "",
            };
            format!("{:.digits$}{} ({}{mark})", e.mean, e.ci.map_or(String::new(), |c| format!(" ± {c:.digits$}")), e.n)
        }
        None => "–".into(),
    }
}

/// Text as one Markdown table cell: a `|` would end the cell.
fn cell(text: &str) -> String {
    text.replace('|', "\\|")
}
