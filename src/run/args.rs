//! The command-line flags several modes share, and how a mode's arguments are declared.
//!
//! coevo keeps one flat surface (`coevo --train`, `coevo --eval RUN`: one mode flag per call). Each mode
//! owns a clap [`Args`](clap::Args) struct in its own module (`run/train.rs`, `run/evaluate.rs`, …) with
//! its mode flag and the flags only it takes; it names, in [`Mode::TAKES`], which flags of [`SceneArgs`]
//! and [`CommonArgs`] (or of another mode) it takes too. `cli.rs` flattens them all into one command and
//! refuses a flag the chosen mode does not take. A mode's arguments become its typed options there, and
//! the options write themselves back as argv (`to_argv`) for the experiment runner's children, so no
//! flag is spelled outside its owner.

use crate::error::ResultExt;
use crate::scene::{Overrides, Scene};
use clap::Args;
use std::path::{Path, PathBuf};

/// A mode's own arguments: its mode flag (`MODE`, the clap id; "" for the viewer, the call without one)
/// and the flags declared elsewhere that it takes besides its own, `--threads` and `--kernels`.
pub(crate) trait Mode: Args {
    const MODE: &'static str;
    const TAKES: &'static [&'static str];
}

/// Which scene a call runs and what it changes of it.
#[derive(Args, Debug, Clone, Default)]
pub(crate) struct SceneArgs {
    /// Scene file to run [default: scenes/standard.ron]; the shipped scenes/*.ron are built in, so they
    /// load from any folder (a file of that name in the working folder wins).
    #[arg(long, help_heading = "Scene", value_name = "PATH")]
    pub(crate) scene: Option<PathBuf>,
    /// Override the scene's random seed.
    #[arg(long, help_heading = "Scene", value_name = "S")]
    pub(crate) seed: Option<u64>,
    /// Steps to simulate (--record) or per episode (--eval).
    #[arg(long, help_heading = "Scene", value_name = "N", value_parser = at_least_one)]
    pub(crate) steps: Option<usize>,
    /// Number of prey (--eval, --record, viewer; the paper evaluates on 50).
    #[arg(long, help_heading = "Scene", value_name = "N")]
    pub(crate) prey: Option<usize>,
    /// Number of predators (--eval, --record, viewer; 0 removes them, as in the paper's Fig. 5a).
    #[arg(long, help_heading = "Scene", value_name = "N")]
    pub(crate) predators: Option<usize>,
    /// Any species' count, as NAME=N (repeatable; --eval, --record, viewer).
    #[arg(long, help_heading = "Scene", value_name = "NAME=N")]
    pub(crate) count: Vec<String>,
    /// A species' policy, as NAME=POLICY with POLICY as a scene file writes it: ChaseNearest, FleeNearest,
    /// FleeInside, Random, Still, Frozen("RUN"), a rule --distill fitted, Zonal((...)), Binned((...)) or Pursuit((...)), or a
    /// classic model, Vicsek((radius: R, noise: ETA)) or Couzin((repulsion_radius: .., orientation_width: ..,
    /// attraction_width: .., noise: SIGMA))
    /// (repeatable; --eval, --record, --animate, --describe-scene), e.g. --policy predator=ChaseNearest
    /// evaluates trained prey against the paper's rule-based predators.
    #[arg(long, help_heading = "Scene", value_name = "NAME=POLICY")]
    pub(crate) policy: Vec<String>,
    /// Deploy a species' snapshot instead of its trained actor, as NAME=EPISODE (repeatable; --eval,
    /// --record and --animate with --run, viewer with --watch), e.g. --snapshot prey=300.
    #[arg(long, help_heading = "Scene", value_name = "NAME=EPISODE")]
    pub(crate) snapshot: Vec<String>,
}

