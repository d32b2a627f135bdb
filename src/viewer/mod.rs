//! The viewer (`cargo run --release --features viewer`): the headless simulation's own world and
//! fixed-step schedule, drawn with Bevy's 2-D renderer and steered from an egui panel. Nothing here
//! simulates; it only decides when `FixedUpdate` runs and shows what it did.
//!
//! A frame, top to bottom (the [`ViewerSet`]s, chained in `Update`):
//!
//! | set       | what happens                                                                | file         |
//! |-----------|-----------------------------------------------------------------------------|--------------|
//! | `Control` | what the panel asked for last frame: load a scene or run, reset, respawn    | `mod.rs`     |
//! | `Step`    | `FixedUpdate` steps-per-frame times (or for a time budget); plots and trails | `mod.rs`     |
//! | `Draw`    | new agents get bodies; bodies follow the agents; periodic ghosts; overlays  | `draw.rs`    |
//!
//! then, in `EguiPrimaryContextPass`, the control panel, the inspector and the plots (`panel.rs`,
//! `plots.rs`), and last the screenshot keys (`capture.rs`).
//!
//! Bevy's own fixed-step loop is told not to run `FixedUpdate`: the viewer steps it itself, so the pace is
//! steps per frame, not wall-clock time, and every step is exactly a headless step (same seed, same run).

// Bevy systems take what they read and write as arguments, and their queries spell out component
// tuples: both lints flag the ordinary shape of a system.
#![allow(clippy::too_many_arguments, clippy::type_complexity)]

pub(crate) mod args;
mod capture;
mod draw;
mod panel;
mod plots;
pub(crate) mod schedule;
pub(crate) mod setup;

use crate::learning::{Learners, LearningPlugin, Mode};
use crate::run::live::LiveRun;
use crate::sim::species::SpeciesRegistry;
use crate::sim::{ActiveScene, SimulationPlugin};
use bevy::app::FixedMainScheduleOrder;
use bevy::ecs::schedule::ScheduleLabel;
use bevy::log::LogPlugin;
use bevy::prelude::*;
use bevy::window::WindowResolution;
use bevy_egui::EguiPlugin;
use std::path::PathBuf;
use std::time::{Duration, Instant};

pub(crate) use capture::ScreenshotRequest;
pub(crate) use schedule::ViewerSet;
pub use setup::{run_folders, scene_files, Control, Playback, RunMode, Setup};

/// Command-line options of the viewer.
#[derive(Clone, Debug)]
pub(crate) struct ViewerOptions {
    pub(crate) setup: Setup,
    pub(crate) window: UVec2,
    pub(crate) steps_per_frame: usize,
    pub(crate) paused: bool,
    /// Start in "as fast as possible".
    pub(crate) fast: bool,
    pub(crate) trails: bool,
    /// The agent selected at start, by id.
    pub(crate) select: Option<u32>,
    /// Show the selected agent's rule against this species (its index) from the start.
    pub(crate) rule_of: Option<usize>,
    /// Render this many frames, save a PNG and exit.
    pub(crate) screenshot: Option<ScreenshotRequest>,
    /// Live training: save the run into this folder when the current episode ends.
    pub(crate) save_run: Option<PathBuf>,
}

/// Wall-clock time spent stepping per frame in "as fast as possible": the rest of the frame draws.
const FAST_FRAME_BUDGET: Duration = Duration::from_millis(40);

pub(crate) struct ViewerPlugin {
    pub(crate) options: ViewerOptions,
}

impl Plugin for ViewerPlugin {
    fn build(&self, app: &mut App) {
        let o = &self.options;
        // The viewer paces FixedUpdate itself (`step`), so Bevy's wall-clock fixed loop must not run it.
        app.world_mut().resource_mut::<FixedMainScheduleOrder>().labels.retain(|l| *l != FixedUpdate.intern());
        app.insert_resource(Playback {
            playing: !o.paused,
            steps_per_frame: o.steps_per_frame.max(1),
            as_fast_as_possible: o.fast,
            step_once: false,
            steps_per_second: 0.0,
            total_steps: 0,
        })
        .insert_resource(Control {
            current: o.setup.clone(),
            restart: None,
            respawn: None,
            error: None,
            save_folder: setup::save_folder(&o.setup),
            save_pending: o.save_run.clone(),
            keep_in: o.save_run.clone(),
            keeping: false,
            notice: None,
        })
        .insert_resource(ClearColor(draw::OUTSIDE));
        app.configure_sets(Update, (ViewerSet::Control, ViewerSet::Step, ViewerSet::Draw).chain());
        app.add_systems(Update, (apply_control.in_set(ViewerSet::Control), step.in_set(ViewerSet::Step)));
        // After the exits asked for this frame, so each is seen: the screenshot's (capture.rs) and the
        // window's own when it is closed (bevy_window's ExitSystems, also in Last).
        app.init_resource::<ExitReason>();
        app.add_systems(
            Last,
            (unsaved_on_exit, end_on_exit).chain().after(capture::one_shot).after(bevy::window::ExitSystems),
        );
        app.add_systems(First, log_close_requests);
        app.add_plugins((
            draw::DrawPlugin { trails: o.trails, select: o.select, rule_of: o.rule_of },
            plots::PlotsPlugin,
            panel::PanelPlugin,
        ));
        app.add_plugins(capture::CapturePlugin { request: o.screenshot.clone() });
    }
}

