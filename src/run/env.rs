//! coevo as an environment for learners outside it (the Rust side of the Python package): the
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
//!
//! An [`ObservationControl`] (`blind:prey:prey`, …, as `coevo --eval --control`) alters the observations
//! handed out exactly as it alters what coevo's actors are given, so an outside learner's policies can be
//! put through the flocking/herding controls. Finished episodes are summarised as `metrics.csv` rows
//! ([`VecEnv::take_episode_rows`]), so an outside learner writes the run files `coevo --plot` reads.
//!
//! Coevolution across the border ([`Coevolve`]): learned species named there stay coevo's, trained inside
//! the world by its own Algorithm 1 (exploration, replay, updates, as `--train` trains them) while the
//! outside learner decides the others, frozen or learning on a [`Schedule`]; their run (metrics, snapshots,
//! checkpoint) is saved as a run folder by [`Env::save_run`].

use crate::error::{Kind, ResultExt};
use crate::learning::control::{ObservationControl, ResolvedControl};
use crate::learning::Mode;
use crate::scene::{Policy, Scene};
use crate::sim::clock::Episode;
use crate::sim::episode::SimRng;
use crate::sim::metrics::{EpisodeLog, EpisodeSummary, SwarmMetrics};
use crate::sim::perception::{Batches, Population};
use crate::sim::species::{SpeciesRegistry, ACTION_DIM};
use crate::sim::SimSet;
use bevy::prelude::*;
use rand_chacha::ChaCha8Rng;

/// The first random stream of the shuffled controls: the permutations of step t of episode e come from
/// stream CONTROL_STREAM + e·(episode_steps + 1) + t of the world's seed, so the observations are a function
/// of the state however often they are read (the simulation draws from stream 0, network initialisation
/// from 1, coevo's learners from 16 + species).
const CONTROL_STREAM: u64 = 1 << 32;

/// The policy name the externally decided species get (`Plugin("external")`).
pub(crate) const EXTERNAL: &str = "external";

/// The learned species coevo keeps training inside the world while the others are decided from outside,
/// and when it trains them. Empty (the default): every learned species is decided from outside.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Coevolve {
    /// Species names, each `Learned` in the scene.
    pub species: Vec<String>,
    pub schedule: Schedule,
}

/// When coevo's side of a [`Coevolve`] world learns.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Schedule {
    /// Every episode, as `--train`: exploration noise, replay and updates.
    #[default]
    Learning,
    /// Never: its actors act as they are, without noise (the opponent held fixed).
    Frozen,
    /// Learning for `every` episodes, then held for `every`, and so on, from the first episode: the two
    /// sides take turns when the outside learner holds itself in the other blocks.
    Alternate { every: usize },
}

impl std::str::FromStr for Schedule {
    type Err = String;

    /// `learning`, `frozen` or `alternate:K` (K ≥ 1 episodes a turn).
    fn from_str(text: &str) -> Result<Schedule, String> {
        let every = |k: &str| match k.parse::<usize>() {
            Ok(every) if every >= 1 => Ok(Schedule::Alternate { every }),
            _ => Err(format!("{text:?}: alternate:K needs K ≥ 1 episodes")),
        };
        match text.split_once(':') {
            None if text == "learning" => Ok(Schedule::Learning),
            None if text == "frozen" => Ok(Schedule::Frozen),
            Some(("alternate", k)) => every(k),
            _ => Err(format!("{text:?} is not learning, frozen or alternate:K")),
        }
    }
}

impl Schedule {
    /// Whether coevo's side learns in episode `episode` (0-based).
    pub fn learns(self, episode: usize) -> bool {
        match self {
            Schedule::Learning => true,
            Schedule::Frozen => false,
            Schedule::Alternate { every } => (episode / every.max(1)).is_multiple_of(2),
        }
    }
}

/// The actions given from outside, per species (empty for species decided inside).
#[derive(Resource, Default, Clone, Debug)]
pub(super) struct ExternalActions(Vec<Vec<f32>>);

/// Decide: the external species' rows of the action batch are the actions given to [`Env::step`].
fn apply_external(actions: Res<ExternalActions>, mut batches: ResMut<Batches>) {
    for (given, batch) in actions.0.iter().zip(batches.species.iter_mut()) {
        if !given.is_empty() && given.len() == batch.actions.len() {
            batch.actions.copy_from_slice(given);
        }
    }
}

/// What a step gives besides observations and rewards ([`StepResult`]'s other fields).
struct Outcome {
    truncated: bool,
    dos: f64,
    doa: f64,
    catches: u32,
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
    pub(super) world: World,
    pub(super) scene: Scene,
    /// What the outside learner is given of the observations (default: everything).
    control: ObservationControl,
    resolved: ResolvedControl,
    /// The externally decided species (registry indices) and their agent counts.
    external: Vec<(usize, usize)>,
    obs_dim: usize,
    headline: usize,
    /// The species coevo trains inside, and when.
    coevolve: Coevolve,
}

impl Env {
    /// A world of `scene` whose `Learned` species are decided from outside. Err when none is, when their
    /// observation sizes differ (one flat array needs one size), or when the scene is refused.
    pub fn new(scene: Scene) -> crate::error::Result<Env> {
        Env::with_control(scene, ObservationControl::default())
    }

