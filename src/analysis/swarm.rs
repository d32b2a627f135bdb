//! The swarm as data: a run's actors deployed without noise (as `--eval` deploys them), its rule-driven
//! species following their rules, and every agent's observation with the action it took on it, step by
//! step, for the species asked for. What `--distill` fits its rules to and `--response` reads its realistic
//! backgrounds from.

use crate::learning::Mode;
use crate::scene::Scene;
use crate::sim::perception::Batches;
use crate::sim::species::{SpeciesRegistry, ACTION_DIM};
use std::path::Path;

/// Observations of one species and the actions it took on them, row by row.
pub(crate) struct Recorded {
    pub(crate) dim: usize,
    /// Per episode, where its rows begin.
    pub(crate) episode_starts: Vec<usize>,
    pub(crate) observations: Vec<f32>,
    pub(crate) actions: Vec<f32>,
    /// Per row, the agent-episode it belongs to (episode × agents + the agent's slot): one agent's rows in
    /// one episode depend on each other, so resampling takes them together.
    pub(crate) clusters: Vec<usize>,
}

impl Recorded {
    /// The rows before episode `episode` and from it on, each as (observations, actions, clusters).
    pub(crate) fn split(&self, episode: usize) -> [(&[f32], &[f32], &[usize]); 2] {
        let row = self.episode_starts.get(episode).copied().unwrap_or(self.actions.len() / ACTION_DIM);
        let (o, a) = (self.observations.split_at(row * self.dim), self.actions.split_at(row * ACTION_DIM));
        let c = self.clusters.split_at(row);
        [(o.0, a.0, c.0), (o.1, a.1, c.1)]
    }
}

/// Which species of `scene` act by an actor a run holds (learned or frozen: those `Learners::new` makes a
/// learner for), read off their policies rather than by making the learners.
pub(crate) fn with_actors(scene: &Scene) -> Vec<bool> {
    use crate::scene::Policy;
    scene.species.iter().map(|d| matches!(d.policy, Policy::Learned | Policy::Frozen(_))).collect()
}

/// Deploys `run`'s actors on `scene` without noise for `episodes` episodes (the other species following
/// their policies) and keeps, per species `kept` names (None for the others), each agent's observation and
/// the action it took on it, every `every` steps.
pub(crate) fn record(
    scene: &Scene,
    run: &Path,
    episodes: usize,
    every: usize,
    kept: &[bool],
) -> crate::error::Result<Vec<Option<Recorded>>> {
    let mut learners = crate::learning::Learners::new(scene, Mode::Evaluate);
    crate::store::load_actors(&mut learners, scene, Some(run))?;
    let mut sim = crate::learning::simulation_of(scene.clone(), learners, |_| {})?;
    let registry = SpeciesRegistry::from_scene(scene);
    let mut recorded: Vec<Option<Recorded>> = (0..registry.len())
        .map(|s| {
            kept.get(s).copied().unwrap_or(false).then(|| Recorded {
                dim: registry.observation_dim(s),
                episode_starts: vec![],
                observations: vec![],
                actions: vec![],
                clusters: vec![],
            })
        })
        .collect();
    let bar = crate::run::step_bar(scene, episodes * scene.episode_steps);
    for episode in 0..episodes {
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
                    r.clusters.extend((0..b.n).map(|slot| episode * b.n + slot));
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
