//! The viewer, in a real window: `coevo --screenshot` under Xvfb, and the PNG it writes checked for size,
//! content and the species' colours in the pixel proportions their bodies should cover. Also the refusals
//! that happen before a window opens. Built only with `--features viewer` (see `.ci/run`).
#![cfg(feature = "viewer")]

use coevo::learning::Mode;
use coevo::run::train::{train, TrainOptions};
use coevo::scene::Scene;
use coevo::viewer::{RunMode, Setup};
use std::path::{Path, PathBuf};
use std::process::Command;

mod common;

const BIN: &str = env!("CARGO_BIN_EXE_coevo");
const WIDTH: u32 = 1280;
const HEIGHT: u32 = 720;

/// One window at a time: `xvfb-run -a` picks a free display number, and two started at once can pick
/// the same one.
static DISPLAY: std::sync::Mutex<()> = std::sync::Mutex::new(());

/// Runs the viewer under a virtual X server (`xvfb-run`, Debian's xvfb); fails if there is none.
fn under_xvfb(args: &[&str]) -> std::process::Output {
    let _one_at_a_time = DISPLAY.lock().unwrap_or_else(|e| e.into_inner());
    let runtime = tempfile::tempdir().unwrap();
    let mut cmd = Command::new("xvfb-run");
    cmd.args(["-a", "-s", &format!("-screen 0 {WIDTH}x{HEIGHT}x24"), BIN]).args(args);
    // A private XDG_RUNTIME_DIR keeps winit and wgpu from warning about a missing one.
    cmd.env("XDG_RUNTIME_DIR", runtime.path());
    std::fs::set_permissions(runtime.path(), std::os::unix::fs::PermissionsExt::from_mode(0o700)).unwrap();
    cmd.output().expect("xvfb-run must be installed to test the viewer (apt-get install xvfb xauth, see .ci/run)")
}

/// RGB pixels of a PNG and its size.
fn read_png(path: &Path) -> (u32, u32, Vec<[u8; 3]>) {
    let img = image::open(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    assert_eq!(img.color(), image::ColorType::Rgb8, "screenshots are saved as 8-bit RGB");
    let img = img.to_rgb8();
    (img.width(), img.height(), img.pixels().map(|p| p.0).collect())
}

fn srgb8(c: [f32; 3]) -> [u8; 3] {
    c.map(|x| (x * 255.0).round() as u8)
}

fn close(a: [u8; 3], b: [u8; 3], tolerance: u8) -> bool {
    a.iter().zip(b).all(|(x, y)| x.abs_diff(y) <= tolerance)
}

/// Runs the viewer with `args` plus `--screenshot`, and returns the PNG's size and pixels.
fn screenshot(args: &[&str]) -> (u32, u32, Vec<[u8; 3]>) {
    screenshot_and_output(args).0
}

/// As [`screenshot`], with what the viewer printed.
fn screenshot_and_output(args: &[&str]) -> ((u32, u32, Vec<[u8; 3]>), String) {
    let dir = tempfile::tempdir().unwrap();
    let shot = dir.path().join("shot.png");
    let size = format!("{WIDTH}x{HEIGHT}");
    let mut all = args.to_vec();
    all.extend(["--window", &size, "--frames", "30", "--screenshot", shot.to_str().unwrap()]);
    let out = under_xvfb(&all);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "viewer failed: {}\n{stderr}", out.status);
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(stdout.contains("fps over frames"), "the frame rate is reported");
    let files: Vec<_> = std::fs::read_dir(dir.path()).unwrap().map(|e| e.unwrap().file_name()).collect();
    assert_eq!(files, vec![std::ffi::OsString::from("shot.png")], "the PNG and no temporary file");
    (read_png(&shot), stdout)
}

