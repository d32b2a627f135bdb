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
    let mut scene = coevo::Scene::load(Path::new("scenes/paper.ron")).unwrap();
    scene.episode_steps = 10;
    scene.learning.hidden = 8;
    scene.learning.batch_size = 16;
    scene.learning.warmup_transitions = 16;
    scene.learning.updates_per_episode = 2;
    for run in ["run", "nan-run"] {
        let opts = coevo::train::TrainOptions {
            run: root.join(run),
            resume: false,
            overwrite: false,
            episodes: Some(1),
            progress: false,
        };
        coevo::train::train(scene.clone(), &opts).unwrap();
    }
    // A NaN in the prey actor's first weight: the safetensors header is followed by the tensors' bytes.
    let actor = root.join("nan-run/checkpoint/prey-actor.safetensors");
    let mut bytes = std::fs::read(&actor).unwrap();
    let header = u64::from_le_bytes(bytes[..8].try_into().unwrap()) as usize;
    let text = String::from_utf8(bytes[8..8 + header].to_vec()).unwrap();
    let at = text.find("\"0.weight\"").unwrap();
    let offsets = &text[at..];
    let start: usize = offsets[offsets.find("data_offsets\":[").unwrap() + 15..].split(',').next().unwrap().parse().unwrap();
    bytes[8 + header + start..8 + header + start + 4].copy_from_slice(&f32::NAN.to_le_bytes());
    std::fs::write(&actor, bytes).unwrap();

    std::fs::write(root.join("notes.csv"), "a user's file\n").unwrap();
    std::fs::write(root.join("notes.gif"), "a user's picture\n").unwrap();
    std::fs::create_dir(root.join("mine")).unwrap();
    std::fs::write(root.join("mine/thesis.txt"), "not a run\n").unwrap();
    #[cfg(unix)]
    std::os::unix::fs::symlink(root.join("notes.csv"), root.join("link.csv")).unwrap();
    dir
}

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
    ("no-episodes", "(episodes: 0)"),
    ("fraction", r#"(species: [(name: "prey", count: 2.5)])"#),
    ("truncated", "(\n  seed: 3,\n  species: [(name: \"prey\", count: 2)\n"),
    ("frozen-missing", r#"(species: [(name: "prey", policy: Frozen("no-such-run"))])"#),
    ("unknown-field", "(world: (gravity: 9.81))"),
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
        // Outputs that would destroy or replace something.
        (vec!["--train", "--out", "run"], "run: already holds a run; continue it with --resume run"),
        (vec!["--train", "--out", "mine", "--overwrite"], "mine: is not empty and holds no coevo run"),
        (vec!["--train", "--out", "notes.csv"], "notes.csv: exists and is not a folder"),
        (vec!["--record", "notes.csv"], "notes.csv: already exists; choose a new name or pass --overwrite"),
        (vec!["--record", "link.csv", "--overwrite"], "link.csv: exists and is not a regular file"),
        (vec!["--record", "mine", "--overwrite"], "mine: exists and is not a regular file"),
        (vec!["--train", "--scene", "frozen-missing.ron", "--out", "fresh"], "no-such-run/checkpoint/prey-actor.safetensors"),
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
        (vec!["--train", "--scene", "/dev/zero"], "/dev/zero: is larger than 1 MiB"),
        (vec!["--record", "out.csv", "--threads", "0"], "--threads: must be ≥ 1"),
        (vec!["--animate", "clip.png"], "--animate clip.png: the file must end in .gif"),
        (vec!["--animate", "notes.gif"], "notes.gif: already exists; choose a new name or pass --overwrite"),
        (vec!["--animate", "clip.gif", "--size", "10"], "--size 10: must be within 64..=2048 pixels"),
        (vec!["--animate", "clip.gif", "--steps-per-frame", "0"], "--steps-per-frame: must be ≥ 1"),
        (vec!["--animate", "clip.gif", "--run", "nan-run"], "prey-actor.safetensors: tensor 0.weight holds a non-finite value"),
        (vec!["--animate", "clip.gif", "--control", "blind"], "--control: not used by --animate"),
        (vec!["--eval", "run", "--confusion-radius", "0"], "confusion_radius: must be a finite number > 0"),
        // Silent accepts.
        (vec!["--record", "out.csv", "--scene", "plugin.ron"], "species[prey].policy: no plugin decides Plugin(\"nobody\")"),
        (vec!["--train", "--scene", "twice.ron"], "species[prey]: appears twice in this scene"),
        (vec!["--describe-scene", "basilisk.ron"], "basilisk.ron:1: species[basilisk]: no preset or species plugin of this program defines \"basilisk\""),
        (vec!["--describe-scene", "pair.ron"], "pair.ron: contact_rewards[0]: prey does not catch predator"),
        (vec!["--describe-scene", "nothere.ron"], "nothere.ron: cannot read scene"),
        (vec!["--describe-scene", "scenes/paper.ron", "--steps", "3"], "--steps: not used by --describe-scene"),
        (vec!["--train", "--scene", "cannibal.ron"], "species[prey].catches: a species cannot catch itself"),
        (vec!["--train", "--eval", "run"], "'--train' cannot be used with '--eval <DIR>'"),
        (vec!["--record", "out.csv", "--train"], "cannot be used with"),
        (vec!["--train", "--steps", "5"], "--steps: not used by --train"),
        (vec!["--train", "--prey", "50"], "--prey: not used by --train"),
        (vec!["--resume", "run", "--scene", "scenes/paper.ron"], "--scene: not used by --resume"),
        (vec!["--eval", "run", "--out", "x"], "--out: not used by --eval"),
        (vec!["--bench", "--seed", "3"], "--seed: not used by --bench"),
        (vec!["--train", "--episodes", "0"], "--episodes: must be ≥ 1 (got 0)"),
        (vec!["--train", "--scene", "no-episodes.ron"], "no-episodes.ron:1: episodes: must be ≥ 1"),
        (vec!["--eval", "run", "--steps", "0"], "--steps: must be ≥ 1"),
        (vec!["--resume", "mine"], "mine: holds no coevo run to resume"),
        (vec!["--train", "--bogus"], "unexpected argument '--bogus'"),
        // Messages in a user's words.
        (vec!["--train", "--scene", "fraction.ron"], "fraction.ron:1: count: must be a whole number (got 2.5)"),
        (vec!["--train", "--scene", "truncated.ron"], "the file ends too early"),
        (vec!["--train", "--scene", "unknown-field.ron"], "gravity"),
        (vec!["--train", "--scene", "binary.ron"], "binary.ron: is not UTF-8 text"),
    ]
}

