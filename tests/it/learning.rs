//! The learning plugin end to end, on tiny runs: training, checkpoints, resume, evaluation, bad input.

use coevo::learning::{Learners, Mode};
use coevo::run::evaluate::{evaluate, EvalOptions};
use coevo::run::simulation as learning_simulation;
use coevo::run::train::{resume, train, TrainOptions};
use coevo::scene::Overrides;
use coevo::scene::{Policy, Scene};
use coevo::sim::perception::Batches;
use coevo::store::checkpoint;
use std::path::Path;

/// The standard scene shrunk to seconds: short episodes, small networks and batches.
fn tiny(episodes: usize) -> Scene {
    let mut s = Scene::load(Path::new("scenes/paper.ron")).unwrap();
    s.episode_steps = 20;
    s.episodes = episodes;
    s.learning.hidden = 16;
    s.learning.batch_size = 32;
    s.learning.warmup_transitions = 32;
    s.learning.buffer_capacity = 2_000;
    s.learning.updates_per_episode = 3;
    s.learning.checkpoint_every = 2;
    s
}

fn opts(run: &Path, episodes: Option<usize>) -> TrainOptions {
    TrainOptions { run: run.to_path_buf(), overwrite: false, episodes, progress: false }
}

/// metrics.csv without the wall-clock column, which is the one thing allowed to differ.
fn metrics_without_wall_clock(run: &Path) -> Vec<String> {
    std::fs::read_to_string(run.join("metrics.csv"))
        .unwrap()
        .lines()
        .map(|l| l.rsplit_once(',').unwrap().0.to_string())
        .collect()
}

/// An evaluation of `run`'s trained actors as they see (no control, no perturbation).
fn seeing(run: &Path, out: Option<String>, episodes: usize, overrides: Overrides) -> EvalOptions {
    EvalOptions {
        run: run.to_path_buf(),
        out,
        control: Default::default(),
        episodes,
        overrides,
        untrained: false,
        snapshots: vec![],
        perturb: None,
        perturb_step: None,
    }
}

#[test]
fn a_tiny_training_run_writes_scene_metrics_and_checkpoints() {
    let dir = tempfile::tempdir().unwrap();
    let run = dir.path().join("run");
    assert_eq!(train(tiny(5), &opts(&run, None)).unwrap(), 5, "episodes trained");
    let lines = metrics_without_wall_clock(&run);
    assert_eq!(lines.len(), 6, "header and one row per episode");
    let order = ["dos", "doa", "polarization", "milling", "clusters", "largest_cluster", "nn_correlation", "edge_rank"];
    let per_species = |s: &str| order.map(|q| format!("{q}_{s}")).join(",");
    assert!(
        lines[0].starts_with(&format!("episode,steps,{},{},catches", per_species("predator"), per_species("prey"))),
        "{}",
        lines[0]
    );
    assert!(lines[0].contains("critic_loss_prey,actor_loss_prey,noise_std_prey,epsilon_prey"));
    let header: Vec<&str> = lines[0].split(',').collect();
    let last: Vec<&str> = lines[5].split(',').collect();
    let cell = |name: &str| last[header.iter().position(|h| *h == name).unwrap()].parse::<f64>().unwrap();
    // Losses appear once the buffer has warmed up (13 agents × 20 steps per episode ≫ 32).
    assert!(cell("critic_loss_prey").is_finite(), "critic loss recorded: {}", lines[5]);
    // σ fell by the decay once per episode.
    assert!((cell("noise_std_prey") - (0.1 - 5.0 * 5e-5)).abs() < 1e-12);
    // Group structure is measured every episode: at least one cluster, the largest a fraction of N.
    assert!(cell("clusters_prey") >= 1.0 && (0.0..=1.0).contains(&cell("largest_cluster_prey")));
    Scene::load(&run.join("scene.ron")).expect("the resolved scene loads back");
    for f in ["prey-actor.safetensors", "prey-training.safetensors", "predator-actor.safetensors", "state.ron"] {
        assert!(run.join("checkpoint").join(f).exists(), "{f}");
    }
    assert!(!run.join("checkpoint.tmp").exists());
}

