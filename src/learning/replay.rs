//! One replay buffer per species (Section "Replay Buffer"): every individual's transitions (o, a, r, o')
//! go into the species' ring buffer; mini-batches are drawn uniformly from everything it holds.
//! Actions are stored as the actor outputs them, normalized to [−1, 1], which is what the critic reads.

use rand::Rng;
use rand_chacha::ChaCha8Rng;

#[derive(Clone, Debug)]
pub(crate) struct ReplayBuffer {
    pub(crate) capacity: usize,
    pub(crate) obs_dim: usize,
    pub(crate) act_dim: usize,
    /// Transitions held (≤ capacity).
    pub(crate) len: usize,
    /// Where the next transition goes; wraps to 0 at capacity, overwriting the oldest.
    next: usize,
    /// Transitions ever pushed: transition k (from 0) sits in slot k mod capacity while it is held, which
    /// is what a checkpoint saves and restores (`store::checkpoint`), so a resumed run samples exactly
    /// what the uninterrupted one would.
    pub(crate) pushed: u64,
    obs: Vec<f32>,
    actions: Vec<f32>,
    rewards: Vec<f32>,
    next_obs: Vec<f32>,
}

/// Consecutive slots of a [`ReplayBuffer`] ([`ReplayBuffer::runs`]): their observations, actions and
/// rewards, row-major.
pub(crate) struct Run<'a> {
    pub(crate) obs: &'a [f32],
    pub(crate) actions: &'a [f32],
    pub(crate) rewards: &'a [f32],
}

/// A mini-batch, row-major.
#[derive(Clone, Debug, Default, PartialEq)]
pub(crate) struct Batch {
    pub(crate) n: usize,
    pub(crate) obs: Vec<f32>,
    pub(crate) actions: Vec<f32>,
    pub(crate) rewards: Vec<f32>,
    pub(crate) next_obs: Vec<f32>,
}

impl ReplayBuffer {
    /// An empty buffer; memory grows with use up to `capacity` transitions.
    pub(crate) fn new(capacity: usize, obs_dim: usize, act_dim: usize) -> Self {
        ReplayBuffer {
            capacity,
            obs_dim,
            act_dim,
            len: 0,
            next: 0,
            pushed: 0,
            obs: vec![],
            actions: vec![],
            rewards: vec![],
            next_obs: vec![],
        }
    }

    pub(crate) fn push(&mut self, obs: &[f32], action: &[f32], reward: f32, next_obs: &[f32]) {
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
        self.pushed += 1;
    }

    /// The oldest transition still held (its index among all ever pushed).
    pub(crate) fn first_held(&self) -> u64 {
        self.pushed - self.len as u64
    }

    /// Transition `k` (an index among all ever pushed, from [`ReplayBuffer::first_held`] on):
    /// (o, a, r, o').
    pub(crate) fn transition(&self, k: u64) -> (&[f32], &[f32], f32, &[f32]) {
        assert!(k >= self.first_held() && k < self.pushed, "transition {k} is not held");
        let (d, a, i) = (self.obs_dim, self.act_dim, (k % self.capacity as u64) as usize);
        (
            &self.obs[i * d..(i + 1) * d],
            &self.actions[i * a..(i + 1) * a],
            self.rewards[i],
            &self.next_obs[i * d..(i + 1) * d],
        )
    }

