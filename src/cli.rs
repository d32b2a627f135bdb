//! The `coevo` command line: every run mode (headless training, evaluation, recording, animations,
//! experiments, benchmarks, the viewer), for the `coevo` binary and for programs with species of their own
//! (`examples/hawk.rs`), which call [`main`] with their [`SpeciesPlugins`].

use clap::parser::ValueSource;
use clap::{error::ErrorKind, ArgGroup, CommandFactory, FromArgMatches, Parser};
use crate::io::Existing;
use crate::learning::Mode;
use crate::scene::{Policy, Scene};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Duration;
use crate::sim::species::SpeciesPlugins;

/// Predators and prey that learn together: a simulator of Li, Li & Zhao (New J. Phys. 2023).
///
/// One mode per call: --train, --resume RUN, --eval RUN, --record OUT.csv or --bench run headless,
/// driving the fixed-step schedule as fast as it goes. Built with `--features viewer` and given no
/// headless mode, it opens the window. Scenes are RON files under scenes/ (see README, "Scenes").
/// A flag the chosen mode does not use is refused, never ignored.
#[derive(Parser, Debug, Clone)]
#[command(name = "coevo", version, about, long_about = None, allow_negative_numbers = true)]
#[command(group(ArgGroup::new("mode").args(["train", "resume", "eval", "record", "animate", "bench", "experiment", "plot", "describe_scene"]).multiple(false)))]
struct Cli {
    /// Scene file to run [default: scenes/standard.ron].
    #[arg(long, value_name = "PATH")]
    scene: Option<PathBuf>,
    /// Override the scene's random seed.
    #[arg(long, value_name = "S")]
    seed: Option<u64>,
    /// Steps to simulate (--record) or per episode (--eval).
    #[arg(long, value_name = "N")]
    steps: Option<usize>,

    /// Train the scene's learning species headless (Algorithm 1) into --out.
    #[arg(long)]
    train: bool,
    /// Episodes of the training run (default: the scene's `episodes`) or of the evaluation (default 1).
    #[arg(long, value_name = "N")]
    episodes: Option<usize>,
    /// Run folder for --train (default runs/<scene>-seed<seed>); must be new or empty.
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
    /// --train into a folder that holds a run, or --record/--screenshot over an existing file: replace it
    /// (coevo's own files only).
    #[arg(long)]
    overwrite: bool,
    /// Continue a killed or finished run from its last checkpoint (to --episodes in total).
    #[arg(long, value_name = "DIR")]
    resume: Option<PathBuf>,
    /// Evaluate a run's policies without noise; writes DIR/eval.csv (per-step DoS/DoA).
    #[arg(long, value_name = "DIR")]
    eval: Option<PathBuf>,
    /// Number of prey (--eval, --record, viewer; the paper evaluates on 50).
    #[arg(long, value_name = "N")]
    prey: Option<usize>,
    /// Number of predators (--eval, --record, viewer; 0 removes them, as in the paper's Fig. 5a).
    #[arg(long, value_name = "N")]
    predators: Option<usize>,
    /// Any species' count, as NAME=N (repeatable; --eval, --record, viewer).
    #[arg(long, value_name = "NAME=N")]
    count: Vec<String>,
    /// No progress bar (--train, --resume).
    #[arg(long)]
    quiet: bool,
    /// Worker threads (default: COEVO_THREADS, else all cores). Results never depend on it.
    #[arg(long, value_name = "N")]
    threads: Option<usize>,

    /// --eval: what the actors see of their neighbours: `blind` zeroes every neighbour slot, `shuffled`
    /// gives each agent another's (controls for alignment claims) [default: seeing].
    #[arg(long, value_name = "CONTROL")]
    control: Option<crate::learning::ObservationControl>,
    /// --eval: the file name of the per-step CSV inside the run folder [default: eval.csv].
    #[arg(long, value_name = "NAME.csv")]
    eval_out: Option<String>,
    /// --eval: prey within this many metres of a predator count as in view for the confusion curve
    /// (NAME-confusion.csv) [default: the scene's confusion_radius, else the perception radius].
    #[arg(long, value_name = "M")]
    confusion_radius: Option<f64>,