/// Opens the window and runs until it is closed (or the screenshot is saved).
pub(crate) fn run(options: ViewerOptions) -> crate::error::Result<()> {
    // Refuse a bad scene or checkpoint before a window opens.
    let (scene, learners) = options.setup.prepare()?;
    let mut window = Window {
        title: format!("coevo: {} ({})", options.setup.source.display(), options.setup.mode.label()),
        resolution: WindowResolution::new(options.window.x, options.window.y),
        resize_constraints: bevy::window::WindowResizeConstraints {
            min_width: MIN_WINDOW.x as f32,
            min_height: MIN_WINDOW.y as f32,
            ..default()
        },
        ..default()
    };
    if options.screenshot.is_some() {
        // Screenshots have the size asked for, whatever the display's scale factor.
        window.resolution = window.resolution.with_scale_factor_override(1.0);
    }
    let mut app = App::new();
    app.add_plugins(
        DefaultPlugins
            .set(WindowPlugin { primary_window: Some(window), ..default() })
            .set(LogPlugin { filter: "warn,coevo=info,wgpu=error,naga=error".into(), ..default() }),
    );
    app.add_plugins(EguiPlugin::default());
    app.add_plugins(SimulationPlugin { scene });
    app.insert_resource(learners);
    app.add_plugins(LearningPlugin { mode: Mode::Train });
    app.add_plugins(ViewerPlugin { options });
    app.add_systems(Startup, |world: &mut World| {
        crate::sim::episode::spawn_population(world);
        track_live_run(world);
    });
    let reason = ExitReason::default();
    app.insert_resource(reason.clone());
    let exit = app.run();
    // Reached only if the app ends without an exit message (end_on_exit ends the process otherwise).
    drop(app);
    let reason = reason.0.lock().unwrap_or_else(|e| e.into_inner()).take();
    end(&exit, reason)
}

/// How the viewer ends, once it is to: an error line for a save the window closed before (`reason`) or an
/// error exit, the headless modes' line for Ctrl-C, nothing for an ordinary close.
fn end(exit: &AppExit, reason: Option<String>) -> crate::error::Result<()> {
    if let Some(reason) = reason {
        return Err(reason.into());
    }
    match exit {
        AppExit::Success => Ok(()),
        // Ctrl-C: Bevy's handler ends the app with the shell's code for an interrupted command, an
        // ordinary way to stop, said as the headless modes say it, never as an error.
        AppExit::Error(code) if code.get() == INTERRUPTED => {
            eprintln!("coevo: interrupted; finished work kept");
            crate::io::end_process(INTERRUPTED.into())
        }
        AppExit::Error(code) => Err(format!("viewer exited with code {code}").into()),
    }
}

/// Says at debug level (`RUST_LOG=coevo::viewer=debug`) each request to close a window as winit reported
/// it and as Bevy passed it on: what `tests/stress/viewer-close.sh` reads when a close seems ignored.
fn log_close_requests(
    mut raw: MessageReader<bevy::winit::RawWinitWindowEvent>,
    mut closes: MessageReader<bevy::window::WindowCloseRequested>,
) {
    // winit's event by its name: bevy_winit does not re-export winit's types.
    for e in raw.read().filter(|e| format!("{:?}", e.event) == "CloseRequested") {
        debug!("winit: close requested for window {:?}", e.window_id);
    }
    for e in closes.read() {
        debug!("bevy: close requested for window {}", e.window);
    }
}

