//! The `coevo` command line: every run mode (headless training, evaluation, recording, animations,
//! experiments, benchmarks, the viewer), for the `coevo` binary and for programs with species of their own
//! (`examples/hawk.rs`), which call [`main`] with their [`SpeciesPlugins`].

use crate::io::Existing;
use crate::learning::Mode;
use crate::scene::{Overrides, Policy, Scene};
use crate::sim::species::SpeciesPlugins;
use clap::{error::ErrorKind, ArgGroup, CommandFactory, FromArgMatches, Parser};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Duration;

/// Predators and prey that learn together: a simulator of Li, Li & Zhao (New J. Phys. 2023).
///
/// One mode per call: --train, --resume RUN, --eval RUN, --record OUT.csv or --bench run headless,
/// driving the fixed-step schedule as fast as it goes. Built with `--features viewer` and given no
/// headless mode, it opens the window. Scenes are RON files under scenes/ (see docs/src/guide/scenes.md).
/// A flag the chosen mode does not use is refused, never ignored.
#[derive(Parser, Debug, Clone)]
#[command(name = "coevo", version, about, long_about = None, allow_negative_numbers = true)]
#[command(group(ArgGroup::new("mode").args(["train", "resume", "eval", "crossplay", "record", "animate", "bench", "experiment", "plot", "describe_scene"]).multiple(false)))]
struct Cli {
    /// Scene file to run [default: scenes/standard.ron].
    #[arg(long, help_heading = "Scene", value_name = "PATH")]
    scene: Option<PathBuf>,
    /// Override the scene's random seed.
    #[arg(long, help_heading = "Scene", value_name = "S")]
    seed: Option<u64>,
    /// Steps to simulate (--record) or per episode (--eval).
    #[arg(long, help_heading = "Scene", value_name = "N")]
    steps: Option<usize>,

    /// Train the scene's learning species headless (Algorithm 1) into --out.
    #[arg(long, help_heading = "Modes")]
    train: bool,
    /// Episodes of the training run (default: the scene's `episodes`) or of the evaluation (default 1).
    #[arg(long, help_heading = "Training and evaluation", value_name = "N")]
    episodes: Option<usize>,
    /// Run folder for --train (default runs/<scene>-seed<seed>); must be new or empty.
    #[arg(long, help_heading = "Training and evaluation", value_name = "DIR")]
    out: Option<PathBuf>,
    /// --train into a folder that holds a run, or --record/--screenshot over an existing file: replace it
    /// (coevo's own files only).
    #[arg(long, help_heading = "Training and evaluation")]
    overwrite: bool,
    /// Continue a killed or finished run from its last checkpoint (to --episodes in total).
    #[arg(long, help_heading = "Modes", value_name = "DIR")]
    resume: Option<PathBuf>,
    /// Evaluate a run's policies without noise; writes DIR/eval.csv (per-step DoS/DoA).
    #[arg(long, help_heading = "Modes", value_name = "DIR")]
    eval: Option<PathBuf>,
    /// Play every prey snapshot of a run against every predator snapshot (noise off, the same seeds in
    /// every cell; --episodes per cell, default 5); writes DIR/crossplay.csv, crossplay-readouts.csv and
    /// heat maps in DIR/figures/.
    #[arg(long, help_heading = "Modes", value_name = "DIR")]
    crossplay: Option<PathBuf>,
    /// Deploy a species' snapshot instead of its trained actor, as NAME=EPISODE (repeatable; --eval,
    /// --record and --animate with --run, viewer with --watch), e.g. --snapshot prey=300.
    #[arg(long, help_heading = "Training and evaluation", value_name = "NAME=EPISODE")]
    snapshot: Vec<String>,
    /// Number of prey (--eval, --record, viewer; the paper evaluates on 50).
    #[arg(long, help_heading = "Scene", value_name = "N")]
    prey: Option<usize>,
    /// Number of predators (--eval, --record, viewer; 0 removes them, as in the paper's Fig. 5a).
    #[arg(long, help_heading = "Scene", value_name = "N")]
    predators: Option<usize>,
    /// Any species' count, as NAME=N (repeatable; --eval, --record, viewer).
    #[arg(long, help_heading = "Scene", value_name = "NAME=N")]
    count: Vec<String>,
    /// A species' policy, as NAME=POLICY with POLICY as a scene file writes it: ChaseNearest, FleeNearest,
    /// Random, Still, Frozen("RUN") (repeatable; --eval, --record, --animate, --describe-scene), e.g.
    /// --policy predator=ChaseNearest evaluates trained prey against the paper's rule-based predators.
    #[arg(long, help_heading = "Scene", value_name = "NAME=POLICY")]
    policy: Vec<String>,
    /// No progress bar (--train, --resume).
    #[arg(long, help_heading = "Training and evaluation")]
    quiet: bool,
    /// Worker threads (default: COEVO_THREADS, else all cores). Results never depend on it.
    #[arg(long, help_heading = "Training and evaluation", value_name = "N")]
    threads: Option<usize>,
    /// Matrix-product kernels: auto, avx512, avx2 or portable (default: COEVO_KERNELS, else auto). Pin one
    /// family so CPUs with and without AVX-512 compute identical runs.
    #[arg(long, help_heading = "Training and evaluation", value_name = "FAMILY")]
    kernels: Option<String>,

