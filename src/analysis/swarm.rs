//! The trained swarm as data: a run's actors deployed without noise (as `--eval` deploys them), and every
//! learned agent's observation with the action its actor took on it, step by step. What `--distill` fits
//! its rules to and `--response` reads its realistic backgrounds from.

use crate::learning::Mode;
use crate::scene::Scene;
use crate::sim::perception::Batches;
use crate::sim::species::{SpeciesRegistry, ACTION_DIM};
use std::path::Path;

/// Observations of one learned species and the actions its actor took on them, row by row.
pub(crate) struct Recorded {
    pub(crate) dim: usize,
    /// Per episode, where its rows begin.
    pub(crate) episode_starts: Vec<usize>,
    pub(crate) observations: Vec<f32>,
    pub(crate) actions: Vec<f32>,
}

impl Recorded {
    /// The rows before episode `episode` and from it on, each as (observations, actions).
    pub(crate) fn split(&self, episode: usize) -> [(&[f32], &[f32]); 2] {
        let row = self.episode_starts.get(episode).copied().unwrap_or(self.actions.len() / ACTION_DIM);
        let (o, a) = (self.observations.split_at(row * self.dim), self.actions.split_at(row * ACTION_DIM));
        [(o.0, a.0), (o.1, a.1)]
    }
}

/// Deploys `run`'s actors on `scene` without noise for `episodes` episodes and keeps, per learned species
/// (None for the others), each agent's observation and the action it took on it, every `every` steps.
pub(crate) fn record(
    scene: &Scene,
    run: &Path,
    episodes: usize,
    every: usize,
) -> crate::error::Result<Vec<Option<Recorded>>> {
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
            // The observations the step decides on, then the actions it decided.
            let kept = step % every.max(1) == 0;
            if kept {
                let batches = &sim.world().resource::<Batches>().species;
                for (r, b) in recorded.iter_mut().zip(batches).filter_map(|(r, b)| Some((r.as_mut()?, b))) {
                    r.observations.extend_from_slice(&b.observations[..b.n * r.dim]);
                }
            }
            sim.step();
            sim.check()?;
            bar.inc(1);
            if kept {
                let batches = &sim.world().resource::<Batches>().species;
                for (r, b) in recorded.iter_mut().zip(batches).filter_map(|(r, b)| Some((r.as_mut()?, b))) {
                    r.actions.extend_from_slice(&b.actions[..b.n * ACTION_DIM]);
                }
            }
        }
    }
    Ok(recorded)
}
