//! What an experiment measures and concludes: the data of a run read from its CSV files ([`RunData`]),
//! the quantities computed from it ([`quantity`]), their names in reports, and the verdict on a claim
//! ([`verdict`]).

use super::stats::{mean, Estimate};
use super::{Claim, Experiment, Quantity};
use crate::sim::metrics::Swarming;
use std::collections::BTreeMap;

/// A run's episodes (prey, or the headline species) and its evaluations.
#[derive(Clone, Debug, Default)]
pub struct RunData {
    pub dos: Vec<f64>,
    pub doa: Vec<f64>,
    pub catches: Vec<f64>,
    pub returns: Vec<f64>,
    /// The other per-episode order parameters by name ([`super::EVAL_ORDER`]); NaN for episodes (or
    /// runs) written before they were measured.
    pub orders: BTreeMap<String, Vec<f64>>,
    pub wall_seconds: f64,
    /// Per evaluation, by name.
    pub evals: BTreeMap<String, EvalData>,
}

/// One evaluation of a run.
#[derive(Clone, Debug, Default)]
pub struct EvalData {
    /// Per order parameter of [`Swarming::NAMES`] (DoS, DoA, polarization, ...): its value per step,
    /// averaged over the evaluation's episodes (NaN throughout for columns an older coevo did not write).
    pub per_step: Vec<Vec<f64>>,
    /// Mean edge rank over every ranked catch of the evaluation (NaN without one).
    pub edge_rank: f64,
    /// The confusion curve of the first predator species in `<eval>-confusion.csv`, per bin of prey in
    /// view: mean |turn command|, mean speed / max speed, catches per predator-step (NaN for empty bins;
    /// empty when the file is absent).
    pub confusion: Vec<[f64; 3]>,
}

impl EvalData {
    pub fn series(&self, name: &str) -> &[f64] {
        Swarming::NAMES.iter().position(|n| *n == name).and_then(|i| self.per_step.get(i)).map_or(&[], |v| v.as_slice())
    }
}

/// The paper's running-mean window, in episodes.
pub const WINDOW: usize = 100;

/// Steps at the end of an evaluation episode averaged as its settled state.
pub const SETTLED_STEPS: usize = 50;

pub fn window_mean(values: &[f64], first: bool) -> f64 {
    let n = values.len().min(WINDOW);
    let part = if first { &values[..n] } else { &values[values.len() - n..] };
    mean(&part.iter().copied().filter(|v| v.is_finite()).collect::<Vec<_>>()).unwrap_or(f64::NAN)
}

/// The finite values of a quantity over `runs` (one per seed), the samples of an estimate.
pub fn values(exp: &Experiment, runs: &[&RunData], q: &Quantity) -> Vec<f64> {
    runs.iter().map(|d| quantity(exp, d, q)).filter(|x| x.is_finite()).collect()
}

/// A run's value of a quantity.
pub fn quantity(exp: &Experiment, d: &RunData, q: &Quantity) -> f64 {
    let settled = |v: &[f64]| {
        mean(&v[v.len().saturating_sub(SETTLED_STEPS)..].iter().copied().filter(|x| x.is_finite()).collect::<Vec<_>>())
            .unwrap_or(f64::NAN)
    };
    let eval = |e: &str, name: &str| d.evals.get(e).map_or(f64::NAN, |x| settled(x.series(name)));
    match q {
        Quantity::DosFirst => window_mean(&d.dos, true),
        Quantity::TrainingFirst(q) => d.orders.get(q).map_or(f64::NAN, |v| window_mean(v, true)),
        Quantity::TrainingLast(q) => d.orders.get(q).map_or(f64::NAN, |v| window_mean(v, false)),
        Quantity::DosLast => window_mean(&d.dos, false),
        Quantity::DoaFirst => window_mean(&d.doa, true),
        Quantity::DoaLast => window_mean(&d.doa, false),
        Quantity::DosChange => window_mean(&d.dos, false) - window_mean(&d.dos, true),
        Quantity::DoaChange => window_mean(&d.doa, false) - window_mean(&d.doa, true),
        Quantity::CatchesChange => window_mean(&d.catches, false) - window_mean(&d.catches, true),
        Quantity::CatchesLast => window_mean(&d.catches, false),
        Quantity::EvalDos(e) => eval(e, "dos"),
        Quantity::EvalDoa(e) => eval(e, "doa"),
        Quantity::EvalOrder(e, name) if name == "edge_rank" => d.evals.get(e).map_or(f64::NAN, |x| x.edge_rank),
        Quantity::EvalOrder(e, name) => eval(e, name),
        Quantity::InteractionDoa(e) => match super::seeing_partner(&exp.spec.evaluations, e) {
            Some(seeing) => eval(&seeing.name, "doa") - eval(e, "doa"),
            None => f64::NAN,
        },
        Quantity::Interaction(e, name) => match super::seeing_partner(&exp.spec.evaluations, e) {
            Some(seeing) => {
                let value = |e: &str| match name.as_str() {
                    "edge_rank" => d.evals.get(e).map_or(f64::NAN, |x| x.edge_rank),
                    _ => eval(e, name),
                };
                value(&seeing.name) - value(e)
            }
            None => f64::NAN,
        },
    }
}

