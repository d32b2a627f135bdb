//! The paper, claim by claim: one row per statement of the paper (its levels, changes, sweeps and
//! controls), with the paper's value and coevo's verdict on each preset, in a table a reader takes in at a
//! glance. Which claims of the experiment files answer each statement is configuration,
//! [`STATEMENTS`] (`experiments/the-paper/statements.ron`); every number and verdict is the one
//! REPRODUCTION.md gives that claim. Written at the top of REPRODUCTION.md and as the book's first results
//! page ([`BOOK_PAGE`]).

use super::file::Quantity;
use super::results::ClaimResult;
use super::verdict::Outcome;
use serde::Deserialize;
use std::fmt::Write as _;
use std::path::Path;

/// The statements and the claims that answer them.
pub(crate) const STATEMENTS: &str = "experiments/the-paper/statements.ron";

/// The book's page of the table, written beside REPRODUCTION.md when the book is there.
pub const BOOK_PAGE: &str = "docs/src/results/the-paper.md";

/// The two presets, in the table's column order: the paper's table values, the authors' code's.
const PRESETS: [&str; 2] = ["paper", "gym-pps"];

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct StatementsFile {
    statements: Vec<Statement>,
    /// Markdown written under the table: what a reader of the verdicts must know that no row holds (how a
    /// change of test moved verdicts).
    #[serde(default)]
    after_table: Option<String>,
}

/// One statement of the paper.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct Statement {
    /// The statement, short, in the paper's words.
    says: String,
    /// The paper's experiment it is about ("training", "speed ratio").
    setting: String,
    /// The paper's number as it writes it ("22 % → 19 %"), or "–".
    value: String,
    /// What a reader must know beside the verdicts (a measure chosen after its results were seen).
    #[serde(default)]
    note: Option<String>,
    /// The claims that test it, as `"EXPERIMENT / CLAIM TEXT"`, best first: a cell shows the first one
    /// judged on its preset (a confirmatory experiment still in progress gives way to the one before it).
    from: Vec<String>,
}

/// The statements, checked against the experiments' claims (`results`): every source names a claim of an
/// experiment file.
fn statements(results: &[ClaimResult]) -> crate::error::Result<Option<StatementsFile>> {
    let path = Path::new(STATEMENTS);
    // Experiments of one's own, without the paper's statements beside them: no table.
    if !path.exists() {
        return Ok(None);
    }
    let text = crate::io::read_text(path, crate::io::MAX_TEXT_BYTES)?;
    let file: StatementsFile = ron::from_str(&text).map_err(|e| format!("{}: {e}", path.display()))?;
    for s in &file.statements {
        for source in &s.from {
            let Some((experiment, _)) = source.split_once(" / ") else {
                return Err(format!("{}: {source:?} is not \"EXPERIMENT / CLAIM TEXT\"", path.display()).into());
            };
            if of_source(results, source).next().is_none() {
                return Err(
                    format!("{}: {source:?} names no claim of experiments/{experiment}.ron", path.display()).into()
                );
            }
        }
    }
    Ok(Some(file))
}

