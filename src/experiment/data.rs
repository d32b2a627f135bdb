//! An experiment's finished runs, loaded from their CSV files (never retraining) and checked: one
//! binary, and every committed run either here or carried (`carry`).

use super::file::eval_file;
use super::file::{Experiment, Tactic, EARLY_STEPS};
use super::results::{EvalData, RunData};
use super::runner::{stage, Stage};
use super::stats::mean;
use crate::learning::nets::Kernels;
use crate::sim::metrics::Swarming;
use crate::sim::species::SpeciesRegistry;
use crate::store::schema::{self, Table};
use crate::store::RunDir;
use std::collections::BTreeMap;
use std::path::Path;

/// One bin of the first species' confusion curve, as `run::evaluate` writes it (`species,prey_in_view,
/// samples,mean_abs_turn,mean_speed_fraction,catches_per_step`).
struct ConfusionRow {
    /// The fewest prey in view the bin counts (`5` of `5-8`); None for a label that names none.
    lowest: Option<u32>,
    decisions: f64,
    turn: f64,
    speed: f64,
    catches: f64,
}

/// The first species' rows of a confusion curve file; empty when there is no file.
fn read_confusion(path: &Path) -> crate::error::Result<Vec<ConfusionRow>> {
    if !path.exists() {
        return Ok(vec![]);
    }
    let text = crate::io::read_text(path, crate::io::MAX_TEXT_BYTES)?;
    let rows: Vec<Vec<&str>> =
        text.lines().skip(1).map(|l| l.split(',').collect()).filter(|r: &Vec<&str>| r.len() == 6).collect();
    let first = rows.first().map(|r| r[0]).unwrap_or_default();
    let cell = |c: &str| c.parse::<f64>().unwrap_or(f64::NAN);
    Ok(rows
        .iter()
        .filter(|r| r[0] == first)
        .map(|r| ConfusionRow {
            lowest: r[1].trim_end_matches('+').split('-').next().and_then(|k| k.parse().ok()),
            decisions: cell(r[2]),
            turn: cell(r[3]),
            speed: cell(r[4]),
            catches: cell(r[5]),
        })
        .collect())
}

/// Each [`Tactic`] of an evaluation from its confusion curve (`confusion`, [`read_confusion`]) and its
/// `-pursuit` file (`run::evaluate`), in the order of `Tactic::ALL`; NaN for what they do not give (an
/// older coevo wrote no `-pursuit` file).
fn read_tactics(confusion: &[ConfusionRow], pursuit: &Path) -> crate::error::Result<[f64; Tactic::ALL.len()]> {
    let mut out = [f64::NAN; Tactic::ALL.len()];
    if !confusion.is_empty() {
        // Decision-weighted mean of a column over the bins whose lowest count `within` accepts.
        let mean_over = |within: &dyn Fn(u32) -> bool, column: fn(&ConfusionRow) -> f64| {
            let (sum, n) = confusion
                .iter()
                .filter(|b| b.lowest.is_some_and(within) && b.decisions > 0.0 && column(b).is_finite())
                .fold((0.0, 0.0), |(s, n), b| (s + b.decisions * column(b), n + b.decisions));
            if n > 0.0 {
                sum / n
            } else {
                f64::NAN
            }
        };
        let (few, many) = (|k: u32| (1..=2).contains(&k), |k: u32| k >= 5);
        out[Tactic::Slowdown.index()] = mean_over(&many, |b| b.speed) - mean_over(&few, |b| b.speed);
        out[Tactic::Hesitation.index()] = mean_over(&many, |b| b.turn) - mean_over(&few, |b| b.turn);
    }
    if pursuit.exists() {
        let table = Table::read_eval(pursuit)?;
        let step = table.column("step")?;
        let weight = table.column("pursuers")?;
        let [centre, isolated, nearest, boundary] =
            ["steer_centre", "steer_isolated", "steer_nearest", "boundary_share"].map(|c| table.column(c));
        let (centre, isolated, nearest, boundary) = (centre?, isolated?, nearest?, boundary?);
        let early = |i: usize| step[i] as usize <= EARLY_STEPS;
        // Pursuer-weighted mean of `value` over the rows `keep` accepts (rows without a value skipped).
        let weighted = |value: &dyn Fn(usize) -> f64, keep: &dyn Fn(usize) -> bool, weighted: bool| {
            let (sum, n) = (0..step.len())
                .filter(|&i| keep(i) && value(i).is_finite())
                .map(|i| (value(i), if weighted { weight[i] } else { 1.0 }))
                .fold((0.0, 0.0), |(s, n), (v, w)| (s + w * v, n + w));
            if n > 0.0 {
                sum / n
            } else {
                f64::NAN
            }
        };
        let centre_first = |i: usize| centre[i] - isolated[i];
        let centre_early = weighted(&centre_first, &early, true);
        let centre_later = weighted(&centre_first, &|i| !early(i), true);
        out[Tactic::CentreEarly.index()] = centre_early;
        out[Tactic::CentreChange.index()] = centre_later - centre_early;
        out[Tactic::IsolatedOverNearest.index()] = weighted(&|i| isolated[i] - nearest[i], &|i| !early(i), true);
        out[Tactic::SteerNearest.index()] = weighted(&|i| nearest[i], &|_| true, true);
        let uniform = crate::sim::collective::boundary_share_uniform(crate::run::evaluate::BOUNDARY_BAND);
        out[Tactic::BoundaryExcess.index()] = weighted(&|i| boundary[i], &|i| !early(i), false) - uniform;
    }
    Ok(out)
}

