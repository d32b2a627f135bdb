//! `coevo --eval RUN`: a run's trained actors deployed without noise (the paper's "loading trained
//! policies on agents"), optionally under an observation control. Writes the per-step file (DoS, DoA and
//! the order parameters of the headline species, catches) and four files beside it: the
//! nearest-neighbour distances (`-nn`), the heading correlation C(r) (`-correlation`), where the
//! predators head and the prey gather per step (`-pursuit`) and the confusion curve (`-confusion`, written
//! last: its presence marks a complete evaluation).
//!
//! The loop accumulates ([`Accumulated::step`]); the files and the summary line are written from what it
//! accumulated ([`Accumulated::distributions`], [`Accumulated::summary`]).

use super::args::Shared;
use crate::io::{AtomicFile, Existing};
use crate::learning::control::ObservationControl;
use crate::learning::Mode;
use crate::scene::Overrides;
use crate::sim::clock::Episode;
use crate::sim::collective::{
    add_heading_correlation, confusion_bin_label, heading_correlation, pursuit_targets, steering,
};
use crate::sim::metrics::{Confusion, SwarmMetrics, Swarming};
use crate::sim::perception::Population;
use crate::sim::space::Arena;
use crate::sim::species::SpeciesRegistry;
use crate::sim::Simulation;
use crate::store::folder::RunDir;
use crate::store::schema::{self, blank};
use bevy::math::DVec2;
use std::io::Write;
use std::path::{Path, PathBuf};

/// The nearest-neighbour distance histogram: bins of this many body diameters, NN_BINS of them and one
/// for everything beyond.
const NN_BIN_DIAMETERS: f64 = 0.25;
const NN_BINS: usize = 80;

#[derive(Clone, Debug, PartialEq)]
pub struct EvalOptions {
    pub run: PathBuf,
    /// What the actors see of their neighbours (a control for alignment claims).
    pub control: ObservationControl,
    /// File name of the per-step CSV inside the run folder (default `eval.csv`).
    pub out: Option<String>,
    pub episodes: usize,
    /// Counts, seed, steps per episode and confusion radius for the evaluation (default: the run's).
    pub overrides: Overrides,
    /// Deploy the actors as initialised before training (from the run's scene and seed), not the trained
    /// checkpoint: the baseline of what training changed.
    pub untrained: bool,
    /// Deploy these species' snapshots (`NAME`, episodes trained) instead of the trained checkpoint.
    pub snapshots: Vec<(String, usize)>,
    /// Also run a twin world in which one prey is turned by this many radians, and write the others'
    /// response ([`super::perturb`])...
    pub perturb: Option<f64>,
    /// ... after this step of each episode (default: half the episode).
    pub perturb_step: Option<usize>,
}

/// `--eval RUN`: the evaluation's own flags.
#[derive(clap::Args, Debug, Clone, Default)]
pub(crate) struct EvalArgs {
    /// Evaluate a run's policies without noise; writes DIR/eval.csv (per-step DoS/DoA).
    #[arg(long, help_heading = "Modes", value_name = "DIR")]
    pub(crate) eval: Option<PathBuf>,
    /// --eval: what the actors see of their neighbours (controls for alignment claims) [default: seeing].
    /// `blind` zeroes, `shuffled` swaps between individuals, every neighbour block of every learning
    /// species; `blind:OBSERVER:OBSERVED` / `shuffled:OBSERVER:OBSERVED` only the block in which species
    /// OBSERVER sees species OBSERVED (`blind:prey:prey`: prey blind to each other, still seeing the
    /// predators; the predators untouched). Block forms repeat: --control blind:prey:prey --control ...
    #[arg(long, help_heading = "Evaluation", value_name = "CONTROL")]
    pub(crate) control: Vec<String>,
    /// --eval: also run a twin world in which one prey is turned by this many radians, and write how the
    /// other prey's headings respond, by topological rank and lag, to NAME-perturbation.csv (information
    /// transfer; not in the paper).
    #[arg(long, help_heading = "Evaluation", value_name = "RADIANS")]
    pub(crate) perturb: Option<f64>,
    /// --eval --perturb: the step of each episode after which the prey is turned [default: half the episode].
    #[arg(long, help_heading = "Evaluation", value_name = "N")]
    pub(crate) perturb_step: Option<usize>,
    /// --eval: the file name of the per-step CSV inside the run folder [default: eval.csv].
    #[arg(long, help_heading = "Evaluation", value_name = "NAME.csv")]
    pub(crate) eval_out: Option<String>,
    /// --eval: prey within this many metres of a predator count as in view for the confusion curve
    /// (NAME-confusion.csv) [default: the scene's confusion_radius, else the perception radius].
    #[arg(long, help_heading = "Evaluation", value_name = "M")]
    pub(crate) confusion_radius: Option<f64>,
    /// --eval: the arena's edge in metres [default: the run's]: a larger group at the density of a smaller
    /// one (not in the paper).
    #[arg(long, help_heading = "Evaluation", value_name = "M")]
    pub(crate) arena_edge: Option<f64>,
    /// --eval: deploy the run's actors as they were before training (initialised from the run's scene and
    /// seed), the baseline of what training changed.
    #[arg(long, help_heading = "Evaluation")]
    pub(crate) untrained: bool,
}

