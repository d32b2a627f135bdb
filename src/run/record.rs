//! Trajectory recording: one CSV row per agent per step, in physical units, for checking the physics
//! against other implementations.
//!
//! `step,id,species,x,y,vx,vy,theta,thrust,turn_rate,reward`: row `step = t` holds the state at t and the
//! action applied from t to t+1 (thrust in N, turn rate in rad/s), and `reward` is the reward of that
//! transition. Step 0 is the spawned state; the last row of each agent (step = N) has no transition, so its
//! action and reward are empty. Numbers are printed in the shortest form that reads back to the same f64.
//! The record is one continuous trajectory: the episode does not reset during it.
//!
//! Beside it, `OUT-order.csv` holds the order parameters of every species with two or more agents at
//! every step (`step,species,dos,doa,polarization,milling,clusters,largest_cluster,nn_correlation`, see
//! [`crate::sim::metrics::Swarming`]); step 0, the spawned state, is not measured.

use crate::io::{AtomicFile, Existing};
use crate::sim::clock::Episode;
use crate::sim::components::*;
use crate::sim::metrics::{SwarmMetrics, Swarming};
use crate::sim::species::SpeciesRegistry;
use crate::sim::Simulation;
use std::io::{self, Write};
use std::path::Path;

pub(crate) const HEADER: &str = "step,id,species,x,y,vx,vy,theta,thrust,turn_rate,reward";

/// `--record OUT.csv`.
#[derive(clap::Args, Debug, Clone, Default)]
pub(crate) struct RecordArgs {
    /// Record a trajectory CSV: step,id,species,x,y,vx,vy,theta,thrust,turn_rate,reward.
    #[arg(long, help_heading = "Modes", value_name = "OUT.csv")]
    pub(crate) record: Option<std::path::PathBuf>,
}

impl super::args::Mode for RecordArgs {
    const MODE: &'static str = "record";
    const TAKES: &'static [&'static str] =
        &["run", "scene", "seed", "steps", "prey", "predators", "count", "policy", "overwrite", "snapshot"];
}

/// `--record OUT.csv`: the deployed scene ([`super::deploy`]) recorded.
pub(crate) fn main(
    out: &Path,
    deploy: &super::deploy::DeployArgs,
    shared: &super::args::Shared,
) -> crate::error::Result<()> {
    let mut d = deploy.deploy(&shared.scene)?;
    record(&mut d.sim, d.steps, out, shared.common.existing())?;
    crate::errln!("coevo: wrote {} steps to {}{}", d.steps, out.display(), d.actors)?;
    Ok(())
}

/// Runs `steps` steps of `sim` and streams the trajectory to `path`, which appears only when complete
/// (see [`crate::io::AtomicFile`]). Stops with an error, writing nothing, if the state stops being
/// physical ([`Simulation::check`]).
pub(crate) fn record(sim: &mut Simulation, steps: usize, path: &Path, existing: Existing) -> crate::error::Result<()> {
    let io_err = |e: io::Error| format!("{}: {e}", path.display());
    let order_path = crate::io::beside(path, "order");
    let order_err = |e: io::Error| format!("{}: {e}", order_path.display());
    sim.world_mut().resource_mut::<Episode>().auto_reset = false;
    crate::io::check_target(&order_path, existing).map_err(order_err)?;
    let mut file = AtomicFile::create(path, existing).map_err(io_err)?;
    let mut order = AtomicFile::create(&order_path, existing).map_err(order_err)?;
    writeln!(file.writer(), "{HEADER}").map_err(io_err)?;
    writeln!(order.writer(), "step,species,{}", Swarming::NAMES.join(",")).map_err(order_err)?;
    let names: Vec<String> = sim.world().resource::<SpeciesRegistry>().defs.iter().map(|d| d.name.clone()).collect();
    let bar = super::progress::step_bar(&sim.world().resource::<crate::sim::ActiveScene>().0, steps);
    for t in 0..=steps {
        let states = snapshot(sim);
        let transitions = if t < steps {
            sim.step();
            sim.check()?;
            bar.inc(1);
            for (s, now) in sim.world().resource::<SwarmMetrics>().now.iter().enumerate() {
                if let Some(now) = now {
                    let values: Vec<String> = now.values().iter().map(f64::to_string).collect();
                    writeln!(order.writer(), "{},{},{}", t + 1, names[s], values.join(",")).map_err(order_err)?;
                }
            }
            Some(snapshot_transitions(sim))
        } else {
            None
        };
        let out = file.writer();
        for (i, s) in states.iter().enumerate() {
            write!(out, "{t},{},{},{},{},{},{},{}", s.id, s.species, s.x, s.y, s.vx, s.vy, s.theta).map_err(io_err)?;
            match &transitions {
                Some(tr) => writeln!(out, ",{},{},{}", tr[i].0, tr[i].1, tr[i].2),
                None => writeln!(out, ",,,"),
            }
            .map_err(io_err)?;
        }
    }
    file.commit().map_err(io_err)?;
    Ok(order.commit().map_err(order_err)?)
}

struct Row {
    id: u32,
    species: String,
    x: f64,
    y: f64,
    vx: f64,
    vy: f64,
    theta: f64,
}

fn snapshot(sim: &mut Simulation) -> Vec<Row> {
    let world = sim.world_mut();
    let registry = world.resource::<SpeciesRegistry>().clone();
    let mut rows: Vec<Row> = world
        .query::<(&AgentId, &SpeciesId, &Position, &Velocity, &Heading)>()
        .iter(world)
        .map(|(id, s, x, v, h)| Row {
            id: id.0,
            species: registry.defs[s.0].name.clone(),
            x: x.0.x,
            y: x.0.y,
            vx: v.0.x,
            vy: v.0.y,
            theta: h.0,
        })
        .collect();
    rows.sort_by_key(|r| r.id);
    rows
}

/// (thrust, turn rate, reward) of the step just taken, by agent id.
fn snapshot_transitions(sim: &mut Simulation) -> Vec<(f64, f64, f64)> {
    let world = sim.world_mut();
    let mut rows: Vec<(u32, (f64, f64, f64))> = world
        .query::<(&AgentId, &Action, &Reward)>()
        .iter(world)
        .map(|(id, a, r)| (id.0, (a.thrust, a.turn_rate, r.0)))
        .collect();
    rows.sort_by_key(|r| r.0);
    rows.into_iter().map(|r| r.1).collect()
}
