//! A run is a function of its scene and seed, also across kills and resumes; processes clean up after
//! themselves. Every run here is a real `coevo` process, killed with SIGKILL or SIGTERM as a machine or a
//! user would.

use coevo::store::manifest::Manifest;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

fn coevo() -> Command {
    Command::new(env!("CARGO_BIN_EXE_coevo"))
}

/// The default scene, for processes started in a temporary folder.
fn standard() -> PathBuf {
    std::fs::canonicalize("scenes/standard.ron").unwrap()
}

/// A small training scene with checkpoints every 2 episodes, snapshots every 5 (out of step with the
/// checkpoints, so a kill can fall between a snapshot and the checkpoint after it) and replay buffers that wrap (1 000
/// transitions; prey store 1 800 per episode, predators 450, so the predators' buffer spans two
/// checkpoints' segments), under either update schedule; with `authors`, every switch of the authors'
/// code on: the replay window keeps only the first rows of each block, so a resume must know
/// how many transitions were offered, not only how many were kept; with `league`, both species train
/// against pools of past opponents, so a resume must restore the pool from the snapshots and
/// the draws and returns from the checkpoint.
fn scene_text(per_step: bool, authors: bool) -> String {
    scene_of(per_step, authors, false)
}

fn scene_of(per_step: bool, authors: bool, league: bool) -> String {
    let schedule = if per_step {
        "updates_per_episode: 0, updates_per_step: 1"
    } else {
        "updates_per_episode: 20, updates_per_step: 0"
    };
    let (world, switches) = if authors {
        (
            // The code's observation too (difference 4 of docs/src/results/authors-code.md), with the energy
            // budget its input reads.
            r#"world: (spawn: AuthorsNoOverlap, energy_budget: true), observation_layout: Authors,"#,
            "replay_window: AuthorsFirstRows, stored_action: AuthorsRescaled, noise_draw: PerSpecies, batch_draw: WithoutReplacement,",
        )
    } else if league {
        ("", r#"opponents: [("predator", Pool(p: 0.5, pick: Prioritised)), ("prey", Pool(p: 0.3, pick: Uniform))],"#)
    } else {
        ("", "")
    };
    let prey = if authors {
        r#"(name: "prey", count: 12, topological_limit: 5, topological_limit_of: [("predator", 2)])"#
    } else {
        r#"(name: "prey", count: 12)"#
    };
    format!(
        r#"(
    preset: "paper",
    seed: 11,
    episode_steps: 150,
    episodes: 24,
    {world}
    species: [{prey}],
    learning: (hidden: 16, batch_size: 32, warmup_transitions: 32, buffer_capacity: 1000,
               {schedule}, checkpoint_every: 2, snapshot_every: 5, {switches}),
)"#
    )
}

fn train(scene: &Path, run: &Path) -> Child {
    coevo()
        .args(["--train", "--quiet", "--threads", "1", "--scene"])
        .arg(scene)
        .arg("--out")
        .arg(run)
        .stderr(Stdio::piped())
        .spawn()
        .unwrap()
}

fn rows(run: &Path) -> usize {
    std::fs::read_to_string(run.join("metrics.csv")).map_or(0, |t| t.lines().count().saturating_sub(1))
}

/// Every metrics.csv column but the wall clock.
fn metrics(run: &Path) -> Vec<String> {
    let text = std::fs::read_to_string(run.join("metrics.csv")).unwrap();
    text.lines().map(|l| l.rsplit_once(',').unwrap().0.to_string()).collect()
}

/// Every file of the checkpoint with its bytes; manifest.ron without its hash of metrics.csv, which holds
/// the wall clock (the one thing that is not a function of scene and seed).
fn checkpoint(run: &Path) -> Vec<(String, Vec<u8>)> {
    let mut files: Vec<(String, Vec<u8>)> = std::fs::read_dir(run.join("checkpoint"))
        .unwrap()
        .map(|e| {
            let e = e.unwrap();
            let name = e.file_name().to_string_lossy().into_owned();
            let mut bytes = std::fs::read(e.path()).unwrap();
            if name == "manifest.ron" {
                let mut manifest: Manifest = ron::from_str(std::str::from_utf8(&bytes).unwrap()).unwrap();
                manifest.metrics = Default::default();
                bytes = manifest.to_ron().into_bytes();
            }
            (name, bytes)
        })
        .collect();
    files.sort();
    files
}