    /// As [`Env::new`], the observations handed out altered by `control` (resolved against the scene: an
    /// unknown species or an observer that is not decided from outside is an Err naming the form).
    pub fn with_control(scene: Scene, control: ObservationControl) -> crate::error::Result<Env> {
        Env::with_options(scene, control, Coevolve::default())
    }

    /// As [`Env::with_control`], the learned species `coevolve` names trained inside the world by coevo
    /// (an Err naming the species when one is not a learned species of the scene, or when none is left to
    /// decide from outside).
    pub fn with_options(scene: Scene, control: ObservationControl, coevolve: Coevolve) -> crate::error::Result<Env> {
        scene.validate()?;
        for name in &coevolve.species {
            if !scene.species.iter().any(|s| s.name == *name && s.policy == Policy::Learned) {
                return Err(format!("coevolve: {name:?} is not a learned species of the scene")).kind(Kind::Input);
            }
        }
        if let Schedule::Alternate { every: 0 } = coevolve.schedule {
            return Err("coevolve: alternate every 0 episodes; give at least 1").kind(Kind::Input);
        }
        let resolved = control
            .resolve(&SpeciesRegistry::from_scene(&scene))
            .map_err(|e| format!("control: {e}"))
            .kind(Kind::Input)?;
        let learned: Vec<usize> = (0..scene.species.len())
            .filter(|&s| scene.species[s].policy == Policy::Learned)
            .filter(|&s| !coevolve.species.contains(&scene.species[s].name))
            .collect();
        if let Some(s) =
            (0..scene.species.len()).find(|&s| coevolve.species.contains(&scene.species[s].name) && resolved.touches(s))
        {
            return Err(format!(
                "control: {} is coevo's (coevolve): a control alters what the outside learner is handed, so it names species decided from outside",
                scene.species[s].name
            ))
            .kind(Kind::Input);
        }
        if learned.is_empty() {
            let why = match coevolve.species.is_empty() {
                true => "the scene has no Learned species to decide from outside",
                false => "coevolve: every learned species is coevo's; none is left to decide from outside",
            };
            return Err(why).kind(if coevolve.species.is_empty() { Kind::Scene } else { Kind::Input });
        }
        // The world runs the scene with its learned species decided from outside; `scene` is kept as given.
        let mut decided = scene.clone();
        for &s in &learned {
            decided.species[s].policy = Policy::Plugin(EXTERNAL.into());
        }
        // coevo's side, if any, trains as `--train` trains (the outside side's rows of the batch are given).
        let mode = if coevolve.species.is_empty() { Mode::Evaluate } else { Mode::Train };
        let mut sim = crate::run::simulation_with(decided, mode, None, |app| {
            crate::sim::policy::PolicyPlugins::register(app, EXTERNAL);
            app.init_resource::<ExternalActions>();
            app.add_systems(FixedUpdate, apply_external.in_set(SimSet::Decide));
        })?;
        let mut world = std::mem::take(sim.world_mut());
        strip(&mut world);
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
        let mut env = Env {
            world,
            scene,
            control,
            resolved,
            external,
            obs_dim: dims[0],
            headline: registry.headline_by_kind(),
            coevolve,
        };
        env.world.resource_mut::<Episode>().auto_reset = false;
        if !env.coevolve.species.is_empty() {
            // Kept from the first step, as the viewer keeps its live training, so that it can be saved.
            let run = super::live::LiveRun::new(&env.world);
            env.world.insert_resource(run);
            env.hold_or_release();
        }
        Ok(env)
    }

    /// coevo's side held or released for the episode about to be played, as its [`Schedule`] says.
    fn hold_or_release(&mut self) {
        let learns = self.coevolve.schedule.learns(self.world.resource::<Episode>().index);
        let mut learners = self.world.resource_mut::<crate::learning::Learners>();
        for learner in learners.species.iter_mut().flatten().filter(|l| !l.frozen) {
            learner.paused = !learns;
        }
    }

    /// Saves coevo's side of the run into a new folder `dir`, written as `--train` writes a run folder:
    /// `scene.ron` (the outside species' policy `Plugin("external")`, so `--resume` and `--eval` refuse the
    /// folder), `provenance.ron`, `metrics.csv` (coevo's species learning), its actors' snapshots and the
    /// checkpoint, whose actors load elsewhere as `Frozen(dir)` opponents. Between episodes only (after the
    /// reset that follows an episode's last step), only when coevo trains a side ([`Coevolve`]), and never
    /// after a reset cut an episode short.
    pub fn save_run(&mut self, dir: &std::path::Path) -> crate::error::Result<()> {
        if !self.world.contains_resource::<super::live::LiveRun>() {
            return Err("save_run: coevo trains no species in this env (coevolve names none)").kind(Kind::Input);
        }
        self.world.resource_scope(|world, mut run: Mut<super::live::LiveRun>| run.save(world, dir))
    }

