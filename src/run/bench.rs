//! `coevo --bench`: throughput figures on this machine, printed, never asserted in tests.
//!
//! Environment steps per second through the real ECS schedule, one thread, random actions, on the
//! periodic arena: 3+10 and 3+50 on the paper's 2 m arena, 3+1 000 and 3+10 000 on an arena scaled so the
//! density stays that of 3+10.

use crate::scene::{Policy, Scene};
use crate::sim::Simulation;
use std::time::Duration;

/// `--bench` and its own flag.
#[derive(clap::Args, Debug, Clone, Default)]
pub(crate) struct BenchArgs {
    /// Print throughput figures for this machine.
    #[arg(long, help_heading = "Modes")]
    pub(crate) bench: bool,
    /// Seconds per benchmark figure (--bench), in (0, 3600].
    #[arg(long, help_heading = "Modes", value_name = "SECONDS")]
    pub(crate) bench_seconds: Option<f64>,
    /// --bench: also draw the cost of a learned step against group size (its figures, at one density) as
    /// FILE.svg and FILE.png, log–log.
    #[arg(long, help_heading = "Modes", value_name = "FILE", requires = "bench")]
    pub(crate) bench_figure: Option<std::path::PathBuf>,
    /// Instead of the figures, time one short training with this binary and with BINARY (another coevo,
    /// e.g. built from an earlier commit), paired and alternating, and print the CPU-time ratio (--bench)
    #[arg(long, help_heading = "Modes", value_name = "BINARY")]
    pub(crate) bench_against: Option<std::path::PathBuf>,
}

impl super::args::Mode for BenchArgs {
    const MODE: &'static str = "bench";
    const TAKES: &'static [&'static str] = &[];
}

impl BenchArgs {
    /// Seconds per figure (`--bench-seconds`, default 2).
    pub(crate) fn budget(&self) -> crate::error::Result<Duration> {
        let seconds = self.bench_seconds.unwrap_or(2.0);
        if !(seconds > 0.0 && seconds <= 3600.0) {
            return Err(format!("--bench-seconds: must be a number of seconds in (0, 3600] (got {seconds})").into());
        }
        Ok(Duration::from_secs_f64(seconds))
    }

    /// `--bench`: what ran the figures, then the environment, learning and external figures.
    pub(crate) fn main(&self) -> crate::error::Result<()> {
        if let Some(other) = &self.bench_against {
            if self.bench_seconds.is_some() {
                return Err("--bench-seconds: not used by --bench-against (it times whole trainings)".into());
            }
            return super::bench_against::main(other);
        }
        let budget = self.budget()?;
        crate::outln!(
            "coevo {} ({}), {} matrix-product kernels, {} threads, on {}",
            env!("CARGO_PKG_VERSION"),
            env!("COEVO_GIT_COMMIT"),
            crate::learning::nets::kernels(),
            crate::parallel::threads(),
            machine()
        )?;
        print(&environment(budget))?;
        print(&learning(budget))?;
        print(&group_size(budget))?;
        print(&external(budget))
    }
}

/// The machine the figures are of: its CPU model (Linux's /proc/cpuinfo) and how many cores this process
/// may use. Figures from another machine, or this one on a busier day, differ: compare binaries paired on
/// one machine (`--bench-against`).
fn machine() -> String {
    let model = std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|text| {
            text.lines()
                .find(|l| l.starts_with("model name"))
                .map(|l| l.split(':').nth(1).unwrap_or("").trim().to_string())
        })
        .filter(|m| !m.is_empty())
        .unwrap_or_else(|| "an unknown CPU".into());
    let cores = std::thread::available_parallelism().map_or(0, |n| n.get());
    format!("{model}, {cores} cores available")
}

/// One measured configuration.
pub(crate) struct Figure {
    pub(crate) label: String,
    pub(crate) per_second: f64,
    pub(crate) unit: &'static str,
}

/// The scene used for environment benchmarks: random policies, `predators` + `prey` agents, the arena
/// edge scaled to keep the 3+10 density when `keep_density`.
pub fn bench_scene(predators: usize, prey: usize, keep_density: bool) -> Scene {
    let mut scene = Scene::preset("paper").expect("paper preset exists");
    scene.species[0].count = predators;
    scene.species[1].count = prey;
    for s in &mut scene.species {
        s.policy = Policy::Random;
    }
    if keep_density {
        scene.world.arena_edge = 2.0 * ((predators + prey) as f64 / 13.0).sqrt();
    }
    scene.episode_steps = usize::MAX;
    scene
}