#[test]
fn same_scene_and_seed_give_identical_metrics() {
    let dir = tempfile::tempdir().unwrap();
    let (a, b, c) = (dir.path().join("a"), dir.path().join("b"), dir.path().join("c"));
    train(tiny(3), &opts(&a, None)).unwrap();
    train(tiny(3), &opts(&b, None)).unwrap();
    let mut other = tiny(3);
    other.seed = 99;
    train(other, &opts(&c, None)).unwrap();
    assert_eq!(metrics_without_wall_clock(&a), metrics_without_wall_clock(&b));
    assert_ne!(metrics_without_wall_clock(&a), metrics_without_wall_clock(&c));
}

#[test]
fn measuring_the_authors_metric_changes_nothing_the_training_does() {
    // `authors_metrics` adds columns to metrics.csv and nothing else: the same checkpoint to the byte,
    // every other column to the byte (a run that measures as the authors' code does is the same run).
    let dir = tempfile::tempdir().unwrap();
    let (plain, measured) = (dir.path().join("plain"), dir.path().join("measured"));
    train(tiny(3), &opts(&plain, None)).unwrap();
    let mut s = tiny(3);
    s.authors_metrics = true;
    train(s, &opts(&measured, None)).unwrap();
    let (a, b) = (metrics_without_wall_clock(&plain), metrics_without_wall_clock(&measured));
    let header: Vec<&str> = b[0].split(',').collect();
    let kept: Vec<usize> = (0..header.len()).filter(|&i| !header[i].starts_with("authors_")).collect();
    assert_eq!(header.len() - kept.len(), 4, "DoS and DoA by the code, per species: {}", b[0]);
    let without = |line: &String| -> String {
        let cells: Vec<&str> = line.split(',').collect();
        kept.iter().map(|&i| cells[i]).collect::<Vec<_>>().join(",")
    };
    assert_eq!(a, b.iter().map(without).collect::<Vec<_>>());
    // Every tensor to the byte; the files' metadata name their scene, which differs by the switch.
    for f in ["prey-actor.safetensors", "prey-training.safetensors", "predator-training.safetensors"] {
        let tensors = |run: &Path| {
            let bytes = std::fs::read(run.join("checkpoint").join(f)).unwrap();
            let header = u64::from_le_bytes(bytes[..8].try_into().unwrap()) as usize;
            bytes[8 + header..].to_vec()
        };
        let data = tensors(&plain);
        assert!(data.len() > 1000 && data == tensors(&measured), "{f} differs");
    }
}

#[test]
fn a_saved_actor_acts_identically_after_loading() {
    let dir = tempfile::tempdir().unwrap();
    let run = dir.path().join("run");
    train(tiny(2), &opts(&run, None)).unwrap();
    // Evaluate mode loads the run's actors; compare with a fresh training sim restored from the checkpoint.
    let scene = Scene::load(&run.join("scene.ron")).unwrap();
    let eval = learning_simulation(scene.clone(), Mode::Evaluate, Some(&run)).unwrap();
    let mut restored = learning_simulation(scene, Mode::Train, None).unwrap();
    {
        let mut learners = restored.world_mut().resource_mut::<Learners>();
        checkpoint::load(&run, &mut learners.species, &["predator".into(), "prey".into()]).unwrap();
    }
    let obs = eval.world().resource::<Batches>().species[1].observations.clone();
    let act = |sim: &coevo::sim::Simulation| {
        let l = sim.world().resource::<Learners>().species[1].as_ref().unwrap();
        l.ddpg.act(&l.dev, &obs, 10)
    };
    assert_eq!(act(&eval), act(&restored));
}

