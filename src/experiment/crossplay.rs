//! `coevo --crossplay RUN`: is it coevolution? Every snapshot of the prey against every snapshot of its
//! predators (the cross-play matrix; its lower triangle, each generation against all earlier opponents,
//! is the CIAO view of Cliff & Miller 1995), and read-outs a researcher can cite: progress against fixed,
//! current and past opponents, regress against early opponents, and where a change of alignment over
//! training comes from (the prey's policy or the predators'). Not in the paper.
//!
//! Every cell deploys two snapshots (`RUN/snapshots/`, written by `--train`) without noise for the same
//! episodes: the same seed, so the same initial populations in every cell, and cells differ only by the
//! actors. Other learning species act with the run's final actors. Cells are independent and run on all
//! cores; a cell computes the same numbers at any thread count.
//!
//! Writes, in the run folder: `crossplay.csv` (one row per cell; `crossplay-<prey>-<predator>.csv` when
//! the scene has more than one predator–prey pair of learning species), `crossplay-readouts.csv`, and
//! heat maps in `figures/`.

use super::plot;
use super::stats::kendall_tau;
use crate::learning::{checkpoint, Learners, Mode};
use crate::run::RunDir;
use crate::scene::{Overrides, Policy, Scene};
use crate::sim::clock::Episode;
use crate::sim::metrics::EpisodeLog;
use crate::sim::species::SpeciesRegistry;
use indicatif::{ProgressBar, ProgressStyle};
use std::path::PathBuf;
use std::time::Instant;

pub struct CrossplayOptions {
    pub run: PathBuf,
    /// Episodes per cell (the same seeds in every cell).
    pub episodes: usize,
    /// Counts, seed and steps per episode (default: the run's).
    pub overrides: Overrides,
    pub progress: bool,
}

/// A pair of learning species: `prey` (the matrix's rows) caught by `predator` (its columns).
#[derive(Clone, Debug)]
pub struct Pair {
    pub prey: usize,
    pub predator: usize,
    pub prey_name: String,
    pub predator_name: String,
}

/// One cell: means over its episodes of the per-episode means (as `metrics.csv` has them), of the prey.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Cell {
    /// Catches of the prey by the predator species, per episode.
    pub catches: f64,
    pub dos: f64,
    pub doa: f64,
    pub nn_correlation: f64,
    pub polarization: f64,
}

