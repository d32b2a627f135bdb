//! The command line's own tests: argv written by the runner reads back the same, and the modes' flag
//! lists agree with the flags declared.

use super::*;
use crate::scene::{Overrides, Policy};
use std::path::PathBuf;

fn parsed(argv: Vec<String>) -> (Cli, Shared) {
    let (cli, viewer) = parse(argv).unwrap_or_else(|e| panic!("{}", one_line(&e)));
    assert!(!viewer);
    let shared = Shared { scene: cli.scene.clone(), common: cli.common.clone() };
    (cli, shared)
}

/// What the experiment runner writes as argv is what the child reads back, to the field.
#[test]
fn options_written_as_argv_read_back_the_same() {
    let eval = crate::run::evaluate::EvalOptions {
        run: PathBuf::from("results/x/a b/seed-1"),
        control: crate::learning::control::ObservationControl::parse(&["blind:prey:prey", "shuffled:predator:prey"])
            .unwrap(),
        out: Some("eval-blind.csv".into()),
        episodes: 3,
        overrides: Overrides {
            counts: vec![("prey".into(), 50), ("predator".into(), 0), ("hawk".into(), 2)],
            policies: vec![
                ("predator".into(), Policy::ChaseNearest),
                ("hawk".into(), Policy::Frozen("r \"1\"".into())),
            ],
            seed: Some(7),
            episode_steps: Some(200),
            confusion_radius: Some(0.1 + 0.2),
            arena_edge: Some(2.0 * 1.1),
        },
        untrained: false,
        snapshots: vec![("prey".into(), 300)],
        perturb: Some(-0.3),
        perturb_step: Some(99),
    };
    let (cli, shared) = parsed(eval.to_argv());
    assert_eq!(cli.eval.options(cli.eval.eval.as_ref().unwrap(), &shared).unwrap(), eval);
    let untrained = crate::run::evaluate::EvalOptions {
        untrained: true,
        snapshots: vec![],
        overrides: Overrides { seed: None, ..eval.overrides.clone() },
        ..eval.clone()
    };
    let (cli, shared) = parsed(untrained.to_argv());
    assert_eq!(cli.eval.options(cli.eval.eval.as_ref().unwrap(), &shared).unwrap(), untrained);

    let cross = crossplay::CrossplayOptions {
        run: PathBuf::from("runs/r"),
        episodes: 4,
        overrides: Overrides {
            counts: vec![("prey".into(), 20)],
            seed: Some(3),
            episode_steps: Some(50),
            ..Default::default()
        },
        progress: false,
    };
    let (cli, shared) = parsed(cross.to_argv());
    assert_eq!(cli.crossplay.options(cli.crossplay.crossplay.as_ref().unwrap(), &shared).unwrap(), cross);

    let resume =
        train::TrainOptions { run: PathBuf::from("runs/r"), overwrite: false, episodes: Some(2000), progress: false };
    let (cli, shared) = parsed(resume.to_argv(train::StartArgs::Resume));
    assert_eq!(cli.resume.options(cli.resume.resume.as_ref().unwrap(), &shared), resume);
    let fresh =
        train::TrainOptions { run: PathBuf::from("runs/new"), overwrite: true, episodes: None, progress: false };
    let (cli, shared) =
        parsed(fresh.to_argv(train::StartArgs::New { scene: std::path::Path::new("scenes/standard.ron"), seed: 11 }));
    assert_eq!((cli.scene.scene.clone(), cli.scene.seed), (Some(PathBuf::from("scenes/standard.ron")), Some(11)));
    let (scene, opts) = cli.train.options(&shared).unwrap();
    assert_eq!((scene.seed, opts), (11, fresh));
}

/// Every flag a mode says it takes exists, and every flag but the process-wide ones is taken by some
/// mode (a flag nobody takes would be refused by every call).
#[test]
fn every_flag_is_taken_and_every_taken_flag_exists() {
    let command = command();
    let ids: Vec<String> = command.get_arguments().map(|a| a.get_id().to_string()).collect();
    let modes = modes();
    for (mode, takes) in &modes {
        for flag in takes {
            assert!(ids.contains(flag), "mode {mode:?} takes --{flag}, which no struct declares");
        }
    }
    for id in ids.iter().filter(|id| !["threads", "kernels", "help", "version"].contains(&id.as_str())) {
        assert!(modes.iter().any(|(m, takes)| m == id || takes.contains(id)), "no mode takes --{id}");
    }
}