#[test]
fn resume_after_a_kill_continues_the_count_and_the_metrics() {
    let dir = tempfile::tempdir().unwrap();
    let run = dir.path().join("run");
    train(tiny(4), &opts(&run, None)).unwrap();
    // A kill after episode 4's checkpoint but before more rows: simulate rows written after it and a
    // half-written checkpoint folder, both of which resume must discard.
    let before = metrics_without_wall_clock(&run);
    std::fs::write(
        run.join("metrics.csv"),
        std::fs::read_to_string(run.join("metrics.csv")).unwrap() + "4,20,garbage\n",
    )
    .unwrap();
    std::fs::create_dir_all(run.join("checkpoint.tmp")).unwrap();
    std::fs::write(run.join("checkpoint.tmp/prey-actor.safetensors"), b"half").unwrap();
    assert_eq!(resume(&opts(&run, Some(7))).unwrap(), 3, "episodes 4, 5 and 6 trained");
    let after = metrics_without_wall_clock(&run);
    assert_eq!(after.len(), 8);
    let episodes: Vec<&str> = after[5..].iter().map(|l| l.split(',').next().unwrap()).collect();
    assert_eq!(episodes, ["4", "5", "6"]);
    assert_eq!(after[..5], before[..], "rows up to the checkpoint are kept as they were");
    assert!(after[5].starts_with("4,20,"));
    let state = std::fs::read_to_string(run.join("checkpoint/state.ron")).unwrap();
    assert!(state.contains("episodes_done: 7"), "{}", &state[..200.min(state.len())]);
}

#[test]
fn corrupt_missing_or_mismatched_checkpoints_are_refused_clearly() {
    let dir = tempfile::tempdir().unwrap();
    let run = dir.path().join("run");
    let missing = resume(&opts(&run, None)).unwrap_err().to_string();
    assert!(missing.contains("run: holds no coevo run to resume"), "{missing}");

    train(tiny(1), &opts(&run, None)).unwrap();
    std::fs::write(run.join("checkpoint/prey-actor.safetensors"), b"not a tensor file").unwrap();
    let eval = |counts: Vec<(String, usize)>| {
        evaluate(&seeing(&run, None, 1, Overrides { counts, episode_steps: Some(5), ..Default::default() }))
    };
    let corrupt = eval(vec![]).unwrap_err().to_string();
    assert!(corrupt.contains("prey-actor.safetensors: not a valid safetensors file"), "{corrupt}");

    // A checkpoint of another observation size: prey that see only 2 neighbours per species.
    let other = dir.path().join("other");
    let mut s = tiny(1);
    s.species[1].topological_limit = 2;
    train(s, &opts(&other, None)).unwrap();
    std::fs::copy(other.join("checkpoint/prey-actor.safetensors"), run.join("checkpoint/prey-actor.safetensors"))
        .unwrap();
    // Its metadata names its own scene, which the checkpoint's manifest does not: refused by that, before
    // its shapes are read.
    let mismatch = eval(vec![]).unwrap_err().to_string();
    assert!(mismatch.contains("prey-actor.safetensors: trained on another scene"), "{mismatch}");
}