/// Every snapshot file with its bytes.
fn snapshots(run: &Path) -> Vec<(String, Vec<u8>)> {
    let mut files: Vec<(String, Vec<u8>)> = std::fs::read_dir(run.join("snapshots"))
        .unwrap()
        .map(|e| {
            let e = e.unwrap();
            (e.file_name().to_string_lossy().into_owned(), std::fs::read(e.path()).unwrap())
        })
        .collect();
    files.sort();
    files
}

fn finish(child: Child) {
    let out = child.wait_with_output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
}

#[test]
fn a_run_killed_at_any_moment_and_resumed_equals_the_uninterrupted_run() {
    let dir = tempfile::tempdir().unwrap();
    for (per_step, authors, league) in
        [(true, false, false), (false, false, false), (false, true, false), (true, false, true)]
    {
        let scene = dir.path().join(format!("scene-{per_step}-{authors}-{league}.ron"));
        std::fs::write(&scene, scene_of(per_step, authors, league)).unwrap();
        let per_step = match (authors, league) {
            (true, _) => "authors".to_string(),
            (_, true) => "league".to_string(),
            _ => per_step.to_string(),
        };
        let whole = dir.path().join(format!("whole-{per_step}"));
        finish(train(&scene, &whole));
        assert_eq!(rows(&whole), 24);
        if league {
            // Past opponents played some episodes, and the checkpoint holds the league's record.
            let table = metrics(&whole);
            let header: Vec<&str> = table[0].split(',').collect();
            for name in ["stand_in_predator", "stand_in_prey"] {
                let at = header.iter().position(|h| *h == name).expect(name);
                let played = table[1..].iter().filter(|r| !r.split(',').nth(at).unwrap().is_empty()).count();
                assert!((1..24).contains(&played), "{name}: {played} of 24 episodes");
            }
            let state = std::fs::read_to_string(whole.join("checkpoint/state.ron")).unwrap();
            assert!(state.contains("league:") && state.contains("return_sum"), "{state}");
        }
        let kept: Vec<String> = snapshots(&whole).into_iter().map(|(name, _)| name).collect();
        let expected: Vec<String> = ["predator", "prey"]
            .iter()
            .flat_map(|s| [0, 5, 10, 15, 20, 24].map(|e| format!("{s}-ep{e:05}.safetensors")))
            .collect();
        assert_eq!(kept, expected);
        // Kill points spread over the run: before the buffer wraps, after, and near the end; each a
        // few milliseconds into an episode (or into a checkpoint being written).
        for (i, after) in [3usize, 11, 19].into_iter().enumerate() {
            let run = dir.path().join(format!("killed-{per_step}-{after}"));
            // On a loaded machine this thread can be descheduled long enough for a short run to finish
            // before the kill lands; such an attempt tests nothing, so it is made again (up to 5 times).
            let killed_early = (0..5).any(|_| {
                let _ = std::fs::remove_dir_all(&run);
                let mut child = train(&scene, &run);
                let started = Instant::now();
                while rows(&run) < after {
                    if child.try_wait().unwrap().is_some() {
                        return false; // finished (or failed) before the kill point was even seen
                    }
                    assert!(started.elapsed() < Duration::from_secs(120), "no progress");
                    std::thread::sleep(Duration::from_millis(1));
                }
                std::thread::sleep(Duration::from_millis(7 * i as u64));
                child.kill().unwrap();
                child.wait().unwrap();
                rows(&run) < 24
            });
            assert!(killed_early, "five attempts all finished before the kill ({per_step}, {after})");
            let resumed = coevo().arg("--resume").arg(&run).args(["--quiet", "--threads", "2"]).output().unwrap();
            assert!(resumed.status.success(), "{}", String::from_utf8_lossy(&resumed.stderr));
            let note = String::from_utf8_lossy(&resumed.stderr);
            assert!(!note.contains("lacks replay buffers"), "{note}");
            assert_eq!(
                metrics(&run),
                metrics(&whole),
                "metrics after a kill at episode {after} (per step: {per_step})"
            );
            assert!(
                checkpoint(&run) == checkpoint(&whole),
                "checkpoint after a kill at episode {after} (per step: {per_step})"
            );
            assert!(
                snapshots(&run) == snapshots(&whole),
                "snapshots after a kill at episode {after} (per step: {per_step})"
            );
            assert!(!run.join("coevo.lock").exists() && !run.join("checkpoint.tmp").exists());
        }
    }
    // Replay segments: one missing is a damaged checkpoint; all removed (to free space) is a resume that
    // refills its buffers and says so.
    let run = dir.path().join("whole-true");
    let segments: Vec<PathBuf> = std::fs::read_dir(run.join("checkpoint"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.to_string_lossy().contains("-replay-"))
        .collect();
    let predators: Vec<&PathBuf> =
        segments.iter().filter(|p| p.to_string_lossy().contains("predator-replay-")).collect();
    assert_eq!(predators.len(), 2, "{segments:?}");
    std::fs::remove_file(predators[0]).unwrap();
    let extend = || coevo().arg("--resume").arg(&run).args(["--episodes", "25", "--quiet"]).output().unwrap();
    let out = extend();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("is incomplete"), "{}", String::from_utf8_lossy(&out.stderr));
    segments.iter().filter(|p| p.exists()).for_each(|p| std::fs::remove_file(p).unwrap());
    let out = extend();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(String::from_utf8_lossy(&out.stderr).contains("lacks replay buffers"));
    assert_eq!(rows(&run), 25);
}

