//! The learning plugin: predator–prey coevolution by multi-agent DDPG (Section "Framework of
//! Coevolution", Algorithm 1; the update itself is in `ddpg.rs`).
//!
//! Per learned species: one actor and one decentralized critic shared by all its individuals (parameter
//! sharing), one replay buffer filled with every individual's transitions, and exploration noise drawn
//! independently per individual. In `Decide` the species' observations go through the actor in one batched
//! forward pass; in `Learn` the step's transitions are stored and the scene's update schedule runs:
//! `updates_per_step` after every environment step (Algorithm 1 as printed) and/or `updates_per_episode`
//! after each episode (the authors' code: 30).
//!
//! Exploration (parameters.md): Gaussian noise of std σ on the tanh output, clamped to [−1, 1]; with
//! probability ε a species acts uniformly at random for that step; σ and ε fall by `exploration_decay` per
//! episode to `exploration_floor`.

pub(crate) mod bf16;
pub mod control;
pub mod ddpg;
pub(crate) mod direct;
pub(crate) mod fused;
pub(crate) mod league;
pub(crate) mod learner;
pub mod nets;
pub(crate) mod replay;
pub(crate) mod wide;

use crate::scene::{LearningParams, NoiseDraw, Policy, Scene};
use crate::sim::clock::Episode;
use crate::sim::episode::SimRng;
use crate::sim::perception::Batches;
use crate::sim::species::{SpeciesRegistry, ACTION_DIM};
use crate::sim::Simulation;
use crate::sim::{ActiveScene, SimSet};
use bevy::prelude::*;
use control::ResolvedControl;
use ddpg::Losses;
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

pub(crate) use learner::{SpeciesLearner, Storing};

/// Train (explore, store, update) or only act (evaluation: no noise, no updates).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mode {
    Train,
    Evaluate,
}

pub(crate) struct LearningPlugin {
    pub(crate) mode: Mode,
}

/// Every learned species' learner (None for rule-based species).
#[derive(Resource)]
pub struct Learners {
    pub species: Vec<Option<SpeciesLearner>>,
    pub mode: Mode,
    pub(crate) params: LearningParams,
    /// Set when a loss or parameter stops being finite; training stops with this message.
    pub(crate) failure: Option<String>,
    /// The learners as they were before the last episode's updates, for saving after a failure.
    pub(crate) last_good: Option<Vec<Option<SpeciesLearner>>>,
    /// Species names, registry order.
    pub(crate) names: Vec<String>,
    /// Opponents from the past (`learning.opponents`), when training and a species has a pool.
    pub(crate) league: Option<league::League>,
}

impl Learners {
    /// Mean losses since the last call, per species, and resets the sums.
    pub(crate) fn take_losses(&mut self) -> Vec<Option<Losses>> {
        self.species
            .iter_mut()
            .map(|l| {
                let l = l.as_mut()?;
                let n = l.updates.max(1) as f32;
                let mean = Losses { critic: l.loss_sum.critic / n, actor: l.loss_sum.actor / n };
                let had = l.updates > 0;
                l.loss_sum = Losses::default();
                l.updates = 0;
                had.then_some(mean)
            })
            .collect()
    }
}

impl Learners {
    /// Fresh learners for a scene: random networks for every `Learned` and `Frozen` species (frozen ones
    /// and, when evaluating, learned ones never update), none for rule-based species.
    pub fn new(scene: &Scene, mode: Mode) -> Learners {
        let registry = SpeciesRegistry::from_scene(scene);
        let mut init_rng = SimRng::stream(scene.seed, 1);
        let p = scene.learning.clone();
        let species = (0..registry.len())
            .map(|s| {
                let frozen = match registry.policy(s) {
                    Policy::Learned => mode == Mode::Evaluate,
                    Policy::Frozen(_) => true,
                    _ => return None,
                };
                let d = registry.observation_dim(s);
                let def = &registry.defs[s];
                let storing = Storing::of(&p, def.count, def.max_thrust, def.max_turn_rate * scene.world.dt);
                Some(SpeciesLearner::new(d, &p, storing, frozen, &mut init_rng, species_stream(scene.seed, s)))
            })
            .collect::<Vec<_>>();
        Learners {
            league: (mode == Mode::Train).then(|| league::League::new(scene, &species)).flatten(),
            species,
            mode,
            params: p,
            failure: None,
            last_good: None,
            names: registry.defs.iter().map(|d| d.name.clone()).collect(),
        }
    }
}