impl super::args::Mode for EvalArgs {
    const MODE: &'static str = "eval";
    const TAKES: &'static [&'static str] =
        &["episodes", "steps", "seed", "prey", "predators", "count", "snapshot", "policy"];
}

impl EvalArgs {
    /// The evaluation of `run` the flags ask for.
    pub(crate) fn options(&self, run: &Path, shared: &Shared) -> crate::error::Result<EvalOptions> {
        let (scene, common) = (&shared.scene, &shared.common);
        if self.untrained && scene.seed.is_some() {
            return Err("--untrained: deploys the networks the run was initialised with, from the run's seed; --seed would initialise others".into());
        }
        let snapshots = scene.snapshots(Some(run), "--eval")?;
        if self.untrained && !snapshots.is_empty() {
            return Err("--untrained: deploys the networks the run was initialised with; --snapshot deploys others (the initial ones are --snapshot NAME=0)".into());
        }
        Ok(EvalOptions {
            run: run.to_path_buf(),
            out: self.eval_out.clone(),
            control: ObservationControl::parse(&self.control).map_err(|e| format!("--control: {e}"))?,
            episodes: common.episodes.unwrap_or(1),
            overrides: Overrides {
                confusion_radius: self.confusion_radius,
                arena_edge: self.arena_edge,
                ..scene.overrides(true)?
            },
            untrained: self.untrained,
            snapshots,
            perturb: self.perturb,
            perturb_step: self.perturb_step,
        })
    }
}

impl EvalOptions {
    /// The call that runs this evaluation, as argv.
    pub(crate) fn to_argv(&self) -> Vec<String> {
        let mut argv =
            vec!["--eval".into(), self.run.display().to_string(), "--episodes".into(), self.episodes.to_string()];
        argv.extend(super::args::overrides_argv(&self.overrides, &self.snapshots));
        let mut flag =
            |name: &str, value: Option<String>| argv.extend(value.map(|v| [name.to_string(), v]).into_iter().flatten());
        for form in self.control.texts() {
            flag("--control", Some(form));
        }
        flag("--perturb", self.perturb.map(|a| a.to_string()));
        flag("--perturb-step", self.perturb_step.map(|s| s.to_string()));
        flag("--confusion-radius", self.overrides.confusion_radius.map(|r| r.to_string()));
        flag("--arena-edge", self.overrides.arena_edge.map(|r| r.to_string()));
        flag("--eval-out", self.out.clone());
        if self.untrained {
            argv.push("--untrained".into());
        }
        argv
    }
}

/// What the evaluation accumulates over its steps, of the headline species.
struct Accumulated {
    /// Sums of the order parameters of [`crate::sim::metrics::Swarming::NAMES`] over the steps that have them.
    sums: [f64; Swarming::N],
    steps: usize,
    /// Edge rank of every ranked catch.
    ranks: Vec<f64>,
    diameter: f64,
    nn_histogram: Vec<u64>,
    /// C(r) of heading fluctuations in bins of one body diameter, out to half the arena's edge.
    correlation: Vec<(f64, u64)>,
    variance: (f64, u64),
    /// The `-pursuit` file's rows so far.
    pursuit: String,
    /// The first species that catches the headline species, and the radius of the prey it has in view
    /// (the confusion curve's).
    pursuer: Option<(usize, f64)>,
    /// Each of its agents' heading and targets at the previous state ([`pursuit_targets`]): the decision
    /// taken there is the turn read at this step.
    targets: Vec<Option<(DVec2, [DVec2; 3])>>,
}