    /// --eval: what the actors see of their neighbours (controls for alignment claims) [default: seeing].
    /// `blind` zeroes, `shuffled` swaps between individuals, every neighbour block of every learning
    /// species; `blind:OBSERVER:OBSERVED` / `shuffled:OBSERVER:OBSERVED` only the block in which species
    /// OBSERVER sees species OBSERVED (`blind:prey:prey`: prey blind to each other, still seeing the
    /// predators; the predators untouched). Block forms repeat: --control blind:prey:prey --control ...
    #[arg(long, help_heading = "Training and evaluation", value_name = "CONTROL")]
    control: Vec<String>,
    /// --eval: also run a twin world in which one prey is turned by this many radians, and write how the
    /// other prey's headings respond, by topological rank and lag, to NAME-perturbation.csv (information
    /// transfer; not in the paper).
    #[arg(long, help_heading = "Training and evaluation", value_name = "RADIANS")]
    perturb: Option<f64>,
    /// --eval --perturb: the step of each episode after which the prey is turned [default: half the episode].
    #[arg(long, help_heading = "Training and evaluation", value_name = "N")]
    perturb_step: Option<usize>,
    /// --eval: the file name of the per-step CSV inside the run folder [default: eval.csv].
    #[arg(long, help_heading = "Training and evaluation", value_name = "NAME.csv")]
    eval_out: Option<String>,
    /// --eval: prey within this many metres of a predator count as in view for the confusion curve
    /// (NAME-confusion.csv) [default: the scene's confusion_radius, else the perception radius].
    #[arg(long, help_heading = "Training and evaluation", value_name = "M")]
    confusion_radius: Option<f64>,
    /// --eval: deploy the run's actors as they were before training (initialised from the run's scene and
    /// seed), the baseline of what training changed.
    #[arg(long, help_heading = "Training and evaluation")]
    untrained: bool,

    /// Run an experiment file (experiments/*.ron), or `all` of them: every preset × variant × seed as a
    /// run under results/, resuming killed runs and skipping finished ones, then evaluations, summaries,
    /// figures and results/NAME/REPORT.md (claims and verdicts); `all` also rewrites REPRODUCTION.md.
    #[arg(long, help_heading = "Modes", value_name = "FILE|all")]
    experiment: Option<String>,
    /// --experiment: runs at a time, sharing the cores (--threads / J each) [default: 2].
    #[arg(long, help_heading = "Experiments", value_name = "J")]
    jobs: Option<usize>,
    /// --experiment: only run index N of the experiment (what a Slurm array task runs).
    #[arg(long, help_heading = "Experiments", value_name = "N")]
    task: Option<usize>,
    /// --experiment: write a Slurm job array and a dependent aggregate job instead of running.
    #[arg(long, help_heading = "Experiments")]
    emit_slurm: bool,
    /// Regenerate summaries, figures and REPORT.md from CSV files alone: an experiment's results folder
    /// (results/NAME, with experiments/NAME.ron), one run folder, or `all` (every experiment, and
    /// REPRODUCTION.md; an experiment whose run folders are not all here keeps its summaries, and its
    /// figures are redrawn from its committed figure-data.ron.gz).
    #[arg(long, help_heading = "Modes", value_name = "DIR")]
    plot: Option<PathBuf>,
    /// --plot: draw a run stopped after its last checkpoint, or an experiment whose runs are not all
    /// finished, from what there is (marked partial) instead of refusing.
    #[arg(long, help_heading = "Experiments")]
    partial: bool,