/// The near and far responses of a perturbation file (`run::perturb`): the sample-weighted mean
/// |Δheading| of ranks 1–6 over lags 1–10, and of ranks 25+ over the same lags; NaN without the file.
fn read_response(path: &Path) -> crate::error::Result<[f64; 2]> {
    use crate::run::perturb::{read_rows, weighted_mean};
    Ok(match read_rows(path)? {
        Some(rows) => {
            [weighted_mean(&rows, 1.0..=10.0, 1.0..=6.0), weighted_mean(&rows, 1.0..=10.0, 25.0..=f64::INFINITY)]
        }
        None => [f64::NAN; 2],
    })
}

/// The species whose DoS/DoA an experiment reports (prey in the paper's scenes).
pub(super) fn headline(exp: &Experiment) -> String {
    let scene = &exp.runs[0].scene;
    scene.species[SpeciesRegistry::from_scene(scene).headline()].name.clone()
}

/// The data of every finished run, by run index.
pub(crate) fn load(exp: &Experiment) -> crate::error::Result<BTreeMap<usize, RunData>> {
    let prey = headline(exp);
    let mut data = BTreeMap::new();
    for (i, run) in exp.runs.iter().enumerate() {
        if stage(run)? != Stage::Trained {
            continue;
        }
        for e in &exp.spec.evaluations {
            if let Some(stale) = eval_file(&run.dir, &e.name).exists().then(|| super::runner::stale(run, e)).flatten() {
                return Err(format!("{stale}; run `coevo --experiment {}` to redo it", exp.file.display()).into());
            }
        }
        // Trained but an evaluation or its cross-play still to come: not finished, so not a row (a row is
        // a finished run, which another machine carries as it is).
        if !super::runner::finished(exp, run) {
            continue;
        }
        let (metrics, _) = RunDir::new(&run.dir).checked_metrics(false)?;
        let mut d = RunData {
            dos: metrics.column(&schema::of("dos", &prey))?,
            doa: metrics.column(&schema::of("doa", &prey))?,
            catches: metrics.column(schema::CATCHES)?,
            returns: metrics.column(&schema::of("return", &prey))?,
            wall_seconds: metrics.column(schema::WALL_SECONDS)?.last().copied().unwrap_or(0.0),
            orders: super::file::EVAL_ORDER
                .iter()
                .map(|q| {
                    (
                        q.to_string(),
                        metrics
                            .column(&schema::of(q.name(), &prey))
                            .unwrap_or_else(|_| vec![f64::NAN; metrics.rows.len()]),
                    )
                })
                .collect(),
            evals: BTreeMap::new(),
            crossplay: super::crossplay_readouts::read_readouts(&run.dir, &prey)?,
            distilled: super::distill::read_numbers(&RunDir::new(&run.dir).distilled())?,
            binaries: vec!["unknown".into()],
            kernels: String::new(),
        };
        // The authors' DoS and DoA, where the scene measured them (`authors_metrics`): curves like the
        // order parameters, read by the claims on the paper's numbers as the shipped code measures them.
        for q in super::results::AUTHORS_CURVES {
            if let Ok(values) = metrics.column(&schema::of(q, &prey)) {
                d.orders.insert(q.to_string(), values);
            }
        }
        if let Some(p) = RunDir::new(&run.dir).read_provenance()? {
            d.binaries = p.binaries().into_iter().map(String::from).collect();
            d.kernels = p.kernels;
        }
        for e in &exp.spec.evaluations {
            let path = eval_file(&run.dir, &e.name);
            if !path.exists() {
                continue;
            }
            let table = Table::read_eval(&path)?;
            let step = table.column(schema::STEP)?;
            let steps = step.iter().fold(0.0f64, |a, &b| a.max(b)) as usize;
            let per_step = |values: &[f64]| -> Vec<f64> {
                (1..=steps)
                    .map(|s| {
                        mean(
                            &step
                                .iter()
                                .zip(values)
                                .filter(|(t, v)| **t as usize == s && v.is_finite())
                                .map(|(_, v)| *v)
                                .collect::<Vec<_>>(),
                        )
                        .unwrap_or(f64::NAN)
                    })
                    .collect()
            };
            // DoS and DoA must be there; the other order parameters only since the collective measures.
            let series = |name: &str| -> crate::error::Result<Vec<f64>> {
                match table.column(&schema::of(name, &prey)) {
                    Ok(values) => Ok(per_step(&values)),
                    Err(_) if !matches!(name, "dos" | "doa") => Ok(vec![f64::NAN; steps]),
                    Err(e) => Err(e),
                }
            };
            let per_step = Swarming::NAMES.iter().map(|n| series(n)).collect::<crate::error::Result<Vec<_>>>()?;
            let ranks = table.column(&schema::of(schema::EDGE_RANK, &prey)).unwrap_or_default();
            let edge_rank = mean(&ranks.into_iter().filter(|x| x.is_finite()).collect::<Vec<_>>()).unwrap_or(f64::NAN);
            let curve = read_confusion(&crate::io::beside(&path, "confusion"))?;
            let response = read_response(&crate::io::beside(&path, crate::store::PERTURBATION))?;
            let tactics = read_tactics(&curve, &crate::io::beside(&path, "pursuit"))?;
            let confusion = curve.iter().map(|b| [b.turn, b.speed, b.catches]).collect();
            // Every catch of the evaluation per episode and per prey deployed (the evaluation's count).
            let catches = table.column(schema::CATCHES).unwrap_or_default();
            let episodes = table
                .column(schema::EPISODE)
                .map_or(0, |v| v.iter().map(|e| *e as u64).collect::<std::collections::BTreeSet<_>>().len());
            let mut deployed = run.scene.clone();
            let prey_count = match e.overrides().apply(&mut deployed, &path) {
                Ok(()) => deployed.species.iter().find(|s| s.name == prey).map_or(0, |s| s.count),
                Err(_) => 0,
            };
            let catches_per_prey = match (episodes, prey_count) {
                (0, _) | (_, 0) => f64::NAN,
                (k, n) => catches.iter().filter(|c| c.is_finite()).sum::<f64>() / (k * n) as f64,
            };
            d.evals.insert(
                e.name.clone(),
                EvalData { per_step, edge_rank, catches_per_prey, confusion, response, tactics },
            );
        }
        data.insert(i, d);
    }
    check_one_binary(exp, &data)?;
    Ok(data)
}