/// The band along the walls of the `-pursuit` file's boundary share, as a fraction of the arena's edge:
/// the outer tenth on each side, 36 % of the area.
pub(crate) const BOUNDARY_BAND: f64 = 0.1;

/// The `-pursuit` file's header. Per step: the predators of the first species that catches the headline
/// species that had three or more of it in view at the state where they took the decision applied in this
/// step (`pursuers`); their mean [`steering`] toward the centre of those prey, the most isolated of them
/// and the nearest ([`pursuit_targets`]), each in [−1, 1] (1: every turn toward it, 0: as often away); and
/// the share of the headline species within [`BOUNDARY_BAND`] × edge of a wall (empty on the torus).
pub(crate) const PURSUIT_HEADER: &str =
    "episode,step,pursuers,steer_centre,steer_isolated,steer_nearest,boundary_share";

impl Accumulated {
    fn new(diameter: f64, arena: &Arena, pursuer: Option<(usize, f64)>) -> Accumulated {
        Accumulated {
            sums: [0.0; Swarming::N],
            steps: 0,
            ranks: Vec::new(),
            diameter,
            nn_histogram: vec![0; NN_BINS + 1],
            correlation: vec![(0.0, 0); (arena.edge / 2.0 / diameter).ceil().max(1.0) as usize],
            variance: (0.0, 0),
            pursuit: format!("{PURSUIT_HEADER}\n"),
            pursuer,
            targets: Vec::new(),
        }
    }

    /// Adds the step just simulated; returns its row of the per-step file.
    fn step(&mut self, sim: &Simulation, prey: usize, catchers: &[usize], episode: usize, step: usize) -> String {
        let world = sim.world();
        let m = world.resource::<SwarmMetrics>();
        let sw = m.now.get(prey).copied().flatten();
        let step_ranks = &m.edge_ranks_now[prey];
        let edge_rank = (!step_ranks.is_empty()).then(|| step_ranks.iter().sum::<f64>() / step_ranks.len() as f64);
        let row = schema::eval_row(
            episode,
            step,
            sw,
            edge_rank,
            m.catches_now,
            catchers.iter().map(|&s| m.catches_now_by[s]),
        );
        if let Some(sw) = sw {
            self.sums.iter_mut().zip(sw.values()).for_each(|(a, v)| *a += v);
            self.steps += 1;
        }
        self.ranks.extend_from_slice(step_ranks);
        for d in &m.nn_distances_now[prey] {
            self.nn_histogram[((d / self.diameter / NN_BIN_DIAMETERS) as usize).min(NN_BINS)] += 1;
        }
        let pop = world.resource::<Population>();
        let range = pop.ranges[prey].clone();
        let arena = world.resource::<Arena>();
        add_heading_correlation(
            arena,
            &pop.position[range.clone()],
            &pop.heading[range],
            self.diameter,
            &mut self.correlation,
            &mut self.variance,
        );
        self.add_pursuit(pop, arena, &m.nn_distances_now[prey], prey, episode, step);
        row
    }

    /// The step's row of the `-pursuit` file: the decisions applied in this step against the targets at
    /// the state they were taken in (none at an episode's first step, whose previous state was another
    /// episode's); then this state's targets, for the next step.
    fn add_pursuit(&mut self, pop: &Population, arena: &Arena, nn: &[f64], prey: usize, episode: usize, step: usize) {
        let prey_at = &pop.position[pop.ranges[prey].clone()];
        let mut sums = [0.0; 3];
        let mut pursuers = 0usize;
        if let Some((s, radius)) = self.pursuer {
            let agents = pop.ranges[s].clone();
            if step > 1 && self.targets.len() == agents.len() {
                for (i, before) in agents.clone().zip(&self.targets) {
                    if let Some((heading, targets)) = before {
                        sums.iter_mut().zip(targets).for_each(|(a, t)| *a += steering(*heading, *t, pop.turn[i]));
                        pursuers += 1;
                    }
                }
            }
            self.targets = agents
                .map(|i| pursuit_targets(arena, pop.position[i], prey_at, nn, radius).map(|t| (pop.heading[i], t)))
                .collect();
        }
        let means = sums.map(|x| (pursuers > 0).then(|| x / pursuers as f64));
        let band = crate::sim::collective::boundary_share(arena, prey_at, BOUNDARY_BAND * arena.edge);
        self.pursuit.push_str(&format!(
            "{episode},{step},{pursuers},{},{},{},{}\n",
            blank(means[0]),
            blank(means[1]),
            blank(means[2]),
            blank(band)
        ));
    }

