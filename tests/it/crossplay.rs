//! Snapshots and cross-play (`coevo --crossplay`): snapshots at the right episodes; a run played against
//! itself with identical snapshots gives identical cells; predators that never move catch only what the
//! prey's own motion brings them; bad requests are one line.

use coevo::analysis::crossplay::{crossplay, CrossplayOptions};
use coevo::analysis::crossplay_matrix::Matrix;
use coevo::analysis::crossplay_readouts::{readouts, READOUTS};
use coevo::learning::nets::Mlp;
use coevo::learning::{Learners, Mode};
use coevo::run::train::{train, TrainOptions};
use coevo::scene::{Overrides, Scene};
use coevo::store::snapshots::{load_snapshot, save_snapshot, snapshot_episodes};
use std::path::{Path, PathBuf};

use crate::common;

/// A small scene trained for 5 episodes with snapshots every 2: episodes 0, 2, 4 and 5 (the end).
fn trained(dir: &Path) -> (Scene, PathBuf) {
    let mut scene = Scene::preset("paper").unwrap();
    scene.seed = 5;
    scene.species[0].count = 2;
    scene.species[1].count = 6;
    scene.episode_steps = 60;
    scene.learning.hidden = 16;
    scene.learning.batch_size = 32;
    scene.learning.warmup_transitions = 32;
    scene.learning.buffer_capacity = 5_000;
    scene.learning.snapshot_every = 2;
    let run = dir.join("run");
    train(scene.clone(), &TrainOptions::new(&run, Some(5))).unwrap();
    (scene, run)
}

fn play(run: &Path) -> Matrix {
    let opts = CrossplayOptions { run: run.into(), episodes: 2, overrides: Overrides::default(), progress: false };
    let (mut matrices, written) = crossplay(&opts).unwrap();
    assert_eq!(matrices.len(), 1);
    assert!(written.iter().any(|w| w.ends_with("crossplay.csv")) && run.join("figures/crossplay.png").exists());
    matrices.remove(0)
}

/// The shape every actor of `species` has in `scene`.
fn like(scene: &Scene, species: usize) -> Mlp {
    Learners::new(scene, Mode::Evaluate).species[species].as_ref().unwrap().ddpg.actor.clone()
}

/// `actor` made still: the last layer's weights zeroed and its bias at tanh⁻¹(−1) for thrust (zero
/// thrust) and 0 for the turn rate, whatever it observes; the hidden layers stay as they were.
fn still(mut actor: Mlp) -> Mlp {
    let mut parameters = actor.parameters();
    let n = parameters.len();
    parameters[n - 2].iter_mut().for_each(|w| *w = 0.0);
    parameters[n - 1].copy_from_slice(&[-20.0, 0.0]);
    actor.set_parameters(&parameters);
    actor
}

#[test]
fn snapshots_are_kept_at_the_right_episodes_and_refused_by_name() {
    let dir = tempfile::tempdir().unwrap();
    let (scene, run) = trained(dir.path());
    for species in ["prey", "predator"] {
        assert_eq!(snapshot_episodes(&run, species), vec![0, 2, 4, 5], "{species}");
    }
    // The last snapshot is the trained actor of the checkpoint, byte for byte.
    assert_eq!(
        std::fs::read(run.join("snapshots/prey-ep00005.safetensors")).unwrap(),
        std::fs::read(run.join("checkpoint/prey-actor.safetensors")).unwrap()
    );
    let e = load_snapshot(&run, "prey", 3, &like(&scene, 1)).unwrap_err().to_string();
    assert!(e.contains("no snapshot of prey after 3 episodes") && e.contains("episodes 0, 2, 4, 5"), "{e}");
    let e = load_snapshot(&run, "hawk", 2, &like(&scene, 1)).unwrap_err().to_string();
    assert!(e.contains("no snapshot of hawk") && !e.contains('\n'), "{e}");
    // A run without snapshots: one line from the command, nothing written.
    std::fs::remove_dir_all(run.join("snapshots")).unwrap();
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_coevo")).arg("--crossplay").arg(&run).output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && stderr.trim().lines().count() == 1 && stderr.contains("snapshot"), "{stderr}");
    assert!(!run.join("crossplay.csv").exists());
}