/// Environment steps per second for the four populations.
pub(crate) fn environment(budget: Duration) -> Vec<Figure> {
    [(3, 10, false), (3, 50, false), (3, 1_000, true), (3, 10_000, true)]
        .into_iter()
        .map(|(p, e, scaled)| {
            let mut sim = Simulation::new(bench_scene(p, e, scaled));
            for _ in 0..10 {
                sim.step(); // warm the grids and batches
            }
            let edge = sim.world().resource::<crate::sim::ActiveScene>().0.world.arena_edge;
            Figure {
                label: format!("environment step, {p}+{e} agents, arena {edge:.1} m, random actions"),
                per_second: crate::parallel::per_second(budget, 20, || sim.step()),
                unit: "steps/s",
            }
        })
        .collect()
}

/// A step of the default scene's learned actors (untrained weights, evaluation mode: one batched forward
/// pass per species, no learning) against group size at one density, as `experiments/group-size.ron`
/// deploys them: prey with predators in the share 3 per 50 (at least 1), the arena's edge
/// 2 √(agents / 53) m (53 agents in 2 m), the metrics every step as an evaluation records them.
pub(crate) fn group_size(budget: Duration) -> Vec<Figure> {
    group_size_steps(budget).into_iter().map(|(.., figure)| figure).collect()
}

/// [`group_size`]'s figures with the prey and the predators of each.
pub(crate) fn group_size_steps(budget: Duration) -> Vec<(usize, usize, Figure)> {
    GROUP_SIZES
        .into_iter()
        .map(|prey| {
            let predators = ((3 * prey) as f64 / 50.0).round().max(1.0) as usize;
            let overrides = crate::scene::Overrides {
                counts: vec![("prey".into(), prey), ("predator".into(), predators)],
                arena_edge: Some(2.0 * ((prey + predators) as f64 / 53.0).sqrt()),
                ..Default::default()
            };
            let mut scene = super::args::load_scene(std::path::Path::new("scenes/standard.ron"), &overrides)
                .expect("the default scene is built in");
            scene.episode_steps = usize::MAX;
            let mut sim =
                crate::run::simulation(scene, crate::learning::Mode::Evaluate, None).expect("no checkpoint needed");
            for _ in 0..3 {
                sim.step(); // warm the grids and batches
            }
            let figure = Figure {
                label: format!("group size: learned step, {prey} prey + {predators} predators at one density"),
                per_second: crate::parallel::per_second(budget, 3, || sim.step()),
                unit: "steps/s",
            };
            (prey, predators, figure)
        })
        .collect()
}

/// The prey of [`group_size`]'s figures.
pub const GROUP_SIZES: [usize; 7] = [10, 50, 200, 1_000, 2_000, 5_000, 10_000];

/// Stepping from outside (`run::env`, what the Python package drives): one world of the standard scene,
/// and 8, 64 and 1 024 worlds stepped together (parked on shared apps, `run::env::pool`), constant actions;
/// world steps per second summed over worlds.
pub(crate) fn external(budget: Duration) -> Vec<Figure> {
    use crate::run::env::{Env, VecEnv};
    let scene = || {
        Scene::load(std::path::Path::new("scenes/standard.ron")).unwrap_or_else(|_| {
            let mut s = Scene::preset("gym-pps").expect("gym-pps preset exists");
            s.observation_frame = crate::scene::ObservationFrame::Body;
            s
        })
    };
    let mut figures = vec![];
    if let Ok(mut env) = Env::new(scene()) {
        let actions = vec![0.5; env.agents().len() * 2];
        figures.push(Figure {
            label: "external env step, 3+10 agents (run::env::Env)".into(),
            per_second: crate::parallel::per_second(budget, 20, || {
                if env.step(&actions).is_ok_and(|r| r.truncated) {
                    let _ = env.reset(None);
                }
            }),
            unit: "steps/s",
        });
    }
    // On one thread and on all of them (--threads), since other work on the machine can make more threads
    // slower than one (the benchmarks page measures both idle and under load).
    let all = crate::parallel::threads();
    for n in [8, 64, 1024] {
        for threads in if all > 1 { vec![1, all] } else { vec![1] } {
            let Ok(mut worlds) = VecEnv::new(scene(), n, 1) else { continue };
            let actions = vec![0.5; worlds.worlds() * worlds.agents() * 2];
            crate::parallel::set_threads(threads);
            let rate = n as f64
                * crate::parallel::per_second(budget, 5, || {
                    let _ = worlds.step(&actions);
                });
            crate::parallel::set_threads(all);
            figures.push(Figure {
                label: format!(
                    "external VecEnv, {n} worlds of 3+10, {threads} thread{} (world steps summed)",
                    if threads == 1 { "" } else { "s" }
                ),
                per_second: rate,
                unit: "steps/s",
            });
        }
    }
    figures
}