    /// The parameters of coevo's actor of `species` as they are now, layer by layer (weights, then biases):
    /// None for a species coevo does not train here.
    pub fn coevo_actor(&self, species: &str) -> Option<Vec<Vec<f32>>> {
        let s = self.scene.species.iter().position(|d| d.name == species)?;
        self.coevolve.species.contains(&self.scene.species[s].name).then_some(())?;
        let learners = self.world.resource::<crate::learning::Learners>();
        learners.species[s].as_ref().map(|l| l.ddpg.actor.parameters())
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

    /// The bound of each number of an observation (`sim::perception::observation_high`; the largest over
    /// the externally decided species): every observation lies in [−high, high].
    pub fn observation_high(&self) -> Vec<f32> {
        let registry = self.world.resource::<SpeciesRegistry>();
        let scene = &self.world.resource::<crate::sim::ActiveScene>().0;
        let mut high = vec![0.0f32; self.obs_dim];
        for &(s, _) in &self.external {
            for (h, x) in high.iter_mut().zip(crate::sim::perception::observation_high(scene, registry, s)) {
                *h = h.max(x);
            }
        }
        high
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
        self.start(seed)?;
        Ok(self.observations())
    }

    /// [`Env::reset`] without handing out the observations.
    fn start(&mut self, seed: Option<u64>) -> crate::error::Result<()> {
        match seed {
            Some(seed) => {
                let mut scene = self.scene.clone();
                scene.seed = seed;
                *self = Env::with_options(scene, self.control.clone(), self.coevolve.clone())?;
            }
            None => {
                let cut = self.world.resource::<Episode>().step < self.scene.episode_steps;
                if cut {
                    // coevo's side misses that episode's end (its updates, its metrics row): no longer the
                    // run `--train` would make, so it is not saved.
                    if let Some(mut run) = self.world.get_resource_mut::<super::live::LiveRun>() {
                        run.altered.get_or_insert_with(|| {
                            "an episode was cut short by a reset before its last step".to_string()
                        });
                    }
                }
                crate::sim::episode::next_episode(&mut self.world);
                if !self.coevolve.species.is_empty() {
                    self.hold_or_release();
                }
            }
        }
        Ok(())
    }

    fn observations(&self) -> Vec<f32> {
        let mut out = vec![0.0; self.external.iter().map(|&(_, n)| n).sum::<usize>() * self.obs_dim];
        self.write_observations(&mut out);
        out
    }

    /// The external agents' observations into `out` (`[agents × d_o]`): a [`VecEnv`] has each world
    /// write its own rows of the step's array, with no array of its own in between.
    fn write_observations(&self, out: &mut [f32]) {
        let batches = self.world.resource::<Batches>();
        // The step's random stream, made the first time a control needs it (most calls have none).
        let mut rng: Option<ChaCha8Rng> = None;
        let mut at = 0;
        for &(s, _) in &self.external {
            let b = &batches.species[s];
            let out = &mut out[at..at + b.observations.len()];
            at += b.observations.len();
            if !self.resolved.touches(s) {
                out.copy_from_slice(&b.observations);
                continue;
            }
            let rng = rng.get_or_insert_with(|| {
                let e = self.world.resource::<Episode>();
                let t = (e.index * (self.scene.episode_steps + 1) + e.step) as u64;
                SimRng::stream(self.scene.seed, CONTROL_STREAM + t)
            });
            out.copy_from_slice(&self.resolved.apply(s, &b.observations, b.n, rng));
        }
    }

    /// The summaries of the episodes finished since the last call (time averages, catches, returns: what a
    /// `metrics.csv` row holds), numbered by this world.
    pub(crate) fn take_episodes(&mut self) -> Vec<EpisodeSummary> {
        std::mem::take(&mut self.world.resource_mut::<EpisodeLog>().episodes)
    }

    /// `metrics.csv`'s header for this scene with its outside-decided species as the learning ones.
    pub(crate) fn metrics_header(&self) -> String {
        let learning: Vec<usize> = self.external.iter().map(|&(s, _)| s).collect();
        let authors = self.world.resource::<crate::sim::ActiveScene>().0.authors_metrics;
        crate::store::schema::metrics_header_for(self.world.resource::<SpeciesRegistry>(), &learning, authors)
    }

    /// One step t → t+1 with `actions` (`[agents × 2]`, normalized, clamped to [−1, 1]). Err on a wrong
    /// length or a non-finite action (one line; the world is not stepped), or when the state stops being
    /// physical. After a truncated step the world keeps its last state until [`Env::reset`].
    pub fn step(&mut self, actions: &[f32]) -> crate::error::Result<StepResult> {
        let mut rewards = vec![0.0; self.external.iter().map(|&(_, n)| n).sum()];
        let Outcome { truncated, dos, doa, catches } = self.advance(actions, &mut rewards)?;
        Ok(StepResult { observations: self.observations(), rewards, truncated, dos, doa, catches })
    }

    /// [`Env::step`], the rewards written into `rewards` (`[agents]`) and the observations left in the
    /// world ([`Env::write_observations`]).
    fn advance(&mut self, actions: &[f32], rewards: &mut [f32]) -> crate::error::Result<Outcome> {
        let agents: usize = self.external.iter().map(|&(_, n)| n).sum();
        if actions.len() != agents * ACTION_DIM {
            return Err(format!(
                "actions: expected {} values ({agents} agents × 2), got {}",
                agents * ACTION_DIM,
                actions.len()
            ))
            .kind(Kind::Input);
        }
        if let Some(i) = actions.iter().position(|a| !a.is_finite()) {
            return Err(format!("actions[{i}]: {} is not a finite number", actions[i])).kind(Kind::Input);
        }
        if self.world.resource::<Episode>().step >= self.scene.episode_steps {
            return Err("step: the episode is over (truncated); reset first").kind(Kind::Input);
        }
        // Into the resource's own vectors: a step allocates nothing for its actions.
        let mut given = self.world.resource_mut::<ExternalActions>();
        given.0.resize(self.scene.species.len(), Vec::new());
        let mut rest = actions;
        for &(s, n) in &self.external {
            let (mine, more) = rest.split_at(n * ACTION_DIM);
            given.0[s].clear();
            given.0[s].extend(mine.iter().map(|a| a.clamp(-1.0, 1.0)));
            rest = more;
        }
        crate::sim::step_world(&mut self.world);
        crate::sim::check_state(&self.world)?;
        if let Some(failure) = self.world.get_resource::<crate::learning::Learners>().and_then(|l| l.failure.clone()) {
            return Err(format!("coevo's side stopped training: {failure}").into());
        }
        let ended = self.world.resource::<Episode>().step >= self.scene.episode_steps;
        if ended && self.world.contains_resource::<super::live::LiveRun>() {
            // coevo's side's episode row and snapshots, read before a VecEnv takes the episode.
            super::live::LiveRun::record(&mut self.world);
        }
        let world = &self.world;
        let batches = world.resource::<Batches>();
        let mut at = 0;
        for &(s, n) in &self.external {
            rewards[at..at + n].copy_from_slice(&batches.species[s].rewards);
            at += n;
        }
        let metrics = world.resource::<SwarmMetrics>();
        let now = metrics.now.get(self.headline).copied().flatten();
        let (dos, doa, catches) =
            (now.map_or(f64::NAN, |m| m.dos), now.map_or(f64::NAN, |m| m.doa), metrics.catches_now);
        let truncated = world.resource::<Episode>().step >= self.scene.episode_steps;
        Ok(Outcome { truncated, dos, doa, catches })
    }

    /// The current state drawn as the headless animations draw it (`size` pixels square plus a caption):
    /// (width, height, RGBA bytes row by row).
    pub fn render(&mut self, size: u32) -> crate::error::Result<(u32, u32, Vec<u8>)> {
        let title = format!("coevo, seed {}", self.scene.seed);
        crate::run::animate::render_rgba(&mut self.world, size, &title)
    }

    /// Every agent's species name, ordered by agent id as [`Env::positions`] (`coevo --record`'s
    /// `OUT-species.npy`).
    pub fn individual_species(&self) -> Vec<String> {
        let pop = self.world.resource::<Population>();
        by_id(pop).into_iter().map(|i| self.scene.species[pop.species[i]].name.clone()).collect()
    }

    /// Every agent's position (x, y), all species, ordered by agent id (`coevo --record`'s `id`).
    pub fn positions(&self) -> Vec<[f64; 2]> {
        let pop = self.world.resource::<Population>();
        by_id(pop).into_iter().map(|i| [pop.position[i].x, pop.position[i].y]).collect()
    }

    /// The global state a centralised critic reads: per agent of every species, ordered by agent id,
    /// [`STATE_DIM`] numbers (x, y, v_x, v_y, h_x, h_y: position in m, velocity in m/s, unit heading),
    /// in the world frame whatever frame the observations use.
    pub fn state(&self) -> Vec<f32> {
        let pop = self.world.resource::<Population>();
        by_id(pop)
            .into_iter()
            .flat_map(|i| {
                let (p, v, h) = (pop.position[i], pop.velocity[i], pop.heading[i]);
                [p.x, p.y, v.x, v.y, h.x, h.y].map(|x| x as f32)
            })
            .collect()
    }

    /// The largest magnitude of each number of [`Env::state`] (bounds of a state space), agent by agent.
    pub fn state_high(&self) -> Vec<f32> {
        let (pop, registry) = (self.world.resource::<Population>(), self.world.resource::<SpeciesRegistry>());
        let scene = &self.world.resource::<crate::sim::ActiveScene>().0;
        by_id(pop)
            .into_iter()
            .flat_map(|i| crate::sim::perception::state_high(scene, registry, pop.species[i]).map(|x| x as f32))
            .collect()
    }

    /// Agents of every species (the rows of [`Env::state`]).
    pub(crate) fn population(&self) -> usize {
        self.world.resource::<Population>().id.len()
    }
}

/// Numbers per agent in [`Env::state`].
pub const STATE_DIM: usize = 6;

/// The population's rows in agent-id order (`coevo --record`'s `id`), the order of everything [`Env`]
/// hands out about every agent.
fn by_id(pop: &Population) -> Vec<usize> {
    let mut order: Vec<usize> = (0..pop.id.len()).collect();
    order.sort_by_key(|&i| pop.id[i].0);
    order
}

/// How a [`VecEnv`]'s worlds are seeded from its one seed.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum WorldSeeds {
    /// World 0 from the seed itself, world i > 0 from [`world_seed`]: a different seed gives other worlds
    /// (seeds 1 and 2 of 32 worlds share none), so runs with different seeds are independent samples.
    #[default]
    Independent,
    /// World i from seed + i, as the first VecEnv seeded them: runs with seeds 1 and 2 share 31 of 32
    /// worlds. Kept to reproduce runs made that way.
    Consecutive,
}