/// The lock file of the first run under `results`, with the PID in it, once one exists.
fn child_pid(results: &Path) -> Option<(PathBuf, u32)> {
    let mut stack = vec![results.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).ok()?.flatten() {
            let p = e.path();
            if p.is_dir() {
                stack.push(p);
            } else if p.file_name().is_some_and(|n| n == "coevo.lock") {
                let pid = std::fs::read_to_string(&p).ok()?.trim().parse().ok()?;
                return Some((p, pid));
            }
        }
    }
    None
}

/// Whether a process runs (a zombie, dead but not yet reaped, does not).
fn running(pid: u32) -> bool {
    std::fs::read_to_string(format!("/proc/{pid}/stat"))
        .is_ok_and(|s| s.rsplit_once(')').is_some_and(|(_, rest)| !rest.trim_start().starts_with('Z')))
}

#[test]
fn a_killed_experiment_leaves_no_child_running_and_can_be_run_again() {
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path();
    std::fs::write(root.join("long.ron"), scene_text(true, false).replace("episodes: 24", "episodes: 100000")).unwrap();
    std::fs::create_dir(root.join("exp")).unwrap();
    // An experiment file outside experiments/, its base beside it.
    std::fs::write(
        root.join("exp/long.ron"),
        r#"(base: "../long.ron", seeds: [1], episodes: 100000, variants: [(name: "a")])"#,
    )
    .unwrap();
    let mut parent =
        coevo().args(["--experiment", "exp/long.ron", "--quiet", "--jobs", "1"]).current_dir(root).spawn().unwrap();
    let started = Instant::now();
    let (lock, pid) = loop {
        if let Some(found) = child_pid(&root.join("results")) {
            break found;
        }
        assert!(started.elapsed() < Duration::from_secs(60), "no training child started");
        std::thread::sleep(Duration::from_millis(5));
    };
    assert!(running(pid));
    parent.kill().unwrap();
    parent.wait().unwrap();
    let killed = Instant::now();
    while running(pid) {
        assert!(killed.elapsed() < Duration::from_secs(10), "the training child {pid} outlived its experiment");
        std::thread::sleep(Duration::from_millis(10));
    }
    assert!(!lock.exists(), "the child removed its lock on the way out");
    // The experiment picks the run up again (here: resumes or restarts it) instead of finding it busy.
    let mut again =
        coevo().args(["--experiment", "exp/long.ron", "--quiet", "--jobs", "1"]).current_dir(root).spawn().unwrap();
    let restarted = Instant::now();
    loop {
        if let Some((_, p)) = child_pid(&root.join("results")) {
            if p != pid {
                break;
            }
        }
        assert!(again.try_wait().unwrap().is_none(), "the re-run ended instead of training");
        assert!(restarted.elapsed() < Duration::from_secs(60), "no training child restarted");
        std::thread::sleep(Duration::from_millis(5));
    }
    again.kill().unwrap();
    again.wait().unwrap();
}

