//! coevo driven from outside (`run::env`, the Rust side of the Python package): the same trajectory as
//! `coevo --record` when given the actions coevo's own actors would take, many worlds stepped together
//! exactly as each alone, and one-line refusals.

use coevo::learning::{Learners, Mode};
use coevo::run::env::{Coevolve, Env, Schedule, VecEnv};
use coevo::scene::Scene;
use coevo::sim::perception::Population;
use std::collections::BTreeMap;

fn standard(seed: u64) -> Scene {
    let mut scene = Scene::load(std::path::Path::new("scenes/standard.ron")).unwrap();
    scene.seed = seed;
    scene
}

/// Positions by agent id after every step, from a `--record` CSV.
fn recorded(path: &std::path::Path) -> BTreeMap<(usize, u32), [f64; 2]> {
    let text = std::fs::read_to_string(path).unwrap();
    text.lines()
        .skip(1)
        .map(|l| l.split(',').collect::<Vec<_>>())
        .map(|c| ((c[0].parse().unwrap(), c[1].parse().unwrap()), [c[3].parse().unwrap(), c[4].parse().unwrap()]))
        .collect()
}

#[test]
fn given_coevo_s_own_actions_the_outside_world_is_the_recorded_one_to_the_bit() {
    let (seed, steps) = (7, 40);
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("record.csv");
    let status = std::process::Command::new(env!("CARGO_BIN_EXE_coevo"))
        .args(["--record", out.to_str().unwrap(), "--scene", "scenes/standard.ron", "--seed", "7", "--steps", "40"])
        .output()
        .unwrap();
    assert!(status.status.success(), "{}", String::from_utf8_lossy(&status.stderr));
    let record = recorded(&out);

    let scene = standard(seed);
    // The actors `--record` deploys without --run: the networks initialised from the scene's seed.
    let learners = Learners::new(&scene, Mode::Evaluate);
    let mut env = Env::new(scene).unwrap();
    assert_eq!(env.agents()[0], "predator_0");
    assert_eq!(env.agents().len(), 13);
    let mut observations = env.reset(Some(seed)).unwrap();
    for t in 1..=steps {
        // Each species' rows through its own actor, in the env's agent order.
        let mut actions = vec![];
        let mut row = 0;
        for (s, l) in learners.species.iter().enumerate() {
            let Some(l) = l else { continue };
            let count = env.scene().species[s].count;
            let obs = &observations[row * env.obs_dim()..(row + count) * env.obs_dim()];
            let mut a = vec![0.0; count * 2];
            l.ddpg.act_into(&l.dev, obs, &mut a);
            actions.extend(a);
            row += count;
        }
        let step = env.step(&actions).unwrap();
        assert_eq!((step.rewards.len(), step.truncated), (13, false));
        observations = step.observations;
        let pop = env.world().resource::<Population>();
        for (id, p) in pop.id.iter().zip(&pop.position) {
            assert_eq!(record[&(t, id.0)], [p.x, p.y], "agent {} at step {t}", id.0);
        }
    }
}

#[test]
fn many_worlds_step_as_each_alone_and_start_their_next_episode() {
    let mut scene = standard(1);
    scene.episode_steps = 5;
    let mut worlds = VecEnv::new(scene.clone(), 3, 20).unwrap();
    let (agents, d) = (worlds.agents(), worlds.obs_dim());
    assert_eq!(worlds.observations().len(), 3 * agents * d);
    // World i is the single env of its world seed: world 0 of the seed itself.
    let seeds = worlds.world_seeds();
    assert_eq!(seeds, (0..3).map(|i| coevo::run::env::world_seed(20, i)).collect::<Vec<_>>());
    assert_eq!(seeds[0], 20);
    let mut alone: Vec<Env> = seeds
        .iter()
        .map(|&seed| {
            let mut s = scene.clone();
            s.seed = seed;
            Env::new(s).unwrap()
        })
        .collect();
    let actions: Vec<f32> = (0..3 * agents * 2).map(|i| ((i * 7919) % 200) as f32 / 100.0 - 1.0).collect();
    for t in 1..=7 {
        let step = worlds.step(&actions).unwrap();
        assert_eq!(step.truncated, vec![t == 5; 3], "step {t}");
        for (i, env) in alone.iter_mut().enumerate() {
            let mine = &actions[i * agents * 2..(i + 1) * agents * 2];
            let r = env.step(mine).unwrap();
            assert_eq!(&step.rewards[i * agents..(i + 1) * agents], r.rewards.as_slice(), "world {i}, step {t}");
            let observed = &step.observations[i * agents * d..(i + 1) * agents * d];
            if r.truncated {
                assert_eq!(step.final_observations[i].as_deref(), Some(r.observations.as_slice()));
                assert_eq!(observed, env.reset(None).unwrap().as_slice(), "the next episode's first state");
            } else {
                assert_eq!(observed, r.observations.as_slice());
                assert!(step.final_observations[i].is_none());
            }
        }
    }
}

