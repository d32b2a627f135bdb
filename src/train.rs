//! Headless training and evaluation runs, driving the fixed-step schedule directly.
//!
//! A run folder holds `scene.ron` (the resolved scene), `metrics.csv` (one row per episode) and
//! `checkpoint/` (see `learning::checkpoint`). `--eval` adds `eval.csv` (one row per time step).

use crate::run::RunDir;
use crate::sim::clock::Episode;
use crate::sim::episode::{SimRng, SpawnedFrom};
use crate::io::{AtomicFile, Existing};
use crate::learning::checkpoint::{self, SpeciesState, TrainingState};
use crate::learning::{Learners, LearningPlugin, Mode};
use crate::sim::metrics::{EpisodeLog, EpisodeSummary, SwarmMetrics, Swarming};
use crate::scene::Scene;
use crate::sim::species::SpeciesRegistry;
use crate::sim::Simulation;
use bevy::prelude::App;
use indicatif::{ProgressBar, ProgressStyle};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

pub struct TrainOptions {
    pub run: PathBuf,
    pub resume: bool,
    /// Replace the run already in `run` (its own files only) instead of refusing.
    pub overwrite: bool,
    /// Total episodes of the run (the scene's `episodes` when None).
    pub episodes: Option<usize>,
    pub progress: bool,
}

/// The species whose DoS/DoA headline a run: the first that something catches and that catches nothing
/// (the prey, also in a scene where hawks catch predators), else the first that something catches, else
/// the first with at least two agents.
pub fn headline_species(registry: &SpeciesRegistry) -> usize {
    let caught = |s: usize| registry.predators_of(s).next().is_some() && registry.defs[s].count >= 2;
    // The bottom of the food chain first (prey, also when hawks catch predators), then anything caught.
    (0..registry.len())
        .find(|&s| caught(s) && registry.prey_of(s).next().is_none())
        .or_else(|| (0..registry.len()).find(|&s| caught(s)))
        .or_else(|| (0..registry.len()).find(|&s| registry.defs[s].count >= 2))
        .unwrap_or(0)
}

/// A simulation with the learning plugin, frozen actors loaded (`Frozen(path)` species, and with `eval_run`
/// every `Learned` species from that run).
pub fn learning_simulation(scene: Scene, mode: Mode, eval_run: Option<&Path>) -> Result<Simulation, String> {
    learning_simulation_with(scene, mode, eval_run, |_| {})
}

/// [`learning_simulation`] with more plugins (a species of your own) added by `extra`.
pub fn learning_simulation_with(
    scene: Scene,
    mode: Mode,
    eval_run: Option<&Path>,
    extra: impl FnOnce(&mut App),
) -> Result<Simulation, String> {
    let mut learners = Learners::new(&scene, mode);
    learners.load_actors(&scene, eval_run)?;
    Simulation::try_with_plugins(scene, |app| {
        app.insert_resource(learners);
        app.add_plugins(LearningPlugin { mode });
        extra(app);
    })
}

fn metrics_header(registry: &SpeciesRegistry, learners: &Learners) -> String {
    let mut cols = vec!["episode".to_string(), "steps".into()];
    for d in &registry.defs {
        cols.extend(Swarming::NAMES.iter().chain(&["edge_rank"]).map(|q| format!("{q}_{}", d.name)));
    }
    cols.push("catches".into());
    cols.extend(split_catchers(registry).iter().map(|&s| format!("catches_by_{}", registry.defs[s].name)));
    for d in &registry.defs {
        cols.push(format!("return_{}", d.name));
    }
    for (s, l) in learners.species.iter().enumerate() {
        if l.as_ref().is_some_and(|l| !l.frozen) {
            let n = &registry.defs[s].name;
            cols.extend([
                format!("critic_loss_{n}"),
                format!("actor_loss_{n}"),
                format!("noise_std_{n}"),
                format!("epsilon_{n}"),
            ]);
        }
    }
    cols.push("wall_seconds".into());
    cols.join(",")
}