/// The answer above the table: per preset, how many statements came out each way (each statement's cell,
/// [`cell`]'s source), in one sentence each; `definitions`: the terms' page, linked from the first term the answer
/// uses.
fn answer(statements: &[Statement], results: &[ClaimResult], definitions: &str) -> String {
    let mut out = String::from("**The answer.** ");
    let mut linked = false;
    for (preset, values) in [("gym-pps", "the authors' code's values"), ("paper", "the paper's stated values")] {
        let mut counts = [0usize; 6];
        // Undecided statements whose interval rules out an effect of the paper's size.
        let mut size_excluded = 0;
        // Decided verdicts of claims stated after their first results (`registration.rs`).
        let mut exploratory = 0;
        for s in statements {
            let found = found(s, preset, results);
            let shown = found.iter().find(|r| judged(r)).or(found.first()).copied();
            let outcome = shown.and_then(|r| r.verdict.as_ref()).map(|v| v.outcome);
            let k = match outcome {
                // A statement no experiment tests (its row says why).
                _ if s.from.is_empty() => 5,
                _ if shown.is_some_and(disagrees) => 3,
                Some(Outcome::Reproduced | Outcome::Equivalent)
                | Some(Outcome::Measured { apart_from_chance: Some(true) })
                | Some(Outcome::EffectDetected) => 0,
                Some(Outcome::DirectionReproduced { .. }) => 1,
                Some(Outcome::NotReproduced | Outcome::DetectedOpposite) => 2,
                Some(Outcome::InProgress | Outcome::NotRunYet) | None => 4,
                Some(_) => 3,
            };
            counts[k] += 1;
            if k <= 2 && shown.is_some_and(|r| r.claim.exploratory) {
                exploratory += 1;
            }
            if k == 3 && matches!(outcome, Some(Outcome::Inconclusive { paper_size_excluded: true })) {
                size_excluded += 1;
            }
        }
        let [held, direction, not, undecided, waiting, unmeasured] = counts;
        let excluded = match size_excluded {
            0 => String::new(),
            n => format!(" ({n} of them rule out an effect of the paper's size)"),
        };
        // Linked where the answer first says it, which is before the page's list of terms.
        let word = match linked {
            false => format!("[exploratory]({definitions}#exploratory)"),
            true => "exploratory".into(),
        };
        linked |= exploratory > 0;
        let exploratory = match exploratory {
            0 => String::new(),
            1 => format!("; 1 of these decided verdicts is {word} (its claim was stated after its first results were committed)"),
            n => format!("; {n} of these decided verdicts are {word} (their claims were stated after their first results were committed)"),
        };
        write!(
            out,
            "With {values} (`{preset}`), {held} of the {} statements hold (reproduced, equivalent, or, where the paper gives no number, detected or told apart from chance), {direction} hold in direction but not in size, {not} are not reproduced and {undecided} are undecided{excluded}{}{}{exploratory}. ",
            statements.len(),
            match waiting {
                0 => String::new(),
                1 => ", and 1 waits for its runs".into(),
                n => format!(", and {n} wait for their runs"),
            },
            match unmeasured {
                0 => String::new(),
                1 => "; 1 is not tested (its row says why)".into(),
                n => format!("; {n} are not tested (their rows say why)"),
            }
        )
        .unwrap();
    }
    // Rows shown from an earlier experiment while their confirmatory one is still running.
    let running = statements
        .iter()
        .filter(|s| {
            s.from
                .first()
                .and_then(|source| of_source(results, source).next())
                .is_some_and(|r| r.verdict.as_ref().is_some_and(|v| v.outcome == Outcome::InProgress))
                // ... and a later source judged, which the row shows meanwhile.
                && s.from.iter().skip(1).any(|source| of_source(results, source).any(judged))
        })
        .count();
    if running > 0 {
        write!(
            out,
            "{running} rows are shown from an earlier, smaller experiment while the one registered to decide them \
             (more seeds, fixed before its runs) is running; it replaces them here when it is judged."
        )
        .unwrap();
    }
    out.push_str("\n\n");
    out
}

/// A verdict in a word or three, with a mark the eye finds in a column.
fn short(outcome: Outcome) -> &'static str {
    match outcome {
        Outcome::Reproduced => "✓ reproduced",
        Outcome::Equivalent => "✓ equivalent",
        Outcome::DirectionReproduced { larger: true } => "◐ direction, larger",
        Outcome::DirectionReproduced { larger: false } => "◐ direction, smaller",
        Outcome::NotReproduced => "✗ not reproduced",
        Outcome::Inconclusive { paper_size_excluded: false } => "? inconclusive",
        Outcome::Inconclusive { paper_size_excluded: true } => "? inconclusive, the paper's size excluded",
        Outcome::NoEffectDetected => "? not detected",
        Outcome::EffectDetected => "detected",
        Outcome::DetectedAsHypothesised => "detected as hypothesised",
        Outcome::DetectedOpposite => "detected opposite",
        Outcome::Measured { apart_from_chance: Some(true) } => "✓ apart from chance",
        Outcome::Measured { apart_from_chance: Some(false) } => "? not apart from chance",
        Outcome::Measured { apart_from_chance: None } => "measured",
        Outcome::InProgress => "in progress",
        Outcome::NotRunYet => "not run yet",
        Outcome::OneSeed => "one seed",
        Outcome::NotMeasured | Outcome::NotAComparison => "not measured",
    }
}