#[test]
fn bad_actions_and_scenes_are_one_line() {
    let mut scene = standard(1);
    scene.episode_steps = 2;
    let mut env = Env::new(scene.clone()).unwrap();
    let e = env.step(&[0.0; 3]).unwrap_err().to_string();
    assert!(e.contains("actions: expected 26 values (13 agents × 2), got 3"), "{e}");
    let mut nan = vec![0.0; 26];
    nan[4] = f32::NAN;
    assert!(env.step(&nan).unwrap_err().to_string().contains("actions[4]: NaN is not a finite number"));
    assert!(env.step(&[0.0; 26]).is_ok() && env.step(&[0.0; 26]).unwrap().truncated);
    assert!(env.step(&[0.0; 26]).unwrap_err().to_string().contains("the episode is over"));
    for s in &mut scene.species {
        s.policy = coevo::scene::Policy::Random;
    }
    assert!(Env::new(scene).err().unwrap().to_string().contains("no Learned species"));
    assert!(VecEnv::new(standard(1), 0, 1).err().unwrap().to_string().contains("num_envs: must be ≥ 1"));
}

#[test]
fn every_observation_lies_within_the_declared_bounds() {
    // Random actions at full thrust and turn, in each shipped kind of world (torus and walls, both
    // presets, the body frame, a shuffled control): every number stays in [−high, high], and the bounds
    // are tight enough to say something (positions within the arena's half edge plus a body's reach).
    use rand::{Rng, SeedableRng};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
    for (file, frame, control) in [
        ("scenes/standard.ron", None, None),
        ("scenes/paper.ron", None, None),
        ("scenes/confined.ron", None, None),
        ("scenes/confined.ron", Some(coevo::scene::ObservationFrame::Body), None),
        ("scenes/standard.ron", Some(coevo::scene::ObservationFrame::Body), Some("shuffled:prey:prey")),
    ] {
        let mut scene = Scene::load(std::path::Path::new(file)).unwrap();
        scene.episode_steps = 100;
        if let Some(frame) = frame {
            scene.observation_frame = frame;
        }
        let world_frame = scene.observation_frame == coevo::scene::ObservationFrame::World;
        let mut env = match control {
            Some(c) => {
                Env::with_control(scene, coevo::learning::control::ObservationControl::parse(&[c.to_string()]).unwrap())
                    .unwrap()
            }
            None => Env::new(scene).unwrap(),
        };
        let high = env.observation_high();
        assert_eq!(high.len(), env.obs_dim());
        if world_frame {
            assert!(high[..2].iter().all(|&h| (1.0..1.2).contains(&h)), "{file}: {:?}", &high[..6]);
        }
        let mut seen = 0.0f32;
        for _ in 0..300 {
            let actions: Vec<f32> = (0..env.agents().len() * 2).map(|_| if rng.gen() { 1.0 } else { -1.0 }).collect();
            let r = env.step(&actions).unwrap();
            for (k, (x, h)) in r.observations.iter().zip(high.iter().cycle()).enumerate() {
                assert!(
                    x.abs() <= *h,
                    "{file} {frame:?}: number {} of an observation is {x}, beyond ±{h}",
                    k % high.len()
                );
                seen = seen.max(x.abs() / h);
            }
            // The global state within its bounds too (a state space's).
            for (k, (x, h)) in env.state().iter().zip(env.state_high()).enumerate() {
                assert!(x.abs() <= h, "{file}: number {k} of the state is {x}, beyond ±{h}");
            }
            if r.truncated {
                env.reset(None).unwrap();
            }
        }
        assert!(seen > 0.5, "{file}: the largest value reaches {seen} of its bound");
    }
}