/// Pixels of each species' colour in the arena, and how many its bodies should cover: the arena floor's
/// extent on screen gives the scale, and each body is a disc of its radius.
fn colour_coverage(w: u32, h: u32, pixels: &[[u8; 3]], scene: &Scene) -> Vec<(f64, f64)> {
    let at = |x: u32, y: u32| pixels[(y * w + x) as usize];
    let floor = srgb8([0.98, 0.98, 0.97]);
    let (mut x0, mut x1, mut y0, mut y1) = (w, 0, h, 0);
    for y in 0..h {
        for x in 0..w {
            if close(at(x, y), floor, 2) {
                (x0, x1, y0, y1) = (x0.min(x), x1.max(x), y0.min(y), y1.max(y));
            }
        }
    }
    assert!(
        x1 > x0 + 300 && y1 > y0 + 300,
        "the arena floor fills a good part of the window ({x0}..{x1} × {y0}..{y1})"
    );
    let (aw, ah) = ((x1 - x0 + 1) as f64, (y1 - y0 + 1) as f64);
    assert!((aw / ah - 1.0).abs() < 0.03, "the arena is square on screen: {aw} × {ah}");
    let per_metre = aw / scene.world.arena_edge;
    scene
        .species
        .iter()
        .map(|s| {
            let colour = srgb8(s.colour);
            // Inside the arena only: the panel writes species names in their colours.
            let inside = (y0..=y1).flat_map(|y| (x0..=x1).map(move |x| (x, y)));
            let counted = inside.filter(|&(x, y)| close(at(x, y), colour, 6)).count() as f64;
            let expected = s.count as f64 * std::f64::consts::PI * (s.radius * per_metre).powi(2);
            eprintln!("{}: {counted} pixels, {expected:.0} expected", s.name);
            (counted, expected)
        })
        .collect()
}

#[test]
fn a_screenshot_of_the_standard_scene_shows_the_arena_and_both_species() {
    let (w, h, pixels) = screenshot(&["--scene", "scenes/paper.ron", "--rules", "--seed", "3"]);
    assert_eq!((w, h), (WIDTH, HEIGHT));
    let scene = Scene::load(Path::new("scenes/paper.ron")).unwrap();
    for ((counted, expected), s) in colour_coverage(w, h, &pixels, &scene).into_iter().zip(&scene.species) {
        // Heading lines and overlaps take some pixels of a disc away; nothing else has these colours.
        let ratio = counted / expected;
        assert!(
            (0.55..=1.1).contains(&ratio),
            "{}: {counted} pixels of its colour, {expected:.0} expected from its bodies",
            s.name
        );
    }
}

/// `scenes/paper.ron` with `steps` steps per episode, written to `dir/short.ron` for the window, and the
/// same scene trained headless for `episodes` episodes into `dir/run`.
fn short_paper_run(dir: &Path, steps: usize, episodes: usize) -> (PathBuf, PathBuf) {
    let mut scene = Scene::load(Path::new("scenes/paper.ron")).unwrap();
    scene.episode_steps = steps;
    let file = dir.join("short.ron");
    std::fs::write(&file, scene.to_ron()).unwrap();
    let run = dir.join("run");
    train(scene, &TrainOptions::new(run.clone(), Some(episodes))).unwrap();
    (file, run)
}

#[test]
fn live_training_in_the_window_is_the_headless_training_run() {
    // The same scene and seed, trained headless for two episodes and live in the window at 25 steps per
    // frame: the episodes' DoS, DoA and catches must be the same numbers, to the last digit.
    let dir = tempfile::tempdir().unwrap();
    let (file, run) = short_paper_run(dir.path(), 200, 2);
    let metrics = std::fs::read_to_string(run.join("metrics.csv")).unwrap();
    let header: Vec<&str> = metrics.lines().next().unwrap().split(',').collect();
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let headless: Vec<String> = metrics
        .lines()
        .skip(1)
        .map(|row| {
            let c: Vec<&str> = row.split(',').collect();
            format!(
                "coevo: episode {} dos {} doa {} catches {}",
                c[0],
                c[col("dos_prey")],
                c[col("doa_prey")],
                c[col("catches")]
            )
        })
        .collect();

    let (_, stdout) = screenshot_and_output(&["--scene", file.to_str().unwrap(), "--steps-per-frame", "25"]);
    let live: Vec<&str> = stdout.lines().filter(|l| l.starts_with("coevo: episode")).collect();
    assert!(live.len() >= 2, "two episodes ran in the window (30 frames × 25 steps): {stdout}");
    assert_eq!(&live[..2], &headless[..]);
}

#[test]
fn a_bad_scene_is_refused_before_a_window_opens() {
    let dir = tempfile::tempdir().unwrap();
    let bad = dir.path().join("bad.ron");
    std::fs::write(&bad, "(preset: \"paper\", world: (arena_edge: -2.0))").unwrap();
    let out = Command::new(BIN).args(["--scene", bad.to_str().unwrap()]).output().unwrap();
    assert_eq!(out.status.code(), Some(1));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(stderr.lines().count(), 1, "one line: {stderr}");
    assert!(stderr.contains("bad.ron") && stderr.contains("world.arena_edge"), "{stderr}");
}