#[test]
fn every_bad_input_is_one_line_a_failure_and_changes_nothing() {
    let dir = workspace();
    let root = dir.path();
    for (name, text) in SCENES {
        std::fs::write(root.join(format!("{name}.ron")), text).unwrap();
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
    let coevo = |args: &[&str]| Command::new(env!("CARGO_BIN_EXE_coevo")).args(args).current_dir(root).output().unwrap();
    // A scene that starts with a byte-order mark is read as the same scene.
    std::fs::write(root.join("bom.ron"), "\u{feff}(seed: 4)").unwrap();
    let out = coevo(&["--record", "bom.csv", "--scene", "bom.ron", "--steps", "3"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    // --overwrite replaces a run's own files and keeps a user's file inside the run folder.
    std::fs::write(root.join("run/my-notes.txt"), "keep").unwrap();
    let first = std::fs::read(root.join("run/metrics.csv")).unwrap();
    let out = coevo(&["--train", "--out", "run", "--overwrite", "--episodes", "1", "--quiet", "--seed", "9"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert_eq!(std::fs::read_to_string(root.join("run/my-notes.txt")).unwrap(), "keep");
    assert_ne!(std::fs::read(root.join("run/metrics.csv")).unwrap(), first, "the run was replaced");
    // A file the user put into a checkpoint folder stops --overwrite.
    std::fs::write(root.join("run/checkpoint/mine.txt"), "x").unwrap();
    let out = coevo(&["--train", "--out", "run", "--overwrite", "--episodes", "1", "--quiet"]);
    assert!(String::from_utf8_lossy(&out.stderr).contains("run/checkpoint/mine.txt: not a file coevo wrote"));
    assert!(root.join("run/checkpoint/mine.txt").exists());
    // A new or empty folder is used as it is.
    std::fs::create_dir(root.join("empty")).unwrap();
    let out = coevo(&["--train", "--out", "empty", "--episodes", "1", "--quiet"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(root.join("empty/checkpoint/state.ron").exists());
}