pub(crate) fn print(figures: &[Figure]) -> crate::error::Result<()> {
    for f in figures {
        crate::outln!("{:<72} {:>12.0} {}", f.label, f.per_second, f.unit)?;
    }
    Ok(())
}

/// The update's largest product, a batch of 256 through a 64-wide layer (256 × 64 × 64), on this process's
/// kernel family, beside the core's fused multiply-add peak: how far faster kernels could go.
fn products(budget: Duration) -> Vec<Figure> {
    let (m, n, k) = (256, 64, 64);
    let (x, w) = (vec![0.5f32; m * k], vec![0.25f32; k * n]);
    let mut z = vec![0.0f32; m * n];
    let flop = 2.0 * (m * n * k) as f64 / 1e9;
    let mut figures = vec![Figure {
        label: format!("matrix product {m} × {k} · {k} × {n} ({} kernels)", crate::learning::nets::kernels()),
        per_second: flop
            * crate::parallel::per_second(budget, 20, || {
                // SAFETY: z is m × n, x m × k, w k × n, all row-major.
                unsafe {
                    crate::learning::fused::product(
                        m,
                        n,
                        k,
                        z.as_mut_ptr(),
                        n,
                        false,
                        x.as_ptr(),
                        (k, 1),
                        w.as_ptr(),
                        (n, 1),
                    )
                };
                std::hint::black_box(&mut z);
            }),
        unit: "GFLOP/s",
    }];
    if let Some(peak) = crate::learning::direct::fma_peak(budget) {
        figures.push(Figure {
            label: "this core's fused multiply-add peak (12 independent chains)".into(),
            per_second: peak / 1e9,
            unit: "GFLOP/s",
        });
    }
    // The avx512-bf16 family's products read against the bf16 instruction's own peak.
    if crate::learning::nets::own_kernels() == crate::learning::nets::Own::Bf16 {
        if let Some(peak) = crate::learning::bf16::dot_peak(budget) {
            figures.push(Figure {
                label: "this core's bf16 dot-product peak (12 independent chains of VDPBF16PS)".into(),
                per_second: peak / 1e9,
                unit: "GFLOP/s",
            });
        }
    }
    figures
}

/// Learning figures: one DDPG update per species at batch 256, batched actor inference, and a policy
/// (evaluation mode: one batched forward pass per species per step) driving 3 + 10 000 agents.
pub(crate) fn learning(budget: Duration) -> Vec<Figure> {
    use crate::learning::{ddpg::Ddpg, nets::Dev, replay::Batch, Mode};
    use rand::{Rng, SeedableRng};
    let dev = Dev::default();
    let params = Scene::preset("paper").expect("paper preset exists").learning;
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(0);
    let mut ddpg = Ddpg::new(&dev, 54, &params, &mut rng);
    let mut draw = |k: usize| (0..k).map(|_| rng.gen_range(-1.0f32..1.0)).collect::<Vec<f32>>();
    let batch = Batch { n: 256, obs: draw(256 * 54), actions: draw(512), rewards: draw(256), next_obs: draw(256 * 54) };
    let mut figures = products(budget);
    figures.push(Figure {
        label: "DDPG update (critic + actor + soft update), batch 256, d_o 54".into(),
        per_second: crate::parallel::per_second(budget, 20, || {
            ddpg.update(&batch);
        }),
        unit: "updates/s",
    });
    for n in [13, 50, 1_000, 10_000] {
        let (obs, mut actions) = (draw(n * 54), vec![0.0; n * 2]);
        figures.push(Figure {
            label: format!("batched actor inference, {n} agents"),
            per_second: crate::parallel::per_second(budget, 20, || ddpg.act_into(&dev, &obs, &mut actions)),
            unit: "passes/s",
        });
    }
    let mut scene = bench_scene(3, 10_000, true);
    for s in &mut scene.species {
        s.policy = Policy::Learned;
    }
    let mut sim = crate::run::simulation(scene, Mode::Evaluate, None).expect("no checkpoint needed");
    figures.push(Figure {
        label: "policy-driven step, 3+10000 agents (untrained weights)".into(),
        per_second: crate::parallel::per_second(budget, 5, || sim.step()),
        unit: "steps/s",
    });
    figures
}
