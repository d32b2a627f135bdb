//! coevo as an environment for learners outside it (issue 24: the Rust side of the Python package): the
//! very `FixedUpdate` schedule `--train` steps, with the scene's `Learned` species decided from outside.
//!
//! [`Env`] is one world: `reset` gives every external agent's observation (coevo's observation vector,
//! the scene's frame and layout), `step` takes their normalized actions in [−1, 1]² (thrust, turn, as the
//! actors output them) and returns the next observations, the rewards coevo's learners get, whether the
//! episode was truncated (at `episode_steps`) and the step's DoS, DoA and catches. Species with any other
//! policy (rule-based, `Frozen` runs, plugins) keep acting inside. [`VecEnv`] steps many worlds at once on
//! flat arrays, on all cores, and starts a world's next episode by itself when one ends.
//!
//! Agents are ordered by species (the scene's order) and, within a species, as coevo numbers them; they
//! are named `<species>_<k>`.

use crate::learning::Mode;
use crate::scene::{Policy, Scene};
use crate::sim::clock::Episode;
use crate::sim::metrics::SwarmMetrics;
use crate::sim::perception::{Batches, Population};
use crate::sim::species::{SpeciesRegistry, ACTION_DIM};
use crate::sim::SimSet;
use bevy::prelude::*;

/// The policy name the externally decided species get (`Plugin("external")`).
pub const EXTERNAL: &str = "external";

/// The actions given from outside, per species (empty for species decided inside).
#[derive(Resource, Default, Clone, Debug)]
struct ExternalActions(Vec<Vec<f32>>);

/// Decide: the external species' rows of the action batch are the actions given to [`Env::step`].
fn apply_external(actions: Res<ExternalActions>, mut batches: ResMut<Batches>) {
    for (given, batch) in actions.0.iter().zip(batches.species.iter_mut()) {
        if !given.is_empty() && given.len() == batch.actions.len() {
            batch.actions.copy_from_slice(given);
        }
    }
}

/// What one step returned, for every external agent in order.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct StepResult {
    /// `[agents × d_o]`.
    pub observations: Vec<f32>,
    pub rewards: Vec<f32>,
    /// The episode reached `episode_steps` with this step.
    pub truncated: bool,
    /// DoS and DoA of the headline species at the new state (NaN with fewer than two), catches at it.
    pub dos: f64,
    pub doa: f64,
    pub catches: u32,
}

/// One world driven from outside. It holds the Bevy `World` alone (taken out of its `App` once built,
/// the schedules live in it), so worlds can step on several threads.
pub struct Env {
    world: World,
    scene: Scene,
    /// The externally decided species (registry indices) and their agent counts.
    external: Vec<(usize, usize)>,
    obs_dim: usize,
    headline: usize,
}

impl Env {
    /// A world of `scene` whose `Learned` species are decided from outside. Err when none is, when their
    /// observation sizes differ (one flat array needs one size), or when the scene is refused.
    pub fn new(scene: Scene) -> crate::error::Result<Env> {
        scene.validate()?;
        let learned: Vec<usize> =
            (0..scene.species.len()).filter(|&s| scene.species[s].policy == Policy::Learned).collect();
        if learned.is_empty() {
            return Err("the scene has no Learned species to decide from outside".into());
        }
        // The world runs the scene with its learned species decided from outside; `scene` is kept as given.
        let mut decided = scene.clone();
        for &s in &learned {
            decided.species[s].policy = Policy::Plugin(EXTERNAL.into());
        }
        let mut sim = crate::learning::simulation_with(decided, Mode::Evaluate, None, |app| {
            crate::sim::policy::PolicyPlugins::register(app, EXTERNAL);
            app.init_resource::<ExternalActions>();
            app.add_systems(FixedUpdate, apply_external.in_set(SimSet::Decide));
        })?;
        let world = std::mem::take(sim.world_mut());
        let registry = world.resource::<SpeciesRegistry>().clone();
        let dims: Vec<usize> = learned.iter().map(|&s| registry.observation_dim(s)).collect();
        if dims.iter().any(|&d| d != dims[0]) {
            return Err(format!(
                "the learning species observe {} values each; one flat observation array needs one size",
                dims.iter().map(usize::to_string).collect::<Vec<_>>().join(", ")
            )
            .into());
        }
        let external = learned.iter().map(|&s| (s, registry.defs[s].count)).collect();
        let mut env = Env { world, scene, external, obs_dim: dims[0], headline: registry.headline() };
        env.world.resource_mut::<Episode>().auto_reset = false;
        Ok(env)
    }

