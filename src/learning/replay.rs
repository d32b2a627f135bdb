//! One replay buffer per species (Section "Replay Buffer"): every individual's transitions (o, a, r, o')
//! go into the species' ring buffer; mini-batches are drawn uniformly from everything it holds.
//! Actions are stored as the actor outputs them, normalized to [−1, 1], which is what the critic reads.

use rand::Rng;
use rand_chacha::ChaCha8Rng;

#[derive(Clone, Debug)]
pub struct ReplayBuffer {
    pub capacity: usize,
    pub obs_dim: usize,
    pub act_dim: usize,
    /// Transitions held (≤ capacity).
    pub len: usize,
    /// Where the next transition goes; wraps to 0 at capacity, overwriting the oldest.
    next: usize,
    obs: Vec<f32>,
    actions: Vec<f32>,
    rewards: Vec<f32>,
    next_obs: Vec<f32>,
}

/// A mini-batch, row-major.
#[derive(Clone, Debug, PartialEq)]
pub struct Batch {
    pub n: usize,
    pub obs: Vec<f32>,
    pub actions: Vec<f32>,
    pub rewards: Vec<f32>,
    pub next_obs: Vec<f32>,
}

impl ReplayBuffer {
    /// An empty buffer; memory grows with use up to `capacity` transitions.
    pub fn new(capacity: usize, obs_dim: usize, act_dim: usize) -> Self {
        ReplayBuffer { capacity, obs_dim, act_dim, len: 0, next: 0, obs: vec![], actions: vec![], rewards: vec![], next_obs: vec![] }
    }

    pub fn push(&mut self, obs: &[f32], action: &[f32], reward: f32, next_obs: &[f32]) {
        let (d, a) = (self.obs_dim, self.act_dim);
        if self.len < self.capacity {
            self.obs.extend_from_slice(obs);
            self.actions.extend_from_slice(action);
            self.rewards.push(reward);
            self.next_obs.extend_from_slice(next_obs);
            self.len += 1;
        } else {
            let i = self.next;
            self.obs[i * d..(i + 1) * d].copy_from_slice(obs);
            self.actions[i * a..(i + 1) * a].copy_from_slice(action);
            self.rewards[i] = reward;
            self.next_obs[i * d..(i + 1) * d].copy_from_slice(next_obs);
        }
        self.next = (self.next + 1) % self.capacity;
    }

    /// `n` transitions drawn uniformly (with replacement) from all held.
    pub fn sample(&self, n: usize, rng: &mut ChaCha8Rng) -> Batch {
        assert!(self.len > 0, "sampling an empty replay buffer");
        let (d, a) = (self.obs_dim, self.act_dim);
        let mut b = Batch { n, obs: Vec::with_capacity(n * d), actions: Vec::with_capacity(n * a), rewards: Vec::with_capacity(n), next_obs: Vec::with_capacity(n * d) };
        for _ in 0..n {
            let i = rng.gen_range(0..self.len);
            b.obs.extend_from_slice(&self.obs[i * d..(i + 1) * d]);
            b.actions.extend_from_slice(&self.actions[i * a..(i + 1) * a]);
            b.rewards.push(self.rewards[i]);
            b.next_obs.extend_from_slice(&self.next_obs[i * d..(i + 1) * d]);
        }
        b
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    #[test]
    fn wraps_at_capacity_and_samples_everything_it_holds() {
        let mut buf = ReplayBuffer::new(5, 1, 1);
        for i in 0..8 {
            buf.push(&[i as f32], &[0.0], i as f32, &[i as f32 + 1.0]);
        }
        assert_eq!(buf.len, 5);
        let mut rng = ChaCha8Rng::seed_from_u64(0);
        let batch = buf.sample(2000, &mut rng);
        let mut seen: Vec<f32> = batch.rewards.clone();
        seen.sort_by(f32::total_cmp);
        seen.dedup();
        // 0, 1, 2 were overwritten by 5, 6, 7; everything held is drawn, and rows stay aligned.
        assert_eq!(seen, vec![3.0, 4.0, 5.0, 6.0, 7.0]);
        for i in 0..batch.n {
            assert_eq!(batch.obs[i], batch.rewards[i]);
            assert_eq!(batch.next_obs[i], batch.rewards[i] + 1.0);
        }
    }
}
