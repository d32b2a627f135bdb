//! One world driven from outside ([`Env`]): the scene's `Learned` species decided by the caller.

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
pub(super) struct ExternalActions(pub(super) Vec<Vec<f32>>);

/// Decide: the external species' rows of the action batch are the actions given to [`Env::step`].
fn apply_external(actions: Res<ExternalActions>, mut batches: ResMut<Batches>) {
    for (given, batch) in actions.0.iter().zip(batches.species.iter_mut()) {
        if !given.is_empty() && given.len() == batch.actions.len() {
            batch.actions.copy_from_slice(given);
        }
    }
}

/// What a step gives besides observations and rewards ([`StepResult`]'s other fields).
pub(super) struct Outcome {
    pub(super) truncated: bool,
    pub(super) dos: f64,
    pub(super) doa: f64,
    pub(super) catches: u32,
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
            let run = crate::run::live::LiveRun::new(&env.world);
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
        if !self.world.contains_resource::<crate::run::live::LiveRun>() {
            return Err("save_run: coevo trains no species in this env (coevolve names none)").kind(Kind::Input);
        }
        self.world.resource_scope(|world, mut run: Mut<crate::run::live::LiveRun>| run.save(world, dir))
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
    pub(super) fn start(&mut self, seed: Option<u64>) -> crate::error::Result<()> {
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
                    if let Some(mut run) = self.world.get_resource_mut::<crate::run::live::LiveRun>() {
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

    pub(super) fn observations(&self) -> Vec<f32> {
        let mut out = vec![0.0; self.external.iter().map(|&(_, n)| n).sum::<usize>() * self.obs_dim];
        self.write_observations(&mut out);
        out
    }

    /// The external agents' observations into `out` (`[agents × d_o]`): a [`VecEnv`] has each world
    /// write its own rows of the step's array, with no array of its own in between.
    pub(super) fn write_observations(&self, out: &mut [f32]) {
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
    pub(super) fn take_episodes(&mut self) -> Vec<EpisodeSummary> {
        std::mem::take(&mut self.world.resource_mut::<EpisodeLog>().episodes)
    }

    /// `metrics.csv`'s header for this scene with its outside-decided species as the learning ones.
    pub(super) fn metrics_header(&self) -> String {
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
    pub(super) fn advance(&mut self, actions: &[f32], rewards: &mut [f32]) -> crate::error::Result<Outcome> {
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
        if ended && self.world.contains_resource::<crate::run::live::LiveRun>() {
            // coevo's side's episode row and snapshots, read before a VecEnv takes the episode.
            crate::run::live::LiveRun::record(&mut self.world);
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
    pub(super) fn population(&self) -> usize {
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