#[test]
fn evaluation_deploys_on_fifty_prey_and_without_predators() {
    let dir = tempfile::tempdir().unwrap();
    let run = dir.path().join("run");
    train(tiny(2), &opts(&run, None)).unwrap();
    let line = evaluate(&seeing(
        &run,
        None,
        2,
        Overrides {
            counts: vec![("prey".into(), 50), ("predator".into(), 0)],
            episode_steps: Some(30),
            ..Default::default()
        },
    ))
    .unwrap();
    assert!(line.contains("predator: 0, prey: 50"), "{line}");
    let csv = std::fs::read_to_string(run.join("eval.csv")).unwrap();
    assert_eq!(csv.lines().count(), 1 + 2 * 30);
    assert!(csv.lines().skip(1).all(|l| l.ends_with(",0")), "no predators, no catches");
    // Every step is measured, the last of each episode too (it used to be read after the respawn).
    for line in csv.lines().skip(1) {
        let cols: Vec<&str> = line.split(',').collect();
        assert!(cols[2].parse::<f64>().is_ok_and(|d| d > 0.0 && d < 1.0) && cols[3].parse::<f64>().is_ok(), "{line}");
    }

    // The distributions beside it: nearest-neighbour distances sum to 1; no predators, an empty curve.
    let nn = std::fs::read_to_string(run.join("eval-nn.csv")).unwrap();
    let total: f64 = nn.lines().skip(1).map(|l| l.rsplit(',').next().unwrap().parse::<f64>().unwrap()).sum();
    assert!((total - 1.0).abs() < 1e-9, "{total}");
    // C(r) in bins of one prey diameter out to half the arena, every bin with pairs in it measured.
    let correlation = std::fs::read_to_string(run.join("eval-correlation.csv")).unwrap();
    let rows: Vec<Vec<&str>> = correlation.lines().skip(1).map(|l| l.split(',').collect()).collect();
    assert_eq!(rows.len(), (1.0 / 0.07f64).ceil() as usize, "{correlation}");
    assert!(
        rows.iter().all(|r| r[2] == "0" || r[3].parse::<f64>().is_ok_and(|c| (-1.0..=1.0).contains(&c))),
        "{correlation}"
    );
    let confusion = std::fs::read_to_string(run.join("eval-confusion.csv")).unwrap();
    assert!(confusion.lines().skip(1).all(|l| l.split(',').nth(2) == Some("0")), "{confusion}");
    // With predators, every predator decision after the first step lands in one bin of the curve.
    let steps = 20;
    evaluate(&seeing(
        &run,
        Some("with-predators.csv".into()),
        2,
        Overrides {
            counts: vec![("prey".into(), 50), ("predator".into(), 3)],
            episode_steps: Some(steps),
            confusion_radius: Some(0.5),
            ..Default::default()
        },
    ))
    .unwrap();
    let confusion = std::fs::read_to_string(run.join("with-predators-confusion.csv")).unwrap();
    let samples: u64 = confusion.lines().skip(1).map(|l| l.split(',').nth(2).unwrap().parse::<u64>().unwrap()).sum();
    assert_eq!(samples, 2 * 3 * (steps as u64 - 1), "{confusion}");
    assert!(
        confusion.lines().filter(|l| !l.ends_with(",0,,,")).count() > 2,
        "a 0.5 m radius spreads decisions over bins: {confusion}"
    );
    // Where the predators steer: a row per step, none at an episode's first step (its decisions were
    // taken in the episode before). The known answers: predators that chase the nearest prey steer toward
    // it at every decision (1), predators that turn at random as often away as toward (about 0).
    let pursuit = std::fs::read_to_string(run.join("with-predators-pursuit.csv")).unwrap();
    assert_eq!(pursuit.lines().count(), 1 + 2 * steps, "{pursuit}");
    assert!(pursuit
        .lines()
        .skip(1)
        .filter(|l| l.split(',').nth(1) == Some("1"))
        .all(|l| l.split(',').nth(2) == Some("0")));
    let steer_nearest = |policy: coevo::scene::Policy, out: &str| -> f64 {
        evaluate(&seeing(
            &run,
            Some(out.into()),
            2,
            Overrides {
                counts: vec![("prey".into(), 50), ("predator".into(), 3)],
                episode_steps: Some(100),
                policies: vec![("predator".into(), policy)],
                ..Default::default()
            },
        ))
        .unwrap();
        let text = std::fs::read_to_string(run.join(out.replace(".csv", "-pursuit.csv"))).unwrap();
        let (sum, n) = text.lines().skip(1).map(|l| l.split(',').collect::<Vec<_>>()).filter(|r| r[2] != "0").fold(
            (0.0, 0.0),
            |(s, n), r| {
                let w: f64 = r[2].parse().unwrap();
                (s + w * r[5].parse::<f64>().unwrap(), n + w)
            },
        );
        assert!(n > 300.0, "{text}");
        sum / n
    };
    assert_eq!(steer_nearest(Policy::ChaseNearest, "chase.csv"), 1.0);
    let random = steer_nearest(Policy::Random, "random.csv");
    assert!(random.abs() < 0.1, "{random}");

    // One step per episode: measured, not zeros; with one prey there is nothing to measure, and it says so.
    let one = |counts: Vec<(String, usize)>| {
        evaluate(&seeing(&run, None, 1, Overrides { counts, episode_steps: Some(1), ..Default::default() })).unwrap()
    };
    let line = one(vec![]);
    assert!(!line.contains("mean DoS 0.0000"), "{line}");
    // Each level beside its value by chance.
    for chance in ["(random positions 0.", "(random headings 0.637)", "(independent headings 0)"] {
        assert!(line.contains(chance), "{chance} not in {line}");
    }
    let csv = std::fs::read_to_string(run.join("eval.csv")).unwrap();
    assert!(csv.lines().nth(1).unwrap().split(',').nth(2).unwrap().parse::<f64>().unwrap() > 0.0);
    let line = one(vec![("prey".into(), 1), ("predator".into(), 1)]);
    assert!(line.contains("no DoS/DoA: fewer than two"), "{line}");
}