#[test]
fn a_pipe_given_as_an_input_is_one_error_line_not_a_hang() {
    let dir = tempfile::tempdir().unwrap();
    let fifo = dir.path().join("scene.ron");
    let made = Command::new("mkfifo").arg(&fifo).status().unwrap();
    assert!(made.success());
    for args in [vec!["--train", "--scene"], vec!["--describe-scene"], vec!["--experiment"]] {
        let mut child = coevo().args(&args).arg(&fifo).current_dir(dir.path()).stderr(Stdio::piped()).spawn().unwrap();
        let started = Instant::now();
        while child.try_wait().unwrap().is_none() {
            if started.elapsed() > Duration::from_secs(10) {
                child.kill().unwrap();
                panic!("coevo {args:?} FIFO: hangs");
            }
            std::thread::sleep(Duration::from_millis(10));
        }
        let out = child.wait_with_output().unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success());
        assert_eq!(stderr.lines().count(), 1, "{stderr}");
        assert!(stderr.contains("is not a regular file"), "{stderr}");
    }
}

#[test]
fn a_memory_limit_turns_a_huge_population_into_one_error_line() {
    let dir = tempfile::tempdir().unwrap();
    let exe = env!("CARGO_BIN_EXE_coevo");
    // 8 GB of address space: 10 million prey need ~11.6 GB.
    let script = format!(
        "ulimit -v 8000000 && exec {exe} --record x.csv --steps 1 --prey 10000000 --scene {}",
        standard().display()
    );
    let out = Command::new("sh").arg("-c").arg(&script).current_dir(dir.path()).output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(stderr.contains("species[prey]: 10000000 agents") && stderr.contains("ulimit -v"), "{stderr}");
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0, "nothing written");
}

#[test]
fn interrupted_writes_leave_no_temporary_behind() {
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path();
    let temporaries = || -> Vec<String> {
        std::fs::read_dir(root)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .filter(|n| n.ends_with(".tmp"))
            .collect()
    };
    let record = |signal: &str| {
        let mut child = coevo()
            .args(["--record", "big.csv", "--steps", "100000", "--prey", "300", "--scene"])
            .arg(standard())
            .current_dir(root)
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let started = Instant::now();
        while temporaries().is_empty() {
            assert!(child.try_wait().unwrap().is_none(), "the record ended before it was interrupted");
            assert!(started.elapsed() < Duration::from_secs(60));
            std::thread::sleep(Duration::from_millis(2));
        }
        std::thread::sleep(Duration::from_millis(50));
        let sent = Command::new("kill").args([signal, &child.id().to_string()]).status().unwrap();
        assert!(sent.success());
        child.wait_with_output().unwrap()
    };
    // SIGTERM and SIGINT: the process removes its temporary before it exits.
    for signal in ["-TERM", "-INT"] {
        let out = record(signal);
        assert!(!out.status.success());
        assert!(temporaries().is_empty(), "{signal} left {:?}", temporaries());
        assert!(!root.join("big.csv").exists(), "no half-written output");
    }
    // SIGKILL leaves it; the next write of the same file removes it.
    record("-KILL");
    assert!(!temporaries().is_empty());
    let out = coevo()
        .args(["--record", "big.csv", "--steps", "2", "--scene"])
        .arg(standard())
        .current_dir(root)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(temporaries().is_empty(), "left: {:?}", temporaries());
}

