//! Screenshots: F12 (or the panel's button) saves the window as a PNG under `screenshots/`, and
//! `--screenshot PATH --frames N` renders N frames, saves PATH, prints the frame rate and exits.
//! A PNG is written atomically (`io::write_atomically`), so no half-written file is ever left at PATH.

use bevy::prelude::*;
use bevy::render::view::screenshot::{Screenshot, ScreenshotCaptured};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// `--screenshot PATH --frames N`.
#[derive(Clone, Debug)]
pub(crate) struct ScreenshotRequest {
    pub(crate) path: PathBuf,
    pub(crate) frames: usize,
}

/// Screenshots to take this frame.
#[derive(Resource, Default)]
pub(crate) struct ScreenshotQueue(pub Vec<PathBuf>);

/// The `--screenshot` run: frames rendered, when the frame-rate window began, and the save's outcome.
#[derive(Resource)]
pub(super) struct OneShot {
    request: ScreenshotRequest,
    frames: usize,
    timing_from: Option<(usize, Instant)>,
    requested_at: Option<usize>,
    outcome: Option<crate::error::Result<()>>,
}

/// Frames rendered before the frame rate is timed (start-up, shader compilation).
const WARM_UP_FRAMES: usize = 10;
/// Frames to wait for a requested screenshot before giving up.
const SAVE_TIMEOUT_FRAMES: usize = 600;

pub(crate) struct CapturePlugin {
    pub(crate) request: Option<ScreenshotRequest>,
}

impl Plugin for CapturePlugin {
    fn build(&self, app: &mut App) {
        app.init_resource::<ScreenshotQueue>().add_systems(Last, (screenshot_key, one_shot, take_screenshots).chain());
        if let Some(request) = &self.request {
            app.insert_resource(OneShot {
                request: request.clone(),
                frames: 0,
                timing_from: None,
                requested_at: None,
                outcome: None,
            });
        }
    }
}

/// `screenshots/coevo-<unix seconds>.png`.
pub(crate) fn timestamped_path() -> PathBuf {
    let secs = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map_or(0, |d| d.as_secs());
    PathBuf::from(format!("screenshots/coevo-{secs}.png"))
}

fn screenshot_key(keys: Res<ButtonInput<KeyCode>>, mut queue: ResMut<ScreenshotQueue>) {
    if keys.just_pressed(KeyCode::F12) {
        queue.0.push(timestamped_path());
    }
}

fn take_screenshots(mut commands: Commands, mut queue: ResMut<ScreenshotQueue>) {
    for path in queue.0.drain(..) {
        commands.spawn(Screenshot::primary_window()).observe(
            move |captured: On<ScreenshotCaptured>, shot: Option<ResMut<OneShot>>| {
                let outcome = save_png(&captured.image, &path);
                match &outcome {
                    Ok(()) => info!("screenshot saved to {}", path.display()),
                    Err(e) => error!("{e}"),
                }
                if let Some(mut shot) = shot.filter(|s| s.request.path == path) {
                    shot.outcome = Some(outcome);
                }
            },
        );
    }
}

fn save_png(image: &Image, path: &Path) -> crate::error::Result<()> {
    let rgb = image
        .clone()
        .try_into_dynamic()
        .map_err(|e| format!("{}: cannot convert the screenshot: {e}", path.display()))?
        .to_rgb8();
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    }
    Ok(crate::io::write_atomically(path, crate::io::Existing::Replace, |w| {
        rgb.write_with_encoder(image::codecs::png::PngEncoder::new(w)).map_err(std::io::Error::other)
    })
    .map_err(|e| format!("{}: cannot write PNG: {e}", path.display()))?)
}

/// Counts frames, asks for the screenshot at frame N and exits once it is saved.
pub(super) fn one_shot(
    shot: Option<ResMut<OneShot>>,
    mut queue: ResMut<ScreenshotQueue>,
    mut exit: MessageWriter<AppExit>,
    history: Res<super::plots::History>,
) {
    let Some(mut shot) = shot else { return };
    shot.frames += 1;
    let frames = shot.frames;
    if frames == WARM_UP_FRAMES.min(shot.request.frames) {
        shot.timing_from = Some((frames, Instant::now()));
    }
    if frames == shot.request.frames.max(1) {
        if let Some((from, at)) = shot.timing_from {
            let seconds = at.elapsed().as_secs_f64();
            if frames > from && seconds > 0.0 {
                println!("coevo: {:.1} fps over frames {from}..{frames}", (frames - from) as f64 / seconds);
            }
        }
        shot.requested_at = Some(frames);
        let path = shot.request.path.clone();
        queue.0.push(path);
    }
    match &shot.outcome {
        Some(Ok(())) => {
            // The episodes finished while the window ran, as `--train` writes them to metrics.csv.
            for ((dos, doa), catches) in history.dos.iter().zip(&history.doa).zip(&history.catches) {
                println!("coevo: episode {} dos {} doa {} catches {}", dos[0], dos[1], doa[1], catches[1]);
            }
            println!("coevo: wrote {}", shot.request.path.display());
            exit.write(AppExit::Success);
        }
        Some(Err(e)) => {
            eprintln!("coevo: error: {e}");
            exit.write(AppExit::from_code(1));
        }
        None if shot.requested_at.is_some_and(|at| frames > at + SAVE_TIMEOUT_FRAMES) => {
            eprintln!("coevo: error: {}: the screenshot never arrived", shot.request.path.display());
            exit.write(AppExit::from_code(1));
        }
        None => {}
    }
}