/// The results of one source, `"EXPERIMENT / CLAIM TEXT"` (one per preset); none for a source not so written.
fn of_source<'a>(results: &'a [ClaimResult], source: &str) -> impl Iterator<Item = &'a ClaimResult> + 'a {
    let (experiment, claim) =
        source.split_once(" / ").map_or((String::new(), None), |(e, c)| (e.to_string(), Some(c.to_string())));
    results.iter().filter(move |r| claim.as_ref().is_some_and(|c| r.experiment == experiment && r.claim.text == *c))
}

/// The results of a statement's sources on `preset`, best first (as its `from` lists them).
fn found<'a>(s: &Statement, preset: &str, results: &'a [ClaimResult]) -> Vec<&'a ClaimResult> {
    s.from.iter().filter_map(|source| of_source(results, source).find(|r| r.preset == preset)).collect()
}

/// Whether a level's verdict disagrees with the contrast its sentence implies (the aggregation's note,
/// `aggregate::say_where_a_level_and_its_contrast_disagree`): the contrast decides the paper's sentence.
fn disagrees(r: &ClaimResult) -> bool {
    r.verdict.as_ref().is_some_and(|v| v.text.contains(super::family::DISAGREES))
}

/// Whether a claim's result stands as a verdict (not waiting for its runs).
fn judged(r: &ClaimResult) -> bool {
    r.verdict.as_ref().is_some_and(|v| !matches!(v.outcome, Outcome::InProgress | Outcome::NotRunYet))
}

/// A quantity counted in episodes, shown without decimals.
fn in_episodes(q: &Quantity) -> bool {
    matches!(
        q,
        Quantity::Reach90(_)
            | Quantity::Halfway(_)
            | Quantity::Reaches(..)
            | Quantity::ExtremeEpisode(_)
            | Quantity::Fitted(_, super::file::Fit::Time)
    )
}

/// One cell: the claim's value with the interval its verdict reads and the verdict in short, from the first
/// source judged on `preset`; with the experiment it comes from and its seeds when that is not the first
/// source (the first still running). `link`: the evidence of an experiment, as a Markdown link.
fn cell(s: &Statement, preset: &str, results: &[ClaimResult], link: &dyn Fn(&str) -> String) -> String {
    let found = found(s, preset, results);
    let Some(first) = found.first() else { return "–".into() };
    let Some(r) = found.iter().find(|r| judged(r)) else {
        let word = first.verdict.as_ref().map_or("not judged", |v| short(v.outcome));
        return format!("{word} ({})", link(&first.experiment));
    };
    // Episodes without decimals; on ln(1 + x) a difference is a log ratio, shown as any other number.
    let digits = if in_episodes(&r.claim.quantity) && r.claim.scale == super::file::Scale::Linear { 0 } else { 3 };
    let value = match (r.estimate, r.shown_half_width()) {
        (Some(e), Some(h)) => format!("{:.digits$} ± {h:.digits$}", e.mean),
        (Some(e), None) => format!("{:.digits$}", e.mean),
        (None, _) => String::new(),
    };
    let value = match r.uninformative() {
        Some(why) => format!("{value} ({why})"),
        None => value,
    };
    let word = r.verdict.as_ref().map_or("", |v| short(v.outcome));
    let word = match disagrees(r) {
        true => format!("{word}, its contrast decides"),
        false => word.to_string(),
    };
    let word = match r.claim.exploratory {
        true => format!("{word}, exploratory"),
        false => word,
    };
    let seeds = r.estimate.map_or(0, |e| e.n);
    let waiting = match first.verdict.as_ref().map(|v| v.outcome) {
        Some(Outcome::InProgress) if !std::ptr::eq(*first, *r) => format!("; {} in progress", link(&first.experiment)),
        _ => String::new(),
    };
    // A minus sign, as the paper's column writes it.
    let value = value.replace('-', "−");
    format!("{value} {word} ({}, {seeds} seeds{waiting})", link(&r.experiment)).trim_start().to_string()
}

