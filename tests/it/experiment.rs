//! The experiment layer end to end on a tiny experiment (2 variants × 2 seeds × 3 short episodes): files
//! and their errors, runs at one and two at a time, a kill and a rerun, summaries, figures, Slurm.

use coevo::experiment::{Experiment, Quantity};
use std::path::Path;
use std::process::Command;

const TINY: &str = r#"(
    description: "a tiny sweep",
    base: "scenes/paper.ron",
    seeds: [1, 2],
    episodes: 3,
    variants: [
        (name: "1:1", patch: (episode_steps: 30, learning: (hidden: 16, batch_size: 32, warmup_transitions: 32, updates_per_episode: 3, checkpoint_every: 1))),
        (name: "5:3", patch: (episode_steps: 30, species: [(name: "prey", max_speed: 0.1)], learning: (hidden: 16, batch_size: 32, warmup_transitions: 32, updates_per_episode: 3, checkpoint_every: 1))),
    ],
    evaluations: [
        (name: "50 prey", counts: [("prey", 50)], episodes: 2, steps: 20),
        (name: "50 prey, blind", counts: [("prey", 50)], episodes: 2, steps: 20, control: Blind),
    ],
    claims: [
        (text: "DoS falls", variant: "5:3", quantity: DosChange, paper: -0.03),
        (text: "seeing minus blind", variant: "5:3", quantity: InteractionDoa("50 prey, blind")),
        (text: "5:3 against 1:1", variant: "5:3", versus: "1:1", quantity: DosChange),
        (text: "catches", variant: "5:3", quantity: CatchesChange),
    ],
)"#;

/// A working folder with the project's scenes and the tiny experiment.
fn workspace() -> tempfile::TempDir {
    workspace_with("tiny", TINY)
}

/// A working folder with the project's scenes and `experiments/<name>.ron` holding `text`.
pub(super) fn workspace_with(name: &str, text: &str) -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    std::fs::create_dir_all(dir.path().join("scenes")).unwrap();
    std::fs::create_dir_all(dir.path().join("experiments")).unwrap();
    std::fs::copy("scenes/paper.ron", dir.path().join("scenes/paper.ron")).unwrap();
    std::fs::write(dir.path().join(format!("experiments/{name}.ron")), text).unwrap();
    dir
}

/// Every file under `dir` with its bytes.
fn files_under(dir: &Path) -> std::collections::BTreeMap<std::path::PathBuf, Vec<u8>> {
    let mut files = std::collections::BTreeMap::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for path in std::fs::read_dir(&d).unwrap().map(|e| e.unwrap().path()) {
            if path.is_dir() {
                stack.push(path);
            } else {
                files.insert(path.strip_prefix(dir).unwrap().to_path_buf(), std::fs::read(&path).unwrap());
            }
        }
    }
    files
}

pub(super) fn coevo(dir: &Path, args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_coevo")).args(args).current_dir(dir).output().unwrap()
}

/// coevo run in `dir` with `args`, which must fail with one line on stderr: that line.
fn refused(dir: &Path, args: &[&str]) -> String {
    let out = coevo(dir, args);
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(!out.status.success() && stderr.lines().count() == 1, "{stderr}");
    stderr
}

#[test]
fn experiment_files_expand_to_runs_and_bad_ones_are_one_line() {
    let dir = workspace();
    // Paths inside experiment files are relative to the working folder (here the repository's).
    let exp = Experiment::load(&dir.path().join("experiments/tiny.ron"), Path::new("results")).unwrap();
    assert_eq!(exp.runs.len(), 4, "1 preset × 2 variants × 2 seeds");
    assert_eq!(exp.runs[2].dir, Path::new("results/tiny/paper/5-3/seed1"));
    assert_eq!(
        (exp.runs[2].scene.species[1].max_speed, exp.runs[2].scene.episodes, exp.runs[3].scene.seed),
        (0.1, 3, 2)
    );
    assert_eq!(exp.spec.claims[0].quantity, Quantity::DosChange);

    // Every shipped experiment file loads.
    for file in Experiment::files(Path::new("experiments")).unwrap() {
        Experiment::load(&file, Path::new("results")).unwrap_or_else(|e| panic!("{e}"));
    }

    for (text, expected) in [
        (TINY.replace("seeds: [1, 2]", "seeds: []"), "bad.ron: seeds: an experiment needs at least one seed"),
        (
            TINY.replace("max_speed: 0.1", "max_speed: -1.0"),
            "bad.ron: variants[5:3]: species[prey].max_speed: must be a finite number > 0",
        ),
        (TINY.replace("description", "descripton"), "bad.ron:2: descripton:"),
        (TINY.replace("variant: \"5:3\"", "variant: \"7:3\""), "bad.ron: claims: no variant named \"7:3\""),
        (TINY.replace("versus: \"1:1\"", "versus: \"2:1\""), "bad.ron: claims: no variant named \"2:1\""),
        (
            TINY.replace("versus: \"1:1\"", "versus: \"5:3\""),
            "bad.ron: claims: \"5:3 against 1:1\" is compared with itself",
        ),
        (
            TINY.replace("(text: \"catches\"", "(text: \"DoS falls\""),
            "bad.ron: claims: \"DoS falls\" is the text of two claims",
        ),
        (
            TINY.replace("quantity: DosChange, paper: -0.03", "quantity: FromStart(\"milling\")"),
            "bad.ron:15: quantity: \"milling\" is no training curve: one of \"dos\", \"doa\", \"catches\", \"authors_dos\", \"authors_doa\"",
        ),
        (
            // The code's metric is read only from runs that measure it.
            TINY.replace("quantity: DosChange, paper: -0.03", "quantity: FromStart(\"authors_doa\")"),
            "bad.ron: claims: \"DoS falls\" reads authors_doa, which variant \"5:3\" does not measure (authors_metrics: true in its patch or the base scene)",
        ),
        (
            TINY.replace("quantity: DosChange, paper: -0.03", "quantity: Extreme(\"catches\")"),
            "Extreme, ExtremeEpisode and AfterExtreme take \"dos\" or \"doa\" (got \"catches\")",
        ),
        (
            TINY.replace("claims: [", "family: Some(\" \"),\n    claims: ["),
            "bad.ron: claims: \"DoS falls\": family must name a family (got an empty name)",
        ),
        (TINY.replace("(\"prey\", 50)", "(\"hawk\", 50)"), "evaluations[50 prey]: no species named \"hawk\""),
        (
            TINY.replace("counts: [(\"prey\", 50)],", "counts: [(\"prey\", 50)], policies: [(\"hawk\", Still)],"),
            "evaluations[50 prey]: no species named \"hawk\"",
        ),
        (TINY.replace("scenes/paper.ron", "scenes/none.ron"), "bad.ron: base: scenes/none.ron: cannot read"),
        (
            TINY.replace("quantity: CatchesChange", "quantity: Crossplay(\"doa_late\")"),
            "bad.ron: claims: Crossplay(\"doa_late\") needs crossplay: (episodes: N) in the file",
        ),
        (
            TINY.replace("quantity: CatchesChange", "quantity: Crossplay(\"doa_later\")"),
            "bad.ron: claims: no cross-play read-out named \"doa_later\"",
        ),
        (
            TINY.replace("quantity: DosChange", "quantity: InteractionDoa(\"50 prey\")"),
            "evaluation \"50 prey\" needs a control (Blind, Shuffled or a block form)",
        ),
        (
            TINY.replace("control: Blind", "control: \"blind:prey:hawk\""),
            "evaluations[50 prey, blind].control: variant 1:1: blind:prey:hawk: no species named \"hawk\"",
        ),
        (TINY.replace("control: Blind", "control: \"blinded\""), "\"blinded\" is not a control"),
        (
            TINY.replace("quantity: DosChange", "quantity: EvalOrder(\"50 prey\", \"swirl\")"),
            "\"swirl\" is no order parameter: one of \"dos\", \"doa\"",
        ),
        (
            // An order parameter of its own quantity (DoS has EvalDos) is refused where another is asked for.
            TINY.replace("quantity: DosChange", "quantity: EvalOrder(\"50 prey\", \"dos\")"),
            "bad.ron: claims: \"dos\" is not taken here (one of polarization, milling, clusters, largest_cluster, nn_correlation, edge_rank)",
        ),
        (
            // A level of the paper's with no rule for its tolerance must state one; an effect takes none.
            TINY.replace("quantity: DosChange, paper: -0.03", "quantity: CatchesLast, paper: 50.0"),
            "bad.ron: claims: \"DoS falls\": a level with the paper's value needs a tolerance",
        ),
        (
            TINY.replace("paper: -0.03", "paper: -0.03, tolerance: Some(0.01)"),
            "bad.ron: claims: \"DoS falls\": tolerance is for a level with the paper's value, a positive number (got 0.01)",
        ),
        (
            TINY.replace("quantity: DosChange, paper: -0.03", "quantity: DosLast, paper: 0.19, tolerance: Some(-0.01)"),
            "tolerance is for a level with the paper's value, a positive number (got -0.01)",
        ),
    ] {
        std::fs::write(dir.path().join("experiments/bad.ron"), text).unwrap();
        let stderr = refused(dir.path(), &["--experiment", "experiments/bad.ron"]);
        assert!(stderr.contains(expected), "{expected}: {stderr}");
        assert!(!dir.path().join("results").exists(), "nothing written for a bad file");
    }
}

/// How many replay-buffer segments (`checkpoint/<species>-replay-<from>-<to>.safetensors`) are among `files`.
fn replay_segments(files: &std::collections::BTreeMap<std::path::PathBuf, Vec<u8>>) -> usize {
    files.keys().filter(|f| f.to_string_lossy().contains("-replay-")).count()
}

/// The tiny experiment's summary without its wall-clock column.
fn summary(dir: &Path) -> Vec<String> {
    summary_of(dir, "tiny")
}

/// `results/<name>/summary.csv` without its wall-clock column.
pub(super) fn summary_of(dir: &Path, name: &str) -> Vec<String> {
    let text = std::fs::read_to_string(dir.join(format!("results/{name}/summary.csv"))).unwrap();
    // Every column but the wall clock, the binary (the same here, but not a result) and shared_from.
    let header: Vec<&str> = text.lines().next().unwrap().split(',').collect();
    let wall = header.iter().position(|h| *h == "wall_seconds").unwrap();
    text.lines()
        .map(|l| {
            let fields: Vec<&str> = l.split(',').collect();
            [&fields[..wall], &fields[wall + 3..]].concat().join(",")
        })
        .collect()
}

