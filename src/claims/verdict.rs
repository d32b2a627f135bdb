//! The verdict on a claim, as a type: what its test came to ([`Outcome`], which reports, the claims table
//! and the checks between a level and its contrast read) with the sentence reports print ([`Verdict`]),
//! and the hypothesis it was tested against. Defined in REPRODUCTION.md's preamble.

use super::file::{Claim, Order};
use super::stats::Estimate;

/// Significance level of every test, after Holm's adjustment.
pub(crate) const ALPHA: f64 = 0.05;

/// Whether a claim is about an effect (a change over training, what a control removes, or a difference
/// of two variants) rather than a level. A claim that states only a direction, or no effect within a
/// margin, tests its quantity against zero whatever it is (e.g. a fitted gain: `known-rules.ron`).
pub(crate) fn is_effect(claim: &Claim) -> bool {
    claim.versus.is_some()
        || claim.grid.is_some()
        || claim.direction_only
        || claim.margin.is_some()
        || claim.quantity.is_difference()
}

/// What a claim's test came to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Outcome {
    /// No finished run of its variant.
    NotRunYet,
    /// One seed: no interval, no test.
    OneSeed,
    /// Its experiment is judged when all its runs are finished, and some are not (no interim analysis).
    InProgress,
    /// A change over training of runs too short for a first and a last window that do not overlap.
    NotMeasured,
    /// A comparison of two variants whose runs are identical (one training, run twice).
    NotAComparison,
    /// An effect detected in the paper's direction with the paper's value inside its interval (for a
    /// direction-only claim, detected in that direction); a level equivalent to the paper's value within its
    /// tolerance ([`tolerance`]).
    Reproduced,
    /// An effect detected in the paper's direction, the paper's value outside its interval.
    DirectionReproduced {
        larger: bool,
    },
    /// An effect detected against the paper's direction, or beyond a claim of none's margin; a level whose
    /// 95 % interval lies outside the paper's value ± its tolerance.
    NotReproduced,
    /// A claim of no effect shown within its margin (TOST).
    Equivalent,
    /// Neither detected nor shown equivalent (an effect), or not told apart from chance (a level);
    /// `paper_size_excluded`: the effect's interval excludes the paper's stated value, so an effect of the
    /// paper's size is ruled out though its direction is not decided.
    Inconclusive {
        paper_size_excluded: bool,
    },
    /// The project's own direction (`ours`), detected as hypothesised or against it.
    DetectedAsHypothesised,
    DetectedOpposite,
    /// An effect the paper gives no number or direction for: detected or not.
    EffectDetected,
    NoEffectDetected,
    /// A level the paper gives no number for: told apart from chance or not, or no chance level.
    Measured {
        apart_from_chance: Option<bool>,
    },
}

impl Outcome {
    /// Whether the paper's statement holds, in its direction at least.
    #[cfg(test)]
    pub(crate) fn reproduced(self) -> bool {
        matches!(self, Outcome::Reproduced | Outcome::DirectionReproduced { .. } | Outcome::Equivalent)
    }
}

/// A claim's verdict: its outcome and the sentence reports print.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Verdict {
    pub(crate) outcome: Outcome,
    pub(crate) text: String,
}

impl Verdict {
    pub(crate) fn new(outcome: Outcome, text: impl Into<String>) -> Verdict {
        Verdict { outcome, text: text.into() }
    }

    /// The verdict's first words, as a note on another row names it ("reproduced", "not reproduced",
    /// "direction reproduced, smaller than the paper's -0.010 ").
    pub(crate) fn word(&self) -> &str {
        self.text.split([':', '(']).next().unwrap_or_default().trim()
    }

    /// Adds a note to the sentence (the test it repeats, a disagreement with its contrast).
    pub(crate) fn note(&mut self, note: &str) {
        self.text.push_str(note);
    }
}

impl std::fmt::Display for Verdict {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.text)
    }
}