/// Ends the process in the frame an exit is asked for (the window closed, Ctrl-C, a screenshot saved),
/// after [`unsaved_on_exit`] has said how far the kept folder goes: coevo's work is finished and written
/// (saves happen within a frame, between episodes), so nothing is left to do. The teardown that would
/// follow, the window destroyed and then the renderer's Vulkan objects on it, is skipped: under Xvfb with
/// Mesa's software Vulkan it sometimes crashed (SIGSEGV after "Closing window", found by
/// tests/stress/viewer-close.sh), turning a complete, resumable run into a failed exit.
fn end_on_exit(mut exits: MessageReader<AppExit>, reason: Res<ExitReason>) {
    // An error exit wins over an ordinary one asked for in the same frame (as `App::should_exit` decides).
    let asked: Vec<AppExit> = exits.read().cloned().collect();
    let Some(exit) = asked.iter().find(|e| e.is_error()).or(asked.first()).cloned() else { return };
    let reason = reason.0.lock().unwrap_or_else(|e| e.into_inner()).take();
    let code = match end(&exit, reason) {
        Ok(()) => 0,
        Err(e) => {
            eprintln!("coevo: error: {e}");
            1
        }
    };
    crate::io::end_process(code)
}

/// Applies what the panel asked for, before this frame's steps.
fn apply_control(world: &mut World) {
    let (restart, respawn) = {
        let mut c = world.resource_mut::<Control>();
        (c.restart.take(), c.respawn.take())
    };
    if let Some(setup) = restart {
        match setup.prepare() {
            Ok((scene, learners)) => {
                crate::learning::restart(world, &scene, Some(learners));
                world.resource_mut::<plots::History>().clear();
                let mut c = world.resource_mut::<Control>();
                c.save_folder = setup::save_folder(&setup);
                c.save_pending = None;
                // A restarted world is another run: the kept folder stays as it was.
                (c.keep_in, c.keeping) = (None, false);
                c.current = setup;
                c.error = None;
                track_live_run(world);
            }
            Err(e) => world.resource_mut::<Control>().error = Some(e.to_string()),
        }
    }
    if let Some(counts) = respawn {
        respawn_with_counts(world, &counts);
    }
}

/// Changes the population and respawns it, keeping the learners and the episode count: the episode starts
/// over with the new numbers.
fn respawn_with_counts(world: &mut World, counts: &[usize]) {
    let mut scene = world.resource::<ActiveScene>().0.clone();
    for (def, &n) in scene.species.iter_mut().zip(counts) {
        def.count = n;
    }
    let source = world.resource::<Control>().current.source.clone();
    if let Err(e) = scene.validate() {
        world.resource_mut::<Control>().error = Some(e.in_file(&source).to_string());
        return;
    }
    world.insert_resource(SpeciesRegistry::from_scene(&scene));
    world.resource_mut::<Control>().current.scene.species.iter_mut().zip(counts).for_each(|(d, &n)| d.count = n);
    world.resource_mut::<ActiveScene>().0 = scene;
    world.resource_mut::<crate::sim::clock::Episode>().step = 0;
    crate::sim::episode::spawn_population(world);
    world.resource_mut::<plots::History>().start_episode(None);
    world.resource_mut::<Control>().error = None;
    let episode = world.resource::<crate::sim::clock::Episode>().index;
    if let Some(mut run) = world.get_resource_mut::<LiveRun>() {
        run.altered.get_or_insert_with(|| format!("the population changed at episode {episode}"));
    }
}

/// A save asked for (`--save-run` or the panel) that the window is closing before: said, with a non-zero
/// exit, never silent.
fn unsaved_on_exit(
    mut exits: ResMut<Messages<AppExit>>,
    mut control: ResMut<Control>,
    live: Option<Res<LiveRun>>,
    reason: Res<ExitReason>,
) {
    if exits.is_empty() {
        return;
    }
    if let (Some(dir), true, Some(live)) = (&control.keep_in, control.keeping, live) {
        println!(
            "coevo: {} holds the live run's {} episodes, checkpointed at episode {} (--resume continues from there)",
            dir.display(),
            live.episodes(),
            live.checkpointed()
        );
    }
    if let Some(dir) = control.save_pending.take() {
        *reason.0.lock().unwrap_or_else(|e| e.into_inner()) = Some(format!(
            "{}: not saved: the window closed before the episode ended (a run is saved between episodes)",
            dir.display()
        ));
        exits.write(AppExit::from_code(1));
    }
}

/// The smallest window, in logical pixels: the size at which both panels and every plot fit whole
/// (`tests/viewer.rs` checks it in each mode); `--window` refuses less and resizing stops there.
const MIN_WINDOW: UVec2 = UVec2::new(1280, 720);