/// The species whose catches metrics.csv also gives apart (`catches_by_<name>`): every species that
/// catches, when more than one does (a third species); none in the two-species scenes.
fn split_catchers(registry: &SpeciesRegistry) -> Vec<usize> {
    let catchers: Vec<usize> = (0..registry.len()).filter(|&s| registry.prey_of(s).next().is_some()).collect();
    if catchers.len() > 1 { catchers } else { vec![] }
}

fn metrics_row(e: &EpisodeSummary, registry: &SpeciesRegistry, learners: &mut Learners, wall_seconds: f64) -> String {
    let blank = |x: Option<f64>| x.map_or(String::new(), |v| v.to_string());
    let mut cols = vec![e.episode.to_string(), e.steps.to_string()];
    for (s, edge_rank) in e.swarming.iter().zip(&e.edge_rank) {
        cols.extend(s.map_or([None; 7], |s| s.values().map(Some)).map(blank));
        cols.push(blank(*edge_rank));
    }
    cols.push(e.catches.to_string());
    cols.extend(split_catchers(registry).iter().map(|&s| e.catches_by.get(s).copied().unwrap_or(0).to_string()));
    cols.extend(e.mean_return.iter().map(|r| r.to_string()));
    let losses = learners.take_losses();
    for (l, loss) in learners.species.iter().zip(losses) {
        if let Some(l) = l.as_ref().filter(|l| !l.frozen) {
            cols.push(blank(loss.map(|x| x.critic as f64)));
            cols.push(blank(loss.map(|x| x.actor as f64)));
            cols.push(l.noise_std.to_string());
            cols.push(l.epsilon.to_string());
        }
    }
    cols.push(format!("{wall_seconds:.3}"));
    cols.join(",")
}

/// CSV `text` rewritten under `header`: each row's cells moved to the columns of the same name, columns
/// the old header lacks left blank, columns the new one lacks dropped. Identity when the headers agree.
fn with_header(text: &str, header: &str) -> String {
    let mut lines = text.lines();
    let old: Vec<&str> = lines.next().unwrap_or("").split(',').collect();
    if old.join(",") == header {
        return text.to_string();
    }
    let map: Vec<Option<usize>> = header.split(',').map(|h| old.iter().position(|o| *o == h)).collect();
    let mut out = format!("{header}\n");
    for line in lines.filter(|l| !l.is_empty()) {
        let cells: Vec<&str> = line.split(',').collect();
        let row: Vec<&str> = map.iter().map(|i| i.and_then(|i| cells.get(i).copied()).unwrap_or("")).collect();
        out.push_str(&row.join(","));
        out.push('\n');
    }
    out
}

fn io_err(path: &Path) -> impl Fn(std::io::Error) -> String + '_ {
    move |e| format!("{}: {e}", path.display())
}

/// The wall_seconds of the last row of a metrics text (0 without rows).
fn last_wall_seconds(metrics: &str) -> f64 {
    let mut lines = metrics.lines();
    let header: Vec<&str> = lines.next().unwrap_or("").split(',').collect();
    let Some(col) = header.iter().position(|h| *h == "wall_seconds") else { return 0.0 };
    lines.filter(|l| !l.is_empty()).last().and_then(|l| l.split(',').nth(col)?.parse().ok()).unwrap_or(0.0)
}

/// Refuses a resume that could not continue the run as it was: its scene.ron edited since training
/// began, a checkpoint whose metrics disagree with its episode count, or nothing left to train.
fn check_resumable(run: &Path, scene: &Scene, state: &TrainingState, total: usize, asked: bool) -> Result<(), String> {
    let (now, then) = (scene.to_ron(), state.scene.to_ron());
    if now != then {
        let line = now.lines().zip(then.lines()).find(|(a, b)| a != b).map_or_else(
            || "its length".to_string(),
            |(a, b)| format!("`{}` (trained with `{}`)", a.trim(), b.trim()),
        );
        return Err(format!(
            "{}: differs from the scene the run was trained on (checkpoint/state.ron), first at {line}; a run continues only under its own scene: restore the file or train a new run",
            RunDir::new(run).scene().display()
        ));
    }
    let rows: Vec<usize> = state.metrics_csv.lines().skip(1).filter(|l| !l.is_empty()).map(|l| l.split(',').next().and_then(|e| e.parse().ok()).unwrap_or(usize::MAX)).collect();
    if rows != (0..state.episodes_done).collect::<Vec<_>>() {
        return Err(format!(
            "{}: damaged checkpoint: episodes_done is {} but its metrics hold episodes {}; restore the checkpoint or train the run again",
            RunDir::new(run).checkpoint().join("state.ron").display(),
            state.episodes_done,
            match (rows.first(), rows.last()) {
                (Some(a), Some(b)) => format!("{a}..={b} ({} rows)", rows.len()),
                _ => "none".to_string(),
            }
        ));
    }
    if total <= state.episodes_done {
        let why = if asked { format!("--episodes {total} asks for no more") } else { "its scene's episodes are all done".to_string() };
        return Err(format!(
            "{}: already trained {} episodes and {why}; extend it with --resume {} --episodes N (N > {})",
            run.display(),
            state.episodes_done,
            run.display(),
            state.episodes_done
        ));
    }
    Ok(())
}