/// A one-episode run of the standard scene with small networks.
fn tiny_run(dir: &Path) -> PathBuf {
    let mut s = Scene::load(Path::new("scenes/paper.ron")).unwrap();
    s.episode_steps = 10;
    s.learning.hidden = 8;
    s.learning.buffer_capacity = 500;
    let run = dir.join("run");
    train(s, &TrainOptions::new(run.clone(), Some(1))).unwrap();
    run
}

#[test]
fn watching_a_run_loads_its_actors_and_refuses_a_scene_they_do_not_fit() {
    let dir = tempfile::tempdir().unwrap();
    let run = tiny_run(dir.path());
    let scene = Scene::load(&run.join("scene.ron")).unwrap();
    let watch = |scene: Scene| {
        Setup { scene, source: run.join("scene.ron"), mode: RunMode::Watch(run.clone()), snapshots: vec![] }.prepare()
    };

    let (_, learners) = watch(scene.clone()).expect("the run's own scene fits its checkpoint");
    assert_eq!(learners.mode, Mode::Evaluate);
    assert!(learners.species.iter().flatten().all(|l| l.frozen), "watched actors never update");

    // Fifty prey and no predators: the networks do not depend on the counts.
    let mut many = scene.clone();
    many.set_count("prey", 50).unwrap();
    many.set_count("predator", 0).unwrap();
    watch(many).expect("any population");

    // Observing 4 neighbours instead of 6 changes the observation size: refused, with the reason.
    let mut other = scene.clone();
    other.species[1].topological_limit = 4;
    let err = watch(other).err().expect("a mismatched checkpoint is refused").to_string();
    assert!(
        err.starts_with("checkpoint refused:")
            && err.contains("prey-actor.safetensors")
            && err.contains("observation size"),
        "{err}"
    );

    // A species the run never trained has no actor to load.
    let mut renamed = scene;
    renamed.species[1].name = "fish".into();
    renamed.species[0].catches = vec!["fish".into()];
    let err = watch(renamed).err().expect("an unknown species is refused").to_string();
    assert!(err.contains("fish-actor.safetensors"), "{err}");
}

#[test]
fn watching_a_run_in_the_window_deploys_it_on_fifty_prey_without_predators() {
    let dir = tempfile::tempdir().unwrap();
    let run = tiny_run(dir.path());
    let (w, h, pixels) = screenshot(&["--watch", run.to_str().unwrap(), "--prey", "50", "--predators", "0"]);
    let mut scene = Scene::load(&run.join("scene.ron")).unwrap();
    scene.set_count("prey", 50).unwrap();
    scene.set_count("predator", 0).unwrap();
    let coverage = colour_coverage(w, h, &pixels, &scene);
    let (predator, (prey, expected)) = (coverage[0].0, coverage[1]);
    assert_eq!(predator, 0.0, "no predator is drawn");
    assert!((0.55..=1.1).contains(&(prey / expected)), "50 prey: {prey} pixels, {expected:.0} expected");
}

#[test]
fn rule_based_mode_replaces_learned_species_by_chase_and_flee() {
    let scene = Scene::load(Path::new("scenes/paper.ron")).unwrap();
    let (scene, learners) =
        Setup { scene, source: "scenes/paper.ron".into(), mode: RunMode::RuleBased, snapshots: vec![] }
            .prepare()
            .unwrap();
    use coevo::scene::Policy;
    assert_eq!(scene.species[0].policy, Policy::ChaseNearest);
    assert_eq!(scene.species[1].policy, Policy::FleeInside, "fleeing, and off the walls of a box");
    assert!(learners.species.iter().all(Option::is_none), "nothing learns");
}

#[test]
fn the_shipped_trained_run_is_first_in_the_run_list_and_loads() {
    let runs = coevo::viewer::run_folders();
    assert_eq!(runs.first().map(PathBuf::as_path), Some(Path::new(coevo::store::SHIPPED_RUN)));
    let run = PathBuf::from(coevo::store::SHIPPED_RUN);
    let scene = Scene::load(&run.join("scene.ron")).unwrap();
    let (_, learners) =
        Setup { scene, source: run.join("scene.ron"), mode: RunMode::Watch(run.clone()), snapshots: vec![] }
            .prepare()
            .expect("the shipped actors fit their scene");
    assert!(learners.species.iter().flatten().all(|l| l.frozen));
}

