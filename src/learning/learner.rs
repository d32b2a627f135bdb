//! One species' learner (Algorithm 1's per-species state): its DDPG networks and optimizers, replay
//! buffer, exploration and random stream, and the two things it does each step: store the transitions
//! and update. The learning plugin (`mod.rs`) runs them for every species; `checkpoint.rs` saves them.

use super::ddpg::{Ddpg, Losses};
use super::nets::Dev;
use super::replay::{Batch, ReplayBuffer};
use crate::scene::{BatchDraw, LearningParams, ReplayWindow, StoredAction};
use crate::sim::perception::SpeciesBatch;
use crate::sim::species::ACTION_DIM;
use rand_chacha::ChaCha8Rng;

/// How a species stores and draws its transitions, where the authors' code differs from coevo's default
/// (docs/src/results/authors-code.md; each switch of [`LearningParams`]). The defaults store what the actor outputs into a ring of
/// the last `buffer_capacity` transitions and draw mini-batches with replacement.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct Storing {
    /// [`ReplayWindow::AuthorsFirstRows`]: (rows, first rows): transition k of the species goes to row
    /// k mod rows, and only the first rows are drawn from, so only those are kept.
    pub(crate) first_rows: Option<(u64, u64)>,
    /// [`StoredAction::AuthorsRescaled`]: the physical scale of each action component (thrust in N, turn
    /// in rad per step) the stored action is rescaled to.
    pub(crate) rescaled: Option<[f32; ACTION_DIM]>,
    pub(crate) draw: BatchDraw,
}

impl Storing {
    /// A species of `count` individuals with `max_thrust` (N) and `turn_per_step` (rad).
    pub(crate) fn of(p: &LearningParams, count: usize, max_thrust: f64, turn_per_step: f64) -> Storing {
        let n = count.max(1) as u64;
        let rows = p.buffer_capacity as u64;
        Storing {
            // `filled_i` grows by n until it reaches the capacity: the first rows are a multiple of n.
            first_rows: (p.replay_window == ReplayWindow::AuthorsFirstRows).then(|| (rows * n, rows.div_ceil(n) * n)),
            rescaled: (p.stored_action == StoredAction::AuthorsRescaled)
                .then_some([max_thrust as f32, turn_per_step as f32]),
            draw: p.batch_draw,
        }
    }

    /// How many transitions the buffer holds at most.
    pub(crate) fn capacity(&self, p: &LearningParams) -> usize {
        self.first_rows.map_or(p.buffer_capacity, |(_, first)| first as usize)
    }
}

/// One species' learner.
#[derive(Clone, Debug)]
pub struct SpeciesLearner {
    pub ddpg: Ddpg,
    /// The species' own dfdx device: every tensor holds a handle to its device, so species that share one
    /// would contend for its reference counts when they update concurrently.
    pub dev: Dev,
    pub(crate) buffer: ReplayBuffer,
    /// Loaded from a checkpoint and never updated.
    pub frozen: bool,
    /// Held for now by whoever steps the world (an outside learner's schedule, `run::env::Schedule`): acts
    /// without exploration, stores and updates nothing, until released. Its snapshots are still taken.
    pub(crate) paused: bool,
    /// Current exploration noise std σ and random-action probability ε.
    pub(crate) noise_std: f64,
    pub(crate) epsilon: f64,
    /// The species' own random stream: exploration noise and mini-batch sampling. One stream per species
    /// lets species update concurrently without changing which random numbers go where.
    pub(crate) rng: ChaCha8Rng,
    /// The observations the current actions were chosen on (o_t), to pair with o_{t+1}.
    pub(super) pending_obs: Vec<f32>,
    /// The mini-batch buffers, reused by every update.
    batch: Batch,
    /// Sum and count of losses since the last episode summary.
    pub(crate) loss_sum: Losses,
    pub(crate) updates: usize,
    pub(crate) storing: Storing,
    /// Transitions offered to the buffer so far, kept or not ([`Storing::first_rows`] keeps only those
    /// whose row is drawn from); equal to the buffer's `pushed` when every transition is kept.
    pub(crate) offered: u64,
}