/// Flags of how a call runs rather than what it runs.
#[derive(Args, Debug, Clone, Default)]
pub(crate) struct CommonArgs {
    /// Episodes of the training run (default: the scene's `episodes`) or of the evaluation (default 1).
    #[arg(long, help_heading = "Running", value_name = "N")]
    pub(crate) episodes: Option<usize>,
    /// --train into a folder that holds a run, or --record/--animate/--screenshot over an existing file:
    /// replace it (coevo's own files only).
    #[arg(long, help_heading = "Running")]
    pub(crate) overwrite: bool,
    /// No progress bar (--train, --resume, --crossplay, --animate, --experiment), and no explanation at the
    /// end of --train and --resume (which goes to stdout otherwise; progress and errors to stderr).
    #[arg(long, help_heading = "Running")]
    pub(crate) quiet: bool,
    /// Worker threads (default: COEVO_THREADS, else all cores). Results never depend on it.
    #[arg(long, help_heading = "Running", value_name = "N", value_parser = at_least_one)]
    pub(crate) threads: Option<usize>,
    /// Matrix-product kernels: auto, avx512, avx512-direct, avx512-bf16, avx2 or portable (default:
    /// COEVO_KERNELS, else auto: gemm's, AVX-512 where the CPU has it). Pin one family so CPUs with and
    /// without AVX-512 compute identical runs; avx512-direct is coevo's own AVX-512 products, avx512-bf16
    /// the same with operands rounded to bfloat16 and f32 sums (AVX512-BF16 CPUs; never chosen by auto;
    /// see Benchmarks).
    #[arg(long, help_heading = "Running", value_name = "FAMILY")]
    pub(crate) kernels: Option<String>,
}

impl CommonArgs {
    /// Sets what is process-wide: the worker threads, and the matrix-product kernels (--kernels, else
    /// COEVO_KERNELS) before any network exists, since gemm fixes its kernels at its first product.
    pub(crate) fn apply_to_process(&self) -> crate::error::Result<()> {
        // Each environment variable is read as its flag is, and refused as its flag would be.
        match (self.threads, environment("COEVO_THREADS")?) {
            (Some(n), _) => crate::parallel::set_threads(n),
            (None, Some(text)) => {
                crate::parallel::set_threads(at_least_one(&text).map_err(|e| format!("COEVO_THREADS: {e}"))?)
            }
            (None, None) => {}
        }
        let pin = |text: &str| text.parse().and_then(crate::learning::nets::pin_kernels);
        match (&self.kernels, environment("COEVO_KERNELS")?) {
            (Some(family), _) => pin(family).map_err(|e| format!("--kernels: {e}"))?,
            (None, Some(family)) => pin(&family).map_err(|e| format!("COEVO_KERNELS: {e}"))?,
            (None, None) => {}
        }
        Ok(())
    }

    /// The existing-file rule of --overwrite.
    pub(crate) fn existing(&self) -> crate::io::Existing {
        if self.overwrite {
            crate::io::Existing::Replace
        } else {
            crate::io::Existing::Refuse
        }
    }
}

/// The flags of [`SceneArgs`] and [`CommonArgs`] as a call gave them, handed to every mode.
#[derive(Debug, Clone, Default)]
pub(crate) struct Shared {
    pub(crate) scene: SceneArgs,
    pub(crate) common: CommonArgs,
}

/// A child process's worker threads, as argv (the experiment runner's children).
pub(crate) fn threads_argv(threads: usize) -> Vec<String> {
    vec!["--threads".into(), threads.to_string()]
}

/// clap's parser of a count that must be ≥ 1.
/// An environment variable coevo reads: None where it is unset, an error where it is not UTF-8.
pub(crate) fn environment(name: &str) -> crate::error::Result<Option<String>> {
    match std::env::var(name) {
        Ok(text) => Ok(Some(text)),
        Err(std::env::VarError::NotPresent) => Ok(None),
        Err(std::env::VarError::NotUnicode(raw)) => {
            Err(format!("{name}: {:?} is not valid UTF-8", raw.to_string_lossy()).into())
        }
    }
}

pub(crate) fn at_least_one(text: &str) -> Result<usize, String> {
    match text.parse::<usize>() {
        Ok(0) => Err("must be ≥ 1".into()),
        Ok(n) => Ok(n),
        Err(_) => Err(format!("{text:?} is not a count")),
    }
}