/// The exit status of a command stopped by Ctrl-C (128 + SIGINT), which Bevy's handler exits with.
const INTERRUPTED: u8 = 130;

/// Why the window closed with an error, for [`run`]'s one error line: a resource whose cell [`run`] keeps
/// a handle to, since the app's world is gone once it has run.
#[derive(Resource, Clone, Default)]
struct ExitReason(std::sync::Arc<std::sync::Mutex<Option<String>>>);

/// Live training keeps its run ([`LiveRun`]) from its first step, so that it can be saved; other modes
/// train nothing. Watching a run shows its training curves (its `metrics.csv`) in the per-episode plots,
/// and, once it was cross-played, its snapshots' ratings.
fn track_live_run(world: &mut World) {
    world.remove_resource::<LiveRun>();
    let mode = world.resource::<Control>().current.mode.clone();
    if mode == RunMode::LiveTraining {
        let run = LiveRun::new(world);
        world.insert_resource(run);
    }
    let registry = world.resource::<SpeciesRegistry>();
    let prey = registry.defs[registry.headline()].name.clone();
    let mut history = world.resource_mut::<plots::History>();
    (history.training, history.ratings, history.trained_count) = match &mode {
        RunMode::Watch(run) => (
            plots::training_curves(run, &prey),
            crate::analysis::crossplay_readouts::read_ratings(run),
            plots::trained_count(run, &prey),
        ),
        _ => (None, None, None),
    };
}

/// Saves the live run into the folder asked for, now that an episode has ended; says what happened in
/// the panel (and on stdout, for scripts).
fn save_live_run(world: &mut World) {
    let (pending, kept) = {
        let mut c = world.resource_mut::<Control>();
        (c.save_pending.take(), c.keep_in.clone().filter(|_| c.keeping))
    };
    if pending.is_none() {
        // `--save-run` keeps the whole run: each episode into the folder its first save made.
        if let Some(dir) = kept {
            let kept = match world.contains_resource::<LiveRun>() {
                true => world.resource_scope(|world, mut run: Mut<LiveRun>| run.keep(world, &dir)),
                false => Ok(()),
            };
            if let Err(e) = kept {
                eprintln!("coevo: error: {e}");
                let mut c = world.resource_mut::<Control>();
                (c.error, c.keeping, c.keep_in) = (Some(e.to_string()), false, None);
            }
        }
        return;
    }
    let Some(dir) = pending else { return };
    let saved = match world.contains_resource::<LiveRun>() {
        true => world.resource_scope(|world, mut run: Mut<LiveRun>| run.save(world, &dir).map(|()| run.episodes())),
        false => Err("only live training is saved as a run".into()),
    };
    let mut c = world.resource_mut::<Control>();
    match saved {
        Ok(episodes) => {
            let episodes = if episodes == 1 { "1 episode".to_string() } else { format!("{episodes} episodes") };
            let notice = format!("saved {episodes} into {} (--resume, --eval, --watch take it)", dir.display());
            println!("coevo: {notice}");
            // The folder `--save-run` keeps grows every episode: the panel says how far it goes then,
            // not what its first save wrote.
            c.notice = (c.keep_in.as_ref() != Some(&dir)).then_some(notice);
            c.error = None;
            // A panel save into another folder is a one-shot copy; the `--save-run` folder is still kept.
            c.keeping = c.keeping || c.keep_in.as_ref() == Some(&dir);
        }
        Err(e) => {
            eprintln!("coevo: error: {e}");
            c.error = Some(e.to_string());
        }
    }
}

/// Runs this frame's fixed steps and records what the plots and trails need after each.
fn step(world: &mut World) {
    let started = Instant::now();
    let p = world.resource::<Playback>().clone();
    let budget: Box<dyn Fn(usize) -> bool> = if p.step_once {
        Box::new(|done| done < 1)
    } else if !p.playing {
        Box::new(|_| false)
    } else if p.as_fast_as_possible {
        Box::new(move |_| started.elapsed() < FAST_FRAME_BUDGET)
    } else {
        Box::new(move |done| done < p.steps_per_frame)
    };
    let mut done = 0;
    while budget(done) && world.resource::<Learners>().failure.is_none() && crate::sim::check_state(world).is_ok() {
        world.run_schedule(FixedUpdate);
        if world.contains_resource::<LiveRun>() {
            LiveRun::record(world);
        }
        plots::record_step(world);
        if world.resource::<crate::sim::clock::Episode>().step == 0 {
            save_live_run(world);
        }
        draw::record_trails(world);
        done += 1;
    }
    let failure = world.resource::<Learners>().failure.clone().map(|f| format!("training stopped: {f}"));
    // The same guard as headless runs: an unphysical state stops the world with its one-line reason.
    let fault = crate::sim::check_state(world).err().map(|e| e.to_string());
    if let Some(message) = failure.or(fault) {
        let mut c = world.resource_mut::<Control>();
        if c.error.is_none() {
            c.error = Some(message);
        }
    }
    let mut p = world.resource_mut::<Playback>();
    p.step_once = false;
    p.total_steps += done as u64;
    let seconds = started.elapsed().as_secs_f64();
    if done > 0 && seconds > 0.0 {
        // A running mean over roughly the last second of frames.
        let now = done as f64 / seconds;
        p.steps_per_second = if p.steps_per_second == 0.0 { now } else { 0.95 * p.steps_per_second + 0.05 * now };
    }
}