    /// Record a trajectory CSV: step,id,species,x,y,vx,vy,theta,thrust,turn_rate,reward.
    #[arg(long, help_heading = "Modes", value_name = "OUT.csv")]
    record: Option<PathBuf>,
    /// Render an episode to an animated GIF, headless (no window, no GPU): species colours, heading
    /// lines, optional --trails, a caption with the step and the live DoS/DoA/polarization/milling.
    #[arg(long, help_heading = "Modes", value_name = "OUT.gif")]
    animate: Option<PathBuf>,
    /// --animate: width of the arena image in pixels [default: 480].
    #[arg(long, help_heading = "Recording and animation", value_name = "PX")]
    size: Option<u32>,
    /// --record, --animate: the run whose trained actors drive the scene's learned species (default: the
    /// seed's freshly initialized actors); its scene.ron is the scene unless --scene is given.
    #[arg(long, help_heading = "Recording and animation", value_name = "DIR")]
    run: Option<PathBuf>,
    /// Print a scene as the simulation will run it: species, counts, who catches whom with the reward of
    /// each contact, the observation layout of each observer species with offsets, and every resolved
    /// parameter (with the species plugins of this program).
    #[arg(long, help_heading = "Modes", value_name = "FILE")]
    describe_scene: Option<PathBuf>,
    /// Print throughput figures for this machine.
    #[arg(long, help_heading = "Modes")]
    bench: bool,
    /// Seconds per benchmark figure (--bench), in (0, 3600].
    #[arg(long, help_heading = "Modes", value_name = "SECONDS")]
    bench_seconds: Option<f64>,

    /// Viewer: watch a run's trained actors (its scene.ron, with --prey/--predators/--count applied).
    #[arg(long, help_heading = "Viewer", value_name = "DIR")]
    watch: Option<PathBuf>,
    /// Viewer: replace learned species by the paper's rule-based chase and flee.
    #[arg(long, help_heading = "Viewer")]
    rules: bool,
    /// Viewer: render --frames frames, save a PNG here and exit.
    #[arg(long, help_heading = "Viewer", value_name = "PATH.png")]
    screenshot: Option<PathBuf>,
    /// Viewer, live training: save the run into this new folder when its current episode ends (what the
    /// panel's "Save this run" does): a run folder that --resume, --eval and --watch take.
    #[arg(long, help_heading = "Viewer", value_name = "DIR")]
    save_run: Option<PathBuf>,
    /// Viewer: frames to render before --screenshot [default: 60].
    #[arg(long, help_heading = "Viewer", value_name = "N")]
    frames: Option<usize>,
    /// Viewer: window size in pixels [default: 1280x720].
    #[arg(long, help_heading = "Viewer", value_name = "WxH")]
    window: Option<String>,
    /// Viewer: fixed steps per rendered frame [default: 1].
    #[arg(long, help_heading = "Viewer", value_name = "N")]
    steps_per_frame: Option<usize>,
    /// Viewer: step as fast as possible, still drawing every frame (the default of live training unless
    /// --steps-per-frame or --paused is given; the panel switches it off for real-time watching).
    #[arg(long, help_heading = "Viewer")]
    fast: bool,
    /// Viewer: start paused.
    #[arg(long, help_heading = "Viewer")]
    paused: bool,
    /// Viewer: draw fading trajectory tails from the start.
    #[arg(long, help_heading = "Viewer")]
    trails: bool,
    /// Viewer: select the agent with this id (its perception radius, neighbours and observation).
    #[arg(long, help_heading = "Viewer", value_name = "ID")]
    select: Option<u32>,
}

/// The flags each mode takes besides its own flag, `--threads` and `--kernels` (which every mode takes); the viewer is
/// the call without a mode flag. clap enforces it ([`command`]): a flag conflicts with every mode that
/// does not take it and, when the viewer does not take it either, requires one of the modes that do.
const TAKES: [(&str, &[&str]); 11] = [
    ("train", &["scene", "seed", "episodes", "out", "overwrite", "quiet"]),
    ("resume", &["episodes", "quiet"]),
    (
        "eval",
        &[
            "episodes",
            "steps",
            "seed",
            "prey",
            "predators",
            "count",
            "eval_out",
            "control",
            "confusion_radius",
            "untrained",
            "snapshot",
            "perturb",
            "perturb_step",
            "policy",
        ],
    ),
    ("crossplay", &["episodes", "steps", "seed", "prey", "predators", "count", "quiet"]),
    ("record", &["run", "scene", "seed", "steps", "prey", "predators", "count", "policy", "overwrite", "snapshot"]),
    (
        "animate",
        &[
            "run",
            "scene",
            "seed",
            "steps",
            "prey",
            "predators",
            "count",
            "policy",
            "overwrite",
            "trails",
            "steps_per_frame",
            "size",
            "quiet",
            "snapshot",
        ],
    ),
    ("bench", &["bench_seconds"]),
    ("describe_scene", &["seed", "prey", "predators", "count", "policy"]),
    ("experiment", &["jobs", "task", "emit_slurm", "quiet"]),
    ("plot", &["partial"]),
    (
        VIEWER,
        &[
            "scene",
            "seed",
            "prey",
            "predators",
            "count",
            "watch",
            "rules",
            "screenshot",
            "save_run",
            "frames",
            "window",
            "steps_per_frame",
            "fast",
            "paused",
            "trails",
            "select",
            "overwrite",
            "snapshot",
        ],
    ),
];

