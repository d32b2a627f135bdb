//! Every error names its kind (`coevo::error::Kind`), so programs can tell a bad scene from a damaged
//! checkpoint, a busy run folder or a bad experiment file; the one line printed is unchanged.

use coevo::error::Kind;
use coevo::experiment::Experiment;
use coevo::learning::{Learners, Mode};
use coevo::scene::{Overrides, Scene};
use coevo::store::RunDir;
use std::path::Path;

#[test]
fn each_concern_classifies_its_errors() {
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path();
    // Scenes: a file that is not there, a value out of range, a count for a species the scene lacks.
    assert_eq!(Scene::load(&root.join("nothere.ron")).unwrap_err().kind, Kind::Scene);
    std::fs::write(root.join("bad.ron"), "(world: (dt: -1.0))").unwrap();
    let e = Scene::load(&root.join("bad.ron")).unwrap_err();
    assert_eq!(e.kind, Kind::Scene, "{e}");
    assert!(e.to_string().starts_with(&format!("{}:", root.join("bad.ron").display())), "{e}");
    let overrides = Overrides { counts: vec![("owl".into(), 3)], ..Default::default() };
    assert_eq!(overrides.load(Path::new("scenes/standard.ron")).unwrap_err().kind, Kind::Scene);
    // Checkpoints: actors asked of a folder that has none.
    let scene = Scene::load(Path::new("scenes/standard.ron")).unwrap();
    let mut learners = Learners::new(&scene, Mode::Evaluate);
    let e = coevo::store::load_actors(&mut learners, &scene, Some(root)).unwrap_err();
    assert_eq!(e.kind, Kind::Checkpoint, "{e}");
    // A manifest that is not a file is a damaged checkpoint, not a failure to read.
    let damaged = root.join("damaged");
    std::fs::create_dir_all(damaged.join("checkpoint/manifest.ron")).unwrap();
    let e = coevo::store::load_actors(&mut learners, &scene, Some(&damaged)).unwrap_err();
    assert!(e.to_string().contains("manifest.ron: is not a regular file"), "{e}");
    assert_eq!(e.kind, Kind::Checkpoint, "{e}");
    // Run folders: a second lock while the first is held; an evaluation output named like a run file.
    let run = RunDir::new(root.join("run"));
    let held = run.lock().unwrap();
    assert_eq!(run.lock().unwrap_err().kind, Kind::RunFolder);
    drop(held);
    assert_eq!(run.eval_output(Some("metrics.csv")).unwrap_err().kind, Kind::Input);
    // Experiment files.
    std::fs::write(root.join("exp.ron"), "(description: \"x\", seeds: [])").unwrap();
    let e = Experiment::load(&root.join("exp.ron"), &root.join("results")).unwrap_err();
    assert_eq!(e.kind, Kind::Experiment, "{e}");
    // Writes: into a folder that is a file.
    std::fs::write(root.join("file"), "x").unwrap();
    let e = coevo::io::write_file(&root.join("file/out.csv"), coevo::io::Existing::Refuse, b"x").unwrap_err();
    assert_eq!(e.kind, Kind::Io, "{e}");
}
