//! `coevo --train` and `--resume`: headless training (Algorithm 1), driving the fixed-step schedule
//! directly, into a run folder ([`crate::store::RunDir`]): `metrics.csv` one row per episode
//! ([`crate::store::schema`]), a checkpoint every `checkpoint_every` episodes (`store::checkpoint`).

use crate::io::Existing;
use crate::learning::{Learners, Mode};
use crate::scene::Scene;
use crate::sim::clock::Episode;
use crate::sim::episode::{SimRng, SpawnedFrom};
use crate::sim::metrics::EpisodeLog;
use crate::sim::species::SpeciesRegistry;
use crate::sim::Simulation;
use crate::store::checkpoint::{self, SpeciesState, TrainingState};
use crate::store::folder::{io_err, RunDir};
use crate::store::manifest::{Digest, Hashing};
use crate::store::schema;
use indicatif::{ProgressBar, ProgressStyle};
use std::io::Write;
use std::path::Path;
use std::time::Instant;

pub use super::train_args::{ResumeArgs, Start, StartArgs, TrainArgs, TrainOptions};

/// `--train` or `--resume`: trains, says where and what came out; `spread`, a line on how far seeds of the
/// scene differ, goes beside "one run is one sample".
pub(crate) fn main(start: Start, opts: &TrainOptions, spread: Option<&str>) -> crate::error::Result<()> {
    let trained = run_training(start, opts)?;
    crate::errln!("coevo: trained {trained} episodes into {}", opts.run.display())?;
    if opts.progress {
        // The explanation is the run's result for a reader: on stdout, so `coevo --train > log` keeps it.
        crate::io::out_text(format_args!("{}", super::explain::explain(&opts.run, spread)?))?;
    }
    Ok(())
}

/// Refuses a resume that could not continue the run as it was: its scene.ron edited since training
/// began, metrics (`metrics`, as they stood at the checkpoint) that disagree with its episode count, or
/// nothing left to train.
fn check_resumable(
    run: &Path,
    scene: &Scene,
    state: &TrainingState,
    metrics: &str,
    total: usize,
    asked: bool,
) -> crate::error::Result<()> {
    let (now, then) = (scene.to_ron(), state.scene.to_ron());
    if now != then {
        let line = now
            .lines()
            .zip(then.lines())
            .find(|(a, b)| a != b)
            .map_or_else(|| "its length".to_string(), |(a, b)| format!("`{}` (trained with `{}`)", a.trim(), b.trim()));
        return Err(format!(
            "{}: differs from the scene the run was trained on (checkpoint/state.ron), first at {line}; a run continues only under its own scene: restore the file or train a new run",
            RunDir::new(run).scene().display()
        ).into());
    }
    let rows: Vec<usize> = metrics
        .lines()
        .skip(1)
        .filter(|l| !l.is_empty())
        .map(|l| l.split(',').next().and_then(|e| e.parse().ok()).unwrap_or(usize::MAX))
        .collect();
    if rows != (0..state.episodes_done).collect::<Vec<_>>() {
        return Err(format!(
            "{}: damaged checkpoint: episodes_done is {} but its metrics hold episodes {}; restore the checkpoint or train the run again",
            RunDir::new(run).state().display(),
            state.episodes_done,
            match (rows.first(), rows.last()) {
                (Some(a), Some(b)) => format!("{a}..={b} ({} rows)", rows.len()),
                _ => "none".to_string(),
            }
        ).into());
    }
    if total <= state.episodes_done {
        let why = if asked {
            format!("--episodes {total} asks for no more")
        } else {
            "its scene's episodes are all done".to_string()
        };
        return Err(format!(
            "{}: already trained {} episodes and {why}; extend it with --resume {} --episodes N (N > {})",
            run.display(),
            state.episodes_done,
            run.display(),
            state.episodes_done
        )
        .into());
    }
    Ok(())
}

/// Trains a scene (or resumes a run) and returns how many episodes this invocation trained (not their
/// summaries: a long run would hold them all; they are in `metrics.csv`). Everything is validated and
/// loaded before the run folder is created or touched.
pub fn train(scene: Scene, opts: &TrainOptions) -> crate::error::Result<usize> {
    run_training(Start::New(Box::new(scene)), opts)
}

/// Continues the run `opts.run` from its last checkpoint, with the scene it was trained with; returns how
/// many episodes this invocation trained.
pub fn resume(opts: &TrainOptions) -> crate::error::Result<usize> {
    run_training(Start::Resume, opts)
}

