//! The number of worker threads decides how long a run takes, never what it computes: the species update
//! concurrently and large populations are perceived and decided in chunks, all of it reproducible.
//! Each run is a separate `coevo` process, so the thread count is really that process's.

use crate::common;
use std::path::Path;
use std::process::Command;

/// A short training scene: both update schedules (after every step and after the episode), and 1 200
/// prey, more than one chunk of observation (512) and of inference (1 024) rows.
const SCENE: &str = r#"(
    preset: "paper",
    seed: 5,
    episode_steps: 6,
    episodes: 3,
    species: [(name: "prey", count: 1200)],
    learning: (hidden: 16, batch_size: 32, warmup_transitions: 32, buffer_capacity: 20000,
               updates_per_episode: 3, updates_per_step: 1, checkpoint_every: 2),
)"#;

fn train(dir: &Path, name: &str, threads: &str) -> (Vec<String>, Vec<Vec<u8>>) {
    train_on(dir, name, threads, "auto")
}

fn train_on(dir: &Path, name: &str, threads: &str, kernels: &str) -> (Vec<String>, Vec<Vec<u8>>) {
    let run = dir.join(name);
    let out = Command::new(env!("CARGO_BIN_EXE_coevo"))
        .args(["--train", "--quiet", "--scene"])
        .arg(dir.join("scene.ron"))
        .arg("--out")
        .arg(&run)
        .args(["--threads", threads, "--kernels", kernels])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let metrics = std::fs::read_to_string(run.join("metrics.csv")).unwrap();
    // Every column but the wall-clock one.
    let rows = metrics.lines().map(|l| l.rsplit_once(',').unwrap().0.to_string()).collect();
    let networks = ["predator-actor", "prey-actor", "predator-training", "prey-training"]
        .iter()
        .map(|f| std::fs::read(run.join(format!("checkpoint/{f}.safetensors"))).unwrap())
        .collect();
    (rows, networks)
}

#[test]
fn one_two_and_three_threads_train_identical_networks_and_metrics() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("scene.ron"), SCENE).unwrap();
    let (metrics, networks) = train(dir.path(), "one", "1");
    assert_eq!(metrics.len(), 4, "header and three episodes");
    assert!(metrics[3].split(',').nth(13).unwrap().parse::<f64>().unwrap().is_finite(), "updates ran: {}", metrics[3]);
    for threads in ["2", "3"] {
        let (m, n) = train(dir.path(), threads, threads);
        assert_eq!(m, metrics, "metrics with {threads} threads");
        assert!(n == networks, "networks with {threads} threads differ from one thread's");
    }
}

#[test]
fn a_league_trains_identically_on_one_and_two_threads() {
    // Both species against pools of past opponents (experiments/league.ron), a snapshot every episode.
    let dir = tempfile::tempdir().unwrap();
    let league = SCENE.replace(
        "checkpoint_every: 2)",
        r#"checkpoint_every: 2, snapshot_every: 1,
               opponents: [("prey", Pool(p: 0.5, pick: Prioritised)), ("predator", Pool(p: 0.5, pick: Uniform))])"#,
    );
    assert_ne!(league, SCENE);
    std::fs::write(dir.path().join("scene.ron"), league.replace("episodes: 3", "episodes: 6")).unwrap();
    let (metrics, networks) = train(dir.path(), "one", "1");
    assert!(metrics[0].contains("stand_in_prey") && metrics.len() == 7, "{metrics:?}");
    let (m, n) = train(dir.path(), "two", "2");
    assert_eq!(m, metrics);
    assert!(n == networks, "networks with 2 threads differ from one thread's");
}

/// The kernel families this CPU can run, as `--kernels` names them.
fn families() -> Vec<&'static str> {
    let mut families = vec!["portable"];
    #[cfg(target_arch = "x86_64")]
    {
        if std::arch::is_x86_feature_detected!("fma") {
            families.push("avx2");
        }
        if std::arch::is_x86_feature_detected!("avx512f") {
            families.extend(["avx512", "avx512-direct"]);
        }
        if std::arch::is_x86_feature_detected!("avx512bf16") && std::arch::is_x86_feature_detected!("avx512bw") {
            families.push("avx512-bf16");
        }
    }
    families
}

