//! The flags of `--train` and `--resume` and the options they make ([`TrainOptions`]), which programs and
//! the experiment runner build directly too; the training itself is [`super::train`].

use super::args::Shared;
use crate::scene::Scene;
use std::path::{Path, PathBuf};

#[derive(Clone, Debug, PartialEq)]
pub struct TrainOptions {
    pub run: PathBuf,
    pub resume: bool,
    /// Replace the run already in `run` (its own files only) instead of refusing.
    pub overwrite: bool,
    /// Total episodes of the run (the scene's `episodes` when None).
    pub episodes: Option<usize>,
    pub progress: bool,
}

impl TrainOptions {
    /// A new run of `episodes` episodes (the scene's when None) into `run`, quietly: what programs and
    /// tests train with.
    pub fn new(run: impl Into<PathBuf>, episodes: Option<usize>) -> TrainOptions {
        TrainOptions { run: run.into(), resume: false, overwrite: false, episodes, progress: false }
    }

    /// The call that trains `scene` (a file) with `seed` as these options say, or resumes `run`, as argv.
    pub(crate) fn to_argv(&self, scene: &Path, seed: u64) -> Vec<String> {
        let mut argv: Vec<String> = if self.resume {
            vec!["--resume".into(), self.run.display().to_string()]
        } else {
            let mut argv = vec!["--train".into(), "--scene".into(), scene.display().to_string()];
            argv.extend(["--seed".into(), seed.to_string(), "--out".into(), self.run.display().to_string()]);
            argv
        };
        if let Some(n) = self.episodes {
            argv.extend(["--episodes".into(), n.to_string()]);
        }
        if self.overwrite {
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
            TrainOptions {
                run,
                resume: false,
                overwrite: common.overwrite,
                episodes: common.episodes,
                progress: !common.quiet,
            },
        ))
    }
}

impl ResumeArgs {
    /// The options of continuing the run `run` (which trains its own scene, [`super::train::resume`]).
    pub(crate) fn options(&self, run: &Path, shared: &Shared) -> TrainOptions {
        let common = &shared.common;
        TrainOptions {
            run: run.to_path_buf(),
            resume: true,
            overwrite: false,
            episodes: common.episodes,
            progress: !common.quiet,
        }
    }
}