impl SceneArgs {
    /// What the call changes of the scene it loads: --prey, --predators and --count (in that order),
    /// --seed, and --steps per episode when `steps` (--eval; --record and --animate run --steps as one
    /// episode).
    pub(crate) fn overrides(&self, steps: bool) -> crate::error::Result<Overrides> {
        let mut counts: Vec<(String, usize)> = self.prey.map(|n| ("prey".to_string(), n)).into_iter().collect();
        counts.extend(self.predators.map(|n| ("predator".to_string(), n)));
        for c in &self.count {
            let (name, n) = c.split_once('=').ok_or_else(|| format!("--count {c}: expected NAME=N"))?;
            counts.push((name.to_string(), n.parse().map_err(|_| format!("--count {c}: {n} is not a count"))?));
        }
        let mut policies = vec![];
        for p in &self.policy {
            let (name, policy) = p.split_once('=').ok_or_else(|| format!("--policy {p}: expected NAME=POLICY"))?;
            let policy = ron::from_str(policy).map_err(|_| {
                format!("--policy {p}: {policy} is not a policy (ChaseNearest, FleeNearest, FleeInside, Random, Still, Frozen(\"RUN\"), Zonal((...)), Binned((...)), Pursuit((...)), Vicsek((...)), Couzin((...)), Learned)")
            })?;
            policies.push((name.to_string(), policy));
        }
        Ok(Overrides {
            counts,
            policies,
            seed: self.seed,
            episode_steps: if steps { self.steps } else { None },
            confusion_radius: None,
            arena_edge: None,
        })
    }

    /// The --snapshot requests (NAME=EPISODE); they need a run whose snapshots to deploy (`run`, given
    /// with the flag `what`).
    pub(crate) fn snapshots(&self, run: Option<&Path>, what: &str) -> crate::error::Result<Vec<(String, usize)>> {
        if !self.snapshot.is_empty() && run.is_none() {
            return Err(format!("--snapshot: deploys a run's snapshots; give the run with {what}").into());
        }
        self.snapshot
            .iter()
            .map(|text| {
                let (name, episode) = text
                    .split_once('=')
                    .ok_or_else(|| format!("--snapshot {text}: expected NAME=EPISODE, e.g. prey=300"))?;
                let episode = episode
                    .parse()
                    .map_err(|_| format!("--snapshot {text}: {episode:?} is not a number of episodes"))?;
                Ok((name.to_string(), episode))
            })
            .collect()
    }

    /// The scene file of the call (--scene, else `default`) with `overrides` applied and validated. The
    /// default scene is built into the binary too, so a call without --scene works outside the clone (a
    /// `scenes/standard.ron` in the working folder still wins).
    pub(crate) fn load(&self, default: &Path, overrides: &Overrides) -> crate::error::Result<(Scene, PathBuf)> {
        let path = self.scene.clone().unwrap_or_else(|| default.to_path_buf());
        Ok((load_scene(&path, overrides)?, path))
    }
}

/// `overrides` and `snapshots` as the flags that ask for them: counts as --count (applied in order, as
/// --prey and --predators are), the seed, --steps per episode (the modes that take it per episode). The
/// confusion radius is --eval's own flag ([`super::evaluate::EvalOptions::to_argv`]).
pub(crate) fn overrides_argv(overrides: &Overrides, snapshots: &[(String, usize)]) -> Vec<String> {
    let mut argv = vec![];
    let mut flag = |name: &str, value: String| argv.extend([name.to_string(), value]);
    if let Some(seed) = overrides.seed {
        flag("--seed", seed.to_string());
    }
    if let Some(steps) = overrides.episode_steps {
        flag("--steps", steps.to_string());
    }
    for (species, n) in &overrides.counts {
        flag("--count", format!("{species}={n}"));
    }
    for (species, policy) in &overrides.policies {
        flag("--policy", format!("{species}={}", ron::to_string(policy).expect("a policy always serializes")));
    }
    for (species, episode) in snapshots {
        flag("--snapshot", format!("{species}={episode}"));
    }
    argv
}