/// The tolerance of a level of the paper's DoS: half the smallest difference between two DoS levels the
/// paper states (22, 20.5, 19, 18, 17 and 15 %: 18 against 17 or 19, one point of D). Within it a level
/// is nearer the paper's number than any other DoS level the paper tells it apart from. Fixed once, by
/// this rule, for every DoS level; the precision the paper prints a number with plays no part.
pub(crate) const DOS_TOLERANCE: f64 = 0.005;

/// The tolerance of a level of the paper's DoA, by the rule of [`DOS_TOLERANCE`]: the paper states 0.65,
/// 0.75, 0.82, 0.85 and 0.96, the nearest two 0.03 apart.
pub(crate) const DOA_TOLERANCE: f64 = 0.015;

/// The fewest seeds whose interval a report shows as a result: from fewer, Student's t makes the interval
/// so wide (t₀.₉₇₅ = 12.7 at 2 seeds, 4.3 at 3, 3.2 at 4) that it says little beyond the sign of a
/// large effect.
pub(crate) const INFORMATIVE_SEEDS: usize = 5;

/// Why a claim's interval carries no information, None when it does: from fewer than
/// [`INFORMATIVE_SEEDS`] seeds, or wider than every value its quantity can take (DoS, DoA, polarization,
/// milling, the largest cluster's share and the edge rank lie in [0, 1], C_nn in [−1, 1]; a difference of
/// two spans twice that). Reports print it beside the interval, and pages that cite one must say so
/// (`tests/it/docs.rs`).
pub(crate) fn uninformative(claim: &Claim, e: &Estimate, half_width: f64) -> Option<String> {
    if e.n < INFORMATIVE_SEEDS {
        return Some(format!("uninformative: {} seeds", e.n));
    }
    let range = claim.quantity.order()?.span()?;
    let range = if is_effect(claim) { 2.0 * range } else { range };
    (2.0 * half_width > range).then(|| format!("uninformative: wider than the {range} the quantity can span"))
}

/// The tolerance a level claim with a paper's value is judged within: the claim's own `tolerance`, else
/// [`DOS_TOLERANCE`] or [`DOA_TOLERANCE`] by the order parameter it reads; None for another level (the
/// file must then state one: `load.rs` refuses it without).
pub(crate) fn tolerance(claim: &Claim) -> Option<f64> {
    claim.tolerance.or(match claim.quantity.order() {
        Some(Order::Dos) => Some(DOS_TOLERANCE),
        Some(Order::Doa) => Some(DOA_TOLERANCE),
        _ => None,
    })
}

/// How the seeds an effect needs are counted: per variant for a difference of two variants, per level or
/// cell over a grid, and for a number read within each run (a change over its training, its own
/// evaluations compared, a control, a fitted gain) as runs of the one variant.
fn seeds_counted(e: &Estimate) -> &'static str {
    use super::stats::Design;
    match e.design {
        Design::Difference => "seeds per variant",
        Design::Mean => "seeds (each run's value read within the run)",
        Design::Slope { .. } => "seeds per level",
        Design::Bootstrap => "seeds per cell",
    }
}

/// What an inconclusive verdict says when no number of seeds up to [`super::stats::Estimate::seeds_for`]'s
/// bound would decide it.
fn more_seeds(e: &Estimate) -> String {
    format!("; more than 10 000 {} would be needed to detect it", seeds_counted(e))
}

