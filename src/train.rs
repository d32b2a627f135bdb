//! Headless training and evaluation runs, driving the fixed-step schedule directly.
//!
//! A run folder holds `scene.ron` (the resolved scene), `metrics.csv` (one row per episode) and
//! `checkpoint/` (see `learning::checkpoint`). `--eval` adds `eval.csv` (one row per time step).

use crate::episode::{Episode, SimRng};
use crate::learning::checkpoint::{self, SpeciesState, TrainingState};
use crate::learning::{LearningPlugin, Learners, Mode};
use crate::metrics::{EpisodeLog, EpisodeSummary, SwarmMetrics};
use crate::scene::Scene;
use crate::species::SpeciesRegistry;
use crate::Simulation;
use indicatif::{ProgressBar, ProgressStyle};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

pub struct TrainOptions {
    pub run: PathBuf,
    pub resume: bool,
    /// Total episodes of the run (the scene's `episodes` when None).
    pub episodes: Option<usize>,
    pub progress: bool,
}

/// The species whose DoS/DoA headline a run: the first that something catches (the prey), else the first
/// with at least two agents.
pub fn headline_species(registry: &SpeciesRegistry) -> usize {
    (0..registry.len())
        .find(|&s| registry.predators_of(s).next().is_some() && registry.defs[s].count >= 2)
        .or_else(|| (0..registry.len()).find(|&s| registry.defs[s].count >= 2))
        .unwrap_or(0)
}

/// A simulation with the learning plugin, frozen actors loaded (`Frozen(path)` species, and with `eval_run`
/// every `Learned` species from that run).
pub fn learning_simulation(scene: Scene, mode: Mode, eval_run: Option<&Path>) -> Result<Simulation, String> {
    let mut learners = Learners::new(&scene, mode);
    learners.load_actors(&scene, eval_run)?;
    Ok(Simulation::with_plugins(scene, |app| {
        app.insert_resource(learners);
        app.add_plugins(LearningPlugin { mode });
    }))
}

fn metrics_header(registry: &SpeciesRegistry, learners: &Learners) -> String {
    let mut cols = vec!["episode".to_string(), "steps".into()];
    for d in &registry.defs {
        cols.push(format!("dos_{}", d.name));
        cols.push(format!("doa_{}", d.name));
    }
    cols.push("catches".into());
    for d in &registry.defs {
        cols.push(format!("return_{}", d.name));
    }
    for (s, l) in learners.species.iter().enumerate() {
        if l.as_ref().is_some_and(|l| !l.frozen) {
            let n = &registry.defs[s].name;
            cols.extend([format!("critic_loss_{n}"), format!("actor_loss_{n}"), format!("noise_std_{n}"), format!("epsilon_{n}")]);
        }
    }
    cols.push("wall_seconds".into());
    cols.join(",")
}

fn metrics_row(e: &EpisodeSummary, learners: &mut Learners, wall_seconds: f64) -> String {
    let blank = |x: Option<f64>| x.map_or(String::new(), |v| v.to_string());
    let mut cols = vec![e.episode.to_string(), e.steps.to_string()];
    for s in &e.swarming {
        cols.push(blank(s.map(|s| s.dos)));
        cols.push(blank(s.map(|s| s.doa)));
    }
    cols.push(e.catches.to_string());
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

fn io_err(path: &Path) -> impl Fn(std::io::Error) -> String + '_ {
    move |e| format!("{}: {e}", path.display())
}