#[test]
fn algorithm_1_schedule_and_rule_based_predators_and_no_predators_train() {
    let dir = tempfile::tempdir().unwrap();
    // One update per environment step (Algorithm 1 as printed), none per episode.
    let mut s = tiny(2);
    s.learning.updates_per_step = 1;
    s.learning.updates_per_episode = 0;
    train(s, &opts(&dir.path().join("alg1"), None)).unwrap();
    // Confined: chase-nearest predators, learned prey; only prey have learner columns.
    let mut s = Scene::load(Path::new("scenes/confined-penalty.ron")).unwrap();
    s.episode_steps = 20;
    s.learning = tiny(1).learning;
    train(s, &opts(&dir.path().join("confined"), Some(2))).unwrap();
    let header = metrics_without_wall_clock(&dir.path().join("confined"))[0].clone();
    assert!(header.contains("critic_loss_prey") && !header.contains("critic_loss_predator"), "{header}");
    // n₀ = 0: training without predators.
    let mut s = tiny(2);
    s.species[0].count = 0;
    train(s, &opts(&dir.path().join("n0"), None)).unwrap();
    assert_eq!(Scene::preset("paper").unwrap().species[1].policy, Policy::Learned);
}

/// Positions, velocities and headings of every agent, in id order, after each of `steps` steps.
fn trajectory(sim: &mut coevo::sim::Simulation, steps: usize) -> Vec<Vec<[f64; 5]>> {
    use coevo::sim::components::{AgentId, Heading, Position, Velocity};
    (0..steps)
        .map(|_| {
            sim.step();
            let world = sim.world_mut();
            let mut rows: Vec<(u32, [f64; 5])> = world
                .query::<(&AgentId, &Position, &Velocity, &Heading)>()
                .iter(world)
                .map(|(id, x, v, h)| (id.0, [x.0.x, x.0.y, v.0.x, v.0.y, h.0]))
                .collect();
            rows.sort_by_key(|r| r.0);
            rows.into_iter().map(|r| r.1).collect()
        })
        .collect()
}

#[test]
fn a_restarted_world_trains_exactly_like_a_fresh_one() {
    // The viewer's reset: a world that ran one scene is restarted into another (different seed, counts
    // and observation size) and must then step, explore and learn exactly as a fresh headless run.
    let mut other = tiny(2);
    other.seed = 99;
    other.set_count("prey", 4).unwrap();
    let mut target = tiny(2);
    target.seed = 7;
    target.species[1].topological_limit = 3;
    let steps = 2 * target.episode_steps + 5; // across an episode end, so updates ran

    let mut fresh = learning_simulation(target.clone(), Mode::Train, None).unwrap();
    let expected = trajectory(&mut fresh, steps);

    let mut reused = learning_simulation(other, Mode::Train, None).unwrap();
    trajectory(&mut reused, 30);
    coevo::learning::restart(reused.world_mut(), &target, Some(Learners::new(&target, Mode::Train)));
    assert_eq!(trajectory(&mut reused, steps), expected);
}

/// A shipped run's actors load into its scene and drive it for three steps without a fault.
fn deploys_for_three_steps(asset: &Path, scene: &Scene) {
    let mut small = scene.clone();
    small.episode_steps = 3;
    let mut sim = coevo::run::simulation(small, coevo::learning::Mode::Evaluate, Some(asset)).unwrap();
    for _ in 0..3 {
        sim.step();
    }
    sim.check().unwrap();
}

