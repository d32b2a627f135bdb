//! From the runs' CSV files alone (never retraining): the paper's claims checked on the per-run values,
//! with the summaries (`summary.rs`) and figures (`figures.rs`) written beside them.

use super::carry;
use super::figure_data;
use super::figures;
use super::file::Experiment;
use super::quantity::chance_level;
use super::registry;
use super::results::{is_effect, ClaimResult, RunData, WINDOW};
use super::stats::{difference, estimate};
use super::summary::{self, Summary};
use super::verdict::{Outcome, Verdict};
use std::collections::BTreeMap;

/// Estimates an experiment's claims on the `data` of its finished runs ([`super::data::load`]) and, when
/// there are any, writes its summaries and figures. The results are not yet judged: [`adjust`] does that
/// over their families, which may span experiment files. Claims with no run yet say so. `carried`: the
/// committed runs finished elsewhere, written beside the folders here ([`super::data::check_complete`]).
pub(crate) fn aggregate(
    exp: &Experiment,
    data: &BTreeMap<usize, RunData>,
    carried: carry::Carried,
) -> crate::error::Result<Aggregated> {
    let written = !data.is_empty();
    let quantities = summary::columns(exp);
    let summary = summary::text(exp, data, &quantities, &carried.lines);

    // The claims are computed from the per-run values alone (summary.csv), so that a clone without run
    // folders recomputes them from the committed summary exactly.
    let table = if written {
        Summary::parse(&summary, &exp.summary_path())?
    } else {
        Summary::read(&exp.summary_path())?.unwrap_or_default()
    };
    if written {
        // An experiment whose runs are all shared from others (`shared_from`) has trained nothing into
        // its own folder: its results are the first thing there.
        crate::io::own_dir(&exp.root)?;
    }
    let drawn = figures::data(exp, data, carried.figures, &table, written)?;
    // No interim analysis: an experiment judged when complete shows no number or figure of its runs
    // until then (so no folder for figures either).
    let blind = in_progress(exp, &table);
    if drawn.is_some() && !blind {
        crate::io::own_dir(&exp.figures_dir())?;
    }
    // A committed summary written before the curve columns existed gains them from the committed curves.
    let extended = match (&drawn, written) {
        (Some(curves), false) => with_curve_columns(exp, &table, curves)?,
        _ => None,
    };
    let extended_summary = extended.is_some();
    let table = match extended {
        Some((text, extended)) => {
            crate::io::write_file(&exp.summary_path(), crate::io::Existing::Replace, text.as_bytes())?;
            extended
        }
        None => table,
    };
    let means = if blind {
        summary::means_text(exp, &Summary::default(), &quantities)
    } else {
        summary::means_text(exp, &table, &quantities)
    };
    let mut results = tests(exp, &table);
    let mut saved = 0;
    if let Some(drawn) = drawn.as_ref().filter(|_| !blind) {
        for preset in &exp.spec.presets {
            figures::draw(exp, preset, &table, drawn, &mut saved)?;
        }
    }
    if written {
        // The figure data before the summary it must match: a write that fails between them leaves the
        // old summary, which the next aggregation finds incomplete, never a new summary beside old curves.
        figure_data::write(exp, drawn.as_ref().expect("drawn from the run folders"))?;
        crate::io::write_file(&exp.summary_path(), crate::io::Existing::Replace, summary.as_bytes())?;
        crate::io::write_file(
            &exp.root.join(super::load::SUMMARY_MEAN),
            crate::io::Existing::Replace,
            means.as_bytes(),
        )?;
        let kernels =
            |i: usize| data.get(&i).map(|d| &d.kernels).or(carried.kernels.get(&i)).cloned().unwrap_or_default();
        let ledger = carry::text(exp, table.runs(exp).into_iter().map(|(i, _)| (i, kernels(i))));
        crate::io::write_file(&exp.root.join(carry::FILE), crate::io::Existing::Replace, ledger.as_bytes())?;
    }
    // Results without a record of their claims (aggregated before coevo kept one): the record begins with
    // the claims as they stand now. Otherwise the record is the runner's, made when the runs started.
    if !table.rows.is_empty() && !exp.root.join(registry::FILE).exists() {
        registry::record(exp, &|_| false)?;
    }
    let recorded = registry::read(&exp.root)?;
    for r in &mut results {
        r.stated = registry::stated(&r.claim, &exp.spec.claims, recorded.as_deref());
    }
    Ok(Aggregated {
        results,
        summary: table,
        figures: drawn.is_some().then_some(saved),
        from_folders: written,
        extended: extended_summary,
    })
}