/// The call without a mode flag.
const VIEWER: &str = "";

/// The command line as clap parses it: [`Cli`] with [`TAKES`] enforced.
fn command() -> clap::Command {
    let modes: Vec<&'static str> = TAKES.iter().map(|(m, _)| *m).filter(|m| *m != VIEWER).collect();
    let mut command = Cli::command();
    let flags: Vec<String> = command
        .get_arguments()
        .map(|a| a.get_id().to_string())
        .filter(|id| !modes.contains(&id.as_str()) && !["threads", "kernels", "help", "version"].contains(&id.as_str()))
        .collect();
    for flag in flags {
        let takers: Vec<&'static str> =
            TAKES.iter().filter(|(_, f)| f.contains(&flag.as_str())).map(|(m, _)| *m).collect();
        let others: Vec<&'static str> = modes.iter().copied().filter(|m| !takers.contains(m)).collect();
        let group = format!("modes taking {flag}");
        let viewer = takers.contains(&VIEWER);
        if !viewer {
            command = command.group(ArgGroup::new(group.clone()).args(takers).multiple(false));
        }
        command = command.mut_arg(&flag, |arg| {
            let arg = arg.conflicts_with_all(others);
            if viewer {
                arg
            } else {
                arg.requires(group)
            }
        });
    }
    command
}

/// What a call does: its mode and the mode's own value.
#[derive(Clone, Debug, PartialEq)]
enum Call {
    Train,
    Resume(PathBuf),
    Eval(PathBuf),
    Crossplay(PathBuf),
    Record(PathBuf),
    Animate(PathBuf),
    Describe(PathBuf),
    Bench,
    Experiment(String),
    Plot(PathBuf),
    Viewer,
}

impl Call {
    fn of(cli: &Cli) -> Call {
        let path = |p: &Option<PathBuf>| p.clone();
        match () {
            _ if cli.train => Call::Train,
            _ if cli.bench => Call::Bench,
            _ => path(&cli.resume)
                .map(Call::Resume)
                .or_else(|| path(&cli.eval).map(Call::Eval))
                .or_else(|| path(&cli.crossplay).map(Call::Crossplay))
                .or_else(|| path(&cli.record).map(Call::Record))
                .or_else(|| path(&cli.animate).map(Call::Animate))
                .or_else(|| path(&cli.describe_scene).map(Call::Describe))
                .or_else(|| cli.experiment.clone().map(Call::Experiment))
                .or_else(|| path(&cli.plot).map(Call::Plot))
                .unwrap_or(Call::Viewer),
        }
    }
}

/// clap's error as one line: its message without the usage and help hints that follow it.
fn one_line(e: &clap::Error) -> String {
    let text = e.to_string();
    let message = text.split("\n\nUsage:").next().unwrap_or("").split("\n\nFor more information").next().unwrap_or("");
    message.split_whitespace().collect::<Vec<_>>().join(" ").trim_start_matches("error: ").to_string()
}

/// Whether `args` (without the program name) is a command line coevo accepts, without running it: the
/// one line it would fail with otherwise. The book's and the README's examples are checked with it.
pub fn check_args<I: IntoIterator<Item = String>>(args: I) -> Result<(), String> {
    let argv = std::iter::once("coevo".to_string()).chain(args);
    let matches = command().try_get_matches_from(argv).map_err(|e| one_line(&e))?;
    Cli::from_arg_matches(&matches).map(|_| ()).map_err(|e| one_line(&e))
}

/// `coevo --help`, as the book's reference prints it.
pub fn help() -> String {
    command().render_help().to_string()
}