/// The table with the legend under it, None without [`STATEMENTS`]. `link`: how an experiment's evidence is linked
/// from where the table is written; `definitions`: the terms' page from there.
pub(crate) fn table(
    results: &[ClaimResult],
    link: &dyn Fn(&str) -> String,
    definitions: &str,
) -> crate::error::Result<Option<String>> {
    let Some(StatementsFile { statements, after_table }) = statements(results)? else { return Ok(None) };
    let mut md = answer(&statements, results, definitions);
    // How to read it, before it.
    writeln!(md, "{LEGEND}\n").unwrap();
    md.push_str(
        "| the paper says | setting | paper | coevo, the paper's values (`paper`) | coevo, the authors' code's values (`gym-pps`) |\n\
         |---|---|---|---|---|\n",
    );
    for s in &statements {
        let cells = PRESETS.map(|preset| cell(s, preset, results, link));
        let says = match &s.note {
            Some(note) => format!("{} *({note})*", s.says),
            None => s.says.clone(),
        };
        writeln!(md, "| {} | {} | {} | {} | {} |", says.replace('|', "\\|"), s.setting, s.value, cells[0], cells[1])
            .unwrap();
    }
    if let Some(text) = after_table {
        writeln!(md, "\n{}", text.trim_end()).unwrap();
    }
    Ok(Some(md))
}

/// How to read the table, above it.
const LEGEND: &str = "Each cell: coevo's mean over seeds ± the interval its verdict reads (for a change or a \
     difference, the Holm-adjusted interval of its family; for a level, the plain 95 % interval, while its verdict \
     reads the 90 % interval of the equivalence test, per test, not adjusted over a family), the verdict, and the \
     experiment it comes from with its seeds. ✓ reproduced (an effect detected in the paper's direction with the paper's \
     value inside its interval; a level equivalent to the paper's value within its tolerance, ±0.005 for DoS and ±0.015 for DoA); ✓ \
     equivalent (a claim of no change shown within its margin); ✓ apart from chance (a level the paper gives no number \
     for, told apart from chance); ◐ the paper's direction detected but not its size; ✗ not reproduced (detected the \
     other way, or a level whose 95 % interval lies outside the paper's value ± its tolerance); ? inconclusive or not \
     detected (neither shown nor excluded, or a level neither shown within nor outside its tolerance: not evidence of \
     no effect; \"the paper's size excluded\": its \
     interval rules out an effect as large as the paper's, though not its direction); measured (a level with neither \
     the paper's number nor a chance level to judge it against); in progress (its experiment is judged when all its \
     runs are in); exploratory (its claim was committed only after the first of its runs' results were: the verdict \
     stands as reported, but it was not stated blind, so it is no confirmation). A level marked \"its contrast decides\" is reproduced as a level while the contrast the paper's \
     sentence implies (its own row) is not: the contrast decides, and the answer above counts it undecided. A \
     \"faster\" or \"slower\" row \
     shows the variant's episode minus the standard's: negative is sooner. Every row is of the paper's world-frame \
     observation (`scenes/paper.ron` on each preset); the default scene of `coevo --train` observes in the body frame, \
     and its results are on the book's \"Flocking or herding?\". `paper`: the parameter values the paper states; \
     `gym-pps`: the authors' published code's values wherever they differ from the paper's (the book's \"Scenes and \
     presets\").";

/// Where a book page takes a table from a report: the opening marker names the report (relative to the
/// repository) and its anchor; `coevo --plot all` writes the table between it and [`INLINED_END`] (mdbook's
/// `{{#include}}` would not show on GitHub, where the book is also read).
pub(crate) const INLINED: &str = "<!-- inlined by coevo --plot all from ";
pub(crate) const INLINED_END: &str = "<!-- end of inlined -->";

