//! The read-outs of a cross-play matrix a researcher can cite (progress, regress, where a change of
//! alignment comes from), written to `crossplay-readouts.csv` and read back for claims.

use super::crossplay_matrix::{Cell, Matrix};
use super::stats::kendall_tau;
use crate::store::RunDir;

/// One read-out of a matrix: its name, value (None where undefined) and what it says.
#[derive(Clone, Debug, PartialEq)]
pub struct Readout {
    pub name: &'static str,
    pub value: Option<f64>,
    pub(crate) meaning: &'static str,
}

fn mean(values: impl Iterator<Item = f64>) -> Option<f64> {
    let v: Vec<f64> = values.filter(|x| x.is_finite()).collect();
    (!v.is_empty()).then(|| v.iter().sum::<f64>() / v.len() as f64)
}

/// Kendall's τ_b of `y` against its index (0, 1, ...): +1 when `y` only grows.
fn trend(y: &[f64]) -> Option<f64> {
    let x: Vec<f64> = (0..y.len()).map(|i| i as f64).collect();
    kendall_tau(&x, y)
}

/// The symmetric decomposition of a diagonal change M[b][b] − M[a][a] into the part the prey's change from
/// a to b makes and the part the predators' change makes (the mean of the two orders of changing one side
/// at a time; the parts sum to the change).
fn decompose(q: impl Fn(usize, usize) -> f64, a: usize, b: usize) -> [f64; 3] {
    let prey = 0.5 * ((q(b, a) - q(a, a)) + (q(b, b) - q(a, b)));
    let predator = 0.5 * ((q(a, b) - q(a, a)) + (q(b, b) - q(b, a)));
    [q(b, b) - q(a, a), prey, predator]
}

/// Pseudo-count (catches per episode) added to every mean before its logarithm in [`ratings`], so a
/// snapshot that never catches (or is never caught) has a finite rating.
const RATING_PSEUDO_COUNT: f64 = 0.5;

/// Every snapshot's rating from the matrix (`experiments/league.ron`): the main effects of a Poisson log-linear model of
/// the catches, E[catches of prey i by predator j] = exp(μ + a_j − b_i), the count-data analogue of
/// Bradley–Terry/Elo. For a complete matrix its maximum-likelihood fit has a closed form: a_j is the log
/// of predator j's mean catches over every prey snapshot, b_i minus the log of prey i's mean catches by
/// every predator snapshot, each against the log of the grand mean (pseudo-count
/// [`RATING_PSEUDO_COUNT`]). Units: natural log of the catch rate; +0.69 = twice the catches against the
/// same opponents. Higher is better for both species. Every opponent snapshot counts alike, so many near
/// copies of one opponent weigh as much as they are many (Nash averaging, Balduzzi et al. 2018, would not;
/// it needs the game's maximum-entropy Nash equilibrium and is not computed here).
/// Returns (prey ratings by prey snapshot, predator ratings by predator snapshot).
pub fn ratings(m: &Matrix) -> (Vec<f64>, Vec<f64>) {
    let log_mean = |v: &mut dyn Iterator<Item = f64>| {
        let finite: Vec<f64> = v.filter(|x| x.is_finite()).collect();
        match finite.is_empty() {
            true => f64::NAN,
            false => (finite.iter().sum::<f64>() / finite.len() as f64 + RATING_PSEUDO_COUNT).ln(),
        }
    };
    let grand = log_mean(&mut m.cells.iter().flatten().map(|c| c.catches));
    let prey = m.cells.iter().map(|r| grand - log_mean(&mut r.iter().map(|c| c.catches))).collect();
    let predators =
        (0..m.predator_episodes.len()).map(|j| log_mean(&mut m.cells.iter().map(|r| r[j].catches)) - grand).collect();
    (prey, predators)
}

/// The ratings as CSV: one row per snapshot.
pub(crate) fn ratings_csv(matrices: &[Matrix]) -> String {
    let mut out = String::from("prey,predator,species,episode,rating\n");
    for m in matrices {
        let (prey, predators) = ratings(m);
        let rows =
            [(&m.pair.prey_name, &m.prey_episodes, prey), (&m.pair.predator_name, &m.predator_episodes, predators)];
        for (species, episodes, values) in rows {
            for (e, v) in episodes.iter().zip(values) {
                let v = if v.is_finite() { v.to_string() } else { String::new() };
                out.push_str(&format!("{},{},{species},{e},{v}\n", m.pair.prey_name, m.pair.predator_name));
            }
        }
    }
    out
}

