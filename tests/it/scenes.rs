//! Scene files: presets, overrides, and one clear error line for every kind of bad input.

use coevo::scene::{Boundary, ContactJudging, Policy, Scene, SpeedClip};
use std::path::Path;

fn err(text: &str) -> String {
    Scene::parse(text, "bad.ron").expect_err("scene should be refused").to_string()
}

#[test]
fn every_shipped_scene_loads() {
    for entry in std::fs::read_dir("scenes").unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_some_and(|e| e == "ron") {
            Scene::load(&path).unwrap_or_else(|e| panic!("{e}"));
        }
    }
}

#[test]
fn the_default_scene_is_the_authors_code_seen_from_each_body() {
    // What --train and the viewer open: the condition with interaction-driven swarming (README).
    let s = Scene::load(Path::new("scenes/standard.ron")).unwrap();
    let gym = Scene::load(Path::new("scenes/gym-pps.ron")).unwrap();
    assert_eq!(s.observation_frame, coevo::scene::ObservationFrame::Body);
    assert_eq!(Scene { observation_frame: gym.observation_frame, ..s }, gym, "otherwise the gym-pps scene");
}

#[test]
fn paper_scene_is_the_papers_setup() {
    let s = Scene::load(Path::new("scenes/paper.ron")).unwrap();
    assert_eq!(s.world.boundary, Boundary::Periodic);
    assert_eq!((s.species[0].name.as_str(), s.species[0].count), ("predator", 3));
    assert_eq!((s.species[1].name.as_str(), s.species[1].count), ("prey", 10));
    assert_eq!((s.episode_steps, s.episodes), (500, 2000));
    assert_eq!(s.species[0].max_turn_rate, 0.5);
    assert_eq!(s.max_distance(), 2f64.sqrt());
}

#[test]
fn presets_differ_where_the_authors_code_differs() {
    let paper = Scene::preset("paper").unwrap();
    let gym = Scene::preset("gym-pps").unwrap();
    assert_eq!((paper.species[0].mass, gym.species[0].mass), (1.0, 3.0));
    assert_eq!((paper.species[1].max_turn_rate, gym.species[1].max_turn_rate), (0.5, 5.0));
    assert_eq!((paper.world.speed_clip, gym.world.speed_clip), (SpeedClip::Norm, SpeedClip::PerComponent));
    assert_eq!((paper.world.wall_stiffness, gym.world.wall_stiffness), (50.0, 100.0));
    assert_eq!((paper.rewards.contact, gym.rewards.contact), (1.0, 5.0));
    assert_eq!(gym.rewards.contacts_judged, ContactJudging::BeforeMove);
    let walls = Scene::load(Path::new("scenes/confined.ron")).unwrap();
    assert_eq!(walls.max_distance(), 2.0 * 2f64.sqrt());
    assert_eq!(walls.species[0].policy, Policy::ChaseNearest);
}

#[test]
fn the_many_eyes_scene_is_the_default_scene_with_predators_seen_only_within_a_twelfth_of_d() {
    let mut many_eyes = Scene::load(Path::new("scenes/many-eyes.ron")).unwrap();
    let standard = Scene::load(Path::new("scenes/standard.ron")).unwrap();
    let prey = many_eyes.species.iter_mut().find(|s| s.name == "prey").unwrap();
    assert_eq!(prey.perception_of.len(), 1, "{:?}", prey.perception_of);
    assert_eq!(prey.perception_of[0].0, "predator");
    prey.perception_of.clear();
    assert_eq!(many_eyes, standard, "nothing else differs");
}

#[test]
fn the_resolved_scene_loads_back_identically() {
    let s = Scene::load(Path::new("scenes/confined-penalty.ron")).unwrap();
    assert_eq!(Scene::parse(&s.to_ron(), "resolved.ron").unwrap(), s);
}

#[test]
fn a_scene_can_add_a_species() {
    let s = Scene::parse(
        r#"(
            species: [(name: "apex", count: 1, mass: 2.0, radius: 0.08, max_speed: 0.4, max_thrust: 1.0,
                       max_turn_rate: 0.5, perception: Full, topological_limit: 6, colour: (0.8, 0.1, 0.1),
                       catches: ["predator"], policy: ChaseNearest)],
        )"#,
        "third.ron",
    )
    .unwrap();
    assert_eq!(s.species.len(), 3);
    assert_eq!(s.species[2].catches, vec!["predator".to_string()]);
}