#[test]
fn a_run_against_itself_with_identical_snapshots_gives_identical_cells() {
    let dir = tempfile::tempdir().unwrap();
    let (_, run) = trained(dir.path());
    let snapshots = run.join("snapshots");
    for species in ["prey", "predator"] {
        let first = snapshots.join(format!("{species}-ep00000.safetensors"));
        for e in [2, 4, 5] {
            std::fs::copy(&first, snapshots.join(format!("{species}-ep{e:05}.safetensors"))).unwrap();
        }
    }
    common::reseal_snapshots(&run);
    let m = play(&run);
    assert_eq!((m.prey_episodes.clone(), m.predator_episodes.clone()), (vec![0, 2, 4, 5], vec![0, 2, 4, 5]));
    // crossplay.csv reads back as the matrix, to the last digit; the mean of two equal matrices is it.
    let read = coevo::analysis::crossplay_matrix::read_matrix(&run, &m.pair).unwrap().unwrap();
    assert_eq!((&read.prey_episodes, &read.cells), (&m.prey_episodes, &m.cells));
    let mean = coevo::analysis::crossplay_matrix::mean_matrix(&[read.clone(), read]).unwrap();
    assert_eq!(mean.cells, m.cells);
    let first = m.cells[0][0];
    assert!(first.catches > 0.0 && first.doa > 0.0, "{first:?}");
    assert!(m.cells.iter().flatten().all(|c| *c == first), "{:?}", m.cells);
    assert_eq!(readouts(&m).iter().map(|r| r.name).collect::<Vec<_>>(), READOUTS);
    // Nothing changes, so no read-out finds an order, and no part of a change; the one level, the final
    // predators' catches of naive prey, is the one cell.
    for r in readouts(&m) {
        match r.name {
            "final_predators_vs_naive_prey" => assert_eq!(r.value, Some(first.catches)),
            _ => assert!(r.value.is_none_or(|v| v == 0.0), "{} = {:?}", r.name, r.value),
        }
    }
    let (prey, predators) = coevo::analysis::crossplay_readouts::ratings(&m);
    assert!(prey.iter().chain(&predators).all(|r| *r == 0.0), "{prey:?} {predators:?}");
    // crossplay-ratings.csv reads back as the ratings, per species (what the viewer plots).
    let read = coevo::analysis::crossplay_readouts::read_ratings(&run).expect("crossplay-ratings.csv");
    let names: Vec<&str> = read.iter().map(|(s, _)| s.as_str()).collect();
    assert_eq!(names, ["prey", "predator"]);
    assert_eq!(read[1].1, [[0.0, 0.0], [2.0, 0.0], [4.0, 0.0], [5.0, 0.0]]);
}

#[test]
fn predators_that_never_move_catch_only_what_the_prey_bring_them() {
    let dir = tempfile::tempdir().unwrap();
    let (scene, run) = trained(dir.path());
    // Every predator snapshot still (different hidden layers, the same zero action); the initial prey
    // snapshot still too.
    for e in [0, 2, 4, 5] {
        let actor = load_snapshot(&run, "predator", e, &like(&scene, 0)).unwrap();
        save_snapshot(&run, &scene, "predator", e, &still(actor)).unwrap();
    }
    let prey0 = load_snapshot(&run, "prey", 0, &like(&scene, 1)).unwrap();
    save_snapshot(&run, &scene, "prey", 0, &still(prey0)).unwrap();
    // Snapshots changed by hand are refused as damaged until the checkpoint's manifest says otherwise.
    let opts = CrossplayOptions { run: run.clone(), episodes: 2, overrides: Overrides::default(), progress: false };
    assert!(crossplay(&opts).unwrap_err().to_string().contains("changed since the checkpoint was written"));
    common::reseal_snapshots(&run);
    let m = play(&run);
    // Nobody moves: no catch.
    assert!(m.cells[0].iter().all(|c| c.catches == 0.0), "{:?}", m.cells[0]);
    // Which still predators stand there changes nothing: every row is constant across the columns.
    for row in &m.cells {
        assert!(row.iter().all(|c| c == &row[0]), "{row:?}");
    }
    assert!(m.cells[1..].iter().any(|r| r[0].catches > 0.0), "moving prey run into still predators: {:?}", m.cells);
    let predator_progress = readouts(&m).into_iter().find(|r| r.name == "predator_progress_vs_fixed_prey").unwrap();
    assert_eq!(predator_progress.value, None, "no predator generation differs from another");
}