#[test]
fn a_tiny_experiment_runs_resumes_and_gives_the_same_summary_at_one_or_two_jobs() {
    let two = workspace();
    let out = coevo(two.path(), &["--experiment", "experiments/tiny.ron", "--jobs", "2"]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    // Before its runs it says how long their training will take here, measured by a probe (no run had
    // an episode yet), and leaves nothing of the probe behind.
    let estimate = stderr.lines().find(|l| l.contains("trainings left")).unwrap_or_else(|| panic!("{stderr}"));
    assert!(
        estimate.starts_with("coevo: experiments/tiny.ron: 4 trainings left, 12 episodes at ")
            && estimate.contains("measured here by 3-episode probes of paper/1:1, 2 side by side")
            && estimate.contains("with 2 at a time"),
        "{estimate}"
    );
    assert!(!two.path().join("results/tiny/.probe-0").exists() && !two.path().join("results/tiny/.probe-1").exists());
    // One experiment writes only under its own results folder (REPRODUCTION.md is written when asked for,
    // by `all`), and says exactly what it wrote.
    let outside: Vec<_> = files_under(two.path())
        .into_keys()
        .filter(|f| !["results/tiny", "scenes", "experiments"].iter().any(|d| f.starts_with(d)))
        .collect();
    assert!(outside.is_empty(), "{outside:?}");
    let figures = std::fs::read_dir(two.path().join("results/tiny/figures")).unwrap().count();
    let said = format!(
        "coevo: wrote results/tiny/summary.csv, results/tiny/summary-mean.csv, results/tiny/figure-data.ron.gz, results/tiny/REPORT.md and {} figures (.svg and .png) in results/tiny/figures/",
        figures / 2
    );
    assert!(stderr.contains(&said), "{said} not in {stderr}");
    // Trained runs keep their networks and state, not their replay buffers (only an extension reads them).
    let kept = files_under(&two.path().join("results/tiny"));
    assert_eq!(kept.keys().filter(|f| f.ends_with("checkpoint/prey-actor.safetensors")).count(), 4);
    assert_eq!(kept.keys().filter(|f| f.ends_with("checkpoint/state.ron")).count(), 4);
    assert_eq!(replay_segments(&kept), 0, "{:?}", kept.keys().collect::<Vec<_>>());
    let rows = summary(two.path());
    assert_eq!(rows.len(), 5, "header and four runs: {rows:?}");
    assert!(rows[0].starts_with("preset,variant,seed,episodes,dos_first100,dos_last100,doa_first100,doa_last100,polarization_first100,polarization_last100,milling_first100"), "{}", rows[0]);
    assert!(rows[0].contains(",eval_50-prey_dos_settled,eval_50-prey_doa_settled,"), "{}", rows[0]);
    let header: Vec<&str> = rows[0].split(',').collect();
    for row in &rows[1..] {
        for (name, cell) in header.iter().zip(row.split(',')).skip(3) {
            // Every value is a finite number; only an order parameter may be blank (an evaluation without
            // a catch has no edge rank), never NaN.
            let optional = (name.starts_with("eval_") && !name.ends_with("_settled") && !name.ends_with("_interaction"))
                    || name.starts_with("edge_rank_")
                    || name.ends_with("_reach90")
                    // The curves' shape needs 10 episodes, its extreme 200: blank in these 3-episode runs.
                    || coevo::claims::summary::curve_columns().iter().any(|(c, _)| c == name);
            assert!(
                cell.parse::<f64>().is_ok_and(f64::is_finite) || (optional && cell.is_empty()),
                "{name} = {cell:?} in {row}"
            );
        }
    }
    // The interaction-driven part of the alignment is seeing minus blind, run by run.
    let column =
        |name: &str| header.iter().position(|h| *h == name).unwrap_or_else(|| panic!("no {name} in {header:?}"));
    for row in &rows[1..] {
        let cells: Vec<f64> = row.split(',').map(|c| c.parse().unwrap_or(f64::NAN)).collect();
        let (seeing, blind, interaction) = (
            cells[column("eval_50-prey_doa_settled")],
            cells[column("eval_50-prey-blind_doa_settled")],
            cells[column("eval_50-prey-blind_doa_interaction")],
        );
        assert!((seeing - blind - interaction).abs() < 1e-12, "{row}");
    }
    let means = std::fs::read_to_string(two.path().join("results/tiny/summary-mean.csv")).unwrap();
    assert!(means.lines().any(|l| l.starts_with("paper,5:3,dos_last100,2,")), "{means}");
    let md = std::fs::read_to_string(two.path().join("results/tiny/REPORT.md")).unwrap();
    assert!(
        md.contains("| [tiny](#tiny) | a tiny sweep | `coevo --experiment experiments/tiny.ron --jobs 2` | 4 of 4 |"),
        "{md}"
    );
    assert!(md.contains("\n## tiny\n") && md.contains("![paper-variants](figures/paper-variants.svg)"), "{md}");
    // Every order parameter of the one list (sim::metrics::order_parameters!) reaches metrics.csv, the
    // evaluation's CSV, the summary's columns (training and evaluation), the claims' validator and the
    // report's table, so one added there is seen everywhere.
    use coevo::sim::metrics::Swarming;
    let run = two.path().join("results/tiny/paper/5-3/seed1");
    let metrics_header = std::fs::read_to_string(run.join("metrics.csv")).unwrap().lines().next().unwrap().to_string();
    let eval_header =
        std::fs::read_to_string(run.join("eval-50-prey.csv")).unwrap().lines().next().unwrap().to_string();
    let summary_header = &rows[0];
    for name in Swarming::NAMES {
        let column = format!("{name}_prey");
        assert!(metrics_header.split(',').any(|c| c == column), "metrics.csv lacks {column}: {metrics_header}");
        assert!(eval_header.split(',').any(|c| c == column), "eval-50-prey.csv lacks {column}: {eval_header}");
    }
    for (name, label) in coevo::experiment::EVAL_ORDER.iter().zip(coevo::experiment::EVAL_ORDER_LABELS) {
        for column in [format!("{name}_last100"), format!("eval_50-prey_{name}")] {
            assert!(summary_header.split(',').any(|c| c == column), "summary.csv lacks {column}");
        }
        assert!(md.contains(&format!(" {label} |")), "REPORT.md's table lacks {label}");
    }
    assert_eq!(Swarming::NAMES[..2], ["dos", "doa"], "DoS and DoA first: they have quantities of their own");
    assert_eq!(coevo::experiment::EVAL_ORDER.len(), Swarming::N - 2 + 1);
    assert!(md.contains("| paper | DoS falls | DoS change, last − first 100 of `5:3` | -0.030 |"), "{md}");
    // A comparison of two variants: the difference of their seed means (Welch's interval beside it).
    let change = |variant: &str| {
        let rows: Vec<Vec<f64>> = rows[1..]
            .iter()
            .filter(|r| r.starts_with(&format!("paper,{variant},")))
            .map(|r| r.split(',').map(|c| c.parse().unwrap_or(f64::NAN)).collect())
            .collect();
        rows.iter().map(|c| c[column("dos_last100")] - c[column("dos_first100")]).sum::<f64>() / rows.len() as f64
    };
    let expected = format!(
        "| paper | 5:3 against 1:1 | DoS change, last − first 100 of `5:3` minus `1:1` (Welch) | – | {:.3} ± ",
        change("5:3") - change("1:1")
    );
    assert!(md.contains(&expected), "{expected} not in {md}");
    // Catches per episode, last − first 100: here all 3 episodes are in both windows, so no change is
    // measured, and the verdict says why instead of reporting a zero.
    assert!(
        md.contains(
            "| paper | catches | catches per episode, change, last − first 100 of `5:3` | – | 0.000 ± 0.000 (2), uninformative: 2 seeds |"
        ),
        "{md}"
    );
    assert!(
        md.contains("| not measured: runs shorter than 200 episodes, too short for a change over training (windows that overlap) |"),
        "{md}"
    );
    // The variants compared: one row per variant (with its seed count) in each panel, the interaction
    // panel among them.
    let variants = std::fs::read_to_string(two.path().join("results/tiny/figures/paper-variants.svg")).unwrap();
    for text in [
        "1:1 (2)",
        "5:3 (2)",
        "DoA seeing − 50 prey, blind",
        "DoA of prey: change over training",
        "catches: change over training",
    ] {
        assert!(variants.contains(text), "{text} not in the variants figure");
    }
    for figure in ["paper-training.png", "paper-catches.png", "paper-eval-50-prey.png", "paper-variants.png"] {
        let bytes = std::fs::read(two.path().join("results/tiny/figures").join(figure)).unwrap();
        let png = resvg::tiny_skia::Pixmap::decode_png(&bytes).unwrap();
        assert!(png.width() >= 600 && png.height() >= 400, "{figure}");
        let distinct: std::collections::BTreeSet<[u8; 4]> =
            png.pixels().iter().map(|p| [p.red(), p.green(), p.blue(), p.alpha()]).collect();
        assert!(distinct.len() > 20, "{figure} is not blank");
    }

    // One job at a time: the same summary.
    let one = workspace();
    assert!(coevo(one.path(), &["--experiment", "experiments/tiny.ron", "--jobs", "1"]).status.success());
    assert_eq!(summary(one.path()), rows);

    // A kill: one run stopped at its checkpoint after 2 of 3 episodes, another before its first
    // checkpoint, and an evaluation not yet written. The rerun resumes, restarts and evaluates only those.
    let seed1 = one.path().join("results/tiny/paper/1-1/seed1");
    let finished = one.path().join("results/tiny/paper/5-3/seed2");
    let untouched = std::fs::metadata(finished.join("metrics.csv")).unwrap().modified().unwrap();
    std::fs::remove_dir_all(&seed1).unwrap();
    let partial = coevo(
        one.path(),
        &[
            "--train",
            "--scene",
            "results/tiny/paper/1-1/scene.ron",
            "--seed",
            "1",
            "--out",
            seed1.to_str().unwrap(),
            "--episodes",
            "2",
            "--quiet",
        ],
    );
    assert!(partial.status.success(), "{}", String::from_utf8_lossy(&partial.stderr));
    assert!(replay_segments(&files_under(&seed1)) > 0, "a run trained by --train keeps its buffers");
    std::fs::remove_dir_all(one.path().join("results/tiny/paper/1-1/seed2/checkpoint")).unwrap();
    std::fs::remove_file(one.path().join("results/tiny/paper/5-3/seed1/eval-50-prey.csv")).unwrap();
    // Only a finished run is a row: aggregated now, without the committed summary to carry, the summary
    // holds the one run trained and evaluated, not the trained one still missing an evaluation.
    let aside = one.path().join("aside");
    std::fs::rename(one.path().join("results/tiny"), &aside).unwrap();
    std::fs::create_dir_all(one.path().join("results/tiny/paper")).unwrap();
    for v in ["1-1", "5-3"] {
        std::fs::rename(aside.join("paper").join(v), one.path().join("results/tiny/paper").join(v)).unwrap();
    }
    let out = coevo(one.path(), &["--plot", "results/tiny", "--partial"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let part = summary(one.path());
    assert!(part.len() == 2 && part[1].starts_with("paper,5:3,2,3,"), "{part:?}");
    for v in ["1-1", "5-3"] {
        std::fs::rename(one.path().join("results/tiny/paper").join(v), aside.join("paper").join(v)).unwrap();
    }
    std::fs::remove_dir_all(one.path().join("results/tiny")).unwrap();
    std::fs::rename(&aside, one.path().join("results/tiny")).unwrap();
    assert!(coevo(one.path(), &["--experiment", "experiments/tiny.ron", "--jobs", "2"]).status.success());
    assert_eq!(
        std::fs::metadata(finished.join("metrics.csv")).unwrap().modified().unwrap(),
        untouched,
        "a finished run is not redone"
    );
    assert!(one.path().join("results/tiny/paper/5-3/seed1/eval-50-prey.csv").exists());
    assert_eq!(replay_segments(&files_under(&seed1)), 0, "the resumed run's buffers go once it is trained");
    let again = summary(one.path());
    assert_eq!(again.len(), 5);
    assert!(again[1].starts_with("paper,1:1,1,3,"), "the resumed run has all its episodes: {}", again[1]);
    assert_eq!(again[2..], rows[2..], "restarted from scratch and untouched runs give the same rows");
    // --plot regenerates from the CSVs alone.
    std::fs::remove_dir_all(one.path().join("results/tiny/figures")).unwrap();
    assert!(coevo(one.path(), &["--plot", "results/tiny"]).status.success());
    assert!(one.path().join("results/tiny/figures/paper-training.png").exists());
    assert!(coevo(one.path(), &["--plot", seed1.to_str().unwrap()]).status.success());
    assert!(seed1.join("figures/training.png").exists());

    // A run whose provenance names another executable: refused in one line (every number of an
    // experiment comes from one binary), unless the experiment file allows mixed binaries.
    let provenance = finished.join("provenance.ron");
    let original = std::fs::read_to_string(&provenance).unwrap();
    assert!(original.contains("binary: \""), "{original}");
    std::fs::write(&provenance, original.replacen("binary: \"", "binary: \"other", 1)).unwrap();
    let stderr = refused(one.path(), &["--plot", "results/tiny"]);
    assert!(stderr.contains("more than one binary") && stderr.contains("mixed_binaries"), "{stderr}");
    let tiny = one.path().join("experiments/tiny.ron");
    std::fs::write(&tiny, TINY.replacen("seeds: [1, 2],", "seeds: [1, 2], mixed_binaries: true,", 1)).unwrap();
    assert!(coevo(one.path(), &["--plot", "results/tiny"]).status.success());
    std::fs::write(&tiny, TINY).unwrap();
    // Or runs on two families of matrix-product kernels.
    let kernels = original.split("kernels: \"").nth(1).unwrap().split('"').next().unwrap();
    std::fs::write(&provenance, original.replacen(&format!("kernels: \"{kernels}\""), "kernels: \"elsewhere\"", 1))
        .unwrap();
    let stderr = refused(one.path(), &["--plot", "results/tiny"]);
    assert!(
        stderr.contains("more than one family of matrix-product kernels") && stderr.contains("elsewhere"),
        "{stderr}"
    );
    std::fs::write(&provenance, original).unwrap();

    // As in a fresh clone (run folders are not committed): REPRODUCTION.md is recomputed from the committed
    // summary.csv alone and the figures are redrawn from the committed figure-data.ron.gz, byte for byte
    // the same, and nothing committed is rewritten.
    let committed = |p: &str| std::fs::read(one.path().join(p)).unwrap();
    assert!(coevo(one.path(), &["--plot", "all"]).status.success());
    let before =
        (committed("REPRODUCTION.md"), committed("results/tiny/summary.csv"), committed("results/tiny/REPORT.md"));
    std::fs::rename(one.path().join("results/tiny/paper"), one.path().join("elsewhere")).unwrap();
    let results = files_under(&one.path().join("results"));
    assert!(results.keys().filter(|f| f.starts_with("tiny/figures")).count() > 10, "{:?}", results.keys());
    std::fs::remove_dir_all(one.path().join("results/tiny/figures")).unwrap();
    let out = coevo(one.path(), &["--plot", "all"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert_eq!(
        (committed("REPRODUCTION.md"), committed("results/tiny/summary.csv"), committed("results/tiny/REPORT.md")),
        before
    );
    assert!(
        files_under(&one.path().join("results")) == results,
        "every file under results/ as it was, figures redrawn"
    );
    // So does one experiment's folder alone, and says what it wrote; without the figure data it has
    // nothing to redraw. Slurm scripts aggregate nothing.
    std::fs::remove_dir_all(one.path().join("results/tiny/figures")).unwrap();
    let out = coevo(one.path(), &["--plot", "results/tiny"]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        out.status.success() && stderr.contains("from the committed summary.csv and figure-data.ron.gz"),
        "{stderr}"
    );
    assert!(files_under(&one.path().join("results")) == results, "figures redrawn again");
    let data = one.path().join("results/tiny/figure-data.ron.gz");
    std::fs::rename(&data, one.path().join("figure-data.ron.gz")).unwrap();
    let stderr = refused(one.path(), &["--plot", "results/tiny"]);
    assert!(stderr.contains("no finished run"), "{stderr}");
    std::fs::rename(one.path().join("figure-data.ron.gz"), &data).unwrap();
    // A committed summary missing a run (3 of the file's 4): refused in one line, by one experiment's
    // --plot and by --plot all, unless --partial, and then its report says "partial".
    let summary = one.path().join("results/tiny/summary.csv");
    let whole = std::fs::read_to_string(&summary).unwrap();
    let cut: String = whole.lines().take(4).map(|l| format!("{l}\n")).collect();
    assert_eq!((whole.lines().count(), cut.lines().count()), (5, 4));
    std::fs::write(&summary, &cut).unwrap();
    for plot in ["results/tiny", "all"] {
        let report = committed("results/tiny/REPORT.md");
        let stderr = refused(one.path(), &["--plot", plot]);
        assert!(stderr.contains("results/tiny/summary.csv holds 3 of the 4 runs of experiments/tiny.ron"), "{stderr}");
        assert_eq!(committed("results/tiny/REPORT.md"), report, "nothing written");
        let out = coevo(one.path(), &["--plot", plot, "--partial"]);
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        let report = String::from_utf8(committed("results/tiny/REPORT.md")).unwrap();
        assert!(report.contains("**Partial: 3 of the 4 runs are finished.**"), "{report}");
    }
    assert!(String::from_utf8(committed("REPRODUCTION.md")).unwrap().contains("**Partial: 3 of the 4 runs"));
    // An experiment judged when complete (no interim analysis) is reported in progress without --partial:
    // how many runs are finished, and no estimate, verdict or figure.
    let tiny = one.path().join("experiments/tiny.ron");
    std::fs::write(&tiny, TINY.replacen("seeds: [1, 2],", "seeds: [1, 2], judged_when_complete: true,", 1)).unwrap();
    std::fs::remove_dir_all(one.path().join("results/tiny/figures")).unwrap();
    for plot in ["results/tiny", "all"] {
        let out = coevo(one.path(), &["--plot", plot]);
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        let report = String::from_utf8(committed("results/tiny/REPORT.md")).unwrap();
        assert!(report.contains("**In progress: 3 of the 4 runs are finished**"), "{report}");
        let rows: Vec<&str> = report.lines().filter(|l| l.starts_with("| paper |")).collect();
        assert_eq!(rows.len(), 4, "{report}");
        for row in rows {
            assert!(
                row.contains(
                    " | – | – | – | – | in progress: 3 of 4 runs finished; judged when all are (no interim analysis) |"
                ),
                "{row}"
            );
        }
        let numbers = report.lines().any(|l| l.starts_with("| paper") && l.contains('±'));
        assert!(!report.contains("Collective measures") && !numbers, "no number: {report}");
        let figures = std::fs::read_dir(one.path().join("results/tiny/figures")).map_or(0, |d| d.count());
        assert_eq!(figures, 0, "no figure of an experiment in progress");
    }
    std::fs::write(&tiny, TINY).unwrap();
    std::fs::write(&summary, &whole).unwrap();
    assert!(coevo(one.path(), &["--plot", "all"]).status.success());
    assert_eq!(committed("results/tiny/REPORT.md"), before.2);
    assert!(coevo(one.path(), &["--experiment", "experiments/tiny.ron", "--emit-slurm"]).status.success());
    // Some run folders but fewer than the summary holds (the others finished on another machine: run
    // folders are not committed): the committed rows and curves of the runs not here are carried, so the
    // experiment runs nothing again and aggregating writes the summaries the whole set of folders wrote,
    // byte for byte.
    let means = committed("results/tiny/summary-mean.csv");
    assert!(String::from_utf8(committed("results/tiny/runs.csv"))
        .unwrap()
        .starts_with("preset,variant,seed,scene,kernels\npaper,1:1,1,"));
    std::fs::create_dir_all(one.path().join("results/tiny/paper/5-3")).unwrap();
    std::fs::rename(one.path().join("elsewhere/5-3/seed2"), one.path().join("results/tiny/paper/5-3/seed2")).unwrap();
    let out = coevo(one.path(), &["--experiment", "experiments/tiny.ron", "--quiet"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(!one.path().join("results/tiny/paper/1-1/seed1").exists(), "the runs finished elsewhere are not run again");
    assert_eq!(
        (
            committed("results/tiny/summary.csv"),
            committed("results/tiny/summary-mean.csv"),
            committed("results/tiny/REPORT.md")
        ),
        (before.1.clone(), means.clone(), before.2.clone())
    );
    // A third seed trained here, beside one more committed run back: the summary gains the new rows and
    // keeps the committed ones as they were.
    let tiny = one.path().join("experiments/tiny.ron");
    std::fs::write(&tiny, TINY.replacen("seeds: [1, 2],", "seeds: [1, 2, 3],", 1)).unwrap();
    std::fs::rename(one.path().join("elsewhere/5-3/seed1"), one.path().join("results/tiny/paper/5-3/seed1")).unwrap();
    let out = coevo(one.path(), &["--experiment", "experiments/tiny.ron", "--quiet"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(
        one.path().join("results/tiny/paper/1-1/seed3").exists()
            && !one.path().join("results/tiny/paper/1-1/seed1").exists()
    );
    let six: Vec<String> = std::fs::read_to_string(&summary).unwrap().lines().map(String::from).collect();
    assert_eq!(six.len(), 7, "{six:?}");
    let old: Vec<String> = String::from_utf8(before.1.clone()).unwrap().lines().map(String::from).collect();
    assert!(old[1..].iter().all(|row| six.contains(row)), "the committed rows kept: {six:?}");
    assert!(
        six[3].starts_with("paper,1:1,3,3,") && six[6].starts_with("paper,5:3,3,3,"),
        "in the runs' order: {six:?}"
    );
    // A committed run whose scene the file has changed since is not carried: refused in one line naming
    // it, with nothing written, and the runner trains it anew.
    let summary_before = committed("results/tiny/summary.csv");
    let changed = TINY.replacen("seeds: [1, 2],", "seeds: [1, 2, 3],", 1).replacen("hidden: 16", "hidden: 8", 1);
    std::fs::write(&tiny, &changed).unwrap();
    std::fs::rename(one.path().join("results/tiny/paper/1-1"), one.path().join("elsewhere-1-1")).unwrap();
    let stderr = refused(one.path(), &["--plot", "results/tiny"]);
    assert!(
        stderr.contains("results/tiny/summary.csv: holds 3 runs not finished here (no folder, or evaluations still to come), and paper/1:1/seed1's committed row is of another scene or evaluations than experiments/tiny.ron asks for now"),
        "{stderr}"
    );
    assert_eq!(committed("results/tiny/summary.csv"), summary_before, "nothing written");
    std::fs::write(&tiny, TINY.replacen("seeds: [1, 2],", "seeds: [1, 2, 3],", 1)).unwrap();
    // Another binary's committed rows are not mixed with this one's folders.
    let ledger = committed("results/tiny/summary.csv");
    let mut lines: Vec<String> = String::from_utf8(ledger.clone()).unwrap().lines().map(String::from).collect();
    let binary = lines[0].split(',').position(|c| c == "binary").unwrap();
    let mut cells: Vec<String> = lines[1].split(',').map(String::from).collect();
    cells[binary] = "0123456789abcdef".into();
    lines[1] = cells.join(",");
    std::fs::write(&summary, lines.join("\n") + "\n").unwrap();
    let stderr = refused(one.path(), &["--plot", "results/tiny"]);
    assert!(
        stderr.contains("runs of more than one binary (the committed paper/1:1/seed1 by 0123456789abcdef"),
        "{stderr}"
    );
    // The runner refuses to continue them with another binary before running anything (a fourth seed
    // gives it a run to make: with none, it makes nothing and aggregation refuses as above).
    let with_seed_4 = TINY.replacen("seeds: [1, 2],", "seeds: [1, 2, 3, 4],", 1);
    std::fs::write(&tiny, &with_seed_4).unwrap();
    let stderr = refused(one.path(), &["--experiment", "experiments/tiny.ron", "--quiet"]);
    assert!(
        stderr.contains("the committed run paper/1:1/seed1 was made by the coevo binary 0123456789abcdef"),
        "{stderr}"
    );
    assert!(!one.path().join("results/tiny/paper/1-1").exists(), "nothing written");
    std::fs::write(&tiny, TINY.replacen("seeds: [1, 2],", "seeds: [1, 2, 3],", 1)).unwrap();
    std::fs::write(&summary, &ledger).unwrap();
    // Nor are rows committed from runs on another family of matrix-product kernels (the same binary
    // computes other numbers there): refused by aggregation, and by the runner before anything runs.
    let runs_csv = one.path().join("results/tiny/runs.csv");
    let record = std::fs::read_to_string(&runs_csv).unwrap();
    let kernels = record.lines().nth(1).unwrap().rsplit(',').next().unwrap().to_string();
    assert!(["avx512", "avx2-fma", "portable"].contains(&kernels.as_str()), "{record}");
    let other = if kernels == "portable" { "avx2-fma" } else { "portable" };
    let first = record.lines().nth(1).unwrap();
    let mut lines: Vec<&str> = record.lines().collect();
    let moved = format!("{}{other}", &first[..first.len() - kernels.len()]);
    lines[1] = &moved;
    std::fs::write(&runs_csv, lines.join("\n") + "\n").unwrap();
    let stderr = refused(one.path(), &["--plot", "results/tiny"]);
    assert!(
        stderr.contains(&format!(
            "runs on more than one family of matrix-product kernels (the committed paper/1:1/seed1 on {other}, the run folders here on {kernels})"
        )),
        "{stderr}"
    );
    std::fs::write(&tiny, &with_seed_4).unwrap();
    let stderr = refused(one.path(), &["--experiment", "experiments/tiny.ron", "--quiet"]);
    assert!(
        stderr.contains(&format!(
            "the committed run paper/1:1/seed1 ran on {other} kernels and this machine runs {kernels}"
        )),
        "{stderr}"
    );
    assert!(!one.path().join("results/tiny/paper/1-1").exists(), "nothing written");
    std::fs::write(&runs_csv, &record).unwrap();
    std::fs::rename(one.path().join("elsewhere-1-1"), one.path().join("results/tiny/paper/1-1")).unwrap();
    std::fs::write(&tiny, TINY).unwrap();
    let out = coevo(one.path(), &["--plot", "all"]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert_eq!(
        (committed("REPRODUCTION.md"), committed("results/tiny/summary.csv"), committed("results/tiny/REPORT.md")),
        before
    );
}

#[test]
fn slurm_scripts_have_the_array_range_and_the_aggregate_dependency() {
    let dir = workspace();
    let out = coevo(dir.path(), &["--experiment", "experiments/tiny.ron", "--emit-slurm"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let slurm = dir.path().join("results/tiny/slurm");
    let array = std::fs::read_to_string(slurm.join("array.sh")).unwrap();
    assert!(array.contains("#SBATCH --array=0-3"), "{array}");
    assert!(array.contains("--experiment experiments/tiny.ron --task \"$SLURM_ARRAY_TASK_ID\""), "{array}");
    let submit = std::fs::read_to_string(slurm.join("submit.sh")).unwrap();
    assert!(
        submit.contains("jid=$(sbatch --parsable --job-name=tiny --output='results/tiny/slurm/%A_%a.log' results/tiny/slurm/array.sh)"),
        "{submit}"
    );
    assert!(submit.contains("sbatch --dependency=afterok:\"$jid\""), "{submit}");
    assert!(submit.contains("results/tiny/slurm/aggregate.sh"), "{submit}");
    assert!(std::fs::read_to_string(slurm.join("aggregate.sh")).unwrap().contains("--plot results/tiny"));
    // Paths and names are words of the scripts, never shell code (robustness III): the array task's
    // command line parses back to exactly the file's path, and submitting runs nothing of a name.
    let root = dir.path();
    let bin = root.join("bin");
    std::fs::create_dir(&bin).unwrap();
    std::fs::write(bin.join("sbatch"), "#!/bin/sh\nprintf '%s\\n' \"$@\" >> sbatch.log\necho 42\n").unwrap();
    std::fs::set_permissions(bin.join("sbatch"), std::os::unix::fs::PermissionsExt::from_mode(0o755)).unwrap();
    for name in ["x;touch PWNED;", "y$(touch PWNED)", "with space", "it's"] {
        let file = format!("experiments/{name}.ron");
        std::fs::write(root.join(&file), TINY).unwrap();
        let out = coevo(root, &["--experiment", &file, "--emit-slurm"]);
        assert!(out.status.success(), "{name}: {}", String::from_utf8_lossy(&out.stderr));
        let scripts = root.join("results").join(name).join("slurm");
        let array = std::fs::read_to_string(scripts.join("array.sh")).unwrap();
        let exec = array.lines().find(|l| l.starts_with("exec ")).unwrap();
        let words = shell_words::split(exec).unwrap();
        assert_eq!(words[2..6], ["--experiment", file.as_str(), "--task", "$SLURM_ARRAY_TASK_ID"], "{name}: {exec}");
        let path = format!("{}:{}", bin.display(), std::env::var("PATH").unwrap());
        let submitted =
            Command::new("bash").arg(scripts.join("submit.sh")).env("PATH", path).current_dir(root).output().unwrap();
        assert!(submitted.status.success(), "{name}: {}", String::from_utf8_lossy(&submitted.stderr));
        let log = std::fs::read_to_string(root.join("sbatch.log")).unwrap();
        assert!(
            log.contains(&format!("--job-name={name}\n")) && log.contains(&format!("results/{name}/slurm/array.sh\n")),
            "{log}"
        );
        assert!(!root.join("PWNED").exists(), "{name}: a name ran as shell code");
    }
    // A name no script can quote safely is refused before anything is written.
    std::fs::write(root.join("experiments/per%cent.ron"), TINY).unwrap();
    let out = coevo(root, &["--experiment", "experiments/per%cent.ron", "--emit-slurm"]);
    assert!(!out.status.success() && String::from_utf8_lossy(&out.stderr).contains("control character or %"));
    assert!(!root.join("results/per%cent/slurm").exists());
    // An array task runs exactly its run (here of a file that keeps trained runs' replay buffers).
    let keeping = TINY.replacen("seeds: [1, 2],", "seeds: [1, 2], keep_replay: true,", 1);
    std::fs::write(dir.path().join("experiments/tiny.ron"), keeping).unwrap();
    assert!(coevo(dir.path(), &["--experiment", "experiments/tiny.ron", "--task", "2"]).status.success());
    assert!(dir.path().join("results/tiny/paper/5-3/seed1/checkpoint/state.ron").exists());
    assert!(replay_segments(&files_under(&dir.path().join("results/tiny/paper/5-3/seed1"))) > 0);
    assert!(!dir.path().join("results/tiny/paper/1-1/seed1").exists());
    let bad = coevo(dir.path(), &["--experiment", "experiments/tiny.ron", "--task", "9"]);
    assert!(String::from_utf8_lossy(&bad.stderr).contains("--task 9: experiments/tiny.ron has runs 0 to 3"));
}

#[test]
fn the_preset_ablations_change_exactly_one_difference_per_variant() {
    // Each variant's scene differs from its file's first variant in the named fields only, and in total
    // the variants walk every difference between the presets that acts on the periodic arena.
    for (file, all_differences) in
        [("experiments/ablation-from-paper.ron", "paper"), ("experiments/ablation-from-gym-pps.ron", "gym-pps")]
    {
        let exp = Experiment::load(Path::new(file), Path::new("results")).unwrap();
        let first_seed: Vec<&coevo::experiment::Run> = exp.runs.iter().filter(|r| r.seed == 1).collect();
        let lines = |s: &coevo::scene::Scene| s.to_ron().lines().map(str::to_string).collect::<Vec<String>>();
        let base = lines(&first_seed[0].scene);
        let mut changed_in_total = std::collections::BTreeSet::new();
        for run in &first_seed[1..] {
            let variant = lines(&run.scene);
            assert_eq!(variant.len(), base.len(), "{file}: {}", run.variant);
            let changed: Vec<String> = base
                .iter()
                .zip(&variant)
                .filter(|(a, b)| a != b)
                .map(|(_, b)| b.trim().split(':').next().unwrap().to_string())
                .collect();
            let expected: &[&str] = match run.variant.as_str() {
                v if v.starts_with("turn rate") => &["max_turn_rate", "max_turn_rate"],
                v if v.starts_with("predator mass") => &["mass"],
                v if v.starts_with("contact reward") => &["contact"],
                v if v.starts_with("contacts") => &["contacts_judged"],
                v if v.starts_with("thrust") => &["thrust_cost"],
                v if v.starts_with("speed clip") => &["speed_clip"],
                v if v.contains("energy budget") => &["energy_budget"],
                v => panic!("{file}: unexpected variant {v}"),
            };
            assert_eq!(changed, expected, "{file}: {}", run.variant);
            changed_in_total.extend(changed);
        }
        // The other preset differs from this one in exactly these fields (walls aside, which do nothing here).
        let other = coevo::scene::Scene::preset(if all_differences == "paper" { "gym-pps" } else { "paper" }).unwrap();
        let mine = coevo::scene::Scene::preset(all_differences).unwrap();
        let mut presets_differ: std::collections::BTreeSet<String> = lines(&mine)
            .iter()
            .zip(lines(&other))
            .filter(|(a, b)| *a != b)
            .map(|(a, _)| a.trim().split(':').next().unwrap().to_string())
            .collect();
        for ignored in ["preset", "wall_stiffness", "wall_damping", "wall_penalty_mode"] {
            presets_differ.remove(ignored);
        }
        assert_eq!(changed_in_total, presets_differ, "{file} walks every difference of the presets");
    }
}

/// An experiment that shares tiny's 1:1 runs and trains an identical variant of its own.
const SHARE: &str = r#"(
    base: "scenes/paper.ron",
    seeds: [1, 2],
    episodes: 3,
    variants: [
        (name: "shared", shared_from: "tiny/1:1", patch: (episode_steps: 30, learning: (hidden: 16, batch_size: 32, warmup_transitions: 32, updates_per_episode: 3, checkpoint_every: 1))),
        (name: "again", same_training_as: "tiny/1:1", patch: (episode_steps: 30, learning: (hidden: 16, batch_size: 32, warmup_transitions: 32, updates_per_episode: 3, checkpoint_every: 1))),
    ],
    evaluations: [(name: "50 prey", counts: [("prey", 50)], episodes: 2, steps: 20)],
    claims: [(text: "again against shared", variant: "again", versus: "shared", quantity: DosLast)],
)"#;

#[test]
fn a_shared_variant_is_the_other_experiments_runs_trained_once_and_never_compared_with_itself() {
    let dir = workspace();
    std::fs::write(dir.path().join("experiments/share.ron"), SHARE).unwrap();
    // Sharing first: the owner's runs are trained in the owner's folders, once.
    let out = coevo(dir.path(), &["--experiment", "experiments/share.ron", "--jobs", "2"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(dir.path().join("results/tiny/paper/1-1/seed1/metrics.csv").exists(), "trained where tiny keeps it");
    assert!(!dir.path().join("results/share/paper/shared").exists(), "no copy under the sharing experiment");
    let owner_metrics =
        std::fs::metadata(dir.path().join("results/tiny/paper/1-1/seed2/metrics.csv")).unwrap().modified().unwrap();
    let out = coevo(dir.path(), &["--experiment", "experiments/tiny.ron", "--jobs", "2"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert_eq!(
        std::fs::metadata(dir.path().join("results/tiny/paper/1-1/seed2/metrics.csv")).unwrap().modified().unwrap(),
        owner_metrics,
        "the owner finds its shared runs finished and does not train them again"
    );
    // The shared rows are tiny's rows (every column up to the wall clock), marked as shared.
    // A row's fields from the seed up to the wall clock, and its shared_from (variant names here hold no
    // comma, so a split is the CSV's fields).
    let (wall, from) = {
        let text = std::fs::read_to_string(dir.path().join("results/share/summary.csv")).unwrap();
        let header: Vec<String> = text.lines().next().unwrap().split(',').map(String::from).collect();
        let at = |name: &str| header.iter().position(|h| h == name).unwrap();
        assert_eq!((at("binary"), at("shared_from")), (at("wall_seconds") + 1, at("wall_seconds") + 2));
        (at("wall_seconds"), at("shared_from"))
    };
    let rows = |experiment: &str, variant: &str| -> Vec<String> {
        let text = std::fs::read_to_string(dir.path().join(format!("results/{experiment}/summary.csv"))).unwrap();
        text.lines()
            .filter(|l| l.starts_with(&format!("paper,{variant},")))
            .map(|l| l.split(',').skip(2).take(wall - 2).collect::<Vec<_>>().join(","))
            .collect()
    };
    let share_summary = std::fs::read_to_string(dir.path().join("results/share/summary.csv")).unwrap();
    assert_eq!(
        share_summary
            .lines()
            .filter(|l| l.starts_with("paper,shared,") && l.split(',').nth(from) == Some("tiny"))
            .count(),
        2
    );
    // Only the columns both experiments have (share evaluates one of tiny's two evaluations) are compared:
    // the training columns at the start of each row.
    let training =
        |v: Vec<String>| v.iter().map(|r| r.split(',').take(20).collect::<Vec<_>>().join(",")).collect::<Vec<_>>();
    assert_eq!(training(rows("share", "shared")), training(rows("tiny", "1:1")));
    // A variant that trains the same scene again is a deterministic re-run: no comparison, no p-value;
    // the contents count the shared runs once (under tiny) and say so.
    let md = std::fs::read_to_string(dir.path().join("results/share/REPORT.md")).unwrap();
    assert!(md.contains("| – | not a comparison: the two variants' runs are identical"), "{md}");
    // Three-episode runs: the report says their first and last 100 episodes overlap.
    assert!(
        md.contains("**Runs of 3 episodes:** shorter than 200 episodes, so their first and last 100 episodes overlap"),
        "{md}"
    );
    assert!(md.contains("| 4 of 4 (2 shared) |"), "{md}");
    // The suite's totals count that re-training once: the same resolved scene and seed by the same binary
    // is one training, whichever experiments hold it.
    let out = coevo(dir.path(), &["--plot", "all"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let suite = std::fs::read_to_string(dir.path().join("REPRODUCTION.md")).unwrap();
    let suite = suite.split("## The whole suite").nth(1).unwrap();
    assert!(suite.contains("6 of 6 trainings finished, of which 4 distinct"), "{suite}");
    assert!(suite.contains("(a deterministic re-training: 2 runs)"), "{suite}");
    // That re-training is declared (same_training_as): undeclared, the suite and share alone are refused
    // in one line naming both runs, and nothing is written.
    let undeclared = SHARE.replace("same_training_as: \"tiny/1:1\", ", "");
    assert_ne!(undeclared, SHARE);
    std::fs::write(dir.path().join("experiments/share.ron"), &undeclared).unwrap();
    let before = files_under(&dir.path().join("results"));
    for args in [&["--plot", "all"][..], &["--plot", "results/share"], &["--experiment", "experiments/share.ron"]] {
        let stderr = refused(dir.path(), args);
        assert!(
            stderr.contains("share/paper/again/seed1 and tiny/paper/1:1/seed1 are one training")
                && stderr.contains("\"tiny/1:1\" in share's"),
            "{args:?}: {stderr}"
        );
    }
    assert!(files_under(&dir.path().join("results")) == before, "nothing written");
    let suite_now = std::fs::read_to_string(dir.path().join("REPRODUCTION.md")).unwrap();
    assert!(suite_now.contains("of which 4 distinct"), "REPRODUCTION.md as it was");
    std::fs::write(dir.path().join("experiments/share.ron"), SHARE).unwrap();
    // A named family spans files: tiny's two seeing-minus-blind tests and share's, which reads tiny's 1:1
    // runs the same way as one of them, are one family of two tests, adjusted together whether the suite
    // is reported (`--plot all`) or share alone (`--plot results/share`, reading tiny's summary).
    let tiny = TINY.replace(
        "(text: \"seeing minus blind\", variant: \"5:3\", quantity: InteractionDoa(\"50 prey, blind\")),",
        "(text: \"seeing minus blind\", variant: \"5:3\", quantity: InteractionDoa(\"50 prey, blind\"), family: Some(\"both\")),
        (text: \"seeing minus blind, 1:1\", variant: \"1:1\", quantity: InteractionDoa(\"50 prey, blind\"), family: Some(\"both\")),",
    );
    assert_ne!(tiny, TINY);
    std::fs::write(dir.path().join("experiments/tiny.ron"), tiny).unwrap();
    let share = SHARE
        .replace(
            "evaluations: [(name: \"50 prey\", counts: [(\"prey\", 50)], episodes: 2, steps: 20)],",
            "evaluations: [(name: \"50 prey\", counts: [(\"prey\", 50)], episodes: 2, steps: 20), (name: \"50 prey, blind\", counts: [(\"prey\", 50)], episodes: 2, steps: 20, control: Blind)],",
        )
        .replace(
            "claims: [",
            "family: Some(\"both\"),\n    claims: [(text: \"shared: seeing minus blind\", variant: \"shared\", quantity: InteractionDoa(\"50 prey, blind\")),",
        );
    std::fs::write(dir.path().join("experiments/share.ron"), &share).unwrap();
    // The new evaluation runs on share's own runs; tiny's runs have it already.
    let out = coevo(dir.path(), &["--experiment", "experiments/share.ron", "--jobs", "2"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let out = coevo(dir.path(), &["--plot", "all"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let row = |experiment: &str, claim: &str| -> String {
        let md = std::fs::read_to_string(dir.path().join(format!("results/{experiment}/REPORT.md"))).unwrap();
        md.lines()
            .find(|l| l.starts_with(&format!("| paper | {claim} |")))
            .unwrap_or_else(|| panic!("{md}"))
            .to_string()
    };
    let p_of = |row: &str| row.split(" | ").nth(7).unwrap().to_string();
    let (five, one, shared) = (
        row("tiny", "seeing minus blind"),
        row("tiny", "seeing minus blind, 1:1"),
        row("share", "shared: seeing minus blind"),
    );
    for r in [&five, &one, &shared] {
        assert!(r.ends_with("| both (2 tests) |"), "{r}");
    }
    // Claims are recorded when their runs start (claims.csv): a claim added after its results is flagged,
    // and so is one moved into another family after them.
    assert!(one.contains("added after its results existed"), "{one}");
    assert!(five.contains("moved to this family after its results existed"), "{five}");
    // The first in the files' order (share before tiny) is the test; the other names it.
    assert!(one.contains("the same test as share / paper / shared: seeing minus blind, counted once"), "{one}");
    assert!(!shared.contains("the same test") && !five.contains("the same test"), "{shared}\n{five}");
    assert_eq!(p_of(&shared), p_of(&one));
    let alone = std::fs::read(dir.path().join("results/share/REPORT.md")).unwrap();
    let out = coevo(dir.path(), &["--plot", "results/share"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert_eq!(std::fs::read(dir.path().join("results/share/REPORT.md")).unwrap(), alone, "share reported alone");
    std::fs::write(dir.path().join("experiments/share.ron"), SHARE).unwrap();
    // A claim edited after its results is flagged, also when its run folders are aggregated again (the
    // same results keep their record).
    let edited = TINY.replace("quantity: DosChange, paper: -0.03)", "quantity: DosChange, paper: -0.05)");
    assert_ne!(edited, TINY);
    std::fs::write(dir.path().join("experiments/tiny.ron"), edited).unwrap();
    let out = coevo(dir.path(), &["--plot", "results/tiny"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(row("tiny", "DoS falls").contains("edited after its results existed"), "{}", row("tiny", "DoS falls"));
    assert!(!row("tiny", "catches").contains("after its results existed"), "{}", row("tiny", "catches"));
    // Reworded, what it tests unchanged: said as such, not as a claim added after its results.
    let reworded = TINY.replace("(text: \"DoS falls\"", "(text: \"DoS falls over training\"");
    assert_ne!(reworded, TINY);
    std::fs::write(dir.path().join("experiments/tiny.ron"), reworded).unwrap();
    let out = coevo(dir.path(), &["--plot", "results/tiny"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let now = row("tiny", "DoS falls over training");
    assert!(
        now.contains("reworded after its results existed (what it tests unchanged)") && !now.contains("post hoc"),
        "{now}"
    );
    std::fs::write(dir.path().join("experiments/tiny.ron"), TINY).unwrap();
    // A shared reference to another scene, or two variants shared from the same runs, are refused.
    for (text, says) in [
        (
            SHARE.replace(
                "shared_from: \"tiny/1:1\", patch: (episode_steps: 30",
                "shared_from: \"tiny/1:1\", patch: (episode_steps: 31",
            ),
            "shared_from: tiny/1:1 is another scene",
        ),
        (
            SHARE.replace("(name: \"again\", same_training_as:", "(name: \"again\", shared_from:"),
            "compares runs with themselves",
        ),
        (SHARE.replace("shared_from: \"tiny/1:1\"", "shared_from: \"tiny/2:2\""), "tiny has no variant \"2:2\""),
        // A declared re-training must be the same scene, and a variant is shared or re-trained, not both.
        (
            SHARE.replace(
                "same_training_as: \"tiny/1:1\", patch: (episode_steps: 30",
                "same_training_as: \"tiny/1:1\", patch: (episode_steps: 31",
            ),
            "same_training_as: tiny/1:1 is another scene",
        ),
        (
            SHARE.replace(
                "(name: \"shared\", shared_from",
                "(name: \"shared\", same_training_as: \"tiny/1:1\", shared_from",
            ),
            "a variant is shared (shared_from) or re-trained (same_training_as), not both",
        ),
        // share.ron's own shared variant, shared again: refused; its other variants may be shared.
        (SHARE.replace("tiny/1:1", "share/shared"), "share/shared is itself shared from tiny/1:1"),
        (
            SHARE.replace(
                "(name: \"50 prey\", counts: [(\"prey\", 50)], episodes: 2",
                "(name: \"50 prey\", counts: [(\"prey\", 50)], episodes: 3",
            ),
            "differs from tiny's of the same name",
        ),
    ] {
        std::fs::write(dir.path().join("experiments/bad.ron"), text).unwrap();
        let stderr = refused(dir.path(), &["--experiment", "experiments/bad.ron"]);
        assert!(stderr.contains(says), "{says}: {stderr}");
    }
}

#[test]
fn untrained_actors_and_the_time_course_are_measured() {
    let dir = workspace();
    let text = TINY
        .replace(
            "(name: \"50 prey, blind\",",
            "(name: \"50 prey, untrained\", counts: [(\"prey\", 50)], episodes: 2, steps: 20, untrained: true),\n        (name: \"50 prey, blind\",",
        )
        .replace(
            "(text: \"catches\",",
            "(text: \"what training changed\", variant: \"5:3\", quantity: Learned(\"50 prey\", \"doa\")),\n        (text: \"time course\", variant: \"5:3\", quantity: Reach90(\"doa\")),\n        (text: \"catches\",",
        );
    std::fs::write(dir.path().join("experiments/tiny.ron"), &text).unwrap();
    let out = coevo(dir.path(), &["--experiment", "experiments/tiny.ron", "--jobs", "2"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let summary = std::fs::read_to_string(dir.path().join("results/tiny/summary.csv")).unwrap();
    let header: Vec<&str> = summary.lines().next().unwrap().split(',').collect();
    let at = |name: &str| header.iter().position(|h| *h == name).unwrap_or_else(|| panic!("no {name}"));
    for row in summary.lines().skip(1).filter(|l| l.starts_with("paper,5:3,")) {
        let cells: Vec<&str> = row.split(',').collect();
        let (trained, untrained) = (
            cells[at("eval_50-prey_doa_settled")].parse::<f64>().unwrap(),
            cells[at("eval_50-prey-untrained_doa_settled")].parse::<f64>().unwrap(),
        );
        assert!(trained.is_finite() && untrained.is_finite() && trained != untrained, "{row}");
    }
    assert!(header.contains(&"doa_reach90"));
    let md = std::fs::read_to_string(dir.path().join("results/tiny/REPORT.md")).unwrap();
    assert!(
        md.contains("DoA in evaluation \"50 prey\", trained minus untrained actors")
            || md.contains("doa in evaluation \"50 prey\", trained minus untrained actors"),
        "{md}"
    );
    // An untrained evaluation deploys the networks the run started from: the same as evaluating a run
    // that never trained (its first checkpoint is after episode 1, so compare with a fresh evaluation).
    let run = dir.path().join("results/tiny/paper/5-3/seed1");
    let out = coevo(
        dir.path(),
        &["--eval", run.to_str().unwrap(), "--untrained", "--episodes", "1", "--steps", "5", "--eval-out", "u.csv"],
    );
    let line = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success() && line.contains("untrained actors"), "{line}");
    // A Learned claim without an untrained partner is refused.
    let bad = TINY.replace("quantity: DosChange, paper: -0.03", "quantity: Learned(\"50 prey\", \"doa\")");
    std::fs::write(dir.path().join("experiments/bad.ron"), bad).unwrap();
    let out = coevo(dir.path(), &["--experiment", "experiments/bad.ron"]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && stderr.contains("needs an untrained partner"), "{stderr}");
}

#[test]
fn claims_on_the_authors_metric_read_its_curves() {
    // The authors' code's differences 9–11 (docs/src/results/authors-code.md): the paper's numbers judged
    // as the shipped code measures them. One run of ten episodes measuring the code's DoS and DoA; its
    // summary holds their first and last 100 episodes and their start (the first 10), each the mean of
    // metrics.csv's column (the start at single precision, as the figure data keeps curves), and the level
    // is told apart from the code's own chance level.
    let dir = workspace();
    let text = r#"(
    description: "the code's metric",
    base: "scenes/paper.ron",
    seeds: [1],
    episodes: 10,
    variants: [
        (name: "measured", patch: (authors_metrics: true, episode_steps: 30, learning: (hidden: 16, batch_size: 32, warmup_transitions: 32, updates_per_episode: 3, checkpoint_every: 5))),
    ],
    evaluations: [],
    claims: [
        (text: "DoA starts at about 0.65, as the code measures it", variant: "measured", quantity: Start("authors_doa"), paper: 0.65),
        (text: "DoA rises, as the code measures it", variant: "measured", quantity: FromStart("authors_doa"), paper: 0.17),
        (text: "DoS ends near 19 %, as the code measures it", variant: "measured", quantity: TrainingLast("authors_dos"), paper: 0.19),
    ],
)"#;
    std::fs::write(dir.path().join("experiments/code.ron"), text).unwrap();
    let out = coevo(dir.path(), &["--experiment", "experiments/code.ron"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let metrics = std::fs::read_to_string(dir.path().join("results/code/paper/measured/seed1/metrics.csv")).unwrap();
    let names: Vec<&str> = metrics.lines().next().unwrap().split(',').collect();
    let curve = |name: &str| -> Vec<f64> {
        let at = names.iter().position(|h| *h == name).unwrap_or_else(|| panic!("no {name}"));
        metrics.lines().skip(1).map(|l| l.split(',').nth(at).unwrap().parse::<f64>().unwrap()).collect()
    };
    let (doa, dos) = (curve("authors_doa_prey"), curve("authors_dos_prey"));
    assert_eq!(doa.len(), 10);
    let summary = std::fs::read_to_string(dir.path().join("results/code/summary.csv")).unwrap();
    let header: Vec<&str> = summary.lines().next().unwrap().split(',').collect();
    let row: Vec<f64> = summary.lines().nth(1).unwrap().split(',').map(|c| c.parse().unwrap_or(f64::NAN)).collect();
    let cell = |name: &str| row[header.iter().position(|h| *h == name).unwrap_or_else(|| panic!("no {name}"))];
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    assert_eq!(cell("authors_doa_start10"), mean(&doa.iter().map(|&x| x as f32 as f64).collect::<Vec<_>>()));
    assert_eq!(cell("authors_doa_last100"), mean(&doa));
    assert_eq!(cell("authors_dos_first100"), mean(&dos));
    assert!(cell("authors_dos_start10").is_finite());
    let report = std::fs::read_to_string(dir.path().join("results/code/REPORT.md")).unwrap();
    assert!(report.contains("authors_doa, first 10 episodes (the untrained start)"), "{report}");
    assert!(report.contains("authors_doa, last 100 episodes minus the first 10"), "{report}");
    assert!(report.contains("authors_dos, last 100 episodes"), "{report}");
    // The code's DoA of random headings at 10 prey (its most opposed partner), not the paper's 2/π.
    assert!(report.contains("apart from chance 0.154"), "{report}");
    // The other experiments' summaries keep their columns: no run of tiny.ron measures the code's metric.
    let tiny = Experiment::load(&dir.path().join("experiments/tiny.ron"), Path::new("results")).unwrap();
    assert!(coevo::claims::summary::columns(&tiny).iter().all(|(name, _)| !name.starts_with("authors_")));
}

#[test]
fn an_experiment_cross_plays_its_runs_and_judges_the_read_outs() {
    let dir = workspace();
    let text = TINY
        .replace("checkpoint_every: 1", "checkpoint_every: 1, snapshot_every: 1")
        .replace("    evaluations: [", "    crossplay: (episodes: 1),\n    evaluations: [")
        .replace(
            "(text: \"catches\",",
            "(text: \"prey part\", variant: \"5:3\", quantity: Crossplay(\"doa_late_prey_part\")),\n        (text: \"regress\", variant: \"5:3\", quantity: Crossplay(\"prey_regress_vs_early_predators\")),\n        (text: \"catches\",",
        );
    std::fs::write(dir.path().join("experiments/tiny.ron"), &text).unwrap();
    let out = coevo(dir.path(), &["--experiment", "experiments/tiny.ron", "--jobs", "2"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let run = dir.path().join("results/tiny/paper/5-3/seed2");
    let cells = std::fs::read_to_string(run.join("crossplay.csv")).unwrap();
    assert_eq!(cells.lines().count(), 1 + 4 * 4, "snapshots 0..=3 of each side: {cells}");
    let summary = std::fs::read_to_string(dir.path().join("results/tiny/summary.csv")).unwrap();
    let header: Vec<&str> = summary.lines().next().unwrap().split(',').collect();
    let at = header.iter().position(|h| *h == "crossplay_doa_late_prey_part").expect("a read-out column");
    let readouts = std::fs::read_to_string(run.join("crossplay-readouts.csv")).unwrap();
    let written = readouts.lines().find(|l| l.contains(",doa_late_prey_part,")).unwrap().split(',').nth(3).unwrap();
    let row = summary.lines().find(|l| l.starts_with("paper,5:3,2,")).unwrap();
    assert_eq!(row.split(',').nth(at).unwrap(), written, "the summary holds the run's read-out");
    assert!(dir.path().join("results/tiny/figures/paper-5-3-crossplay.png").exists(), "the mean matrix over seeds");
    let md = std::fs::read_to_string(dir.path().join("results/tiny/REPORT.md")).unwrap();
    assert!(md.contains("cross-play read-out doa_late_prey_part"), "{md}");
    // The share is a level against 0.5, not an effect against zero.
    assert!(md.contains("cross-play read-out prey_regress_vs_early_predators"), "{md}");
    redrawn_without_run_folders(dir.path());
}

/// As in a clone (run folders are not committed): `--plot` redraws every figure of the tiny experiment,
/// byte for byte, from its committed figure data.
fn redrawn_without_run_folders(dir: &Path) {
    let figures = files_under(&dir.join("results/tiny/figures"));
    std::fs::remove_dir_all(dir.join("results/tiny/figures")).unwrap();
    std::fs::rename(dir.join("results/tiny/paper"), dir.join("elsewhere")).unwrap();
    let out = coevo(dir, &["--plot", "results/tiny"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(files_under(&dir.join("results/tiny/figures")) == figures, "every figure redrawn as it was");
    // Figure data of other runs than the summary's (here: another training length) is refused in one line.
    let summary = dir.join("results/tiny/summary.csv");
    let text = std::fs::read_to_string(&summary).unwrap();
    let tampered = text.replacen("paper,5:3,1,3,", "paper,5:3,1,4,", 1);
    assert_ne!(tampered, text);
    std::fs::write(&summary, tampered).unwrap();
    let stderr = refused(dir, &["--plot", "results/tiny"]);
    assert!(stderr.contains("run paper/5:3/seed1 has 3 training episodes but summary.csv says 4"), "{stderr}");
    std::fs::write(&summary, text).unwrap();
}

#[test]
fn an_evaluation_with_a_perturbation_gives_the_response_columns_and_claims() {
    let dir = workspace();
    let text = TINY
        .replace(
            "(name: \"50 prey, blind\",",
            "(name: \"50 prey, turned\", counts: [(\"prey\", 50)], episodes: 2, steps: 20, perturb: 1.0, perturb_step: 5),\n        (name: \"50 prey, blind\",",
        )
        .replace(
            "(text: \"catches\",",
            "(text: \"near response\", variant: \"5:3\", quantity: Response(\"50 prey, turned\", \"near\")),\n        (text: \"catches\",",
        );
    std::fs::write(dir.path().join("experiments/tiny.ron"), &text).unwrap();
    let out = coevo(dir.path(), &["--experiment", "experiments/tiny.ron", "--jobs", "2"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let run = dir.path().join("results/tiny/paper/5-3/seed1");
    assert!(run.join("eval-50-prey-turned-perturbation.csv").exists());
    let summary = std::fs::read_to_string(dir.path().join("results/tiny/summary.csv")).unwrap();
    let header: Vec<&str> = summary.lines().next().unwrap().split(',').collect();
    let at = header.iter().position(|h| *h == "eval_50-prey-turned_response_near").expect("a response column");
    for row in summary.lines().skip(1) {
        let near: f64 = row.split(',').nth(at).unwrap().parse().unwrap();
        assert!(near.is_finite() && near > 0.0, "the neighbours of the turned prey respond: {row}");
    }
    assert!(dir.path().join("results/tiny/figures/paper-perturbation-50-prey-turned.png").exists());
    let md = std::fs::read_to_string(dir.path().join("results/tiny/REPORT.md")).unwrap();
    assert!(md.contains("near response to one prey turned, in evaluation \"50 prey, turned\""), "{md}");
    redrawn_without_run_folders(dir.path());
    // A Response claim needs a perturbed evaluation of that name.
    let bad = text.replace("perturb: 1.0, perturb_step: 5", "perturb_step: 5");
    std::fs::write(dir.path().join("experiments/bad.ron"), bad).unwrap();
    let out = coevo(dir.path(), &["--experiment", "experiments/bad.ron"]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && stderr.contains("with perturb: RADIANS"), "{stderr}");
}

#[test]
fn an_evaluation_edited_in_the_file_is_run_again_and_never_aggregated_stale() {
    let dir = workspace();
    assert!(coevo(dir.path(), &["--experiment", "experiments/tiny.ron", "--jobs", "2"]).status.success());
    let run = dir.path().join("results/tiny/paper/1-1/seed1");
    let trained = std::fs::metadata(run.join("metrics.csv")).unwrap().modified().unwrap();
    let last_row = |file: &str| {
        let text = std::fs::read_to_string(run.join(file)).unwrap();
        text.lines().last().unwrap().split(',').take(2).collect::<Vec<_>>().join(",")
    };
    assert_eq!(last_row("eval-50-prey.csv"), "1,20");
    // The file now asks for 3 episodes of each evaluation: the 2-episode files are not aggregated under
    // the new spec (one line naming a file), and the runner evaluates again, training nothing.
    let edited = TINY.replace("episodes: 2, steps: 20", "episodes: 3, steps: 20");
    std::fs::write(dir.path().join("experiments/tiny.ron"), edited).unwrap();
    let stderr = refused(dir.path(), &["--plot", "results/tiny"]);
    assert!(stderr.contains("holds 2 episodes of 20 steps, the evaluation \"50 prey\" asks for 3 of 20"), "{stderr}");
    // `--plot all` still reports every experiment: this one from its committed summary, saying why.
    let summary = std::fs::read(dir.path().join("results/tiny/summary.csv")).unwrap();
    let out = coevo(dir.path(), &["--plot", "all"]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(stderr.contains("asks for 3 of 20; run `coevo --experiment experiments/tiny.ron` to redo it (reported from the committed summary)"), "{stderr}");
    assert_eq!(std::fs::read(dir.path().join("results/tiny/summary.csv")).unwrap(), summary);
    let out = coevo(dir.path(), &["--experiment", "experiments/tiny.ron", "--jobs", "2"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert_eq!(last_row("eval-50-prey.csv"), "2,20");
    assert_eq!(last_row("eval-50-prey-blind.csv"), "2,20");
    assert_eq!(std::fs::metadata(run.join("metrics.csv")).unwrap().modified().unwrap(), trained);
    // Training extended by a file that asks for more episodes: the runs resume without the replay buffers
    // the runner dropped, and the runner passes on the child's warning that they differ from uninterrupted
    // runs (the child succeeds, so its other output stays quiet).
    let longer =
        TINY.replace("episodes: 2, steps: 20", "episodes: 3, steps: 20").replacen("episodes: 3,", "episodes: 4,", 1);
    std::fs::write(dir.path().join("experiments/tiny.ron"), longer).unwrap();
    let out = coevo(dir.path(), &["--experiment", "experiments/tiny.ron", "--jobs", "1"]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert_eq!(stderr.matches("coevo: warning: ").count(), 4, "{stderr}");
    assert!(stderr.contains("lacks replay buffers") && !stderr.contains("coevo: trained"), "{stderr}");
}

/// Copies `from` into `to`, leaving out run folders (`seed*`) and Slurm scripts, which a clone lacks.
fn copy_as_cloned(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for entry in std::fs::read_dir(from).unwrap().map(|e| e.unwrap()) {
        let name = entry.file_name().to_string_lossy().into_owned();
        let path = entry.path();
        if path.is_dir() {
            if !name.starts_with("seed") && name != "slurm" {
                copy_as_cloned(&path, &to.join(&name));
            }
        } else if !name.ends_with(".png") {
            // PNGs are not committed (.gitignore): `--plot` writes them beside the SVGs.
            std::fs::copy(&path, to.join(&name)).unwrap();
        }
    }
}

#[test]
fn the_committed_results_are_what_plot_all_regenerates_from_them() {
    // The project's own results as a clone has them: `--plot all` recomputes every REPORT.md and
    // REPRODUCTION.md from the committed summaries and redraws the figures from the committed figure data,
    // and every file comes out byte for byte as committed (so nothing committed is stale or hand-edited).
    let dir = tempfile::tempdir().unwrap();
    for folder in ["experiments", "scenes", "results"] {
        copy_as_cloned(Path::new(folder), &dir.path().join(folder));
    }
    std::fs::copy("REPRODUCTION.md", dir.path().join("REPRODUCTION.md")).unwrap();
    // The book's page of the paper's claims, written where the book is.
    let book_page = coevo::experiment::paper_table::BOOK_PAGE;
    std::fs::create_dir_all(dir.path().join(book_page).parent().unwrap()).unwrap();
    std::fs::write(dir.path().join(book_page), "stale").unwrap();
    let committed = files_under(&dir.path().join("results"));
    // The figures of every experiment with figure data go, so they must be redrawn. (An experiment still in
    // progress has figure data and no figure, so no committed `figures/`: a clean clone has no such folder.)
    let mut redrawn = 0;
    for experiment in std::fs::read_dir(dir.path().join("results")).unwrap().map(|e| e.unwrap().path()) {
        if experiment.join("figure-data.ron.gz").exists() {
            if experiment.join("figures").exists() {
                std::fs::remove_dir_all(experiment.join("figures")).unwrap();
            }
            redrawn += 1;
        }
    }
    assert!(redrawn >= 3, "experiments with figure data: {redrawn}");
    let out = coevo(dir.path(), &["--plot", "all"]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert_eq!(stderr.matches("from the committed summary.csv and figure-data.ron.gz").count(), redrawn, "{stderr}");
    let reproduction = std::fs::read_to_string(dir.path().join("REPRODUCTION.md")).unwrap();
    assert!(
        reproduction == std::fs::read_to_string("REPRODUCTION.md").unwrap(),
        "REPRODUCTION.md is not what `coevo --plot all` makes of the committed results: run it and commit"
    );
    assert!(
        std::fs::read_to_string(dir.path().join(book_page)).unwrap() == std::fs::read_to_string(book_page).unwrap(),
        "{book_page} is not what `coevo --plot all` makes of the committed results: run it and commit"
    );
    let mut regenerated = files_under(&dir.path().join("results"));
    regenerated.retain(|f, _| f.extension().is_none_or(|e| e != "png"));
    let differing: Vec<_> = regenerated.keys().filter(|f| committed.get(*f) != regenerated.get(*f)).collect();
    assert!(differing.is_empty(), "regenerated differently from the committed results: {differing:?}");
    assert_eq!(regenerated.len(), committed.len(), "no file added or removed");
}

#[test]
fn every_committed_mean_rederives_from_its_summary() {
    // summary-mean.csv is written from the summary's rows (so that runs carried from another machine count
    // as the folders here do): every line of each committed summary-mean.csv, written from run folders,
    // comes out of the committed summary.csv to the byte.
    let mut checked = 0;
    for file in Experiment::files(Path::new("experiments")).unwrap() {
        let exp = Experiment::load(&file, Path::new("results")).unwrap();
        let Ok(committed) = std::fs::read_to_string(exp.root.join("summary-mean.csv")) else { continue };
        let table = coevo::claims::summary::Summary::read(&exp.root.join("summary.csv")).unwrap().unwrap();
        let means = coevo::claims::summary::means_text(&exp, &table, &coevo::claims::summary::columns(&exp));
        if coevo::experiment::aggregate::in_progress(&exp, &table) {
            assert_eq!(
                committed, "preset,variant,quantity,seeds,mean,ci95\n",
                "{}: no mean while in progress",
                exp.name
            );
            continue;
        }
        let derived: std::collections::BTreeSet<&str> = means.lines().collect();
        for line in committed.lines() {
            assert!(derived.contains(line), "{}: {line} is not what its summary gives", exp.name);
            checked += 1;
        }
        // Summaries written before the curve columns gained them later (from the committed figure data),
        // and their means were written without those lines: every other line must be there.
        let curves: Vec<String> = coevo::claims::summary::curve_columns().into_iter().map(|(c, _)| c).collect();
        let extra: Vec<&&str> = derived
            .iter()
            .filter(|l| !committed.lines().any(|c| c == **l) && !curves.iter().any(|c| l.contains(&format!(",{c},"))))
            .collect();
        assert!(extra.is_empty(), "{}: lines its summary-mean.csv lacks: {extra:?}", exp.name);
    }
    assert!(checked > 1000, "{checked} lines");
}

#[test]
fn an_experiment_distills_its_runs_and_deploys_the_rules_with_their_ablations() {
    let dir = workspace();
    let text = TINY
        .replace(
            "(name: \"50 prey, blind\",",
            "(name: \"50 prey, distilled prey\", counts: [(\"prey\", 50)], episodes: 2, steps: 20, distilled: [(species: \"prey\")]),\n        \
             (name: \"50 prey, distilled prey without alignment\", counts: [(\"prey\", 50)], episodes: 2, steps: 20, distilled: [(species: \"prey\", without: [Alignment])]),\n        \
             (name: \"50 prey, inertial distilled\", counts: [(\"prey\", 50)], episodes: 2, steps: 20, distilled: [(species: \"prey\", form: Inertial), (species: \"predator\", form: Inertial)]),\n        \
             (name: \"50 prey, binned alignment alone\", counts: [(\"prey\", 50)], episodes: 2, steps: 20, distilled: [(species: \"prey\", form: Binned, without: [Repulsion, Attraction, Evasion])]),\n        \
             (name: \"50 prey, blind\",",
        )
        .replace(
            "    claims: [",
            "    distill: (counts: [(\"prey\", 20)], episodes: 2, steps: 20, forms: [Memoryless, Inertial, Binned]),\n    claims: [",
        )
        .replace(
            "(text: \"catches\",",
            "(text: \"distilled minus learned\", variant: \"5:3\", quantity: EvalDifference(\"50 prey, distilled prey\", \"50 prey\", \"doa\"), margin: 0.05),\n        \
             (text: \"the fitted alignment gain\", variant: \"5:3\", quantity: Distilled(\"prey\", Memoryless, \"turn.alignment\")),\n        \
             (text: \"binned minus zonal\", variant: \"5:3\", quantity: DistilledDifference(\"prey\", Binned, Memoryless, \"explained_turn\"), paper: 1.0, direction_only: true, ours: true),\n        \
             (text: \"catches\",",
        );
    std::fs::write(dir.path().join("experiments/tiny.ron"), &text).unwrap();
    let out = coevo(dir.path(), &["--experiment", "experiments/tiny.ron", "--jobs", "2"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let run = dir.path().join("results/tiny/paper/5-3/seed1");
    let fitted = coevo::analysis::distill::DistilledFile::read(&run.join("distilled.ron")).unwrap();
    assert_eq!(
        (fitted.counts.iter().find(|(s, _)| s == "prey").unwrap().1, fitted.episodes, fitted.steps),
        (20, 2, 20)
    );
    assert_eq!(fitted.species.len(), 5, "prey and predators, memoryless and inertial; prey binned");
    // The distilled evaluation ran the fitted rule: its file names it, and it differs from the learned prey.
    for name in ["distilled-prey", "distilled-prey-without-alignment", "inertial-distilled", "binned-alignment-alone"] {
        assert!(run.join(format!("eval-50-prey-{name}.csv")).exists(), "{name}");
    }
    let summary = std::fs::read_to_string(dir.path().join("results/tiny/summary.csv")).unwrap();
    let header: Vec<&str> = summary.lines().next().unwrap().split(',').collect();
    for column in [
        "distilled_prey_memoryless_turn_alignment",
        "distilled_predator_inertial_persistence",
        "distilled_prey_inertial_explained_turn",
        "distilled_prey_binned_turn_kin[0]",
        "distilled_prey_binned_turn_alignment_held_out",
    ] {
        let at = header.iter().position(|h| *h == column).unwrap_or_else(|| panic!("a column {column}"));
        for row in summary.lines().skip(1) {
            assert!(row.split(',').nth(at).unwrap().parse::<f64>().unwrap().is_finite(), "{column}: {row}");
        }
    }
    let md = std::fs::read_to_string(dir.path().join("results/tiny/REPORT.md")).unwrap();
    assert!(md.contains("doa in evaluation \"50 prey, distilled prey\" minus in \"50 prey\""), "{md}");
    assert!(md.contains("turn.alignment of the Memoryless rule fitted to the prey"), "{md}");
    assert!(md.contains("explained_turn of the Binned rule fitted to the prey minus of the Memoryless one"), "{md}");
    // An edited distill: fits the rules again and runs again the evaluations that deploy them, as an
    // edited evaluation is run again; the other evaluations stay as they were.
    let learned = std::fs::read(run.join("eval-50-prey.csv")).unwrap();
    let edited = text.replace(
        "distill: (counts: [(\"prey\", 20)], episodes: 2, steps: 20,",
        "distill: (counts: [(\"prey\", 20)], episodes: 2, steps: 16,",
    );
    assert_ne!(edited, text);
    std::fs::write(dir.path().join("experiments/tiny.ron"), &edited).unwrap();
    let out = coevo(dir.path(), &["--experiment", "experiments/tiny.ron", "--jobs", "2"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let fitted = coevo::analysis::distill::DistilledFile::read(&run.join("distilled.ron")).unwrap();
    assert_eq!(fitted.steps, 16, "fitted again on the edited distill:");
    assert_eq!(
        std::fs::read(run.join("eval-50-prey.csv")).unwrap(),
        learned,
        "an evaluation without fitted rules is kept"
    );
    std::fs::write(dir.path().join("experiments/tiny.ron"), &text).unwrap();
    let out = coevo(dir.path(), &["--experiment", "experiments/tiny.ron", "--jobs", "2"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    redrawn_without_run_folders(dir.path());
    // Deploying fitted rules needs the fit; an ablation needs a zonal rule; a number must be one a rule has,
    // of a species a rule is fitted to; an evaluation deploys one rule per species.
    for (from, to, says) in [
        (
            "    distill: (counts: [(\"prey\", 20)], episodes: 2, steps: 20, forms: [Memoryless, Inertial, Binned]),\n",
            "",
            "needs distill:",
        ),
        ("forms: [Memoryless, Inertial, Binned]", "forms: [Memoryless, Inertial]", "form Binned is not read"),
        ("Binned, Memoryless, \"explained_turn\"", "Binned, Binned, \"explained_turn\"", "compares a form with itself"),
        ("(species: \"prey\", without: [Alignment])", "(species: \"predator\", without: [Alignment])", "has none"),
        ("\"turn.alignment\"", "\"turn.nope\"", "no number named \"turn.nope\""),
        (
            "Distilled(\"prey\", Memoryless, \"turn.alignment\")",
            "Distilled(\"wolf\", Memoryless, \"turn.alignment\")",
            "no Memoryless rule is read of \"wolf\"",
        ),
        (
            "Distilled(\"prey\", Memoryless, \"turn.alignment\")",
            "Distilled(\"predator\", Memoryless, \"turn.alignment\")",
            "has no such number",
        ),
        ("distilled: [(species: \"prey\")]", "distilled: [(species: \"wolf\")]", "no species named \"wolf\""),
        (
            "distilled: [(species: \"prey\")]",
            "distilled: [(species: \"prey\"), (species: \"prey\", form: Inertial)]",
            "listed twice",
        ),
        ("without: [Alignment]", "without: [Alignment, Alignment]", "lists Alignment twice"),
    ] {
        let bad = text.replace(from, to);
        assert_ne!(bad, text);
        std::fs::write(dir.path().join("experiments/bad.ron"), bad).unwrap();
        let stderr = refused(dir.path(), &["--experiment", "experiments/bad.ron"]);
        assert!(stderr.contains(says), "{stderr}");
    }
}

/// A pinned experiment (`results/NAME/binary/pin.ron`) is continued only by a build that reproduces the
/// pin's fingerprint; such a build is then recorded among the pin's rebuilds, and its runs are the pin's.
#[test]
fn a_pinned_experiment_runs_only_with_a_build_that_reproduces_its_fingerprint() {
    // The fingerprint is of the AVX2-FMA kernels' numbers: elsewhere there is nothing to compare with.
    #[cfg(target_arch = "x86_64")]
    let fma = std::arch::is_x86_feature_detected!("fma");
    #[cfg(not(target_arch = "x86_64"))]
    let fma = false;
    if !fma {
        eprintln!("skipped: the pinned fingerprint is of the AVX2-FMA kernels, which this machine lacks");
        return;
    }
    let one_run = r#"(
    base: "scenes/paper.ron",
    seeds: [1],
    episodes: 2,
    variants: [(name: "1:1", patch: (episode_steps: 30, learning: (hidden: 16, batch_size: 32, warmup_transitions: 32, updates_per_episode: 3)))],
    evaluations: [(name: "50 prey", counts: [("prey", 50)], episodes: 1, steps: 20)],
)"#;
    let dir = workspace_with("tiny", one_run);
    let root = dir.path();
    // Pinned to the commit this test's coevo was built from, named in full as a pin names it; the
    // workspace is made part of this clone (a `.git` file pointing at its repository), as an experiment
    // is run inside one.
    let built = coevo::GIT_COMMIT.trim_end_matches("-dirty");
    let repo = Path::new(env!("CARGO_MANIFEST_DIR"));
    let git = |args: &[&str]| Command::new("git").arg("-C").arg(repo).args(args).output().unwrap();
    let commit = String::from_utf8(git(&["rev-parse", "--verify", &format!("{built}^{{commit}}")]).stdout).unwrap();
    let commit = commit.trim();
    if commit.len() != 40 {
        eprintln!("skipped: this coevo was not built from a git checkout ({built})");
        return;
    }
    let git_dir = String::from_utf8(git(&["rev-parse", "--absolute-git-dir"]).stdout).unwrap();
    std::fs::write(root.join(".git"), format!("gitdir: {}\n", git_dir.trim())).unwrap();
    let pin = |fingerprint: &str| {
        format!(
            "(commit: \"{commit}\", blake3: \"0000000000000000\", toolchain: \"rustc\", cargo_lock: \"0\", kernels: \"avx2-fma\", fingerprint: \"{fingerprint}\")"
        )
    };
    let pin_file = root.join("results/tiny/binary/pin.ron");
    std::fs::create_dir_all(pin_file.parent().unwrap()).unwrap();
    let me = env!("CARGO_BIN_EXE_coevo");
    let args = ["--experiment", "experiments/tiny.ron", "--pinned-binary", me, "--quiet"];
    // An experiment without a pin takes no pinned binary.
    let err = refused(root, &args);
    assert!(err.contains("--pinned-binary: experiments/tiny.ron is not pinned"), "{err}");

    // A pin whose commit is abbreviated, or is no commit of this repository, is refused before anything
    // is built or copied; so is a pinned binary that is not a regular executable program.
    std::fs::write(&pin_file, pin("2eee7e2b9b23e15b").replace(commit, &commit[..12])).unwrap();
    let err = refused(root, &args);
    assert!(err.contains("pin.ron") && err.contains("is not a commit's full name"), "{err}");
    std::fs::write(&pin_file, pin("2eee7e2b9b23e15b").replace(commit, &"0123456789".repeat(4))).unwrap();
    let err = refused(root, &args);
    assert!(err.contains("pin.ron") && err.contains("is not a commit of this repository"), "{err}");
    assert!(!root.join("target/pinned").exists(), "something was built or copied for a pin of no commit");
    std::fs::write(&pin_file, pin("2eee7e2b9b23e15b")).unwrap();
    let fifo = root.join("fifo");
    assert!(Command::new("mkfifo").arg(&fifo).status().unwrap().success());
    let script = root.join("script");
    std::fs::write(&script, "#!/bin/sh\necho coevo\n").unwrap();
    std::fs::set_permissions(&script, std::os::unix::fs::PermissionsExt::from_mode(0o755)).unwrap();
    let link = root.join("link");
    std::os::unix::fs::symlink(me, &link).unwrap();
    for (given, says) in [(&fifo, "is not a regular file"), (&script, "no ELF header"), (&link, "is a symbolic link")] {
        let given = given.to_str().unwrap();
        let err = refused(root, &["--experiment", "experiments/tiny.ron", "--pinned-binary", given, "--quiet"]);
        assert!(err.contains(given) && err.contains(says), "{err}");
    }
    assert!(std::fs::read_dir(root.join("target/pinned")).map_or(true, |mut d| d.next().is_none()), "a copy was left");

    // A build that computes other numbers than the pinned binary is refused, before any run; so is a build
    // of uncommitted changes (when this test's coevo is one, nothing else can be checked here).
    std::fs::write(&pin_file, pin("ffffffffffffffff")).unwrap();
    let err = refused(root, &args);
    let expected = match coevo::GIT_COMMIT.ends_with("-dirty") {
        true => format!("it is a build of {}, not a clean build of the pinned commit {commit}", coevo::GIT_COMMIT),
        false => "it gives fingerprint 2eee7e2b9b23e15b where the pin says ffffffffffffffff".to_string(),
    };
    assert!(err.contains("results/tiny/binary/pin.ron") && err.contains(&expected), "{err}");
    assert!(!root.join("results/tiny/paper").exists(), "a run started with a refused binary");
    if coevo::GIT_COMMIT.ends_with("-dirty") {
        eprintln!("the rest skipped: this coevo is a build of uncommitted changes");
        return;
    }

    // One that reproduces it makes the runs, on the pin's kernels, and is recorded as a rebuild.
    std::fs::write(&pin_file, pin("2eee7e2b9b23e15b")).unwrap();
    let out = coevo(root, &args);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(String::from_utf8_lossy(&out.stderr).contains("reproduced"));
    let recorded = coevo::claims::pin::Pin::read(&root.join("results/tiny")).unwrap().unwrap();
    assert_eq!(recorded.rebuilds.len(), 1);
    let provenance = std::fs::read_to_string(root.join("results/tiny/paper/1-1/seed1/provenance.ron")).unwrap();
    assert!(provenance.contains(&format!("binary: \"{}\"", recorded.rebuilds[0])), "{provenance}");
    // Made by the checked copy, named by its hash.
    assert!(root.join(format!("target/pinned/coevo-{commit}-{}", recorded.rebuilds[0])).is_file());
    assert!(provenance.contains("kernels: \"avx2-fma\""), "{provenance}");
    // Recorded, it continues the experiment unchecked, by itself.
    let again = coevo(root, &["--experiment", "experiments/tiny.ron", "--quiet"]);
    let said = String::from_utf8_lossy(&again.stderr);
    assert!(again.status.success() && !said.contains("reproduced") && !said.contains("building"), "{said}");
}

/// A grid of 3 × 2 cells over the tiny runs: one axis a scene number by its path, the other levels with
/// patches (each with the tiny runs' learning settings), beside one listed variant.
const GRID: &str = r#"(
    description: "a tiny grid",
    base: "scenes/paper.ron",
    seeds: [1, 2],
    episodes: 3,
    grid: [
        (name: "prey speed", path: "species.prey.max_speed", values: [0.1, 0.3, 0.5]),
        (name: "predators", levels: [
            (label: "two", value: 2.0, patch: (species: [(name: "predator", count: 2)], episode_steps: 30, learning: (hidden: 16, batch_size: 32, warmup_transitions: 32, updates_per_episode: 3, checkpoint_every: 1))),
            (label: "three", value: 3.0, patch: (episode_steps: 30, learning: (hidden: 16, batch_size: 32, warmup_transitions: 32, updates_per_episode: 3, checkpoint_every: 1))),
        ]),
    ],
    variants: [
        (name: "slow prey", patch: (episode_steps: 30, species: [(name: "prey", max_speed: 0.2)], learning: (hidden: 16, batch_size: 32, warmup_transitions: 32, updates_per_episode: 3, checkpoint_every: 1))),
    ],
    evaluations: [
        (name: "50 prey", counts: [("prey", 50)], episodes: 2, steps: 20),
        (name: "50 prey, blind", counts: [("prey", 50)], episodes: 2, steps: 20, control: Blind),
        (name: "20 prey, one density", counts: [("prey", 20)], arena_edge: 1.5, episodes: 2, steps: 20),
        (name: "40 prey, one density", counts: [("prey", 40)], arena_edge: 2.5, episodes: 2, steps: 20),
    ],
    claims: [
        (text: "trend of DoA along prey speed", quantity: EvalDoa("50 prey"), grid: Trend(axis: "prey speed", at: "three")),
        (text: "where seeing minus blind crosses 0", quantity: InteractionDoa("50 prey, blind"), grid: Boundary(axis: "prey speed", crosses: 0.0, at: "three")),
        (text: "its shift with predators", quantity: InteractionDoa("50 prey, blind"), grid: BoundaryShift(axis: "prey speed", crosses: 0.0)),
    ],
)"#;

#[test]
fn a_grid_experiment_runs_its_cells_judges_a_trend_and_a_boundary_and_draws_its_map() {
    // Every cell trains as short as the listed variant: each level of "predators" carries the same patch.
    let dir = workspace_with("grid", GRID);
    let out = coevo(dir.path(), &["--experiment", "experiments/grid.ron", "--jobs", "2"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let results = dir.path().join("results/grid");
    // 1 listed variant + 3 × 2 cells, named by their levels' labels, at 2 seeds.
    let summary = std::fs::read_to_string(results.join("summary.csv")).unwrap();
    assert_eq!(summary.lines().count(), 1 + 7 * 2, "{summary}");
    assert!(summary.contains("paper,\"0.1, two\",2,"), "{summary}");
    let scene = std::fs::read_to_string(results.join("paper/0.1-two/scene.ron")).unwrap();
    assert!(scene.contains("max_speed: 0.1") && scene.contains("count: 2"), "both levels' patches: {scene}");
    let md = std::fs::read_to_string(results.join("REPORT.md")).unwrap();
    for claim in ["trend of DoA along prey speed", "where seeing minus blind crosses 0", "its shift with predators"] {
        let row = md.lines().find(|l| l.contains(claim)).unwrap_or_else(|| panic!("no row for {claim:?}: {md}"));
        assert!(!row.contains("not run yet"), "judged: {row}");
    }
    let trend = md.lines().find(|l| l.contains("trend of DoA along prey speed")).unwrap();
    assert!(trend.contains("least-squares slope") && trend.contains("α = 0.05/"), "{trend}");
    let boundary = md.lines().find(|l| l.contains("where seeing minus blind crosses 0")).unwrap();
    assert!(boundary.contains("a crossing of 0 within the axis") && boundary.contains("bootstrap"), "{boundary}");
    // A group-size series (evaluations that set arena_edge): catches per prey for each, and its figure.
    let header: Vec<&str> = summary.lines().next().unwrap().split(',').collect();
    let at = header.iter().position(|h| *h == "eval_40-prey-one-density_catches_per_prey").expect("a catches column");
    let row = summary.lines().find(|l| l.starts_with("paper,slow prey,1,")).unwrap();
    let eval = std::fs::read_to_string(results.join("paper/slow-prey/seed1/eval-40-prey-one-density.csv")).unwrap();
    let column = eval.lines().next().unwrap().split(',').position(|h| h == "catches").unwrap();
    let caught: f64 = eval.lines().skip(1).map(|l| l.split(',').nth(column).unwrap().parse::<f64>().unwrap()).sum();
    let shown: f64 = row.split(',').nth(at).unwrap().parse().unwrap();
    assert!(
        (shown - caught / (2.0 * 40.0)).abs() < 1e-9,
        "{shown} against {caught} catches over 2 episodes of 40 prey"
    );
    let scene = std::fs::read_to_string(results.join("paper/slow-prey/seed1/scene.ron")).unwrap();
    assert!(scene.contains("arena_edge: 2.0"), "the run keeps its own arena: {scene}");
    for figure in ["paper-grid-map", "paper-grid-curves", "paper-group-size"] {
        assert!(results.join(format!("figures/{figure}.svg")).exists(), "{figure}");
    }
    // Judged again from the CSV files alone: the same report, to the byte.
    let before = std::fs::read(results.join("REPORT.md")).unwrap();
    let out = coevo(dir.path(), &["--plot", "results/grid"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert_eq!(std::fs::read(results.join("REPORT.md")).unwrap(), before, "a report is a function of its runs");
}

#[test]
fn a_grid_axis_naming_no_scene_field_or_a_claim_naming_no_axis_is_one_line() {
    let cases = [
        (GRID.replace("species.prey.max_speed", "species.prey.wings"), "grid[prey speed].path"),
        (GRID.replace("values: [0.1, 0.3, 0.5]", "values: [0.5, 0.3]"), "values must increase"),
        (GRID.replace("Trend(axis: \"prey speed\"", "Trend(axis: \"prey sped\""), "no grid axis named \"prey sped\""),
        (GRID.replace("crosses: 0.0, at: \"three\")", "crosses: 0.0, at: \"four\")"), "\"four\" is no level"),
        (
            GRID.replace("at: \"three\")),\n        (text: \"where", ")),\n        (text: \"where"),
            "at: must name the level",
        ),
    ];
    for (text, expected) in cases {
        let dir = workspace_with("grid", &text);
        let line = refused(dir.path(), &["--experiment", "experiments/grid.ron"]);
        assert!(line.contains("experiments/grid.ron") && line.contains(expected), "{expected:?}: {line}");
        assert!(!dir.path().join("results/grid").exists(), "nothing written before the file is whole");
    }
}

#[test]
fn a_variant_on_its_own_kernel_family_runs_on_it_and_is_held_to_it() {
    // `kernels:` puts one variant's runs on another family of matrix-product kernels (portable runs on
    // every CPU) beside the experiment's own: a comparison of families by one binary.
    let dir = workspace();
    let text = TINY.replace("(name: \"5:3\", patch: (", "(name: \"5:3\", kernels: Some(\"portable\"), patch: (");
    assert_ne!(text, TINY);
    std::fs::write(dir.path().join("experiments/tiny.ron"), &text).unwrap();
    let out = coevo(dir.path(), &["--experiment", "experiments/tiny.ron", "--jobs", "2"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let kernels = |variant: &str| {
        let p = std::fs::read_to_string(dir.path().join(format!("results/tiny/paper/{variant}/seed1/provenance.ron")));
        p.unwrap().lines().find(|l| l.trim_start().starts_with("kernels:")).unwrap().trim().to_string()
    };
    assert_eq!(kernels("5-3"), "kernels: \"portable\",");
    assert_ne!(kernels("1-1"), kernels("5-3"));
    // A family coevo does not have is refused before any run, naming the field.
    let bad = text.replace("kernels: Some(\"portable\")", "kernels: Some(\"sse9\")");
    std::fs::write(dir.path().join("experiments/bad.ron"), bad).unwrap();
    let stderr = refused(dir.path(), &["--experiment", "experiments/bad.ron"]);
    assert!(stderr.contains("bad.ron:8: kernels: \"sse9\" is no kernel family: avx512,"), "{stderr}");
}