impl Cell {
    pub const NAMES: [&'static str; 5] = ["catches", "dos", "doa", "nn_correlation", "polarization"];

    /// The cell's values in [`Cell::NAMES`] order.
    pub fn values(&self) -> [f64; 5] {
        [self.catches, self.dos, self.doa, self.nn_correlation, self.polarization]
    }

    /// The cell of values in [`Cell::NAMES`] order.
    pub fn from_values([catches, dos, doa, nn_correlation, polarization]: [f64; 5]) -> Cell {
        Cell { catches, dos, doa, nn_correlation, polarization }
    }
}

/// The cross-play matrix of a pair: `cells[i][j]` is prey snapshot `prey_episodes[i]` against predator
/// snapshot `predator_episodes[j]`.
#[derive(Clone, Debug)]
pub struct Matrix {
    pub pair: Pair,
    pub prey_episodes: Vec<usize>,
    pub predator_episodes: Vec<usize>,
    pub cells: Vec<Vec<Cell>>,
}

/// The predator–prey pairs among the learning species.
fn pairs(registry: &SpeciesRegistry) -> Vec<Pair> {
    let learned = |s: usize| matches!(registry.policy(s), Policy::Learned);
    (0..registry.len())
        .filter(|&prey| learned(prey))
        .flat_map(|prey| registry.predators_of(prey).filter(move |&p| learned(p) && p != prey).map(move |p| (prey, p)))
        .map(|(prey, predator)| Pair {
            prey,
            predator,
            prey_name: registry.defs[prey].name.clone(),
            predator_name: registry.defs[predator].name.clone(),
        })
        .collect()
}

/// One cell's numbers: `episodes` episodes of the scene with the two snapshots deployed.
fn play(
    scene: &Scene,
    run: &std::path::Path,
    pair: &Pair,
    actors: [&crate::learning::nets::Mlp; 2],
    episodes: usize,
) -> crate::error::Result<Cell> {
    let mut learners = Learners::new(scene, Mode::Evaluate);
    learners.load_actors(scene, Some(run))?;
    for (s, actor) in [pair.prey, pair.predator].into_iter().zip(actors) {
        learners.species[s].as_mut().expect("learning species have learners").ddpg.actor = actor.clone();
    }
    let mut sim = crate::learning::simulation_of(scene.clone(), learners, |_| {})?;
    while sim.world().resource::<Episode>().index < episodes {
        sim.step();
        sim.check()?;
    }
    let log = &sim.world().resource::<EpisodeLog>().episodes[..episodes];
    let mut sum = [0.0; 5];
    for e in log {
        let sw = e.swarming[pair.prey].unwrap_or_default();
        let values = [e.catches_by[pair.predator] as f64, sw.dos, sw.doa, sw.nn_correlation, sw.polarization];
        sum.iter_mut().zip(values).for_each(|(a, v)| *a += v);
    }
    let [catches, dos, doa, nn_correlation, polarization] = sum.map(|v| v / episodes as f64);
    Ok(Cell { catches, dos, doa, nn_correlation, polarization })
}

/// Plays every cell of every pair of a run, writes the run's cross-play files ([`write`]) and returns the
/// matrices and the files written. Everything is checked and loaded before anything is played.
pub fn crossplay(opts: &CrossplayOptions) -> crate::error::Result<(Vec<Matrix>, Vec<String>)> {
    let dir = RunDir::new(&opts.run);
    let no_run = || Err(format!("{}: holds no trained coevo run to cross-play", opts.run.display()).into());
    if !dir.is_run() {
        return no_run();
    }
    dir.check_plugins()?;
    if opts.episodes == 0 {
        return Err("--episodes: must be ≥ 1".into());
    }
    // Nobody else writes the run meanwhile, and what a killed process left (a checkpoint swap cut short)
    // is put right before its snapshots are read and checked against the manifest. Its numbers become
    // part of the run's (provenance `also_by`).
    let _lock = dir.lock()?;
    if !dir.has_actors() {
        return no_run();
    }
    let scene_path = dir.scene();
    let scene = opts.overrides.load(&scene_path)?;
    let registry = SpeciesRegistry::from_scene(&scene);
    let pairs = pairs(&registry);
    if pairs.is_empty() {
        return Err(format!(
            "{}: no learning species catches another learning species; cross-play needs a predator–prey pair that both learn",
            scene_path.display()
        )
        .into());
    }
    // Every snapshot, loaded (and checked against the scene's shapes) before anything is played.
    let like = Learners::new(&scene, Mode::Evaluate);
    let mut snapshots: Vec<Vec<(usize, crate::learning::nets::Mlp)>> = vec![vec![]; registry.len()];
    for s in pairs.iter().flat_map(|p| [p.prey, p.predator]) {
        if !snapshots[s].is_empty() {
            continue;
        }
        let name = &registry.defs[s].name;
        let episodes = checkpoint::snapshot_episodes(&opts.run, name);
        if episodes.len() < 2 {
            return Err(format!(
                "{}: {} snapshot(s) of {name}, cross-play needs two or more (runs trained before coevo kept snapshots have none; retrain, with learning.snapshot_every > 0)",
                dir.snapshots().display(),
                episodes.len()
            )
            .into());
        }
        let shape = &like.species[s].as_ref().expect("learning species have learners").ddpg.actor;
        for e in episodes {
            snapshots[s].push((e, checkpoint::load_snapshot(&opts.run, name, e, shape)?));
        }
    }
    dir.note_binary()?;
    // Cells of every pair, row-major, in one list: they run on all cores.
    let mut cells: Vec<(usize, usize, usize, crate::error::Result<Cell>)> = pairs
        .iter()
        .enumerate()
        .flat_map(|(k, p)| {
            let (rows, columns) = (snapshots[p.prey].len(), snapshots[p.predator].len());
            (0..rows).flat_map(move |i| (0..columns).map(move |j| (k, i, j, Ok(Cell::default()))))
        })
        .collect();
    let total = cells.len();
    let bar = if opts.progress { ProgressBar::new(total as u64) } else { ProgressBar::hidden() };
    bar.set_style(ProgressStyle::with_template("{bar:30} {pos}/{len} cells  ETA {eta}").expect("valid template"));
    let run_cell = |(k, i, j, out): &mut (usize, usize, usize, crate::error::Result<Cell>)| {
        let p = &pairs[*k];
        *out = play(&scene, &opts.run, p, [&snapshots[p.prey][*i].1, &snapshots[p.predator][*j].1], opts.episodes);
        bar.inc(1);
    };
    // The first cell alone, timed, says how long the whole matrix will take.
    let started = Instant::now();
    run_cell(&mut cells[0]);
    let per_cell = started.elapsed().as_secs_f64();
    if opts.progress {
        let threads = crate::parallel::threads().min(total).max(1);
        bar.println(format!(
            "cross-play: {total} cells × {} episodes × {} steps, ~{:.0} s at {:.2} s per cell on {threads} threads",
            opts.episodes,
            scene.episode_steps,
            per_cell * (total - 1) as f64 / threads as f64,
            per_cell
        ));
    }
    crate::parallel::for_each_mut(&mut cells[1..], run_cell);
    bar.finish_and_clear();
    let mut matrices: Vec<Matrix> = pairs
        .iter()
        .map(|p| Matrix {
            pair: p.clone(),
            prey_episodes: snapshots[p.prey].iter().map(|(e, _)| *e).collect(),
            predator_episodes: snapshots[p.predator].iter().map(|(e, _)| *e).collect(),
            cells: vec![vec![Cell::default(); snapshots[p.predator].len()]; snapshots[p.prey].len()],
        })
        .collect();
    for (k, i, j, cell) in cells {
        matrices[k].cells[i][j] = cell?;
    }
    let written = write(&opts.run, &matrices)?;
    Ok((matrices, written))
}

/// The cells of a matrix as CSV, one row per cell.
pub fn cells_csv(m: &Matrix) -> String {
    let mut out = format!(
        "{}_episode,{}_episode,{}\n",
        m.pair.prey_name,
        m.pair.predator_name,
        Cell::NAMES.map(|n| if n == "catches" { n.to_string() } else { format!("{n}_{}", m.pair.prey_name) }).join(",")
    );
    for (i, row) in m.cells.iter().enumerate() {
        for (j, c) in row.iter().enumerate() {
            let values: Vec<String> = c.values().iter().map(f64::to_string).collect();
            out.push_str(&format!("{},{},{}\n", m.prey_episodes[i], m.predator_episodes[j], values.join(",")));
        }
    }
    out
}

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

/// A run's cross-play matrix as written in `crossplay.csv` (the scene's only pair), None without one.
pub fn read_matrix(run: &std::path::Path, pair: &Pair) -> crate::error::Result<Option<Matrix>> {
    let path = RunDir::new(run).crossplay(crate::run::CROSSPLAY);
    let Ok(text) = crate::io::read_text(&path, crate::io::MAX_TEXT_BYTES) else { return Ok(None) };
    let bad = |e: csv::Error| format!("{}: {e}", path.display());
    let mut reader = csv::Reader::from_reader(text.as_bytes());
    let mut rows: Vec<(usize, usize, Cell)> = vec![];
    for record in reader.records() {
        let record = record.map_err(bad)?;
        let number = |i: usize| record.get(i).and_then(|c| c.parse::<f64>().ok()).unwrap_or(f64::NAN);
        let (i, j) = (number(0) as usize, number(1) as usize);
        let cell = Cell {
            catches: number(2),
            dos: number(3),
            doa: number(4),
            nn_correlation: number(5),
            polarization: number(6),
        };
        rows.push((i, j, cell));
    }
    let mut prey_episodes: Vec<usize> = rows.iter().map(|r| r.0).collect();
    let mut predator_episodes: Vec<usize> = rows.iter().map(|r| r.1).collect();
    for v in [&mut prey_episodes, &mut predator_episodes] {
        v.sort_unstable();
        v.dedup();
    }
    let mut cells =
        vec![vec![Cell { catches: f64::NAN, ..Cell::default() }; predator_episodes.len()]; prey_episodes.len()];
    for (i, j, cell) in rows {
        let (a, b) = (prey_episodes.binary_search(&i), predator_episodes.binary_search(&j));
        if let (Ok(a), Ok(b)) = (a, b) {
            cells[a][b] = cell;
        }
    }
    Ok(Some(Matrix { pair: pair.clone(), prey_episodes, predator_episodes, cells }))
}

/// The cell-by-cell mean of matrices over the same snapshots (seeds of one variant), None when there are
/// none or their snapshots differ.
pub fn mean_matrix(matrices: &[Matrix]) -> Option<Matrix> {
    let first = matrices.first()?;
    let same = |m: &Matrix| m.prey_episodes == first.prey_episodes && m.predator_episodes == first.predator_episodes;
    if !matrices.iter().all(same) {
        return None;
    }
    let mut mean = first.clone();
    for (i, row) in mean.cells.iter_mut().enumerate() {
        for (j, cell) in row.iter_mut().enumerate() {
            let values: Vec<[f64; 5]> = matrices.iter().map(|m| m.cells[i][j].values()).collect();
            let [catches, dos, doa, nn_correlation, polarization] =
                std::array::from_fn(|k| values.iter().map(|v| v[k]).sum::<f64>() / values.len() as f64);
            *cell = Cell { catches, dos, doa, nn_correlation, polarization };
        }
    }
    Some(mean)
}

/// The pair a scene's cross-play is of, when it has exactly one.
pub fn only_pair(scene: &Scene) -> Option<Pair> {
    let found = pairs(&SpeciesRegistry::from_scene(scene));
    (found.len() == 1).then(|| found[0].clone())
}

/// File stem of a pair's outputs: `crossplay` when it is the scene's only pair.
fn stem(m: &Matrix, only: bool) -> String {
    match only {
        true => crate::run::CROSSPLAY.into(),
        false => format!("{}-{}-{}", crate::run::CROSSPLAY, m.pair.prey_name, m.pair.predator_name),
    }
}

/// The heat maps of a matrix (catches and the prey's DoA over prey × predator snapshots).
pub fn heatmaps(m: &Matrix, what: &str) -> Vec<plot::Heatmap> {
    let grid = |f: fn(&Cell) -> f64| m.cells.iter().map(|r| r.iter().map(f).collect()).collect();
    let map = |title: String, values: Vec<Vec<f64>>, log: bool| plot::Heatmap {
        title,
        x_label: format!("{} snapshot (episode)", m.pair.predator_name),
        y_label: format!("{} snapshot (episode)", m.pair.prey_name),
        x_ticks: m.predator_episodes.clone(),
        y_ticks: m.prey_episodes.clone(),
        values,
        log,
    };
    vec![
        map(format!("{what}catches per episode"), grid(|c| c.catches), true),
        map(format!("{what}DoA of {}", m.pair.prey_name), grid(|c| c.doa), false),
    ]
}

/// Writes a run's cross-play files (module docs) and returns what was written, a line each.
fn write(run: &std::path::Path, matrices: &[Matrix]) -> crate::error::Result<Vec<String>> {
    use crate::io::Existing;
    let dir = RunDir::new(run);
    let figures = dir.figures();
    crate::io::own_dir(&figures)?;
    let mut written = Vec::new();
    let only = matrices.len() == 1;
    for m in matrices {
        let csv = dir.crossplay(&stem(m, only));
        crate::io::write_file(&csv, Existing::Replace, cells_csv(m).as_bytes())?;
        let figure = figures.join(stem(m, only));
        plot::save_heatmaps(&figure, &heatmaps(m, ""))?;
        written.push(csv.display().to_string());
        written.push(figure.with_extension("png").display().to_string());
    }
    let readouts = dir.crossplay(crate::run::CROSSPLAY_READOUTS);
    crate::io::write_file(&readouts, Existing::Replace, readouts_csv(matrices).as_bytes())?;
    written.push(readouts.display().to_string());
    Ok(written)
}