/// `--describe-scene FILE`.
#[derive(Args, Debug, Clone, Default)]
pub(crate) struct DescribeArgs {
    /// Print a scene as the simulation will run it: species, counts, who catches whom with the reward of
    /// each contact, the observation layout of each observer species with offsets, and every resolved
    /// parameter (with the species plugins of this program).
    #[arg(long, help_heading = "Modes", value_name = "FILE")]
    pub(crate) describe_scene: Option<PathBuf>,
}

impl Mode for DescribeArgs {
    const MODE: &'static str = "describe_scene";
    const TAKES: &'static [&'static str] = &["seed", "prey", "predators", "count", "policy"];
}

/// `--fingerprint RUN`.
#[derive(Args, Debug, Clone, Default)]
pub(crate) struct FingerprintArgs {
    /// Print a run's behavioural fingerprint: a hash of its metrics.csv without wall_seconds and of its
    /// checkpoint's files. The same short training by two builds of one commit gives the same fingerprint
    /// (how a pinned experiment's binary is rebuilt: docs/src/guide/experiments.md).
    #[arg(long, help_heading = "Modes", value_name = "DIR")]
    pub(crate) fingerprint: Option<PathBuf>,
}

impl Mode for FingerprintArgs {
    const MODE: &'static str = "fingerprint";
    const TAKES: &'static [&'static str] = &[];
}

/// `--describe-scene FILE`: the scene with the call's overrides, described.
pub(crate) fn describe(path: &Path, shared: &Shared) -> crate::error::Result<()> {
    let scene = load_scene(path, &shared.scene.overrides(false)?)?;
    crate::io::out_text(format_args!("{}", crate::sim::species::describe(&scene, &path.display().to_string())))
}

/// The default scene of every mode that loads one.
pub(crate) const STANDARD_SCENE: &str = "scenes/standard.ron";

/// The default scene's text, built into the binary ([`SceneArgs::load`]).
/// The scenes shipped in `scenes/`, built into the binary (and the Python package) by the path a clone
/// gives them, so that they load outside the clone too (after `cargo install`, from an installed wheel).
const SHIPPED_SCENES: [(&str, &str); 9] = [
    (STANDARD_SCENE, include_str!("../../scenes/standard.ron")),
    ("scenes/paper.ron", include_str!("../../scenes/paper.ron")),
    ("scenes/gym-pps.ron", include_str!("../../scenes/gym-pps.ron")),
    ("scenes/gym-pps-code.ron", include_str!("../../scenes/gym-pps-code.ron")),
    ("scenes/confined.ron", include_str!("../../scenes/confined.ron")),
    ("scenes/confined-penalty.ron", include_str!("../../scenes/confined-penalty.ron")),
    ("scenes/many-eyes.ron", include_str!("../../scenes/many-eyes.ron")),
    ("scenes/distilled.ron", include_str!("../../scenes/distilled.ron")),
    ("scenes/prey-vs-chasers.ron", include_str!("../../scenes/prey-vs-chasers.ron")),
];

/// A scene's text (as [`load_scene`] read it from `path`, which errors name) with `overrides` applied and
/// validated: what an environment made again from a pickle runs, whatever the file holds by then.
pub fn scene_from_text(text: &str, path: &Path, overrides: &Overrides) -> crate::error::Result<Scene> {
    let mut scene = Scene::parse(text, &format!("{} (as first read)", path.display()))?;
    overrides.apply(&mut scene, path).kind(crate::error::Kind::Scene)?;
    Ok(scene)
}

/// A scene file with `overrides` applied and validated: the file at `path` when there is one, else, when
/// `path` names a shipped scene (`scenes/paper.ron`), its built-in copy (a file of that name in the working
/// folder always wins).
pub fn load_scene(path: &Path, overrides: &Overrides) -> crate::error::Result<Scene> {
    if !path.exists() {
        if let Some((name, text)) = SHIPPED_SCENES.iter().find(|(name, _)| path == Path::new(name)) {
            let mut scene = Scene::parse(text, &format!("{name} (built in)"))?;
            // A scene's error, as `Overrides::load` says it of a file on disk.
            overrides.apply(&mut scene, path).kind(crate::error::Kind::Scene)?;
            return Ok(scene);
        }
    }
    overrides.load(path)
}