/// The seed of world `i` of a [`VecEnv`] seeded `seed` ([`WorldSeeds::Independent`]): `seed` for world 0
/// (a one-world VecEnv is the single env of that seed), else SplitMix64 (Steele et al. 2014) of `seed`
/// and `i` mixed, so neighbouring seeds' worlds do not coincide.
pub fn world_seed(seed: u64, i: u64) -> u64 {
    fn splitmix64(mut z: u64) -> u64 {
        z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    if i == 0 {
        seed
    } else {
        splitmix64(seed ^ splitmix64(i))
    }
}

/// Many worlds of one scene, world i from [`world_seed`]`(seed, i)`, stepped together on flat arrays.
/// Where coevo trains no species, the worlds share one app per thread and keep only their state between
/// steps ([`super::pool`]), with the same results as worlds of their own.
pub struct VecEnv {
    envs: super::pool::Worlds,
    agents: usize,
    /// Finished episodes not yet taken, in the order they finished (by step, then by world).
    finished: Vec<EpisodeSummary>,
    /// Episodes finished so far in all worlds: the next finished episode's number in `metrics.csv`.
    numbered: usize,
    /// No step since the worlds were made: the first `reset` returns their first episode (world i's is
    /// the first episode of its seed, as a single env's `reset(world seed)`) rather than starting a second.
    fresh: bool,
    /// Whether to step the worlds on one thread or on all ([`crate::parallel::Adaptive`]).
    threads: crate::parallel::Adaptive,
    /// At most this many threads for this VecEnv's steps (None: [`crate::parallel::threads`]).
    max_threads: Option<usize>,
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
    /// Per world, as [`StepResult`]: DoS and DoA of the headline species, catches at the new state.
    pub dos: Vec<f64>,
    pub doa: Vec<f64>,
    pub catches: Vec<u32>,
}

/// One world's step in a [`VecEnv`]: its result and, when its episode ended, its last observations.
type WorldStep = crate::error::Result<(Outcome, Option<Vec<f32>>, Vec<EpisodeSummary>)>;

impl VecEnv {
    pub fn new(scene: Scene, worlds: usize, seed: u64) -> crate::error::Result<VecEnv> {
        VecEnv::with_control(scene, worlds, seed, ObservationControl::default())
    }

    /// As [`VecEnv::new`], every world's observations altered by `control` ([`Env::with_control`]).
    pub(crate) fn with_control(
        scene: Scene,
        worlds: usize,
        seed: u64,
        control: ObservationControl,
    ) -> crate::error::Result<VecEnv> {
        VecEnv::seeded(scene, worlds, seed, control, WorldSeeds::default())
    }

    /// As [`VecEnv::with_control`], the worlds seeded as `seeds` says.
    pub fn seeded(
        scene: Scene,
        worlds: usize,
        seed: u64,
        control: ObservationControl,
        seeds: WorldSeeds,
    ) -> crate::error::Result<VecEnv> {
        VecEnv::coevolving(scene, worlds, seed, control, seeds, Coevolve::default())
    }

    /// As [`VecEnv::seeded`], with coevo training the species `coevolve` names in every world
    /// ([`Env::with_options`]): each world's learners learn from that world alone, as in `--train`, so
    /// n worlds train n populations of them.
    pub fn coevolving(
        scene: Scene,
        worlds: usize,
        seed: u64,
        control: ObservationControl,
        seeds: WorldSeeds,
        coevolve: Coevolve,
    ) -> crate::error::Result<VecEnv> {
        if worlds == 0 {
            return Err("num_envs: must be ≥ 1").kind(Kind::Input);
        }
        // All the worlds are bounded before the second is built: built one by one, each would be checked
        // against what the ones before it had left, and the refusal would come late and name no figure.
        let limit = crate::io::memory_bytes();
        let check = |bytes: f64| -> crate::error::Result<()> {
            if bytes > limit {
                return Err(format!(
                    "num_envs: {worlds} worlds of this scene would need about {}, more than the {} of memory coevo may use here (the least of free memory, the cgroup limit and ulimit -v)",
                    crate::io::bytes_shown(bytes),
                    crate::io::bytes_shown(limit)
                ))
                .kind(Kind::Input);
            }
            Ok(())
        };
        // Whether pooled or not is known once a world is built (one world is bounded when its scene is
        // validated).
        let bytes = super::pool::Bytes { apart: scene.world_bytes(), parked: scene.parked_bytes() };
        let envs = super::pool::Worlds::new(worlds, crate::parallel::threads(), bytes, check, |i| {
            let mut s = scene.clone();
            s.seed = match seeds {
                WorldSeeds::Independent => world_seed(seed, i as u64),
                WorldSeeds::Consecutive => seed.wrapping_add(i as u64),
            };
            Env::with_options(s, control.clone(), coevolve.clone())
        })?;
        let agents = envs.any().agents().len();
        Ok(VecEnv {
            envs,
            agents,
            finished: vec![],
            numbered: 0,
            fresh: true,
            threads: Default::default(),
            max_threads: None,
        })
    }

    /// Steps on at most `n` threads (at least 1; never more than [`crate::parallel::threads`]); which
    /// thread steps a world never changes what it computes.
    pub fn set_max_threads(&mut self, n: usize) {
        self.max_threads = Some(n.max(1));
    }

    /// Saves world `world`'s run of coevo's side ([`Env::save_run`]); between episodes, so right after a
    /// step that ended that world's episode (the world then stands at its next episode's start). A reset
    /// that cut an episode short leaves the run unsaveable ([`Env::reset`]).
    pub fn save_run(&mut self, world: usize, dir: &std::path::Path) -> crate::error::Result<()> {
        let n = self.envs.len();
        self.envs.with(world, |env| env.save_run(dir)).unwrap_or_else(|| {
            Err(format!("save_run: world {world}: there are {n} (0 to {})", n - 1)).kind(Kind::Input)
        })
    }

    /// World `world`'s [`Env::coevo_actor`].
    pub fn coevo_actor(&mut self, world: usize, species: &str) -> Option<Vec<Vec<f32>>> {
        self.envs.with(world, |env| env.coevo_actor(species))?
    }

    /// Every world's [`Env::state`], world after world: `[worlds × agents of all species × STATE_DIM]`.
    pub fn state(&mut self) -> Vec<f32> {
        self.envs.map(1, |_, env| env.state()).concat()
    }

    /// Agents of every species per world (the rows of a world's [`Env::state`]).
    pub fn population(&self) -> usize {
        self.envs.any().population()
    }

    /// Each world's seed, in order.
    pub fn world_seeds(&self) -> Vec<u64> {
        self.envs.seeds()
    }

    /// `metrics.csv`'s header ([`Env::metrics_header`]).
    pub fn metrics_header(&self) -> String {
        self.envs.any().metrics_header()
    }

    /// The episodes finished since the last call as the first cells of `metrics.csv` rows (up to the
    /// returns, [`crate::store::schema::episode_cells`]), numbered in the order they finished across all worlds
    /// (by step, then by world), so the file does not depend on how often this is called.
    pub fn take_episode_rows(&mut self) -> Vec<String> {
        let registry = self.envs.any().world.resource::<SpeciesRegistry>();
        let first = self.numbered;
        let rows: Vec<String> = self
            .finished
            .drain(..)
            .enumerate()
            .map(|(k, mut e)| {
                e.episode = first + k;
                crate::store::schema::episode_cells(&e, registry).join(",")
            })
            .collect();
        self.numbered += rows.len();
        rows
    }

    pub fn worlds(&self) -> usize {
        self.envs.len()
    }

    pub fn agents(&self) -> usize {
        self.agents
    }

    pub fn obs_dim(&self) -> usize {
        self.envs.any().obs_dim()
    }

    /// [`Env::observation_high`] (the same in every world).
    pub fn observation_high(&self) -> Vec<f32> {
        self.envs.any().observation_high()
    }

    /// The agents' names (the same in every world).
    pub fn agent_names(&self) -> Vec<String> {
        self.envs.any().agents()
    }

    /// Starts the next episode in every world (the first call after the worlds were made: their first
    /// episode, already spawned); returns the observations.
    pub fn reset(&mut self) -> crate::error::Result<Vec<f32>> {
        if !std::mem::take(&mut self.fresh) {
            self.envs.map(1, |_, env| env.reset(None)).into_iter().collect::<crate::error::Result<Vec<_>>>()?;
        }
        Ok(self.observations())
    }

    /// Every world's current observations, `[worlds × agents × d_o]`.
    pub fn observations(&mut self) -> Vec<f32> {
        self.envs.map(1, |_, env| env.observations()).concat()
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
            ))
            .kind(Kind::Input);
        }
        // Every world's actions are checked before any world steps: a refused call changes nothing.
        if let Some(i) = actions.iter().position(|a| !a.is_finite()) {
            let names = self.envs.any().agents();
            let (world, agent) = (i / per, (i % per) / ACTION_DIM);
            return Err(format!("world {world}, {}: {} is not a finite number", names[agent], actions[i]))
                .kind(Kind::Input);
        }
        // A step taken (never one refused above) leaves the first episode: a reset after it starts the next.
        self.fresh = false;
        // On one thread or all, whichever has been faster lately (other work on the machine can make
        // all threads slower than one); the same worlds either way. Each world writes its rows of the
        // step's arrays.
        let (n, agents, d) = (self.envs.len(), self.agents, self.obs_dim());
        let (mut observations, mut rewards) = (vec![0.0; n * agents * d], vec![0.0; n * agents]);
        let rows: Vec<(&mut [f32], &mut [f32])> =
            observations.chunks_mut(agents * d).zip(rewards.chunks_mut(agents)).collect();
        let (cap, envs) = (self.max_threads, &mut self.envs);
        let stepped: Vec<WorldStep> = self.threads.run_at_most(cap, |workers| {
            envs.map_with(workers, rows, |k, env, (observed, rewarded)| {
                let outcome = env.advance(&actions[k * per..(k + 1) * per], rewarded)?;
                if !outcome.truncated {
                    env.write_observations(observed);
                    return Ok((outcome, None, vec![]));
                }
                let (last, finished) = (env.observations(), env.take_episodes());
                env.start(None)?;
                env.write_observations(observed);
                Ok((outcome, Some(last), finished))
            })
        });
        let mut step = VecStep { observations, rewards, ..VecStep::default() };
        for out in stepped {
            let (r, last, finished) = out?;
            step.truncated.push(r.truncated);
            step.final_observations.push(last);
            step.dos.push(r.dos);
            step.doa.push(r.doa);
            step.catches.push(r.catches);
            self.finished.extend(finished);
        }
        Ok(step)
    }
}

