//! A battery of bad and hostile inputs, one per class of mistake: every one must end with a non-zero exit,
//! exactly one line on stderr naming the file or flag and the field, no panic, and nothing written,
//! replaced or deleted (the working folder is compared file by file before and after).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;

/// Every file under `dir` with its bytes (symlinks as their target), so a run that wrote, replaced or
/// deleted anything shows up as a difference.
fn snapshot(dir: &Path) -> BTreeMap<PathBuf, Vec<u8>> {
    let mut files = BTreeMap::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for entry in std::fs::read_dir(&d).unwrap() {
            let path = entry.unwrap().path();
            let meta = std::fs::symlink_metadata(&path).unwrap();
            if meta.file_type().is_symlink() {
                files.insert(path.clone(), std::fs::read_link(&path).unwrap().to_string_lossy().as_bytes().to_vec());
            } else if meta.is_dir() {
                files.insert(path.clone(), b"<dir>".to_vec());
                stack.push(path);
            } else {
                files.insert(path.clone(), std::fs::read(&path).unwrap());
            }
        }
    }
    files
}

/// A working folder with the project's scenes, a trained run, a run whose actor holds a NaN, a user's
/// file, a link to it and a folder of the user's.
fn workspace() -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path();
    std::fs::create_dir(root.join("scenes")).unwrap();
    for entry in std::fs::read_dir("scenes").unwrap() {
        let path = entry.unwrap().path();
        std::fs::copy(&path, root.join("scenes").join(path.file_name().unwrap())).unwrap();
    }
    let mut scene = coevo::scene::Scene::load(Path::new("scenes/paper.ron")).unwrap();
    scene.episode_steps = 10;
    scene.learning.hidden = 8;
    scene.learning.batch_size = 16;
    scene.learning.warmup_transitions = 16;
    scene.learning.updates_per_episode = 2;
    for run in ["run", "nan-run"] {
        let opts = coevo::run::train::TrainOptions::new(root.join(run), Some(1));
        coevo::run::train::train(scene.clone(), &opts).unwrap();
    }
    // Two episodes, a checkpoint and a snapshot after each: two replay segments per species of equal
    // size, and rows to lose.
    let mut twice = scene.clone();
    twice.learning.checkpoint_every = 1;
    twice.learning.snapshot_every = 1;
    coevo::run::train::train(twice.clone(), &coevo::run::train::TrainOptions::new(root.join("run2"), Some(2))).unwrap();
    twice.seed += 1;
    coevo::run::train::train(twice, &coevo::run::train::TrainOptions::new(root.join("other-seed"), Some(2))).unwrap();
    // A NaN in the prey actor's first weight: the safetensors header is followed by the tensors' bytes.
    let actor = root.join("nan-run/checkpoint/prey-actor.safetensors");
    let mut bytes = std::fs::read(&actor).unwrap();
    let header = u64::from_le_bytes(bytes[..8].try_into().unwrap()) as usize;
    let text = String::from_utf8(bytes[8..8 + header].to_vec()).unwrap();
    let at = text.find("\"0.weight\"").unwrap();
    let offsets = &text[at..];
    let start: usize =
        offsets[offsets.find("data_offsets\":[").unwrap() + 15..].split(',').next().unwrap().parse().unwrap();
    bytes[8 + header + start..8 + header + start + 4].copy_from_slice(&f32::NAN.to_le_bytes());
    std::fs::write(&actor, bytes).unwrap();

    // Runs that must not be resumed as they are: scene.ron edited after training, episodes_done lowered
    // by hand, a species plugin this binary lacks, and one another live process holds.
    for (run, file, from, to) in [
        ("edited-run", "scene.ron", "max_speed: 0.5", "max_speed: 0.4"),
        ("lowered-run", "checkpoint/state.ron", "episodes_done: 1", "episodes_done: 0"),
    ] {
        copy_dir(&root.join("run"), &root.join(run));
        let path = root.join(run).join(file);
        let text = std::fs::read_to_string(&path).unwrap();
        assert!(text.contains(from), "{file} holds {from}");
        std::fs::write(&path, text.replacen(from, to, 1)).unwrap();
    }
    damage(root);
    copy_dir(&root.join("run"), &root.join("hawk-run"));
    std::fs::write(root.join("hawk-run/provenance.ron"), "(coevo_version: \"0.1.0\", plugins: [\"hawk\"])\n").unwrap();
    copy_dir(&root.join("run"), &root.join("kernels-run"));
    std::fs::write(
        root.join("kernels-run/provenance.ron"),
        "(coevo_version: \"0.1.0\", kernels: \"another-family\", plugins: [])\n",
    )
    .unwrap();
    // A run as coevo ships them, under assets/ of a source tree (provenance.ron says where).
    std::fs::write(root.join("Cargo.toml"), "[package]\nname = \"coevo\"\n").unwrap();
    copy_dir(&root.join("run"), &root.join("assets/shipped-run"));
    let provenance = std::fs::read_to_string(root.join("run/provenance.ron")).unwrap();
    let shipped = provenance.trim_end().strip_suffix(')').unwrap().to_string()
        + "    shipped: Some(\"assets/shipped-run\"),\n)\n";
    std::fs::write(root.join("assets/shipped-run/provenance.ron"), shipped).unwrap();
    copy_dir(&root.join("run"), &root.join("busy-run"));
    std::fs::write(root.join("busy-run/coevo.lock"), format!("{}\n", std::process::id())).unwrap();
    std::fs::create_dir(root.join("experiments")).unwrap();
    for (name, text) in EXPERIMENTS {
        std::fs::write(root.join("experiments").join(format!("{name}.ron")), text).unwrap();
    }
    std::fs::create_dir_all(root.join("results/report-dir/REPORT.md")).unwrap();

    std::fs::write(root.join("notes.csv"), "a user's file\n").unwrap();
    std::fs::write(root.join("notes.gif"), "a user's picture\n").unwrap();
    std::fs::create_dir(root.join("mine")).unwrap();
    std::fs::write(root.join("mine/thesis.txt"), "not a run\n").unwrap();
    #[cfg(unix)]
    std::os::unix::fs::symlink(root.join("notes.csv"), root.join("link.csv")).unwrap();
    dir
}

