//! Information transfer (`coevo --eval RUN --perturb RADIANS`): one prey of a twin world is turned and the
//! other prey's headings are compared with the untouched world's. Without any observation nothing
//! responds; with observation the neighbours do; bad requests are one line.

use coevo::run::train::{train, TrainOptions};
use coevo::scene::{Perception, Scene};
use std::path::{Path, PathBuf};

/// A run of one short episode (its actors barely trained: they still act on what they observe).
fn run(dir: &Path, name: &str, scene: Scene) -> PathBuf {
    let run = dir.join(name);
    train(scene, &TrainOptions::new(&run, Some(1))).unwrap();
    run
}

fn scene() -> Scene {
    let mut s = Scene::preset("paper").unwrap();
    s.seed = 3;
    s.episode_steps = 60;
    s.learning.hidden = 16;
    s.learning.warmup_transitions = 32;
    s.learning.batch_size = 32;
    s
}

fn perturbed(run: &Path, extra: &[&str]) -> std::process::Output {
    let mut args = vec!["--eval", run.to_str().unwrap(), "--episodes", "2", "--eval-out", "p.csv"];
    args.extend_from_slice(extra);
    std::process::Command::new(env!("CARGO_BIN_EXE_coevo")).args(&args).output().unwrap()
}

/// (lag, rank_from, mean |Δheading|) of every row with samples.
fn response(run: &Path) -> Vec<(usize, usize, f64)> {
    let text = std::fs::read_to_string(run.join("p-perturbation.csv")).unwrap();
    text.lines()
        .skip(1)
        .map(|l| l.split(',').collect::<Vec<_>>())
        .filter(|c| c[4] != "0")
        .map(|c| (c[0].parse().unwrap(), c[1].parse().unwrap(), c[3].parse().unwrap()))
        .collect()
}

#[test]
fn nobody_who_sees_nobody_responds_and_neighbours_who_see_do() {
    let dir = tempfile::tempdir().unwrap();
    // Four prey, no predators, perception of a millionth of D, on a 60 m arena: no observation and (in
    // 60 steps) no contact.
    let mut blind = scene();
    blind.world.arena_edge = 60.0;
    blind.species[0].count = 0;
    blind.species[1].count = 4;
    blind.species[1].perception = Perception::FractionOfD(1e-6);
    let blind = run(dir.path(), "blind", blind);
    let out = perturbed(&blind, &["--perturb", "1.0", "--perturb-step", "10"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let rows = response(&blind);
    assert_eq!(rows.iter().filter(|r| r.0 == 1).count(), 3, "three other prey, ranks 1 to 3: {rows:?}");
    assert!(rows.iter().all(|r| r.2 == 0.0), "{rows:?}");
    // The default counts on the paper's arena, full perception: the turned prey's neighbours turn too.
    let seeing = run(dir.path(), "seeing", scene());
    let out = perturbed(&seeing, &["--perturb", "1.0"]);
    let line = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success() && line.contains("perturbation (one prey turned by 1 rad after step 30)"), "{line}");
    let rows = response(&seeing);
    assert!(rows.iter().any(|r| r.0 <= 10 && r.1 <= 6 && r.2 > 1e-6), "{rows:?}");
    // The evaluation itself is the untouched world's: the same file as without --perturb.
    let plain = seeing.join("p.csv");
    let with = std::fs::read(&plain).unwrap();
    assert!(perturbed(&seeing, &[]).status.success());
    assert_eq!(std::fs::read(&plain).unwrap(), with);
    // Bad requests: one line, nothing written.
    for (args, says) in [
        (vec!["--perturb", "0"], "--perturb 0: must be a finite, non-zero angle"),
        (vec!["--perturb", "1", "--perturb-step", "60"], "--perturb-step 60: must be between 1 and"),
        (vec!["--perturb-step", "5"], "--perturb-step: needs --perturb RADIANS"),
    ] {
        std::fs::remove_file(seeing.join("p-perturbation.csv")).ok();
        let out = perturbed(&seeing, &args);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(
            !out.status.success() && stderr.trim().lines().count() == 1 && stderr.contains(says),
            "{says}: {stderr}"
        );
        assert!(!seeing.join("p-perturbation.csv").exists());
    }
}