/// Trains a scene (or resumes a run) and returns the episode summaries of this invocation.
pub fn train(scene: Scene, opts: &TrainOptions) -> Result<Vec<EpisodeSummary>, String> {
    let run = &opts.run;
    let scene = if opts.resume {
        Scene::load(&run.join("scene.ron")).map_err(|e| e.to_string())?
    } else {
        scene
    };
    let total = opts.episodes.unwrap_or(scene.episodes);
    std::fs::create_dir_all(run).map_err(io_err(run))?;
    let scene_path = run.join("scene.ron");
    if !opts.resume {
        crate::io::write_atomically(&scene_path, |w| w.write_all(scene.to_ron().as_bytes())).map_err(io_err(&scene_path))?;
    }
    let mut sim = learning_simulation(scene.clone(), Mode::Train, None)?;
    let registry = sim.world().resource::<SpeciesRegistry>().clone();
    let names: Vec<String> = registry.defs.iter().map(|d| d.name.clone()).collect();
    let metrics_path = run.join("metrics.csv");
    let mut metrics_text: String;
    if opts.resume {
        let world = sim.world_mut();
        let state = {
            let mut learners = world.resource_mut::<Learners>();
            let state = checkpoint::load(run, &mut learners.species, &names)?;
            learners.rng = state.learn_rng.clone();
            state
        };
        world.resource_mut::<SimRng>().0 = state.sim_rng.clone();
        world.resource_mut::<Episode>().index = state.episodes_done;
        crate::episode::spawn_population(world);
        metrics_text = state.metrics_csv;
    } else {
        let header = metrics_header(&registry, sim.world().resource::<Learners>());
        metrics_text = format!("{header}\n");
    }
    crate::io::write_atomically(&metrics_path, |w| w.write_all(metrics_text.as_bytes())).map_err(io_err(&metrics_path))?;
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
    let save = |sim: &Simulation, learners_override: Option<&Vec<Option<crate::learning::SpeciesLearner>>>, metrics_text: &str| {
        let world = sim.world();
        let learners = world.resource::<Learners>();
        let species = learners_override.unwrap_or(&learners.species);
        let state = TrainingState {
            scene: scene.clone(),
            episodes_done: world.resource::<Episode>().index,
            sim_rng: world.resource::<SimRng>().0.clone(),
            learn_rng: learners.rng.clone(),
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
                    })
                })
                .collect(),
            metrics_csv: metrics_text.to_string(),
        };
        checkpoint::save(run, species, &names, &state).map_err(|e| format!("{}: cannot save checkpoint: {e}", run.display()))
    };
    while sim.episode().index < total {
        sim.step();
        steps += 1;
        if let Some(failure) = sim.world().resource::<Learners>().failure.clone() {
            let last_good = sim.world().resource::<Learners>().last_good.clone();
            save(&sim, last_good.as_ref(), &metrics_text)?;
            return Err(format!("training stopped: {failure}; the last good networks are saved in {}", checkpoint::checkpoint_dir(run).display()));
        }
        let Some(summary) = sim.world_mut().resource_mut::<EpisodeLog>().episodes.pop() else { continue };
        let wall = started.elapsed().as_secs_f64();
        let row = metrics_row(&summary, &mut sim.world_mut().resource_mut::<Learners>(), wall);
        writeln!(csv, "{row}").map_err(io_err(&metrics_path))?;
        metrics_text.push_str(&row);
        metrics_text.push('\n');
        let done = summary.episode + 1;
        if done % every == 0 || done == total {
            save(&sim, None, &metrics_text)?;
        }
        if let Some(sw) = summary.swarming.get(prey).copied().flatten() {
            bar.set_message(format!("DoS {:.3} DoA {:.3}  {:.0} steps/s", sw.dos, sw.doa, steps as f64 / wall));
        }
        bar.set_position(done as u64);
        summaries.push(summary);
    }
    bar.finish();
    Ok(summaries)
}

pub struct EvalOptions {
    pub run: PathBuf,
    pub counts: Vec<(String, usize)>,
    pub episodes: usize,
    pub steps: Option<usize>,
    pub seed: Option<u64>,
}

/// Deploys a run's policies without noise and writes per-step DoS/DoA to `RUN/eval.csv`; returns the
/// summary line.
pub fn evaluate(opts: &EvalOptions) -> Result<String, String> {
    let mut scene = Scene::load(&opts.run.join("scene.ron")).map_err(|e| e.to_string())?;
    for (name, n) in &opts.counts {
        scene.set_count(name, *n).map_err(|e| format!("{}: {e}", opts.run.join("scene.ron").display()))?;
    }
    if let Some(steps) = opts.steps {
        scene.episode_steps = steps.max(1);
    }
    if let Some(seed) = opts.seed {
        scene.seed = seed;
    }
    scene.validate().map_err(|(f, m)| format!("{}: {f}: {m}", opts.run.display()))?;
    let mut sim = learning_simulation(scene.clone(), Mode::Evaluate, Some(&opts.run))?;
    let registry = sim.world().resource::<SpeciesRegistry>().clone();
    let prey = headline_species(&registry);
    let name = &registry.defs[prey].name;
    let mut text = format!("episode,step,dos_{name},doa_{name},catches\n");
    let (mut sum_dos, mut sum_doa, mut n) = (0.0, 0.0, 0usize);
    for episode in 0..opts.episodes {
        for step in 1..=scene.episode_steps {
            sim.step();
            let m = sim.world().resource::<SwarmMetrics>();
            let sw = m.now.get(prey).copied().flatten();
            let blank = |x: Option<f64>| x.map_or(String::new(), |v| v.to_string());
            text.push_str(&format!("{episode},{step},{},{},{}\n", blank(sw.map(|s| s.dos)), blank(sw.map(|s| s.doa)), m.catches_now));
            if let Some(sw) = sw {
                sum_dos += sw.dos;
                sum_doa += sw.doa;
                n += 1;
            }
        }
    }
    let path = opts.run.join("eval.csv");
    crate::io::write_atomically(&path, |w| w.write_all(text.as_bytes())).map_err(io_err(&path))?;
    let counts: Vec<String> = registry.defs.iter().map(|d| format!("{} {}", d.count, d.name)).collect();
    Ok(format!(
        "eval {}: {} episodes × {} steps, {}: mean DoS {:.4}, mean DoA {:.4} ({name}); per step in {}",
        opts.run.display(),
        opts.episodes,
        scene.episode_steps,
        counts.join(" + "),
        sum_dos / n.max(1) as f64,
        sum_doa / n.max(1) as f64,
        path.display()
    ))
}