/// Runs damaged after training, each in one way (robustness III): every one is refused by whatever reads
/// it, in one line naming the file.
fn damage(root: &Path) {
    let copy = |from: &str, to: &str| {
        copy_dir(&root.join(from), &root.join(to));
        root.join(to)
    };
    let flip = |path: &Path, at: usize| {
        let mut bytes = std::fs::read(path).unwrap();
        let n = bytes.len();
        bytes[n - at] ^= 0x01;
        std::fs::write(path, bytes).unwrap();
    };
    let swap = |a: &Path, b: &Path| {
        let tmp = a.with_extension("swap");
        std::fs::rename(a, &tmp).unwrap();
        std::fs::rename(b, a).unwrap();
        std::fs::rename(&tmp, b).unwrap();
    };
    // The predator's and the prey's actors swapped (the same shapes in the paper preset).
    let run = copy("run", "swapped-run");
    swap(&run.join("checkpoint/prey-actor.safetensors"), &run.join("checkpoint/predator-actor.safetensors"));
    // One finite weight changed in its last bit.
    flip(&copy("run", "tweaked-run").join("checkpoint/prey-actor.safetensors"), 6);
    // A NaN written over the last transition of a replay segment.
    let run = copy("run", "nan-segment-run");
    let segment = std::fs::read_dir(run.join("checkpoint"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .find(|p| p.to_string_lossy().contains("prey-replay-"))
        .unwrap();
    let mut bytes = std::fs::read(&segment).unwrap();
    let n = bytes.len();
    bytes[n - 4..].copy_from_slice(&f32::NAN.to_le_bytes());
    std::fs::write(&segment, bytes).unwrap();
    // Two replay segments of one size swapped.
    let run = copy("run2", "swapped-segments-run");
    let mut segments: Vec<PathBuf> = std::fs::read_dir(run.join("checkpoint"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.to_string_lossy().contains("predator-replay-"))
        .collect();
    segments.sort();
    assert_eq!(segments.len(), 2);
    assert_eq!(std::fs::metadata(&segments[0]).unwrap().len(), std::fs::metadata(&segments[1]).unwrap().len());
    swap(&segments[0], &segments[1]);
    // The random stream's state edited in state.ron.
    let state = copy("run", "reseeded-run").join("checkpoint/state.ron");
    let text = std::fs::read_to_string(&state).unwrap();
    let at = text.find("seed: (").unwrap() + "seed: (".len();
    let digit = text[at..].find(|c: char| c.is_ascii_digit()).unwrap() + at;
    let changed = if &text[digit..=digit] == "7" { "8" } else { "7" };
    std::fs::write(&state, format!("{}{changed}{}", &text[..digit], &text[digit + 1..])).unwrap();
    // A metrics row edited (the episode's step count).
    let metrics = copy("run", "edited-row-run").join("metrics.csv");
    let text = std::fs::read_to_string(&metrics).unwrap();
    std::fs::write(&metrics, text.replacen("\n0,10,", "\n0,11,", 1)).unwrap();
    // The manifest removed.
    std::fs::remove_file(copy("run", "unsealed-run").join("checkpoint/manifest.ron")).unwrap();
    // The manifest's scene edited (its files' hashes left as they are).
    let manifest = copy("run", "rescened-run").join("checkpoint/manifest.ron");
    let text = std::fs::read_to_string(&manifest).unwrap();
    let id = text.split("scene: \"").nth(1).unwrap().split('"').next().unwrap().to_string();
    std::fs::write(&manifest, text.replacen(&id, "0123456789abcdef", 1)).unwrap();
    // A snapshot copied in from a run of another scene (another seed).
    let run = copy("run2", "foreign-snapshot-run");
    std::fs::copy(
        root.join("other-seed/snapshots/prey-ep00001.safetensors"),
        run.join("snapshots/prey-ep00001.safetensors"),
    )
    .unwrap();
    // metrics.csv broken for plots: a row repeated, a row lost, a row cut mid-line, a NaN, a header only,
    // rows after the last checkpoint.
    let metrics = |run: &str| std::fs::read_to_string(root.join(run).join("metrics.csv")).unwrap();
    let lines: Vec<String> = metrics("run2").lines().map(str::to_string).collect();
    let write = |run: &str, text: String| std::fs::write(copy("run2", run).join("metrics.csv"), text).unwrap();
    write("repeated-row-run", format!("{}\n{}\n", lines.join("\n"), lines[2]));
    write("lost-row-run", format!("{}\n{}\n", lines[0], lines[1]));
    write("cut-row-run", format!("{}\n{}", lines[..2].join("\n"), &lines[2][..lines[2].len() / 2]));
    let mut cells: Vec<&str> = lines[1].split(',').collect();
    cells[2] = "NaN";
    write("nan-row-run", format!("{}\n{}\n{}\n", lines[0], cells.join(","), lines[2]));
    write("header-only-run", format!("{}\n", lines[0]));
    let mut next: Vec<String> = lines[2].split(',').map(str::to_string).collect();
    next[0] = "2".into();
    write("after-checkpoint-run", format!("{}\n{}\n", lines.join("\n"), next.join(",")));
    // Outputs that cannot be written (a folder where a file goes), refused before any episode is played:
    // eval.csv is not replaced first, nor figures/ made before crossplay-readouts.csv.
    std::fs::create_dir(copy("run", "eval-dir-run").join("eval-nn.csv")).unwrap();
    std::fs::create_dir(copy("run2", "crossplay-dir-run").join("crossplay-readouts.csv")).unwrap();
    // Folders of the run that are links: figures/ to a user's folder, snapshots/ to another run's.
    #[cfg(unix)]
    {
        std::os::unix::fs::symlink(root.join("mine"), copy("run2", "linked-figures-run").join("figures")).unwrap();
        let run = copy("run2", "linked-snapshots-run");
        std::fs::remove_dir_all(run.join("snapshots")).unwrap();
        std::os::unix::fs::symlink(root.join("run2/snapshots"), run.join("snapshots")).unwrap();
    }
}

/// A copy of the folder `from` at `to` (files and folders only).
pub(super) fn copy_dir(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for entry in std::fs::read_dir(from).unwrap() {
        let entry = entry.unwrap();
        if entry.file_type().unwrap().is_dir() {
            copy_dir(&entry.path(), &to.join(entry.file_name()));
        } else {
            std::fs::copy(entry.path(), to.join(entry.file_name())).unwrap();
        }
    }
}

/// Experiment files written into the workspace's experiments/, by name: each is refused at load, before
/// anything is trained or written.
const EXPERIMENTS: &[(&str, &str)] = &[
    ("dotdot", r#"(base: "scenes/paper.ron", seeds: [1], variants: [(name: "..")])"#),
    ("dot", r#"(base: "scenes/paper.ron", seeds: [1], variants: [(name: ".")])"#),
    ("...", r#"(base: "scenes/paper.ron", seeds: [1], variants: [(name: "a")])"#),
    ("no-presets", r#"(base: "scenes/paper.ron", presets: [], seeds: [1], variants: [(name: "a")])"#),
    ("twin-presets", r#"(base: "scenes/paper.ron", presets: ["paper", "paper"], seeds: [1], variants: [(name: "a")])"#),
    ("twin-seeds", r#"(base: "scenes/paper.ron", seeds: [1, 2, 1], variants: [(name: "a")])"#),
    ("no-episodes", r#"(base: "scenes/paper.ron", seeds: [1], episodes: 0, variants: [(name: "a")])"#),
    (
        "nan-claim",
        r#"(base: "scenes/paper.ron", seeds: [1], variants: [(name: "a")], claims: [(text: "t", variant: "a", quantity: DoaLast, paper: NaN)])"#,
    ),
    (
        "ours-sized-claim",
        r#"(base: "scenes/paper.ron", seeds: [1], variants: [(name: "a")], claims: [(text: "t", variant: "a", quantity: DoaLast, paper: 0.9, ours: true)])"#,
    ),
    (
        "inf-claim",
        r#"(base: "scenes/paper.ron", seeds: [1], variants: [(name: "a")], claims: [(text: "t", variant: "a", quantity: DoaLast, paper: inf)])"#,
    ),
    (
        "radius",
        r#"(base: "scenes/paper.ron", seeds: [1], variants: [(name: "a")], evaluations: [(name: "x", confusion_radius: -1.0)])"#,
    ),
    (
        "collide",
        r#"(base: "scenes/paper.ron", seeds: [1], variants: [(name: "a")], evaluations: [(name: "x"), (name: "x-confusion")])"#,
    ),
    (
        "comma",
        r#"(base: "scenes/paper.ron", seeds: [1], variants: [(name: "a", patch: (species: [(name: "pr,ey", count: 2, mass: 1.0, radius: 0.03, max_speed: 0.5, max_thrust: 1.0, max_turn_rate: 0.5, perception: Full, topological_limit: 6, colour: (0.1, 0.1, 0.1), catches: [], policy: Random)]))])"#,
    ),
    ("fine", r#"(base: "scenes/paper.ron", seeds: [1, 2], variants: [(name: "a")])"#),
    // Its REPORT.md is a folder (made in the workspace): refused before any run trains.
    ("report-dir", r#"(base: "scenes/paper.ron", seeds: [1], variants: [(name: "a")])"#),
    // Found only after runs had trained, before robustness III: refused at load now.
    ("zero-crossplay", r#"(base: "scenes/paper.ron", seeds: [1], variants: [(name: "a")], crossplay: (episodes: 0))"#),
    ("nul-variant", "(base: \"scenes/paper.ron\", seeds: [1], variants: [(name: \"a\u{0}b\")])"),
];

/// Scenes written into the workspace for the cases below, by name.
const SCENES: &[(&str, &str)] = &[
    ("subnormal-mass", r#"(species: [(name: "prey", mass: 1e-310)])"#),
    ("huge-dt", "(world: (dt: 50.0))"),
    ("stiff", "(world: (contact_stiffness: 1e9))"),
    ("stiff-walls", "(world: (boundary: Walls, wall_stiffness: 1e7))"),
    ("fast", r#"(species: [(name: "prey", max_speed: 40.0)])"#),
    ("noise", "(learning: (noise_std: 1e300))"),
    ("limit", r#"(species: [(name: "prey", topological_limit: 100000000000)])"#),
    ("hidden", "(learning: (hidden: 100000000))"),
    ("batch", "(learning: (batch_size: 100000000000, buffer_capacity: 100000000000))"),
    ("buffer", r#"(learning: (buffer_capacity: 100000000000), species: [(name: "prey", count: 100000)])"#),
    ("plugin", r#"(species: [(name: "prey", policy: Plugin("nobody"))])"#),
    ("twice", r#"(species: [(name: "prey", count: 3), (name: "prey", count: 4)])"#),
    ("basilisk", r#"(species: [(name: "basilisk", count: 2)])"#),
    ("pair", r#"(contact_rewards: [(catcher: "prey", caught: "predator", catcher_reward: 1.0, caught_reward: -1.0)])"#),
    ("cannibal", r#"(species: [(name: "prey", catches: ["prey"])])"#),
    ("blind-to", r#"(species: [(name: "prey", blind_to: ["hawk"])])"#),
    (
        "perceive-twice",
        r#"(species: [(name: "prey", perception_of: [("predator", Full), ("predator", Radius(0.1))])])"#,
    ),
    ("perceive-zero", r#"(species: [(name: "prey", perception_of: [("predator", FractionOfD(0.0))])])"#),
    ("slots-of", r#"(species: [(name: "prey", topological_limit_of: [("hawk", 2)])])"#),
    ("slots-huge", r#"(species: [(name: "prey", topological_limit_of: [("predator", 18446744073709551615)])])"#),
    ("authors-body", "(observation_layout: Authors, observation_frame: Body)"),
    ("no-episodes", "(episodes: 0)"),
    ("fraction", r#"(species: [(name: "prey", count: 2.5)])"#),
    ("truncated", "(\n  seed: 3,\n  species: [(name: \"prey\", count: 2)\n"),
    ("frozen-missing", r#"(species: [(name: "prey", policy: Frozen("no-such-run"))])"#),
    ("unknown-field", "(world: (gravity: 9.81))"),
    (
        "long-species",
        r#"(species: [(name: "prey", count: 0), (name: "LONG", count: 2, mass: 1.0, radius: 0.03, max_speed: 0.5, max_thrust: 1.0, max_turn_rate: 0.5, perception: Full, topological_limit: 6, colour: (0.1, 0.1, 0.1), catches: [], policy: Random)])"#,
    ),
    (
        "comma",
        r#"(species: [(name: "prey", count: 3), (name: "pr,ey", count: 2, mass: 1.0, radius: 0.03, max_speed: 0.5, max_thrust: 1.0, max_turn_rate: 0.5, perception: Full, topological_limit: 6, colour: (0.1, 0.1, 0.1), catches: [], policy: Random)])"#,
    ),
];

/// (arguments, what the one error line must contain).
fn cases() -> Vec<(Vec<&'static str>, &'static str)> {
    vec![
        // Values that would blow the integrator up or write NaN.
        (vec!["--train", "--scene", "subnormal-mass.ron"], "species[prey].mass: drag·dt/mass"),
        (vec!["--train", "--scene", "huge-dt.ron"], "drag·dt/mass"),
        (vec!["--train", "--scene", "stiff.ron"], "world.contact_stiffness: k·dt²"),
        (vec!["--record", "out.csv", "--scene", "stiff-walls.ron"], "world.wall_stiffness"),
        (vec!["--train", "--scene", "fast.ron"], "species[prey].max_speed: a body would move"),
        (vec!["--eval", "nan-run"], "prey-actor.safetensors: tensor 0.weight holds a non-finite value"),
        (vec!["--eval", "eval-dir-run"], "eval-dir-run/eval-nn.csv: exists and is not a regular file"),
        (vec!["--crossplay", "crossplay-dir-run"], "crossplay-readouts.csv: exists and is not a regular file"),
        // Outputs that would destroy or replace something.
        (vec!["--train", "--out", "run"], "run: already holds a run; continue it with --resume run"),
        (vec!["--train", "--out", "mine", "--overwrite"], "mine: is not empty and holds no coevo run"),
        (vec!["--train", "--out", "notes.csv"], "notes.csv: exists and is not a folder"),
        (vec!["--record", "notes.csv"], "notes.csv: already exists; choose a new name or pass --overwrite"),
        (vec!["--record", "link.csv", "--overwrite"], "link.csv: exists and is not a regular file"),
        (vec!["--record", "mine", "--overwrite"], "mine: exists and is not a regular file"),
        (
            vec!["--train", "--scene", "frozen-missing.ron", "--out", "fresh"],
            "no-such-run/checkpoint/prey-actor.safetensors",
        ),
        // Sizes that would panic or exhaust memory.
        (vec!["--train", "--scene", "noise.ron"], "learning.noise_std: must be ≤ 10"),
        (vec!["--bench", "--bench-seconds", "inf"], "--bench-seconds: must be a number of seconds in (0, 3600]"),
        (vec!["--bench", "--bench-seconds", "NaN"], "--bench-seconds"),
        (vec!["--bench", "--bench-seconds", "0"], "--bench-seconds"),
        (vec!["--train", "--scene", "limit.ron"], "species[prey]: 10 agents with observations of"),
        (vec!["--eval", "run", "--prey", "100000000000"], "species[prey]: 100000000000 agents"),
        (vec!["--train", "--scene", "hidden.ron"], "learning.hidden: networks of width 100000000"),
        (vec!["--train", "--scene", "batch.ron"], "learning.batch_size: mini-batches of 100000000000"),
        (vec!["--train", "--scene", "buffer.ron"], "learning.buffer_capacity: a replay buffer of"),
        (vec!["--train", "--scene", "/dev/zero"], "/dev/zero: is not a regular file"),
        (vec!["--record", "out.csv", "--threads", "0"], "'--threads <N>': must be ≥ 1"),
        (vec!["--animate", "clip.png"], "--animate clip.png: the file must end in .gif"),
        (vec!["--animate", "notes.gif"], "notes.gif: already exists; choose a new name or pass --overwrite"),
        (vec!["--animate", "clip.gif", "--size", "10"], "'--size <PX>': 10 is not in 64..=2048"),
        (vec!["--animate", "clip.gif", "--steps-per-frame", "0"], "'--steps-per-frame <N>': must be ≥ 1"),
        (vec!["--frames", "0"], "'--frames <N>': must be ≥ 1"),
        (vec!["--experiment", "all", "--jobs", "0"], "'--jobs <J>': must be ≥ 1"),
        (
            vec!["--animate", "clip.gif", "--run", "nan-run"],
            "prey-actor.safetensors: tensor 0.weight holds a non-finite value",
        ),
        (
            vec!["--animate", "clip.gif", "--control", "blind"],
            "the argument '--animate <OUT.gif>' cannot be used with '--control <CONTROL>'",
        ),
        (vec!["--eval", "run", "--confusion-radius", "0"], "confusion_radius: must be a finite number > 0"),
        // Silent accepts.
        (
            vec!["--record", "out.csv", "--scene", "plugin.ron"],
            "species[prey].policy: no plugin decides Plugin(\"nobody\")",
        ),
        (vec!["--train", "--scene", "twice.ron"], "species[prey]: appears twice in this scene"),
        (
            vec!["--describe-scene", "basilisk.ron"],
            "basilisk.ron:1: species[basilisk]: no preset or species plugin of this program defines \"basilisk\"",
        ),
        (vec!["--describe-scene", "pair.ron"], "pair.ron: contact_rewards[0]: prey does not catch predator"),
        (vec!["--describe-scene", "nothere.ron"], "nothere.ron: cannot read scene"),
        (
            vec!["--describe-scene", "scenes/paper.ron", "--steps", "3"],
            "'--describe-scene <FILE>' cannot be used with '--steps <N>'",
        ),
        (vec!["--train", "--scene", "cannibal.ron"], "species[prey].catches: a species cannot catch itself"),
        (vec!["--train", "--scene", "blind-to.ron"], "species[prey].blind_to: no species named \"hawk\" in this scene"),
        (vec!["--describe-scene", "perceive-twice.ron"], "species[prey].perception_of: \"predator\" is named twice"),
        (vec!["--describe-scene", "perceive-zero.ron"], "species[prey].perception_of: must be"),
        (vec!["--describe-scene", "slots-of.ron"], "species[prey].topological_limit_of: no species named \"hawk\" in this scene"),
        (vec!["--train", "--scene", "slots-huge.ron"], "species[prey]: 10 agents with observations of"),
        (vec!["--describe-scene", "authors-body.ron"], "observation_layout: Authors is the authors' code's world-frame observation"),
        (vec!["--eval", "run", "--control", "blinded"], "--control: \"blinded\" is not a control"),
        (vec!["--eval", "run", "--policy", "predator=Chase"], "--policy predator=Chase: Chase is not a policy"),
        (vec!["--eval", "run", "--policy", "predator"], "--policy predator: expected NAME=POLICY"),
        (vec!["--eval", "run", "--policy", "hawk=Still"], "scene.ron: no species named \"hawk\""),
        (vec!["--train", "--policy", "predator=Still"], "'--train' cannot be used with '--policy"),
        (
            vec!["--eval", "run", "--untrained", "--seed", "3"],
            "--untrained: deploys the networks the run was initialised with",
        ),
        (
            vec!["--eval", "run", "--control", "blind:prey:hawk"],
            "--control: blind:prey:hawk: no species named \"hawk\"",
        ),
        (
            vec!["--eval", "run", "--control", "blind", "--control", "shuffled:prey:prey"],
            "--control: blind, shuffled:prey:prey: only block forms",
        ),
        (vec!["--train", "--eval", "run"], "'--train' cannot be used with '--eval <DIR>'"),
        (vec!["--record", "out.csv", "--train"], "cannot be used with"),
        (vec!["--train", "--steps", "5"], "the argument '--train' cannot be used with '--steps <N>'"),
        (vec!["--train", "--prey", "50"], "'--train' cannot be used with '--prey <N>'"),
        (
            vec!["--resume", "run", "--scene", "scenes/paper.ron"],
            "'--resume <DIR>' cannot be used with '--scene <PATH>'",
        ),
        (vec!["--eval", "run", "--out", "x"], "'--eval <DIR>' cannot be used with '--out <DIR>'"),
        (vec!["--bench", "--seed", "3"], "'--bench' cannot be used with '--seed <S>'"),
        (
            vec!["--episodes", "5"],
            "the following required arguments were not provided: <--train|--resume <DIR>|--eval <DIR>|--crossplay <DIR>|--distill <DIR>>",
        ),
        (vec!["--train", "--episodes", "0"], "--episodes: must be ≥ 1"),
        (vec!["--train", "--scene", "no-episodes.ron"], "no-episodes.ron:1: episodes: must be ≥ 1"),
        (vec!["--eval", "run", "--steps", "0"], "'--steps <N>': must be ≥ 1"),
        (vec!["--resume", "mine"], "mine: holds no coevo run to resume"),
        (vec!["--train", "--bogus"], "unexpected argument '--bogus'"),
        // Messages in a user's words.
        (vec!["--train", "--scene", "fraction.ron"], "fraction.ron:1: count: must be a whole number (got 2.5)"),
        (vec!["--train", "--scene", "truncated.ron"], "the file ends too early"),
        (vec!["--train", "--scene", "unknown-field.ron"], "gravity"),
        (vec!["--train", "--scene", "binary.ron"], "binary.ron: is not UTF-8 text"),
        (vec!["--train", "--episodes", "-1"], "invalid value '-1' for '--episodes <N>'"),
        (vec!["--describe-scene", "comma.ron"], "species[2].name: \"pr,ey\": use letters, digits, _ and - only"),
        // A run continues only as the run it is: its own scene, its own episodes, its own plugins, one
        // process at a time.
        (
            vec!["--resume", "edited-run", "--episodes", "3"],
            "edited-run/scene.ron: differs from the scene the run was trained on",
        ),
        (
            vec!["--resume", "lowered-run", "--episodes", "3"],
            "lowered-run/checkpoint/state.ron: changed since the checkpoint was written",
        ),
        (
            vec!["--resume", "run", "--episodes", "1"],
            "run: already trained 1 episodes and --episodes 1 asks for no more",
        ),
        (vec!["--resume", "hawk-run", "--episodes", "3"], "hawk-run: the run needs the species plugin \"hawk\""),
        (vec!["--eval", "hawk-run"], "the run needs the species plugin \"hawk\""),
        (vec!["--record", "out.csv", "--run", "hawk-run"], "the run needs the species plugin \"hawk\""),
        (vec!["--resume", "busy-run", "--episodes", "3"], "busy-run: in use by coevo process"),
        (
            vec!["--resume", "kernels-run", "--episodes", "3"],
            "kernels-run: the run was trained on another-family kernels and this machine runs",
        ),
        (vec!["--eval", "busy-run"], "busy-run: in use by coevo process"),
        // A run shipped with coevo (assets/) is read, never written: copies are evaluated and resumed.
        (vec!["--eval", "assets/shipped-run"], "assets/shipped-run: a run shipped with coevo (assets/shipped-run)"),
        (vec!["--eval", "assets/shipped-run", "--eval-out", "x.csv"], "mkdir -p runs && cp -r assets/shipped-run runs/"),
        (vec!["--resume", "assets/shipped-run", "--episodes", "3"], "kept as committed, so nothing writes into it"),
        (vec!["--crossplay", "assets/shipped-run"], "assets/shipped-run: a run shipped with coevo"),
        (vec!["--plot", "assets/shipped-run"], "assets/shipped-run: a run shipped with coevo"),
        // A user-chosen output never takes a run's own name or another evaluation's.
        (vec!["--eval", "run", "--eval-out", "metrics.csv"], "--eval-out metrics.csv: is one of the run's own files"),
        (vec!["--eval", "run", "--eval-out", "scene.csv"], "--eval-out scene.csv: is one of the run's own files"),
        (
            vec!["--eval", "run", "--eval-out", "x-confusion.csv"],
            "ends in -confusion, the name of another evaluation's confusion file",
        ),
        (vec!["--eval", "run", "--eval-out", "../x.csv"], "--eval-out ../x.csv: must be a single name"),
        // A checkpoint proves its integrity: whatever reads it checks each file against its manifest and
        // its metadata (robustness III).
        (vec!["--eval", "swapped-run", "--steps", "3"], "predator-actor.safetensors: holds a network of prey, not of predator"),
        (
            vec!["--eval", "tweaked-run", "--steps", "3"],
            "tweaked-run/checkpoint/prey-actor.safetensors: changed since the checkpoint was written",
        ),
        (vec!["--resume", "nan-segment-run", "--episodes", "3"], "tensor next_obs holds a non-finite value"),
        (
            vec!["--resume", "swapped-segments-run", "--episodes", "3"],
            "predator-replay-0-30.safetensors: changed since the checkpoint was written",
        ),
        (
            vec!["--resume", "reseeded-run", "--episodes", "3"],
            "reseeded-run/checkpoint/state.ron: changed since the checkpoint was written",
        ),
        (
            vec!["--resume", "edited-row-run", "--episodes", "3"],
            "edited-row-run/metrics.csv: its rows up to the checkpoint differ from what was trained",
        ),
        (vec!["--eval", "unsealed-run", "--steps", "3"], "unsealed-run/checkpoint/manifest.ron: missing"),
        (vec!["--eval", "rescened-run", "--steps", "3"], "than the run's (scene 0123456789abcdef)"),
        (
            vec!["--crossplay", "foreign-snapshot-run", "--episodes", "1", "--steps", "3"],
            "snapshots/prey-ep00001.safetensors: trained on another scene",
        ),
        (
            vec!["--eval", "foreign-snapshot-run", "--snapshot", "prey=1", "--steps", "3"],
            "trained on another scene",
        ),
        // Plots and summaries draw only from whole data.
        (vec!["--plot", "repeated-row-run"], "repeated-row-run/metrics.csv:4: episode 1 where episode 2 belongs"),
        (vec!["--plot", "lost-row-run"], "holds 1 episodes but the checkpoint 2: rows were lost"),
        (vec!["--plot", "cut-row-run"], "cut-row-run/metrics.csv:3: the last row is cut short"),
        (vec!["--plot", "nan-row-run"], "\"NaN\" is not a finite number"),
        (vec!["--plot", "header-only-run"], "holds no episode (a header only)"),
        (vec!["--plot", "after-checkpoint-run"], "holds 3 episodes but the checkpoint only 2"),
        // No write through a link.
        (vec!["--plot", "linked-figures-run"], "linked-figures-run/figures: is a symbolic link"),
        (vec!["--resume", "linked-snapshots-run", "--episodes", "3"], "linked-snapshots-run/snapshots: is a symbolic link"),
        // Flags given twice, names that fail late.
        (
            vec!["--eval", "run", "--control", "blind:prey:prey", "--control", "shuffled:prey:prey"],
            "name the same block twice",
        ),
        (vec!["--eval", "run", "--seed", "1", "--seed", "2"], "'--seed <S>' cannot be used multiple times"),
        (vec!["--experiment", "experiments/zero-crossplay.ron"], "crossplay.episodes: must be ≥ 1 (got 0)"),
        (vec!["--experiment", "experiments/nul-variant.ron"], "must not hold a control character"),
        (vec!["--train", "--scene", "long-species.ron"], "at most 64 characters"),
        // Experiment files are checked whole before anything runs.
        (
            vec!["--experiment", "experiments/dotdot.ron"],
            "experiments/dotdot.ron: variants[..].name: as a folder name (\"..\") it must not start with a dot",
        ),
        (vec!["--experiment", "experiments/dot.ron"], "variants[.].name"),
        (vec!["--experiment", "experiments/....ron"], "experiments/....ron: the file name must not start with a dot"),
        (vec!["--experiment", "experiments/no-presets.ron"], "presets: an experiment needs at least one preset"),
        (
            vec!["--experiment", "experiments/no-presets.ron", "--emit-slurm"],
            "presets: an experiment needs at least one preset",
        ),
        (vec!["--experiment", "experiments/twin-presets.ron"], "presets: \"paper\" appears twice"),
        (vec!["--experiment", "experiments/twin-seeds.ron"], "seeds: seed 1 appears twice"),
        (vec!["--experiment", "experiments/no-episodes.ron"], "no-episodes.ron: episodes: must be ≥ 1"),
        (vec!["--experiment", "experiments/nan-claim.ron"], "claims: \"t\": paper must be a finite number (got NaN)"),
        (vec!["--experiment", "experiments/inf-claim.ron"], "paper must be a finite number (got inf)"),
        (vec!["--experiment", "experiments/ours-sized-claim.ron"], "claims: \"t\": ours is a direction of the project's"),
        (
            vec!["--experiment", "experiments/radius.ron"],
            "evaluations[x].confusion_radius: must be a finite number of metres > 0",
        ),
        (
            vec!["--experiment", "experiments/collide.ron"],
            "evaluations[x-confusion].name: as the file eval-x-confusion.csv: ends in -confusion",
        ),
        (vec!["--experiment", "experiments/comma.ron"], "use letters, digits, _ and - only"),
        (
            vec!["--experiment", "experiments/fine.ron", "--task", "99999"],
            "--task 99999: experiments/fine.ron has runs 0 to 1",
        ),
        (
            vec!["--experiment", "experiments/fine.ron", "--task", "0", "--emit-slurm"],
            "--task: not used by --emit-slurm",
        ),
        (vec!["--bench", "--bench-against", "no-such-binary"], "--bench-against no-such-binary: No such file"),
        (vec!["--bench", "--bench-against", "scenes"], "--bench-against scenes: not a file"),
        (
            vec!["--bench", "--bench-against", "no-such-binary", "--bench-seconds", "1"],
            "--bench-seconds: not used by --bench-against",
        ),
        (
            vec!["--experiment", "experiments/report-dir.ron"],
            "results/report-dir/REPORT.md: exists and is not a regular file",
        ),
        (
            vec!["--plot", "results/fine"],
            "--plot results/fine: no finished run of experiments/fine.ron there, and no figure-data.ron.gz; nothing written",
        ),
    ]
}

#[test]
fn every_bad_input_is_one_line_a_failure_and_changes_nothing() {
    let dir = workspace();
    let root = dir.path();
    for (name, text) in SCENES {
        std::fs::write(root.join(format!("{name}.ron")), text.replace("LONG", &"s".repeat(10_000))).unwrap();
    }
    std::fs::write(root.join("binary.ron"), [b'(', 0xff, 0xfe, b')']).unwrap();
    let before = snapshot(root);
    for (args, expected) in cases() {
        let out = Command::new(env!("CARGO_BIN_EXE_coevo")).args(&args).current_dir(root).output().unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        let shown = args.join(" ");
        assert!(!out.status.success(), "coevo {shown}: accepted");
        assert!(!stderr.contains("panicked"), "coevo {shown}: panicked: {stderr}");
        assert_eq!(stderr.lines().count(), 1, "coevo {shown}: not one line: {stderr}");
        assert!(stderr.starts_with("coevo: error: "), "coevo {shown}: {stderr}");
        assert!(stderr.contains(expected), "coevo {shown}: {stderr:?} does not say {expected:?}");
        assert_eq!(snapshot(root), before, "coevo {shown}: the working folder changed");
    }
}

#[test]
fn what_may_be_written_is_written_and_nothing_else() {
    let dir = workspace();
    let root = dir.path();
    let coevo =
        |args: &[&str]| Command::new(env!("CARGO_BIN_EXE_coevo")).args(args).current_dir(root).output().unwrap();
    // A scene that starts with a byte-order mark is read as the same scene.
    std::fs::write(root.join("bom.ron"), "\u{feff}(seed: 4)").unwrap();
    let out = coevo(&["--record", "bom.csv", "--scene", "bom.ron", "--steps", "3"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    // A file replaced with --overwrite keeps its permissions (it was widened to 0644).
    use std::os::unix::fs::PermissionsExt;
    std::fs::set_permissions(root.join("bom.csv"), std::fs::Permissions::from_mode(0o600)).unwrap();
    let out = coevo(&["--record", "bom.csv", "--scene", "bom.ron", "--steps", "4", "--overwrite"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert_eq!(std::fs::metadata(root.join("bom.csv")).unwrap().permissions().mode() & 0o777, 0o600);
    // --overwrite replaces a run's own files and its outputs (evaluations, cross-play, figures: they
    // described the run replaced), and keeps a user's file inside the run folder.
    std::fs::write(root.join("run/my-notes.txt"), "keep").unwrap();
    for old in ["eval.csv", "eval-50-prey.csv", "eval-50-prey-confusion.csv", "crossplay.csv", "figures/x.svg"] {
        std::fs::create_dir_all(root.join("run/figures")).unwrap();
        std::fs::write(root.join("run").join(old), "old").unwrap();
    }
    let first = std::fs::read(root.join("run/metrics.csv")).unwrap();
    let out = coevo(&["--train", "--out", "run", "--overwrite", "--episodes", "1", "--quiet", "--seed", "9"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert_eq!(std::fs::read_to_string(root.join("run/my-notes.txt")).unwrap(), "keep");
    assert_ne!(std::fs::read(root.join("run/metrics.csv")).unwrap(), first, "the run was replaced");
    for old in ["eval.csv", "eval-50-prey.csv", "eval-50-prey-confusion.csv", "crossplay.csv", "figures"] {
        assert!(!root.join("run").join(old).exists(), "{old} of the replaced run is still there");
    }
    // A CSV coevo cannot tell from an evaluation saved under the user's name stops --overwrite.
    std::fs::write(root.join("run/mine.csv"), "x").unwrap();
    let out = coevo(&["--train", "--out", "run", "--overwrite", "--episodes", "1", "--quiet"]);
    assert!(String::from_utf8_lossy(&out.stderr).contains("run/mine.csv: may be an evaluation"), "{out:?}");
    std::fs::remove_file(root.join("run/mine.csv")).unwrap();
    // A file the user put into a checkpoint folder stops --overwrite.
    std::fs::write(root.join("run/checkpoint/mine.txt"), "x").unwrap();
    let out = coevo(&["--train", "--out", "run", "--overwrite", "--episodes", "1", "--quiet"]);
    assert!(String::from_utf8_lossy(&out.stderr).contains("run/checkpoint/mine.txt: not a file coevo wrote"));
    assert!(root.join("run/checkpoint/mine.txt").exists());
    // A copy of a shipped run is an ordinary run, also a copy of the whole assets/ folder elsewhere (no
    // source tree around it): evaluated in place, its provenance then names this binary.
    for copy in ["runs/shipped-run", "backup/assets/shipped-run"] {
        copy_dir(&root.join("assets/shipped-run"), &root.join(copy));
        let out = coevo(&["--eval", copy, "--steps", "3"]);
        assert!(out.status.success(), "{copy}: {}", String::from_utf8_lossy(&out.stderr));
        assert!(root.join(copy).join("eval.csv").exists(), "{copy}");
    }
    // A damaged provenance.ron does not stop --overwrite from replacing the run.
    copy_dir(&root.join("nan-run"), &root.join("damaged-run"));
    std::fs::write(root.join("damaged-run/provenance.ron"), "(damaged").unwrap();
    let out = coevo(&["--train", "--out", "damaged-run", "--overwrite", "--episodes", "1", "--quiet"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(std::fs::read_to_string(root.join("damaged-run/provenance.ron")).unwrap().contains("binary"));
    // --partial draws a run stopped after its last checkpoint, saying so in the figure.
    let out = coevo(&["--plot", "after-checkpoint-run", "--partial"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let svg = std::fs::read_to_string(root.join("after-checkpoint-run/figures/training.svg")).unwrap();
    assert!(svg.contains("partial: episodes 2..3 after the last checkpoint"), "the figure says it is partial");
    // A run trained outside coevo (python/examples/ippo.py: scene, metrics and actors, no training state
    // or provenance) is drawn whole, without --partial.
    let outside = root.join("outside-run");
    std::fs::create_dir_all(outside.join("checkpoint")).unwrap();
    for file in
        ["scene.ron", "metrics.csv", "checkpoint/prey-actor.safetensors", "checkpoint/predator-actor.safetensors"]
    {
        std::fs::copy(root.join("run2").join(file), outside.join(file)).unwrap();
    }
    let out = coevo(&["--plot", "outside-run"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let svg = std::fs::read_to_string(outside.join("figures/training.svg")).unwrap();
    assert!(!svg.contains("partial"), "a whole run trained outside coevo is not marked partial");
    // What a killed process left is cleared by the next use: a checkpoint.old/ of a swap cut short
    // beside a whole checkpoint, and a lock file left empty (a disk that filled as it was taken).
    copy_dir(&root.join("run/checkpoint"), &root.join("run2/checkpoint.old"));
    std::fs::write(root.join("run2/coevo.lock"), "").unwrap();
    let out = coevo(&["--eval", "run2", "--steps", "3"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(!root.join("run2/checkpoint.old").exists() && !root.join("run2/coevo.lock").exists());
    // A swap cut between its two renames (checkpoint/ gone, checkpoint.old/ whole): an evaluation puts the
    // checkpoint back before reading its actors, and checks them against its manifest.
    copy_dir(&root.join("run2"), &root.join("cut-swap-run"));
    std::fs::rename(root.join("cut-swap-run/checkpoint"), root.join("cut-swap-run/checkpoint.old")).unwrap();
    let out = coevo(&["--eval", "cut-swap-run", "--steps", "3"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(
        root.join("cut-swap-run/checkpoint/manifest.ron").exists()
            && !root.join("cut-swap-run/checkpoint.old").exists()
    );
    std::fs::rename(root.join("cut-swap-run/checkpoint"), root.join("cut-swap-run/checkpoint.old")).unwrap();
    let out = coevo(&["--crossplay", "cut-swap-run", "--episodes", "1", "--steps", "3"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(root.join("cut-swap-run/checkpoint/manifest.ron").exists());
    // A new or empty folder is used as it is.
    std::fs::create_dir(root.join("empty")).unwrap();
    let out = coevo(&["--train", "--out", "empty", "--episodes", "1", "--quiet"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(root.join("empty/checkpoint/state.ron").exists());
}

/// coevo with `args` (split by the shell) in `root`, under `ulimit LIMIT` (e.g. "-f 256").
fn under_limit(root: &Path, limit: &str, args: &str) -> std::process::Output {
    Command::new("sh")
        .args(["-c", &format!("ulimit {limit}; exec \"$COEVO\" {args}")])
        .env("COEVO", env!("CARGO_BIN_EXE_coevo"))
        .current_dir(root)
        .output()
        .unwrap()
}

/// Every file under `dir` whose name says it was left half-done: a temporary, a lock, a checkpoint being
/// written or swapped.
fn leftovers(dir: &Path) -> Vec<PathBuf> {
    snapshot(dir)
        .into_keys()
        .filter(|p| {
            let name = p.file_name().unwrap().to_string_lossy();
            name.ends_with(".tmp") || name == "coevo.lock" || name == "checkpoint.tmp" || name == "checkpoint.old"
        })
        .collect()
}

#[test]
fn arguments_environment_and_resource_limits_end_in_one_line_and_leave_nothing() {
    use std::ffi::OsStr;
    use std::os::unix::ffi::OsStrExt;
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path();
    std::fs::create_dir(root.join("scenes")).unwrap();
    std::fs::copy("scenes/standard.ron", root.join("scenes/standard.ron")).unwrap();
    let one_line = |args: &[&OsStr], env: &[(&str, &OsStr)], expected: &str| {
        let before = snapshot(root);
        let out = Command::new(env!("CARGO_BIN_EXE_coevo"))
            .args(args)
            .envs(env.iter().copied())
            .current_dir(root)
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        let shown = format!("{args:?} {env:?}");
        assert!(!out.status.success() && !stderr.contains("panicked"), "{shown}: {stderr}");
        assert_eq!(stderr.lines().count(), 1, "{shown}: not one line: {stderr}");
        assert!(
            stderr.starts_with("coevo: error: ") && stderr.contains(expected),
            "{shown}: {stderr:?} lacks {expected:?}"
        );
        assert_eq!(snapshot(root), before, "{shown}: the working folder changed");
    };
    let s = |text: &'static str| OsStr::new(text);
    let bad = OsStr::from_bytes(b"run-\xff");
    // A path that is not UTF-8, in every mode that takes one.
    one_line(&[s("--train"), s("--out"), bad], &[], "argument 3 (\"run-\u{fffd}\") is not valid UTF-8");
    one_line(&[s("--experiment"), bad], &[], "is not valid UTF-8");
    one_line(&[s("--describe-scene"), bad], &[], "is not valid UTF-8");
    // Environment variables are read as their flags are.
    for threads in ["0", "abc", "-1"] {
        one_line(
            &[s("--describe-scene"), s("scenes/standard.ron")],
            &[("COEVO_THREADS", s(threads))],
            "COEVO_THREADS: ",
        );
    }
    one_line(&[s("--describe-scene"), s("scenes/standard.ron")], &[("COEVO_KERNELS", bad)], "COEVO_KERNELS: ");
    // A name holding a newline is shown escaped: still one line.
    one_line(&[s("--describe-scene"), s("a\nb.ron")], &[], "a\\nb.ron");

    // A FIFO where an input file is expected: refused, never waited on (opening a FIFO blocks until a
    // writer comes; `timeout` turns a hang into a failure here).
    std::fs::copy("scenes/paper.ron", root.join("scenes/paper.ron")).unwrap();
    std::fs::create_dir_all(root.join("experiments")).unwrap();
    std::fs::write(
        root.join("experiments/fine.ron"),
        r#"(base: "scenes/paper.ron", seeds: [1], variants: [(name: "a")])"#,
    )
    .unwrap();
    std::fs::create_dir_all(root.join("results/fine")).unwrap();
    // (The snapshot is taken without the FIFO, which reading would block on.)
    let before = snapshot(root);
    let fifo = root.join("results/fine/figure-data.ron.gz");
    assert!(Command::new("mkfifo").arg(&fifo).status().unwrap().success());
    let out = Command::new("timeout")
        .args(["20", env!("CARGO_BIN_EXE_coevo"), "--plot", "results/fine"])
        .current_dir(root)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && stderr.lines().count() == 1, "--plot with a FIFO: {stderr}");
    assert!(stderr.contains("figure-data.ron.gz: is not a regular file"), "{stderr}");
    std::fs::remove_file(&fifo).unwrap();
    assert_eq!(snapshot(root), before);

    // A file size limit (ulimit -f, in KiB blocks here): the write that crosses it fails, and coevo says
    // which limit, exits non-zero and leaves no temporary file, lock or half-written checkpoint. (Without
    // care SIGXFSZ kills the process where it stands.)
    let limited = |command: &str, expected_file: &str| {
        let out = under_limit(root, "-f 256", command);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success() && !stderr.contains("panicked"), "{command}: {stderr}");
        assert_eq!(stderr.lines().count(), 1, "{command}: not one line: {stderr}");
        assert!(stderr.contains("a file size limit was reached"), "{command}: {stderr}");
        assert!(leftovers(root).is_empty(), "{command}: left {:?}", leftovers(root));
        assert!(!root.join(expected_file).exists(), "{command}: {expected_file} half-written");
    };
    limited("--train --out limited --episodes 1 --quiet", "limited/checkpoint");
    limited("--record big.csv --steps 3000", "big.csv");

    // An open-file limit (ulimit -n) too low to save a checkpoint: one line naming the limit, no lock or
    // half-written checkpoint left. (A process limit, ulimit -u, binds no root process: not tested here.)
    // A stack limit far below any program's (ulimit -s 32, in KiB): the command line is read and run on a
    // thread whose stack coevo sizes, so the main thread's limit binds nothing of coevo's. (The kernel puts
    // the arguments and the environment on that stack, and the C and Rust start-up use most of the rest:
    // under 16 KiB whether a process starts at all depends on the size of its environment, a harness's
    // included, so the limit here is 32 KiB and the environment only PATH.)
    let out = Command::new("sh")
        .args(["-c", "ulimit -s 32; exec \"$COEVO\" --describe-scene scenes/paper.ron"])
        .env_clear()
        .env("PATH", "/usr/bin:/bin")
        .env("COEVO", env!("CARGO_BIN_EXE_coevo"))
        .current_dir(root)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success() && stdout.contains("resolved scene:"),
        "ulimit -s: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let out = under_limit(root, "-n 5", "--train --out few-files --episodes 1 --quiet");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && stderr.lines().count() == 1, "ulimit -n: {stderr}");
    assert!(stderr.contains("the limit on open files was reached, such as `ulimit -n`"), "{stderr}");
    assert!(leftovers(root).is_empty(), "ulimit -n: left {:?}", leftovers(root));
    assert!(!root.join("few-files/checkpoint").exists(), "ulimit -n: a checkpoint half-written");

    // A memory limit (ulimit -v) above what the scene's estimate asks but below what 10⁵ prey take: the
    // refused allocation ends the run in one line, nothing left behind (Rust's default would abort).
    let out = under_limit(root, "-v 650000", "--record crowd.csv --prey 100000 --steps 1");
    let stderr = String::from_utf8_lossy(&out.stderr);
    // (Before it, the notice of what 10⁵ prey cost, as any such call prints.)
    let errors: Vec<&str> = stderr.lines().filter(|l| l.starts_with("coevo: error: ")).collect();
    assert!(!out.status.success() && errors.len() == 1, "ulimit -v: {stderr}");
    assert!(
        errors[0].starts_with("coevo: error: out of memory: ") || errors[0].contains("of memory coevo may use here"),
        "ulimit -v: {stderr}"
    );
    assert!(leftovers(root).is_empty() && !root.join("crowd.csv").exists(), "ulimit -v: left {:?}", leftovers(root));
}

#[test]
fn a_run_folder_removed_while_training_stops_the_training_and_is_not_recreated() {
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path();
    std::fs::write(
        root.join("small.ron"),
        "(preset: \"paper\", episode_steps: 20, episodes: 100000, learning: (hidden: 8, batch_size: 16, warmup_transitions: 16, updates_per_episode: 1, checkpoint_every: 1))",
    )
    .unwrap();
    let child = Command::new(env!("CARGO_BIN_EXE_coevo"))
        .args(["--train", "--scene", "small.ron", "--out", "run", "--quiet"])
        .current_dir(root)
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let start = std::time::Instant::now();
    while !root.join("run/checkpoint/state.ron").exists() {
        assert!(start.elapsed().as_secs() < 120, "no checkpoint in 2 minutes");
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    std::fs::remove_dir_all(root.join("run")).unwrap_or_else(|_| {
        // Removed mid-swap of a checkpoint: try again.
        std::thread::sleep(std::time::Duration::from_millis(50));
        std::fs::remove_dir_all(root.join("run")).unwrap();
    });
    let out = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && stderr.lines().count() == 1, "{stderr}");
    assert!(stderr.contains("run: removed or replaced while this process was writing it"), "{stderr}");
    assert!(!root.join("run").exists(), "the folder was recreated");
}

#[test]
fn a_resume_into_a_checkpoint_that_cannot_be_written_is_refused_before_training() {
    // The checkpoint folder made immutable (chattr +i binds root too, which ignores permission bits):
    // refused up front in one line, with no episode trained and no checkpoint.old/ left behind.
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path();
    std::fs::write(
        root.join("small.ron"),
        "(preset: \"paper\", episode_steps: 10, learning: (hidden: 8, batch_size: 16, warmup_transitions: 16, updates_per_episode: 1))",
    )
    .unwrap();
    let coevo =
        |args: &[&str]| Command::new(env!("CARGO_BIN_EXE_coevo")).args(args).current_dir(root).output().unwrap();
    assert!(coevo(&["--train", "--scene", "small.ron", "--episodes", "1", "--out", "run", "--quiet"]).status.success());
    let checkpoint = root.join("run/checkpoint");
    if !Command::new("chattr").arg("+i").arg(&checkpoint).status().is_ok_and(|s| s.success()) {
        eprintln!("skipped: chattr +i is not available here (it needs root and a file system that keeps the flag)");
        return;
    }
    let before = snapshot(&root.join("run"));
    let out = coevo(&["--resume", "run", "--episodes", "2", "--quiet"]);
    assert!(Command::new("chattr").arg("-i").arg(&checkpoint).status().unwrap().success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && stderr.lines().count() == 1, "{stderr}");
    assert!(stderr.contains("run/checkpoint: cannot be written"), "{stderr}");
    assert_eq!(snapshot(&root.join("run")), before, "the run changed");
}
