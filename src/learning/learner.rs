//! One species' learner (Algorithm 1's per-species state): its DDPG networks and optimizers, replay
//! buffer, exploration and random stream, and the two things it does each step: store the transitions
//! and update. The learning plugin (`mod.rs`) runs them for every species; `checkpoint.rs` saves them.

use super::ddpg::{Ddpg, Losses};
use super::nets::Dev;
use super::replay::{Batch, ReplayBuffer};
use crate::scene::LearningParams;
use crate::sim::perception::SpeciesBatch;
use crate::sim::species::ACTION_DIM;
use rand_chacha::ChaCha8Rng;

/// One species' learner.
#[derive(Clone, Debug)]
pub struct SpeciesLearner {
    pub ddpg: Ddpg,
    /// The species' own dfdx device: every tensor holds a handle to its device, so species that share one
    /// would contend for its reference counts when they update concurrently.
    pub dev: Dev,
    pub buffer: ReplayBuffer,
    /// Loaded from a checkpoint and never updated.
    pub frozen: bool,
    /// Current exploration noise std σ and random-action probability ε.
    pub noise_std: f64,
    pub epsilon: f64,
    /// The species' own random stream: exploration noise and mini-batch sampling. One stream per species
    /// lets species update concurrently without changing which random numbers go where.
    pub rng: ChaCha8Rng,
    /// The observations the current actions were chosen on (o_t), to pair with o_{t+1}.
    pub(super) pending_obs: Vec<f32>,
    /// The mini-batch buffers, reused by every update.
    batch: Batch,
    /// Sum and count of losses since the last episode summary.
    pub loss_sum: Losses,
    pub updates: usize,
}

impl SpeciesLearner {
    /// A species' fresh learner: networks drawn from `init_rng` (the scene's initialization stream, shared
    /// by the species in registry order), an empty buffer, exploration at its initial σ and ε, and `rng`
    /// its own stream ([`super::species_stream`]).
    pub fn new(obs_dim: usize, p: &LearningParams, frozen: bool, init_rng: &mut ChaCha8Rng, rng: ChaCha8Rng) -> Self {
        let dev = Dev::default();
        SpeciesLearner {
            ddpg: Ddpg::new(&dev, obs_dim, p, init_rng),
            dev,
            buffer: ReplayBuffer::new(p.buffer_capacity, obs_dim, ACTION_DIM),
            frozen,
            noise_std: p.noise_std,
            epsilon: p.epsilon,
            rng,
            pending_obs: vec![],
            batch: Batch::default(),
            loss_sum: Losses::default(),
            updates: 0,
        }
    }

    /// A copy of the networks and exploration state with an empty replay buffer: what a checkpoint holds.
    pub fn without_buffer(&self) -> SpeciesLearner {
        SpeciesLearner {
            ddpg: self.ddpg.clone(),
            dev: self.dev.clone(),
            buffer: ReplayBuffer::new(self.buffer.capacity, self.buffer.obs_dim, self.buffer.act_dim),
            frozen: self.frozen,
            noise_std: self.noise_std,
            epsilon: self.epsilon,
            rng: self.rng.clone(),
            pending_obs: vec![],
            batch: Batch::default(),
            loss_sum: self.loss_sum,
            updates: self.updates,
        }
    }
}

impl SpeciesLearner {
    /// Stores the step's transitions (o_t, a_t, r_t, o_{t+1}) of every individual in the species' buffer.
    pub(super) fn store(&mut self, b: &SpeciesBatch) {
        let d = b.obs_dim;
        // Rows pair up only if the population did not change during the step.
        if self.pending_obs.len() != b.observations.len() {
            return;
        }
        for row in 0..b.n {
            self.buffer.push(
                &self.pending_obs[row * d..(row + 1) * d],
                &b.actions[row * ACTION_DIM..(row + 1) * ACTION_DIM],
                b.rewards[row],
                b.observation(row),
            );
        }
    }

    /// `n` DDPG updates, each on a mini-batch of `batch_size` sampled from the species' buffer with its own
    /// stream. Err (the losses) when a loss or, at the end, a parameter is not finite.
    pub(super) fn update(&mut self, n: usize, batch_size: usize) -> Result<(), Losses> {
        for _ in 0..n {
            self.buffer.sample_into(&mut self.batch, batch_size, &mut self.rng);
            let losses = self.ddpg.update(&self.batch);
            self.loss_sum.critic += losses.critic;
            self.loss_sum.actor += losses.actor;
            self.updates += 1;
            if !losses.critic.is_finite() || !losses.actor.is_finite() {
                return Err(losses);
            }
        }
        match n > 0 && !self.ddpg.is_finite() {
            true => Err(self.loss_sum),
            false => Ok(()),
        }
    }
}