impl SpeciesLearner {
    /// A species' fresh learner: networks drawn from `init_rng` (the scene's initialization stream, shared
    /// by the species in registry order), an empty buffer, exploration at its initial σ and ε, and `rng`
    /// its own stream ([`super::species_stream`]).
    pub(crate) fn new(
        obs_dim: usize,
        p: &LearningParams,
        storing: Storing,
        frozen: bool,
        init_rng: &mut ChaCha8Rng,
        rng: ChaCha8Rng,
    ) -> Self {
        let dev = Dev::default();
        SpeciesLearner {
            ddpg: Ddpg::new(&dev, obs_dim, p, init_rng),
            dev,
            buffer: ReplayBuffer::new(storing.capacity(p), obs_dim, ACTION_DIM),
            frozen,
            paused: false,
            noise_std: p.noise_std,
            epsilon: p.epsilon,
            rng,
            pending_obs: vec![],
            batch: Batch::default(),
            loss_sum: Losses::default(),
            updates: 0,
            storing,
            offered: 0,
        }
    }

    /// A copy of the networks and exploration state with an empty replay buffer: what a checkpoint holds.
    pub(crate) fn without_buffer(&self) -> SpeciesLearner {
        SpeciesLearner {
            ddpg: self.ddpg.clone(),
            dev: self.dev.clone(),
            buffer: ReplayBuffer::new(self.buffer.capacity, self.buffer.obs_dim, self.buffer.act_dim),
            frozen: self.frozen,
            paused: self.paused,
            noise_std: self.noise_std,
            epsilon: self.epsilon,
            rng: self.rng.clone(),
            pending_obs: vec![],
            batch: Batch::default(),
            loss_sum: self.loss_sum,
            updates: self.updates,
            storing: self.storing,
            offered: self.offered,
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
            let k = self.offered;
            self.offered += 1;
            if let Some((rows, first)) = self.storing.first_rows {
                if k % rows >= first {
                    continue;
                }
            }
            let mut action: [f32; ACTION_DIM] =
                b.actions[row * ACTION_DIM..(row + 1) * ACTION_DIM].try_into().expect("an action per row");
            if let Some(scale) = self.storing.rescaled {
                // As the authors' env.step leaves the array it stores: thrust to [0, max], turn to ±max.
                action = [(action[0] + 1.0) / 2.0 * scale[0], action[1] * scale[1]];
            }
            self.buffer.push(&self.pending_obs[row * d..(row + 1) * d], &action, b.rewards[row], b.observation(row));
        }
    }

