//! The viewer, in a real window: `coevo --screenshot` under Xvfb, and the PNG it writes checked for size,
//! content and the species' colours in the pixel proportions their bodies should cover. Also the refusals
//! that happen before a window opens. Built only with `--features viewer` (see `.ci/run`).
#![cfg(feature = "viewer")]

use coevo::learning::Mode;
use coevo::scene::Scene;
use coevo::train::{train, TrainOptions};
use coevo::viewer::{RunMode, Setup};
use std::path::{Path, PathBuf};
use std::process::Command;

const BIN: &str = env!("CARGO_BIN_EXE_coevo");
const WIDTH: u32 = 1280;
const HEIGHT: u32 = 720;

/// Runs the viewer under a virtual X server (`xvfb-run`, Debian's xvfb); fails if there is none.
fn under_xvfb(args: &[&str]) -> std::process::Output {
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

#[test]
fn a_screenshot_of_the_standard_scene_shows_the_arena_and_both_species() {
    let dir = tempfile::tempdir().unwrap();
    let shot = dir.path().join("standard.png");
    let out = under_xvfb(&[
        "--scene",
        "scenes/standard.ron",
        "--rules",
        "--seed",
        "3",
        "--window",
        &format!("{WIDTH}x{HEIGHT}"),
        "--frames",
        "30",
        "--screenshot",
        shot.to_str().unwrap(),
    ]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "viewer failed: {}\n{stderr}", out.status);
    assert!(String::from_utf8_lossy(&out.stdout).contains("fps over frames"), "the frame rate is reported");
    assert!(!dir.path().join("standard.png.tmp").exists(), "no temporary file is left");

    let (w, h, pixels) = read_png(&shot);
    assert_eq!((w, h), (WIDTH, HEIGHT));
    let at = |x: u32, y: u32| pixels[(y * w + x) as usize];

    // The arena floor, to scale: its extent gives pixels per metre.
    let floor = srgb8([0.98, 0.98, 0.97]);
    let (mut x0, mut x1, mut y0, mut y1) = (w, 0, h, 0);
    for y in 0..h {
        for x in 0..w {
            if close(at(x, y), floor, 2) {
                (x0, x1, y0, y1) = (x0.min(x), x1.max(x), y0.min(y), y1.max(y));
            }
        }
    }
    assert!(x1 > x0 + 300 && y1 > y0 + 300, "the arena floor fills a good part of the window ({x0}..{x1} × {y0}..{y1})");
    let (aw, ah) = ((x1 - x0 + 1) as f64, (y1 - y0 + 1) as f64);
    assert!((aw / ah - 1.0).abs() < 0.03, "the arena is square on screen: {aw} × {ah}");

    let scene = Scene::load(Path::new("scenes/standard.ron")).unwrap();
    let per_metre = aw / scene.world.arena_edge;
    let mut covered = Vec::new();
    for s in &scene.species {
        let colour = srgb8(s.colour);
        let counted = pixels.iter().filter(|p| close(**p, colour, 6)).count() as f64;
        // Bodies are discs of the body radius; their anti-aliased rims, the heading lines and overlaps
        // take some pixels away, none are added.
        let expected = s.count as f64 * std::f64::consts::PI * (s.radius * per_metre).powi(2);
        let ratio = counted / expected;
        eprintln!("{}: {counted} pixels, {expected:.0} expected ({ratio:.2})", s.name);
        assert!((0.55..=1.1).contains(&ratio), "{}: {counted} pixels of its colour, {expected:.0} expected from its bodies", s.name);
        covered.push(counted);
    }
    // Nothing else on screen has those colours.
    assert!(covered.iter().all(|&c| c > 200.0));
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
    let mut s = Scene::load(Path::new("scenes/standard.ron")).unwrap();
    s.episode_steps = 10;
    s.learning.hidden = 8;
    s.learning.buffer_capacity = 500;
    let run = dir.join("run");
    train(s, &TrainOptions { run: run.clone(), resume: false, episodes: Some(1), progress: false }).unwrap();
    run
}

#[test]
fn watching_a_run_loads_its_actors_and_refuses_a_scene_they_do_not_fit() {
    let dir = tempfile::tempdir().unwrap();
    let run = tiny_run(dir.path());
    let scene = Scene::load(&run.join("scene.ron")).unwrap();
    let watch = |scene: Scene| Setup { scene, source: run.join("scene.ron"), mode: RunMode::Watch(run.clone()) }.prepare();

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
    let err = watch(other).err().expect("a mismatched checkpoint is refused");
    assert!(err.starts_with("checkpoint refused:") && err.contains("prey-actor.safetensors") && err.contains("observation size"), "{err}");

    // A species the run never trained has no actor to load.
    let mut renamed = scene;
    renamed.species[1].name = "fish".into();
    renamed.species[0].catches = vec!["fish".into()];
    let err = watch(renamed).err().expect("an unknown species is refused");
    assert!(err.contains("fish-actor.safetensors"), "{err}");
}

#[test]
fn rule_based_mode_replaces_learned_species_by_chase_and_flee() {
    let scene = Scene::load(Path::new("scenes/standard.ron")).unwrap();
    let (scene, learners) = Setup { scene, source: "scenes/standard.ron".into(), mode: RunMode::RuleBased }.prepare().unwrap();
    use coevo::scene::Policy;
    assert_eq!(scene.species[0].policy, Policy::ChaseNearest);
    assert_eq!(scene.species[1].policy, Policy::FleeNearest);
    assert!(learners.species.iter().all(Option::is_none), "nothing learns");
}