/// The scene a training starts from: a new run's (its folder checked free), or a resumed run's own (its
/// folder checked to be a run of this build's plugins and kernels, locked and writable). One process per
/// run: a resume takes the lock before reading what another process may be writing; a new run once
/// everything is validated and loaded, so a refused scene leaves no folder behind.
fn open(
    start: Start,
    opts: &TrainOptions,
    dir: &RunDir,
) -> crate::error::Result<(Scene, Option<crate::store::folder::RunLock>)> {
    match start {
        Start::New(scene) => {
            dir.check_new(opts.overwrite)?;
            Ok((*scene, None))
        }
        Start::Resume => {
            if !dir.is_run() {
                return Err(format!("{}: holds no coevo run to resume", opts.run.display()).into());
            }
            dir.check_plugins()?;
            dir.check_kernels()?;
            let lock = dir.lock()?;
            dir.check_writable()?;
            Ok((Scene::load(&dir.scene())?, Some(lock)))
        }
    }
}

/// A resumed run put back as its checkpoint left it (learners, league, spawn state, episode), checked
/// against its scene and rows; returns `metrics.csv`'s rows up to the checkpoint, under today's header.
fn restore(
    sim: &mut Simulation,
    dir: &RunDir,
    scene: &Scene,
    opts: &TrainOptions,
    total: usize,
    registry: &SpeciesRegistry,
    names: &[String],
) -> crate::error::Result<String> {
    let run = &opts.run;
    let world = sim.world_mut();
    let (state, manifest) = {
        let mut learners = world.resource_mut::<Learners>();
        let l = &mut *learners;
        let (state, manifest) = checkpoint::load(run, &mut l.species, names)?;
        if let Some(league) = l.league.as_mut() {
            let load = |name: &str, episode, like: &_| crate::store::snapshots::load_snapshot(run, name, episode, like);
            league.restore(run, &l.species, state.episodes_done, state.league.clone(), load)?;
        }
        (state, manifest)
    };
    let rows = match &manifest {
        Some(m) => dir.metrics_up_to(&m.metrics)?,
        None => state.metrics_csv.clone(),
    };
    check_resumable(run, scene, &state, &rows, total, opts.episodes.is_some())?;
    dir.note_binary()?;
    world.resource_mut::<SimRng>().0 = state.spawn_rng.clone().unwrap_or_else(|| state.sim_rng.clone());
    world.resource_mut::<Episode>().index = state.episodes_done;
    crate::sim::episode::spawn_population(world);
    if state.spawn_rng.is_none() || state.species.iter().flatten().any(|s| s.transitions.is_none()) {
        crate::errln!(
            "coevo: warning: {}: the checkpoint lacks replay buffers or spawn state (an older coevo, or segments removed, as an experiment does once a run is trained): the resumed run refills its buffers and differs from an uninterrupted one",
            run.display()
        )?;
    }
    // A run begun by an older coevo keeps its rows, under today's columns (new ones blank).
    Ok(schema::with_header(
        &rows,
        &schema::metrics_header(registry, world.resource::<Learners>(), scene.authors_metrics),
    ))
}

/// A new run's folder made (after checking it may be): its scene, provenance and `metrics.csv`'s header,
/// returned.
fn begin(
    sim: &Simulation,
    dir: &RunDir,
    scene: &Scene,
    opts: &TrainOptions,
    registry: &SpeciesRegistry,
) -> crate::error::Result<String> {
    dir.check_new(opts.overwrite)?;
    dir.clear()?;
    crate::io::write_file(&dir.scene(), Existing::Replace, scene.to_ron().as_bytes())?;
    dir.write_provenance(scene)?;
    let header = schema::metrics_header(registry, sim.world().resource::<Learners>(), scene.authors_metrics);
    Ok(format!("{header}\n"))
}