/// Trains a scene (or resumes a run) and returns the episode summaries of this invocation. Everything is
/// validated and loaded before the run folder is created or touched.
pub fn train(scene: Scene, opts: &TrainOptions) -> Result<Vec<EpisodeSummary>, String> {
    let run = &opts.run;
    let dir = RunDir::new(run);
    if opts.resume {
        if !dir.is_run() {
            return Err(format!("{}: holds no coevo run to resume", run.display()));
        }
        dir.check_plugins()?;
    } else {
        dir.check_new(opts.overwrite)?;
    }
    // One process per run: a resume takes it before reading what another process may be writing; a new
    // run once everything is validated and loaded, so a refused scene leaves no folder behind.
    let mut lock = if opts.resume { Some(dir.lock()?) } else { None };
    let scene = if opts.resume { Scene::load(&dir.scene()).map_err(|e| e.to_string())? } else { scene };
    scene.validate().map_err(|(f, m)| format!("{}: {f}: {m}", run.display()))?;
    let total = opts.episodes.unwrap_or(scene.episodes);
    if total == 0 {
        return Err("--episodes: must be ≥ 1".into());
    }
    let mut sim = learning_simulation(scene.clone(), Mode::Train, None)?;
    if lock.is_none() {
        lock = Some(dir.lock()?);
    }
    let _lock = lock;
    let registry = sim.world().resource::<SpeciesRegistry>().clone();
    let names: Vec<String> = registry.defs.iter().map(|d| d.name.clone()).collect();
    let metrics_path = dir.metrics();
    let mut metrics_text: String;
    // Seconds trained before this invocation: wall_seconds counts the run's whole training time.
    let mut wall_before = 0.0;
    if opts.resume {
        let world = sim.world_mut();
        let state = {
            let mut learners = world.resource_mut::<Learners>();
            checkpoint::load(run, &mut learners.species, &names)?
        };
        check_resumable(run, &scene, &state, total, opts.episodes.is_some())?;
        world.resource_mut::<SimRng>().0 = state.spawn_rng.clone().unwrap_or_else(|| state.sim_rng.clone());
        world.resource_mut::<Episode>().index = state.episodes_done;
        crate::sim::episode::spawn_population(world);
        if state.spawn_rng.is_none() || state.species.iter().flatten().any(|s| s.transitions.is_none()) {
            eprintln!(
                "coevo: {}: the checkpoint lacks replay buffers or spawn state (an older coevo, or segments removed): the resumed run refills its buffers and differs from an uninterrupted one",
                run.display()
            );
        }
        // A run begun by an older coevo keeps its rows, under today's columns (new ones blank).
        metrics_text = with_header(&state.metrics_csv, &metrics_header(&registry, world.resource::<Learners>()));
        wall_before = last_wall_seconds(&metrics_text);
    } else {
        dir.check_new(opts.overwrite)?;
        dir.clear()?;
        crate::io::write_file(&dir.scene(), Existing::Replace, scene.to_ron().as_bytes())?;
        dir.write_provenance(&scene)?;
        let header = metrics_header(&registry, sim.world().resource::<Learners>());
        metrics_text = format!("{header}\n");
    }
    crate::io::write_file(&metrics_path, Existing::Replace, metrics_text.as_bytes())?;
    let mut csv = std::fs::OpenOptions::new().append(true).open(&metrics_path).map_err(io_err(&metrics_path))?;

    let start_episode = sim.episode().index;
    let every = scene.learning.checkpoint_every.max(1);
    let prey = headline_species(&registry);
    let bar = if opts.progress { ProgressBar::new(total as u64) } else { ProgressBar::hidden() };
    bar.set_style(
        ProgressStyle::with_template("{bar:30} {pos}/{len} episodes  ETA {eta}  {msg}").expect("valid template"),
    );
    bar.set_position(start_episode as u64);
    let started = Instant::now();
    let (mut steps, mut summaries) = (0usize, Vec::new());
    let save = |sim: &Simulation,
                learners_override: Option<&Vec<Option<crate::learning::SpeciesLearner>>>,
                metrics_text: &str| {
        let world = sim.world();
        let learners = world.resource::<Learners>();
        let species = learners_override.unwrap_or(&learners.species);
        let state = TrainingState {
            scene: scene.clone(),
            episodes_done: world.resource::<Episode>().index,
            sim_rng: world.resource::<SimRng>().0.clone(),
            spawn_rng: Some(world.resource::<SpawnedFrom>().0.clone()),
            species: species
                .iter()
                .zip(&names)
                .map(|(l, name)| {
                    l.as_ref().map(|l| SpeciesState {
                        name: name.clone(),
                        noise_std: l.noise_std,
                        epsilon: l.epsilon,
                        actor_adam_step: l.ddpg.actor_opt.step,
                        critic_adam_step: l.ddpg.critic_opt.step,
                        rng: Some(l.rng.clone()),
                        transitions: (!l.frozen).then_some(l.buffer.pushed),
                    })
                })
                .collect(),
            metrics_csv: metrics_text.to_string(),
        };
        checkpoint::save(run, species, &names, &state)
            .map_err(|e| format!("{}: cannot save checkpoint: {e}", run.display()))
    };
    while sim.episode().index < total {
        sim.step();
        sim.check()?;
        steps += 1;
        if let Some(failure) = sim.world().resource::<Learners>().failure.clone() {
            let last_good = sim.world().resource::<Learners>().last_good.clone();
            save(&sim, last_good.as_ref(), &metrics_text)?;
            return Err(format!(
                "training stopped: {failure}; the last good networks are saved in {}",
                checkpoint::checkpoint_dir(run).display()
            ));
        }
        let Some(summary) = sim.world_mut().resource_mut::<EpisodeLog>().episodes.pop() else {
            continue;
        };
        let wall = wall_before + started.elapsed().as_secs_f64();
        let row = metrics_row(&summary, &registry, &mut sim.world_mut().resource_mut::<Learners>(), wall);
        writeln!(csv, "{row}").map_err(io_err(&metrics_path))?;
        metrics_text.push_str(&row);
        metrics_text.push('\n');
        let done = summary.episode + 1;
        if done % every == 0 || done == total {
            save(&sim, None, &metrics_text)?;
        }
        if let Some(sw) = summary.swarming.get(prey).copied().flatten() {
            let rate = steps as f64 / started.elapsed().as_secs_f64();
            bar.set_message(format!("DoS {:.3} DoA {:.3}  {rate:.0} steps/s", sw.dos, sw.doa));
        }
        bar.set_position(done as u64);
        summaries.push(summary);
    }
    bar.finish();
    Ok(summaries)
}

