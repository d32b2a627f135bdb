//! What `--record` and `--animate` show: a scene whose learned species act exactly as in `--eval` (trained
//! actors, no noise), from a run (`--run`) or freshly initialised.

use super::args::SceneArgs;
use crate::learning::Mode;
use crate::scene::Policy;
use crate::sim::Simulation;
use std::path::{Path, PathBuf};

/// `--run DIR`, shared by --record and --animate.
#[derive(clap::Args, Debug, Clone, Default)]
pub(crate) struct DeployArgs {
    /// --record, --animate: the run whose trained actors drive the scene's learned species (default: the
    /// seed's freshly initialized actors); its scene.ron is the scene unless --scene is given.
    #[arg(long, help_heading = "Recording and animation", value_name = "DIR")]
    pub(crate) run: Option<PathBuf>,
}

/// The deployed simulation, the steps to run and a note saying which actors drive it.
pub(crate) struct Deployed {
    pub(crate) sim: Simulation,
    pub(crate) steps: usize,
    pub(crate) actors: String,
}

impl DeployArgs {
    /// The scene of --run (or --scene) with the counts applied and --steps as one episode, every species
    /// acting exactly as in --eval.
    pub(crate) fn deploy(&self, scene: &SceneArgs) -> crate::error::Result<Deployed> {
        if let Some(run) = &self.run {
            crate::store::folder::RunDir::new(run).check_plugins()?;
        }
        let default = self
            .run
            .as_ref()
            .map_or(PathBuf::from(super::args::STANDARD_SCENE), |r| r.join(crate::store::folder::SCENE));
        let (mut loaded, _) = scene.load(&default, &scene.overrides(false)?)?;
        let steps = scene.steps.unwrap_or(loaded.episode_steps);
        loaded.episode_steps = steps;
        super::progress::announce_cost(&loaded, steps)?;
        let wanted = scene.snapshots(self.run.as_deref(), "--run")?;
        let mut learners = crate::learning::Learners::new(&loaded, Mode::Evaluate);
        crate::store::load_actors(&mut learners, &loaded, self.run.as_deref())?;
        if let Some(run) = &self.run {
            crate::store::load_snapshots(&mut learners, &loaded, run, &wanted)?;
        }
        let sim = crate::learning::simulation_of(loaded.clone(), learners, |_| {})?;
        let actors: Vec<String> = loaded
            .species
            .iter()
            .filter_map(|def| match (&def.policy, &self.run) {
                (Policy::Learned, Some(run)) => Some(match wanted.iter().find(|(s, _)| s == &def.name) {
                    Some((_, e)) => format!("{}: snapshot after {e} episodes of {}", def.name, run.display()),
                    None => format!("{}: trained actor of {}", def.name, run.display()),
                }),
                (Policy::Learned, None) => Some(format!(
                    "{}: freshly initialized actor of seed {} (untrained: no --run given)",
                    def.name, loaded.seed
                )),
                (Policy::Frozen(path), _) => Some(format!("{}: trained actor of {path}", def.name)),
                _ => None,
            })
            .collect();
        let actors = if actors.is_empty() { String::new() } else { format!(" ({})", actors.join("; ")) };
        Ok(Deployed { sim, steps, actors })
    }

    /// What the clip or record shows, for a caption: the run, else the scene file.
    pub(crate) fn title(&self, scene: &SceneArgs) -> String {
        match (&self.run, &scene.scene) {
            (Some(run), _) => format!("trained run {}", run.display()),
            (None, Some(scene)) => scene.display().to_string(),
            (None, None) => Path::new(super::args::STANDARD_SCENE).display().to_string(),
        }
    }
}