/// [`train`] or [`resume`], as `start` says.
fn run_training(start: Start, opts: &TrainOptions) -> crate::error::Result<usize> {
    let run = &opts.run;
    let dir = RunDir::new(run);
    let resuming = matches!(start, Start::Resume);
    let (scene, mut lock) = open(start, opts, &dir)?;
    scene.validate().map_err(|e| e.in_file(run))?;
    let total = opts.episodes.unwrap_or(scene.episodes);
    if total == 0 {
        return Err("--episodes: must be ≥ 1".into());
    }
    let mut sim = crate::run::simulation(scene.clone(), Mode::Train, None)?;
    if lock.is_none() {
        lock = Some(dir.lock()?);
    }
    let lock = lock.expect("taken above");
    let registry = sim.world().resource::<SpeciesRegistry>().clone();
    let names: Vec<String> = registry.defs.iter().map(|d| d.name.clone()).collect();
    let metrics_path = dir.metrics();
    // metrics.csv up to the last row written: what the next checkpoint's manifest hashes.
    let metrics_text = match resuming {
        true => restore(&mut sim, &dir, &scene, opts, total, &registry, &names)?,
        false => begin(&sim, &dir, &scene, opts, &registry)?,
    };
    // Seconds trained before this invocation: wall_seconds counts the run's whole training time.
    let wall_before = if resuming { schema::last_wall_seconds(&metrics_text) } else { 0.0 };
    crate::io::write_file(&metrics_path, Existing::Replace, metrics_text.as_bytes())?;
    let mut csv = std::fs::OpenOptions::new().append(true).open(&metrics_path).map_err(io_err(&metrics_path))?;
    // The rows are hashed as they are written, so memory stays constant over any number of episodes.
    let mut metrics = Hashing::new(std::io::sink());
    metrics.write_all(metrics_text.as_bytes()).expect("a sink takes everything");
    drop(metrics_text);

    let start_episode = sim.episode().index;
    // Snapshots of every learning species' actor (cross-play, `super::crossplay`): as initialised, every
    // `snapshot_every` episodes, and at the end; written before the checkpoint that follows them, so a run
    // killed in between writes the same bytes again when it replays those episodes.
    let snapshot_every = scene.learning.snapshot_every;
    let snapshot = |sim: &Simulation, episode: usize| -> crate::error::Result<()> {
        lock.held()?;
        let learners = sim.world().resource::<Learners>();
        for (l, name) in learners.species.iter().zip(&names) {
            if let Some(l) = l.as_ref().filter(|l| !l.frozen) {
                crate::store::snapshots::save_snapshot(run, &scene, name, episode, &l.ddpg.actor)
                    .map_err(|e| lock.held().err().unwrap_or(e))?;
            }
        }
        Ok(())
    };
    if snapshot_every > 0 && start_episode == 0 {
        snapshot(&sim, 0)?;
    }
    let every = scene.learning.checkpoint_every.max(1);
    let prey = registry.headline();
    let bar = if opts.progress { ProgressBar::new(total as u64) } else { ProgressBar::hidden() };
    bar.set_style(
        ProgressStyle::with_template("{bar:30} {pos}/{len} episodes  ETA {eta}  {msg}").expect("valid template"),
    );
    bar.set_position(start_episode as u64);
    let started = Instant::now();
    let (mut steps, mut trained) = (0usize, 0usize);
    let save = |sim: &Simulation,
                learners_override: Option<&Vec<Option<crate::learning::SpeciesLearner>>>,
                metrics: &Hashing<std::io::Sink>| {
        lock.held()?;
        // A folder removed during the save fails it: said as the removal it is.
        save_checkpoint(run, sim.world(), &scene, learners_override, metrics.digest())
            .map_err(|e| lock.held().err().unwrap_or(e))
    };
    while sim.episode().index < total {
        sim.step();
        sim.check()?;
        steps += 1;
        if let Some(failure) = sim.world().resource::<Learners>().failure.clone() {
            let last_good = sim.world().resource::<Learners>().last_good.clone();
            save(&sim, last_good.as_ref(), &metrics)?;
            return Err(format!(
                "training stopped: {failure}; the last good networks are saved in {}",
                crate::store::names::checkpoint_dir(run).display()
            )
            .into());
        }
        let Some(summary) = sim.world_mut().resource_mut::<EpisodeLog>().episodes.pop() else {
            continue;
        };
        let wall = wall_before + started.elapsed().as_secs_f64();
        let row = schema::metrics_row(&summary, &registry, &mut sim.world_mut().resource_mut::<Learners>(), wall);
        let row = format!("{row}\n");
        csv.write_all(row.as_bytes()).map_err(io_err(&metrics_path))?;
        metrics.write_all(row.as_bytes()).expect("a sink takes everything");
        let done = summary.episode + 1;
        if snapshot_every > 0 && (done % snapshot_every == 0 || done == total) {
            snapshot(&sim, done)?;
        }
        if done % every == 0 || done == total {
            save(&sim, None, &metrics)?;
        }
        if let Some(sw) = summary.swarming.get(prey).copied().flatten() {
            let rate = steps as f64 / started.elapsed().as_secs_f64();
            bar.set_message(format!("DoS {:.3} DoA {:.3}  {rate:.0} steps/s", sw.dos, sw.doa));
        }
        bar.set_position(done as u64);
        trained += 1;
    }
    bar.finish();
    Ok(trained)
}

/// Saves the world's training state as `run`'s checkpoint (what `--resume` continues from): the learners
/// (or `species`: the last good networks after a failure), the random streams and the episodes done,
/// with `metrics`, the digest of the run's `metrics.csv` as it stands. For `--train` and for runs stepped
/// elsewhere ([`super::live::LiveRun`]).
pub(crate) fn save_checkpoint(
    run: &Path,
    world: &bevy::ecs::world::World,
    scene: &Scene,
    species: Option<&Vec<Option<crate::learning::SpeciesLearner>>>,
    metrics: Digest,
) -> crate::error::Result<()> {
    let learners = world.resource::<Learners>();
    let species = species.unwrap_or(&learners.species);
    let names: Vec<String> = world.resource::<SpeciesRegistry>().defs.iter().map(|d| d.name.clone()).collect();
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
                    offered: (!l.frozen && l.storing.first_rows.is_some()).then_some(l.offered),
                })
            })
            .collect(),
        metrics_csv: String::new(),
        league: learners.league.as_ref().map(|g| g.state.clone()),
    };
    Ok(checkpoint::save(run, species, &names, &state, metrics)
        .map_err(|e| format!("{}: cannot save checkpoint: {e}", run.display()))?)
}