#[test]
fn too_many_worlds_are_refused_up_front_with_the_figure() {
    let scene = coevo::scene::Scene::load(std::path::Path::new("scenes/paper.ron")).unwrap();
    let start = std::time::Instant::now();
    let e = coevo::run::env::VecEnv::new(scene, 100_000_000, 0).err().expect("refused").to_string();
    assert!(e.starts_with("num_envs: 100000000 worlds of this scene would need about "), "{e}");
    assert!(!e.contains(" 0.0 GB"), "{e}");
    assert!(start.elapsed().as_secs() < 5, "refused before building the worlds");
    assert_eq!(
        [coevo::io::bytes_shown(2.5e9), coevo::io::bytes_shown(3.2e6), coevo::io::bytes_shown(1.0)],
        ["2.5 GB", "3.2 MB", "1 kB"]
    );
}

#[test]
fn vecenvs_of_neighbouring_seeds_share_no_world() {
    // World i of seed s was seed s + i once, so seeds 1 and 2 of 32 worlds shared 31: runs with different
    // seeds were not independent samples. Now no two of the worlds of seeds 1..=3 share a seed; the old
    // seeding is kept, by name, to reproduce runs made with it.
    use coevo::run::env::{world_seed, WorldSeeds};
    let mut all: Vec<u64> = (1..=3u64).flat_map(|s| (0..32).map(move |i| world_seed(s, i))).collect();
    all.sort_unstable();
    all.dedup();
    assert_eq!(all.len(), 96);
    let scene = standard(1);
    let control = coevo::learning::control::ObservationControl::default();
    let old = VecEnv::seeded(scene.clone(), 3, 7, control.clone(), WorldSeeds::Consecutive).unwrap();
    assert_eq!(old.world_seeds(), vec![7, 8, 9]);
    let new = VecEnv::seeded(scene, 3, 7, control, WorldSeeds::Independent).unwrap();
    assert_eq!(new.world_seeds()[0], 7);
    assert!(!new.world_seeds()[1..].contains(&8));
}

/// A short scene whose learners update within a few episodes: 20 steps an episode, a small buffer warm-up.
fn quick(seed: u64) -> Scene {
    let mut scene = standard(seed);
    scene.episode_steps = 20;
    scene.learning.warmup_transitions = 32;
    scene.learning.batch_size = 16;
    scene.learning.hidden = 16;
    scene.learning.snapshot_every = 2;
    scene.learning.checkpoint_every = 2;
    scene
}

/// Plays `episodes` episodes of `env` (`from_start`: from the first episode of its seed, else from the next)
/// with the outside side's actions a fixed function of its observations, returning every observation
/// handed out.
fn play(env: &mut Env, episodes: usize, from_start: bool) -> Vec<f32> {
    let mut seen = vec![];
    let seed = from_start.then_some(env.scene().seed);
    let mut obs = env.reset(seed).unwrap();
    for e in 0..episodes {
        loop {
            seen.extend_from_slice(&obs);
            let actions: Vec<f32> =
                obs.chunks(env.obs_dim()).flat_map(|o| [o[0].tanh(), (o[1] - o[2]).tanh()]).collect();
            let step = env.step(&actions).unwrap();
            obs = step.observations;
            if step.truncated {
                break;
            }
        }
        if e + 1 < episodes {
            obs = env.reset(None).unwrap();
        }
    }
    seen
}

fn coevolve(schedule: Schedule) -> Coevolve {
    Coevolve { species: vec!["predator".into()], schedule }
}