#[test]
fn the_shipped_trained_run_is_the_default_scene_and_loads() {
    // assets/trained-standard is what the viewer's run list offers first and what the README's GIF shows.
    let asset = Path::new("assets/trained-standard");
    let scene = Scene::load(&asset.join("scene.ron")).unwrap();
    let mut default = Scene::load(Path::new("scenes/standard.ron")).unwrap();
    default.seed = scene.seed;
    assert_eq!(scene, default, "the shipped actors were trained on scenes/standard.ron");
    deploys_for_three_steps(asset, &scene);
}

#[test]
fn the_shipped_confined_run_is_the_confined_scene_and_loads() {
    // assets/trained-confined: learned prey against the paper's rule-based predators, in the box.
    let asset = Path::new("assets/trained-confined");
    let scene = Scene::load(&asset.join("scene.ron")).unwrap();
    let text = std::fs::read_to_string("scenes/confined.ron").unwrap();
    let mut confined = Scene::parse_with_preset(&text, "scenes/confined.ron", Some("gym-pps")).unwrap();
    confined.seed = scene.seed;
    assert_eq!(scene, confined, "the shipped prey were trained on scenes/confined.ron with gym-pps");
    deploys_for_three_steps(asset, &scene);
}

#[test]
fn a_finished_training_run_explains_itself() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("tiny.ron");
    std::fs::write(
        &scene,
        r#"(episode_steps: 5, learning: (hidden: 8, batch_size: 16, warmup_transitions: 16, updates_per_episode: 1, checkpoint_every: 1000))"#,
    )
    .unwrap();
    let train = |episodes: &str, out: &str| {
        let o = std::process::Command::new(env!("CARGO_BIN_EXE_coevo"))
            .args(["--train", "--scene"])
            .arg(&scene)
            .args(["--episodes", episodes, "--out"])
            .arg(dir.path().join(out))
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        // The explanation on stdout; stderr says where the run went.
        assert!(String::from_utf8_lossy(&o.stderr).contains("coevo: trained"));
        String::from_utf8_lossy(&o.stdout).into_owned()
    };
    // Three episodes: both windows are the same three episodes, and it says so.
    let short = train("3", "short");
    for expected in [
        "prey, mean of the first → last 3 of 3 episodes",
        "(random positions, 10 prey: 0.2",
        "(random headings: 2/π = 0.637)",
        "catches per episode",
        "the two windows overlap (3 of 3 episodes are in both): not a change over training",
        "next:",
        "--control blind",
        "--watch",
    ] {
        assert!(short.contains(expected), "{expected:?} not in:\n{short}");
    }
    // coevo spelled as it runs from here: not on the PATH, so the executable's path (relative to the
    // working folder, where it lies under target/)...
    let exe = std::path::Path::new(env!("CARGO_BIN_EXE_coevo"));
    let here = std::fs::canonicalize(std::env::current_dir().unwrap()).unwrap();
    let relative = std::fs::canonicalize(exe).unwrap().strip_prefix(&here).unwrap().display().to_string();
    assert!(short.contains(&format!("\n  {relative} --eval {}", dir.path().join("short").display())), "{short}");
    // ... and `coevo` when that name on the PATH is this executable.
    let on_path = std::process::Command::new(exe)
        .env("PATH", exe.parent().unwrap())
        .args(["--train", "--scene"])
        .arg(&scene)
        .args(["--episodes", "1", "--out"])
        .arg(dir.path().join("on-path"))
        .output()
        .unwrap();
    let said = String::from_utf8_lossy(&on_path.stdout);
    assert!(said.contains(&format!("\n  coevo --eval {}", dir.path().join("on-path").display())), "{said}");
    // In a clone (a Cargo.toml here, as in the tests' working folder) the viewer is the build that adds it.
    assert!(said.contains("cargo run --release --features viewer -- --watch"), "{said}");
    // The comments of the next commands stand in one column.
    let columns: Vec<usize> = short
        .lines()
        .skip_while(|l| *l != "next:")
        .skip(1)
        .map(|l| l.find("   # ").expect("a comment on every next command"))
        .collect();
    assert!(columns.len() == 5 && columns.iter().all(|&c| c == columns[0]), "{short}");
    // 210 episodes: first and last 100 apart, no overlap note.
    let long = train("210", "long");
    assert!(long.contains("first → last 100 of 210 episodes") && !long.contains("overlap"), "{long}");
    // And the course of each running mean in a sentence: where it peaked, and how far it moved back.
    for what in ["DoA", "DoS", "catches per episode"] {
        let line = long
            .lines()
            .find(|l| l.trim_start().starts_with(&format!("{what}: its 100-episode mean")))
            .unwrap_or_else(|| panic!("{what}: {long}"));
        assert!(line.contains("near the end") || line.contains(", then "), "{line}");
    }
    assert!(!short.contains("its 100-episode mean"), "no course without two full windows: {short}");
}