    /// The `-nn`, `-correlation`, `-pursuit` and `-confusion` files, in that order, and the correlation
    /// length.
    fn distributions(&self, sim: &Simulation, registry: &SpeciesRegistry) -> ([String; 4], Option<f64>) {
        let total = self.nn_histogram.iter().sum::<u64>().max(1) as f64;
        let mut nn = String::from("from_diameters,to_diameters,from_m,to_m,fraction\n");
        for (b, count) in self.nn_histogram.iter().enumerate() {
            let (lo, hi) = (
                b as f64 * NN_BIN_DIAMETERS,
                if b == NN_BINS { f64::INFINITY } else { (b + 1) as f64 * NN_BIN_DIAMETERS },
            );
            nn.push_str(&format!(
                "{lo},{hi},{},{},{}\n",
                lo * self.diameter,
                hi * self.diameter,
                *count as f64 / total
            ));
        }
        let (c_of_r, correlation_length) = heading_correlation(&self.correlation, self.variance, self.diameter);
        let mut correlation = String::from("from_m,to_m,pairs,c\n");
        for (b, (c, &(_, pairs))) in c_of_r.iter().zip(&self.correlation).enumerate() {
            correlation.push_str(&format!(
                "{},{},{pairs},{}\n",
                b as f64 * self.diameter,
                (b + 1) as f64 * self.diameter,
                blank(*c)
            ));
        }
        let curve = sim.world().resource::<Confusion>();
        let mut confusion =
            String::from("species,prey_in_view,samples,mean_abs_turn,mean_speed_fraction,catches_per_step\n");
        for (s, bins) in curve.0.iter().enumerate().filter(|(s, _)| registry.prey_of(*s).next().is_some()) {
            for (b, bin) in bins.iter().enumerate() {
                let (turn, speed, catches) =
                    bin.means().map_or([None; 3], |(t, v, c)| [Some(t), Some(v), Some(c)]).into();
                confusion.push_str(&format!(
                    "{},{},{},{},{},{}\n",
                    registry.defs[s].name,
                    confusion_bin_label(b),
                    bin.samples,
                    blank(turn),
                    blank(speed),
                    blank(catches)
                ));
            }
        }
        ([nn, correlation, self.pursuit.clone(), confusion], correlation_length)
    }

    /// The means over the evaluation, in words.
    /// The summary line's means, each beside its value by chance (`random_dos`: DoS of uniform random
    /// positions at this count and arena): a level is read against chance, not alone.
    fn summary(&self, name: &str, correlation_length: Option<f64>, random_dos: Option<f64>) -> String {
        if self.steps == 0 {
            return format!("no DoS/DoA: fewer than two {name}");
        }
        let [dos, doa, polarization, milling, clusters, largest, c_nn] = self.sums.map(|v| v / self.steps as f64);
        let edge = if self.ranks.is_empty() {
            "no ranked catch".to_string()
        } else {
            format!(
                "edge rank of caught {name} {:.3} (at random 0.5; {} catches)",
                self.ranks.iter().sum::<f64>() / self.ranks.len() as f64,
                self.ranks.len()
            )
        };
        let random = random_dos.map_or(String::new(), |r| format!(" (random positions {r:.3})"));
        format!(
            "mean DoS {dos:.4}{random}, DoA {doa:.4} (random headings 0.637), polarization {polarization:.3}, milling {milling:.3}, \
             {clusters:.1} clusters (largest {:.0} %), C_nn {c_nn:.3} (independent headings 0), correlation length {}, {edge} ({name})",
            100.0 * largest,
            correlation_length.map_or("beyond half the arena".to_string(), |xi| format!("{xi:.3} m (where the heading fluctuations' C(r) first crosses 0)"))
        )
    }
}