#[test]
fn each_pinned_kernel_family_is_recorded_and_reproducible_at_any_thread_count() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("scene.ron"), SCENE).unwrap();
    for family in families() {
        let one = train_on(dir.path(), &format!("{family}-1"), "1", family);
        let two = train_on(dir.path(), &format!("{family}-2"), "2", family);
        assert_eq!(one.0, two.0, "{family}: metrics at 1 and 2 threads");
        assert!(one.1 == two.1, "{family}: networks at 1 and 2 threads differ");
        let provenance = std::fs::read_to_string(dir.path().join(format!("{family}-1/provenance.ron"))).unwrap();
        let recorded = if family == "avx2" { "avx2-fma" } else { family };
        assert!(provenance.contains(&format!("kernels: \"{recorded}\"")), "{family}: {provenance}");
    }
    // coevo's own AVX-512 products sum in another order than gemm's: the switch does switch.
    if families().contains(&"avx512-direct") {
        let read = |name: &str| std::fs::read(dir.path().join(name).join("checkpoint/prey-actor.safetensors")).unwrap();
        assert_ne!(read("avx512-1"), read("avx512-direct-1"), "avx512-direct trained gemm's networks");
    }
    if families().contains(&"avx512-bf16") {
        let read = |name: &str| std::fs::read(dir.path().join(name).join("checkpoint/prey-actor.safetensors")).unwrap();
        assert_ne!(read("avx512-direct-1"), read("avx512-bf16-1"), "avx512-bf16 trained f32 networks");
    }
}

#[test]
fn a_cpu_without_the_bf16_kernels_is_refused_in_one_line() {
    // On a CPU that has them the family runs (above); on one that has not, one line names it.
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx512bf16") && std::arch::is_x86_feature_detected!("avx512bw") {
        return;
    }
    let out = Command::new(env!("CARGO_BIN_EXE_coevo"))
        .args(["--describe-scene", "scenes/standard.ron", "--kernels", "avx512-bf16"])
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && stderr.trim().lines().count() == 1, "{stderr}");
    assert!(stderr.contains("cannot run the avx512-bf16 kernels"), "{stderr}");
}

#[test]
fn an_unknown_kernel_family_is_one_error_line() {
    for (args, env, names) in [(vec!["--kernels", "sse9"], None, "--kernels"), (vec![], Some("sse9"), "COEVO_KERNELS")]
    {
        let mut command = Command::new(env!("CARGO_BIN_EXE_coevo"));
        command.args(["--describe-scene", "scenes/standard.ron"]).args(&args);
        if let Some(v) = env {
            command.env("COEVO_KERNELS", v);
        }
        let out = command.output().unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{names}: accepted");
        assert_eq!(stderr.trim().lines().count(), 1, "{names}: {stderr}");
        assert!(stderr.contains(names) && stderr.contains("sse9"), "{names}: {stderr}");
    }
}

#[test]
fn a_large_crowded_population_moves_identically_on_one_two_and_three_threads() {
    // Above 512 agents observations, and above 4096 contacts, the order parameters' terms and the cluster
    // links, are computed in parallel chunks: the state after 30 steps of random actions, with many bodies
    // in contact, and its order parameters must not depend on the thread count.
    use coevo::scene::{Boundary, Policy};
    use coevo::sim::components::{ContactForce, Heading, Position, Velocity};
    use coevo::sim::metrics::SwarmMetrics;
    use coevo::sim::perception::Batches;
    let state = |threads: usize| {
        coevo::parallel::set_threads(threads);
        let mut scene = common::scene(3, 5_000, Policy::Random, Boundary::Periodic);
        scene.world.arena_edge = 11.0;
        let mut sim = coevo::sim::Simulation::new(scene);
        for _ in 0..30 {
            sim.step();
        }
        let world = sim.world_mut();
        let mut q = world.query::<(&Position, &Velocity, &Heading, &ContactForce)>();
        let mut rows: Vec<[f64; 7]> =
            q.iter(world).map(|(x, v, h, f)| [x.0.x, x.0.y, v.0.x, v.0.y, h.0, f.0.x, f.0.y]).collect();
        rows.sort_by(|a, b| a.partial_cmp(b).unwrap());
        let observations: Vec<f32> = world.resource::<Batches>().species[1].observations.clone();
        let metrics = world.resource::<SwarmMetrics>();
        (rows, observations, metrics.now.clone(), metrics.nn_distances_now.clone())
    };
    let one = state(1);
    let touching = one.0.iter().filter(|r| r[5] != 0.0 || r[6] != 0.0).count();
    assert!(touching > 100, "only {touching} bodies in contact: the test needs a crowd");
    let prey = one.2[1].expect("5 000 prey have order parameters");
    assert!(prey.clusters > 1.0 && prey.largest_cluster < 1.0, "the crowd needs several clusters: {prey:?}");
    for threads in [2, 3] {
        assert!(state(threads) == one, "{threads} threads move the crowd differently from one");
    }
    coevo::parallel::set_threads(1);
}