#[test]
fn watching_a_run_deploys_the_snapshots_asked_for() {
    let dir = tempfile::tempdir().unwrap();
    let run = tiny_run(dir.path());
    let scene = Scene::load(&run.join("scene.ron")).unwrap();
    let setup = |snapshots: Vec<(String, usize)>| Setup {
        scene: scene.clone(),
        source: run.join("scene.ron"),
        mode: RunMode::Watch(run.clone()),
        snapshots,
    };
    // A snapshot unlike the trained actor (the tiny run makes no update), so deploying it shows.
    let (_, trained) = setup(vec![]).prepare().unwrap();
    let mut other = trained.species[1].as_ref().unwrap().ddpg.actor.clone();
    let shifted: Vec<Vec<f32>> = other.parameters().iter().map(|p| p.iter().map(|x| x + 0.5).collect()).collect();
    other.set_parameters(&shifted);
    coevo::store::snapshots::save_snapshot(&run, &scene, "prey", 0, &other).unwrap();
    common::reseal_snapshots(&run);
    let (_, learners) = setup(vec![("prey".into(), 0)]).prepare().unwrap();
    assert_eq!(learners.species[1].as_ref().unwrap().ddpg.actor.parameters(), other.parameters());
    assert_ne!(trained.species[1].as_ref().unwrap().ddpg.actor.parameters(), other.parameters());
    let err = setup(vec![("prey".into(), 7)]).prepare().err().unwrap().to_string();
    assert!(err.starts_with("snapshot refused:") && err.contains("no snapshot of prey after 7 episodes"), "{err}");
}

#[test]
fn with_an_agent_selected_the_plots_keep_their_height() {
    // The inspector scrolls instead of squeezing its plots: the per-episode plot's dark area, below the
    // selected agent's observation table, stays over 120 px tall (it was ~60 before the panel scrolled).
    let (w, h, pixels) = screenshot(&["--scene", "scenes/paper.ron", "--select", "3", "--steps-per-frame", "5"]);
    let dark = |x: u32, y: u32| pixels[(y * w + x) as usize].iter().all(|&c| c <= 22);
    let (x0, x1) = (w - 280, w - 20);
    let plot_rows = (0..h).filter(|&y| (x0..x1).filter(|&x| dark(x, y)).count() * 10 >= (x1 - x0) as usize * 8).count();
    assert!(plot_rows >= 120, "{plot_rows} rows of plot in the inspector with an agent selected");
}