/// A run's ratings as `crossplay-ratings.csv` holds them, of the pair whose prey is its first: per
/// species (prey, then predator) its (snapshot episode, rating) points; None without the file.
pub fn read_ratings(run: &std::path::Path) -> Option<Vec<(String, Vec<[f64; 2]>)>> {
    let path = RunDir::new(run).crossplay(crate::store::CROSSPLAY_RATINGS);
    let text = crate::io::read_text(&path, crate::io::MAX_TEXT_BYTES).ok()?;
    let mut reader = csv::Reader::from_reader(text.as_bytes());
    let mut out: Vec<(String, Vec<[f64; 2]>)> = Vec::new();
    let mut pair: Option<(String, String)> = None;
    for record in reader.records() {
        let record = record.ok()?;
        let this = (record.get(0)?.to_string(), record.get(1)?.to_string());
        if pair.get_or_insert_with(|| this.clone()) != &this {
            break;
        }
        let (species, episode, rating) = (record.get(2)?, record.get(3)?.parse().ok()?, record.get(4)?);
        let point = [episode, rating.parse().unwrap_or(f64::NAN)];
        match out.iter_mut().find(|(s, _)| s == species) {
            Some((_, points)) => points.push(point),
            None => out.push((species.to_string(), vec![point])),
        }
    }
    (!out.is_empty()).then_some(out)
}

/// The names of [`readouts`], in order (summary.csv has a column `crossplay_<name>` for each).
pub const READOUTS: [&str; 19] = [
    "predator_progress_vs_fixed_prey",
    "prey_progress_vs_fixed_predators",
    "catches_vs_current",
    "predator_progress_vs_past_prey",
    "prey_progress_vs_past_predators",
    "prey_regress_vs_early_predators",
    "predator_regress_vs_early_prey",
    "doa_prey_trend_vs_fixed_predators",
    "doa_rise",
    "doa_rise_prey_part",
    "doa_rise_predator_part",
    "doa_late",
    "doa_late_prey_part",
    "doa_late_predator_part",
    "final_predators_vs_naive_prey",
    "naive_prey_final_minus_peak",
    "predator_rating_trend",
    "prey_rating_trend",
    "predator_rating_final_minus_peak",
];

/// The value a read-out that is a share takes without any order (0.5 for the regress shares): in claims
/// it is a level told apart from that chance; every other read-out is an effect tested against zero.
pub(crate) fn chance(readout: &str) -> Option<f64> {
    readout.contains("_regress_").then_some(0.5)
}

/// The read-outs of a run, as written in `crossplay-readouts.csv` ([`readouts_csv`]), of the pair whose
/// prey is `prey` (its first predator species); empty without the file.
pub(crate) fn read_readouts(
    run: &std::path::Path,
    prey: &str,
) -> crate::error::Result<std::collections::BTreeMap<String, f64>> {
    let path = RunDir::new(run).crossplay(crate::store::CROSSPLAY_READOUTS);
    let mut out = std::collections::BTreeMap::new();
    let Ok(text) = crate::io::read_text(&path, crate::io::MAX_TEXT_BYTES) else { return Ok(out) };
    let bad = |e: csv::Error| format!("{}: {e}", path.display());
    let mut reader = csv::Reader::from_reader(text.as_bytes());
    let mut predator: Option<String> = None;
    for record in reader.records() {
        let record = record.map_err(bad)?;
        if record.len() < 4 || &record[0] != prey || predator.as_deref().is_some_and(|p| p != &record[1]) {
            continue;
        }
        predator = Some(record[1].to_string());
        out.insert(record[2].to_string(), record[3].parse().unwrap_or(f64::NAN));
    }
    Ok(out)
}