/// Refuses runs (training, resumes, evaluations) made by more than one executable (a pinned binary and
/// its verified rebuilds count as one, [`super::pin`]), or on more than one family of matrix-product
/// kernels, unless the experiment file says `mixed_binaries: true`: its numbers
/// would not come from one program.
fn check_one_binary(exp: &Experiment, data: &BTreeMap<usize, RunData>) -> crate::error::Result<()> {
    if exp.spec.mixed_binaries {
        return Ok(());
    }
    // A variant on its own family (`kernels:`) runs on that one; the others on one family between them.
    if let Some((&i, d)) = data.iter().find(|&(&i, d)| {
        let family = exp.runs[i].kernels;
        !d.kernels.is_empty() && family.is_some_and(|f| Some(f) != Kernels::parse(&d.kernels))
    }) {
        return Err(format!(
            "{}: {} ran on {} kernels, not its variant's {}; rerun it",
            exp.file.display(),
            exp.runs[i].dir.display(),
            d.kernels,
            exp.runs[i].kernels.map_or("", Kernels::name)
        )
        .into());
    }
    let mut families = data.iter().filter(|&(&i, d)| !d.kernels.is_empty() && exp.runs[i].kernels.is_none());
    if let Some((&first, a)) = families.next() {
        if let Some((&other, b)) = families.find(|(_, b)| b.kernels != a.kernels) {
            return Err(format!(
                "{}: runs on more than one family of matrix-product kernels ({} on {}, {} on {}); rerun them on one (COEVO_KERNELS or --kernels) or set mixed_binaries: true",
                exp.file.display(),
                exp.runs[first].dir.display(),
                a.kernels,
                exp.runs[other].dir.display(),
                b.kernels
            )
            .into());
        }
    }
    let mut first: Option<(&str, &std::path::Path)> = None;
    for (&i, d) in data {
        let dir = &exp.runs[i].dir;
        for b in &d.binaries {
            match first {
                None => first = Some((b, dir)),
                Some((a, other)) if !super::pin::Pin::same(exp.pin.as_ref(), a, b) => {
                    return Err(format!(
                        "{}: runs of more than one binary ({} by {a}, {} by {b}); rerun them with one coevo or set mixed_binaries: true",
                        exp.file.display(),
                        other.display(),
                        dir.display()
                    )
                    .into())
                }
                Some(_) => {}
            }
        }
    }
    Ok(())
}

/// What aggregation carries of the committed runs that have no folder here ([`super::carry::carried`]),
/// refused when a run of the committed `summary.csv` (that the experiment file still has) cannot be
/// carried (no record of its scene, another scene, another binary or kernels, its figure data missing):
/// aggregating would drop it from the summary and the figures. Nothing is written then. With no run folder
/// at all (a fresh clone) nothing is carried: the committed summary.csv is read as it is and nothing of it
/// is rewritten.
pub(crate) fn check_complete(
    exp: &Experiment,
    data: &BTreeMap<usize, RunData>,
) -> crate::error::Result<super::carry::Carried> {
    let header = super::summary::header(&super::summary::columns(exp));
    super::carry::carried(exp, data, &header)
}
