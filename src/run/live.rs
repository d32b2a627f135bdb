//! A training run stepped by a caller other than `--train` (the viewer's live training), kept so that it
//! can be saved as a run folder: the `metrics.csv` rows, snapshots and checkpoint `--train` writes, saved at
//! an episode boundary, so that `--resume`, `--eval` and the viewer's watch mode take it, and a resumed run
//! continues exactly as the `--train` run of its scene and seed would have.

use crate::io::Existing;
use crate::learning::nets::Mlp;
use crate::learning::Learners;
use crate::sim::clock::Episode;
use crate::sim::metrics::EpisodeLog;
use crate::sim::species::SpeciesRegistry;
use crate::sim::ActiveScene;
use crate::store::folder::RunDir;
use crate::store::schema;
use bevy::prelude::{Resource, World};
use std::path::Path;
use std::time::Instant;

#[derive(Resource)]
pub struct LiveRun {
    /// `metrics.csv` as `--train` would have written it so far.
    metrics_text: String,
    /// Episodes recorded (the next row's episode).
    episodes: usize,
    /// Each learning species' actor at the episodes `--train` snapshots (kept until saved).
    snapshots: Vec<(String, usize, Mlp)>,
    started: Instant,
    /// Why the world is no longer the `--train` run of its scene and seed (its population was changed
    /// while it trained): such a run is not saved.
    pub altered: Option<String>,
    /// Snapshots already written into the folder the run is kept in ([`LiveRun::keep`]).
    snapshots_written: usize,
    /// The episode of the last checkpoint written there.
    checkpointed: usize,
}

impl LiveRun {
    /// The run of the world as it is now, before its first step.
    pub fn new(world: &World) -> LiveRun {
        let authors = world.resource::<crate::sim::ActiveScene>().0.authors_metrics;
        let header = schema::metrics_header(world.resource::<SpeciesRegistry>(), world.resource::<Learners>(), authors);
        let mut run = LiveRun {
            metrics_text: format!("{header}\n"),
            episodes: 0,
            snapshots: vec![],
            started: Instant::now(),
            altered: None,
            snapshots_written: 0,
            checkpointed: 0,
        };
        if world.resource::<ActiveScene>().0.learning.snapshot_every > 0 {
            run.snapshot(world, 0);
        }
        run
    }

    /// Episodes trained so far.
    pub fn episodes(&self) -> usize {
        self.episodes
    }

    /// The episode of the last checkpoint written into the folder the run is kept in.
    pub fn checkpointed(&self) -> usize {
        self.checkpointed
    }

    /// Keeps the run, saved into `dir` by [`LiveRun::save`], up to date there at an episode boundary, as
    /// `--train` writes its folder: every episode's `metrics.csv` row and snapshots, the checkpoint every
    /// `checkpoint_every` episodes. A window closed mid-training leaves what a `--train` killed there leaves:
    /// rows past the last checkpoint, which `--resume` drops and trains again.
    pub fn keep(&mut self, world: &World, dir: &Path) -> crate::error::Result<()> {
        let episode = world.resource::<Episode>();
        if episode.step != 0 || episode.index != self.episodes || self.episodes == self.checkpointed {
            return Ok(());
        }
        if let Some(why) = &self.altered {
            return Err(format!("{}: no longer kept: {why}", dir.display()).into());
        }
        if let Some(failure) = &world.resource::<Learners>().failure {
            return Err(format!("{}: no longer kept: training stopped: {failure}", dir.display()).into());
        }
        crate::sim::check_state(world).map_err(|e| format!("{}: no longer kept: {e}", dir.display()))?;
        let run = RunDir::new(dir);
        let scene = &world.resource::<ActiveScene>().0;
        let lock = run.lock()?;
        let every = scene.learning.checkpoint_every.max(1);
        let checkpoint = self.episodes.is_multiple_of(every) || self.episodes == scene.episodes;
        let written = self.write_since(world, &run, checkpoint);
        drop(lock);
        written
    }