impl Plugin for LearningPlugin {
    fn build(&self, app: &mut App) {
        // Learners inserted beforehand (with trained actors loaded, see [`simulation`]) are
        // kept; otherwise fresh ones.
        if !app.world().contains_resource::<Learners>() {
            let scene = app.world().resource::<ActiveScene>().0.clone();
            app.insert_resource(Learners::new(&scene, self.mode));
        }
        app.add_systems(FixedUpdate, (decide_learned.in_set(SimSet::Decide), learn.in_set(SimSet::Learn)));
    }
}

/// A simulation with the learning plugin driven by `learners` as given (actors chosen by the caller:
/// cross-play deploys snapshots), more plugins added by `extra`.
pub fn simulation_of(
    scene: Scene,
    learners: Learners,
    extra: impl FnOnce(&mut App),
) -> crate::error::Result<Simulation> {
    let mode = learners.mode;
    Simulation::try_with_plugins(scene, |app| {
        app.insert_resource(learners);
        app.add_plugins(LearningPlugin { mode });
        extra(app);
    })
}

/// The random stream of learned species `s`: stream 16 + s of the seed (0 is the environment's, 1 the
/// networks' initialisation).
pub(crate) fn species_stream(seed: u64, s: usize) -> ChaCha8Rng {
    SimRng::stream(seed, 16 + s as u64)
}

/// Batched actor inference for every learned species, plus exploration while training.
fn decide_learned(
    mut learners: ResMut<Learners>,
    mut batches: ResMut<Batches>,
    control: Option<Res<ResolvedControl>>,
    episode: Res<Episode>,
) {
    let l = &mut *learners;
    let explore = l.mode == Mode::Train;
    let noise_draw = l.params.noise_draw;
    if let Some(league) = l.league.as_mut() {
        league.play(episode.index);
    }
    for (s, learner) in l.species.iter_mut().enumerate() {
        let Some(learner) = learner else { continue };
        let batch = &mut batches.species[s];
        if batch.n == 0 {
            continue;
        }
        // A snapshot playing the species this episode acts as it was kept: no noise, nothing stored.
        if let Some(actor) = l.league.as_ref().and_then(|g| g.stand_in(s)) {
            ddpg::act_with(actor, &batch.observations, &mut batch.actions);
            continue;
        }
        match control.as_deref().filter(|c| c.touches(s) && !explore) {
            None => learner.ddpg.act_into(&learner.dev, &batch.observations, &mut batch.actions),
            Some(control) => {
                let seen = control.apply(s, &batch.observations, batch.n, &mut learner.rng);
                learner.ddpg.act_into(&learner.dev, &seen, &mut batch.actions);
            }
        }
        if explore && !learner.frozen && !learner.paused {
            explore_actions(&mut batch.actions, learner.epsilon, learner.noise_std, noise_draw, &mut learner.rng);
        }
        learner.pending_obs.clone_from(&batch.observations);
    }
}

