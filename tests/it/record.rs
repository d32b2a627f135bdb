//! Trajectory records: format, determinism, and the command line's handling of bad input.

use std::process::Command;

pub(super) fn coevo(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_coevo")).args(args).output().expect("coevo runs")
}

fn record(dir: &std::path::Path, name: &str, scene: &str, seed: &str, steps: &str) -> String {
    let out = dir.join(name);
    let o = coevo(&["--record", out.to_str().unwrap(), "--scene", scene, "--steps", steps, "--seed", seed]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    std::fs::read_to_string(out).unwrap()
}

#[test]
fn same_scene_and_seed_give_byte_identical_records() {
    let dir = tempfile::tempdir().unwrap();
    for (i, scene) in ["scenes/confined.ron", "scenes/gym-pps.ron"].into_iter().enumerate() {
        let a = record(dir.path(), &format!("a{i}.csv"), scene, "7", "60");
        let b = record(dir.path(), &format!("b{i}.csv"), scene, "7", "60");
        let c = record(dir.path(), &format!("c{i}.csv"), scene, "8", "60");
        assert_eq!(a, b, "{scene}");
        assert_ne!(a, c, "{scene}: another seed, another trajectory");
    }
}

#[test]
fn a_policy_override_is_the_scene_file_that_sets_that_policy() {
    let dir = tempfile::tempdir().unwrap();
    // confined.ron's predators chase; a copy of the file with fleeing predators, and the override.
    let text = std::fs::read_to_string("scenes/confined.ron").unwrap();
    assert!(text.contains("policy: ChaseNearest"));
    let fleeing = dir.path().join("fleeing.ron");
    std::fs::write(&fleeing, text.replace("policy: ChaseNearest", "policy: FleeNearest")).unwrap();
    let by_file = record(dir.path(), "file.csv", fleeing.to_str().unwrap(), "4", "40");
    let out = dir.path().join("flag.csv");
    let args = ["--record", out.to_str().unwrap(), "--scene", "scenes/confined.ron", "--steps", "40", "--seed", "4"];
    let o = coevo(&[&args[..], &["--policy", "predator=FleeNearest"]].concat());
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(std::fs::read_to_string(&out).unwrap(), by_file);
    assert_ne!(record(dir.path(), "chase.csv", "scenes/confined.ron", "4", "40"), by_file, "the policy acts");
}

#[test]
fn record_rows_hold_state_action_and_reward_in_physical_units() {
    let dir = tempfile::tempdir().unwrap();
    let text = record(dir.path(), "r.csv", "scenes/confined.ron", "3", "20");
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some("step,id,species,x,y,vx,vy,theta,thrust,turn_rate,reward"));
    let rows: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
    assert_eq!(rows.len(), 21 * 13, "steps 0..=20 for 13 agents");
    for row in &rows {
        assert_eq!(row.len(), 11);
        let step: usize = row[0].parse().unwrap();
        let (x, y): (f64, f64) = (row[3].parse().unwrap(), row[4].parse().unwrap());
        assert!(x.abs() <= 1.0 && y.abs() <= 1.0, "inside the walls");
        if step == 0 {
            assert_eq!((row[5], row[6]), ("0", "0"), "spawned at rest");
        }
        if step == 20 {
            assert_eq!(&row[8..], ["", "", ""], "no transition after the last state");
        } else {
            let thrust: f64 = row[8].parse().unwrap();
            let turn: f64 = row[9].parse().unwrap();
            assert!((0.0..=1.0).contains(&thrust) && turn.abs() <= 0.5, "within the paper's limits");
            let reward: f64 = row[10].parse().unwrap();
            if row[2] == "predator" {
                // Chase-nearest: full thrust; reward = catches − 0.01·1 − 0.1·|turn|.
                assert_eq!(thrust, 1.0);
                let catches = reward + 0.01 + 0.1 * turn.abs();
                assert!((catches - catches.round()).abs() < 1e-9 && catches >= -1e-9, "{reward}");
            }
        }
    }
    // The position update uses the new velocity: x(t+1) = x(t) + v(t+1)·Δt for an agent away from walls.
    let at = |step: usize, id: &str| rows.iter().find(|r| r[0] == step.to_string() && r[1] == id).unwrap().clone();
    let (r0, r1) = (at(5, "4"), at(6, "4"));
    let f = |r: &Vec<&str>, i: usize| r[i].parse::<f64>().unwrap();
    assert!((f(&r1, 3) - (f(&r0, 3) + 0.1 * f(&r1, 5))).abs() < 1e-12);
}

