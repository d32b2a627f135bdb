//! What the viewer's stages share: what runs ([`Setup`], [`RunMode`]), what the panel asked for
//! ([`Control`]), the pace ([`Playback`]), and what the pickers offer (scene files, run folders).

use crate::learning::{Learners, Mode};
use crate::scene::{Policy, Scene};
use crate::sim::species::SpeciesRegistry;
use bevy::prelude::*;
use std::path::PathBuf;

/// How the world's species are driven.
#[derive(Clone, Debug, PartialEq)]
pub enum RunMode {
    /// The scene as written: its learned species train while you watch (as `--train` would, step for
    /// step).
    LiveTraining,
    /// The actors of a run folder (`runs/<name>/checkpoint/`), deployed without noise or updates.
    Watch(PathBuf),
    /// Learned species replaced by the paper's rule-based behaviours: a species that catches chases, a
    /// species that is caught flees, any other moves at random.
    RuleBased,
}

impl RunMode {
    pub(crate) fn label(&self) -> String {
        match self {
            RunMode::LiveTraining => "live training".into(),
            RunMode::Watch(run) => format!("watching {}", run.display()),
            RunMode::RuleBased => "rule-based".into(),
        }
    }
}

/// What the viewer runs: a scene (named by the file it came from) in a mode.
#[derive(Clone, Debug)]
pub struct Setup {
    pub scene: Scene,
    pub source: PathBuf,
    pub mode: RunMode,
    /// In watch mode, these species' snapshots (`NAME`, episodes) instead of their trained actors.
    pub snapshots: Vec<(String, usize)>,
}

impl Setup {
    /// The scene as this mode runs it and the learners it needs. An error (a checkpoint that is missing or
    /// does not fit the scene) changes nothing.
    pub fn prepare(&self) -> crate::error::Result<(Scene, Learners)> {
        let mut scene = self.scene.clone();
        if self.mode == RunMode::RuleBased {
            let registry = SpeciesRegistry::from_scene(&scene);
            for (s, def) in scene.species.iter_mut().enumerate() {
                if matches!(def.policy, Policy::Learned | Policy::Frozen(_)) {
                    def.policy = if registry.prey_of(s).next().is_some() {
                        Policy::ChaseNearest
                    } else if registry.predators_of(s).next().is_some() {
                        Policy::FleeInside
                    } else {
                        Policy::Random
                    };
                }
            }
        }
        scene.validate().map_err(|e| e.in_file(&self.source))?;
        // The viewer registers no plugin policies of its own.
        crate::sim::policy::PolicyPlugins::default()
            .check(&scene)
            .map_err(|e| format!("{}: {e}", self.source.display()))?;
        let (mode, run) = match &self.mode {
            RunMode::Watch(run) => (Mode::Evaluate, Some(run.as_path())),
            _ => (Mode::Train, None),
        };
        let mut learners = Learners::new(&scene, mode);
        crate::store::load_actors(&mut learners, &scene, run).map_err(|e| format!("checkpoint refused: {e}"))?;
        if let Some(run) = run {
            crate::store::load_snapshots(&mut learners, &scene, run, &self.snapshots)
                .map_err(|e| format!("snapshot refused: {e}"))?;
        }
        Ok((scene, learners))
    }
}

/// Play, pause and pace.
#[derive(Resource, Clone, Debug)]
pub struct Playback {
    pub(crate) playing: bool,
    /// Fixed steps per rendered frame.
    pub(crate) steps_per_frame: usize,
    /// Step for `FAST_FRAME_BUDGET` per frame instead (live training at full speed, still drawn).
    pub(crate) as_fast_as_possible: bool,
    /// One step on the next frame, even when paused.
    pub(crate) step_once: bool,
    /// Steps per second of wall-clock time, measured over the last frames.
    pub(crate) steps_per_second: f64,
    pub(crate) total_steps: u64,
}

/// What runs now and what the panel asked for.
#[derive(Resource, Clone, Debug)]
pub struct Control {
    pub(crate) current: Setup,
    /// Applied at the start of the next frame (a restart with new learners).
    pub(crate) restart: Option<Setup>,
    /// New counts per species: respawn now, keep the learners (the networks do not depend on counts).
    pub(crate) respawn: Option<Vec<usize>>,
    /// The last thing that could not be done, shown in the panel until the next success.
    pub(crate) error: Option<String>,
    /// Live training: the folder the panel offers to save the run into, and the save asked for, done when
    /// the current episode ends (a run is saved between episodes, as `--train` checkpoints it).
    pub(crate) save_folder: String,
    pub(crate) save_pending: Option<PathBuf>,
    /// `--save-run`: the folder the whole live run is kept in. Once the first save has made it, every
    /// episode's metrics row, snapshot and checkpoint go there as `--train` writes them, until the window
    /// closes or the world restarts.
    pub(crate) keep_in: Option<PathBuf>,
    /// Set when the first save into `keep_in` succeeded.
    pub(crate) keeping: bool,
    /// What was last saved, shown in the panel.
    pub(crate) notice: Option<String>,
}

/// The folder the panel offers for saving a live run of `setup`: `runs/live-<scene>-seed<seed>`.
pub(super) fn save_folder(setup: &Setup) -> String {
    let stem = setup.source.file_stem().map_or("scene".into(), |s| s.to_string_lossy().into_owned());
    format!("runs/live-{stem}-seed{}", setup.scene.seed)
}

/// The scene files a picker offers: `scenes/*.ron`, sorted.
pub fn scene_files() -> Vec<PathBuf> {
    list_dir("scenes", |p| p.extension().is_some_and(|e| e == "ron"))
}

/// The run folders a picker offers: the shipped run first, then `runs/*/` holding a `checkpoint/`, sorted.
pub fn run_folders() -> Vec<PathBuf> {
    let is_run = |p: &std::path::Path| crate::store::RunDir::new(p).has_actors();
    let mut runs: Vec<PathBuf> = crate::store::SHIPPED_RUNS.iter().map(PathBuf::from).filter(|p| is_run(p)).collect();
    runs.extend(list_dir("runs", is_run));
    runs
}

fn list_dir(dir: &str, keep: impl Fn(&std::path::Path) -> bool) -> Vec<PathBuf> {
    let mut out: Vec<PathBuf> = std::fs::read_dir(dir)
        .map(|rd| rd.filter_map(|e| e.ok().map(|e| e.path())).filter(|p| keep(p)).collect())
        .unwrap_or_default();
    out.sort();
    out
}
