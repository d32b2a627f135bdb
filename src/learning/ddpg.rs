//! Algorithm 1 for one species, on one screen: a shared actor μ(o) and a **decentralized** critic
//! Q(o, a) on the agent's own observation and action, their target copies, and one DDPG update.
//!
//! ```text
//!   y      = r + γ · Q'(o', μ'(o'))                       TD target (no gradient)
//!   L(θ^Q) = 1/S Σ (y − Q(o, a))²                          critic loss, Adam on θ^Q
//!   J(θ^μ) = −1/S Σ Q(o, μ(o))                             actor loss through the critic, Adam on θ^μ
//!   θ'     ← τ·θ + (1 − τ)·θ'                             soft update of both targets
//! ```
//!
//! Episodes end by a time limit, not by a terminal state, so the target always bootstraps.
//!
//! The update is written twice: [`Ddpg::update`] computes it with the passes of `fused.rs` (buffers reused,
//! only the gradients it needs), `Ddpg::update_reference` (built for the tests) with dfdx's tape. The tests below train the same
//! networks both ways and require the same parameters.

use super::fused::{gradients_like, Workspace};
use super::nets::{matrix, Adam, Dev, Mlp, Output};
use super::replay::Batch;
use crate::scene::LearningParams;
use crate::sim::species::ACTION_DIM;
// dfdx's tape: the reference update only.
#[cfg(test)]
use dfdx::losses::mse_loss;
#[cfg(test)]
use dfdx::prelude::*;
use rand_chacha::ChaCha8Rng;

/// Rows per actor forward pass in [`Ddpg::act_into`]: large populations are split into chunks of this
/// many agents, processed in parallel.
pub(crate) const ACT_CHUNK: usize = 1024;

/// Actor, critic, targets and optimizers of one species.
#[derive(Clone, Debug)]
pub struct Ddpg {
    pub actor: Mlp,
    pub(crate) critic: Mlp,
    pub(crate) target_actor: Mlp,
    pub(crate) target_critic: Mlp,
    pub(crate) actor_opt: Adam,
    pub(crate) critic_opt: Adam,
    /// Discount factor γ.
    pub(crate) gamma: f32,
    /// Soft update rate τ.
    pub(crate) tau: f32,
    /// The update's buffers (not part of the learner's state: rebuilt at the first update).
    pub(crate) work: Workspace,
}

/// Losses of one update.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct Losses {
    pub(crate) critic: f32,
    pub(crate) actor: f32,
}

impl Ddpg {
    /// Fresh networks for observations of width `obs_dim`: 3 hidden layers of `hidden` (Appendix B).
    pub fn new(dev: &Dev, obs_dim: usize, p: &LearningParams, rng: &mut ChaCha8Rng) -> Ddpg {
        crate::parallel::single_threaded_kernels();
        let h = p.hidden;
        let actor = Mlp::new(dev, &[obs_dim, h, h, h, ACTION_DIM], Output::Tanh, rng);
        let critic = Mlp::new(dev, &[obs_dim + ACTION_DIM, h, h, h, 1], Output::Linear, rng);
        Ddpg {
            actor_opt: Adam::new(p.actor_lr as f32, &actor),
            critic_opt: Adam::new(p.critic_lr as f32, &critic),
            target_actor: actor.clone(),
            target_critic: critic.clone(),
            actor,
            critic,
            gamma: p.gamma as f32,
            tau: p.tau as f32,
            work: Workspace::default(),
        }
    }

    pub(crate) fn obs_dim(&self) -> usize {
        self.actor.input_width()
    }

    /// μ(o) for a batch of `n` observations in one forward pass on dfdx: `[n × 2]` actions in [−1, 1]. The
    /// reference [`Ddpg::act_into`] is tested against.
    pub fn act(&self, dev: &Dev, observations: &[f32], n: usize) -> Vec<f32> {
        self.actor.forward(matrix(dev, observations.to_vec(), n, self.obs_dim())).as_vec()
    }