/// Runs the command line with `species` registered (none for plain `coevo`): one line on stderr and a
/// non-zero exit on any error.
pub fn main(species: SpeciesPlugins) -> ExitCode {
    if let Err(e) = species.register() {
        return fail(&e.to_string());
    }
    let matches = match command().try_get_matches() {
        Ok(m) => m,
        Err(e) if matches!(e.kind(), ErrorKind::DisplayHelp | ErrorKind::DisplayVersion) => e.exit(),
        Err(e) => return fail(&one_line(&e)),
    };
    let cli = match Cli::from_arg_matches(&matches) {
        Ok(cli) => cli,
        Err(e) => return fail(&one_line(&e)),
    };
    let call = Call::of(&cli);
    if call != Call::Viewer {
        crate::io::install_signal_cleanup();
        // Output piped into `head` ends quietly, as a Unix tool's does, instead of panicking on EPIPE.
        // SAFETY: restores the default action of one signal before any thread is started.
        unsafe { libc::signal(libc::SIGPIPE, libc::SIG_DFL) };
    }
    match run(cli, call) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => fail(&e.to_string()),
    }
}

/// One line on stderr and a failure; a stderr that cannot take it (closed, full) still fails, quietly.
fn fail(message: &str) -> ExitCode {
    let _ = crate::errln!("coevo: error: {message}");
    ExitCode::FAILURE
}

/// A count-like flag that must be ≥ 1.
fn at_least_one(flag: &str, value: Option<usize>) -> crate::error::Result<()> {
    match value {
        Some(0) => Err(format!("{flag}: must be ≥ 1 (got 0)").into()),
        _ => Ok(()),
    }
}

/// What the call changes of the scene it loads: --prey, --predators and --count (in that order),
/// --seed, and --steps per episode when `steps` (--eval; --record and --animate run --steps as one
/// episode).
fn overrides(cli: &Cli, steps: bool) -> crate::error::Result<Overrides> {
    let mut counts: Vec<(String, usize)> = cli.prey.map(|n| ("prey".to_string(), n)).into_iter().collect();
    counts.extend(cli.predators.map(|n| ("predator".to_string(), n)));
    for c in &cli.count {
        let (name, n) = c.split_once('=').ok_or_else(|| format!("--count {c}: expected NAME=N"))?;
        counts.push((name.to_string(), n.parse().map_err(|_| format!("--count {c}: {n} is not a count"))?));
    }
    let mut policies = vec![];
    for p in &cli.policy {
        let (name, policy) = p.split_once('=').ok_or_else(|| format!("--policy {p}: expected NAME=POLICY"))?;
        let policy = ron::from_str(policy).map_err(|_| {
            format!("--policy {p}: {policy} is not a policy (ChaseNearest, FleeNearest, Random, Still, Frozen(\"RUN\"), Learned)")
        })?;
        policies.push((name.to_string(), policy));
    }
    Ok(Overrides {
        counts,
        policies,
        seed: cli.seed,
        episode_steps: if steps { cli.steps } else { None },
        confusion_radius: None,
    })
}

/// The --snapshot requests (NAME=EPISODE); they need a run whose snapshots to deploy (`run`).
fn snapshots(cli: &Cli, run: Option<&Path>, what: &str) -> crate::error::Result<Vec<(String, usize)>> {
    if !cli.snapshot.is_empty() && run.is_none() {
        return Err(format!("--snapshot: deploys a run's snapshots; give the run with {what}").into());
    }
    cli.snapshot
        .iter()
        .map(|text| {
            let (name, episode) = text
                .split_once('=')
                .ok_or_else(|| format!("--snapshot {text}: expected NAME=EPISODE, e.g. prey=300"))?;
            let episode =
                episode.parse().map_err(|_| format!("--snapshot {text}: {episode:?} is not a number of episodes"))?;
            Ok((name.to_string(), episode))
        })
        .collect()
}

/// The scene file of the call (--scene, else `default`) with the call's overrides applied and validated.
fn load_scene(cli: &Cli, default: &Path, overrides: &Overrides) -> crate::error::Result<(Scene, PathBuf)> {
    let path = cli.scene.clone().unwrap_or_else(|| default.to_path_buf());
    Ok((overrides.load(&path)?, path))
}

