//! Training curves made outside coevo's run folders (another implementation's runs of a scene: the
//! authors' learner on coevo's world, `python/examples/gym_pps_learner.py`), compared with
//! coevo's own as a report compares two variants: the same quantities ([`super::quantity::derive`]), the
//! same test (Welch's difference, TOST within a margin fixed beforehand), Holm over the family
//! ([`super::family::adjust`]), and the same words ([`super::verdict::verdict`]). Nothing here reads a
//! file: the caller hands over each run's per-episode DoS, DoA and catches.

use super::file::{Claim, Quantity};
use super::quantity::{derive, primitive};
use super::results::{is_effect, ClaimResult, RunData, WINDOW};
use super::stats::difference;
use crate::error::{Error, Kind, Result};

/// One pre-registered comparison: `quantity` of the other implementation's runs minus coevo's.
#[derive(Clone, Debug)]
pub struct Comparison {
    /// What it asks, in words.
    pub(crate) text: String,
    /// A training-curve quantity (first or last 100 episodes, the start, the change over training, ...).
    pub(crate) quantity: Quantity,
    /// The equivalence margin: "the same" within ±margin (TOST); None for a two-sided test of a difference.
    pub(crate) margin: Option<f64>,
}

impl Comparison {
    /// A comparison with its quantity as experiment files write it (`DoaLast`, `FromStart("doa")`),
    /// refused unless it is one that training curves of DoS, DoA and catches give.
    pub fn parse(text: &str, quantity: &str, margin: Option<f64>) -> Result<Comparison> {
        let refuse = |message: String| Error::field(format!("quantity of \"{text}\""), message).of_kind(Kind::Input);
        let parsed =
            ron::from_str::<Quantity>(quantity).map_err(|e| refuse(format!("{quantity:?} is not a quantity ({e})")))?;
        if let Some(message) = parsed.curve_argument_error() {
            return Err(refuse(message));
        }
        if !parsed.of_training_curves() {
            return Err(refuse(format!(
                "{quantity:?} is not one of the training curves' quantities (DosFirst, DosLast, DoaFirst, DoaLast, \
                 CatchesFirst, CatchesLast, their Change, and Start, FromStart, Reach90, Halfway, Reaches, Fitted, Extreme, ExtremeEpisode or \
                 AfterExtreme of \"dos\", \"doa\" or \"catches\")"
            )));
        }
        Ok(Comparison { text: text.into(), quantity: parsed, margin })
    }
}

/// A run made elsewhere, as its training curves: per episode, the headline species' DoS and DoA and the
/// catches (what `metrics.csv` logs as `dos_prey`, `doa_prey` and `catches`).
pub fn curves(dos: Vec<f64>, doa: Vec<f64>, catches: Vec<f64>) -> RunData {
    RunData { dos, doa, catches, ..Default::default() }
}

/// The label of the two sides in the verdicts' claims (a claim's `variant` and `versus`).
const THEIRS: &str = "other implementation";
const OURS: &str = "coevo";