    /// μ(o) into `actions` (`[n × 2]`): one forward pass per [`ACT_CHUNK`] rows, the chunks on all
    /// worker threads. The chunking depends only on n, so the result never depends on the thread count.
    /// The forward pass is `fused.rs`'s (bias in the product's epilogue, activations in place, buffers
    /// kept per thread): the same products and sums as dfdx's, so the same actions to the bit, without
    /// dfdx's per-op allocations and broadcast kernels (which took half of a 10 000-agent step).
    pub fn act_into(&self, _dev: &Dev, observations: &[f32], actions: &mut [f32]) {
        act_with(&self.actor, observations, actions);
    }

    /// One DDPG update on a mini-batch (the body of Algorithm 1's inner loop after sampling), in the
    /// reused buffers of `fused.rs`.
    pub(crate) fn update(&mut self, b: &Batch) -> Losses {
        let (n, d, w) = (b.n, self.obs_dim(), &mut self.work);
        gradients_like(&mut w.critic_gradients, &self.critic);
        gradients_like(&mut w.actor_gradients, &self.actor);

        // TD target y = r + γ·Q'(o', μ'(o')), kept in d_q until the critic's gradient replaces it.
        w.target_actor.forward(&self.target_actor, n, &b.next_obs, &[]);
        w.target_critic.forward(&self.target_critic, n, &b.next_obs, w.target_actor.output());
        w.d_q.clear();
        w.d_q.extend(b.rewards.iter().zip(w.target_critic.output()).map(|(r, q)| r + q * self.gamma));

        // Critic: minimise L = 1/S Σ (y − Q(o, a))², dL/dQ = 2 (Q − y) / S.
        w.critic.forward_to_learn(&self.critic, n, &b.obs, &b.actions);
        let mut critic_loss = 0.0;
        for (g, q) in w.d_q.iter_mut().zip(w.critic.output()) {
            let e = q - *g;
            critic_loss += e * e;
            *g = 2.0 * e / n as f32;
        }
        w.critic.backward(&self.critic, &w.d_q, Some(&mut w.critic_gradients), None);
        self.critic_opt.update(&mut self.critic, &w.critic_gradients);

        // Actor: maximise Q(o, μ(o)) through the (just updated) critic: J = −1/S Σ Q, dJ/dQ = −1/S; only
        // the critic's input gradient in its action columns, dJ/dμ, is needed.
        w.actor.forward_to_learn(&self.actor, n, &b.obs, &[]);
        w.actor_value.forward(&self.critic, n, &b.obs, w.actor.output());
        let actor_loss = -w.actor_value.output().iter().sum::<f32>() / n as f32;
        w.d_q.fill(-1.0 / n as f32);
        w.d_actions.resize(n * ACTION_DIM, 0.0);
        w.actor_value.backward(&self.critic, &w.d_q, None, Some((d..d + ACTION_DIM, &mut w.d_actions)));
        w.actor.backward(&self.actor, &w.d_actions, Some(&mut w.actor_gradients), None);
        self.actor_opt.update(&mut self.actor, &w.actor_gradients);

        // Targets follow slowly.
        self.target_actor.soft_update_towards(&self.actor, self.tau);
        self.target_critic.soft_update_towards(&self.critic, self.tau);
        Losses { critic: critic_loss / n as f32, actor: actor_loss }
    }

    /// [`Ddpg::update`] computed by dfdx's tape: the reference the fused update is tested against.
    #[cfg(test)]
    pub(crate) fn update_reference(&mut self, dev: &Dev, b: Batch) -> Losses {
        let d = self.obs_dim();
        let obs = matrix(dev, b.obs, b.n, d);
        let actions = matrix(dev, b.actions, b.n, ACTION_DIM);
        let rewards = matrix(dev, b.rewards, b.n, 1);
        let next_obs = matrix(dev, b.next_obs, b.n, d);

        // TD target y = r + γ·Q'(o', μ'(o')).
        let next_actions = self.target_actor.forward(next_obs.clone());
        let next_q = self.target_critic.forward((next_obs, next_actions).concat_along(Axis::<1>));
        let y = rewards + next_q * self.gamma;

        // Critic: minimise (y − Q(o, a))².
        let q = self.critic.forward((obs.leaky_trace(), actions).concat_along(Axis::<1>));
        let critic_loss = mse_loss(q, y);
        let critic_loss_value = critic_loss.array();
        let grads = critic_loss.backward();
        let critic_grads = self.critic.gradients(&grads);
        self.critic_opt.update(&mut self.critic, &critic_grads);

        // Actor: maximise Q(o, μ(o)), the gradient flowing through the (just updated) critic.
        let mu = self.actor.forward(obs.leaky_trace());
        let q = self.critic.forward((obs.retaped::<OwnedTape<f32, Dev>>(), mu).concat_along(Axis::<1>));
        let actor_loss = -q.mean();
        let actor_loss_value = actor_loss.array();
        let grads = actor_loss.backward();
        let actor_grads = self.actor.gradients(&grads);
        self.actor_opt.update(&mut self.actor, &actor_grads);

        // Targets follow slowly.
        self.target_actor.soft_update_towards(&self.actor, self.tau);
        self.target_critic.soft_update_towards(&self.critic, self.tau);
        Losses { critic: critic_loss_value, actor: actor_loss_value }
    }