#[test]
fn random_positions_give_the_known_dos_baselines() {
    use coevo::scene::Boundary;
    use coevo::sim::space::Arena;
    // Uniform random positions in the 2 m torus: DoS ≈ 0.227 at 10 prey and ≈ 0.100 at 50.
    let torus = Arena { edge: 2.0, boundary: Boundary::Periodic };
    let ten = coevo::sim::metrics::random_dos(&torus, 10).unwrap();
    let fifty = coevo::sim::metrics::random_dos(&torus, 50).unwrap();
    assert!((ten - 0.227).abs() < 0.005 && (fifty - 0.100).abs() < 0.003, "{ten} {fifty}");
    assert_eq!(coevo::sim::metrics::random_dos(&torus, 1), None);
}

#[test]
fn a_training_of_a_scene_the_project_ran_says_how_far_its_seeds_differ() {
    // The default scene, trained from the clone (experiments/ and the committed results here): the
    // explanation gives the range of the 40 seeds of results/herding-equivalence, the experiment that ran
    // it on the most seeds (judged when complete: while it was in progress, nothing of its runs was shown
    // and flocking-or-herding's 10 seeds were cited).
    let dir = tempfile::tempdir().unwrap();
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_coevo"))
        .args(["--train", "--episodes", "1", "--out"])
        .arg(dir.path().join("run"))
        .output()
        .unwrap();
    // The explanation is the run's result: on stdout (progress and errors on stderr).
    let said = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{said}{}", String::from_utf8_lossy(&out.stderr));
    let line = said.lines().find(|l| l.contains("how far seeds differ")).unwrap_or_else(|| panic!("{said}"));
    assert!(
        line.contains(
            "the 40 seeds of this scene in results/herding-equivalence (gym-pps preset, variant \"with predators\"), trained 2000 episodes each"
        ),
        "{line}"
    );
    // A scene no experiment ran: nothing to compare with, nothing said.
    let scene = dir.path().join("odd.ron");
    std::fs::write(&scene, "(episode_steps: 5, species: [(name: \"prey\", count: 7)])").unwrap();
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_coevo"))
        .args(["--train", "--episodes", "1", "--scene"])
        .arg(&scene)
        .arg("--out")
        .arg(dir.path().join("odd"))
        .output()
        .unwrap();
    let said = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success() && said.contains("one run is one sample") && !said.contains("how far seeds differ"),
        "{said}"
    );
}

