//! The read-outs of a cross-play matrix a researcher can cite (progress, regress, where a change of
//! alignment comes from), written to `crossplay-readouts.csv` and read back for claims.

use super::crossplay_matrix::{Cell, Matrix};
use super::stats::kendall_tau;
use crate::run::RunDir;

/// One read-out of a matrix: its name, value (None where undefined) and what it says.
#[derive(Clone, Debug, PartialEq)]
pub struct Readout {
    pub name: &'static str,
    pub value: Option<f64>,
    pub meaning: &'static str,
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

/// The names of [`readouts`], in order (summary.csv has a column `crossplay_<name>` for each).
pub const READOUTS: [&str; 14] = [
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
];

/// The value a read-out that is a share takes without any order (0.5 for the regress shares): in claims
/// it is a level told apart from that chance; every other read-out is an effect tested against zero.
pub fn chance(readout: &str) -> Option<f64> {
    readout.contains("_regress_").then_some(0.5)
}

/// The read-outs of a run, as written in `crossplay-readouts.csv` ([`readouts_csv`]), of the pair whose
/// prey is `prey` (its first predator species); empty without the file.
pub fn read_readouts(
    run: &std::path::Path,
    prey: &str,
) -> crate::error::Result<std::collections::BTreeMap<String, f64>> {
    let path = RunDir::new(run).crossplay(crate::run::CROSSPLAY_READOUTS);
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
    ]
}

/// The read-outs of every matrix as CSV.
pub fn readouts_csv(matrices: &[Matrix]) -> String {
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