/// The read-outs of a matrix. Generations are the snapshot episodes both species have (the diagonal and
/// CIAO need them paired); "early" opponents of generation k are generations 0..=k.
pub fn readouts(m: &Matrix) -> Vec<Readout> {
    let shared = &m
        .prey_episodes
        .iter()
        .enumerate()
        .filter_map(|(i, e)| m.predator_episodes.iter().position(|f| f == e).map(|j| (i, j)))
        .collect::<Vec<(usize, usize)>>();
    let n = shared.len();
    let at = |what: fn(&Cell) -> f64| move |a: usize, b: usize| what(&m.cells[shared[a].0][shared[b].1]);
    let catches = at(|c| c.catches);
    let doa = at(|c| c.doa);
    let (rows, columns) = (m.prey_episodes.len(), m.predator_episodes.len());
    let row = |i: usize, f: fn(&Cell) -> f64| -> Vec<f64> { m.cells[i].iter().map(f).collect() };
    let column = |j: usize, f: fn(&Cell) -> f64| -> Vec<f64> { m.cells.iter().map(|r| f(&r[j])).collect() };
    let neg = |v: Vec<f64>| -> Vec<f64> { v.into_iter().map(|x| -x).collect() };
    let past =
        |k: usize, of_predator: bool| mean((0..k).map(|l| if of_predator { catches(l, k) } else { -catches(k, l) }));
    let early = |who: usize, k: usize, prey_side: bool| {
        mean((0..=k).map(|l| if prey_side { catches(who, l) } else { catches(l, who) }))
    };
    let regress = |prey_side: bool| {
        let mut worse = (0usize, 0usize);
        for k in 0..n {
            for l in k + 1..n {
                if let (Some(later), Some(earlier)) = (early(l, k, prey_side), early(k, k, prey_side)) {
                    worse.1 += 1;
                    // Later prey caught more, or later predators catch less, by the same early opponents.
                    worse.0 += usize::from(if prey_side { later > earlier } else { later < earlier });
                }
            }
        }
        (worse.1 > 0).then(|| worse.0 as f64 / worse.1 as f64)
    };
    let diagonal = |q: &dyn Fn(usize, usize) -> f64| -> Vec<f64> { (0..n).map(|k| q(k, k)).collect() };
    // Forgetting: the naive prey (the first prey snapshot) against every predator snapshot.
    let naive: Vec<f64> = m.cells.first().map_or(vec![], |r| r.iter().map(|c| c.catches).collect());
    let peak = |v: &[f64]| v.iter().copied().filter(|x| x.is_finite()).reduce(f64::max);
    let final_minus_peak = |v: &[f64]| Some(*v.last()? - peak(v)?).filter(|x| x.is_finite());
    let (prey_ratings, predator_ratings) = ratings(m);
    let (rise, late) = match n {
        0 | 1 => ([None; 3], [None; 3]),
        2 => (decompose(doa, 0, 1).map(Some), [None; 3]),
        _ => (decompose(doa, 0, 1).map(Some), decompose(doa, 1, n - 1).map(Some)),
    };
    vec![
        Readout {
            name: "predator_progress_vs_fixed_prey",
            value: mean((0..rows).filter_map(|i| trend(&row(i, |c| c.catches)))),
            meaning: "Kendall tau of catches against predator age, per prey snapshot, averaged: +1 = later predators always catch more of the same prey",
        },
        Readout {
            name: "prey_progress_vs_fixed_predators",
            value: mean((0..columns).filter_map(|j| trend(&neg(column(j, |c| c.catches))))),
            meaning: "Kendall tau of escapes (minus catches) against prey age, per predator snapshot, averaged: +1 = later prey are always caught less by the same predators",
        },
        Readout {
            name: "catches_vs_current",
            value: trend(&diagonal(&catches)),
            meaning: "Kendall tau of catches on the diagonal (each generation against its contemporaries) against age: 0 with progress on both sides is an arms race",
        },
        Readout {
            name: "predator_progress_vs_past_prey",
            value: trend(&(1..n).filter_map(|k| past(k, true)).collect::<Vec<_>>()),
            meaning: "CIAO: Kendall tau, over generations, of a predator generation's mean catches against all earlier prey generations",
        },
        Readout {
            name: "prey_progress_vs_past_predators",
            value: trend(&(1..n).filter_map(|k| past(k, false)).collect::<Vec<_>>()),
            meaning: "CIAO: Kendall tau, over generations, of a prey generation's mean escapes against all earlier predator generations",
        },
        Readout {
            name: "prey_regress_vs_early_predators",
            value: regress(true),
            meaning: "share of generation pairs k < l in which prey l is caught more than prey k by predators of generations 0..=k (intransitivity; 0.5 without order)",
        },
        Readout {
            name: "predator_regress_vs_early_prey",
            value: regress(false),
            meaning: "share of generation pairs k < l in which predators l catch fewer than predators k of prey generations 0..=k (intransitivity; 0.5 without order)",
        },
        Readout {
            name: "doa_prey_trend_vs_fixed_predators",
            value: mean((0..columns).filter_map(|j| trend(&column(j, |c| c.doa)[1.min(rows)..]))),
            meaning: "Kendall tau of DoA against prey age (trained generations), per predator snapshot, averaged: below 0 = later prey align less against the same predators",
        },
        Readout { name: "doa_rise", value: rise[0], meaning: "diagonal DoA change from the initial snapshots to the first trained ones" },
        Readout { name: "doa_rise_prey_part", value: rise[1], meaning: "the part of doa_rise the prey's policy change makes (symmetric decomposition)" },
        Readout { name: "doa_rise_predator_part", value: rise[2], meaning: "the part of doa_rise the predators' policy change makes" },
        Readout { name: "doa_late", value: late[0], meaning: "diagonal DoA change from the first trained snapshots to the last" },
        Readout { name: "doa_late_prey_part", value: late[1], meaning: "the part of doa_late the prey's policy change makes (symmetric decomposition)" },
        Readout { name: "doa_late_predator_part", value: late[2], meaning: "the part of doa_late the predators' policy change makes" },
        Readout {
            name: "final_predators_vs_naive_prey",
            value: naive.last().copied().filter(|x| x.is_finite()),
            meaning: "catches per episode of the first prey snapshot (untrained) by the last predator snapshot: what the final predators can still do against naive prey",
        },
        Readout {
            name: "naive_prey_final_minus_peak",
            value: final_minus_peak(&naive),
            meaning: "catches of the naive prey by the last predator snapshot minus by the best one: forgetting (≤ 0; the peak is picked on noise too, so compare it between conditions, not with 0)",
        },
        Readout {
            name: "predator_rating_trend",
            value: trend(&predator_ratings),
            meaning: "Kendall tau of the predator snapshots' ratings (Poisson main effects of the matrix, ratings()) against age: +1 = every generation rates above the one before",
        },
        Readout {
            name: "prey_rating_trend",
            value: trend(&prey_ratings),
            meaning: "Kendall tau of the prey snapshots' ratings against age",
        },
        Readout {
            name: "predator_rating_final_minus_peak",
            value: final_minus_peak(&predator_ratings),
            meaning: "the last predator snapshot's rating minus the best one's (log catch rate; ≤ 0; compare between conditions)",
        },
    ]
}