/// `page` with every inlined table refreshed from its report (`read`, the report's text by its path), or
/// Err naming the marker that names no report or anchor. The text between `<!-- ANCHOR: NAME -->` and
/// `<!-- ANCHOR_END: NAME -->` is the table.
pub fn inline_tables(page: &str, read: &dyn Fn(&str) -> Option<String>) -> std::result::Result<String, String> {
    let mut out = String::new();
    let mut rest = page;
    while let Some(at) = rest.find(INLINED) {
        let head = &rest[at..];
        let line_end = head.find("-->").ok_or("an inlined marker without its -->")? + 3;
        let (report, anchor) = head[INLINED.len()..line_end - 3]
            .trim()
            .rsplit_once(':')
            .ok_or_else(|| format!("{}: not REPORT:ANCHOR", &head[..line_end]))?;
        let end = head.find(INLINED_END).ok_or_else(|| format!("{report}:{anchor}: no {INLINED_END}"))?;
        let text = read(report).ok_or_else(|| format!("{report}: no such report"))?;
        let open = format!("<!-- ANCHOR: {anchor} -->\n");
        let close = format!("<!-- ANCHOR_END: {anchor} -->");
        let from = text.find(&open).ok_or_else(|| format!("{report}: no anchor {anchor:?}"))? + open.len();
        let to = text[from..].find(&close).ok_or_else(|| format!("{report}: {anchor:?} not closed"))? + from;
        out.push_str(&rest[..at]);
        out.push_str(&head[..line_end]);
        out.push_str("\n\n");
        out.push_str(text[from..to].trim_end());
        out.push_str("\n\n");
        out.push_str(INLINED_END);
        rest = &head[end + INLINED_END.len()..];
    }
    out.push_str(rest);
    Ok(out)
}

/// The book's pages that inline a report's table (`inline_tables`).
pub const INLINING_PAGES: [&str; 2] = ["docs/src/results/collective.md", "docs/src/results/observation-frames.md"];

/// The book's page of the table (`table`, linked from the book).
pub(crate) fn book_page(table: &str) -> String {
    // The answer, then the training curves against the paper's levels, then the rows.
    let (answer, rows) = table.split_once("\n\n").unwrap_or(("", table));
    format!(
        "# The paper, claim by claim\n\n<!-- Generated by `coevo --plot all` from {STATEMENTS} and the committed results; do not \
         edit by hand. -->\n\n{answer}\n\n{TERMS}\n\n{FIGURE}\n\nEach statement of Li, Li & Zhao (NJP 2023) that coevo tests, the \
         paper's number, and what came out with the paper's parameter values and with those of the authors' published code. \
         Every row's claims, hypotheses and tests are in `REPRODUCTION.md` and in each experiment's folder (linked), its \
         `REPORT.md`; how the controls separate flocking from herding, and what was found beyond the paper, are on the \
         pages that follow.\n\n{rows}"
    )
}

/// The terms the book page uses, each linked to its definition before its first use (`tests/it/docs.rs`).
const TERMS: &str = "*Every term and mark on this page is defined in [Terms and \
     symbols](../reference/definitions.md): among them [D](../reference/definitions.md#d), the largest distance in the \
     arena; [DoS](../reference/definitions.md#dos) and [DoA](../reference/definitions.md#doa), the paper's order \
     parameters; [milling](../reference/definitions.md#milling); [catches](../reference/definitions.md#catches); the [halfway episode](../reference/definitions.md#halfway) \
     and the episode a [common level](../reference/definitions.md#common-level) is reached; the marks \
     [✓](../reference/definitions.md#marks), [◐](../reference/definitions.md#marks) and \
     [✗](../reference/definitions.md#marks); and an [uninformative](../reference/definitions.md#uninformative) \
     interval.*";