/// What [`aggregate`] found, and what it wrote.
pub(crate) struct Aggregated {
    /// Estimated and tested, not yet adjusted or judged ([`adjust`]).
    pub(crate) results: Vec<ClaimResult>,
    /// The per-run values the claims were computed from (written now, or the committed summary.csv).
    pub(crate) summary: Summary,
    /// How many figures it drew (each as .svg and .png): from the run folders, or in a clone from the
    /// committed figure data. None when it drew none (a clone of a commit without figure data).
    pub(crate) figures: Option<usize>,
    /// Whether the run folders were here, so summary.csv, summary-mean.csv and figure-data.ron.gz were
    /// written from them (else the committed ones were read and left as they are).
    pub(crate) from_folders: bool,
    /// Whether a committed summary.csv was extended with its curve columns ([`summary::extend`]).
    pub(crate) extended: bool,
}

/// The verdict on a change over training (or a curve's shape) of runs shorter than two windows.
const OVERLAP: &str =
    "not measured: runs shorter than 200 episodes, too short for a change over training (windows that overlap)";

/// Whether an experiment judged when complete (`judged_when_complete`) has runs still to finish: then no
/// estimate, verdict, mean or figure of its runs is shown (no interim analysis).
pub fn in_progress(exp: &Experiment, table: &Summary) -> bool {
    exp.spec.judged_when_complete && table.runs(exp).len() < exp.runs.len()
}

/// The verdict on a comparison of two variants whose runs are identical.
const IDENTICAL: &str = "not a comparison: the two variants' runs are identical (one training, run twice)";

/// The tests of an experiment from its committed summary.csv (extended in memory with its curve columns
/// from the committed figure data, as [`aggregate`] extends it), without writing anything: another file's
/// tests, for the families a report shares with it.
pub(crate) fn committed_tests(exp: &Experiment) -> crate::error::Result<Vec<ClaimResult>> {
    let Some(table) = Summary::read(&exp.summary_path())? else {
        return Ok(tests(exp, &Summary::default()));
    };
    let indices: Vec<usize> = table.runs(exp).iter().map(|(i, _)| *i).collect();
    let curves = if indices.is_empty() { None } else { super::figure_data::read(exp, &indices)? };
    let table = match curves {
        Some(curves) => with_curve_columns(exp, &table, &curves)?.map_or(table, |(_, extended)| extended),
        None => table,
    };
    Ok(tests(exp, &table))
}

/// The committed summary.csv (`table`) with its curve columns, when it was written before them
/// ([`summary::extend`], from the committed `curves`): the extended text and its table; None when it has
/// them already.
fn with_curve_columns(
    exp: &Experiment,
    table: &Summary,
    curves: &BTreeMap<usize, figure_data::FigureData>,
) -> crate::error::Result<Option<(String, Summary)>> {
    let path = exp.summary_path();
    let text = crate::io::read_text(&path, crate::io::MAX_TEXT_BYTES)?;
    match summary::extend(exp, &text, table, curves) {
        Some(text) => {
            let extended = Summary::parse(&text, &path)?;
            Ok(Some((text, extended)))
        }
        None => Ok(None),
    }
}

