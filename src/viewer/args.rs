//! The viewer's flags (the call without a mode flag). They are parsed in every build, so a build without
//! the window refuses them with a hint instead of an unknown-flag error.

#[cfg(not(feature = "viewer"))]
use crate::run::{animate::AnimateArgs, args::Shared};
use std::path::PathBuf;

/// The viewer's own flags; it also takes the scene flags, --overwrite, --snapshot, and --animate's
/// --trails and --steps-per-frame.
#[derive(clap::Args, Debug, Clone, Default)]
pub(crate) struct ViewerArgs {
    /// Viewer: watch a run's trained actors (its scene.ron, with --prey/--predators/--count applied).
    #[arg(long, help_heading = "Viewer", value_name = "DIR")]
    pub(crate) watch: Option<PathBuf>,
    /// Viewer: replace learned species by the paper's rule-based chase and flee.
    #[arg(long, help_heading = "Viewer")]
    pub(crate) rules: bool,
    /// Viewer: render --frames frames, save a PNG here and exit.
    #[arg(long, help_heading = "Viewer", value_name = "PATH.png")]
    pub(crate) screenshot: Option<PathBuf>,
    /// Viewer, live training: save the run into this new folder when its current episode ends (what the
    /// panel's "Save this run" does), then keep it there as it trains, as --train writes a run (every
    /// episode's row and snapshots, a checkpoint every checkpoint_every episodes): a run folder that
    /// --resume, --eval and --watch take.
    #[arg(long, help_heading = "Viewer", value_name = "DIR")]
    pub(crate) save_run: Option<PathBuf>,
    /// Viewer: frames to render before --screenshot [default: 60].
    #[arg(long, help_heading = "Viewer", value_name = "N", value_parser = crate::run::args::at_least_one)]
    pub(crate) frames: Option<usize>,
    /// Viewer: window size in pixels, at least 1280x720 [default: 1280x720].
    #[arg(long, help_heading = "Viewer", value_name = "WxH")]
    pub(crate) window: Option<String>,
    /// Viewer: step as fast as possible, still drawing every frame (the default of live training unless
    /// --steps-per-frame or --paused is given; the panel switches it off for real-time watching).
    #[arg(long, help_heading = "Viewer")]
    pub(crate) fast: bool,
    /// Viewer: start paused.
    #[arg(long, help_heading = "Viewer")]
    pub(crate) paused: bool,
    /// Viewer: select the agent with this id (its perception radius, neighbours and observation).
    #[arg(long, help_heading = "Viewer", value_name = "ID")]
    pub(crate) select: Option<u32>,
    /// Viewer, with --select: show the selected agent's rule from the start: how it would turn with one
    /// more agent of SPECIES at each place around it, amid what it sees now (the panel's "its rule").
    #[arg(long, help_heading = "Viewer", value_name = "SPECIES")]
    pub(crate) rule_of: Option<String>,
}

impl crate::run::args::Mode for ViewerArgs {
    const MODE: &'static str = "";
    const TAKES: &'static [&'static str] =
        &["scene", "seed", "prey", "predators", "count", "overwrite", "snapshot", "trails", "steps_per_frame"];
}

/// Without the window: the hint. (With it, `ViewerArgs::main` is in `viewer/mod.rs`, beside the app.)
#[cfg(not(feature = "viewer"))]
impl ViewerArgs {
    pub(crate) fn main(&self, _: &AnimateArgs, _: &Shared) -> crate::error::Result<()> {
        Err("choose a mode: --train, --eval RUN, --record OUT.csv or --bench (see --help); the window needs `--features viewer`".into())
    }
}