#[test]
fn bad_input_is_one_line_and_a_failure_with_no_output() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("bad.ron");
    std::fs::write(&scene, "(\n  species: [(name: \"prey\", mass: -2.0)],\n)\n").unwrap();
    let out = dir.path().join("never.csv");
    let o = coevo(&["--record", out.to_str().unwrap(), "--scene", scene.to_str().unwrap()]);
    assert!(!o.status.success());
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(stderr.contains("bad.ron:2: species[prey].mass: must be a finite number > 0"), "{stderr}");
    assert!(!out.exists(), "no output file for a refused scene");
    assert!(std::fs::read_dir(dir.path()).unwrap().count() == 1, "no temporary left behind");

    let o = coevo(&["--record", out.to_str().unwrap(), "--scene", "scenes/missing.ron"]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("scenes/missing.ron: cannot read scene"));
}

#[test]
fn a_record_drives_learned_species_with_the_runs_actors() {
    use bevy::math::DVec2;
    use coevo::learning::{Learners, Mode};
    use coevo::scene::Scene;
    use coevo::sim::components::{AgentId, Heading, Position, Velocity};
    use coevo::sim::perception::{Batches, Perceive};
    let dir = tempfile::tempdir().unwrap();
    let run = dir.path().join("run");
    let mut scene = Scene::load(std::path::Path::new("scenes/paper.ron")).unwrap();
    scene.episode_steps = 20;
    scene.learning.hidden = 16;
    scene.learning.batch_size = 32;
    scene.learning.warmup_transitions = 32;
    scene.learning.updates_per_episode = 5;
    let opts = coevo::run::train::TrainOptions::new(run.clone(), Some(2));
    coevo::run::train::train(scene, &opts).unwrap();

    let out = dir.path().join("r.csv");
    let o = coevo(&["--record", out.to_str().unwrap(), "--run", run.to_str().unwrap(), "--steps", "6"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(
        String::from_utf8_lossy(&o.stderr).contains("prey: trained actor of"),
        "says which actor drives each species"
    );
    let text = std::fs::read_to_string(&out).unwrap();
    let rows: Vec<Vec<String>> = text.lines().skip(1).map(|l| l.split(',').map(str::to_string).collect()).collect();

    // Rebuild the state of step 4 from the record, perceive it and ask the trained actors.
    let mut sim =
        coevo::run::simulation(Scene::load(&run.join("scene.ron")).unwrap(), Mode::Evaluate, Some(&run)).unwrap();
    let step: Vec<&Vec<String>> = rows.iter().filter(|r| r[0] == "4").collect();
    let num = |r: &Vec<String>, i: usize| r[i].parse::<f64>().unwrap();
    {
        let world = sim.world_mut();
        let mut q = world.query::<(&AgentId, &mut Position, &mut Velocity, &mut Heading)>();
        for (id, mut x, mut v, mut h) in q.iter_mut(world) {
            let r = step.iter().find(|r| r[1] == id.0.to_string()).unwrap();
            x.0 = DVec2::new(num(r, 3), num(r, 4));
            v.0 = DVec2::new(num(r, 5), num(r, 6));
            h.0 = num(r, 7);
        }
        world.run_schedule(Perceive);
    }
    let world = sim.world();
    let learners = world.resource::<Learners>();
    let registry = world.resource::<coevo::sim::species::SpeciesRegistry>();
    for (s, def) in registry.defs.iter().enumerate() {
        let batch = &world.resource::<Batches>().species[s];
        let l = learners.species[s].as_ref().unwrap();
        let actions = l.ddpg.act(&l.dev, &batch.observations, batch.n);
        let recorded: Vec<&&Vec<String>> = step.iter().filter(|r| r[2] == def.name).collect();
        assert_eq!(recorded.len(), batch.n);
        for (row, r) in recorded.iter().enumerate() {
            let a = coevo::sim::policy::rescale(
                [actions[2 * row], actions[2 * row + 1]],
                def.max_thrust,
                def.max_turn_rate,
            );
            assert_eq!(
                (num(r, 8), num(r, 9)),
                (a.thrust, a.turn_rate),
                "{} {}: recorded action is the actor's",
                def.name,
                r[1]
            );
        }
    }
    // Not the old default of half thrust and no turning.
    assert!(rows.iter().filter(|r| !r[8].is_empty()).any(|r| num(r, 9) != 0.0));
}

#[test]
fn the_order_parameters_beside_a_record_are_those_of_its_trajectory() {
    use bevy::math::DVec2;
    let dir = tempfile::tempdir().unwrap();
    let steps = 15;
    let text = record(dir.path(), "t.csv", "scenes/gym-pps.ron", "5", &steps.to_string());
    let order = std::fs::read_to_string(dir.path().join("t-order.csv")).unwrap();
    let mut lines = order.lines();
    assert_eq!(lines.next(), Some("step,species,dos,doa,polarization,milling,clusters,largest_cluster,nn_correlation"));
    let rows: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
    assert_eq!(rows.len(), steps * 2, "both species, steps 1..={steps}");
    // Recomputed from the trajectory alone: the prey's positions and headings at each step.
    let scene = coevo::scene::Scene::load(std::path::Path::new("scenes/gym-pps.ron")).unwrap();
    let arena = coevo::sim::space::Arena { edge: scene.world.arena_edge, boundary: scene.world.boundary };
    let link = scene.cluster_link * 2.0 * scene.species[1].radius;
    for t in 1..=steps {
        let (pos, head): (Vec<DVec2>, Vec<DVec2>) = text
            .lines()
            .skip(1)
            .map(|l| l.split(',').collect::<Vec<_>>())
            .filter(|r| r[0] == t.to_string() && r[2] == "prey")
            .map(|r| {
                (DVec2::new(r[3].parse().unwrap(), r[4].parse().unwrap()), DVec2::from_angle(r[7].parse().unwrap()))
            })
            .unzip();
        let expected = coevo::sim::metrics::swarming_of(&arena, &pos, &head, link).unwrap().values();
        let row = rows.iter().find(|r| r[0] == t.to_string() && r[1] == "prey").unwrap();
        for (k, e) in expected.iter().enumerate() {
            let got: f64 = row[2 + k].parse().unwrap();
            assert!((got - e).abs() < 1e-9, "step {t}, column {}: {got} vs {e}", k + 2);
        }
    }
}

#[test]
fn the_force_map_of_fleeing_prey_shows_them_turning_away_from_the_predator() {
    // Prey that flee the nearest predator and predators that chase, recorded: the prey's map against the
    // nearest predator turns them right (−) when it is on their left and left (+) when on their right. Read
    // from positions and headings alone. (The chasers keep their prey dead ahead: their bins beside them
    // hold too few samples to read.)
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("rules.csv");
    let (traj, scene) = (out.to_str().unwrap(), "scenes/standard.ron");
    let rules = ["--policy", "prey=FleeNearest", "--policy", "predator=ChaseNearest"];
    let o = coevo(&[&["--record", traj, "--scene", scene, "--steps", "3000", "--prey", "20"][..], &rules].concat());
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let o = coevo(&["--force-map", traj, "--scene", scene]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = std::fs::read_to_string(dir.path().join("rules-force-map.csv")).unwrap();
    assert!(dir.path().join("rules-force-map-prey-predator.svg").exists());
    let mean_turning = |species: &str, observed: &str, left_side: bool| {
        let rows: Vec<f64> = text
            .lines()
            .skip(1)
            .map(|l| l.split(',').collect::<Vec<_>>())
            .filter(|r| r[0] == species && r[1] == observed && !r[5].is_empty())
            .filter(|r| {
                let left: f64 = r[3].parse().unwrap();
                if left_side {
                    left > 0.15
                } else {
                    left < -0.15
                }
            })
            .map(|r| r[5].parse::<f64>().unwrap())
            .collect();
        assert!(rows.len() >= 3, "{species}/{observed}: {} bins", rows.len());
        rows.iter().sum::<f64>() / rows.len() as f64
    };
    assert!(mean_turning("prey", "predator", true) < 0.0 && mean_turning("prey", "predator", false) > 0.0);
    // A second call refuses to overwrite without --overwrite, in one line.
    let o = coevo(&["--force-map", traj, "--scene", scene]);
    assert!(!o.status.success());
    assert_eq!(String::from_utf8_lossy(&o.stderr).lines().count(), 1);
    // Not a trajectory: one line naming the file.
    let o = coevo(&["--force-map", "scenes/standard.ron", "--scene", scene]);
    assert!(!o.status.success() && String::from_utf8_lossy(&o.stderr).contains("not a trajectory"));
}

#[test]
fn a_force_map_of_a_dotted_name_writes_only_the_files_it_names_and_leaves_the_users_untouched() {
    // `exp.v2.csv` beside the user's own `exp.svg` and `exp.png`: every pair's figure is named after the
    // whole trajectory name, the user's files stay as they were, and what is announced exists.
    let dir = tempfile::tempdir().unwrap();
    let traj = dir.path().join("exp.v2.csv");
    let (t, scene) = (traj.to_str().unwrap(), "scenes/standard.ron");
    let o = coevo(&["--record", t, "--scene", scene, "--steps", "60", "--prey", "8"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    for mine in ["exp.svg", "exp.png"] {
        std::fs::write(dir.path().join(mine), "the user's own").unwrap();
    }
    let o = coevo(&["--force-map", t, "--scene", scene]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    for mine in ["exp.svg", "exp.png"] {
        assert_eq!(std::fs::read_to_string(dir.path().join(mine)).unwrap(), "the user's own", "{mine}");
    }
    let said = String::from_utf8_lossy(&o.stdout);
    let announced: Vec<&str> = said.lines().filter_map(|l| l.strip_prefix("wrote ")).collect();
    assert_eq!(announced.len(), 5, "the CSV and four maps: {said}");
    for line in announced {
        let path = line.trim_end_matches(" (and .png)");
        assert!(std::path::Path::new(path).is_file(), "announced but not written: {path}");
        assert!(path.contains("exp.v2-force-map"), "{path}");
    }
    // A refusal comes before any output: a folder where the last figure goes leaves nothing new behind.
    let fresh = dir.path().join("again.csv");
    std::fs::copy(&traj, &fresh).unwrap();
    std::fs::create_dir(dir.path().join("again-force-map-prey-prey.png")).unwrap();
    let before = std::fs::read_dir(dir.path()).unwrap().count();
    let o = coevo(&["--force-map", fresh.to_str().unwrap(), "--scene", scene]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && stderr.lines().count() == 1 && stderr.contains("not a regular file"), "{stderr}");
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), before, "a file was written before the refusal");
    // Rows that mix agents up are refused, naming the line: an id twice in a step, an id that changes species.
    let text = std::fs::read_to_string(&traj).unwrap();
    let mut lines: Vec<String> = text.lines().map(String::from).collect();
    let twice = [lines.clone(), vec![lines[1].clone()]].concat().join("\n");
    let first_step_end = lines.iter().skip(1).take_while(|l| l.starts_with("0,")).count() + 1;
    let bad = dir.path().join("bad.csv");
    let mut dup = lines.clone();
    dup.insert(2, lines[1].clone());
    for (rows, says) in [(dup.join("\n"), "appears twice at step 0"), (twice, "steps must follow")] {
        std::fs::write(&bad, rows).unwrap();
        let o = coevo(&["--force-map", bad.to_str().unwrap(), "--scene", scene]);
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success() && stderr.lines().count() == 1 && stderr.contains(says), "{says}: {stderr}");
    }
    let cells: Vec<&str> = lines[first_step_end + 1].split(',').collect();
    let other = if cells[2] == "prey" { "predator" } else { "prey" };
    lines[first_step_end + 1] = [&cells[..2], &[other], &cells[3..]].concat().join(",");
    std::fs::write(&bad, lines.join("\n")).unwrap();
    let o = coevo(&["--force-map", bad.to_str().unwrap(), "--scene", scene]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && stderr.contains("earlier and is a"), "{stderr}");
}

#[test]
fn a_response_of_no_run_is_one_line_and_makes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("no-run");
    let o = coevo(&["--response", missing.to_str().unwrap()]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && stderr.lines().count() == 1 && stderr.contains("not a run folder"), "{stderr}");
    assert!(!missing.exists(), "no folder made for a path that was not there");
}

#[test]
fn distilled_rules_are_fitted_to_a_trained_run_and_deployed_as_scene_policies() {
    let dir = tempfile::tempdir().unwrap();
    let run = dir.path().join("trained");
    super::bad_inputs::copy_dir(std::path::Path::new("assets/trained-standard"), &run);
    let r = run.to_str().unwrap();
    let o = coevo(&["--distill", r, "--prey", "20", "--episodes", "2", "--steps", "60", "--quiet"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(stdout.contains("prey (Memoryless): variance explained on held-out episodes"), "{stdout}");
    let fitted = coevo::analysis::distill::DistilledFile::read(&run.join("distilled.ron")).unwrap();
    let rule = fitted.policy("prey", coevo::scene::RuleForm::Inertial).unwrap();
    assert!(matches!(rule, coevo::scene::Policy::Zonal(_)));
    assert!(matches!(
        fitted.policy("predator", coevo::scene::RuleForm::Memoryless),
        Some(coevo::scene::Policy::Pursuit(_))
    ));
    // The fitted rule is a policy like any other: --eval deploys it, and says so.
    let policy = format!("prey={}", ron::to_string(rule).unwrap());
    let o = coevo(&["--eval", r, "--prey", "20", "--steps", "30", "--policy", &policy, "--eval-out", "eval-rule.csv"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(String::from_utf8_lossy(&o.stdout).contains("prey: 20 (Zonal((repulsion_radius:"));
    // One line, nothing written: too few episodes to hold any out, and a folder without a run.
    let o = coevo(&["--distill", r, "--episodes", "1"]);
    assert!(!o.status.success() && String::from_utf8_lossy(&o.stderr).lines().count() == 1);
    assert!(String::from_utf8_lossy(&o.stderr).contains("needs ≥ 2"));
    let o = coevo(&["--distill", dir.path().join("none").to_str().unwrap()]);
    assert!(!o.status.success() && String::from_utf8_lossy(&o.stderr).contains("not a run folder with trained actors"));
    assert!(!dir.path().join("none").exists());
}

#[test]
fn a_record_as_npy_holds_the_csvs_positions_in_trajectorytools_layout() {
    // `--record OUT.npy`: [frames, individuals, 2] float64, frame t the state at step t, individuals by
    // id: the CSV record's x and y to the bit; OUT-species.npy names each individual's species.
    let dir = tempfile::tempdir().unwrap();
    let csv = record(dir.path(), "r.csv", "scenes/standard.ron", "3", "20");
    let npy = dir.path().join("n.npy");
    let o =
        coevo(&["--record", npy.to_str().unwrap(), "--scene", "scenes/standard.ron", "--steps", "20", "--seed", "3"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let bytes = std::fs::read(&npy).unwrap();
    assert_eq!(&bytes[..8], b"\x93NUMPY\x01\x00");
    let header_len = u16::from_le_bytes([bytes[8], bytes[9]]) as usize;
    assert_eq!((10 + header_len) % 64, 0, "the data starts on a 64-byte boundary, as NumPy writes it");
    let header = std::str::from_utf8(&bytes[10..10 + header_len]).unwrap();
    assert!(header.starts_with("{'descr': '<f8', 'fortran_order': False, 'shape': (21, 13, 2), }"), "{header}");
    let data: Vec<f64> =
        bytes[10 + header_len..].chunks_exact(8).map(|b| f64::from_le_bytes(b.try_into().unwrap())).collect();
    let rows: Vec<Vec<&str>> = csv.lines().skip(1).map(|l| l.split(',').collect()).collect();
    assert_eq!(data.len(), rows.len() * 2);
    for (k, row) in rows.iter().enumerate() {
        // Rows by step, then id: the array's order.
        assert_eq!([data[2 * k], data[2 * k + 1]], [row[3].parse::<f64>().unwrap(), row[4].parse::<f64>().unwrap()]);
    }
    let species = std::fs::read(dir.path().join("n-species.npy")).unwrap();
    let header_len = u16::from_le_bytes([species[8], species[9]]) as usize;
    assert!(std::str::from_utf8(&species[10..10 + header_len]).unwrap().contains("'descr': '<U8'"));
    let first: String = species[10 + header_len..10 + header_len + 32].chunks_exact(4).map(|c| c[0] as char).collect();
    assert_eq!(first, "predator");
    assert!(dir.path().join("n-order.csv").exists());
}

#[test]
fn a_record_as_netcdf_holds_the_csvs_positions_in_movement_s_layout() {
    // `--record OUT.nc`: a `movement` poses dataset, position (time, space, keypoint, individual) the CSV
    // record's x and y to the bit, individuals by id and named by species, time in seconds (fps = 1/dt);
    // an existing file is refused and left as it was.
    let dir = tempfile::tempdir().unwrap();
    let csv = record(dir.path(), "r.csv", "scenes/standard.ron", "3", "20");
    let nc = dir.path().join("m.nc");
    let args = ["--record", nc.to_str().unwrap(), "--scene", "scenes/standard.ron", "--steps", "20", "--seed", "3"];
    let o = coevo(&args);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let mut reader = netcdf3::FileReader::open(&nc).unwrap();
    let position = reader.read_var_f64("position").unwrap();
    let time = reader.read_var_f64("time").unwrap();
    let individuals = reader.read_var_u8("individual").unwrap();
    let species = reader.read_var_u8("species").unwrap();
    let set = reader.data_set();
    assert_eq!(set.get_var("position").unwrap().dim_names(), ["time", "space", "keypoint", "individual"]);
    assert_eq!(set.get_global_attr_as_string("ds_type").unwrap(), "poses");
    assert_eq!(set.get_global_attr_as_string("time_unit").unwrap(), "seconds");
    let fps = set.get_global_attr_f64("fps").unwrap()[0];
    let rows: Vec<Vec<&str>> = csv.lines().skip(1).map(|l| l.split(',').collect()).collect();
    let n = 13;
    assert_eq!(position.len(), rows.len() * 2);
    for (k, row) in rows.iter().enumerate() {
        let (t, i) = (k / n, k % n);
        let (x, y) = (position[t * 2 * n + i], position[t * 2 * n + n + i]);
        assert_eq!([x, y], [row[3].parse::<f64>().unwrap(), row[4].parse::<f64>().unwrap()]);
        assert_eq!(row[0].parse::<usize>().unwrap(), t);
    }
    assert_eq!(time.len(), 21);
    assert!((time[20] - 20.0 / fps).abs() < 1e-12);
    let words = |bytes: &[u8], width: usize| -> Vec<String> {
        bytes
            .chunks(width)
            .map(|c| String::from_utf8(c.iter().copied().take_while(|b| *b != 0).collect()).unwrap())
            .collect()
    };
    assert_eq!(words(&individuals, individuals.len() / n)[..4], ["predator_0", "predator_1", "predator_2", "prey_0"]);
    assert_eq!(words(&species, species.len() / n)[3], "prey");
    let before = std::fs::read(&nc).unwrap();
    let o = coevo(&args);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("m.nc"), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(std::fs::read(&nc).unwrap(), before);
    // A record that would not fit in memory is refused before its first step, writing nothing.
    let big = dir.path().join("big.nc");
    let o = coevo(&["--record", big.to_str().unwrap(), "--steps", "4000000000", "--prey", "1000"]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && stderr.contains("held in memory until it is written"), "{stderr}");
    assert!(!big.exists() && !dir.path().join("big-order.csv").exists());
}