/// `comparisons` of `theirs` minus `ours` (a run each: its per-episode `dos`, `doa` and `catches`), as one
/// family named `family`: each estimated, tested, Holm-adjusted and judged. Refused, naming what is
/// wrong: a run whose three curves differ in length or whose length differs from the others' (their
/// windows would be different episodes), a change over training on runs too short for its first and last
/// windows not to overlap, a side with fewer than two runs that give the quantity, a margin that is not a
/// positive number.
pub fn compare(
    family: &str,
    theirs: &[RunData],
    ours: &[RunData],
    comparisons: &[Comparison],
) -> Result<Vec<ClaimResult>> {
    let input = |field: String, message: String| Error::field(field, message).of_kind(Kind::Input);
    let mut episodes = None;
    for (side, runs) in [("theirs", theirs), ("ours", ours)] {
        for (k, d) in runs.iter().enumerate() {
            let n = d.doa.len();
            if d.dos.len() != n || d.catches.len() != n {
                return Err(input(
                    format!("{side}[{k}]"),
                    format!("its curves differ in length (dos {}, doa {n}, catches {})", d.dos.len(), d.catches.len()),
                ));
            }
            let first = *episodes.get_or_insert(n);
            if first != n {
                return Err(input(
                    format!("{side}[{k}]"),
                    format!("{n} episodes, the first run has {first}: their windows would be other episodes"),
                ));
            }
        }
    }
    let episodes = episodes.unwrap_or(0);
    let value = |d: &RunData, q: &Quantity| derive(&[], q, &|p| primitive(d, p));
    let mut results = Vec::new();
    for (i, c) in comparisons.iter().enumerate() {
        let refuse = |message: String| input(format!("comparisons[{i}] ({})", c.text), message);
        if c.margin.is_some_and(|m| !(m.is_finite() && m > 0.0)) {
            return Err(refuse(format!("margin {:?}: must be a positive number", c.margin)));
        }
        if c.quantity.compares_windows() && episodes < 2 * WINDOW {
            return Err(refuse(format!(
                "{:?} compares the first and last {WINDOW} episodes, which overlap in runs of {episodes} episodes",
                c.quantity
            )));
        }
        let samples =
            |runs: &[RunData]| runs.iter().map(|d| value(d, &c.quantity)).filter(|x| x.is_finite()).collect::<Vec<_>>();
        let (a, b) = (samples(theirs), samples(ours));
        if let Some((side, n)) = [("theirs", a.len()), ("ours", b.len())].into_iter().find(|&(_, n)| n < 2) {
            return Err(refuse(format!(
                "{:?} has a value in {n} of {side} runs (every value NaN, or too few runs): an interval needs two",
                c.quantity
            )));
        }
        let claim = Claim {
            versus: Some(OURS.into()),
            margin: c.margin,
            family: Some(family.into()),
            ..Claim::of(&c.text, THEIRS, c.quantity.clone())
        };
        debug_assert!(is_effect(&claim));
        let estimate = difference(&a, &b);
        let p = estimate.and_then(|e| e.test_p(c.margin));
        results.push(ClaimResult {
            estimate,
            p,
            // Each comparison its own test: no two are counted once, even if their samples agree.
            same_test: p.map(|_| (vec![i as u64], None, None)),
            ..ClaimResult::untested(family, "", &claim, None)
        });
    }
    super::family::adjust(&mut results);
    Ok(results)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::experiment::file::Curve;

    fn run(doa: f64, catches: f64) -> RunData {
        // 200 episodes: the first 100 at 0.5 below the last 100.
        let series = |last: f64, first: f64| (0..200).map(|e| if e < 100 { first } else { last }).collect();
        curves(series(0.2, 0.25), series(doa, doa - 0.5), series(catches, 70.0))
    }

    #[test]
    fn curves_made_elsewhere_are_judged_as_a_report_judges_two_variants() {
        let theirs: Vec<RunData> = [0.80, 0.81, 0.82, 0.80].iter().map(|&d| run(d, 30.0 + d)).collect();
        let ours: Vec<RunData> = [0.80, 0.82, 0.81, 0.81, 0.80].iter().map(|&d| run(d, 60.0 + d)).collect();
        let comparisons = [
            Comparison { text: "DoA at the end, the same".into(), quantity: Quantity::DoaLast, margin: Some(0.05) },
            Comparison { text: "catches at the end".into(), quantity: Quantity::CatchesLast, margin: None },
            Comparison { text: "DoA's rise".into(), quantity: Quantity::DoaChange, margin: Some(0.05) },
        ];
        let results = compare("a family", &theirs, &ours, &comparisons).unwrap();
        let a: Vec<f64> = [0.80, 0.81, 0.82, 0.80].into();
        let b: Vec<f64> = [0.80, 0.82, 0.81, 0.81, 0.80].into();
        let e = difference(&a, &b).unwrap();
        assert!((results[0].estimate.unwrap().mean - e.mean).abs() < 1e-12);
        assert_eq!(results[0].p, e.tost_p(0.05));
        assert!(results.iter().all(|r| r.family_tests == 3), "one family of three tests");
        assert!(results[0].verdict_text().starts_with("equivalent within ±0.05"), "{}", results[0].verdict_text());
        // 30 fewer catches, every seed: a difference, detected.
        assert!((results[1].estimate.unwrap().mean + 30.0).abs() < 0.01);
        assert!(results[1].verdict_text().starts_with("effect detected: -30.0"), "{}", results[1].verdict_text());
        // A change over training: the same rise of 0.5 on every run, exactly (no spread): equivalent.
        assert!(results[2].estimate.unwrap().mean.abs() < 1e-12);
    }

    #[test]
    fn what_curves_cannot_answer_is_refused() {
        let runs = vec![run(0.8, 30.0), run(0.81, 31.0)];
        let message = |theirs: &[RunData], c: Comparison| compare("f", theirs, &runs, &[c]).unwrap_err().to_string();
        // An evaluation's quantity: no value in curves.
        let eval = Comparison { text: "settled".into(), quantity: Quantity::EvalDoa("50 prey".into()), margin: None };
        let m = message(&runs, eval);
        assert!(m.starts_with("comparisons[0] (settled): EvalDoa(\"50 prey\") has a value in 0 of theirs runs"), "{m}");
        // A margin that is not a positive number.
        let margin = Comparison::parse("m", "DoaLast", Some(-0.1)).unwrap();
        assert!(message(&runs, margin).contains("must be a positive"));
        // One run: no interval.
        let last = Comparison::parse("l", "DoaLast", None).unwrap();
        assert!(message(&runs[..1], last.clone()).contains("has a value in 1 of theirs runs"));
        // Runs of other lengths, or a run whose curves differ in length.
        let mut short = run(0.8, 30.0);
        short.doa.pop();
        let m = message(&[runs[0].clone(), short.clone()], last.clone());
        assert!(m.starts_with("theirs[1]: its curves differ in length (dos 200, doa 199, catches 200)"), "{m}");
        short.dos.pop();
        short.catches.pop();
        let m = message(&[runs[0].clone(), short.clone()], last.clone());
        assert!(m.starts_with("theirs[1]: 199 episodes, the first run has 200"), "{m}");
        // A change over training on runs whose windows overlap.
        let cut = |d: &RunData| curves(d.dos[..150].into(), d.doa[..150].into(), d.catches[..150].into());
        let (a, b): (Vec<_>, Vec<_>) = (runs.iter().map(cut).collect(), runs.iter().map(cut).collect());
        let m = compare("f", &a, &b, &[Comparison::parse("c", "DoaChange", None).unwrap()]).unwrap_err().to_string();
        assert!(m.contains("overlap in runs of 150 episodes"), "{m}");
        // Quantities as experiment files write them; what curves do not give, refused when parsed.
        assert_eq!(
            Comparison::parse("r", "FromStart(\"doa\")", None).unwrap().quantity,
            Quantity::FromStart(Curve::Doa)
        );
        let unknown = Comparison::parse("x", "DoaPeak", None).unwrap_err().to_string();
        assert!(unknown.starts_with("quantity of \"x\": \"DoaPeak\" is not a quantity"), "{unknown}");
        let catches = Comparison::parse("x", "Reach90(\"catches\")", None).unwrap_err().to_string();
        assert!(catches.contains("Reach90 takes \"dos\" or \"doa\""), "{catches}");
        let evaluation = Comparison::parse("x", "EvalDoa(\"50 prey\")", None).unwrap_err().to_string();
        assert!(evaluation.contains("is not one of the training curves' quantities"), "{evaluation}");
        let authors = Comparison::parse("x", "Start(\"authors_doa\")", None).unwrap_err().to_string();
        assert!(authors.contains("is not one of the training curves' quantities"), "{authors}");
    }
}