    /// Whether every parameter of every network is finite.
    pub(crate) fn is_finite(&self) -> bool {
        [&self.actor, &self.critic, &self.target_actor, &self.target_critic].iter().all(|n| n.is_finite())
    }
}

/// `actor`'s μ(o) into `actions`, as [`Ddpg::act_into`] computes it: any actor of the species' shape (a
/// snapshot standing in for the species, `league.rs`) acts to the bit as it did when it was kept.
pub(crate) fn act_with(actor: &Mlp, observations: &[f32], actions: &mut [f32]) {
    let d = actor.input_width();
    crate::parallel::for_each_chunk(actions, ACT_CHUNK * ACTION_DIM, |i, out| {
        let rows = out.len() / ACTION_DIM;
        let obs = &observations[i * ACT_CHUNK * d..(i * ACT_CHUNK + rows) * d];
        super::fused::with_pass(|pass| {
            pass.forward(actor, rows, obs, &[]);
            out.copy_from_slice(pass.output());
        });
    });
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::Scene;
    use rand::{Rng, SeedableRng};

    fn fixed_batch(n: usize, d: usize, rng: &mut ChaCha8Rng) -> Batch {
        let mut draw = |k: usize| (0..k).map(|_| rng.gen_range(-1.0f32..1.0)).collect::<Vec<f32>>();
        Batch { n, obs: draw(n * d), actions: draw(n * ACTION_DIM), rewards: draw(n), next_obs: draw(n * d) }
    }

    #[test]
    fn batched_inference_gives_dfdx_s_actions_to_the_bit() {
        let dev = Dev::default();
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let mut ddpg = Ddpg::new(&dev, 54, &Scene::preset("paper").unwrap().learning, &mut rng);
        // A few updates, so the biases are not the initial ones.
        let batch = fixed_batch(64, 54, &mut rng);
        for _ in 0..5 {
            ddpg.update(&batch);
        }
        // More rows than one chunk, and a short last chunk.
        let n = 2 * ACT_CHUNK + 37;
        let obs: Vec<f32> = (0..n * 54).map(|_| rng.gen_range(-2.0f32..2.0)).collect();
        let mut fast = vec![0.0; n * ACTION_DIM];
        ddpg.act_into(&dev, &obs, &mut fast);
        // dfdx on the same chunks (gemm may sum a chunk's last rows in another kernel than a whole batch's).
        let slow: Vec<f32> =
            obs.chunks(ACT_CHUNK * 54).flat_map(|chunk| ddpg.act(&dev, chunk, chunk.len() / 54)).collect();
        let worst = fast.iter().zip(&slow).map(|(a, b)| (a - b).abs()).fold(0.0f32, f32::max);
        let differ = fast.iter().zip(&slow).filter(|(a, b)| a != b).count();
        assert_eq!(fast, slow, "{differ} of {} differ, by at most {worst}", fast.len());
    }

    #[test]
    fn shapes_and_actor_range() {
        let dev = Dev::default();
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let ddpg = Ddpg::new(&dev, 54, &Scene::preset("paper").unwrap().learning, &mut rng);
        assert_eq!((ddpg.actor.input_width(), ddpg.actor.output_width()), (54, 2));
        assert_eq!((ddpg.critic.input_width(), ddpg.critic.output_width()), (56, 1));
        assert_eq!(ddpg.actor.layers.len(), 4, "three hidden layers and the output");
        let obs: Vec<f32> = (0..13 * 54).map(|i| ((i * 37) % 200) as f32 / 10.0 - 10.0).collect();
        let a = ddpg.act(&dev, &obs, 13);
        assert_eq!(a.len(), 26);
        assert!(a.iter().all(|x| x.abs() <= 1.0));
    }

    #[test]
    fn updates_reduce_the_critic_loss_on_a_fixed_batch() {
        let dev = Dev::default();
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let mut ddpg = Ddpg::new(&dev, 10, &Scene::preset("paper").unwrap().learning, &mut rng);
        let batch = fixed_batch(256, 10, &mut rng);
        let first = ddpg.update(&batch).critic;
        let mut last = first;
        for _ in 0..200 {
            last = ddpg.update(&batch).critic;
        }
        assert!(last < 0.5 * first, "critic loss {first} -> {last}");
        assert!(ddpg.is_finite());
    }

    #[test]
    fn actor_update_climbs_the_critic() {
        // With a frozen critic the actor's objective Q(o, μ(o)) must rise.
        let dev = Dev::default();
        let mut rng = ChaCha8Rng::seed_from_u64(9);
        let mut ddpg = Ddpg::new(&dev, 6, &Scene::preset("paper").unwrap().learning, &mut rng);
        ddpg.actor_opt.lr = 1e-3;
        ddpg.critic_opt.lr = 0.0;
        let batch = fixed_batch(128, 6, &mut rng);
        let before = ddpg.update(&batch).actor;
        let mut after = before;
        for _ in 0..100 {
            after = ddpg.update(&batch).actor;
        }
        assert!(after < before, "actor loss −Q should fall: {before} -> {after}");
    }

    /// The largest difference between two networks' parameters.
    fn max_difference(a: &Mlp, b: &Mlp) -> f32 {
        a.parameter_slices()
            .flatten()
            .zip(b.parameter_slices().flatten())
            .map(|(x, y)| (x - y).abs())
            .fold(0.0, f32::max)
    }

    #[test]
    fn the_fused_update_trains_the_networks_dfdx_trains() {
        // The same networks, the same 500 mini-batches, both update paths: every parameter of all four
        // networks, and every loss, must agree to ~1e-5 (a bound, not bit equality, so that a change of summation
        // order in either path stays legal; today they agree to the bit).
        let dev = Dev::default();
        let mut rng = ChaCha8Rng::seed_from_u64(21);
        let mut fused = Ddpg::new(&dev, 54, &Scene::preset("paper").unwrap().learning, &mut rng);
        let mut reference = fused.clone();
        for k in 0..500 {
            let batch = fixed_batch(256, 54, &mut rng);
            let (a, b) = (fused.update(&batch), reference.update_reference(&dev, batch));
            let tolerance = 1e-5 * (1.0 + b.critic.abs().max(b.actor.abs()));
            assert!((a.critic - b.critic).abs() <= tolerance, "update {k}: critic loss {a:?} vs {b:?}");
            assert!((a.actor - b.actor).abs() <= tolerance, "update {k}: actor loss {a:?} vs {b:?}");
        }
        let pairs = [
            (&fused.actor, &reference.actor),
            (&fused.critic, &reference.critic),
            (&fused.target_actor, &reference.target_actor),
            (&fused.target_critic, &reference.target_critic),
        ];
        for (i, (a, b)) in pairs.into_iter().enumerate() {
            let diff = max_difference(a, b);
            assert!(diff <= 1e-5, "network {i}: parameters differ by {diff}");
        }
        // And the update did move them (the comparison is not of two untouched copies).
        assert!(
            max_difference(
                &fused.actor,
                &Ddpg::new(&dev, 54, &Scene::preset("paper").unwrap().learning, &mut ChaCha8Rng::seed_from_u64(21))
                    .actor
            ) > 1e-3
        );
        assert_eq!(fused.actor_opt.step, 500);
    }
}