/// Exploration (Algorithm 1, "a_i = μ(o_i) + N_t"): with probability ε the species acts uniformly at
/// random for the step (each individual and component drawn), else Gaussian noise of std σ is added to
/// the actors' `actions` (normalized, then clamped to [−1, 1]), drawn as `draw` says.
pub(crate) fn explore_actions(
    actions: &mut [f32],
    epsilon: f64,
    noise_std: f64,
    draw: NoiseDraw,
    rng: &mut ChaCha8Rng,
) {
    if rng.gen_bool(epsilon.clamp(0.0, 1.0)) {
        actions.iter_mut().for_each(|a| *a = rng.gen_range(-1.0..=1.0));
    } else if noise_std > 0.0 {
        let noise = Normal::new(0.0, noise_std as f32).expect("σ is finite and ≥ 0");
        match draw {
            // Independent noise for every individual and action component.
            NoiseDraw::PerIndividual => actions.iter_mut().for_each(|a| *a = (*a + noise.sample(rng)).clamp(-1.0, 1.0)),
            // One vector for the species, added to every individual (the authors' code).
            NoiseDraw::PerSpecies => {
                let shared: [f32; ACTION_DIM] = std::array::from_fn(|_| noise.sample(rng));
                for action in actions.chunks_mut(ACTION_DIM) {
                    action.iter_mut().zip(&shared).for_each(|(a, n)| *a = (*a + n).clamp(-1.0, 1.0));
                }
            }
        }
    }
}

/// Stores the step's transitions and runs the update schedule, the species concurrently (one per worker
/// thread; each has its own buffer, networks and random stream, so the result is the sequential one).
fn learn(mut learners: ResMut<Learners>, batches: Res<Batches>, episode: Res<Episode>) {
    let l = &mut *learners;
    if l.mode != Mode::Train || l.failure.is_some() {
        return;
    }
    let p = &l.params;
    let episode_done = episode.is_done();
    if episode_done {
        l.last_good = Some(l.species.iter().map(|x| x.as_ref().map(SpeciesLearner::without_buffer)).collect());
    }
    let updates = p.updates_per_step + if episode_done { p.updates_per_episode } else { 0 };
    if let Some(league) = l.league.as_mut() {
        (0..batches.species.len()).for_each(|s| league.add_rewards(s, &batches.species[s].rewards));
    }
    let league = l.league.as_ref();
    let mut work: Vec<(usize, &mut SpeciesLearner, Result<(), Losses>)> = l
        .species
        .iter_mut()
        .enumerate()
        .filter(|(s, _)| league.is_none_or(|g| g.stand_in(*s).is_none()))
        .filter_map(|(s, x)| x.as_mut().filter(|x| !x.frozen && !x.paused).map(|x| (s, x, Ok(()))))
        .collect();
    for (s, learner, _) in &mut work {
        learner.store(&batches.species[*s]);
    }
    let (warmup, batch_size) = (p.warmup_transitions.max(1), p.batch_size);
    work.retain(|(_, learner, _)| learner.buffer.len >= warmup);
    if updates > 0 {
        crate::parallel::for_each_mut(&mut work, |(_, learner, result)| *result = learner.update(updates, batch_size));
    }
    for (s, learner, result) in work {
        if let Err(losses) = result {
            l.failure = Some(format!(
                "species {}: loss or parameters became non-finite (critic loss {}, actor loss {}) in episode {} at step {}",
                l.names[s], losses.critic, losses.actor, episode.index, episode.step
            ));
            return;
        }
        if episode_done {
            learner.noise_std = (learner.noise_std - p.exploration_decay).max(p.exploration_floor.min(p.noise_std));
            learner.epsilon = (learner.epsilon - p.exploration_decay).max(p.exploration_floor.min(p.epsilon));
        }
    }
    if let (true, Some(league)) = (episode_done, l.league.as_mut()) {
        league.end_episode(episode.index, &l.species);
    }
}

/// Starts a scene afresh in a running world, as a new [`Simulation`] of it would start: its resources,
/// the learners (for an app with the learning plugin) and a new population. The viewer's reset and scene
/// picker use this, so a restarted world steps exactly like a headless one of the same scene and seed.
pub fn restart(world: &mut World, scene: &Scene, learners: Option<Learners>) {
    crate::sim::insert_scene(world, scene);
    if let Some(learners) = learners {
        world.insert_resource(learners);
    }
    crate::sim::episode::spawn_population(world);
}
