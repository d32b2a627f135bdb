//! Training curves made outside coevo's run folders (another implementation's runs of a scene: the
//! authors' learner on coevo's world, `python/examples/gym_pps_learner.py`, issue 37), compared with
//! coevo's own as a report compares two variants: the same quantities ([`super::claims::derive`]), the
//! same test (Welch's difference, TOST within a margin fixed beforehand), Holm over the family
//! ([`super::aggregate::adjust`]), and the same words ([`super::claims::verdict`]). Nothing here reads a
//! file: the caller hands over each run's per-episode DoS, DoA and catches.

use super::claims::{derive, is_effect, primitive, ClaimResult, RunData};
use super::file::{Claim, Quantity};
use super::registry::Stated;
use super::stats::difference;
use crate::error::{Error, Kind, Result};

/// One pre-registered comparison: `quantity` of the other implementation's runs minus coevo's.
#[derive(Clone, Debug)]
pub struct Comparison {
    /// What it asks, in words.
    pub text: String,
    /// A training-curve quantity (first or last 100 episodes, the start, the change over training, ...).
    pub quantity: Quantity,
    /// The equivalence margin: "the same" within ±margin (TOST); None for a two-sided test of a difference.
    pub margin: Option<f64>,
}

impl Comparison {
    /// A comparison with its quantity as experiment files write it (`DoaLast`, `FromStart("doa")`).
    pub fn parse(text: &str, quantity: &str, margin: Option<f64>) -> Result<Comparison> {
        let quantity = ron::from_str::<Quantity>(quantity).map_err(|e| {
            Error::field(format!("quantity of \"{text}\""), format!("{quantity:?} is not a quantity ({e})"))
                .of_kind(Kind::Input)
        })?;
        Ok(Comparison { text: text.into(), quantity, margin })
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
/// family named `family`: each estimated, tested, Holm-adjusted and judged. Refused, naming the
/// comparison, when a quantity is not one of training curves (it needs an evaluation) or a side has no
/// run that gives it a value.
pub fn compare(
    family: &str,
    theirs: &[RunData],
    ours: &[RunData],
    comparisons: &[Comparison],
) -> Result<Vec<ClaimResult>> {
    let value = |d: &RunData, q: &Quantity| derive(&[], q, &|p| primitive(d, p));
    let mut results = Vec::new();
    for (i, c) in comparisons.iter().enumerate() {
        let refuse =
            |message: String| Error::field(format!("comparisons[{i}] ({})", c.text), message).of_kind(Kind::Input);
        if c.margin.is_some_and(|m| !(m.is_finite() && m > 0.0)) {
            return Err(refuse(format!("margin {:?}: must be a positive number", c.margin)));
        }
        let samples =
            |runs: &[RunData]| runs.iter().map(|d| value(d, &c.quantity)).filter(|x| x.is_finite()).collect::<Vec<_>>();
        let (a, b) = (samples(theirs), samples(ours));
        if a.is_empty() || b.is_empty() {
            return Err(refuse(format!(
                "{:?} has no value in {} of these runs (only training-curve quantities compare: the first or last \
                 100 episodes, the start, the change)",
                c.quantity,
                if a.is_empty() { "the other implementation's" } else { "coevo's" }
            )));
        }
        let claim = Claim {
            text: c.text.clone(),
            variant: THEIRS.into(),
            quantity: c.quantity.clone(),
            paper: None,
            versus: Some(OURS.into()),
            margin: c.margin,
            baseline: None,
            direction_only: false,
            family: Some(family.into()),
        };
        debug_assert!(is_effect(&claim));
        let estimate = difference(&a, &b);
        let p = estimate.and_then(|e| match c.margin {
            Some(m) => e.tost_p(m),
            None => e.p_value(),
        });
        results.push(ClaimResult {
            experiment: family.into(),
            preset: String::new(),
            claim,
            estimate,
            p,
            p_holm: None,
            level: None,
            family_tests: 0,
            // Each comparison its own test: no two are counted once, even if their samples agree.
            same_test: p.map(|_| (vec![i as u64], None, None)),
            same_as: None,
            stated: Stated::Unknown,
            baseline: None,
            verdict: String::new(),
        });
    }
    super::aggregate::adjust(&mut results);
    Ok(results)
}

#[cfg(test)]
mod tests {
    use super::*;

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
        assert!(results[0].verdict.starts_with("equivalent within ±0.05"), "{}", results[0].verdict);
        // 30 fewer catches, every seed: a difference, detected.
        assert!((results[1].estimate.unwrap().mean + 30.0).abs() < 0.01);
        assert!(results[1].verdict.starts_with("effect detected: -30.0"), "{}", results[1].verdict);
        // A change over training: the same rise of 0.5 on every run, exactly (no spread): equivalent.
        assert!(results[2].estimate.unwrap().mean.abs() < 1e-12);
    }

    #[test]
    fn a_quantity_curves_do_not_give_and_a_bad_margin_are_refused() {
        let runs = vec![run(0.8, 30.0), run(0.81, 31.0)];
        let eval = Comparison { text: "settled".into(), quantity: Quantity::EvalDoa("50 prey".into()), margin: None };
        let message = compare("f", &runs, &runs, &[eval]).unwrap_err().to_string();
        assert!(message.starts_with("comparisons[0] (settled): EvalDoa"), "{message}");
        assert!(message.contains("only training-curve quantities"), "{message}");
        let margin = Comparison::parse("m", "DoaLast", Some(-0.1)).unwrap();
        assert!(compare("f", &runs, &runs, &[margin]).unwrap_err().to_string().contains("must be a positive"));
        assert_eq!(
            Comparison::parse("r", "FromStart(\"doa\")", None).unwrap().quantity,
            Quantity::FromStart("doa".into())
        );
        let unknown = Comparison::parse("x", "DoaPeak", None).unwrap_err().to_string();
        assert!(unknown.starts_with("quantity of \"x\": \"DoaPeak\" is not a quantity"), "{unknown}");
    }
}
