//! The `coevo` command: headless training, evaluation, recording and benchmarks.

use clap::Parser;
use coevo::scene::Scene;
use coevo::Simulation;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;

/// Predators and prey that learn together: a simulator of Li, Li & Zhao (New J. Phys. 2023).
///
/// Every mode runs headless, driving the fixed-step schedule as fast as it goes.
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

    /// Record a trajectory CSV: step,id,species,x,y,vx,vy,theta,thrust,turn_rate,reward.
    #[arg(long, value_name = "OUT.csv")]
    record: Option<PathBuf>,
    /// Print throughput figures for this machine.
    #[arg(long)]
    bench: bool,
    /// Seconds per benchmark figure.
    #[arg(long, default_value_t = 2.0, value_name = "SECONDS")]
    bench_seconds: f64,
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
    let mut scene = Scene::load(&cli.scene).map_err(|e| e.to_string())?;
    if let Some(seed) = cli.seed {
        scene.seed = seed;
    }
    Ok(scene)
}

fn run(cli: Cli) -> Result<(), String> {
    if cli.bench {
        let budget = Duration::from_secs_f64(cli.bench_seconds.max(0.01));
        coevo::bench::print(&coevo::bench::environment(budget));
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
    Err("choose a mode: --train, --eval RUN, --record OUT.csv or --bench (see --help)".into())
}
