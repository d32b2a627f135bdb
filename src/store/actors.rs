//! Trained actors into a simulation's learners: a `Frozen(path)` species' actor, a run's learned actors,
//! or a run's snapshots, each file checked as a checkpoint is.

use crate::learning::Learners;
use crate::scene::{Policy, Scene};
use std::path::{Path, PathBuf};

/// Loads trained actors: every `Frozen(path)` species from its folder and, with `run`, every `Learned`
/// species from that run. Fails, changing nothing, when a checkpoint is missing or does not fit the
/// scene (observation size, hidden width, species name).
pub fn load_actors(learners: &mut Learners, scene: &Scene, run: Option<&Path>) -> crate::error::Result<()> {
    let mut loaded = Vec::new();
    for (s, def) in scene.species.iter().enumerate() {
        let source = match (&def.policy, run) {
            (Policy::Frozen(path), _) => PathBuf::from(path),
            (Policy::Learned, Some(run)) => run.to_path_buf(),
            _ => continue,
        };
        let l = learners.species[s].as_ref().expect("learned and frozen species have learners");
        loaded.push((s, super::checkpoint::load_actor(&source, &def.name, &l.ddpg.actor)?));
    }
    for (s, actor) in loaded {
        learners.species[s].as_mut().expect("checked above").ddpg.actor = actor;
    }
    Ok(())
}

/// Replaces the actors of the named learning species by their snapshots of `run` after the given
/// episodes (`--snapshot prey=300`; cross-play deploys the same files). Fails, changing nothing, on a
/// species that is not learned in the scene or an episode the run kept no snapshot of.
pub(crate) fn load_snapshots(
    learners: &mut Learners,
    scene: &Scene,
    run: &Path,
    wanted: &[(String, usize)],
) -> crate::error::Result<()> {
    let mut loaded = Vec::new();
    for (name, episode) in wanted {
        let s = scene.species.iter().position(|d| &d.name == name && d.policy == Policy::Learned).ok_or_else(|| {
            let learned: Vec<&str> =
                scene.species.iter().filter(|d| d.policy == Policy::Learned).map(|d| d.name.as_str()).collect();
            format!("--snapshot {name}={episode}: no learning species named {name:?} (learned: {})", learned.join(", "))
        })?;
        let like = &learners.species[s].as_ref().expect("learned species have learners").ddpg.actor;
        loaded.push((s, super::snapshots::load_snapshot(run, name, *episode, like)?));
    }
    for (s, actor) in loaded {
        learners.species[s].as_mut().expect("checked above").ddpg.actor = actor;
    }
    Ok(())
}