#[test]
fn errors_name_file_line_and_field() {
    assert_eq!(err("(\n  wrld: (),\n)").split(": Unexpected").next().unwrap(), "bad.ron:2: wrld");
    assert_eq!(err("(\n  world: (\n    drag: \"much\",\n  ),\n)"), "bad.ron:3: drag: Expected float");
    assert_eq!(
        err("(\n  species: [\n    (name: \"prey\",\n     mass: -1.0),\n  ],\n)"),
        "bad.ron:4: species[prey].mass: must be a finite number > 0 (got -1)"
    );
    assert_eq!(err("(\n  preset: \"papr\",\n)"), "bad.ron:2: preset: unknown preset \"papr\" (known: paper, gym-pps)");
    assert!(err("(species: [(name: \"predator\", count: 0), (name: \"prey\", count: 0)])")
        .contains("species: every species has count 0"));
    assert!(err("(species: [(name: \"prey\", radius: 1.5)])")
        .contains("species[prey].radius: body diameter 3 m does not fit"));
    assert!(err("(world: (arena_edge: 0.0))").contains("world.arena_edge: must be a finite number > 0"));
    assert!(
        err("(world: (drag: NaN))").contains("world.drag: must be a finite number"),
        "{}",
        err("(world: (drag: NaN))")
    );
    assert!(err("(species: [(name: \"prey\", catches: [\"shark\"])])").contains("no species named \"shark\""));
    assert!(err("(species: [(name: \"apex\", count: 1)])").contains(
        "species[apex]: no preset or species plugin of this program defines \"apex\"; a new species must set: mass"
    ));
    assert!(err("(species: [(count: 1)])").contains("species[0].name: every species entry needs a name"));
    assert!(err("(learning: (gamma: 1.5))").contains("learning.gamma: must be in [0, 1]"));
    let missing = Scene::load(Path::new("scenes/nope.ron")).unwrap_err().to_string();
    assert!(missing.starts_with("scenes/nope.ron: cannot read scene"), "{missing}");
}

/// The shipped scenes are built into the binary: `coevo --train` works from a folder outside the clone
/// and trains exactly scenes/standard.ron, `--scene scenes/paper.ron` exactly that file; any other scene
/// named on the command line is still read from disk.
#[test]
fn the_default_scene_works_outside_the_clone() {
    let dir = tempfile::tempdir().unwrap();
    let coevo = |args: &[&str]| {
        std::process::Command::new(env!("CARGO_BIN_EXE_coevo")).args(args).current_dir(dir.path()).output().unwrap()
    };
    let out = coevo(&["--train", "--episodes", "1", "--quiet", "--out", "run"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let trained = coevo::scene::Scene::load(&dir.path().join("run/scene.ron")).unwrap();
    let standard = coevo::scene::Scene::load(std::path::Path::new("scenes/standard.ron")).unwrap();
    assert_eq!(trained.to_ron(), standard.to_ron());
    let out = coevo(&["--train", "--episodes", "1", "--quiet", "--scene", "scenes/paper.ron", "--out", "paper"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let trained = coevo::scene::Scene::load(&dir.path().join("paper/scene.ron")).unwrap();
    let paper = coevo::scene::Scene::load(std::path::Path::new("scenes/paper.ron")).unwrap();
    assert_eq!(trained.to_ron(), paper.to_ron());
    let out = coevo(&["--train", "--episodes", "1", "--scene", "scenes/mine.ron", "--out", "other"]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && stderr.contains("scenes/mine.ron: cannot read scene"), "{stderr}");
    // Every shipped scene is described there too, as in the clone.
    for entry in std::fs::read_dir("scenes").unwrap() {
        let name = format!("scenes/{}", entry.unwrap().file_name().to_string_lossy());
        let out = coevo(&["--describe-scene", &name]);
        assert!(out.status.success(), "{name}: {}", String::from_utf8_lossy(&out.stderr));
        let here =
            std::process::Command::new(env!("CARGO_BIN_EXE_coevo")).args(["--describe-scene", &name]).output().unwrap();
        let text = |o: &std::process::Output| String::from_utf8_lossy(&o.stdout).into_owned();
        assert_eq!(text(&out), text(&here), "{name}: the built-in copy is the file");
    }
    // After a training outside the clone, the hint to watch it names no folder the user did not give.
    let out = coevo(&["--train", "--episodes", "1", "--out", "hinted"]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(stdout.contains("--watch hinted") && !stdout.contains("CLONE"), "{stdout}");
}
