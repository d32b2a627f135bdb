//! What an experiment measures and concludes: the data of a run read from its CSV files ([`RunData`]),
//! the quantities computed from it ([`quantity`]), their names in reports, and a claim's result
//! ([`ClaimResult`], judged by [`super::verdict`]).

use super::file::Claim;
use super::stats::Estimate;
use crate::sim::metrics::Swarming;
use std::collections::BTreeMap;

/// A run's episodes (prey, or the headline species) and its evaluations.
#[derive(Clone, Debug, Default)]
pub struct RunData {
    pub(crate) dos: Vec<f64>,
    pub(crate) doa: Vec<f64>,
    pub(crate) catches: Vec<f64>,
    pub(crate) returns: Vec<f64>,
    /// The other per-episode order parameters by name ([`super::file::EVAL_ORDER`]); NaN for episodes (or
    /// runs) written before they were measured.
    pub(crate) orders: BTreeMap<String, Vec<f64>>,
    pub(crate) wall_seconds: f64,
    /// The executables that made the run (`provenance.ron`; "unknown" before provenance files).
    pub(crate) binaries: Vec<String>,
    /// The family of matrix-product kernels it ran on (`provenance.ron`; empty when not recorded): the
    /// same binary computes other numbers on another family.
    pub(crate) kernels: String,
    /// Per evaluation, by name.
    pub(crate) evals: BTreeMap<String, EvalData>,
    /// The read-outs of the run's cross-play (`crossplay-readouts.csv`) by name, when it has one.
    pub(crate) crossplay: BTreeMap<String, f64>,
    /// The numbers of the rules fitted to it (`distilled.ron`) by species, form and name
    /// ([`super::distill::numbers`]), when it has them.
    pub(crate) distilled: BTreeMap<(String, crate::scene::RuleForm, String), f64>,
}

/// One evaluation of a run.
#[derive(Clone, Debug, Default)]
pub(crate) struct EvalData {
    /// Per order parameter of [`Swarming::NAMES`] (DoS, DoA, polarization, ...): its value per step,
    /// averaged over the evaluation's episodes (NaN throughout for columns an older coevo did not write).
    pub(crate) per_step: Vec<Vec<f64>>,
    /// Mean edge rank over the evaluation's steps with a ranked catch, each step's own mean (NaN without one).
    pub(crate) edge_rank: f64,
    /// Catches per prey per episode over the whole evaluation ([`Quantity::EvalCatches`]).
    pub(crate) catches_per_prey: f64,
    /// The confusion curve of the first predator species in `<eval>-confusion.csv`, per bin of prey in
    /// view: mean |turn command|, mean speed / max speed, catches per predator-step (NaN for empty bins;
    /// empty when the file is absent).
    pub(crate) confusion: Vec<[f64; 3]>,
    /// With a perturbation: the near and far responses ([`Quantity::Response`]); NaN otherwise.
    pub(crate) response: [f64; 2],
    /// Each [`super::file::Tactic`] in the order of `Tactic::ALL` (NaN where the files give none: an older
    /// coevo wrote no `-pursuit` file).
    pub(crate) tactics: [f64; super::file::Tactic::ALL.len()],
}

impl EvalData {
    pub(crate) fn series(&self, name: &str) -> &[f64] {
        Swarming::NAMES.iter().position(|n| *n == name).and_then(|i| self.per_step.get(i)).map_or(&[], |v| v.as_slice())
    }
}

/// The paper's running-mean window, in episodes (owned by `sim::metrics`, beside the running mean).
pub(crate) use crate::sim::metrics::WINDOW;

/// Steps at the end of an evaluation episode averaged as its settled state.
pub(crate) const SETTLED_STEPS: usize = 50;

pub(crate) use super::curves::{window_mean, AUTHORS_CURVES, CURVES, HALFWAY_WINDOW};