    /// The external agents' names, `<species>_<k>`, in order.
    pub fn agents(&self) -> Vec<String> {
        self.external
            .iter()
            .flat_map(|&(s, n)| (0..n).map(move |k| format!("{}_{k}", self.scene.species[s].name)))
            .collect()
    }

    pub fn obs_dim(&self) -> usize {
        self.obs_dim
    }

    pub fn scene(&self) -> &Scene {
        &self.scene
    }

    pub fn episode_steps(&self) -> usize {
        self.scene.episode_steps
    }

    /// The world (positions, headings and everything else coevo measures).
    pub fn world(&self) -> &World {
        &self.world
    }

    /// Starts a new episode and returns the observations: with a seed, the world starts afresh from it
    /// (exactly as `--train`/`--record` with that seed); without, the next episode of the same stream.
    pub fn reset(&mut self, seed: Option<u64>) -> crate::error::Result<Vec<f32>> {
        match seed {
            Some(seed) => {
                let mut scene = self.scene.clone();
                scene.seed = seed;
                *self = Env::new(scene)?;
            }
            None => crate::sim::episode::next_episode(&mut self.world),
        }
        Ok(self.observations())
    }

    fn observations(&self) -> Vec<f32> {
        let batches = self.world.resource::<Batches>();
        self.external.iter().flat_map(|&(s, _)| batches.species[s].observations.iter().copied()).collect()
    }

    /// One step t → t+1 with `actions` (`[agents × 2]`, normalized, clamped to [−1, 1]). Err on a wrong
    /// length or a non-finite action (one line; the world is not stepped), or when the state stops being
    /// physical. After a truncated step the world keeps its last state until [`Env::reset`].
    pub fn step(&mut self, actions: &[f32]) -> crate::error::Result<StepResult> {
        let agents: usize = self.external.iter().map(|&(_, n)| n).sum();
        if actions.len() != agents * ACTION_DIM {
            return Err(format!(
                "actions: expected {} values ({agents} agents × 2), got {}",
                agents * ACTION_DIM,
                actions.len()
            )
            .into());
        }
        if let Some(i) = actions.iter().position(|a| !a.is_finite()) {
            return Err(format!("actions[{i}]: {} is not a finite number", actions[i]).into());
        }
        if self.world.resource::<Episode>().step >= self.scene.episode_steps {
            return Err("step: the episode is over (truncated); reset first".into());
        }
        let mut given = vec![Vec::new(); self.scene.species.len()];
        let mut rest = actions;
        for &(s, n) in &self.external {
            let (mine, more) = rest.split_at(n * ACTION_DIM);
            given[s] = mine.iter().map(|a| a.clamp(-1.0, 1.0)).collect();
            rest = more;
        }
        self.world.insert_resource(ExternalActions(given));
        self.world.run_schedule(FixedUpdate);
        crate::sim::check_state(&self.world)?;
        let world = &self.world;
        let batches = world.resource::<Batches>();
        let rewards = self.external.iter().flat_map(|&(s, _)| batches.species[s].rewards.iter().copied()).collect();
        let metrics = world.resource::<SwarmMetrics>();
        let now = metrics.now.get(self.headline).copied().flatten();
        Ok(StepResult {
            observations: self.observations(),
            rewards,
            truncated: world.resource::<Episode>().step >= self.scene.episode_steps,
            dos: now.map_or(f64::NAN, |m| m.dos),
            doa: now.map_or(f64::NAN, |m| m.doa),
            catches: metrics.catches_now,
        })
    }