    /// Transitions `from..to` (indices among all ever pushed, all held) as runs of consecutive slots, in
    /// order: one run, or two where the ring wraps. What a checkpoint writes column by column, in bulk.
    pub(crate) fn runs(&self, from: u64, to: u64) -> impl Iterator<Item = Run<'_>> {
        assert!(from >= self.first_held() && from <= to && to <= self.pushed, "transitions {from}..{to} are not held");
        let (d, a, cap) = (self.obs_dim, self.act_dim, self.capacity as u64);
        let start = (from % cap) as usize;
        let first = ((to - from) as usize).min(self.capacity - start);
        let rest = (to - from) as usize - first;
        [(start, first), (0, rest)].into_iter().filter(|&(_, n)| n > 0).map(move |(i, n)| Run {
            obs: &self.obs[i * d..(i + n) * d],
            actions: &self.actions[i * a..(i + n) * a],
            rewards: &self.rewards[i..i + n],
        })
    }

    /// An empty frame of the buffer as it stood after `pushed` transitions: [`ReplayBuffer::put`] each
    /// transition it held (`first_held()..pushed`) back, and it samples exactly as the saved one did.
    pub(crate) fn restoring(capacity: usize, obs_dim: usize, act_dim: usize, pushed: u64) -> Self {
        let len = pushed.min(capacity as u64) as usize;
        ReplayBuffer {
            capacity,
            obs_dim,
            act_dim,
            len,
            next: (pushed % capacity as u64) as usize,
            pushed,
            obs: vec![0.0; len * obs_dim],
            actions: vec![0.0; len * act_dim],
            rewards: vec![0.0; len],
            next_obs: vec![0.0; len * obs_dim],
        }
    }

    /// Puts transition `k` back in its slot (see [`ReplayBuffer::restoring`]).
    pub(crate) fn put(&mut self, k: u64, obs: &[f32], action: &[f32], reward: f32, next_obs: &[f32]) {
        assert!(k >= self.first_held() && k < self.pushed, "transition {k} is not held");
        let (d, a, i) = (self.obs_dim, self.act_dim, (k % self.capacity as u64) as usize);
        self.obs[i * d..(i + 1) * d].copy_from_slice(obs);
        self.actions[i * a..(i + 1) * a].copy_from_slice(action);
        self.rewards[i] = reward;
        self.next_obs[i * d..(i + 1) * d].copy_from_slice(next_obs);
    }

    /// `n` transitions drawn uniformly (with replacement) from all held.
    #[cfg(test)]
    pub(crate) fn sample(&self, n: usize, rng: &mut ChaCha8Rng) -> Batch {
        let mut b = Batch::default();
        self.sample_into(&mut b, n, rng);
        b
    }

    /// `n` transitions drawn uniformly with replacement into `b`, whose buffers are reused.
    pub(crate) fn sample_into(&self, b: &mut Batch, n: usize, rng: &mut ChaCha8Rng) {
        assert!(self.len > 0, "sampling an empty replay buffer");
        self.fill(b, (0..n).map(|_| rng.gen_range(0..self.len)).collect::<Vec<_>>());
    }

    /// `n` distinct transitions drawn uniformly without replacement into `b` (the authors' buffer.py);
    /// `n` must not exceed what the buffer holds.
    pub(crate) fn sample_distinct_into(&self, b: &mut Batch, n: usize, rng: &mut ChaCha8Rng) {
        assert!(n <= self.len, "drawing {n} distinct transitions from {}", self.len);
        self.fill(b, rand::seq::index::sample(rng, self.len, n).into_vec());
    }

    /// `b` holds the transitions in `slots`, in that order.
    fn fill(&self, b: &mut Batch, slots: Vec<usize>) {
        let (d, a) = (self.obs_dim, self.act_dim);
        b.n = slots.len();
        b.obs.clear();
        b.actions.clear();
        b.rewards.clear();
        b.next_obs.clear();
        for i in slots {
            b.obs.extend_from_slice(&self.obs[i * d..(i + 1) * d]);
            b.actions.extend_from_slice(&self.actions[i * a..(i + 1) * a]);
            b.rewards.push(self.rewards[i]);
            b.next_obs.extend_from_slice(&self.next_obs[i * d..(i + 1) * d]);
        }
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

    #[test]
    fn runs_lay_out_the_transitions_in_order_also_across_the_wrap() {
        let mut buf = ReplayBuffer::new(5, 2, 1);
        for i in 0..13 {
            let x = i as f32;
            buf.push(&[x, -x], &[x / 2.0], x * 10.0, &[x + 1.0, -x - 1.0]);
        }
        // Held: transitions 8..13 in slots 3, 4, 0, 1, 2.
        for (from, to, pieces) in [(8, 13, 2), (8, 10, 1), (10, 13, 1), (9, 12, 2), (11, 11, 0)] {
            let runs: Vec<Run> = buf.runs(from, to).collect();
            assert_eq!(runs.len(), pieces, "{from}..{to}");
            let (mut obs, mut actions, mut rewards) = (vec![], vec![], vec![]);
            for r in &runs {
                obs.extend_from_slice(r.obs);
                actions.extend_from_slice(r.actions);
                rewards.extend_from_slice(r.rewards);
            }
            let (mut o, mut a, mut w) = (vec![], vec![], vec![]);
            for k in from..to {
                let t = buf.transition(k);
                o.extend_from_slice(t.0);
                a.extend_from_slice(t.1);
                w.push(t.2);
            }
            assert_eq!((obs, actions, rewards), (o, a, w), "{from}..{to}");
        }
    }

    #[test]
    fn a_restored_buffer_samples_as_the_saved_one() {
        for pushes in [3, 5, 8, 13] {
            let mut buf = ReplayBuffer::new(5, 2, 1);
            for i in 0..pushes {
                let x = i as f32;
                buf.push(&[x, -x], &[x / 2.0], x * 10.0, &[x + 1.0, -x - 1.0]);
            }
            let mut back = ReplayBuffer::restoring(5, 2, 1, buf.pushed);
            for k in buf.first_held()..buf.pushed {
                let (o, a, r, o2) = buf.transition(k);
                back.put(k, o, a, r, o2);
            }
            let (mut r1, mut r2) = (ChaCha8Rng::seed_from_u64(3), ChaCha8Rng::seed_from_u64(3));
            assert_eq!(buf.sample(64, &mut r1), back.sample(64, &mut r2), "after {pushes} pushes");
            // And both go on identically.
            buf.push(&[9.0, 9.0], &[9.0], 9.0, &[9.0, 9.0]);
            back.push(&[9.0, 9.0], &[9.0], 9.0, &[9.0, 9.0]);
            assert_eq!(buf.sample(64, &mut r1), back.sample(64, &mut r2), "after {pushes} + 1 pushes");
        }
    }
}