    /// Run an experiment file (experiments/*.ron), or `all` of them: every preset × variant × seed as a
    /// run under results/, resuming killed runs and skipping finished ones, then evaluations, summaries,
    /// figures and REPRODUCTION.md.
    #[arg(long, value_name = "FILE|all")]
    experiment: Option<String>,
    /// --experiment: runs at a time, sharing the cores (--threads / J each) [default: 2].
    #[arg(long, value_name = "J")]
    jobs: Option<usize>,
    /// --experiment: only run index N of the experiment (what a Slurm array task runs).
    #[arg(long, value_name = "N")]
    task: Option<usize>,
    /// --experiment: write a Slurm job array and a dependent aggregate job instead of running.
    #[arg(long)]
    emit_slurm: bool,
    /// Regenerate summaries and figures from CSV files alone: an experiment's results folder
    /// (results/NAME, with experiments/NAME.ron), one run folder, or `all` (every experiment, and
    /// REPRODUCTION.md).
    #[arg(long, value_name = "DIR")]
    plot: Option<PathBuf>,

    /// Record a trajectory CSV: step,id,species,x,y,vx,vy,theta,thrust,turn_rate,reward.
    #[arg(long, value_name = "OUT.csv")]
    record: Option<PathBuf>,
    /// Render an episode to an animated GIF, headless (no window, no GPU): species colours, heading
    /// lines, optional --trails, a caption with the step and the live DoS/DoA/polarization/milling.
    #[arg(long, value_name = "OUT.gif")]
    animate: Option<PathBuf>,
    /// --animate: width of the arena image in pixels [default: 480].
    #[arg(long, value_name = "PX")]
    size: Option<u32>,
    /// --record, --animate: the run whose trained actors drive the scene's learned species (default: the
    /// seed's freshly initialized actors); its scene.ron is the scene unless --scene is given.
    #[arg(long, value_name = "DIR")]
    run: Option<PathBuf>,
    /// Print a scene as the simulation will run it: species, counts, who catches whom with the reward of
    /// each contact, the observation layout of each observer species with offsets, and every resolved
    /// parameter (with the species plugins of this program).
    #[arg(long, value_name = "FILE")]
    describe_scene: Option<PathBuf>,
    /// Print throughput figures for this machine.
    #[arg(long)]
    bench: bool,
    /// Seconds per benchmark figure (--bench), in (0, 3600].
    #[arg(long, value_name = "SECONDS")]
    bench_seconds: Option<f64>,

    /// Viewer: watch a run's trained actors (its scene.ron, with --prey/--predators/--count applied).
    #[arg(long, value_name = "DIR")]
    watch: Option<PathBuf>,
    /// Viewer: replace learned species by the paper's rule-based chase and flee.
    #[arg(long)]
    rules: bool,
    /// Viewer: render --frames frames, save a PNG here and exit.
    #[arg(long, value_name = "PATH.png")]
    screenshot: Option<PathBuf>,
    /// Viewer: frames to render before --screenshot [default: 60].
    #[arg(long, value_name = "N")]
    frames: Option<usize>,
    /// Viewer: window size in pixels [default: 1280x720].
    #[arg(long, value_name = "WxH")]
    window: Option<String>,
    /// Viewer: fixed steps per rendered frame [default: 1].
    #[arg(long, value_name = "N")]
    steps_per_frame: Option<usize>,
    /// Viewer: step as fast as possible (for live training), still drawing every frame.
    #[arg(long)]
    fast: bool,
    /// Viewer: start paused.
    #[arg(long)]
    paused: bool,
    /// Viewer: draw fading trajectory tails from the start.
    #[arg(long)]
    trails: bool,
    /// Viewer: select the agent with this id (its perception radius, neighbours and observation).
    #[arg(long, value_name = "ID")]
    select: Option<u32>,
}

/// The mode of a call and the flags it uses (besides the mode's own flag and --threads).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum RunMode {
    Train,
    Resume,
    Eval,
    Record,
    Animate,
    Describe,
    Bench,
    Experiment,
    Plot,
    Viewer,
}

impl RunMode {
    fn of(cli: &Cli) -> RunMode {
        match () {
            _ if cli.train => RunMode::Train,
            _ if cli.resume.is_some() => RunMode::Resume,
            _ if cli.eval.is_some() => RunMode::Eval,
            _ if cli.record.is_some() => RunMode::Record,
            _ if cli.animate.is_some() => RunMode::Animate,
            _ if cli.describe_scene.is_some() => RunMode::Describe,
            _ if cli.bench => RunMode::Bench,
            _ if cli.experiment.is_some() => RunMode::Experiment,
            _ if cli.plot.is_some() => RunMode::Plot,
            _ => RunMode::Viewer,
        }
    }