    /// The current state drawn as the headless animations draw it (`size` pixels square plus a caption):
    /// (width, height, RGBA bytes row by row).
    pub fn render(&mut self, size: u32) -> crate::error::Result<(u32, u32, Vec<u8>)> {
        let title = format!("coevo, seed {}", self.scene.seed);
        crate::run::animate::render_rgba(&mut self.world, size, &title)
    }

    /// Every agent's position (x, y), in coevo's agent order (all species).
    pub fn positions(&self) -> Vec<[f64; 2]> {
        self.world.resource::<Population>().position.iter().map(|p| [p.x, p.y]).collect()
    }
}

/// Many worlds of one scene, world i from seed `seed + i`, stepped together on flat arrays.
pub struct VecEnv {
    envs: Vec<Env>,
    agents: usize,
}

/// What a [`VecEnv`] step returned: `[worlds × agents × d_o]` observations (of the next episode's first
/// state for a world whose episode ended: its last observations are in `final_observations`),
/// `[worlds × agents]` rewards, and per world whether its episode ended with this step.
#[derive(Clone, Debug, Default)]
pub struct VecStep {
    pub observations: Vec<f32>,
    pub rewards: Vec<f32>,
    pub truncated: Vec<bool>,
    pub final_observations: Vec<Option<Vec<f32>>>,
}

/// One world's step in a [`VecEnv`]: its result and, when its episode ended, its last observations.
type WorldStep = crate::error::Result<(StepResult, Option<Vec<f32>>)>;

impl VecEnv {
    pub fn new(scene: Scene, worlds: usize, seed: u64) -> crate::error::Result<VecEnv> {
        if worlds == 0 {
            return Err("num_envs: must be ≥ 1".into());
        }
        let envs = (0..worlds as u64)
            .map(|i| {
                let mut s = scene.clone();
                s.seed = seed.wrapping_add(i);
                Env::new(s)
            })
            .collect::<crate::error::Result<Vec<_>>>()?;
        let agents = envs[0].agents().len();
        Ok(VecEnv { envs, agents })
    }

    pub fn worlds(&self) -> usize {
        self.envs.len()
    }

    pub fn agents(&self) -> usize {
        self.agents
    }

    pub fn obs_dim(&self) -> usize {
        self.envs[0].obs_dim()
    }

    /// The agents' names (the same in every world).
    pub fn agent_names(&self) -> Vec<String> {
        self.envs[0].agents()
    }

    /// Starts the next episode in every world; returns the observations.
    pub fn reset(&mut self) -> crate::error::Result<Vec<f32>> {
        for env in &mut self.envs {
            env.reset(None)?;
        }
        Ok(self.observations())
    }

    /// Every world's current observations, `[worlds × agents × d_o]`.
    pub fn observations(&self) -> Vec<f32> {
        self.envs.iter().flat_map(Env::observations).collect()
    }

    /// One step of every world (`actions`: `[worlds × agents × 2]`), on all cores; a world whose episode
    /// ends starts its next one.
    pub fn step(&mut self, actions: &[f32]) -> crate::error::Result<VecStep> {
        let per = self.agents * ACTION_DIM;
        if actions.len() != per * self.envs.len() {
            return Err(format!(
                "actions: expected {} values ({} worlds × {} agents × 2), got {}",
                per * self.envs.len(),
                self.envs.len(),
                self.agents,
                actions.len()
            )
            .into());
        }
        let mut work: Vec<(&mut Env, &[f32], Option<WorldStep>)> =
            self.envs.iter_mut().zip(actions.chunks(per)).map(|(e, a)| (e, a, None)).collect();
        crate::parallel::for_each_mut(&mut work, |(env, a, out)| {
            *out = Some(env.step(a).and_then(|mut r| {
                if !r.truncated {
                    return Ok((r, None));
                }
                let last = std::mem::replace(&mut r.observations, env.reset(None)?);
                Ok((r, Some(last)))
            }));
        });
        let mut step = VecStep::default();
        for (_, _, out) in work {
            let (r, last) = out.expect("every world stepped")?;
            step.observations.extend(r.observations);
            step.rewards.extend(r.rewards);
            step.truncated.push(r.truncated);
            step.final_observations.push(last);
        }
        Ok(step)
    }
}