#[test]
fn an_evaluation_deploys_the_snapshots_it_is_asked_for() {
    let dir = tempfile::tempdir().unwrap();
    let (_, run) = trained(dir.path());
    let eval = |extra: &[&str], out: &str| {
        let mut args = vec!["--eval", run.to_str().unwrap(), "--episodes", "1", "--steps", "20", "--eval-out", out];
        args.extend_from_slice(extra);
        std::process::Command::new(env!("CARGO_BIN_EXE_coevo")).args(&args).output().unwrap()
    };
    let read = |out: &str| std::fs::read_to_string(run.join(out)).unwrap();
    // The last snapshot is the trained actor: the same evaluation, to the last digit.
    let out = eval(&[], "trained.csv");
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let out = eval(&["--snapshot", "prey=5", "--snapshot", "predator=5"], "last.csv");
    assert!(
        String::from_utf8_lossy(&out.stdout).contains("snapshots: prey after 5 episodes, predator after 5 episodes")
    );
    assert_eq!(read("trained.csv"), read("last.csv"));
    // An earlier snapshot is another actor.
    assert!(eval(&["--snapshot", "prey=0"], "first.csv").status.success());
    assert_ne!(read("trained.csv"), read("first.csv"));
    for (args, says) in [
        (vec!["--snapshot", "prey=3"], "no snapshot of prey after 3 episodes"),
        (vec!["--snapshot", "hawk=2"], "--snapshot hawk=2: no learning species named \"hawk\""),
        (vec!["--snapshot", "prey"], "--snapshot prey: expected NAME=EPISODE"),
        (vec!["--snapshot", "prey=2", "--untrained"], "--untrained: deploys the networks"),
    ] {
        let out = eval(&args, "bad.csv");
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(
            !out.status.success() && stderr.trim().lines().count() == 1 && stderr.contains(says),
            "{says}: {stderr}"
        );
        assert!(!run.join("bad.csv").exists());
    }
}

#[test]
fn each_predator_prey_pair_of_learning_species_gets_its_own_matrix() {
    let dir = tempfile::tempdir().unwrap();
    let mut scene = Scene::preset("paper").unwrap();
    scene.episode_steps = 30;
    scene.learning.hidden = 16;
    scene.learning.batch_size = 32;
    scene.learning.warmup_transitions = 32;
    scene.learning.snapshot_every = 1;
    scene.species[0].count = 1;
    scene.species[1].count = 5;
    // A second predator species, "hawk", that also catches the prey.
    let mut hawk = scene.species[0].clone();
    hawk.name = "hawk".into();
    scene.species.push(hawk);
    let run = dir.path().join("run");
    train(scene, &TrainOptions::new(&run, Some(2))).unwrap();
    let opts = CrossplayOptions { run: run.clone(), episodes: 1, overrides: Overrides::default(), progress: false };
    let (matrices, _) = crossplay(&opts).unwrap();
    let pairs: Vec<(String, String)> =
        matrices.iter().map(|m| (m.pair.prey_name.clone(), m.pair.predator_name.clone())).collect();
    assert_eq!(pairs, [("prey".to_string(), "predator".to_string()), ("prey".to_string(), "hawk".to_string())]);
    for stem in ["crossplay-prey-predator", "crossplay-prey-hawk"] {
        let cells = std::fs::read_to_string(run.join(format!("{stem}.csv"))).unwrap();
        assert_eq!(cells.lines().count(), 1 + 3 * 3, "{stem}: snapshots 0, 1, 2 of each side");
        assert!(run.join(format!("figures/{stem}.png")).exists());
    }
    let readouts = std::fs::read_to_string(run.join("crossplay-readouts.csv")).unwrap();
    assert!(
        readouts.lines().any(|l| l.starts_with("prey,hawk,"))
            && readouts.lines().any(|l| l.starts_with("prey,predator,"))
    );
}