    fn flag(self) -> &'static str {
        match self {
            RunMode::Train => "--train",
            RunMode::Resume => "--resume",
            RunMode::Eval => "--eval",
            RunMode::Record => "--record",
            RunMode::Animate => "--animate",
            RunMode::Describe => "--describe-scene",
            RunMode::Bench => "--bench",
            RunMode::Experiment => "--experiment",
            RunMode::Plot => "--plot",
            RunMode::Viewer => "the viewer",
        }
    }

    fn uses(self, arg: &str) -> bool {
        let own: &[&str] = match self {
            RunMode::Train => &["train", "scene", "seed", "episodes", "out", "overwrite", "quiet"],
            RunMode::Resume => &["resume", "episodes", "quiet"],
            RunMode::Eval => &["eval", "episodes", "steps", "seed", "prey", "predators", "count", "eval_out", "control", "confusion_radius"],
            RunMode::Record => &["record", "run", "scene", "seed", "steps", "prey", "predators", "count", "overwrite"],
            RunMode::Animate => &[
                "animate",
                "run",
                "scene",
                "seed",
                "steps",
                "prey",
                "predators",
                "count",
                "overwrite",
                "trails",
                "steps_per_frame",
                "size",
                "quiet",
            ],
            RunMode::Bench => &["bench", "bench_seconds"],
            RunMode::Describe => &["describe_scene", "seed", "prey", "predators", "count"],
            RunMode::Experiment => &["experiment", "jobs", "task", "emit_slurm", "quiet"],
            RunMode::Plot => &["plot"],
            RunMode::Viewer => &[
                "scene",
                "seed",
                "prey",
                "predators",
                "count",
                "watch",
                "rules",
                "screenshot",
                "frames",
                "window",
                "steps_per_frame",
                "fast",
                "paused",
                "trails",
                "select",
                "overwrite",
            ],
        };
        arg == "threads" || own.contains(&arg)
    }
}

/// Runs the command line with `species` registered (none for plain `coevo`): one line on stderr and a
/// non-zero exit on any error.
pub fn main(species: SpeciesPlugins) -> ExitCode {
    if let Err(e) = species.register() {
        return fail(&e);
    }
    let matches = match Cli::command().try_get_matches() {
        Ok(m) => m,
        Err(e) if matches!(e.kind(), ErrorKind::DisplayHelp | ErrorKind::DisplayVersion) => e.exit(),
        // clap's message, on one line: what is wrong and with which flag.
        Err(e) => return fail(e.to_string().lines().next().unwrap_or("").trim_start_matches("error: ")),
    };
    let cli = match Cli::from_arg_matches(&matches) {
        Ok(cli) => cli,
        Err(e) => return fail(e.to_string().lines().next().unwrap_or("").trim_start_matches("error: ")),
    };
    let mode = RunMode::of(&cli);
    if mode != RunMode::Viewer {
        crate::io::install_signal_cleanup();
    }
    let command = Cli::command();
    let is_arg = |id: &str| command.get_arguments().any(|a| a.get_id().as_str() == id);
    let given = matches
        .ids()
        .map(|id| id.as_str())
        .filter(|id| is_arg(id) && matches.value_source(id) == Some(ValueSource::CommandLine));
    for arg in given {
        if !mode.uses(arg) {
            return fail(&format!("--{}: not used by {} (see --help)", arg.replace('_', "-"), mode.flag()));
        }
    }
    match run(cli, mode) {
        Ok(()) => ExitCode::SUCCESS,
        Err(message) => fail(&message),
    }
}

fn fail(message: &str) -> ExitCode {
    eprintln!("coevo: error: {message}");
    ExitCode::FAILURE
}

/// A count-like flag that must be ≥ 1.
fn at_least_one(flag: &str, value: Option<usize>) -> Result<(), String> {
    match value {
        Some(0) => Err(format!("{flag}: must be ≥ 1 (got 0)")),
        _ => Ok(()),
    }
}

/// The scene file of the call (--scene, else `default`), with --seed applied.
fn load_scene(cli: &Cli, default: &Path) -> Result<(Scene, PathBuf), String> {
    let path = cli.scene.clone().unwrap_or_else(|| default.to_path_buf());
    let mut scene = Scene::load(&path).map_err(|e| e.to_string())?;
    if let Some(seed) = cli.seed {
        scene.seed = seed;
    }
    Ok((scene, path))
}