/// The verdict on a claim, defined in REPRODUCTION.md's preamble. An effect is *detected* when its
/// Holm-adjusted p-value is below [`ALPHA`], which is exactly when its interval at `level` (the family's
/// stepped level, [`super::stats::holm_levels`]) excludes zero; an interval that contains zero is never
/// called a result. Effects: *reproduced* (detected in the paper's direction, the paper's value inside the
/// interval), *direction reproduced, smaller/larger than the paper*, *not reproduced* (detected the other
/// way, or an effect shown where the claim is of none), *equivalent within ±m* (TOST, adjusted),
/// *inconclusive*. Levels with the paper's value: *reproduced* when equivalent to it within its
/// [`tolerance`] (TOST at 5 %, unadjusted), *not reproduced* when the 95 % interval lies outside it,
/// *inconclusive* otherwise; each says whether the interval excludes chance.
pub(crate) fn verdict(
    claim: &Claim,
    e: Option<Estimate>,
    p_holm: Option<f64>,
    level: Option<f64>,
    baseline: Option<f64>,
) -> Verdict {
    let mut judged = test(claim, e, p_holm, level, baseline);
    // A claim stated after its first results (`registration.rs`) keeps its test and says so with its verdict.
    if claim.exploratory && e.is_some_and(|e| e.ci.is_some()) {
        judged.text.push_str(EXPLORATORY);
    }
    judged
}

/// What an exploratory claim's verdict ends with.
pub(crate) const EXPLORATORY: &str = "; exploratory: stated after its first results were committed";

/// [`verdict`] as the test alone gives it.
fn test(claim: &Claim, e: Option<Estimate>, p_holm: Option<f64>, level: Option<f64>, baseline: Option<f64>) -> Verdict {
    use Outcome::*;
    let Some(e) = e else { return Verdict::new(NotRunYet, "not run yet") };
    let Some(ci) = e.ci else { return Verdict::new(OneSeed, "one seed: no interval") };
    match is_effect(claim) {
        true => effect_verdict(claim, e, ci, p_holm, level.unwrap_or(ALPHA)),
        false => level_verdict(claim, e, ci, baseline),
    }
}

