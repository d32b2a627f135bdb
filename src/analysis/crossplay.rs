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
//! the scene has more than one predator–prey pair of learning species), `crossplay-readouts.csv`,
//! `crossplay-ratings.csv` (every snapshot's rating, `crossplay_readouts::ratings`), and heat maps in
//! `figures/`. The matrix and its CSV are `crossplay_matrix.rs`; the read-outs
//! `crossplay_readouts.rs`.

use super::crossplay_matrix::{cells_csv, pairs, Cell, Matrix, Pair};
use super::crossplay_readouts::{ratings_csv, readouts, readouts_csv};
use super::plot;
use crate::learning::{Learners, Mode};
use crate::run::args::Shared;
use crate::scene::{Overrides, Scene};
use crate::sim::clock::Episode;
use crate::sim::metrics::EpisodeLog;
use crate::sim::species::SpeciesRegistry;
use crate::store::RunDir;
use indicatif::{ProgressBar, ProgressStyle};
use std::path::PathBuf;
use std::time::Instant;

#[derive(Clone, Debug, PartialEq)]
pub struct CrossplayOptions {
    pub run: PathBuf,
    /// Episodes per cell (the same seeds in every cell).
    pub episodes: usize,
    /// Counts, seed and steps per episode (default: the run's).
    pub overrides: Overrides,
    pub progress: bool,
}

/// `--crossplay RUN`.
#[derive(clap::Args, Debug, Clone, Default)]
pub(crate) struct CrossplayArgs {
    /// Play every prey snapshot of a run against every predator snapshot (noise off, the same seeds in
    /// every cell; --episodes per cell, default 5); writes DIR/crossplay.csv, crossplay-readouts.csv and
    /// heat maps in DIR/figures/.
    #[arg(long, help_heading = "Modes", value_name = "DIR")]
    pub(crate) crossplay: Option<PathBuf>,
}

impl crate::run::args::Mode for CrossplayArgs {
    const MODE: &'static str = "crossplay";
    const TAKES: &'static [&'static str] = &["episodes", "steps", "seed", "prey", "predators", "count", "quiet"];
}

impl CrossplayArgs {
    pub(crate) fn options(&self, run: &std::path::Path, shared: &Shared) -> crate::error::Result<CrossplayOptions> {
        Ok(CrossplayOptions {
            run: run.to_path_buf(),
            episodes: shared.common.episodes.unwrap_or(5),
            overrides: shared.scene.overrides(true)?,
            progress: !shared.common.quiet,
        })
    }
}

impl CrossplayOptions {
    /// The call that runs this cross-play, as argv.
    pub(crate) fn to_argv(&self) -> Vec<String> {
        let mut argv =
            vec!["--crossplay".into(), self.run.display().to_string(), "--episodes".into(), self.episodes.to_string()];
        argv.extend(crate::run::args::overrides_argv(&self.overrides, &[]));
        if !self.progress {
            argv.push("--quiet".into());
        }
        argv
    }
}

/// `--crossplay`: plays the run and prints each matrix's read-outs and the files written.
pub(crate) fn main(opts: &CrossplayOptions) -> crate::error::Result<()> {
    let (matrices, written) = crossplay(opts)?;
    for m in &matrices {
        crate::outln!(
            "cross-play {}: {} {} snapshots × {} {} snapshots, {} episodes per cell",
            opts.run.display(),
            m.prey_episodes.len(),
            m.pair.prey_name,
            m.predator_episodes.len(),
            m.pair.predator_name,
            opts.episodes
        )?;
        for r in readouts(m) {
            let value = r.value.map_or("–".to_string(), |v| format!("{v:+.3}"));
            crate::outln!("  {:<36} {value:>7}", r.name)?;
        }
    }
    for line in written {
        crate::outln!("wrote {line}")?;
    }
    Ok(())
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
    crate::store::load_actors(&mut learners, scene, Some(run))?;
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
    crate::io::check_targets(&outputs(&dir, &pairs), crate::io::Existing::Replace)?;
    crate::io::check_own_dir(&dir.figures())?;
    // Every snapshot, loaded (and checked against the scene's shapes) before anything is played.
    let like = Learners::new(&scene, Mode::Evaluate);
    let mut snapshots: Vec<Vec<(usize, crate::learning::nets::Mlp)>> = vec![vec![]; registry.len()];
    for s in pairs.iter().flat_map(|p| [p.prey, p.predator]) {
        if !snapshots[s].is_empty() {
            continue;
        }
        let name = &registry.defs[s].name;
        let episodes = crate::store::snapshots::snapshot_episodes(&opts.run, name);
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
            snapshots[s].push((e, crate::store::snapshots::load_snapshot(&opts.run, name, e, shape)?));
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

/// File stem of a pair's outputs: `crossplay` when it is the scene's only pair.
fn stem(pair: &Pair, only: bool) -> String {
    match only {
        true => crate::store::CROSSPLAY.into(),
        false => format!("{}-{}-{}", crate::store::CROSSPLAY, pair.prey_name, pair.predator_name),
    }
}

/// Every file [`write`] will write for these pairs: checked before the first cell is played, so a
/// folder, a FIFO or a link where one of them goes is refused before the work, not after it.
fn outputs(dir: &RunDir, pairs: &[Pair]) -> Vec<std::path::PathBuf> {
    let only = pairs.len() == 1;
    let mut files = vec![];
    for p in pairs {
        files.push(dir.crossplay(&stem(p, only)));
        files.extend(plot::files(&dir.figures().join(stem(p, only))));
    }
    files.push(dir.crossplay(crate::store::CROSSPLAY_READOUTS));
    files.push(dir.crossplay(crate::store::CROSSPLAY_RATINGS));
    files
}

/// The heat maps of a matrix (catches and the prey's DoA over prey × predator snapshots).
pub(crate) fn heatmaps(m: &Matrix, what: &str) -> Vec<plot::Heatmap> {
    let grid = |f: fn(&Cell) -> f64| m.cells.iter().map(|r| r.iter().map(f).collect()).collect();
    let map = |title: String, values: Vec<Vec<f64>>, log: bool| plot::Heatmap {
        title,
        x_label: format!("{} snapshot (episode)", m.pair.predator_name),
        y_label: format!("{} snapshot (episode)", m.pair.prey_name),
        x_ticks: m.predator_episodes.iter().map(usize::to_string).collect(),
        y_ticks: m.prey_episodes.iter().map(usize::to_string).collect(),
        values,
        log,
        diverging: false,
        marked: Vec::new(),
        annotate: false,
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
        let csv = dir.crossplay(&stem(&m.pair, only));
        crate::io::write_file(&csv, Existing::Replace, cells_csv(m).as_bytes())?;
        let figure = figures.join(stem(&m.pair, only));
        plot::save_heatmaps(&figure, &heatmaps(m, ""))?;
        written.push(csv.display().to_string());
        written.push(plot::files(&figure)[1].display().to_string());
    }
    let readouts = dir.crossplay(crate::store::CROSSPLAY_READOUTS);
    crate::io::write_file(&readouts, Existing::Replace, readouts_csv(matrices).as_bytes())?;
    written.push(readouts.display().to_string());
    let ratings = dir.crossplay(crate::store::CROSSPLAY_RATINGS);
    crate::io::write_file(&ratings, Existing::Replace, ratings_csv(matrices).as_bytes())?;
    written.push(ratings.display().to_string());
    Ok(written)
}