#[test]
fn a_live_run_saved_from_the_window_resumes_to_the_headless_run() {
    let dir = tempfile::tempdir().unwrap();
    let (file, headless) = short_paper_run(dir.path(), 50, 3);
    // Live training at 25 steps per frame, saved when its first episode ends.
    let saved = dir.path().join("saved");
    let shot = dir.path().join("shot.png");
    let (file, saved_s, shot_s) = (file.to_str().unwrap(), saved.to_str().unwrap(), shot.to_str().unwrap());
    let size = format!("{WIDTH}x{HEIGHT}");
    let out = under_xvfb(&[
        "--scene",
        file,
        "--steps-per-frame",
        "25",
        "--window",
        &size,
        "--frames",
        "30",
        "--screenshot",
        shot_s,
        "--save-run",
        saved_s,
    ]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{}\n{stdout}", String::from_utf8_lossy(&out.stderr));
    assert!(stdout.contains(&format!("coevo: saved 1 episode into {saved_s}")), "{stdout}");
    // --save-run keeps the whole run: every episode the window trained is in its metrics.csv, and the
    // exit says how far it goes and where its last checkpoint is.
    let trained = std::fs::read_to_string(saved.join("metrics.csv")).unwrap().lines().count() - 1;
    assert!(trained > 3, "{trained} episodes kept\n{stdout}");
    assert!(
        stdout
            .contains(&format!("coevo: {saved_s} holds the live run's {trained} episodes, checkpointed at episode 1")),
        "{stdout}"
    );
    // A run folder: --eval takes it, and --resume continues it to the headless run, to the last digit.
    let eval = Command::new(BIN).args(["--eval", saved_s, "--episodes", "1", "--steps", "10"]).output().unwrap();
    assert!(eval.status.success(), "{}", String::from_utf8_lossy(&eval.stderr));
    let resume = Command::new(BIN).args(["--resume", saved_s, "--episodes", "3", "--quiet"]).output().unwrap();
    assert!(resume.status.success(), "{}", String::from_utf8_lossy(&resume.stderr));
    let without_wall = |run: &Path| -> Vec<String> {
        let text = std::fs::read_to_string(run.join("metrics.csv")).unwrap();
        text.lines().map(|l| l.rsplit_once(',').unwrap().0.to_string()).collect()
    };
    assert_eq!(without_wall(&saved), without_wall(&headless));
    for actor in ["predator-actor.safetensors", "prey-actor.safetensors"] {
        let read = |run: &Path| std::fs::read(run.join("checkpoint").join(actor)).unwrap();
        assert!(read(&saved) == read(&headless), "{actor}");
    }
    // A save the window closes before (5 steps of a 50-step episode) is said, with a non-zero exit.
    let early = dir.path().join("early");
    let shot2 = dir.path().join("shot2.png");
    let out = under_xvfb(&[
        "--scene",
        file,
        "--steps-per-frame",
        "1",
        "--window",
        &size,
        "--frames",
        "5",
        "--screenshot",
        shot2.to_str().unwrap(),
        "--save-run",
        early.to_str().unwrap(),
    ]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && stderr.contains("not saved: the window closed before the episode ended"),
        "{stderr}"
    );
    assert!(!early.exists());
    // Never over a run: the same folder again is refused before a window opens.
    let out = under_xvfb(&["--scene", file, "--save-run", saved_s]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && stderr.contains("already holds a run"), "{stderr}");
}

#[test]
fn bodies_pressed_against_a_wall_are_drawn_over_it() {
    // The confined scene with prey that flee straight away (FleeNearest, not the viewer's rule-based
    // FleeInside): they run into the walls and stay pressed against them (soft walls: a body overlaps the
    // wall by up to its radius). The wall band keeps its own colour only where no body is: on it, the
    // prey's colour must show.
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("pressed.ron");
    let text = std::fs::read_to_string("scenes/confined.ron").unwrap();
    assert!(text.contains(r#"(name: "prey", count: 10, policy: Learned)"#));
    std::fs::write(&file, text.replace("policy: Learned", "policy: FleeNearest")).unwrap();
    let (w, h, pixels) = screenshot(&["--scene", file.to_str().unwrap(), "--steps-per-frame", "20"]);
    let scene = Scene::load(&file).unwrap();
    let prey = srgb8(scene.species[1].colour);
    let wall = srgb8([0.42, 0.42, 0.46]);
    // The wall band: the columns and rows where its colour is; prey pixels inside its bounding box but
    // outside the floor are bodies drawn over it.
    let at = |x: u32, y: u32| pixels[(y * w + x) as usize];
    let floor = srgb8([0.98, 0.98, 0.97]);
    let (mut fx0, mut fx1, mut fy0, mut fy1) = (w, 0, h, 0);
    let (mut wx0, mut wx1, mut wy0, mut wy1) = (w, 0, h, 0);
    for y in 0..h {
        for x in 0..w {
            if close(at(x, y), floor, 2) {
                (fx0, fx1, fy0, fy1) = (fx0.min(x), fx1.max(x), fy0.min(y), fy1.max(y));
            }
            if close(at(x, y), wall, 2) {
                (wx0, wx1, wy0, wy1) = (wx0.min(x), wx1.max(x), wy0.min(y), wy1.max(y));
            }
        }
    }
    let on_wall = (wy0..=wy1)
        .flat_map(|y| (wx0..=wx1).map(move |x| (x, y)))
        .filter(|&(x, y)| !(fx0..=fx1).contains(&x) || !(fy0..=fy1).contains(&y))
        .filter(|&(x, y)| close(at(x, y), prey, 8))
        .count();
    assert!(on_wall > 50, "{on_wall} prey-coloured pixels on the wall band");
}

/// The plot frames in the right panel, top to bottom, as (top, bottom, left, right) pixel rows and
/// columns: runs of rows that are dark (egui_plot's frame) across most of the panel, thin grid, chance
/// and curve lines inside a frame bridged.
fn plot_frames(w: u32, h: u32, pixels: &[[u8; 3]]) -> Vec<(u32, u32, u32, u32)> {
    let at = |x: u32, y: u32| pixels[(y * w + x) as usize];
    let dark = |x: u32, y: u32| at(x, y).iter().all(|&c| c <= 22);
    let (x0, x1) = (w - 300, w - 40);
    let rows: Vec<u32> =
        (0..h).filter(|&y| (x0..x1).filter(|&x| dark(x, y)).count() * 10 >= (x1 - x0) as usize * 6).collect();
    let mut frames: Vec<(u32, u32)> = vec![];
    for y in rows {
        match frames.last_mut() {
            Some((_, bottom)) if y <= *bottom + 14 => *bottom = y,
            _ => frames.push((y, y)),
        }
    }
    frames
        .into_iter()
        .filter(|(top, bottom)| bottom - top >= 60)
        .map(|(top, bottom)| {
            // The frame's columns: mostly dark from top to bottom (grid lines cross it).
            let column = |x: u32| (top..bottom).filter(|&y| dark(x, y)).count() * 10 >= (bottom - top) as usize * 7;
            let left = (w - 370..w).find(|&x| column(x)).unwrap_or(0);
            let right = (left..w).rev().find(|&x| column(x)).unwrap_or(left);
            (top, bottom, left, right)
        })
        .collect()
}

/// Groups of consecutive indices (columns or rows) for which `lit` holds, gaps up to `gap` bridged.
fn blobs(range: std::ops::Range<u32>, gap: u32, lit: impl Fn(u32) -> bool) -> usize {
    let mut count = 0;
    let mut last: Option<u32> = None;
    for i in range.filter(|&i| lit(i)) {
        if last.is_none_or(|l| i > l + gap) {
            count += 1;
        }
        last = Some(i);
    }
    count
}

#[test]
fn at_1280x720_the_plots_are_whole_with_labelled_ticks_chance_lines_and_the_last_episode_fast() {
    // Live training starts "as fast as possible": with 20-step episodes many end during the 30 frames,
    // so the step plot shows the last finished one (not an empty new episode).
    let dir = tempfile::tempdir().unwrap();
    let mut scene = Scene::load(Path::new("scenes/paper.ron")).unwrap();
    scene.episode_steps = 20;
    let file = dir.path().join("short.ron");
    std::fs::write(&file, scene.to_ron()).unwrap();
    let ((w, h, pixels), stdout) = screenshot_and_output(&["--scene", file.to_str().unwrap()]);
    assert!(stdout.lines().filter(|l| l.starts_with("coevo: episode")).count() >= 2, "{stdout}");
    let at = |x: u32, y: u32| pixels[(y * w + x) as usize];
    let frames = plot_frames(w, h, &pixels);
    eprintln!("plot frames: {frames:?}");
    assert_eq!(frames.len(), 3, "per episode, step by step, catches: {frames:?}");
    for &(top, bottom, left, right) in &frames {
        assert!(bottom - top >= 100 && right - left >= 200, "a plot of {}×{} px", right - left, bottom - top);
        // Tick labels: light text in the strip under the frame (x) and in the one left of it (y).
        let light = |x: u32, y: u32| at(x, y).iter().all(|&c| c >= 110);
        let x_labels = blobs(left..right, 8, |x| (bottom + 2..bottom + 16).any(|y| light(x, y)));
        let y_labels = blobs(top..bottom, 4, |y| (left.saturating_sub(36)..left - 2).any(|x| light(x, y)));
        assert!(x_labels >= 3 && y_labels >= 2, "frame at row {top}: {x_labels} x and {y_labels} y tick labels");
    }
    let (_, last_bottom, _, _) = frames[2];
    assert!(last_bottom + 30 <= h, "the catches plot and its axis are whole: frame ends at row {last_bottom} of {h}");
    // Chance lines: dashed near-white rows inside the per-episode and step plots (DoA 2/π and DoS).
    for &(top, bottom, left, right) in &frames[..2] {
        let chance = |x: u32, y: u32| at(x, y).iter().all(|&c| (205..=240).contains(&c));
        // At least two dashes in a row: nothing else inside a plot is near-white, and an untrained
        // swarm's curves lie on their chance lines, hiding most of them.
        let lines = blobs(top..bottom, 2, |y| (left..right).filter(|&x| chance(x, y)).count() >= 12);
        let rows: Vec<(u32, usize)> = (top..bottom)
            .map(|y| (y, (left..right).filter(|&x| chance(x, y)).count()))
            .filter(|&(_, n)| n > 0)
            .collect();
        assert!(lines >= 2, "frame at row {top}: {lines} chance lines (near-white pixels per row: {rows:?})");
    }
    // The step plot holds a DoA curve (orange) of the last finished episode.
    let (top, bottom, left, right) = frames[1];
    let doa = (top..bottom)
        .flat_map(|y| (left..right).map(move |x| (x, y)))
        .filter(|&(x, y)| close(at(x, y), [235, 140, 40], 30))
        .count();
    assert!(doa >= 20, "{doa} pixels of the DoA curve in the step plot");
}

#[test]
fn ctrl_c_ends_the_viewer_as_an_interruption_not_an_error() {
    // Ctrl-C in the terminal (SIGINT to coevo, not to the X server): status 130 and one line saying so,
    // never "coevo: error: viewer exited with code 130".
    let _one_at_a_time = DISPLAY.lock().unwrap_or_else(|e| e.into_inner());
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("ctrl-c-once.ron");
    std::fs::copy("scenes/standard.ron", &scene).unwrap();
    let err = dir.path().join("stderr.txt");
    let mut command = Command::new("xvfb-run");
    command
        .args(["-a", "-s", &format!("-screen 0 {WIDTH}x{HEIGHT}x24"), BIN, "--scene", scene.to_str().unwrap()])
        .env("XDG_RUNTIME_DIR", dir.path())
        .stdout(std::process::Stdio::null())
        .stderr(std::fs::File::create(&err).unwrap());
    // A test harness started in the background (`cmd &` in a script) ignores SIGINT, one started by nohup
    // ignores SIGHUP, and an ignored signal stays ignored across exec. Either leaves the viewer without
    // Bevy's Ctrl-C handler: ctrlc installs it only over the default dispositions of SIGINT, SIGTERM and
    // SIGHUP (ctrlc 3.5, `termination`), and the Ctrl-C this test sends then kills it outright. Restored to
    // the defaults, as a terminal's foreground job has them.
    // SAFETY: between fork and exec only `signal`, which is async-signal-safe, is called.
    unsafe {
        std::os::unix::process::CommandExt::pre_exec(&mut command, || {
            for signal in [libc::SIGINT, libc::SIGTERM, libc::SIGHUP] {
                libc::signal(signal, libc::SIG_DFL);
            }
            Ok(())
        });
    }
    let mut child = command.spawn().unwrap();
    // The app is running (and Bevy's handler installed) once its renderer says what it runs on.
    let start = std::time::Instant::now();
    while !std::fs::read_to_string(&err).unwrap_or_default().contains("coevo::viewer") {
        assert!(start.elapsed().as_secs() < 120, "the viewer did not start: {:?}", std::fs::read_to_string(&err));
        std::thread::sleep(std::time::Duration::from_millis(200));
    }
    let pattern = format!("^{BIN} --scene {}", scene.display());
    let pid = String::from_utf8(Command::new("pgrep").args(["-f", &pattern]).output().unwrap().stdout).unwrap();
    let pid = pid.trim();
    assert!(!pid.is_empty() && Command::new("kill").args(["-INT", pid]).status().unwrap().success(), "{pid:?}");
    // Never a hang: a viewer still running a minute after Ctrl-C fails the test.
    let start = std::time::Instant::now();
    let status = loop {
        if let Some(status) = child.try_wait().unwrap() {
            break status;
        }
        if start.elapsed().as_secs() > 60 {
            let _ = Command::new("kill").args(["-KILL", pid]).status();
            panic!("the viewer did not end within 60 s of Ctrl-C: {}", std::fs::read_to_string(&err).unwrap());
        }
        std::thread::sleep(std::time::Duration::from_millis(200));
    };
    let stderr = std::fs::read_to_string(&err).unwrap();
    assert_eq!(status.code(), Some(130), "exit {status:?}: {stderr}");
    assert!(stderr.contains("coevo: interrupted") && !stderr.contains("coevo: error"), "{stderr}");
}

#[test]
fn the_selected_agents_rule_is_drawn_around_it_and_a_bad_species_is_one_line() {
    // The shipped run, paused on its first state, the same agent selected: with the overlay the arena
    // gains the field's red and blue cells around the selected prey, and nothing else changes (the panel's
    // checkbox aside, the same frame).
    let run = "assets/trained-standard";
    let args = ["--watch", run, "--select", "5", "--paused", "--seed", "4"];
    let (w, h, plain) = screenshot(&args);
    let (_, _, ruled) = screenshot(&[&args[..], &["--rule-of", "predator"]].concat());
    // Only the arena (between the panels) counts: the panel's checkbox differs too.
    let (x0, x1) = (w * 3 / 10, w * 7 / 10);
    let tinted = |p: &[u8; 3]| (p[0] as i32 - p[1] as i32).abs() > 25 || (p[2] as i32 - p[1] as i32).abs() > 25;
    let changed = (0..h)
        .flat_map(|y| (x0..x1).map(move |x| (y * w + x) as usize))
        .filter(|&i| plain[i] != ruled[i] && tinted(&ruled[i]))
        .count();
    assert!(changed > 2000, "{changed} arena pixels tinted by the rule overlay");
    let out = under_xvfb(&["--watch", run, "--select", "5", "--rule-of", "hawk", "--screenshot", "/tmp/none.png"]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && stderr.contains("--rule-of hawk: no species of that name"), "{stderr}");
    assert!(!Path::new("/tmp/none.png").exists());
}

#[test]
fn watching_fifty_prey_the_plots_are_whole_and_a_smaller_window_is_refused() {
    // Watching a run, the per-episode plot's title is the longest (the run's training, then the episodes
    // watched): the three plots still fit at the minimum size, the catches plot with its axis.
    let (w, h, pixels) = screenshot(&["--watch", "assets/trained-standard", "--prey", "50", "--steps-per-frame", "5"]);
    let frames = plot_frames(w, h, &pixels);
    assert_eq!(frames.len(), 3, "per episode, step by step, catches: {frames:?}");
    let (_, last_bottom, _, _) = frames[2];
    assert!(last_bottom + 30 <= h, "the catches plot and its axis are whole: frame ends at row {last_bottom} of {h}");
    // Below the minimum: one line, no window.
    let out = under_xvfb(&["--window", "1024x600", "--frames", "2", "--screenshot", "/tmp/coevo-too-small.png"]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && stderr.contains("--window 1024x600: expected WxH of at least 1280x720"),
        "{stderr}"
    );
    assert!(!Path::new("/tmp/coevo-too-small.png").exists());
}

/// Asks every top-level window named "coevo…" to close, as a window manager's close button does
/// (WM_DELETE_WINDOW): once one exists and `after` seconds have passed. Debian's python3-xlib (.ci/run).
const CLOSE_WINDOW: &str = include_str!("close_window.py");

#[test]
fn closing_the_window_during_save_run_says_how_far_the_kept_folder_goes() {
    // Live training kept with --save-run, the window closed by its close button mid-run: an ordinary
    // exit (status 0) that says how many episodes the folder holds and where its checkpoint is, and the
    // folder holds exactly that many rows.
    let _one_at_a_time = DISPLAY.lock().unwrap_or_else(|e| e.into_inner());
    let dir = tempfile::tempdir().unwrap();
    let mut scene = Scene::load(Path::new("scenes/paper.ron")).unwrap();
    scene.episode_steps = 50;
    let file = dir.path().join("short.ron");
    std::fs::write(&file, scene.to_ron()).unwrap();
    let close = dir.path().join("close.py");
    std::fs::write(&close, CLOSE_WINDOW).unwrap();
    let (saved, out, status) = (dir.path().join("saved"), dir.path().join("out.txt"), dir.path().join("status"));
    let (closer, err) = (dir.path().join("closer.txt"), dir.path().join("err.txt"));
    let script = format!(
        // A viewer that ignored the close is killed after a minute (status 137): a failure, never a hang.
        "{BIN} --scene {} --steps-per-frame 25 --save-run {} > {} 2>{} & pid=$!; /usr/bin/python3 {} 8 > {} 2>&1; \
         echo \"closer: $?\" >> {}; \
         for i in $(seq 300); do kill -0 $pid 2>/dev/null || break; sleep 0.2; done; kill -9 $pid 2>/dev/null; \
         wait $pid; echo $? > {}",
        file.display(),
        saved.display(),
        out.display(),
        err.display(),
        close.display(),
        closer.display(),
        closer.display(),
        status.display()
    );
    let run = Command::new("xvfb-run")
        .args(["-a", "-s", &format!("-screen 0 {WIDTH}x{HEIGHT}x24"), "sh", "-c", &script])
        .env("XDG_RUNTIME_DIR", dir.path())
        .output()
        .expect("xvfb-run");
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    let stdout = std::fs::read_to_string(&out).unwrap();
    let closer = std::fs::read_to_string(&closer).unwrap();
    assert!(closer.ends_with("closer: 0\n"), "the close was not sent: {closer}");
    let stderr = std::fs::read_to_string(&err).unwrap();
    assert_eq!(std::fs::read_to_string(&status).unwrap().trim(), "0", "{stdout}{stderr}");
    let line = stdout.lines().find(|l| l.contains("holds the live run's")).unwrap_or_else(|| panic!("{stdout}"));
    let episodes: usize =
        line.split("holds the live run's ").nth(1).unwrap().split(' ').next().unwrap().parse().unwrap();
    let rows = std::fs::read_to_string(saved.join("metrics.csv")).unwrap().lines().count() - 1;
    assert!(episodes >= 2 && rows == episodes, "{line}: the folder holds {rows} rows");
    assert!(line.contains("checkpointed at episode") && line.contains("--resume continues from there"), "{line}");
}