/// The nearest-neighbour distance histogram: bins of this many body diameters, NN_BINS of them and one
/// for everything beyond.
const NN_BIN_DIAMETERS: f64 = 0.25;
const NN_BINS: usize = 80;

pub struct EvalOptions {
    pub run: PathBuf,
    /// What the actors see of their neighbours (a control for alignment claims).
    pub control: crate::learning::ObservationControl,
    /// File name of the per-step CSV inside the run folder (default `eval.csv`).
    pub out: Option<String>,
    pub counts: Vec<(String, usize)>,
    pub episodes: usize,
    pub steps: Option<usize>,
    pub seed: Option<u64>,
    /// Radius (m) of "prey in view" for the confusion curve (default: the scene's).
    pub confusion_radius: Option<f64>,
}

/// Deploys a run's policies without noise and streams per-step DoS/DoA to `RUN/eval.csv` (replaced
/// whole, when complete); returns the summary line.
pub fn evaluate(opts: &EvalOptions) -> Result<String, String> {
    let dir = RunDir::new(&opts.run);
    let path = dir.eval_output(opts.out.as_deref())?;
    if !dir.is_run() {
        return Err(format!("{}: holds no coevo run to evaluate", opts.run.display()));
    }
    dir.check_plugins()?;
    let scene_path = dir.scene();
    let mut scene = Scene::load(&scene_path).map_err(|e| e.to_string())?;
    for (name, n) in &opts.counts {
        scene.set_count(name, *n).map_err(|e| format!("{}: {e}", scene_path.display()))?;
    }
    if let Some(steps) = opts.steps {
        scene.episode_steps = steps;
    }
    if let Some(seed) = opts.seed {
        scene.seed = seed;
    }
    if let Some(r) = opts.confusion_radius {
        scene.confusion_radius = Some(r);
    }
    if opts.episodes == 0 {
        return Err("--episodes: must be ≥ 1".into());
    }
    scene.validate().map_err(|(f, m)| format!("{}: {f}: {m}", opts.run.display()))?;
    let mut sim = learning_simulation(scene.clone(), Mode::Evaluate, Some(&opts.run))?;
    // Nobody else writes the run while it is evaluated (a training would swap its checkpoint).
    let _lock = dir.lock()?;
    sim.world_mut().insert_resource(opts.control);
    // Each episode's last step is read before the next population is spawned.
    sim.world_mut().resource_mut::<Episode>().auto_reset = false;
    let registry = sim.world().resource::<SpeciesRegistry>().clone();
    let prey = headline_species(&registry);
    let name = &registry.defs[prey].name;
    let write_err = |e: std::io::Error| format!("{}: {e}", path.display());
    let mut file = AtomicFile::create(&path, Existing::Replace).map_err(write_err)?;
    let columns: Vec<String> = Swarming::NAMES.iter().chain(&["edge_rank"]).map(|q| format!("{q}_{name}")).collect();
    let catchers = split_catchers(&registry);
    let by: String = catchers.iter().map(|&s| format!(",catches_by_{}", registry.defs[s].name)).collect();
    writeln!(file.writer(), "episode,step,{},catches{by}", columns.join(",")).map_err(write_err)?;
    let blank = |x: Option<f64>| x.map_or(String::new(), |v| v.to_string());
    let (mut sums, mut n) = ([0.0; 7], 0usize);
    let mut ranks = Vec::new();
    let diameter = 2.0 * registry.defs[prey].radius;
    let mut nn_histogram = vec![0u64; NN_BINS + 1];
    // C(r) of heading fluctuations in bins of one body diameter, out to half the arena's edge.
    let arena = *sim.world().resource::<crate::sim::space::Arena>();
    let mut correlation = vec![(0.0, 0u64); (arena.edge / 2.0 / diameter).ceil().max(1.0) as usize];
    let mut variance = (0.0, 0u64);
    for episode in 0..opts.episodes {
        if episode > 0 {
            crate::sim::episode::next_episode(sim.world_mut());
        }
        for step in 1..=scene.episode_steps {
            sim.step();
            sim.check()?;
            let m = sim.world().resource::<SwarmMetrics>();
            let sw = m.now.get(prey).copied().flatten();
            let step_ranks = &m.edge_ranks_now[prey];
            let edge_rank = (!step_ranks.is_empty()).then(|| step_ranks.iter().sum::<f64>() / step_ranks.len() as f64);
            let cells: Vec<String> = sw.map_or([None; 7], |s| s.values().map(Some)).map(blank).into_iter().chain([blank(edge_rank)]).collect();
            let by: String = catchers.iter().map(|&s| format!(",{}", m.catches_now_by[s])).collect();
            writeln!(file.writer(), "{episode},{step},{},{}{by}", cells.join(","), m.catches_now).map_err(write_err)?;
            if let Some(sw) = sw {
                sums.iter_mut().zip(sw.values()).for_each(|(a, v)| *a += v);
                n += 1;
            }
            ranks.extend_from_slice(step_ranks);
            for d in &m.nn_distances_now[prey] {
                nn_histogram[((d / diameter / NN_BIN_DIAMETERS) as usize).min(NN_BINS)] += 1;
            }
            let pop = sim.world().resource::<crate::sim::perception::Population>();
            let range = pop.ranges[prey].clone();
            crate::sim::collective::add_heading_correlation(&arena, &pop.position[range.clone()], &pop.heading[range], diameter, &mut correlation, &mut variance);
        }
    }
    // The distributions beside the per-step file: <stem>-nn.csv, -correlation.csv and -confusion.csv.
    let total = nn_histogram.iter().sum::<u64>().max(1) as f64;
    let mut nn = String::from("from_diameters,to_diameters,from_m,to_m,fraction\n");
    for (b, count) in nn_histogram.iter().enumerate() {
        let (lo, hi) = (b as f64 * NN_BIN_DIAMETERS, if b == NN_BINS { f64::INFINITY } else { (b + 1) as f64 * NN_BIN_DIAMETERS });
        nn.push_str(&format!("{lo},{hi},{},{},{}\n", lo * diameter, hi * diameter, *count as f64 / total));
    }
    let (c_of_r, correlation_length) = crate::sim::collective::heading_correlation(&correlation, variance, diameter);
    let mut correlation_csv = String::from("from_m,to_m,pairs,c\n");
    for (b, (c, &(_, pairs))) in c_of_r.iter().zip(&correlation).enumerate() {
        correlation_csv.push_str(&format!("{},{},{pairs},{}\n", b as f64 * diameter, (b + 1) as f64 * diameter, blank(*c)));
    }
    let curve = sim.world().resource::<crate::sim::metrics::Confusion>();
    let mut confusion = String::from("species,prey_in_view,samples,mean_abs_turn,mean_speed_fraction,catches_per_step\n");
    for (s, bins) in curve.0.iter().enumerate().filter(|(s, _)| registry.prey_of(*s).next().is_some()) {
        for (b, bin) in bins.iter().enumerate() {
            let (turn, speed, catches) = bin.means().map_or([None; 3], |(t, v, c)| [Some(t), Some(v), Some(c)]).into();
            confusion.push_str(&format!(
                "{},{},{},{},{},{}\n",
                registry.defs[s].name,
                crate::sim::collective::confusion_bin_label(b),
                bin.samples,
                blank(turn),
                blank(speed),
                blank(catches)
            ));
        }
    }
    file.commit().map_err(write_err)?;
    // The confusion curve last: the experiment runner takes its presence for a complete evaluation.
    for (what, text) in crate::run::EVAL_BESIDE.iter().zip([nn, correlation_csv, confusion]) {
        crate::io::write_file(&crate::io::beside(&path, what), Existing::Replace, text.as_bytes())?;
    }
    let counts: Vec<String> = registry.defs.iter().map(|d| format!("{} {}", d.count, d.name)).collect();
    let means = if n > 0 {
        let [dos, doa, polarization, milling, clusters, largest, c_nn] = sums.map(|v| v / n as f64);
        let edge = if ranks.is_empty() { "no ranked catch".to_string() } else { format!("edge rank of caught {name} {:.3} ({} catches)", ranks.iter().sum::<f64>() / ranks.len() as f64, ranks.len()) };
        format!(
            "mean DoS {dos:.4}, DoA {doa:.4}, polarization {polarization:.3}, milling {milling:.3}, \
             {clusters:.1} clusters (largest {:.0} %), C_nn {c_nn:.3}, correlation length {}, {edge} ({name})",
            100.0 * largest,
            correlation_length.map_or("beyond half the arena".to_string(), |xi| format!("{xi:.3} m"))
        )
    } else {
        format!("no DoS/DoA: fewer than two {name}")
    };
    Ok(format!(
        "eval {}{}: {} episodes × {} steps, {}: {means}; per step in {}",
        opts.run.display(),
        match opts.control {
            crate::learning::ObservationControl::Seeing => String::new(),
            c => format!(" ({c:?} control)"),
        },
        opts.episodes,
        scene.episode_steps,
        counts.join(" + "),
        path.display()
    ))
}