fn run(cli: Cli, call: Call) -> crate::error::Result<()> {
    at_least_one("--threads", cli.threads)?;
    if let Some(n) = cli.threads {
        crate::parallel::set_threads(n);
    }
    // Before any network exists: gemm fixes its kernels at its first product.
    match (&cli.kernels, std::env::var("COEVO_KERNELS")) {
        (Some(family), _) => crate::learning::nets::pin_kernels(family).map_err(|e| format!("--kernels: {e}"))?,
        (None, Ok(family)) => crate::learning::nets::pin_kernels(&family).map_err(|e| format!("COEVO_KERNELS: {e}"))?,
        (None, Err(_)) => {}
    }
    at_least_one("--episodes", cli.episodes)?;
    at_least_one("--steps", cli.steps)?;
    let standard = Path::new("scenes/standard.ron");
    match call {
        Call::Bench => {
            let seconds = cli.bench_seconds.unwrap_or(2.0);
            if !(seconds > 0.0 && seconds <= 3600.0) {
                return Err(format!("--bench-seconds: must be a number of seconds in (0, 3600] (got {seconds})").into());
            }
            let budget = Duration::from_secs_f64(seconds);
            crate::outln!(
                "coevo {} ({}), {} matrix-product kernels, {} threads",
                env!("CARGO_PKG_VERSION"),
                env!("COEVO_GIT_COMMIT"),
                crate::learning::nets::kernels(),
                crate::parallel::threads()
            )?;
            crate::run::bench::print(&crate::run::bench::environment(budget))?;
            crate::run::bench::print(&crate::run::bench::learning(budget))?;
            crate::run::bench::print(&crate::run::bench::external(budget))?;
            Ok(())
        }
        Call::Eval(run) => {
            if cli.untrained && cli.seed.is_some() {
                return Err("--untrained: deploys the networks the run was initialised with, from the run's seed; --seed would initialise others".into());
            }
            let opts = crate::run::evaluate::EvalOptions {
                run: run.clone(),
                out: cli.eval_out.clone(),
                control: crate::learning::control::ObservationControl::parse(&cli.control)
                    .map_err(|e| format!("--control: {e}"))?,
                episodes: cli.episodes.unwrap_or(1),
                overrides: Overrides { confusion_radius: cli.confusion_radius, ..overrides(&cli, true)? },
                untrained: cli.untrained,
                snapshots: snapshots(&cli, Some(&run), "--eval")?,
                perturb: match (cli.perturb, cli.perturb_step) {
                    (None, Some(_)) => return Err("--perturb-step: needs --perturb RADIANS".into()),
                    (None, None) => None,
                    (Some(angle), step) => {
                        let steps = match cli.steps {
                            Some(n) => n,
                            None => Scene::load(&crate::run::RunDir::new(&run).scene())?.episode_steps,
                        };
                        Some(crate::run::perturb::Perturbation { angle, step: step.unwrap_or(steps / 2) })
                    }
                },
            };
            if cli.untrained && !opts.snapshots.is_empty() {
                return Err("--untrained: deploys the networks the run was initialised with; --snapshot deploys others (the initial ones are --snapshot NAME=0)".into());
            }
            crate::outln!("{}", crate::run::evaluate::evaluate(&opts)?)?;
            Ok(())
        }
        Call::Crossplay(run) => {
            use crate::experiment::crossplay;
            let opts = crossplay::CrossplayOptions {
                run: run.clone(),
                episodes: cli.episodes.unwrap_or(5),
                overrides: overrides(&cli, true)?,
                progress: !cli.quiet,
            };
            let (matrices, written) = crossplay::crossplay(&opts)?;
            for m in &matrices {
                crate::outln!(
                    "cross-play {}: {} {} snapshots × {} {} snapshots, {} episodes per cell",
                    run.display(),
                    m.prey_episodes.len(),
                    m.pair.prey_name,
                    m.predator_episodes.len(),
                    m.pair.predator_name,
                    opts.episodes
                )?;
                for r in crossplay::readouts(m) {
                    let value = r.value.map_or("–".to_string(), |v| format!("{v:+.3}"));
                    crate::outln!("  {:<36} {value:>7}", r.name)?;
                }
            }
            for line in written {
                crate::outln!("wrote {line}")?;
            }
            Ok(())
        }
        Call::Train | Call::Resume(_) => {
            let (scene, run) = match &cli.resume {
                // The run's own scene is loaded by `train`.
                Some(run) => (Scene::preset("paper").expect("a preset of this program"), run.clone()),
                None => {
                    let (scene, path) = load_scene(&cli, standard, &overrides(&cli, false)?)?;
                    let stem = path.file_stem().map_or("run".into(), |s| s.to_string_lossy().into_owned());
                    let run =
                        cli.out.clone().unwrap_or_else(|| PathBuf::from(format!("runs/{stem}-seed{}", scene.seed)));
                    (scene, run)
                }
            };
            let opts = crate::run::train::TrainOptions {
                run: run.clone(),
                resume: cli.resume.is_some(),
                overwrite: cli.overwrite,
                episodes: cli.episodes,
                progress: !cli.quiet,
            };
            let trained = crate::run::train::train(scene, &opts)?;
            crate::errln!("coevo: trained {trained} episodes into {}", run.display())?;
            if !cli.quiet {
                crate::io::err_text(format_args!("{}", crate::run::train::explain(&run)?))?;
            }
            Ok(())
        }
        Call::Record(out) => {
            let (mut sim, steps, actors) = deployed(&cli, standard)?;
            let existing = if cli.overwrite { Existing::Replace } else { Existing::Refuse };
            crate::run::record::record(&mut sim, steps, &out, existing)?;
            crate::errln!("coevo: wrote {steps} steps to {}{actors}", out.display())?;
            Ok(())
        }
        Call::Animate(out) => {
            if out.extension().is_none_or(|e| e != "gif") {
                return Err(format!("--animate {}: the file must end in .gif", out.display()).into());
            }
            at_least_one("--steps-per-frame", cli.steps_per_frame)?;
            let size = cli.size.unwrap_or(480);
            if !(64..=2048).contains(&size) {
                return Err(format!("--size {size}: must be within 64..=2048 pixels").into());
            }
            let existing = if cli.overwrite { Existing::Replace } else { Existing::Refuse };
            crate::io::check_target(&out, existing).map_err(|e| format!("--animate {}: {e}", out.display()))?;
            let (mut sim, steps, actors) = deployed(&cli, standard)?;
            let title = match (&cli.run, &cli.scene) {
                (Some(run), _) => format!("trained run {}", run.display()),
                (None, Some(scene)) => scene.display().to_string(),
                (None, None) => standard.display().to_string(),
            };
            let opts = crate::run::animate::AnimateOptions {
                steps,
                steps_per_frame: cli.steps_per_frame.unwrap_or(1),
                trails: cli.trails,
                size,
                title,
                progress: !cli.quiet,
            };
            let s = crate::run::animate::animate(&mut sim, &opts, &out, existing)?;
            crate::errln!(
                "coevo: wrote {} frames ({steps} steps, {:.1} MB) to {}{actors}; over the clip: polarization {:.3}, milling {:.3}, DoA {:.3}",
                s.frames,
                s.bytes as f64 / 1e6,
                out.display(),
                s.polarization,
                s.milling,
                s.doa
            )?;
            Ok(())
        }
        Call::Experiment(which) => crate::experiment::report::experiment(&crate::experiment::report::Request {
            which: &which,
            jobs: cli.jobs,
            task: cli.task,
            emit_slurm: cli.emit_slurm,
            quiet: cli.quiet,
        }),
        Call::Describe(path) => {
            let (scene, source) =
                load_scene(&Cli { scene: Some(path), ..cli.clone() }, standard, &overrides(&cli, false)?)?;
            crate::io::out_text(format_args!(
                "{}",
                crate::sim::species::describe(&scene, &source.display().to_string())
            ))?;
            Ok(())
        }
        Call::Plot(dir) => crate::experiment::report::plot(&dir, cli.partial),
        Call::Viewer => viewer(&cli),
    }
}

