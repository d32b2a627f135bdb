//! The `coevo` command: headless training, evaluation, recording and benchmarks.

use clap::Parser;
use coevo::scene::Scene;
use coevo::Simulation;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;

/// Predators and prey that learn together: a simulator of Li, Li & Zhao (New J. Phys. 2023).
///
/// Every mode but the viewer runs headless, driving the fixed-step schedule as fast as it goes.
/// Built with `--features viewer` and given no headless mode, it opens the window instead.
/// Scenes are RON files under scenes/ (see README, "Scenes").
#[derive(Parser, Debug)]
#[command(name = "coevo", version, about, long_about = None)]
struct Cli {
    /// Scene file to run.
    #[arg(long, default_value = "scenes/standard.ron", value_name = "PATH")]
    scene: PathBuf,
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
    /// Run folder for --train (default runs/<scene>-seed<seed>).
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
    /// Continue a killed or finished run from its last checkpoint (to --episodes in total).
    #[arg(long, value_name = "DIR")]
    resume: Option<PathBuf>,
    /// Evaluate a run's policies without noise; writes DIR/eval.csv (per-step DoS/DoA).
    #[arg(long, value_name = "DIR")]
    eval: Option<PathBuf>,
    /// Number of prey for --eval (the paper evaluates on 50).
    #[arg(long, value_name = "N")]
    prey: Option<usize>,
    /// Number of predators for --eval (0 removes them, as in the paper's Fig. 5a).
    #[arg(long, value_name = "N")]
    predators: Option<usize>,
    /// Any species' count for --eval, as NAME=N (repeatable).
    #[arg(long, value_name = "NAME=N")]
    count: Vec<String>,
    /// No progress bar.
    #[arg(long)]
    quiet: bool,

    /// Record a trajectory CSV: step,id,species,x,y,vx,vy,theta,thrust,turn_rate,reward.
    #[arg(long, value_name = "OUT.csv")]
    record: Option<PathBuf>,
    /// Print throughput figures for this machine.
    #[arg(long)]
    bench: bool,
    /// Seconds per benchmark figure.
    #[arg(long, default_value_t = 2.0, value_name = "SECONDS")]
    bench_seconds: f64,

    /// Viewer: watch a run's trained actors (its scene.ron, with --prey/--predators/--count applied).
    #[arg(long, value_name = "DIR")]
    watch: Option<PathBuf>,
    /// Viewer: replace learned species by the paper's rule-based chase and flee.
    #[arg(long)]
    rules: bool,
    /// Viewer: render --frames frames, save a PNG here and exit.
    #[arg(long, value_name = "PATH.png")]
    screenshot: Option<PathBuf>,
    /// Viewer: frames to render before --screenshot.
    #[arg(long, default_value_t = 60, value_name = "N")]
    frames: usize,
    /// Viewer: window size in pixels.
    #[arg(long, default_value = "1280x720", value_name = "WxH")]
    window: String,
    /// Viewer: fixed steps per rendered frame.
    #[arg(long, default_value_t = 1, value_name = "N")]
    steps_per_frame: usize,
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

fn main() -> ExitCode {
    let cli = Cli::parse();
    match run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(message) => {
            eprintln!("coevo: error: {message}");
            ExitCode::FAILURE
        }
    }
}

fn load_scene(cli: &Cli) -> Result<Scene, String> {
    load_scene_from(cli, &cli.scene)
}

/// A scene file with --seed applied.
fn load_scene_from(cli: &Cli, path: &std::path::Path) -> Result<Scene, String> {
    let mut scene = Scene::load(path).map_err(|e| e.to_string())?;
    if let Some(seed) = cli.seed {
        scene.seed = seed;
    }
    Ok(scene)
}

fn run(cli: Cli) -> Result<(), String> {
    if cli.bench {
        let budget = Duration::from_secs_f64(cli.bench_seconds.max(0.01));
        coevo::bench::print(&coevo::bench::environment(budget));
        coevo::bench::print(&coevo::bench::learning(budget));
        return Ok(());
    }
    if let Some(run) = &cli.eval {
        let counts = counts(&cli)?;
        let opts = coevo::train::EvalOptions { run: run.clone(), counts, episodes: cli.episodes.unwrap_or(1), steps: cli.steps, seed: cli.seed };
        println!("{}", coevo::train::evaluate(&opts)?);
        return Ok(());
    }
    if cli.train || cli.resume.is_some() {
        let (scene, run) = match &cli.resume {
            Some(run) => (Scene::preset("paper").expect("preset"), run.clone()),
            None => {
                let scene = load_scene(&cli)?;
                let stem = cli.scene.file_stem().map_or("run".into(), |s| s.to_string_lossy().into_owned());
                let run = cli.out.clone().unwrap_or_else(|| PathBuf::from(format!("runs/{stem}-seed{}", scene.seed)));
                (scene, run)
            }
        };
        let opts = coevo::train::TrainOptions { run: run.clone(), resume: cli.resume.is_some(), episodes: cli.episodes, progress: !cli.quiet };
        let summaries = coevo::train::train(scene, &opts)?;
        eprintln!("coevo: trained {} episodes into {}", summaries.len(), run.display());
        return Ok(());
    }
    if let Some(out) = &cli.record {
        let mut scene = load_scene(&cli)?;
        let steps = cli.steps.unwrap_or(scene.episode_steps);
        scene.episode_steps = steps.max(1);
        let mut sim = Simulation::new(scene);
        coevo::record::record(&mut sim, steps, out).map_err(|e| format!("{}: {e}", out.display()))?;
        eprintln!("coevo: wrote {} steps to {}", steps, out.display());
        return Ok(());
    }
    viewer(&cli)
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
    use coevo::viewer::{RunMode, ScreenshotRequest, Setup, ViewerOptions};
    let (source, mode) = match &cli.watch {
        Some(run) => (run.join("scene.ron"), RunMode::Watch(run.clone())),
        None => (cli.scene.clone(), if cli.rules { RunMode::RuleBased } else { RunMode::LiveTraining }),
    };
    let mut scene = load_scene_from(cli, &source)?;
    for (name, n) in counts(cli)? {
        scene.set_count(&name, n).map_err(|e| format!("{}: {e}", source.display()))?;
    }
    let window = cli
        .window
        .split_once('x')
        .and_then(|(w, h)| Some(bevy::math::UVec2::new(w.parse().ok()?, h.parse().ok()?)))
        .filter(|s| s.x >= 320 && s.y >= 240)
        .ok_or_else(|| format!("--window {}: expected WxH of at least 320x240, e.g. 1280x720", cli.window))?;
    if let Some(path) = &cli.screenshot {
        if path.extension().is_none_or(|e| e != "png") {
            return Err(format!("--screenshot {}: the file must end in .png", path.display()));
        }
    }
    coevo::viewer::run(ViewerOptions {
        setup: Setup { scene, source, mode },
        window,
        steps_per_frame: cli.steps_per_frame,
        paused: cli.paused,
        fast: cli.fast,
        trails: cli.trails,
        select: cli.select,
        screenshot: cli.screenshot.clone().map(|path| ScreenshotRequest { path, frames: cli.frames.max(1) }),
    })
}
