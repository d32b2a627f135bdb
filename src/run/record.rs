//! Trajectory recording: one CSV row per agent per step, in physical units, for checking the physics
//! against other implementations.
//!
//! `step,id,species,x,y,vx,vy,theta,thrust,turn_rate,reward`: row `step = t` holds the state at t and the
//! action applied from t to t+1 (thrust in N, turn rate in rad/s), and `reward` is the reward of that
//! transition. Step 0 is the spawned state; the last row of each agent (step = N) has no transition, so its
//! action and reward are empty. Numbers are printed in the shortest form that reads back to the same f64.
//! The record is one continuous trajectory: the episode does not reset during it.
//!
//! `--record OUT.npy` writes the positions alone in the layout of idtracker.ai and trajectorytools
//! (Romero-Ferrero et al., Nat. Methods 2019): a NumPy array `[frames, individuals, 2]` of float64 x, y in
//! metres, frame t the state at step t (frame 0 the spawned state), individuals by agent id, positions as
//! simulated (on a torus, wrapped into the arena); `OUT-species.npy` beside it names each individual's
//! species (`trajectorytools.Trajectories.from_positions(np.load("OUT.npy"))` reads the first).
//!
//! `--record OUT.nc` writes the same positions as a `movement` poses dataset in netCDF ([`super::movement`]),
//! with each individual's species and the time in seconds.
//!
//! Beside either, `OUT-order.csv` holds the order parameters of every species with two or more agents at
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

/// `--record OUT.csv` (or `OUT.npy`).
#[derive(clap::Args, Debug, Clone, Default)]
pub(crate) struct RecordArgs {
    /// Record a trajectory CSV: step,id,species,x,y,vx,vy,theta,thrust,turn_rate,reward; OUT.npy writes
    /// the positions as idtracker.ai and trajectorytools lay them out ([frames, individuals, 2], metres),
    /// with OUT-species.npy naming each individual's species; OUT.nc writes them as a `movement` poses
    /// dataset (netCDF).
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
    let npy = path.extension().is_some_and(|e| e == "npy");
    let netcdf = path.extension().is_some_and(|e| e == "nc");
    let order_path = crate::io::beside(path, "order");
    let order_err = |e: io::Error| format!("{}: {e}", order_path.display());
    let species_path = crate::io::beside(path, "species").with_extension("npy");
    let species_err = |e: io::Error| format!("{}: {e}", species_path.display());
    sim.world_mut().resource_mut::<Episode>().auto_reset = false;
    if netcdf {
        crate::io::check_target(path, existing).map_err(io_err)?;
    }
    crate::io::check_target(&order_path, existing).map_err(order_err)?;
    if npy {
        crate::io::check_target(&species_path, existing).map_err(species_err)?;
    }
    // The netCDF file is written whole at the end (its writer takes each variable whole); the others stream.
    let mut file = match netcdf {
        true => None,
        false => Some(AtomicFile::create(path, existing).map_err(io_err)?),
    };
    let mut order = AtomicFile::create(&order_path, existing).map_err(order_err)?;
    let first = snapshot(sim);
    if netcdf {
        // The frames, the variable laid out for the file and the file's bytes: three copies of every position.
        let need = (steps as f64 + 1.0) * (first.len() as f64 * 16.0 * 3.0 + 24.0);
        let limit = crate::io::memory_bytes();
        if need > limit {
            let shown = crate::io::bytes_shown;
            return Err(format!(
                "{}: a netCDF record of {steps} steps of {} agents is held in memory until it is written, {}, more than the {} coevo may use here; record fewer --steps, or to OUT.npy, which streams",
                path.display(),
                first.len(),
                shown(need),
                shown(limit)
            )
            .into());
        }
    }
    let mut frames: Vec<Vec<(f64, f64)>> = Vec::new();
    let mut species = None;
    if npy {
        npy_header(file.as_mut().expect("streamed").writer(), "<f8", &[steps + 1, first.len(), 2]).map_err(io_err)?;
        let names: Vec<&str> = first.iter().map(|r| r.species.as_str()).collect();
        let mut f = AtomicFile::create(&species_path, existing).map_err(species_err)?;
        npy_strings(f.writer(), &names).map_err(species_err)?;
        species = Some(f);
    } else if let Some(file) = file.as_mut() {
        writeln!(file.writer(), "{HEADER}").map_err(io_err)?;
    }
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
        let Some(file) = file.as_mut() else {
            frames.push(states.iter().map(|s| (s.x, s.y)).collect());
            continue;
        };
        let out = file.writer();
        if npy {
            for s in &states {
                out.write_all(&s.x.to_le_bytes()).and_then(|_| out.write_all(&s.y.to_le_bytes())).map_err(io_err)?;
            }
            continue;
        }
        for (i, s) in states.iter().enumerate() {
            write!(out, "{t},{},{},{},{},{},{},{}", s.id, s.species, s.x, s.y, s.vx, s.vy, s.theta).map_err(io_err)?;
            match &transitions {
                Some(tr) => writeln!(out, ",{},{},{}", tr[i].0, tr[i].1, tr[i].2),
                None => writeln!(out, ",,,"),
            }
            .map_err(io_err)?;
        }
    }
    match file {
        Some(file) => file.commit().map_err(io_err)?,
        None => {
            let species: Vec<String> = first.iter().map(|r| r.species.clone()).collect();
            let fps = 1.0 / sim.world().resource::<crate::sim::ActiveScene>().0.world.dt;
            let poses = super::movement::Poses { positions: &frames, species: &species, fps: Some(fps) };
            super::movement::write(path, &poses, existing)?;
        }
    }
    if let Some(f) = species {
        f.commit().map_err(species_err)?;
    }
    Ok(order.commit().map_err(order_err)?)
}

/// A NumPy `.npy` header (format 1.0) for a C-ordered array of `descr` (e.g. `<f8`) and `shape`: the
/// magic, the version, the header's length, then the dictionary padded with spaces to a newline that ends
/// on a multiple of 64 bytes, as NumPy writes it.
fn npy_header(out: &mut impl Write, descr: &str, shape: &[usize]) -> io::Result<()> {
    let dims: Vec<String> = shape.iter().map(usize::to_string).collect();
    let shape = if dims.len() == 1 { format!("({},)", dims[0]) } else { format!("({})", dims.join(", ")) };
    let mut dict = format!("{{'descr': '{descr}', 'fortran_order': False, 'shape': {shape}, }}");
    let len = 10 + dict.len() + 1;
    dict.push_str(&" ".repeat(len.next_multiple_of(64) - len));
    dict.push('\n');
    out.write_all(b"\x93NUMPY\x01\x00")?;
    out.write_all(&(dict.len() as u16).to_le_bytes())?;
    out.write_all(dict.as_bytes())
}

/// `names` as a `.npy` array of NumPy unicode strings (`<U`n, UTF-32, padded with zeros).
fn npy_strings(out: &mut impl Write, names: &[&str]) -> io::Result<()> {
    let width = names.iter().map(|n| n.chars().count()).max().unwrap_or(0).max(1);
    npy_header(out, &format!("<U{width}"), &[names.len()])?;
    for name in names {
        let chars = name.chars().map(u32::from).chain(std::iter::repeat(0)).take(width);
        for c in chars {
            out.write_all(&c.to_le_bytes())?;
        }
    }
    Ok(())
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