/// Every file an evaluation writing `path` makes, checked before its episodes run (a folder or a FIFO at
/// eval-nn.csv is refused now, not after eval.csv was replaced).
fn check_outputs(path: &Path, opts: &EvalOptions) -> crate::error::Result<()> {
    let mut outputs = vec![path.to_path_buf()];
    outputs.extend(crate::store::folder::EVAL_BESIDE.iter().map(|what| crate::io::beside(path, what)));
    if opts.perturb.is_some() {
        outputs.push(crate::io::beside(path, crate::store::folder::PERTURBATION));
    }
    crate::io::check_targets(&outputs, Existing::Replace)
}

/// The perturbation `--perturb` and `--perturb-step` ask for, checked against the episode's `steps`; None
/// without `--perturb`.
fn perturbation(opts: &EvalOptions, steps: usize) -> crate::error::Result<Option<super::perturb::Perturbation>> {
    let Some(angle) = opts.perturb else { return Ok(None) };
    let p = super::perturb::Perturbation { angle, step: opts.perturb_step.unwrap_or(steps / 2) };
    if p.step == 0 || p.step >= steps {
        return Err(format!(
            "--perturb-step {}: must be between 1 and the episode's steps − 1 ({})",
            p.step,
            steps - 1
        )
        .into());
    }
    if !p.angle.is_finite() || p.angle == 0.0 {
        return Err(format!("--perturb {}: must be a finite, non-zero angle in radians", p.angle).into());
    }
    Ok(Some(p))
}

/// Each species with its count (species names are not pluralized: "prey: 50", not "50 prey"), a replaced
/// policy beside it: "predator: 3 (ChaseNearest), prey: 50".
fn counts_shown(opts: &EvalOptions, registry: &SpeciesRegistry) -> String {
    registry
        .defs
        .iter()
        .map(|d| match opts.overrides.policies.iter().any(|(name, _)| *name == d.name) {
            // As a scene file or --policy writes it (a fitted rule with all its numbers).
            true => format!("{}: {} ({})", d.name, d.count, ron::to_string(&d.policy).unwrap_or_default()),
            false => format!("{}: {}", d.name, d.count),
        })
        .collect::<Vec<_>>()
        .join(", ")
}