/// Every claim of `exp` on every preset, estimated and tested on the per-run values of `table` (the
/// experiment's summary.csv): its estimate and unadjusted p-value, not yet adjusted or judged.
pub(crate) fn tests(exp: &Experiment, table: &Summary) -> Vec<ClaimResult> {
    let mut results = Vec::new();
    // A claim of a preset, not yet estimated, tested or judged; its chance level from the variant's scene.
    let untested = |preset: &String, claim: &super::file::Claim| {
        let scene = exp.runs.iter().find(|r| r.preset == *preset && r.variant == claim.variant).map(|r| &r.scene);
        ClaimResult::untested(&exp.name, preset, claim, chance_level(exp, claim, scene))
    };
    // An experiment judged when complete, in progress: every claim says so, untested (no interim analysis),
    // also where another file's report reads its committed summary for a shared family.
    if in_progress(exp, table) {
        let verdict = Verdict::new(
            Outcome::InProgress,
            format!(
                "in progress: {} of {} runs finished; judged when all are (no interim analysis)",
                table.runs(exp).len(),
                exp.runs.len()
            ),
        );
        for preset in &exp.spec.presets {
            for claim in &exp.spec.claims {
                results.push(ClaimResult { verdict: Some(verdict.clone()), ..untested(preset, claim) });
            }
        }
        return results;
    }
    for preset in &exp.spec.presets {
        for claim in &exp.spec.claims {
            // On the claim's scale (ln(1 + x) for heavy-tailed counts), fixed with its hypothesis.
            let samples = |variant: &str| -> Vec<f64> {
                let values = table.values(exp, preset, variant, &claim.quantity).into_iter();
                values.map(|x| claim.scale.of(x)).filter(|x| x.is_finite()).collect()
            };
            if let Some(test) = &claim.grid {
                let t = super::grid::test(&exp.spec, claim, test, &samples);
                results.push(ClaimResult {
                    estimate: t.estimate,
                    p: t.p,
                    same_test: t.reads,
                    resamples: t.resamples,
                    ..untested(preset, claim)
                });
                continue;
            }
            let (ours, theirs) = (samples(&claim.variant), claim.versus.as_deref().map(samples));
            // Two variants whose runs are identical (a deterministic re-run, e.g. a switch that never acts)
            // are one sample, not two: no comparison, no p-value.
            let identical = theirs.as_ref().is_some_and(|t| t.len() >= 2 && *t == ours);
            // A change over training needs a first and a last window that do not overlap.
            let overlap = claim.quantity.compares_windows()
                && std::iter::once(&claim.variant)
                    .chain(&claim.versus)
                    .any(|v| table.episodes(preset, v).is_some_and(|n| n < 2 * WINDOW));
            let identical = identical || overlap;
            let e = match &theirs {
                Some(t) => difference(&ours, t),
                None => estimate(&ours),
            };
            // The claim's own test: TOST for a claim of no effect, else the two-sided test of none.
            let p = e.filter(|_| is_effect(claim) && !identical).and_then(|e| e.test_p(claim.margin));
            // What the test reads, to the bit: two claims of one family that read the same samples in the
            // same way are one test.
            let same_test = p.map(|_| {
                let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                (bits(&ours), theirs.as_deref().map(bits), claim.margin.map(f64::to_bits))
            });
            let verdict = match (overlap, identical) {
                (true, _) => Some(Verdict::new(Outcome::NotMeasured, OVERLAP)),
                (false, true) => Some(Verdict::new(Outcome::NotAComparison, IDENTICAL)),
                _ => None,
            };
            let caveat = caveat(exp, table, preset, claim);
            results.push(ClaimResult { estimate: e, p, same_test, verdict, caveat, ..untested(preset, claim) });
        }
    }
    results
}

/// What a reader of a verdict must know of its samples: how many runs of an arm have no value (left out of
/// the test: a curve a fit could not be made to, a quantity undefined in that run), and for a fitted time
/// constant how many sit at the fit's cap ([`super::curves::FIT_LONGEST`] × the episodes), which the test
/// reads as the slowest approach although such a curve may not approach at all within the run (it drifts,
/// or moves the other way). None when there is nothing to say.
fn caveat(exp: &Experiment, table: &Summary, preset: &str, claim: &super::file::Claim) -> Option<String> {
    let arms: Vec<(&str, Vec<f64>)> = std::iter::once(claim.variant.as_str())
        .chain(claim.versus.as_deref())
        .map(|variant| (variant, table.values(exp, preset, variant, &claim.quantity)))
        .collect();
    let mut said = String::new();
    let missing: Vec<String> = arms
        .iter()
        .filter_map(|(v, values)| {
            let left_out = values.iter().filter(|x| !x.is_finite()).count();
            (left_out > 0).then(|| format!("{left_out} of {} runs of `{v}`", values.len()))
        })
        .collect();
    if !missing.is_empty() {
        said.push_str(&format!("; without a value, left out: {}", missing.join(" and ")));
    }
    if let super::file::Quantity::Fitted(_, super::file::Fit::Time) = claim.quantity {
        let capped: Vec<(&str, usize, usize)> = arms
            .iter()
            .map(|(variant, values)| {
                let cap = 0.99 * super::curves::FIT_LONGEST * table.episodes(preset, variant).unwrap_or(0) as f64;
                let n = values.iter().filter(|x| x.is_finite()).count();
                (*variant, values.iter().filter(|&&x| x >= cap).count(), n)
            })
            .collect();
        if capped.iter().any(|&(_, c, _)| c > 0) {
            let arms: Vec<String> = capped.iter().map(|(v, c, n)| format!("{c} of {n} runs of `{v}`")).collect();
            said.push_str(&format!(
                "; at the fit's cap (no approach within the run, read as the slowest): {}",
                arms.join(" and ")
            ));
        }
    }
    (!said.is_empty()).then_some(said)
}

#[cfg(test)]
mod tests {
    use super::{tests, Experiment, Summary};
    use crate::claims::family::adjust;
    use crate::claims::results::tests::{claim, tested};
    use crate::experiment::file::Quantity;
    use crate::experiment::stats::holm;
    use std::path::Path;