/// The simulation --record and --animate show: the scene of --run (or --scene) with the counts applied,
/// every species acting exactly as in --eval (trained actors without noise); the steps to run; and a
/// note saying which actors drive it.
fn deployed(cli: &Cli, standard: &Path) -> crate::error::Result<(crate::sim::Simulation, usize, String)> {
    if let Some(run) = &cli.run {
        crate::run::RunDir::new(run).check_plugins()?;
    }
    let default = cli.run.as_ref().map_or(standard.to_path_buf(), |r| r.join(crate::run::SCENE));
    let (mut scene, _) = load_scene(cli, &default, &overrides(cli, false)?)?;
    let steps = cli.steps.unwrap_or(scene.episode_steps);
    scene.episode_steps = steps;
    crate::run::announce_cost(&scene, steps)?;
    let wanted = snapshots(cli, cli.run.as_deref(), "--run")?;
    let mut learners = crate::learning::Learners::new(&scene, Mode::Evaluate);
    learners.load_actors(&scene, cli.run.as_deref())?;
    if let Some(run) = &cli.run {
        learners.load_snapshots(&scene, run, &wanted)?;
    }
    let sim = crate::learning::simulation_of(scene.clone(), learners, |_| {})?;
    let actors: Vec<String> = scene
        .species
        .iter()
        .filter_map(|def| match (&def.policy, &cli.run) {
            (Policy::Learned, Some(run)) => Some(match wanted.iter().find(|(s, _)| s == &def.name) {
                Some((_, e)) => format!("{}: snapshot after {e} episodes of {}", def.name, run.display()),
                None => format!("{}: trained actor of {}", def.name, run.display()),
            }),
            (Policy::Learned, None) => Some(format!(
                "{}: freshly initialized actor of seed {} (untrained: no --run given)",
                def.name, scene.seed
            )),
            (Policy::Frozen(path), _) => Some(format!("{}: trained actor of {path}", def.name)),
            _ => None,
        })
        .collect();
    let actors = if actors.is_empty() { String::new() } else { format!(" ({})", actors.join("; ")) };
    Ok((sim, steps, actors))
}