/// An effect's verdict: its equivalence within a margin, or its direction against the paper's (or the
/// project's), at the level Holm's procedure tested it at.
fn effect_verdict(claim: &Claim, e: Estimate, ci: f64, p_holm: Option<f64>, level: f64) -> Verdict {
    use Outcome::*;
    let detected = p_holm.is_some_and(|p| p < ALPHA);
    let p_text = p_holm.map_or(String::new(), |p| format!("Holm p = {}", p_shown(p)));
    let power = || match e.detectable_at(level) {
        Some(d) => format!(
            "80 % power at its level (α = {}) only for effects of ±{d:.3} or more with {} seeds",
            alpha_shown(level),
            e.n
        ),
        None => String::new(),
    };
    if let Some(m) = claim.margin {
        let h = e.half_width(2.0 * level).unwrap_or(ci);
        let (lo, hi) = (e.mean - h, e.mean + h);
        let two_sided = e.half_width(level).unwrap_or(ci);
        return if detected {
            Verdict::new(
                Equivalent,
                format!(
                    "equivalent within ±{m}: the adjusted interval [{lo:.3}, {hi:.3}] lies inside (TOST, {p_text})"
                ),
            )
        } else if e.mean.abs() - two_sided >= m {
            Verdict::new(NotReproduced, format!("not reproduced: an effect beyond ±{m} ({:+.3})", e.mean))
        } else {
            // What the data do support: the adjusted interval lies inside a margin only wider than its
            // farther end (rounded up, so the margin printed is never one the interval reaches past).
            Verdict::new(
                Inconclusive { paper_size_excluded: false },
                format!(
                    "inconclusive: neither equivalence within ±{m} (adjusted interval [{lo:.3}, {hi:.3}]) nor an effect shown; equivalence would be shown only for a margin wider than ±{:.3} (at this test's level)",
                    (lo.abs().max(hi.abs()) * 1000.0).ceil() / 1000.0
                ),
            )
        };
    }
    let h = e.half_width(level).unwrap_or(ci);
    let inside = |x: f64| e.mean - h <= x && x <= e.mean + h;
    match claim.paper {
        // The project's own direction: judged against its hypothesis, never "reproduced".
        Some(sign) if claim.ours && detected => match e.mean.signum() == sign.signum() {
            true => Verdict::new(DetectedAsHypothesised, format!("detected as hypothesised ({p_text})")),
            false => Verdict::new(DetectedOpposite, format!("detected opposite to the hypothesis ({p_text})")),
        },
        Some(paper) if detected && e.mean.signum() == paper.signum() => {
            if claim.direction_only || inside(paper) {
                Verdict::new(Reproduced, format!("reproduced: detected in the paper's direction ({p_text})"))
            } else {
                let larger = e.mean.abs() >= paper.abs();
                let size = if larger { "larger" } else { "smaller" };
                Verdict::new(
                    DirectionReproduced { larger },
                    format!("direction reproduced, {size} than the paper's {paper:+.3} ({p_text})"),
                )
            }
        }
        Some(_) if detected => {
            Verdict::new(NotReproduced, format!("not reproduced: detected the other way ({p_text})"))
        }
        // The seeds that would decide it: for a direction the paper gives no size of, those that would
        // detect the difference measured here if it were the true one (none when it points the other way),
        // and how far that answer moves over the interval: from its far end in the hypothesised direction
        // to its near end, which holds 0 (never) since the effect was not detected.
        Some(paper) if claim.direction_only => {
            let far = e.mean + paper.signum() * h;
            let seeds = match e.mean.signum() == paper.signum() {
                true => e.seeds_for(level, e.mean).map_or(more_seeds(&e), |n| {
                    let range = match e.seeds_for(level, far) {
                        Some(at_far) => format!("; over its adjusted interval the answer runs from about {at_far} (at {far:+.3}) to never (at 0, inside it)"),
                        None => String::new(),
                    };
                    format!("; about {n} {} would detect a difference of the size measured here ({:+.3}) with 80 % power{range}", seeds_counted(&e), e.mean)
                }),
                false => "; the estimate points away from the paper's direction, so more seeds are not expected to show it".into(),
            };
            Verdict::new(
                Inconclusive { paper_size_excluded: false },
                format!("inconclusive: no effect detected; {}{seeds}", power()),
            )
        }
        Some(paper) if !inside(paper) => Verdict::new(
            Inconclusive { paper_size_excluded: true },
            format!(
                "inconclusive: no effect detected, and the paper's {paper:+.3} is outside the adjusted interval (an effect of its size is excluded)"
            ),
        ),
        Some(paper) => {
            let seeds = e.seeds_for(level, paper).map_or(more_seeds(&e), |n| match n <= e.n {
                true => format!("; its {} seeds had 80 % power for the paper's {paper:+.3} (about {n} would): an effect of that size would likely have been detected", e.n),
                false => format!("; about {n} {} would detect the paper's {paper:+.3} with 80 % power", seeds_counted(&e)),
            });
            Verdict::new(
                Inconclusive { paper_size_excluded: false },
                format!("inconclusive: no effect detected; {}{seeds}", power()),
            )
        }
        None if detected => Verdict::new(EffectDetected, format!("effect detected: {:+.3} ({p_text})", e.mean)),
        None => Verdict::new(NoEffectDetected, format!("no effect detected (inconclusive): {}", power())),
    }
}