    /// `n` DDPG updates, each on a mini-batch of `batch_size` sampled from the species' buffer with its own
    /// stream. Err (the losses) when a loss or, at the end, a parameter is not finite.
    pub(super) fn update(&mut self, n: usize, batch_size: usize) -> Result<(), Losses> {
        for _ in 0..n {
            match self.storing.draw {
                BatchDraw::WithReplacement => self.buffer.sample_into(&mut self.batch, batch_size, &mut self.rng),
                BatchDraw::WithoutReplacement => {
                    self.buffer.sample_distinct_into(&mut self.batch, batch_size, &mut self.rng)
                }
            }
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::NoiseDraw;
    use rand::SeedableRng;

    fn learner(storing: Storing, capacity: usize) -> SpeciesLearner {
        let mut p = crate::scene::Scene::preset("paper").unwrap().learning;
        (p.hidden, p.buffer_capacity) = (4, capacity);
        let mut init = ChaCha8Rng::seed_from_u64(1);
        SpeciesLearner::new(1, &p, storing, false, &mut init, ChaCha8Rng::seed_from_u64(2))
    }

    /// Steps of a species of two whose observation, action and reward all say which transition it is.
    fn offer(l: &mut SpeciesLearner, steps: usize) {
        for _ in 0..steps {
            let k = l.offered as f32;
            l.pending_obs = vec![k, k + 1.0];
            let b = SpeciesBatch {
                n: 2,
                obs_dim: 1,
                observations: vec![k + 0.5, k + 1.5],
                actions: vec![0.5, -0.5, 0.5, -0.5],
                rewards: vec![k, k + 1.0],
            };
            l.store(&b);
        }
    }

    #[test]
    fn the_authors_replay_window_keeps_only_the_first_rows_of_each_block() {
        // Rows for 4 × 2 transitions, drawn from the first 4 (a multiple of n = 2 covering the capacity 3).
        let storing = Storing::of(
            &crate::scene::LearningParams {
                buffer_capacity: 3,
                replay_window: ReplayWindow::AuthorsFirstRows,
                ..crate::scene::Scene::preset("paper").unwrap().learning
            },
            2,
            1.0,
            0.5,
        );
        assert_eq!(storing.first_rows, Some((6, 4)));
        let mut l = learner(storing, 3);
        assert_eq!(l.buffer.capacity, 4);
        offer(&mut l, 10);
        assert_eq!(l.offered, 20);
        // Transitions 0–3 (rows 0–3), 4–5 dropped (rows 4–5), 6–9 kept, 10–11 dropped, 12–15, 16–17 dropped,
        // 18–19 kept: the buffer holds the last four kept, 14–15 and 18–19 in rows 2, 3, 0, 1.
        let mut held: Vec<f32> = (l.buffer.first_held()..l.buffer.pushed).map(|k| l.buffer.transition(k).2).collect();
        held.sort_by(f32::total_cmp);
        assert_eq!(held, [14.0, 15.0, 18.0, 19.0]);
        // By default every transition is kept: the last three.
        let mut l = learner(Storing::default(), 3);
        offer(&mut l, 10);
        let held: Vec<f32> = (l.buffer.first_held()..l.buffer.pushed).map(|k| l.buffer.transition(k).2).collect();
        assert_eq!(held, [17.0, 18.0, 19.0]);
    }

    #[test]
    fn the_authors_stored_action_is_rescaled_and_nothing_else_changes() {
        let rescaled = Storing { rescaled: Some([1.0, 0.5]), ..Storing::default() };
        let (mut a, mut b) = (learner(rescaled, 10), learner(Storing::default(), 10));
        offer(&mut a, 1);
        offer(&mut b, 1);
        let (oa, act_a, ra, na) = a.buffer.transition(0);
        let (ob, act_b, rb, nb) = b.buffer.transition(0);
        assert_eq!((oa, ra, na), (ob, rb, nb));
        assert_eq!(act_b, [0.5, -0.5], "normalized as the actor gave it");
        // Thrust (0.5 + 1) / 2 × 1 N, turn −0.5 × 0.5 rad per step.
        assert_eq!(act_a, [0.75, -0.25]);
    }

    #[test]
    fn a_batch_without_replacement_holds_distinct_transitions() {
        let mut l = learner(Storing::default(), 64);
        offer(&mut l, 16);
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let mut batch = Batch::default();
        l.buffer.sample_distinct_into(&mut batch, 32, &mut rng);
        let mut seen = batch.rewards.clone();
        seen.sort_by(f32::total_cmp);
        assert_eq!(seen, (0..32).map(|k| k as f32).collect::<Vec<_>>(), "all 32 held, each once");
        // With replacement, 32 draws of 32 repeat one (all distinct has probability 32!/32^32).
        l.buffer.sample_into(&mut batch, 32, &mut rng);
        let mut seen = batch.rewards.clone();
        seen.sort_by(f32::total_cmp);
        seen.dedup();
        assert!(seen.len() < 32);
    }

    #[test]
    fn noise_per_species_is_one_vector_for_every_individual() {
        let deltas = |draw: NoiseDraw| {
            let mut actions = vec![0.0f32; 2 * 5];
            crate::learning::explore_actions(&mut actions, 0.0, 0.1, draw, &mut ChaCha8Rng::seed_from_u64(4));
            actions.chunks(2).map(|a| [a[0], a[1]]).collect::<Vec<_>>()
        };
        let shared = deltas(NoiseDraw::PerSpecies);
        assert!(shared.iter().all(|a| *a == shared[0]) && shared[0] != [0.0, 0.0], "{shared:?}");
        let own = deltas(NoiseDraw::PerIndividual);
        assert!(own.iter().skip(1).all(|a| *a != own[0]), "{own:?}");
    }
}
