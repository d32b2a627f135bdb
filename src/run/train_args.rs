//! The flags of `--train` and `--resume` and the options they make ([`TrainOptions`]), which programs and
//! the experiment runner build directly too; the training itself is [`super::train`].

use super::args::Shared;
use crate::scene::Scene;
use std::path::{Path, PathBuf};

/// How a training begins: a new run of a scene, or the run already in the folder continued from its last
/// checkpoint with its own `scene.ron`. One type, so a resumed run cannot be handed a scene, nor a new run
/// be started without one.
#[derive(Clone, Debug)]
pub enum Start {
    New(Box<Scene>),
    Resume,
}

/// A training as a command line says it ([`TrainOptions::to_argv`]): a new run of a scene file with a
/// seed, or a resume.
#[derive(Clone, Copy, Debug)]
pub enum StartArgs<'a> {
    New { scene: &'a Path, seed: u64 },
    Resume,
}

#[derive(Clone, Debug, PartialEq)]
pub struct TrainOptions {
    pub run: PathBuf,
    /// Replace the run already in `run` (its own files only) instead of refusing; a new run's only.
    pub overwrite: bool,
    /// Total episodes of the run (the scene's `episodes` when None).
    pub episodes: Option<usize>,
    pub progress: bool,
}

impl TrainOptions {
    /// A new run of `episodes` episodes (the scene's when None) into `run`, quietly: what programs and
    /// tests train with.
    pub fn new(run: impl Into<PathBuf>, episodes: Option<usize>) -> TrainOptions {
        TrainOptions { run: run.into(), overwrite: false, episodes, progress: false }
    }

    /// The call that begins as `start` says (a scene file with a seed, or a resume of `run`) with these
    /// options, as argv.
    pub(crate) fn to_argv(&self, start: StartArgs) -> Vec<String> {
        let mut argv: Vec<String> = match start {
            StartArgs::Resume => vec!["--resume".into(), self.run.display().to_string()],
            StartArgs::New { scene, seed } => {
                let mut argv = vec!["--train".into(), "--scene".into(), scene.display().to_string()];
                argv.extend(["--seed".into(), seed.to_string(), "--out".into(), self.run.display().to_string()]);
                argv
            }
        };
        if let Some(n) = self.episodes {
            argv.extend(["--episodes".into(), n.to_string()]);
        }
        // Only a new run replaces a folder; a resume continues the one there.
        if self.overwrite && matches!(start, StartArgs::New { .. }) {
            argv.push("--overwrite".into());
        }
        if !self.progress {
            argv.push("--quiet".into());
        }
        argv
    }
}

/// `--train`: a new run of a scene.
#[derive(clap::Args, Debug, Clone, Default)]
pub struct TrainArgs {
    /// Train the scene's learning species headless (Algorithm 1) into --out.
    #[arg(long, help_heading = "Modes")]
    pub(crate) train: bool,
    /// Run folder for --train (default runs/<scene>-seed<seed>); must be new or empty.
    #[arg(long, help_heading = "Running", value_name = "DIR")]
    pub(crate) out: Option<PathBuf>,
}

impl super::args::Mode for TrainArgs {
    const MODE: &'static str = "train";
    const TAKES: &'static [&'static str] = &["scene", "seed", "episodes", "overwrite", "quiet"];
}

/// `--resume RUN`: a killed or finished run continued.
#[derive(clap::Args, Debug, Clone, Default)]
pub struct ResumeArgs {
    /// Continue a killed or finished run from its last checkpoint (to --episodes in total).
    #[arg(long, help_heading = "Modes", value_name = "DIR")]
    pub(crate) resume: Option<PathBuf>,
}

impl super::args::Mode for ResumeArgs {
    const MODE: &'static str = "resume";
    const TAKES: &'static [&'static str] = &["episodes", "quiet"];
}

impl TrainArgs {
    /// The scene to train (--scene with --seed) and the options.
    pub(crate) fn options(&self, shared: &Shared) -> crate::error::Result<(Scene, TrainOptions)> {
        let (args, common) = (&shared.scene, &shared.common);
        let (scene, path) = args.load(Path::new(super::args::STANDARD_SCENE), &args.overrides(false)?)?;
        let stem = path.file_stem().map_or("run".into(), |s| s.to_string_lossy().into_owned());
        let run = self.out.clone().unwrap_or_else(|| PathBuf::from(format!("runs/{stem}-seed{}", scene.seed)));
        Ok((
            scene,
            TrainOptions { run, overwrite: common.overwrite, episodes: common.episodes, progress: !common.quiet },
        ))
    }
}

impl ResumeArgs {
    /// The options of continuing the run `run` (which trains its own scene, [`super::train::resume`]).
    pub(crate) fn options(&self, run: &Path, shared: &Shared) -> TrainOptions {
        let common = &shared.common;
        TrainOptions { run: run.to_path_buf(), overwrite: false, episodes: common.episodes, progress: !common.quiet }
    }
}