    /// Into the run folder `run` (locked by the caller): the snapshots not written there yet, `metrics.csv`
    /// and, with `checkpoint`, the checkpoint, as `--train` writes them at an episode boundary. Snapshots
    /// first, then the rows: a row never stands for an episode whose snapshot is missing.
    fn write_since(&mut self, world: &World, run: &RunDir, checkpoint: bool) -> crate::error::Result<()> {
        let (dir, scene) = (run.path(), &world.resource::<ActiveScene>().0);
        for (name, episode, actor) in &self.snapshots[self.snapshots_written..] {
            crate::store::snapshots::save_snapshot(dir, scene, name, *episode, actor)?;
        }
        self.snapshots_written = self.snapshots.len();
        crate::io::write_file(&run.metrics(), Existing::Replace, self.metrics_text.as_bytes())?;
        if checkpoint {
            let metrics = crate::store::manifest::Digest::of(self.metrics_text.as_bytes());
            super::train::save_checkpoint(dir, world, scene, None, metrics)?;
            self.checkpointed = self.episodes;
        }
        Ok(())
    }

    fn snapshot(&mut self, world: &World, episode: usize) {
        let names = &world.resource::<SpeciesRegistry>().defs;
        for (l, def) in world.resource::<Learners>().species.iter().zip(names) {
            if let Some(l) = l.as_ref().filter(|l| !l.frozen) {
                self.snapshots.push((def.name.clone(), episode, l.ddpg.actor.clone()));
            }
        }
    }

    /// After a step: every episode that ended becomes its `metrics.csv` row (read from the episode log, not
    /// taken: the viewer's plots take them after), with the snapshots `--train` would write.
    pub fn record(world: &mut World) {
        world.resource_scope(|world, mut run: bevy::prelude::Mut<LiveRun>| {
            let ended: Vec<_> =
                world.resource::<EpisodeLog>().episodes.iter().filter(|e| e.episode >= run.episodes).cloned().collect();
            let scene = &world.resource::<ActiveScene>().0;
            let (every, total) = (scene.learning.snapshot_every, scene.episodes);
            for summary in ended {
                let registry = world.resource::<SpeciesRegistry>().clone();
                let wall = run.started.elapsed().as_secs_f64();
                let row = schema::metrics_row(&summary, &registry, &mut world.resource_mut::<Learners>(), wall);
                run.metrics_text.push_str(&row);
                run.metrics_text.push('\n');
                run.episodes = summary.episode + 1;
                if every > 0 && (run.episodes.is_multiple_of(every) || run.episodes == total) {
                    let episodes = run.episodes;
                    run.snapshot(world, episodes);
                }
            }
        });
    }

    /// Saves the run into a new folder `dir` (never over anything): `scene.ron`, `provenance.ron`,
    /// `metrics.csv`, the snapshots and the checkpoint, as `--train` leaves a run it was stopped in at
    /// this episode. Only at an episode boundary, and only a run whose population was never changed.
    pub fn save(&mut self, world: &World, dir: &Path) -> crate::error::Result<()> {
        if dir.as_os_str().is_empty() {
            return Err("not saved: name a folder to save the run into".into());
        }
        if let Some(why) = &self.altered {
            return Err(format!(
                "{}: not saved: {why}, so it is no longer the run of its scene and seed",
                dir.display()
            )
            .into());
        }
        // A run whose training failed or whose world faulted is not a run `--train` would have saved.
        if let Some(failure) = &world.resource::<Learners>().failure {
            return Err(format!("{}: not saved: training stopped: {failure}", dir.display()).into());
        }
        crate::sim::check_state(world).map_err(|e| format!("{}: not saved: {e}", dir.display()))?;
        let episode = world.resource::<Episode>();
        if episode.step != 0 || episode.index != self.episodes {
            return Err(format!("{}: not saved: runs are saved between episodes", dir.display()).into());
        }
        let run = RunDir::new(dir);
        run.check_new(false)?;
        let existed = dir.exists();
        let scene = &world.resource::<ActiveScene>().0;
        let lock = run.lock()?;
        let written = (|| -> crate::error::Result<()> {
            crate::io::write_file(&run.scene(), Existing::Replace, scene.to_ron().as_bytes())?;
            run.write_provenance(scene)?;
            self.snapshots_written = 0;
            self.write_since(world, &run, true)
        })();
        drop(lock);
        if written.is_err() {
            // Nothing half-written stays behind: the folder was new (removed again) or empty (emptied).
            let _ = run.clear();
            if !existed {
                let _ = std::fs::remove_dir(dir);
            }
        }
        written
    }
}