/// A claim checked on one preset.
#[derive(Clone, Debug)]
pub struct ClaimResult {
    pub(crate) experiment: String,
    pub(crate) preset: String,
    pub claim: Claim,
    pub estimate: Option<Estimate>,
    /// For an effect: the two-sided p-value of "no effect" (TOST's for a claim of no effect), and Holm's
    /// adjustment of it over its family ([`super::family::adjust`]).
    pub p: Option<f64>,
    pub p_holm: Option<f64>,
    /// For an effect: the level α_k at which its interval is shown, so that the interval excludes zero
    /// exactly when Holm's procedure detects it ([`super::stats::holm_levels`]); for a claim of no effect
    /// its TOST interval is the (1 − 2α_k) one.
    pub level: Option<f64>,
    /// How many tests its family holds, across every experiment file that names it (0 when untested).
    pub(crate) family_tests: usize,
    /// What its test reads, to the bit (its samples and margin): tests of one family that read the same
    /// are one test ([`super::family::adjust`]). None when untested.
    pub(crate) same_test: Option<SameTest>,
    /// The test of its family it repeats ("experiment / preset / claim"), counted once.
    pub(crate) same_as: Option<String>,
    /// Whether it stands as recorded with its results ([`super::registry`]).
    pub(crate) stated: super::registry::Stated,
    /// For a level: the value chance alone gives ([`chance_level`]).
    pub(crate) baseline: Option<f64>,
    /// None until it is judged ([`super::family::adjust`]), or given before its test (in progress,
    /// identical runs, windows that overlap).
    pub(crate) verdict: Option<super::verdict::Verdict>,
    /// A grid's boundary or its shift: its bootstrap resamples, sorted (`grid::Tested`), whose
    /// percentiles are its interval at its family-adjusted level.
    pub(crate) resamples: Option<Vec<f64>>,
    /// What a reader of its verdict must know of its samples, said after the verdict (how many fitted
    /// times sit at the fit's cap, [`super::aggregate::tests`]).
    pub(crate) caveat: Option<String>,
}

impl ClaimResult {
    /// Its verdict's sentence, as reports print it; empty until it is judged.
    pub fn verdict_text(&self) -> &str {
        self.verdict.as_ref().map_or("", |v| v.text.as_str())
    }

    /// A claim of `experiment` on `preset`, not yet estimated, tested or judged; `baseline` its chance
    /// level ([`chance_level`]).
    pub(crate) fn untested(experiment: &str, preset: &str, claim: &Claim, baseline: Option<f64>) -> ClaimResult {
        ClaimResult {
            experiment: experiment.into(),
            preset: preset.into(),
            claim: claim.clone(),
            estimate: None,
            p: None,
            p_holm: None,
            level: None,
            family_tests: 0,
            same_test: None,
            same_as: None,
            stated: super::registry::Stated::Unknown,
            baseline,
            verdict: None,
            resamples: None,
            caveat: None,
        }
    }
}

/// A test's samples (this variant's, and the compared variant's) and margin, as bits.
pub(crate) type SameTest = (Vec<u64>, Option<Vec<u64>>, Option<u64>);

// What kind of test a claim gets and at which level are the verdict's (`verdict.rs`), re-exported here
// beside the quantities they read.
pub(crate) use super::verdict::is_effect;

impl ClaimResult {
    /// The half-width of the interval shown for this claim: at its family-adjusted level for an effect
    /// (the (1 − 2α_k) interval of TOST for a claim of no effect), the plain 95 % interval for a level.
    pub(crate) fn shown_half_width(&self) -> Option<f64> {
        let e = self.estimate?;
        match (self.level, self.claim.margin) {
            (Some(level), Some(_)) => e.half_width(2.0 * level),
            (Some(level), None) => e.half_width(level),
            (None, _) => e.ci,
        }
    }