impl args::ViewerArgs {
    /// Opens the window as the flags say.
    pub(crate) fn main(
        &self,
        draw: &crate::run::animate::AnimateArgs,
        shared: &crate::run::args::Shared,
    ) -> crate::error::Result<()> {
        use std::path::Path;
        let scene = &shared.scene;
        if self.watch.is_some() && (scene.scene.is_some() || self.rules) {
            return Err("--watch: shows a run in its own scene; it does not combine with --scene or --rules".into());
        }
        let (default, mode) = match &self.watch {
            Some(run) => {
                crate::store::RunDir::new(run).check_plugins()?;
                (run.join(crate::store::SCENE), RunMode::Watch(run.clone()))
            }
            None => (
                Path::new(crate::run::args::STANDARD_SCENE).to_path_buf(),
                if self.rules { RunMode::RuleBased } else { RunMode::LiveTraining },
            ),
        };
        let (loaded, source) = scene.load(&default, &scene.overrides(false)?)?;
        let size = self.window.clone().unwrap_or_else(|| "1280x720".into());
        let window = size
            .split_once('x')
            .and_then(|(w, h)| Some(bevy::math::UVec2::new(w.parse().ok()?, h.parse().ok()?)))
            .filter(|s| s.x >= MIN_WINDOW.x && s.y >= MIN_WINDOW.y)
            .ok_or_else(|| {
                format!("--window {size}: expected WxH of at least 1280x720 (where the panels and plots fit whole), e.g. 1920x1080")
            })?;
        if let Some(path) = &self.screenshot {
            if path.extension().is_none_or(|e| e != "png") {
                return Err(format!("--screenshot {}: the file must end in .png", path.display()).into());
            }
            crate::io::check_target(path, shared.common.existing())
                .map_err(|e| format!("--screenshot {}: {e}", path.display()))?;
        }
        let snapshots = scene.snapshots(self.watch.as_deref(), "--watch")?;
        let rule_of = match (&self.rule_of, self.select) {
            (None, _) => None,
            (Some(name), None) => {
                return Err(
                    format!("--rule-of {name}: shows the selected agent's rule; select one with --select ID").into()
                )
            }
            (Some(name), Some(_)) => Some(loaded.species.iter().position(|d| &d.name == name).ok_or_else(|| {
                let known: Vec<&str> = loaded.species.iter().map(|d| d.name.as_str()).collect();
                format!("--rule-of {name}: no species of that name in the scene ({})", known.join(", "))
            })?),
        };
        if let Some(dir) = &self.save_run {
            if self.watch.is_some() || self.rules {
                return Err(
                    format!("--save-run {}: saves live training; not with --watch or --rules", dir.display()).into()
                );
            }
            crate::store::RunDir::new(dir).check_new(false).map_err(|e| format!("--save-run {e}"))?;
        }
        run(ViewerOptions {
            setup: Setup { scene: loaded, source, mode, snapshots },
            window,
            steps_per_frame: draw.steps_per_frame.unwrap_or(1),
            paused: self.paused,
            // Live training starts fast, so its curves move within the first minute (an episode takes ~20 s
            // at one step per frame); watching a run or rule-based agents starts at one step per frame.
            fast: self.fast || (self.watch.is_none() && !self.rules && draw.steps_per_frame.is_none() && !self.paused),
            trails: draw.trails,
            select: self.select,
            rule_of,
            screenshot: self
                .screenshot
                .clone()
                .map(|path| ScreenshotRequest { path, frames: self.frames.unwrap_or(60) }),
            save_run: self.save_run.clone(),
        })
    }
}