#[cfg(not(feature = "viewer"))]
fn viewer(_: &Cli) -> crate::error::Result<()> {
    Err("choose a mode: --train, --eval RUN, --record OUT.csv or --bench (see --help); the window needs `--features viewer`".into())
}

#[cfg(feature = "viewer")]
fn viewer(cli: &Cli) -> crate::error::Result<()> {
    use crate::viewer::{RunMode as ViewMode, ScreenshotRequest, Setup, ViewerOptions};
    if cli.watch.is_some() && (cli.scene.is_some() || cli.rules) {
        return Err("--watch: shows a run in its own scene; it does not combine with --scene or --rules".into());
    }
    let (default, mode) = match &cli.watch {
        Some(run) => {
            crate::run::RunDir::new(run).check_plugins()?;
            (run.join(crate::run::SCENE), ViewMode::Watch(run.clone()))
        }
        None => {
            (PathBuf::from("scenes/standard.ron"), if cli.rules { ViewMode::RuleBased } else { ViewMode::LiveTraining })
        }
    };
    let (scene, source) = load_scene(cli, &default, &overrides(cli, false)?)?;
    at_least_one("--frames", cli.frames)?;
    at_least_one("--steps-per-frame", cli.steps_per_frame)?;
    let size = cli.window.clone().unwrap_or_else(|| "1280x720".into());
    let window = size
        .split_once('x')
        .and_then(|(w, h)| Some(bevy::math::UVec2::new(w.parse().ok()?, h.parse().ok()?)))
        .filter(|s| s.x >= 320 && s.y >= 240)
        .ok_or_else(|| format!("--window {size}: expected WxH of at least 320x240, e.g. 1280x720"))?;
    if let Some(path) = &cli.screenshot {
        if path.extension().is_none_or(|e| e != "png") {
            return Err(format!("--screenshot {}: the file must end in .png", path.display()).into());
        }
        let existing = if cli.overwrite { Existing::Replace } else { Existing::Refuse };
        crate::io::check_target(path, existing).map_err(|e| format!("--screenshot {}: {e}", path.display()))?;
    }
    let snapshots = snapshots(cli, cli.watch.as_deref(), "--watch")?;
    if let Some(dir) = &cli.save_run {
        if cli.watch.is_some() || cli.rules {
            return Err(
                format!("--save-run {}: saves live training; not with --watch or --rules", dir.display()).into()
            );
        }
        crate::run::RunDir::new(dir).check_new(false).map_err(|e| format!("--save-run {e}"))?;
    }
    crate::viewer::run(ViewerOptions {
        setup: Setup { scene, source, mode, snapshots },
        window,
        steps_per_frame: cli.steps_per_frame.unwrap_or(1),
        paused: cli.paused,
        // Live training starts fast, so its curves move within the first minute (an episode takes ~20 s
        // at one step per frame); watching a run or rule-based agents starts at one step per frame.
        fast: cli.fast || (cli.watch.is_none() && !cli.rules && cli.steps_per_frame.is_none() && !cli.paused),
        trails: cli.trails,
        select: cli.select,
        screenshot: cli.screenshot.clone().map(|path| ScreenshotRequest { path, frames: cli.frames.unwrap_or(60) }),
        save_run: cli.save_run.clone(),
    })
}