/// Deploys a run's policies without noise and streams per-step DoS/DoA to `RUN/eval.csv` (replaced
/// whole, when complete); returns the summary line.
pub fn evaluate(opts: &EvalOptions) -> crate::error::Result<String> {
    if opts.perturb.is_none() && opts.perturb_step.is_some() {
        return Err("--perturb-step: needs --perturb RADIANS".into());
    }
    let dir = RunDir::new(&opts.run);
    let path = dir.eval_output(opts.out.as_deref())?;
    // An evaluation replaces its files whole; the line says so when an earlier one was there.
    let replaced = path.exists();
    if !dir.is_run() {
        let what = if opts.run.exists() { "holds no coevo run to evaluate" } else { "no such folder" };
        return Err(format!("{}: {what}", opts.run.display()).into());
    }
    dir.check_plugins()?;
    if opts.episodes == 0 {
        return Err("--episodes: must be ≥ 1".into());
    }
    // Nobody else writes the run while it is evaluated (a training would swap its checkpoint), and what a
    // killed process left (a checkpoint swap cut short) is put right before the actors are read.
    let _lock = dir.lock()?;
    check_outputs(&path, opts)?;
    let scene = opts.overrides.load(&dir.scene())?;
    let trained = (!opts.untrained).then_some(opts.run.as_path());
    let build = || -> crate::error::Result<Simulation> {
        let mut learners = crate::learning::Learners::new(&scene, Mode::Evaluate);
        crate::store::load_actors(&mut learners, &scene, trained)?;
        crate::store::load_snapshots(&mut learners, &scene, &opts.run, &opts.snapshots)?;
        crate::learning::simulation_of(scene.clone(), learners, |_| {})
    };
    super::progress::announce_cost(&scene, opts.episodes * scene.episode_steps)?;
    let mut sim = build()?;
    let mut twin = match perturbation(opts, scene.episode_steps)? {
        Some(p) => Some((build()?, super::perturb::Response::new(p, 0))),
        None => None,
    };
    let control = {
        let registry = sim.world().resource::<SpeciesRegistry>();
        opts.control.resolve(registry).map_err(|e| format!("--control: {e}"))?
    };
    if path.starts_with(&opts.run) {
        // Its numbers become part of the run's: the run records the evaluating executable.
        dir.note_binary()?;
    }
    sim.world_mut().insert_resource(control.clone());
    // Each episode's last step is read before the next population is spawned.
    sim.world_mut().resource_mut::<Episode>().auto_reset = false;
    let registry = sim.world().resource::<SpeciesRegistry>().clone();
    let prey = registry.headline();
    if let Some((twin, response)) = &mut twin {
        twin.world_mut().insert_resource(control);
        twin.world_mut().resource_mut::<Episode>().auto_reset = false;
        *response = super::perturb::Response::new(response.perturbation, prey);
    }
    let name = &registry.defs[prey].name;
    let catchers = schema::split_catchers(&registry);
    let write_err = |e: std::io::Error| format!("{}: {e}", path.display());
    let mut file = AtomicFile::create(&path, Existing::Replace).map_err(write_err)?;
    writeln!(file.writer(), "{}", schema::eval_header(&registry, prey)).map_err(write_err)?;
    let pursuer = (0..registry.len())
        .find(|&s| registry.prey_of(s).any(|t| t == prey))
        .map(|s| (s, scene.confusion_radius.unwrap_or(registry.perception_radius[s])));
    let mut acc = Accumulated::new(2.0 * registry.defs[prey].radius, sim.world().resource::<Arena>(), pursuer);
    let bar = super::progress::step_bar(&scene, opts.episodes * scene.episode_steps);
    for episode in 0..opts.episodes {
        if episode > 0 {
            crate::sim::episode::next_episode(sim.world_mut());
            if let Some((twin, _)) = &mut twin {
                crate::sim::episode::next_episode(twin.world_mut());
            }
        }
        for step in 1..=scene.episode_steps {
            sim.step();
            sim.check()?;
            bar.inc(1);
            if let Some((twin, response)) = &mut twin {
                twin.step();
                twin.check()?;
                response.step(&sim, twin, step)?;
            }
            let row = acc.step(&sim, prey, &catchers, episode, step);
            writeln!(file.writer(), "{row}").map_err(write_err)?;
        }
    }
    let (files, correlation_length) = acc.distributions(&sim, &registry);
    file.commit().map_err(write_err)?;
    // The confusion curve last: the experiment runner takes its presence for a complete evaluation.
    if let Some((_, response)) = &twin {
        let out = crate::io::beside(&path, crate::store::folder::PERTURBATION);
        crate::io::write_file(&out, Existing::Replace, response.csv().as_bytes())?;
    }
    for (what, text) in crate::store::folder::EVAL_BESIDE.iter().zip(files) {
        crate::io::write_file(&crate::io::beside(&path, what), Existing::Replace, text.as_bytes())?;
    }
    Ok(format!(
        "eval {}{}{}: {} × {} steps ({}): {}; per step in {}{}",
        opts.run.display(),
        if opts.untrained {
            " (untrained actors, as initialised from the run's seed)".to_string()
        } else {
            snapshots_shown(&opts.snapshots)
        },
        match opts.control.is_seeing() {
            true => String::new(),
            false => format!(" (control {}: {})", opts.control.texts().join(" + "), opts.control.describe()),
        },
        if opts.episodes == 1 { "1 episode".to_string() } else { format!("{} episodes", opts.episodes) },
        scene.episode_steps,
        counts_shown(opts, &registry),
        acc.summary(
            name,
            correlation_length,
            crate::sim::metrics::random_dos(sim.world().resource::<Arena>(), registry.defs[prey].count)
        ),
        path.display(),
        if replaced { " (it replaced the earlier one)" } else { "" }
    ) + &twin.map_or(String::new(), |(_, r)| format!("; {}", r.summary())))
}

/// The snapshots an evaluation deploys, as its summary line names them.
pub(crate) fn snapshots_shown(snapshots: &[(String, usize)]) -> String {
    match snapshots.is_empty() {
        true => String::new(),
        false => {
            let each: Vec<String> = snapshots.iter().map(|(s, e)| format!("{s} after {e} episodes")).collect();
            format!(" (snapshots: {})", each.join(", "))
        }
    }
}