/// A scene with --prey, --predators and --count applied, validated again.
fn with_counts(cli: &Cli, mut scene: Scene, source: &Path) -> Result<Scene, String> {
    for (name, n) in counts(cli)? {
        scene.set_count(&name, n).map_err(|e| format!("{}: {e}", source.display()))?;
    }
    scene.validate().map_err(|(f, m)| format!("{}: {f}: {m}", source.display()))?;
    Ok(scene)
}

fn run(cli: Cli, mode: RunMode) -> Result<(), String> {
    at_least_one("--threads", cli.threads)?;
    if let Some(n) = cli.threads {
        crate::parallel::set_threads(n);
    }
    at_least_one("--episodes", cli.episodes)?;
    at_least_one("--steps", cli.steps)?;
    let standard = Path::new("scenes/standard.ron");
    match mode {
        RunMode::Bench => {
            let seconds = cli.bench_seconds.unwrap_or(2.0);
            if !(seconds > 0.0 && seconds <= 3600.0) {
                return Err(format!("--bench-seconds: must be a number of seconds in (0, 3600] (got {seconds})"));
            }
            let budget = Duration::from_secs_f64(seconds);
            crate::run::bench::print(&crate::run::bench::environment(budget));
            crate::run::bench::print(&crate::run::bench::learning(budget));
            Ok(())
        }
        RunMode::Eval => {
            let run = cli.eval.clone().expect("eval mode");
            let opts = crate::run::evaluate::EvalOptions {
                run,
                out: cli.eval_out.clone(),
                control: cli.control.unwrap_or_default(),
                counts: counts(&cli)?,
                episodes: cli.episodes.unwrap_or(1),
                steps: cli.steps,
                seed: cli.seed,
                confusion_radius: cli.confusion_radius,
            };
            println!("{}", crate::run::evaluate::evaluate(&opts)?);
            Ok(())
        }
        RunMode::Train | RunMode::Resume => {
            let (scene, run) = match &cli.resume {
                // The run's own scene is loaded by `train`.
                Some(run) => (Scene::preset("paper").expect("preset"), run.clone()),
                None => {
                    let (scene, path) = load_scene(&cli, standard)?;
                    let stem = path.file_stem().map_or("run".into(), |s| s.to_string_lossy().into_owned());
                    let run =
                        cli.out.clone().unwrap_or_else(|| PathBuf::from(format!("runs/{stem}-seed{}", scene.seed)));
                    (scene, run)
                }
            };
            let opts = crate::run::train::TrainOptions {
                run: run.clone(),
                resume: mode == RunMode::Resume,
                overwrite: cli.overwrite,
                episodes: cli.episodes,
                progress: !cli.quiet,
            };
            let summaries = crate::run::train::train(scene, &opts)?;
            eprintln!("coevo: trained {} episodes into {}", summaries.len(), run.display());
            Ok(())
        }
        RunMode::Record => {
            let out = cli.record.clone().expect("record mode");
            let (mut sim, steps, actors) = deployed(&cli, standard)?;
            let existing = if cli.overwrite { Existing::Replace } else { Existing::Refuse };
            crate::run::record::record(&mut sim, steps, &out, existing)?;
            eprintln!("coevo: wrote {steps} steps to {}{actors}", out.display());
            Ok(())
        }
        RunMode::Animate => {
            let out = cli.animate.clone().expect("animate mode");
            if out.extension().is_none_or(|e| e != "gif") {
                return Err(format!("--animate {}: the file must end in .gif", out.display()));
            }
            at_least_one("--steps-per-frame", cli.steps_per_frame)?;
            let size = cli.size.unwrap_or(480);
            if !(64..=2048).contains(&size) {
                return Err(format!("--size {size}: must be within 64..=2048 pixels"));
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
            eprintln!(
                "coevo: wrote {} frames ({steps} steps, {:.1} MB) to {}{actors}; over the clip: polarization {:.3}, milling {:.3}, DoA {:.3}",
                s.frames,
                s.bytes as f64 / 1e6,
                out.display(),
                s.polarization,
                s.milling,
                s.doa
            );
            Ok(())
        }
        RunMode::Experiment => experiment(&cli),
        RunMode::Describe => {
            let path = cli.describe_scene.clone().expect("describe mode");
            let (scene, source) = load_scene(&Cli { scene: Some(path), ..cli.clone() }, standard)?;
            let scene = with_counts(&cli, scene, &source)?;
            print!("{}", crate::sim::species::describe(&scene, &source.display().to_string()));
            Ok(())
        }
        RunMode::Plot => plot(cli.plot.as_deref().expect("plot mode")),
        RunMode::Viewer => viewer(&cli),
    }
}

/// Where experiments are read and their runs written.
const EXPERIMENTS: &str = "experiments";
const RESULTS: &str = "results";

/// `--experiment FILE|all`: run, evaluate and aggregate; then REPRODUCTION.md from every experiment's
/// results so far.
fn experiment(cli: &Cli) -> Result<(), String> {
    use crate::experiment::{aggregate, runner, Experiment};
    let which = cli.experiment.as_deref().expect("experiment mode");
    let files = match which {
        "all" => Experiment::files(Path::new(EXPERIMENTS))?,
        file => vec![PathBuf::from(file)],
    };
    let experiments = files.iter().map(|f| Experiment::load(f, Path::new(RESULTS))).collect::<Result<Vec<_>, _>>()?;
    at_least_one("--jobs", cli.jobs)?;
    if let Some(task) = cli.task {
        match experiments.as_slice() {
            [exp] if task < exp.runs.len() => {}
            [exp] => return Err(format!("--task {task}: {} has runs 0 to {}", exp.file.display(), exp.runs.len() - 1)),
            _ => return Err("--task: names a run of one experiment file, not of `all`".into()),
        }
    }
    if cli.emit_slurm {
        if cli.task.is_some() {
            return Err("--task: not used by --emit-slurm, which writes a job for every run".into());
        }
        let exe = std::env::current_exe().map_err(|e| format!("cannot find the coevo binary: {e}"))?;
        for exp in &experiments {
            let dir = runner::emit_slurm(exp, &exe.to_string_lossy())?;
            println!("{}: {} runs; submit with: bash {}/submit.sh", exp.name, exp.runs.len(), dir.display());
        }
        return Ok(());
    }
    let opts = runner::RunnerOptions {
        exe: std::env::current_exe().map_err(|e| format!("cannot find the coevo binary: {e}"))?,
        jobs: cli.jobs.unwrap_or(2),
        progress: !cli.quiet,
    };
    // Every experiment is attempted; the one error line names the first failure.
    let failed: Vec<String> = experiments.iter().filter_map(|exp| runner::run(exp, &opts, cli.task).err()).collect();
    if let Some(first) = failed.first() {
        let others = match failed.len() {
            1 => String::new(),
            n => format!("; {} more experiments failed", n - 1),
        };
        return Err(format!("{first}{others} (REPRODUCTION.md left as it was)"));
    }
    if cli.task.is_some() {
        return Ok(());
    }
    // REPRODUCTION.md covers the project's experiment files; another file's experiment reports alone.
    if which == "all" || experiments.iter().all(|e| in_experiments_folder(&e.file)) {
        return write_reproduction();
    }
    for exp in &experiments {
        let claims = aggregate::aggregate(exp, &aggregate::load(exp)?)?;
        eprintln!("coevo: wrote {}/summary.csv, summary-mean.csv and figures/ ({} claims checked)", exp.root.display(), claims.len());
    }
    Ok(())
}

/// Whether an experiment file is one of the project's (in ./experiments), whose results REPRODUCTION.md
/// gathers.
fn in_experiments_folder(file: &Path) -> bool {
    let folder = |p: &Path| std::fs::canonicalize(p).ok();
    let parent = file.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new("."));
    folder(parent).is_some_and(|p| Some(p) == folder(Path::new(EXPERIMENTS)))
}