    /// Why the interval shown carries no information ([`super::verdict::uninformative`]), None when it does.
    pub(crate) fn uninformative(&self) -> Option<String> {
        super::verdict::uninformative(&self.claim, &self.estimate?, self.shown_half_width()?)
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::claims::file::{Curve, Experiment, Quantity};
    use crate::claims::quantity::quantity;
    use crate::claims::verdict::{hypothesis, ALPHA, DOA_TOLERANCE, DOS_TOLERANCE};
    use std::path::Path;

    /// The sentence of a verdict ([`crate::claims::verdict::verdict`]), which these tests read.
    fn verdict(claim: &Claim, e: Option<Estimate>, p: Option<f64>, level: Option<f64>, b: Option<f64>) -> String {
        crate::claims::verdict::verdict(claim, e, p, level, b).text
    }

    #[test]
    fn changes_are_the_last_window_minus_the_first() {
        let exp = Experiment::load(Path::new("experiments/ablation-from-paper.ron"), Path::new("results")).unwrap();
        // 250 episodes: the first 100 and the last 100 do not overlap.
        let series = |first: f64, last: f64| {
            (0..250)
                .map(|i| {
                    if i < 100 {
                        first
                    } else if i >= 150 {
                        last
                    } else {
                        f64::NAN
                    }
                })
                .collect::<Vec<_>>()
        };
        let d = RunData {
            dos: series(0.22, 0.19),
            doa: series(0.70, 0.85),
            catches: series(72.0, 26.0),
            ..Default::default()
        };
        for (q, expected) in
            [(Quantity::DosChange, -0.03), (Quantity::DoaChange, 0.15), (Quantity::CatchesChange, -46.0)]
        {
            assert!((quantity(&exp, &d, &q) - expected).abs() < 1e-12, "{q:?}");
        }
    }

    #[test]
    fn the_authors_curves_are_read_from_their_own_windows() {
        // 300 episodes of the code's DoA, each window its own value: the first 10 at 0.15, the rest of the
        // first 100 at 0.25, the last 100 at 0.5; its DoS flat at 0.3. Each quantity reads its window of the
        // right series, and the paper's DoA (a ramp) never enters.
        let exp = Experiment::load(Path::new("experiments/ablation-from-paper.ron"), Path::new("results")).unwrap();
        let doa: Vec<f64> = (0..300)
            .map(|i| {
                if i < 10 {
                    0.15
                } else if i < 200 {
                    0.25
                } else {
                    0.5
                }
            })
            .collect();
        let d = RunData {
            doa: (0..300).map(|i| i as f64 / 300.0).collect(),
            orders: [("authors_doa".to_string(), doa), ("authors_dos".to_string(), vec![0.3; 300])].into(),
            ..Default::default()
        };
        let a = |q: Quantity| quantity(&exp, &d, &q);
        let start = (0.15f32 as f64 * 10.0) / 10.0;
        assert!((a(Quantity::Start(Curve::AuthorsDoa)) - start).abs() < 1e-12);
        assert!(
            (a(Quantity::TrainingFirst(crate::claims::file::Order::AuthorsDoa)) - (0.15 * 10.0 + 0.25 * 90.0) / 100.0)
                .abs()
                < 1e-12
        );
        assert_eq!(a(Quantity::TrainingLast(crate::claims::file::Order::AuthorsDoa)), 0.5);
        assert!((a(Quantity::FromStart(Curve::AuthorsDoa)) - (0.5 - start)).abs() < 1e-12);
        assert!(a(Quantity::FromStart(Curve::AuthorsDos)).abs() < 1e-7, "the flat curve's start at single precision");
        // A run that did not measure them has no value, never the paper's curve.
        let plain = RunData { doa: d.doa.clone(), ..Default::default() };
        assert!(quantity(&exp, &plain, &Quantity::FromStart(Curve::AuthorsDoa)).is_nan());
    }

    pub(crate) fn claim(quantity: Quantity, paper: Option<f64>, margin: Option<f64>) -> Claim {
        Claim { paper, margin, ..Claim::of("t", "v", quantity) }
    }

    /// The verdict on one effect claim of its own family (so Holm's adjustment is the p-value itself and
    /// its level α): TOST for a claim of no effect.
    fn judged(c: &Claim, samples: &[f64]) -> String {
        let e = crate::claims::stats::estimate(samples);
        let p = e.and_then(|e| e.test_p(c.margin));
        verdict(c, e, p, Some(ALPHA), None)
    }

    #[test]
    fn verdicts_on_hand_made_samples() {
        let rises = claim(Quantity::DoaChange, Some(0.17), None);
        // A clear effect in the paper's direction, the paper's value inside the interval.
        let clear = [0.15, 0.18, 0.20, 0.16, 0.19];
        assert!(
            judged(&rises, &clear).starts_with("reproduced: detected in the paper's direction"),
            "{}",
            judged(&rises, &clear)
        );
        // Detected in the paper's direction, the paper's value outside: the direction only.
        let small = [0.05, 0.06, 0.04, 0.05, 0.055];
        assert!(
            judged(&rises, &small).starts_with("direction reproduced, smaller than the paper's +0.170"),
            "{}",
            judged(&rises, &small)
        );
        // The same effect the other way.
        let opposite: Vec<f64> = clear.iter().map(|x| -x).collect();
        assert!(judged(&rises, &opposite).starts_with("not reproduced: detected the other way"));
        // A wide interval holding both zero and the paper's value: inconclusive, with the power at its level.
        let wide = [0.4, -0.3, 0.25, -0.2, 0.1];
        let v = judged(&rises, &wide);
        assert!(v.starts_with("inconclusive: no effect detected; 80 % power at its level (α = 0.05)"), "{v}");
        // Tight around zero, excluding the paper's +0.17: no effect detected, an effect of its size excluded
        // (inconclusive: only an equivalence test shows no effect).
        let null = [0.01, -0.01, 0.0, 0.02, -0.02];
        assert!(
            judged(&rises, &null).starts_with("inconclusive: no effect detected, and the paper's +0.170 is outside")
        );
        // A claim of no change with a margin: tight around zero is equivalent, the clear effect is not.
        let flat = claim(Quantity::DosChange, None, Some(0.05));
        assert!(judged(&flat, &null).starts_with("equivalent within ±0.05"), "{}", judged(&flat, &null));
        assert!(
            judged(&flat, &clear).starts_with("not reproduced: an effect beyond ±0.05"),
            "{}",
            judged(&flat, &clear)
        );
        // An effect detected but smaller than the margin is no evidence against "no effect beyond ±m".
        let inside = [0.03, 0.06, 0.04, 0.055, 0.04];
        assert!(judged(&flat, &inside).starts_with("inconclusive: neither equivalence"), "{}", judged(&flat, &inside));
        assert!(judged(&flat, &wide).starts_with("inconclusive: neither equivalence"));
        // ... and says which margin the data support: the farther end of the adjusted (90 %, one test)
        // interval, mean 0.045 ± t(0.95, 4) · sd/√5 = 0.045 ± 2.132 · 0.00548 = [0.0333, 0.0567], rounded up.
        assert!(
            judged(&flat, &inside)
                .ends_with("equivalence would be shown only for a margin wider than ±0.057 (at this test's level)"),
            "{}",
            judged(&flat, &inside)
        );
        // No number from the paper: detected or not, never "holds".
        let free = claim(Quantity::InteractionDoa("x".into()), None, None);
        assert!(judged(&free, &clear).starts_with("effect detected: +0.176"));
        assert!(judged(&free, &wide).starts_with("no effect detected (inconclusive)"));
        // A direction only (the paper's "faster"): the sign decides; a size is never excluded.
        let faster = Claim {
            direction_only: true,
            versus: Some("w".into()),
            ..claim(Quantity::Reach90(Curve::Doa), Some(-1.0), None)
        };
        assert!(judged(&faster, &opposite).starts_with("reproduced: detected in the paper's direction"));
        assert!(judged(&faster, &clear).starts_with("not reproduced: detected the other way"));
        assert!(judged(&faster, &null).starts_with("inconclusive: no effect detected"), "{}", judged(&faster, &null));
        // The project's own direction (a question the paper does not ask): never "reproduced".
        let ours = Claim { ours: true, ..faster.clone() };
        assert!(
            judged(&ours, &opposite).starts_with("detected as hypothesised (Holm p"),
            "{}",
            judged(&ours, &opposite)
        );
        assert!(judged(&ours, &clear).starts_with("detected opposite to the hypothesis (Holm p"));
        assert!(judged(&ours, &null).starts_with("inconclusive: no effect detected"));
        assert_eq!(hypothesis(&ours, None), "an effect < 0 (the project's hypothesis, not the paper's)");
        assert_eq!(hypothesis(&faster, None), "an effect < 0");
        // A detected effect that does not survive Holm's adjustment is not detected, and its power is
        // stated at the level it was tested at.
        let e = crate::claims::stats::estimate(&clear);
        let v = verdict(&free, e, Some(0.2), Some(ALPHA / 44.0), None);
        assert!(v.starts_with("no effect detected (inconclusive): 80 % power at its level (α = 0.05/44)"), "{v}");
    }

    /// A claim of experiment `experiment` tested on one sample, not yet adjusted or judged.
    pub(crate) fn tested(c: &Claim, experiment: &str, sample: &[f64]) -> ClaimResult {
        let e = crate::claims::stats::estimate(sample).unwrap();
        ClaimResult {
            experiment: experiment.into(),
            preset: "p".into(),
            claim: c.clone(),
            estimate: Some(e),
            p: e.p_value(),
            p_holm: None,
            level: None,
            family_tests: 0,
            same_test: Some((sample.iter().map(|x| x.to_bits()).collect(), None, None)),
            same_as: None,
            stated: crate::claims::registry::Stated::Unknown,
            baseline: None,
            verdict: None,
            resamples: None,
            caveat: None,
        }
    }

    #[test]
    fn the_shown_interval_agrees_with_the_verdict() {
        // A family of four: each interval at its Holm level excludes zero exactly when the verdict says
        // detected.
        let samples: [&[f64]; 5] = [
            &[0.15, 0.18, 0.20, 0.16, 0.19],
            &[0.05, -0.01, 0.08, 0.02, 0.04],
            &[0.4, -0.3, 0.25, -0.2, 0.1],
            &[0.03, 0.05, 0.02, 0.06, 0.04],
            // p ≈ 0.03: below 0.05 but not rejected in a family of five, so its plain 95 % interval would
            // exclude zero while the adjusted one must not.
            &[0.09, 0.01, 0.06, 0.1, 0.03],
        ];
        let e: Vec<Estimate> = samples.iter().map(|s| crate::claims::stats::estimate(s).unwrap()).collect();
        let p: Vec<f64> = e.iter().map(|e| e.p_value().unwrap()).collect();
        let free = claim(Quantity::InteractionDoa("x".into()), None, None);
        assert!(p.iter().any(|&p| (0.017..0.05).contains(&p)), "{p:?}");
        let mut results: Vec<ClaimResult> = (0..samples.len()).map(|i| tested(&free, "e", samples[i])).collect();
        crate::claims::family::adjust(&mut results);
        assert_eq!(
            results.iter().map(|r| r.p_holm.unwrap()).collect::<Vec<_>>(),
            crate::claims::stats::holm(&p),
            "one file's claims without a family name are one family"
        );
        for (i, r) in results.iter().enumerate() {
            let h = r.shown_half_width().unwrap();
            let excludes_zero = e[i].mean.abs() > h;
            assert_eq!(
                excludes_zero,
                r.verdict_text().starts_with("effect detected"),
                "test {i}: {} ± {h}: {}",
                e[i].mean,
                r.verdict_text()
            );
        }
    }

    #[test]
    fn levels_are_judged_by_equivalence_within_their_tolerance_and_told_apart_from_chance() {
        let level = claim(Quantity::EvalDoa("x".into()), Some(0.82), None);
        let e = |s: &[f64]| crate::claims::stats::estimate(s);
        let chance = Some(std::f64::consts::FRAC_2_PI);
        // Mean 0.82, SD 0.016 over 5 seeds: the 90 % interval (±0.015) is not inside 0.82 ± 0.015, and
        // the 95 % one holds 0.82: inconclusive. Ten seeds with SD 0.003 are within it.
        let five = [0.80, 0.83, 0.84, 0.81, 0.82];
        assert_eq!(DOA_TOLERANCE, 0.015);
        let text = verdict(&level, e(&five), None, None, chance);
        assert!(text.starts_with("inconclusive: the 90 % interval"), "{text}");
        let ten = [0.815, 0.822, 0.818, 0.825, 0.82, 0.817, 0.823, 0.819, 0.821, 0.82];
        let text = verdict(&level, e(&ten), None, None, chance);
        assert!(text.starts_with("reproduced: equivalent to the paper's 0.82 within ±0.015"), "{text}");
        assert!(text.ends_with("apart from chance (0.637)"), "{text}");
        // Near chance and far from the paper: outside the band, and not told apart from chance.
        let low = [0.63, 0.64, 0.62, 0.64, 0.63];
        let text = verdict(&level, e(&low), None, None, Some(0.635));
        assert!(
            text.starts_with("not reproduced: the 95 % CI [0.622, 0.642] lies outside the paper's 0.82 ± 0.015"),
            "{text}"
        );
        assert!(text.ends_with("not told apart from chance (0.635)"), "{text}");
        // More seeds cannot make a level that sits just outside the band "reproduced", as reaching the
        // paper's number at its printed precision could: 0.837 is outside 0.82 ± 0.015 however tight.
        let outside = [0.836, 0.838, 0.837, 0.836, 0.838, 0.837];
        assert!(verdict(&level, e(&outside), None, None, chance).starts_with("not reproduced"));
        assert_eq!(verdict(&level, None, None, None, chance), "not run yet");
        assert_eq!(verdict(&level, e(&[0.8]), None, None, chance), "one seed: no interval");
        // DoS levels take ±0.005; a claim's own tolerance replaces the rule's.
        let starts = claim(Quantity::DosFirst, Some(0.22), None);
        assert_eq!(crate::claims::verdict::tolerance(&starts), Some(DOS_TOLERANCE));
        let near = [0.219, 0.221, 0.220, 0.219, 0.221, 0.220];
        assert!(verdict(&starts, e(&near), None, None, Some(0.1)).starts_with("reproduced"));
        let own = Claim { tolerance: Some(0.0005), ..starts.clone() };
        assert!(verdict(&own, e(&near), None, None, Some(0.1)).starts_with("inconclusive"));
        assert!(hypothesis(&own, None).contains("within ±0.0005"));
    }

    #[test]
    fn a_claim_on_the_log_scale_tests_ln_1_plus_each_value() {
        use crate::claims::file::Scale;
        assert_eq!(Scale::Linear.of(3.0), 3.0);
        assert_eq!(Scale::Log1p.of(0.0), 0.0);
        assert!((Scale::Log1p.of(std::f64::consts::E - 1.0) - 1.0).abs() < 1e-12);
        assert!(Scale::Log1p.of(-1.0).is_nan(), "no sample where ln(1 + x) is undefined");
        // Heavy tails: every seed of one arm above every seed of the other, two of them far out. Welch on the
        // raw values holds zero; on ln(1 + x) it does not.
        let every = [78.0, 80.0, 82.0, 85.0, 88.0, 90.0, 95.0, 100.0, 1500.0, 2500.0];
        let base = [23.0, 25.0, 26.0, 28.0, 29.0, 30.0, 31.0, 33.0, 34.0, 35.0];
        let raw = crate::claims::stats::difference(&every, &base).unwrap();
        assert!(raw.mean - raw.ci.unwrap() < 0.0, "{raw:?}");
        let log = |v: &[f64]| v.iter().map(|&x| Scale::Log1p.of(x)).collect::<Vec<_>>();
        let logged = crate::claims::stats::difference(&log(&every), &log(&base)).unwrap();
        assert!(logged.mean - logged.ci.unwrap() > 0.0, "{logged:?}");
        // Only for effects: a level on the log scale is refused when its file is read.
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("x.ron");
        std::fs::write(
            &file,
            r#"(base: "scenes/paper.ron", seeds: [1], variants: [(name: "a")], claims: [(text: "t", variant: "a", quantity: CatchesLast, scale: Log1p)])"#,
        )
        .unwrap();
        let refused = Experiment::load(&file, dir.path()).unwrap_err().to_string();
        assert!(refused.contains("a scale other than Linear is for an effect"), "{refused}");
    }
}
