//! The trained swarm as data: a run's actors deployed without noise (as `--eval` deploys them), and every
//! learned agent's observation with the action its actor took on it, step by step. What `--distill` fits
//! its rules to and `--response` reads its realistic backgrounds from.

use crate::learning::Mode;
use crate::scene::Scene;
use crate::sim::perception::Batches;
use crate::sim::species::{SpeciesRegistry, ACTION_DIM};
use std::path::Path;

/// Observations of one learned species and the actions its actor took on them, row by row.
pub struct Recorded {
    pub dim: usize,
    /// Per episode, where its rows begin.
    pub episode_starts: Vec<usize>,
    pub observations: Vec<f32>,
    pub actions: Vec<f32>,
}

impl Recorded {
    /// Rows from episode `from` on (to the end) or before it, as (observations, actions).
    pub fn episodes(&self, from: usize, after: bool) -> (&[f32], &[f32]) {
        let row = self.episode_starts.get(from).copied().unwrap_or(self.actions.len() / ACTION_DIM);
        let (o, a) = (row * self.dim, row * ACTION_DIM);
        match after {
            true => (&self.observations[o..], &self.actions[a..]),
            false => (&self.observations[..o], &self.actions[..a]),
        }
    }
}

/// Deploys `run`'s actors on `scene` without noise for `episodes` episodes and keeps, per learned species
/// (None for the others), each agent's observation and the action it took on it, every `every` steps.
pub fn record(scene: &Scene, run: &Path, episodes: usize, every: usize) -> crate::error::Result<Vec<Option<Recorded>>> {
    let mut learners = crate::learning::Learners::new(scene, Mode::Evaluate);
    learners.load_actors(scene, Some(run))?;
    let learned: Vec<bool> = learners.species.iter().map(|l| l.is_some()).collect();
    let mut sim = crate::learning::simulation_of(scene.clone(), learners, |_| {})?;
    let registry = SpeciesRegistry::from_scene(scene);
    let mut recorded: Vec<Option<Recorded>> = (0..registry.len())
        .map(|s| {
            learned[s].then(|| Recorded {
                dim: registry.observation_dim(s),
                episode_starts: vec![],
                observations: vec![],
                actions: vec![],
            })
        })
        .collect();
    let bar = crate::run::step_bar(scene, episodes * scene.episode_steps);
    for _ in 0..episodes {
        for r in recorded.iter_mut().flatten() {
            r.episode_starts.push(r.actions.len() / ACTION_DIM);
        }
        for step in 0..scene.episode_steps {
            let kept = step % every.max(1) == 0;
            let before: Vec<Vec<f32>> = match kept {
                true => sim.world().resource::<Batches>().species.iter().map(|b| b.observations.clone()).collect(),
                false => vec![],
            };
            sim.step();
            sim.check()?;
            bar.inc(1);
            if !kept {
                continue;
            }
            let batches = sim.world().resource::<Batches>();
            for (s, r) in recorded.iter_mut().enumerate() {
                let Some(r) = r else { continue };
                let n = batches.species[s].n;
                r.observations.extend_from_slice(&before[s][..n * r.dim]);
                r.actions.extend_from_slice(&batches.species[s].actions[..n * ACTION_DIM]);
            }
        }
    }
    Ok(recorded)
}