/// Summaries and figures of every experiment with finished runs, and REPRODUCTION.md over all of them.
fn write_reproduction() -> Result<(), String> {
    use crate::experiment::{aggregate, Experiment};
    let mut all = Vec::new();
    for file in Experiment::files(Path::new(EXPERIMENTS))? {
        let exp = Experiment::load(&file, Path::new(RESULTS))?;
        let data = aggregate::load(&exp)?;
        // + 0.0: an empty f64 sum is −0.0, which would print as "-0.0 h".
        let seconds: f64 = data.values().map(|d| d.wall_seconds).sum::<f64>() + 0.0;
        let results = aggregate::aggregate(&exp, &data)?;
        let finished = data.len();
        all.push((exp, results, seconds, finished));
    }
    crate::io::write_file(Path::new("REPRODUCTION.md"), Existing::Replace, aggregate::reproduction(&all).as_bytes())?;
    eprintln!("coevo: wrote REPRODUCTION.md");
    Ok(())
}

/// `--plot DIR`: an experiment's summaries and figures, or one run's learning curves, from CSVs alone.
fn plot(dir: &Path) -> Result<(), String> {
    use crate::experiment::{aggregate, Experiment};
    if dir == Path::new("all") {
        return write_reproduction();
    }
    if crate::run::is_run(dir) {
        let path = crate::experiment::aggregate::plot_run(dir)?;
        eprintln!("coevo: wrote {}", path.display());
        return Ok(());
    }
    let name = dir.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    let file = Path::new(EXPERIMENTS).join(format!("{name}.ron"));
    if !file.exists() {
        return Err(format!("--plot {}: neither a run folder nor the results of an experiment file {}", dir.display(), file.display()));
    }
    let results = dir.parent().unwrap_or(Path::new("."));
    let exp = Experiment::load(&file, results)?;
    let data = aggregate::load(&exp)?;
    if data.is_empty() {
        return Err(format!("--plot {}: no finished run of {} there; nothing written", dir.display(), file.display()));
    }
    let claims = aggregate::aggregate(&exp, &data)?;
    eprintln!("coevo: wrote {}/summary.csv, summary-mean.csv and figures/ ({} claims checked)", exp.root.display(), claims.len());
    Ok(())
}