/// A level's verdict: equivalent to the paper's value within its tolerance, outside it, or undecided, and
/// whether it is told apart from chance.
fn level_verdict(claim: &Claim, e: Estimate, ci: f64, baseline: Option<f64>) -> Verdict {
    use Outcome::*;
    let (lo, hi) = (e.mean - ci, e.mean + ci);
    let inside = |x: f64| lo <= x && x <= hi;
    let chance = baseline.map(|b| (b, inside(b)));
    let chance_note = match chance {
        Some((b, false)) => format!("; apart from chance ({b:.3})"),
        Some((b, true)) => format!("; not told apart from chance ({b:.3})"),
        None => String::new(),
    };
    match (claim.paper, tolerance(claim)) {
        // Equivalence to the paper's level within its tolerance t (TOST at 5 %: the 90 % interval inside
        // paper ± t); not reproduced when the 95 % interval lies wholly outside paper ± t.
        (Some(paper), Some(t)) => {
            let h = e.half_width(0.10).unwrap_or(ci);
            let (lo90, hi90) = (e.mean - h, e.mean + h);
            if paper - t < lo90 && hi90 < paper + t {
                Verdict::new(
                    Reproduced,
                    format!(
                        "reproduced: equivalent to the paper's {paper} within ±{t} (TOST; 90 % interval [{lo90:.3}, {hi90:.3}]){chance_note}"
                    ),
                )
            } else if hi < paper - t || lo > paper + t {
                Verdict::new(
                    NotReproduced,
                    format!("not reproduced: the 95 % CI [{lo:.3}, {hi:.3}] lies outside the paper's {paper} ± {t}{chance_note}"),
                )
            } else {
                Verdict::new(
                    Inconclusive { paper_size_excluded: false },
                    format!(
                        "inconclusive: the 90 % interval [{lo90:.3}, {hi90:.3}] is not within the paper's {paper} ± {t}, nor the 95 % CI outside it{chance_note}"
                    ),
                )
            }
        }
        (Some(paper), None) => Verdict::new(
            Inconclusive { paper_size_excluded: false },
            format!("inconclusive: no tolerance to judge the paper's {paper} within"),
        ),
        (None, _) => match chance {
            Some((b, false)) => Verdict::new(
                Measured { apart_from_chance: Some(true) },
                format!("measured: differs from chance ({b:.3})"),
            ),
            Some((b, true)) => Verdict::new(
                Measured { apart_from_chance: Some(false) },
                format!("measured: not told apart from chance ({b:.3})"),
            ),
            None => Verdict::new(Measured { apart_from_chance: None }, "measured (the paper gives no number)"),
        },
    }
}

/// The hypothesis a claim tests, as reports print it beside its verdict: an effect in the paper's
/// direction, any effect (two-sided), equivalence within a margin, or a level against the paper's value at
/// its precision and against chance.
pub(crate) fn hypothesis(claim: &Claim, baseline: Option<f64>) -> String {
    if let Some(super::file::GridTest::Boundary { crosses, .. }) = claim.grid {
        return format!("a crossing of {crosses} within the axis");
    }
    if is_effect(claim) {
        let direction = |p: f64| if p < 0.0 { "an effect < 0" } else { "an effect > 0" };
        return match (claim.margin, claim.paper) {
            (Some(m), _) => format!("no effect: equivalence within ±{m}"),
            (None, Some(p)) if claim.ours => format!("{} (the project's hypothesis, not the paper's)", direction(p)),
            (None, Some(p)) if claim.direction_only => direction(p).into(),
            (None, Some(p)) => format!("{} (the paper: {p:+})", direction(p)),
            (None, None) => "any effect (two-sided)".into(),
        };
    }
    let chance = baseline.map_or(String::new(), |b| format!(", apart from chance {b:.3}"));
    match claim.paper {
        Some(p) => match tolerance(claim) {
            Some(t) => format!("the level {p}: equivalence within ±{t}{chance}"),
            None => format!("the level {p} (no tolerance){chance}"),
        },
        None if baseline.is_some() => format!("a level apart from chance {:.3}", baseline.unwrap_or_default()),
        None => "a level (measured)".into(),
    }
}

/// A test's level as reports show it: [`ALPHA`] over the Holm step's divisor (`0.05/44`; `0.05` alone).
pub(crate) fn alpha_shown(level: f64) -> String {
    match (ALPHA / level).round() as usize {
        0 | 1 => format!("{ALPHA}"),
        d => format!("{ALPHA}/{d}"),
    }
}