#[test]
fn a_run_names_every_executable_that_trained_or_evaluated_it() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("scene.ron");
    std::fs::write(&scene, scene_text(false, false).replace("episodes: 24", "episodes: 3")).unwrap();
    // Another build of coevo: the same program with bytes appended, so its file (its identity) differs.
    let other = dir.path().join("coevo-other");
    let mut bytes = std::fs::read(env!("CARGO_BIN_EXE_coevo")).unwrap();
    bytes.extend_from_slice(b"another build");
    std::fs::write(&other, bytes).unwrap();
    std::fs::set_permissions(&other, std::os::unix::fs::PermissionsExt::from_mode(0o755)).unwrap();
    let run = dir.path().join("run");
    let ok = |out: std::process::Output| assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    ok(coevo()
        .args(["--train", "--quiet", "--episodes", "2", "--scene"])
        .arg(&scene)
        .arg("--out")
        .arg(&run)
        .output()
        .unwrap());
    let provenance = || std::fs::read_to_string(run.join("provenance.ron")).unwrap();
    let first = provenance();
    assert!(first.contains("binary: \"") && !first.contains("also_by"), "{first}");
    for episodes in ["3", "4"] {
        // Resumed, then evaluated, by the other build, twice: named once.
        ok(Command::new(&other)
            .args(["--resume"])
            .arg(&run)
            .args(["--quiet", "--episodes", episodes])
            .output()
            .unwrap());
        ok(Command::new(&other).args(["--eval"]).arg(&run).args(["--episodes", "1", "--steps", "5"]).output().unwrap());
    }
    let after = provenance();
    let named = after.lines().skip_while(|l| !l.contains("also_by")).take_while(|l| !l.contains(']')).count();
    assert_eq!(named, 2, "also_by and one executable: {after}");
}