#[test]
fn prey_trained_only_against_past_predators_leave_the_predators_untrained() {
    use coevo::scene::{Opponents, Pick};
    // p = 1: every episode the prey train against snapshots of the predators kept every 2 episodes, so
    // the predators never store, update or lower their exploration, and their actor stays as initialised.
    let dir = tempfile::tempdir().unwrap();
    let run = dir.path().join("run");
    let mut scene = tiny(6);
    scene.learning.snapshot_every = 2;
    scene.learning.opponents = vec![("prey".into(), Opponents::Pool { p: 1.0, pick: Pick::Uniform })];
    train(scene, &opts(&run, None)).unwrap();
    let lines = metrics_without_wall_clock(&run);
    let header: Vec<&str> = lines[0].split(',').collect();
    let column = |name: &str| -> Vec<String> {
        let at = header.iter().position(|h| *h == name).unwrap_or_else(|| panic!("{name} in {}", lines[0]));
        lines[1..].iter().map(|l| l.split(',').nth(at).unwrap().to_string()).collect()
    };
    // The snapshot each episode drew: one kept by then (0 before episode 2, 0 or 2 before episode 4, …).
    let drawn: Vec<usize> = column("stand_in_predator").iter().map(|c| c.parse().unwrap()).collect();
    for (episode, snapshot) in drawn.iter().enumerate() {
        assert!(snapshot % 2 == 0 && *snapshot <= episode, "episode {episode} drew {snapshot}");
    }
    assert!(!header.contains(&"stand_in_prey"), "no pool draws from the prey");
    assert!(column("critic_loss_predator").iter().all(String::is_empty), "predators never updated");
    assert!(column("critic_loss_prey")[5].parse::<f64>().unwrap().is_finite(), "prey updated");
    assert!(column("noise_std_predator").iter().all(|s| s == "0.1"), "predators' σ never fell");
    let snapshot = |name: &str| std::fs::read(run.join("snapshots").join(name)).unwrap();
    assert!(snapshot("predator-ep00006.safetensors") == snapshot("predator-ep00000.safetensors"));
    assert!(snapshot("prey-ep00006.safetensors") != snapshot("prey-ep00000.safetensors"));
    // A pool needs snapshots to draw from, and a species to draw.
    for (edit, says) in [
        ("snapshot_every: 0", "learning.snapshot_every: must be ≥ 1"),
        ("p: 1.5", "learning.opponents[prey]: p is a probability (got 1.5)"),
    ] {
        let mut scene = tiny(2);
        let pool = match edit {
            "p: 1.5" => Opponents::Pool { p: 1.5, pick: Pick::Uniform },
            _ => Opponents::Pool { p: 0.5, pick: Pick::Prioritised },
        };
        scene.learning.opponents = vec![("prey".into(), pool)];
        if edit == "snapshot_every: 0" {
            scene.learning.snapshot_every = 0;
        }
        let err = scene.validate().unwrap_err().to_string();
        assert!(err.contains(says), "{edit}: {err}");
    }
}

#[test]
fn a_fingerprint_is_the_runs_numbers_not_its_wall_clock() {
    use coevo::store::provenance::fingerprint;
    let dir = tempfile::tempdir().unwrap();
    let (a, b, c) = (dir.path().join("a"), dir.path().join("b"), dir.path().join("c"));
    train(tiny(2), &opts(&a, None)).unwrap();
    train(tiny(2), &opts(&b, None)).unwrap();
    // Another wall clock in every row: the same fingerprint.
    let metrics = std::fs::read_to_string(b.join("metrics.csv")).unwrap();
    let slower: Vec<String> = metrics
        .lines()
        .enumerate()
        .map(|(i, l)| match (i, l.rsplit_once(',')) {
            (0, _) | (_, None) => l.to_string(),
            (_, Some((rest, _))) => format!("{rest},999.000"),
        })
        .collect();
    std::fs::write(b.join("metrics.csv"), slower.join("\n") + "\n").unwrap();
    assert_ne!(std::fs::read(a.join("metrics.csv")).unwrap(), std::fs::read(b.join("metrics.csv")).unwrap());
    assert_eq!(fingerprint(&a).unwrap(), fingerprint(&b).unwrap());
    // Another seed, or one checkpoint byte changed: another fingerprint.
    let mut other = tiny(2);
    other.seed += 1;
    train(other, &opts(&c, None)).unwrap();
    assert_ne!(fingerprint(&a).unwrap(), fingerprint(&c).unwrap());
    let actor = b.join("checkpoint/prey-actor.safetensors");
    let mut bytes = std::fs::read(&actor).unwrap();
    let n = bytes.len();
    bytes[n - 1] ^= 1;
    std::fs::write(&actor, bytes).unwrap();
    assert_ne!(fingerprint(&a).unwrap(), fingerprint(&b).unwrap());
    let none = fingerprint(&dir.path().join("nothing")).unwrap_err().to_string();
    assert!(none.contains("holds no coevo run to fingerprint"), "{none}");
}