/// A p-value as reports show it.
pub(crate) fn p_shown(p: f64) -> String {
    if p < 0.001 {
        "< 0.001".into()
    } else if (0.0445..0.0555).contains(&p) {
        // Near α, a third decimal could round across it (0.0496 as "0.050" beside "detected").
        format!("{p:.4}")
    } else {
        format!("{p:.3}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::claims::file::Quantity;
    use crate::claims::stats::estimate;

    fn claim(paper: Option<f64>, versus: bool) -> Claim {
        Claim { paper, versus: versus.then(|| "b".into()), ..Claim::of("c", "v", Quantity::DoaLast) }
    }

    #[test]
    fn each_verdict_carries_the_outcome_its_sentence_states() {
        let e = estimate(&[0.80, 0.82, 0.84]);
        let outcome = |c: &Claim, p: Option<f64>, b: Option<f64>| verdict(c, e, p, Some(ALPHA), b).outcome;
        // Effects: detected in the paper's direction with its value inside, outside, the other way, not at all.
        assert_eq!(outcome(&claim(Some(0.82), true), Some(0.001), None), Outcome::Reproduced);
        assert_eq!(outcome(&claim(Some(0.1), true), Some(0.001), None), Outcome::DirectionReproduced { larger: true });
        assert_eq!(outcome(&claim(Some(-0.82), true), Some(0.001), None), Outcome::NotReproduced);
        assert_eq!(
            outcome(&claim(Some(0.82), true), Some(0.3), None),
            Outcome::Inconclusive { paper_size_excluded: false }
        );
        assert_eq!(outcome(&claim(None, true), Some(0.001), None), Outcome::EffectDetected);
        assert_eq!(outcome(&claim(None, true), Some(0.3), None), Outcome::NoEffectDetected);
        // Levels: equivalent to the paper's value within its tolerance, undecided, outside it, or no number.
        let tight = estimate(&[0.819, 0.82, 0.821, 0.82, 0.819, 0.821]);
        assert_eq!(verdict(&claim(Some(0.82), false), tight, None, None, Some(0.637)).outcome, Outcome::Reproduced);
        assert_eq!(
            outcome(&claim(Some(0.82), false), None, Some(0.637)),
            Outcome::Inconclusive { paper_size_excluded: false }
        );
        assert_eq!(outcome(&claim(Some(0.5), false), None, Some(0.637)), Outcome::NotReproduced);
        assert_eq!(
            outcome(&claim(None, false), None, Some(0.637)),
            Outcome::Measured { apart_from_chance: Some(true) }
        );
        assert_eq!(verdict(&claim(None, false), None, None, None, None).outcome, Outcome::NotRunYet);
        let one = verdict(&claim(None, false), estimate(&[0.8]), None, None, None);
        assert_eq!((one.outcome, one.word()), (Outcome::OneSeed, "one seed"));
        assert!(Outcome::Equivalent.reproduced() && !Outcome::Inconclusive { paper_size_excluded: true }.reproduced());
    }

    #[test]
    fn an_undecided_direction_says_how_many_seeds_over_its_interval() {
        // A difference measured at +0.02 between two arms of 5 seeds, not detected: the seeds that would
        // detect it, and the range from the interval's far end (fewer) to its near end, which holds 0.
        let e = crate::claims::stats::difference(&[0.80, 0.86, 0.83, 0.79, 0.85], &[0.81, 0.82, 0.80, 0.78, 0.82]);
        let c = Claim { direction_only: true, ..claim(Some(1.0), true) };
        let text = verdict(&c, e, Some(0.4), Some(ALPHA), None).text;
        let number = |after: &str| -> usize {
            let at = text.find(after).unwrap_or_else(|| panic!("{after:?} in {text}")) + after.len();
            text[at..].split_whitespace().next().unwrap().parse().unwrap()
        };
        let (measured, far) = (number("; about "), number("runs from about "));
        assert!(far < measured, "{text}");
        assert!(text.contains("to never (at 0, inside it)"), "{text}");
    }
}