#[test]
fn a_live_run_saved_between_episodes_resumes_to_the_train_run() {
    use coevo::run::live::LiveRun;
    let dir = tempfile::tempdir().unwrap();
    let scene_path = dir.path().join("scene.ron");
    std::fs::write(&scene_path, scene_text(false, false)).unwrap();
    let whole = dir.path().join("whole");
    finish(train(&scene_path, &whole));
    // The world stepped as the viewer's live training steps it, its episodes recorded (and then taken by
    // someone else, as the viewer's plots take them), saved after 7 of its 24 episodes.
    let scene = coevo::scene::Scene::load(&scene_path).unwrap();
    let mut sim = coevo::run::simulation(scene, coevo::learning::Mode::Train, None).unwrap();
    let live = LiveRun::new(sim.world());
    sim.world_mut().insert_resource(live);
    let saved = dir.path().join("saved");
    let save = |sim: &mut coevo::sim::Simulation, to: &Path| {
        sim.world_mut().resource_scope(|world, mut run: bevy::prelude::Mut<LiveRun>| run.save(world, to))
    };
    while sim.episode().index < 7 {
        sim.step();
        LiveRun::record(sim.world_mut());
        sim.world_mut().resource_mut::<coevo::sim::metrics::EpisodeLog>().episodes.clear();
        if sim.episode().index == 3 && sim.episode().step == 10 {
            let e = save(&mut sim, &saved).unwrap_err().to_string();
            assert!(e.contains("runs are saved between episodes"), "{e}");
            assert!(!saved.exists(), "a refused save writes nothing");
        }
    }
    assert_eq!(sim.world().resource::<LiveRun>().episodes(), 7);
    save(&mut sim, &saved).unwrap();
    assert_eq!(rows(&saved), 7);
    // Never into no folder (the current one), never over another run.
    let e = save(&mut sim, Path::new("")).unwrap_err().to_string();
    assert!(e.contains("name a folder"), "{e}");
    let e = save(&mut sim, &saved).unwrap_err().to_string();
    assert!(e.contains("already holds a run"), "{e}");
    // `--resume` continues it exactly as the uninterrupted `--train` run.
    let resumed = coevo().arg("--resume").arg(&saved).args(["--quiet", "--threads", "1"]).output().unwrap();
    assert!(resumed.status.success(), "{}", String::from_utf8_lossy(&resumed.stderr));
    assert!(!String::from_utf8_lossy(&resumed.stderr).contains("lacks replay buffers"));
    assert_eq!(metrics(&saved), metrics(&whole));
    assert!(checkpoint(&saved) == checkpoint(&whole), "the checkpoint of the resumed live run");
    assert!(snapshots(&saved) == snapshots(&whole), "the snapshots of the resumed live run");
    let eval = coevo().arg("--eval").arg(&saved).args(["--episodes", "1", "--steps", "20"]).output().unwrap();
    assert!(eval.status.success(), "{}", String::from_utf8_lossy(&eval.stderr));
    // A world whose population changed while it trained is no longer the run of its scene: not saved.
    sim.world_mut().resource_mut::<LiveRun>().altered = Some("the population changed at episode 7".into());
    let e = save(&mut sim, &dir.path().join("altered")).unwrap_err().to_string();
    assert!(e.contains("not saved: the population changed"), "{e}");
    assert!(!dir.path().join("altered").exists());
    // `--save-run` keeps the whole run: saved after episode 1, then kept as it trains (every row and
    // snapshot, a checkpoint every 2 episodes), and left after episode 15 as a window closing mid-episode
    // leaves it: 15 rows, checkpointed at 14. `--resume` drops the row past the checkpoint and continues
    // to the uninterrupted run.
    let scene = coevo::scene::Scene::load(&scene_path).unwrap();
    let mut sim = coevo::run::simulation(scene, coevo::learning::Mode::Train, None).unwrap();
    let live = LiveRun::new(sim.world());
    sim.world_mut().insert_resource(live);
    let kept = dir.path().join("kept");
    while sim.episode().index < 15 || sim.episode().step < 40 {
        sim.step();
        LiveRun::record(sim.world_mut());
        sim.world_mut().resource_mut::<coevo::sim::metrics::EpisodeLog>().episodes.clear();
        if sim.episode().step == 0 {
            let (index, kept) = (sim.episode().index, kept.clone());
            sim.world_mut()
                .resource_scope(|world, mut run: bevy::prelude::Mut<LiveRun>| match index {
                    1 => run.save(world, &kept),
                    _ => run.keep(world, &kept),
                })
                .unwrap();
        }
    }
    assert_eq!(rows(&kept), 15);
    assert_eq!(sim.world().resource::<LiveRun>().checkpointed(), 14);
    let (kept_snapshots, whole_snapshots) = (snapshots(&kept), snapshots(&whole));
    let names: Vec<&str> = kept_snapshots.iter().map(|(name, _)| name.as_str()).collect();
    assert_eq!(names.len(), 2 * 4, "ep 0, 5, 10 and 15 of both species: {names:?}");
    assert!(kept_snapshots.iter().all(|k| whole_snapshots.contains(k)), "each as the --train run wrote it");
    let resumed = coevo().arg("--resume").arg(&kept).args(["--quiet", "--threads", "1"]).output().unwrap();
    assert!(resumed.status.success(), "{}", String::from_utf8_lossy(&resumed.stderr));
    assert_eq!(metrics(&kept), metrics(&whole));
    assert!(checkpoint(&kept) == checkpoint(&whole), "the checkpoint of the resumed kept run");
}

/// Every file and folder under `dir` whose name marks it as a temporary or a leftover of a checkpoint
/// swap, or a lock.
fn leftovers(dir: &Path) -> Vec<PathBuf> {
    let mut found = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for entry in std::fs::read_dir(&d).unwrap() {
            let path = entry.unwrap().path();
            let name = path.file_name().unwrap().to_string_lossy().into_owned();
            if name.ends_with(".tmp") || name == "checkpoint.old" || name == "coevo.lock" {
                found.push(path.clone());
            }
            if path.is_dir() {
                stack.push(path);
            }
        }
    }
    found
}