#[test]
fn coevo_keeps_training_its_side_while_the_other_is_decided_outside_reproducibly() {
    let make = |schedule| Env::with_options(quick(5), Default::default(), coevolve(schedule)).unwrap();
    // Only the prey are handed out; the predators are coevo's.
    let mut learning = make(Schedule::Learning);
    assert!(learning.agents().iter().all(|a| a.starts_with("prey_")), "{:?}", learning.agents());
    let before = learning.coevo_actor("predator").unwrap();
    let seen = play(&mut learning, 4, true);
    let after = learning.coevo_actor("predator").unwrap();
    assert_ne!(before, after, "the predators' actor learned while the prey were decided outside");
    // The same seed and the same outside decisions: the same run, bit for bit.
    let mut again = make(Schedule::Learning);
    assert_eq!(play(&mut again, 4, true), seen);
    assert_eq!(again.coevo_actor("predator").unwrap(), after);
    // Held: its actor stays as initialised.
    let mut frozen = make(Schedule::Frozen);
    play(&mut frozen, 4, true);
    assert_eq!(frozen.coevo_actor("predator").unwrap(), before);
    // Taking turns every 2 episodes: learning in episodes 0–1, held in 2–3.
    let mut turns = make(Schedule::Alternate { every: 2 });
    play(&mut turns, 2, true);
    let learned = turns.coevo_actor("predator").unwrap();
    assert_ne!(learned, before);
    play(&mut turns, 2, false);
    assert_eq!(turns.coevo_actor("predator").unwrap(), learned, "held in episodes 2 and 3");
    play(&mut turns, 1, false);
    assert_ne!(turns.coevo_actor("predator").unwrap(), learned, "learning again in episode 4");
}

#[test]
fn coevo_s_side_is_saved_as_a_run_folder_and_refusals_are_one_line() {
    let mut env = Env::with_options(quick(5), Default::default(), coevolve(Schedule::Learning)).unwrap();
    play(&mut env, 4, true);
    env.reset(None).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let run = dir.path().join("run");
    env.save_run(&run).unwrap();
    let metrics = std::fs::read_to_string(run.join("metrics.csv")).unwrap();
    assert_eq!(metrics.lines().count(), 1 + 4, "{metrics}");
    assert!(run.join("scene.ron").is_file() && run.join("provenance.ron").is_file());
    // Its predators' snapshots, as `--train` takes them (here at episodes 0, 2 and 4): an opponent pool.
    let snapshots = std::fs::read_dir(run.join("snapshots")).unwrap().count();
    assert!(snapshots >= 3, "{snapshots} snapshot files");
    // And its actor deploys elsewhere as a frozen opponent, as any run's.
    let mut scene = quick(6);
    scene.species.iter_mut().filter(|s| s.name == "predator").for_each(|s| {
        s.policy = coevo::scene::Policy::Frozen(run.to_string_lossy().into_owned());
    });
    let mut against = Env::new(scene).unwrap();
    play(&mut against, 1, true);
    // Refused, each in one line.
    let refused = |c: Coevolve| Env::with_options(quick(5), Default::default(), c).err().unwrap().to_string();
    let unknown = refused(Coevolve { species: vec!["wolf".into()], schedule: Schedule::Learning });
    assert!(unknown.contains("\"wolf\" is not a learned species"), "{unknown}");
    let both = refused(Coevolve { species: vec!["predator".into(), "prey".into()], schedule: Schedule::Learning });
    assert!(both.contains("none is left to decide from outside"), "{both}");
    let zero = refused(Coevolve { species: vec!["predator".into()], schedule: Schedule::Alternate { every: 0 } });
    assert!(zero.contains("every 0 episodes"), "{zero}");
    let controlled = Env::with_options(
        quick(5),
        coevo::learning::control::ObservationControl::parse(&["blind:predator:prey".to_string()]).unwrap(),
        coevolve(Schedule::Learning),
    )
    .err()
    .unwrap()
    .to_string();
    assert!(controlled.contains("predator is coevo's"), "{controlled}");
    // A reset that cuts an episode short leaves coevo's side without that episode's end: not saved.
    let mut cut = Env::with_options(quick(5), Default::default(), coevolve(Schedule::Learning)).unwrap();
    let first = cut.reset(Some(5)).unwrap();
    cut.step(&vec![0.0; first.len() / cut.obs_dim() * 2]).unwrap();
    cut.reset(None).unwrap();
    let refused_cut = cut.save_run(&dir.path().join("cut")).unwrap_err().to_string();
    assert!(refused_cut.contains("cut short"), "{refused_cut}");
    let plain = Env::new(quick(5)).unwrap().save_run(&dir.path().join("other")).unwrap_err().to_string();
    assert!(plain.contains("coevolve names none"), "{plain}");
    for message in [unknown, both, zero, plain, controlled, refused_cut] {
        assert!(!message.contains('\n'), "{message}");
    }
}