/// The simulation --record and --animate show: the scene of --run (or --scene) with the counts applied,
/// every species acting exactly as in --eval (trained actors without noise); the steps to run; and a
/// note saying which actors drive it.
fn deployed(cli: &Cli, standard: &Path) -> Result<(crate::sim::Simulation, usize, String), String> {
    if let Some(run) = &cli.run {
        crate::run::RunDir::new(run).check_plugins()?;
    }
    let default = cli.run.as_ref().map_or(standard.to_path_buf(), |r| r.join(crate::run::SCENE));
    let (scene, source) = load_scene(cli, &default)?;
    let mut scene = with_counts(cli, scene, &source)?;
    let steps = cli.steps.unwrap_or(scene.episode_steps);
    scene.episode_steps = steps;
    let sim = crate::learning::simulation(scene.clone(), Mode::Evaluate, cli.run.as_deref())?;
    let actors: Vec<String> = scene
        .species
        .iter()
        .filter_map(|def| match (&def.policy, &cli.run) {
            (Policy::Learned, Some(run)) => Some(format!("{}: trained actor of {}", def.name, run.display())),
            (Policy::Learned, None) => Some(format!("{}: freshly initialized actor of seed {} (untrained: no --run given)", def.name, scene.seed)),
            (Policy::Frozen(path), _) => Some(format!("{}: trained actor of {path}", def.name)),
            _ => None,
        })
        .collect();
    let actors = if actors.is_empty() { String::new() } else { format!(" ({})", actors.join("; ")) };
    Ok((sim, steps, actors))
}

/// --prey, --predators and --count NAME=N, in that order.
fn counts(cli: &Cli) -> Result<Vec<(String, usize)>, String> {
    let mut counts: Vec<(String, usize)> = cli.prey.map(|n| ("prey".to_string(), n)).into_iter().collect();
    counts.extend(cli.predators.map(|n| ("predator".to_string(), n)));
    for c in &cli.count {
        let (name, n) = c.split_once('=').ok_or_else(|| format!("--count {c}: expected NAME=N"))?;
        counts.push((name.to_string(), n.parse().map_err(|_| format!("--count {c}: {n} is not a count"))?));
    }
    Ok(counts)
}

#[cfg(not(feature = "viewer"))]
fn viewer(_: &Cli) -> Result<(), String> {
    Err("choose a mode: --train, --eval RUN, --record OUT.csv or --bench (see --help); the window needs `--features viewer`".into())
}

#[cfg(feature = "viewer")]
fn viewer(cli: &Cli) -> Result<(), String> {
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
    let (scene, source) = load_scene(cli, &default)?;
    let scene = with_counts(cli, scene, &source)?;
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
            return Err(format!("--screenshot {}: the file must end in .png", path.display()));
        }
        let existing = if cli.overwrite { Existing::Replace } else { Existing::Refuse };
        crate::io::check_target(path, existing).map_err(|e| format!("--screenshot {}: {e}", path.display()))?;
    }
    crate::viewer::run(ViewerOptions {
        setup: Setup { scene, source, mode },
        window,
        steps_per_frame: cli.steps_per_frame.unwrap_or(1),
        paused: cli.paused,
        fast: cli.fast,
        trails: cli.trails,
        select: cli.select,
        screenshot: cli.screenshot.clone().map(|path| ScreenshotRequest { path, frames: cli.frames.unwrap_or(60) }),
    })
}