/// The book page's figure: the standard run's training curves with the paper's levels and chance.
const FIGURE: &str = "![The standard experiment's training curves with the authors' code's values: DoS and DoA of the \
     prey, 100-episode running means over ten seeds with 95 % bands, the paper's start and end levels dashed in colour \
     and chance dashed in grey](../../../results/standard/figures/gym-pps-training.svg)\n\n*The standard experiment \
     with the authors' code's values (`gym-pps`, ten seeds): the prey's DoS and DoA over training, the paper's start and \
     end levels dashed in colour, chance in grey; the rows below judge each level and change. The same with the paper's \
     values: `results/standard/figures/paper-training.svg`.*";

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_marked_table_is_written_from_its_reports_anchor_and_a_missing_one_refused() {
        let report = "# r\n<!-- ANCHOR: collective -->\n| a |\n|---|\n| 1 |\n<!-- ANCHOR_END: collective -->\n";
        let read = |path: &str| (path == "results/x/REPORT.md").then(|| report.to_string());
        let page = format!("before\n\n{INLINED}results/x/REPORT.md:collective -->\nstale\n{INLINED_END}\n\nafter\n");
        let inlined = inline_tables(&page, &read).unwrap();
        assert_eq!(
            inlined,
            format!("before\n\n{INLINED}results/x/REPORT.md:collective -->\n\n| a |\n|---|\n| 1 |\n\n{INLINED_END}\n\nafter\n")
        );
        assert_eq!(inline_tables(&inlined, &read).unwrap(), inlined, "written again, the same");
        let other = page.replace(":collective", ":missing");
        assert!(inline_tables(&other, &read).unwrap_err().contains("no anchor"));
        assert!(inline_tables(&page.replace("results/x", "results/y"), &read).unwrap_err().contains("no such report"));
    }
    use crate::experiment::file::Claim;
    use crate::experiment::stats::estimate;
    use crate::experiment::verdict::Verdict;

    fn judged(experiment: &str, preset: &str, outcome: Outcome, samples: &[f64]) -> ClaimResult {
        let claim = Claim { paper: Some(0.19), ..Claim::of("DoS falls to around 19 %", "standard", Quantity::DosLast) };
        ClaimResult {
            estimate: estimate(samples),
            verdict: Some(Verdict::new(outcome, "")),
            ..ClaimResult::untested(experiment, preset, &claim, None)
        }
    }

    #[test]
    fn a_cell_shows_the_first_judged_source_and_what_is_still_running() {
        // Three seeds: every interval here is marked uninformative, as a cell from fewer than five is.
        let s = Statement {
            says: "DoS falls to about 19 %".into(),
            setting: "training".into(),
            value: "0.19".into(),
            note: None,
            from: vec!["sweeps / DoS falls to around 19 %".into(), "standard / DoS falls to around 19 %".into()],
        };
        let link = |e: &str| format!("[{e}]");
        let results = [
            judged("sweeps", "paper", Outcome::InProgress, &[]),
            judged("standard", "paper", Outcome::NotReproduced, &[0.20, 0.21, 0.22]),
            judged("sweeps", "gym-pps", Outcome::Reproduced, &[0.18, 0.19, 0.20]),
            judged("standard", "gym-pps", Outcome::Inconclusive { paper_size_excluded: false }, &[0.1, 0.3]),
        ];
        // The confirmatory source still running gives way to the next, and the cell says it is running.
        assert_eq!(
            cell(&s, "paper", &results, &link),
            "0.210 ± 0.025 (uninformative: 3 seeds) ✗ not reproduced ([standard], 3 seeds; [sweeps] in progress)"
        );
        // Judged, it takes over.
        assert_eq!(
            cell(&s, "gym-pps", &results, &link),
            "0.190 ± 0.025 (uninformative: 3 seeds) ✓ reproduced ([sweeps], 3 seeds)"
        );
        // Nothing judged yet: what the first source says.
        assert_eq!(cell(&s, "paper", &results[..1], &link), "in progress ([sweeps])");
        // A source that names no claim is refused when the statements are read.
        assert!(cell(&s, "other", &results, &link) == "–");
        // A statement no experiment tests shows a dash and is counted apart, not as waiting for runs.
        let untested = Statement { from: vec![], note: Some("not tested: why".into()), ..s.clone() };
        assert_eq!(cell(&untested, "paper", &results, &link), "–");
        let said = answer(&[s.clone(), untested], &results, "definitions.md");
        assert!(said.contains("; 1 is not tested (its row says why)") && !said.contains("waits"), "{said}");
    }
}