#[test]
fn a_signal_at_any_moment_leaves_nothing_half_done_and_says_so_once() {
    let dir = tempfile::tempdir().unwrap();
    // A checkpoint and a snapshot after every episode: most of the time is spent writing.
    let scene = dir.path().join("scene.ron");
    std::fs::write(
        &scene,
        scene_text(false, false)
            .replace("checkpoint_every: 2, snapshot_every: 5", "checkpoint_every: 1, snapshot_every: 1"),
    )
    .unwrap();
    let whole = dir.path().join("whole");
    finish(train(&scene, &whole));
    for (i, signal) in ["-TERM", "-INT", "-HUP"].iter().cycle().take(9).enumerate() {
        let run = dir.path().join(format!("signalled-{i}"));
        let mut child = train(&scene, &run);
        let started = Instant::now();
        while rows(&run) < 2 + i {
            assert!(child.try_wait().unwrap().is_none(), "the run ended before the signal");
            assert!(started.elapsed() < Duration::from_secs(120), "no progress");
            std::thread::sleep(Duration::from_millis(1));
        }
        // At a different moment of the episode each time: stepping, snapshotting, checkpointing.
        std::thread::sleep(Duration::from_millis(3 * i as u64));
        assert!(Command::new("kill").args([signal.to_string(), child.id().to_string()]).status().unwrap().success());
        let out = child.wait_with_output().unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(130), "{signal}: {stderr}");
        assert_eq!(stderr.lines().count(), 1, "{signal}: one line: {stderr}");
        assert!(stderr.contains("interrupted"), "{stderr}");
        assert_eq!(leftovers(&run), Vec::<PathBuf>::new(), "{signal} after {} episodes", 2 + i);
        let resumed = coevo().arg("--resume").arg(&run).args(["--quiet"]).output().unwrap();
        assert!(resumed.status.success(), "{}", String::from_utf8_lossy(&resumed.stderr));
        assert_eq!(metrics(&run), metrics(&whole), "{signal}: resumed after the signal");
    }
}

#[test]
fn of_two_processes_writing_one_new_file_exactly_one_succeeds() {
    let dir = tempfile::tempdir().unwrap();
    let record = || {
        coevo()
            .args(["--record", "same.csv", "--steps", "300", "--prey", "200", "--scene"])
            .arg(standard())
            .current_dir(dir.path())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap()
    };
    for _ in 0..3 {
        let _ = std::fs::remove_file(dir.path().join("same.csv"));
        let _ = std::fs::remove_file(dir.path().join("same-order.csv"));
        let (a, b) = (record(), record());
        let outs = [a.wait_with_output().unwrap(), b.wait_with_output().unwrap()];
        let succeeded = outs.iter().filter(|o| o.status.success()).count();
        let stderr: Vec<String> = outs.iter().map(|o| String::from_utf8_lossy(&o.stderr).into_owned()).collect();
        assert_eq!(succeeded, 1, "{stderr:?}");
        let refused = outs.iter().find(|o| !o.status.success()).unwrap();
        assert!(String::from_utf8_lossy(&refused.stderr).contains("already exists"), "{stderr:?}");
        let rows = std::fs::read_to_string(dir.path().join("same.csv")).unwrap().lines().count();
        assert_eq!(rows, 1 + 301 * 203, "the file is one process's, whole");
    }
}

#[test]
fn a_full_output_is_an_error_not_a_panic() {
    let dir = tempfile::tempdir().unwrap();
    let full = || std::fs::OpenOptions::new().write(true).open("/dev/full").unwrap();
    let describe = || {
        let mut c = coevo();
        c.arg("--describe-scene").arg(standard()).current_dir(dir.path());
        c
    };
    // stdout full: the error goes to stderr.
    let out = describe().stdout(full()).output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("standard output:") && !stderr.contains("panicked"), "{stderr}");
    // stderr full, with an error or with the closing line of a record: a failure, and no panic (which
    // exits 101).
    let out = coevo().args(["--describe-scene", "nope.ron"]).current_dir(dir.path()).stderr(full()).output().unwrap();
    assert_eq!(out.status.code(), Some(1));
    let out = coevo()
        .args(["--record", "r.csv", "--steps", "2", "--scene"])
        .arg(standard())
        .current_dir(dir.path())
        .stderr(full())
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
}