    #[test]
    fn a_named_family_spans_files_and_a_repeated_test_counts_once() {
        let named = |text: &str, family: Option<&str>| {
            let mut c = claim(Quantity::InteractionDoa("x".into()), None, None);
            c.text = text.into();
            c.family = family.map(String::from);
            c
        };
        let samples: [&[f64]; 4] = [
            &[0.15, 0.18, 0.20, 0.16, 0.19],
            &[0.05, -0.01, 0.08, 0.02, 0.04],
            &[0.09, 0.01, 0.06, 0.1, 0.03],
            &[0.4, -0.3, 0.25, -0.2, 0.1],
        ];
        let mut results = vec![
            // "shared" in two files: a, b and b's repeat of a's first test (the same samples).
            tested(&named("a1", Some("shared")), "a", samples[0]),
            tested(&named("a2", Some("shared")), "a", samples[1]),
            tested(&named("b1", Some("shared")), "b", samples[2]),
            tested(&named("b2", Some("shared")), "b", samples[0]),
            // Unnamed: each file its own family, although b's test is the same as a's.
            tested(&named("a3", None), "a", samples[3]),
            tested(&named("b3", None), "b", samples[3]),
        ];
        let p: Vec<f64> = results.iter().map(|r| r.p.unwrap()).collect();
        adjust(&mut results);
        let across = holm(&[p[0], p[1], p[2]]);
        for (i, expected) in [(0, across[0]), (1, across[1]), (2, across[2]), (3, across[0]), (4, p[4]), (5, p[5])] {
            assert_eq!(results[i].p_holm, Some(expected), "{}", results[i].claim.text);
        }
        assert_eq!(results.iter().map(|r| r.family_tests).collect::<Vec<_>>(), [3, 3, 3, 3, 1, 1]);
        assert_eq!(results[3].same_as.as_deref(), Some("a / p / a1"));
        assert_eq!(results[3].level, results[0].level);
        assert!(results[3].verdict_text().ends_with("the same test as a / p / a1, counted once in its family"));
        assert!(results[5].same_as.is_none(), "another family's test is not a repeat");
        assert!(results.iter().all(|r| !r.verdict_text().is_empty()), "every claim judged");
    }

    #[test]
    fn a_level_that_contradicts_its_contrast_says_so() {
        // "At R = D/3 DoA drops to 0.75, against 0.82 at R = D": a level that reaches 0.75 and a contrast
        // that goes the other way.
        let mut level = claim(Quantity::DoaLast, Some(0.75), None);
        level.text = "R = D/3: DoA drops to 0.75".into();
        let mut contrast = claim(Quantity::DoaLast, Some(-0.07), None);
        contrast.text = "R = D/3 against R = D: DoA lower".into();
        contrast.versus = Some("R = D".into());
        let mut results = vec![
            tested(&level, "perception", &[0.74, 0.75, 0.76, 0.75, 0.755]),
            tested(&contrast, "perception", &[0.10, 0.12, 0.09, 0.11, 0.1]),
        ];
        results[0].p = None;
        results[0].baseline = Some(std::f64::consts::FRAC_2_PI);
        adjust(&mut results);
        assert!(results[0].verdict_text().starts_with("reproduced"), "{}", results[0].verdict_text());
        assert!(results[1].verdict_text().starts_with("not reproduced"), "{}", results[1].verdict_text());
        assert!(
            results[0].verdict_text().ends_with(
                "disagrees with the primary contrast \"R = D/3 against R = D: DoA lower\" (not reproduced): the contrast decides the paper's sentence"
            ),
            "{}",
            results[0].verdict_text()
        );
        assert!(results[1]
            .verdict_text()
            .contains("its secondary level row \"R = D/3: DoA drops to 0.75\" is reproduced"));
        // When both agree, neither says more.
        let mut agreeing =
            vec![results[0].clone(), tested(&contrast, "perception", &[-0.06, -0.08, -0.07, -0.075, -0.065])];
        agreeing[0].verdict = None;
        adjust(&mut agreeing);
        assert!(!agreeing
            .iter()
            .any(|r| r.verdict_text().contains("disagrees") || r.verdict_text().contains("secondary level")));
    }

    #[test]
    fn a_fitted_time_says_how_many_runs_sit_at_the_fits_cap() {
        // The committed convergence-rates runs: with `paper`, 9 of the 20 one-predator DoS fits and 1 of the
        // 20 standard ones sit at the cap (a review recomputed these from summary.csv).
        let exp = Experiment::load(Path::new("experiments/convergence-rates.ron"), Path::new("results")).unwrap();
        let table = Summary::read(&exp.summary_path()).unwrap().unwrap();
        let results = tests(&exp, &table);
        let caveat = |text: &str| {
            let r = results.iter().find(|r| r.preset == "paper" && r.claim.text == text).unwrap();
            r.caveat.clone().unwrap_or_default()
        };
        let slower = caveat("one predator against three: DoS falls slower (fitted time constant longer)");
        assert!(slower.contains("9 of 20 runs of `n0 = 1` and 1 of 20 runs of `standard`"), "{slower}");
        // Not a time constant: nothing at a cap, and every run has a value.
        assert_eq!(caveat("one predator against three: DoS's fitted end level (secondary)"), "");
    }
}