/// The read-outs of every matrix as CSV.
pub(crate) fn readouts_csv(matrices: &[Matrix]) -> String {
    let mut out = String::from("prey,predator,readout,value,meaning\n");
    for m in matrices {
        for r in readouts(m) {
            out.push_str(&format!(
                "{},{},{},{},\"{}\"\n",
                m.pair.prey_name,
                m.pair.predator_name,
                r.name,
                r.value.map_or(String::new(), |v| v.to_string()),
                r.meaning
            ));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::analysis::crossplay_matrix::Pair;

    /// A matrix whose catches follow the rating model exactly: exp(μ + a_j − b_i) − the pseudo-count's
    /// share, so the ratings come back as a and b, centred.
    fn matrix(catches: impl Fn(usize, usize) -> f64, rows: usize, columns: usize) -> Matrix {
        Matrix {
            pair: Pair { prey: 1, predator: 0, prey_name: "prey".into(), predator_name: "predator".into() },
            prey_episodes: (0..rows).map(|i| 100 * i).collect(),
            predator_episodes: (0..columns).map(|j| 100 * j).collect(),
            cells: (0..rows)
                .map(|i| (0..columns).map(|j| Cell { catches: catches(i, j), ..Cell::default() }).collect())
                .collect(),
        }
    }

    #[test]
    fn ratings_are_log_catch_rates_against_every_opponent() {
        // Predator j catches twice as many as predator j − 1 of every prey; prey differ by a factor 3.
        let m = matrix(|i, j| 10.0 * 2f64.powi(j as i32) / 3f64.powi(i as i32) - RATING_PSEUDO_COUNT, 1, 3);
        let (prey, predators) = ratings(&m);
        assert_eq!(prey, [0.0]);
        let steps: Vec<f64> = predators.windows(2).map(|w| w[1] - w[0]).collect();
        assert!(steps.iter().all(|s| (s - 2f64.ln()).abs() < 1e-12), "{predators:?}");
        // Two prey a factor 3 apart (one predator): the better-escaping prey rates ln 3 higher.
        let m = matrix(|i, _| 9.0 / 3f64.powi(i as i32) - RATING_PSEUDO_COUNT, 2, 1);
        let (prey, _) = ratings(&m);
        assert!((prey[1] - prey[0] - 3f64.ln()).abs() < 1e-12, "{prey:?}");
    }

    #[test]
    fn forgetting_is_read_off_the_naive_prey_row() {
        // Predators of episodes 0..=400 catch naive prey 1, 5, 9, 4, 2 times per episode; later prey
        // are never caught.
        let naive = [1.0, 5.0, 9.0, 4.0, 2.0];
        let m = matrix(|i, j| if i == 0 { naive[j] } else { 0.0 }, 3, 5);
        let value = |name: &str| readouts(&m).into_iter().find(|r| r.name == name).unwrap().value;
        assert_eq!(value("final_predators_vs_naive_prey"), Some(2.0));
        assert_eq!(value("naive_prey_final_minus_peak"), Some(-7.0));
        // The predator ratings follow the naive row (the only one with catches): peak at episode 200.
        let (_, predators) = ratings(&m);
        let final_minus_peak = predators[4] - predators[2];
        assert_eq!(value("predator_rating_final_minus_peak"), Some(final_minus_peak));
        assert!(final_minus_peak < 0.0);
    }
}