/// What a world stepped from outside keeps of its app: the schedules it steps (`FixedUpdate`, and
/// `Perceive`, which a reset and the step run) and no reflection registry (nothing here reflects), so that
/// each of many worlds holds less. The app's frame schedules (`Main`, `First`, `PostUpdate`, `Last`, the
/// fixed-step loop) never run here: [`crate::sim::step_world`] runs `FixedUpdate` alone.
fn strip(world: &mut World) {
    use bevy::ecs::schedule::ScheduleLabel;
    world.remove_resource::<bevy::prelude::AppTypeRegistry>();
    let mut schedules = world.resource_mut::<bevy::ecs::schedule::Schedules>();
    let kept = [bevy::prelude::FixedUpdate.intern(), crate::sim::perception::Perceive.intern()];
    let unused: Vec<_> = schedules.iter().map(|(_, s)| s.label()).filter(|l| !kept.contains(l)).collect();
    for label in unused {
        schedules.remove(label);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::alloc::{GlobalAlloc, Layout, System};
    use std::cell::Cell;

    /// The system allocator, counting the bytes live that this thread allocated (other tests run beside):
    /// what a world holds, measured.
    struct Counting;
    thread_local! {
        static LIVE: Cell<isize> = const { Cell::new(0) };
    }
    fn count(bytes: isize) {
        // A thread being torn down has no counter left: its allocations are not this test's.
        let _ = LIVE.try_with(|live| live.set(live.get() + bytes));
    }
    // SAFETY: every call is forwarded to the system allocator unchanged; only sizes are counted.
    unsafe impl GlobalAlloc for Counting {
        unsafe fn alloc(&self, l: Layout) -> *mut u8 {
            count(l.size() as isize);
            unsafe { System.alloc(l) }
        }
        unsafe fn dealloc(&self, p: *mut u8, l: Layout) {
            count(-(l.size() as isize));
            unsafe { System.dealloc(p, l) }
        }
        unsafe fn realloc(&self, p: *mut u8, l: Layout, new: usize) -> *mut u8 {
            count(new as isize - l.size() as isize);
            unsafe { System.realloc(p, l, new) }
        }
    }
    #[global_allocator]
    static ALLOCATOR: Counting = Counting;

    /// The bytes a world of `scene` holds: made alone (an app of its own; 16 of them, a sixteenth) or
    /// parked among many (the bytes 48 pooled worlds hold beyond 16, a thirty-second of them), once made,
    /// reset and stepped, on one thread.
    fn measured(scene: &Scene) -> (f64, f64) {
        let live = || LIVE.with(|l| l.get()) as f64;
        let before = live();
        let alone: Vec<Env> = (0..16)
            .map(|_| {
                let mut env = Env::new(scene.clone()).unwrap();
                env.reset(None).unwrap();
                env.step(&vec![0.3; env.agents().len() * 2]).unwrap();
                env
            })
            .collect();
        let apart = (live() - before) / 16.0;
        drop(alone);
        let pooled = |n: usize| {
            let before = live();
            let mut env = VecEnv::seeded(scene.clone(), n, 1, Default::default(), WorldSeeds::Independent).unwrap();
            assert!(env.envs.pooled());
            env.set_max_threads(1);
            env.reset().unwrap();
            env.step(&vec![0.3; n * env.agents() * 2]).unwrap();
            live() - before
        };
        (apart, (pooled(48) - pooled(16)) / 32.0)
    }

    /// Pooled worlds against the same worlds each in an app of its own, in kinds of worlds whose steps
    /// read every parked part: learned species decided from outside, rule-based and noisy classic
    /// opponents (the environment's random stream), walls, the authors' energy budget, a shuffled control
    /// (the world's seed), episodes ending and restarting. Every output is compared to the bit.
    #[test]
    fn pooled_worlds_step_as_worlds_of_their_own() {
        let load = |f: &str| Scene::load(std::path::Path::new(f)).unwrap();
        let mut energy = load("scenes/gym-pps-code.ron");
        energy.world.energy_budget = true;
        let mut vicsek = load("scenes/confined.ron");
        vicsek.species[0].policy = Policy::Vicsek(crate::scene::VicsekRule { radius: 0.5, noise: 1.0 });
        let mut random = load("scenes/standard.ron");
        random.species[0].policy = Policy::Random;
        let shuffled = ObservationControl::parse(&["shuffled:prey:prey"]).unwrap();
        for (name, mut scene, control) in [
            ("standard", load("scenes/standard.ron"), ObservationControl::default()),
            ("prey-vs-chasers", load("scenes/prey-vs-chasers.ron"), ObservationControl::default()),
            ("energy", energy, ObservationControl::default()),
            ("vicsek in walls", vicsek, ObservationControl::default()),
            ("random, shuffled", random, shuffled),
        ] {
            scene.episode_steps = 6;
            let make = || VecEnv::seeded(scene.clone(), 7, 11, control.clone(), WorldSeeds::Independent).unwrap();
            let mut pooled = make();
            assert!(pooled.envs.pooled(), "{name}: {:?}", super::super::pool::eligible(pooled.envs.any()));
            let mut apart = make();
            let seeds = apart.world_seeds();
            apart.envs = super::super::pool::Worlds::Apart(
                seeds
                    .iter()
                    .map(|&seed| {
                        let mut s = scene.clone();
                        s.seed = seed;
                        Env::with_control(s, control.clone()).unwrap()
                    })
                    .collect(),
            );
            assert_eq!(pooled.world_seeds(), seeds);
            assert_eq!(pooled.reset().unwrap(), apart.reset().unwrap(), "{name}");
            let n = 7 * pooled.agents() * ACTION_DIM;
            for t in 0..15 {
                let actions: Vec<f32> = (0..n).map(|i| ((i * 7919 + t * 104_729) % 200) as f32 / 100.0 - 1.0).collect();
                if t == 9 {
                    // A reset between steps, mid-episode, for every world.
                    assert_eq!(pooled.reset().unwrap(), apart.reset().unwrap(), "{name}, reset at {t}");
                }
                let (a, b) = (pooled.step(&actions).unwrap(), apart.step(&actions).unwrap());
                // Debug text tells bits apart (NaN from NaN included); kept out of the message, it is long.
                assert!(format!("{a:?}") == format!("{b:?}"), "{name}, step {t}: the pooled step differs");
                assert_eq!(pooled.state(), apart.state(), "{name}, step {t}");
            }
            let rows = pooled.take_episode_rows();
            assert!(rows.len() >= 14, "{name}: {} episodes", rows.len());
            assert_eq!(rows, apart.take_episode_rows(), "{name}");
        }
    }

    /// A world whose step panics is swapped back out: the others, and its own seed, are as they were, and
    /// the engine hosts again.
    #[test]
    fn a_panicking_step_leaves_every_world_its_own() {
        let scene = Scene::load(std::path::Path::new("scenes/standard.ron")).unwrap();
        let make = || VecEnv::seeded(scene.clone(), 3, 5, Default::default(), WorldSeeds::Independent).unwrap();
        let (mut hit, mut calm) = (make(), make());
        let seeds = hit.world_seeds();
        let caught = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            hit.envs.map(1, |k, env| assert_ne!(k, 1, "world {} panics", env.scene().seed))
        }));
        assert!(caught.is_err());
        assert_eq!(hit.world_seeds(), seeds);
        assert_eq!(hit.observations(), calm.observations());
        let actions = vec![0.2; 3 * hit.agents() * ACTION_DIM];
        let (a, b) = (hit.step(&actions).unwrap(), calm.step(&actions).unwrap());
        assert!(format!("{a:?}") == format!("{b:?}"));
    }

    /// What keeps worlds apart: coevo training a side (its learners are per world), or one world alone.
    #[test]
    fn worlds_where_coevo_trains_stay_apart() {
        let scene = Scene::load(std::path::Path::new("scenes/standard.ron")).unwrap();
        let coevolve = Coevolve { species: vec!["predator".into()], schedule: Schedule::Learning };
        let worlds = VecEnv::coevolving(scene, 2, 1, Default::default(), WorldSeeds::Independent, coevolve).unwrap();
        assert!(!worlds.envs.pooled());
        let one = VecEnv::new(Scene::load(std::path::Path::new("scenes/standard.ron")).unwrap(), 1, 1).unwrap();
        assert!(!one.envs.pooled());
    }

    #[test]
    fn a_refused_step_leaves_the_first_reset_its_first_episode() {
        let make =
            || VecEnv::seeded(Scene::preset("gym-pps").unwrap(), 2, 3, Default::default(), WorldSeeds::Independent);
        let (mut refused, mut fresh) = (make().unwrap(), make().unwrap());
        assert!(refused.step(&[0.0; 3]).is_err() && refused.step(&vec![f32::NAN; 2 * refused.agents * 2]).is_err());
        assert_eq!(refused.reset().unwrap(), fresh.reset().unwrap());
    }

    #[test]
    fn a_world_holds_what_the_memory_check_bounds_it_by() {
        for prey in [10, 200] {
            let mut scene = Scene::preset("gym-pps").unwrap();
            scene.species.iter_mut().filter(|s| s.name == "prey").for_each(|s| s.count = prey);
            // The check bounds a world from above (never again ~20 times too little), and not by much.
            let (apart, parked) = measured(&scene);
            for (what, held, bound) in [("alone", apart, scene.world_bytes()), ("parked", parked, scene.parked_bytes())]
            {
                assert!(
                    held <= bound && bound <= 1.5 * held,
                    "{prey} prey: a world {what} holds {held} B, bounded by {bound} B"
                );
            }
        }
    }
}