/// A claim checked on one preset.
#[derive(Clone, Debug)]
pub struct ClaimResult {
    pub experiment: String,
    pub preset: String,
    pub claim: Claim,
    pub estimate: Option<Estimate>,
    pub verdict: String,
}

/// Whether a measured estimate bears out the paper's number.
pub fn verdict(claim: &Claim, e: Option<Estimate>) -> String {
    let Some(e) = e else { return "not run yet".into() };
    let (paper, ci) = match (claim.paper, &claim.versus, e.ci) {
        (None, None, _) => return "measured (the paper gives no number)".into(),
        (_, _, None) => return "one seed: no interval".into(),
        // A comparison of two variants without a number of the paper: is the difference outside its interval?
        (None, Some(base), Some(ci)) if e.mean.abs() > ci => {
            return format!("differs from `{base}`: the 95 % CI excludes 0")
        }
        (None, Some(base), Some(_)) => return format!("no difference from `{base}` detected"),
        (Some(paper), _, Some(ci)) => (paper, ci),
    };
    let change = matches!(claim.quantity, Quantity::DosChange | Quantity::DoaChange | Quantity::CatchesChange);
    if (e.mean - paper).abs() <= ci {
        "holds: the paper's value is inside the 95 % CI".into()
    } else if change && e.mean.abs() <= ci {
        "does not hold: no significant change".into()
    } else if change && e.mean.signum() == paper.signum() {
        "same direction, different size".into()
    } else if change {
        "does not hold: opposite direction".into()
    } else {
        "does not hold: outside the 95 % CI".into()
    }
}

pub fn quantity_name(q: &Quantity) -> String {
    match q {
        Quantity::DosFirst => "DoS, first 100 episodes".into(),
        Quantity::TrainingFirst(q) => format!("{q}, first 100 episodes"),
        Quantity::TrainingLast(q) => format!("{q}, last 100 episodes"),
        Quantity::DosLast => "DoS, last 100 episodes".into(),
        Quantity::DoaFirst => "DoA, first 100 episodes".into(),
        Quantity::DoaLast => "DoA, last 100 episodes".into(),
        Quantity::DosChange => "DoS change, last − first 100".into(),
        Quantity::DoaChange => "DoA change, last − first 100".into(),
        Quantity::CatchesChange => "catches per episode, change, last − first 100".into(),
        Quantity::CatchesLast => "catches per episode, last 100".into(),
        Quantity::EvalDos(e) => format!("DoS settled in evaluation \"{e}\""),
        Quantity::EvalDoa(e) => format!("DoA settled in evaluation \"{e}\""),
        Quantity::EvalOrder(e, q) => format!("{q} in evaluation \"{e}\""),
        Quantity::InteractionDoa(e) => format!("DoA seeing minus \"{e}\" (interaction-driven alignment)"),
        Quantity::Interaction(e, q) => format!("{q} seeing minus \"{e}\""),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

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
}
