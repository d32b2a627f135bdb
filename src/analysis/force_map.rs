//! Force maps from trajectories, the empirical route to an interaction rule (Katz et al., PNAS 2011;
//! Herbert-Read et al., PNAS 2011): from a recorded trajectory (`--record`, or one written the same way
//! from Python), how a focal agent turns and speeds up, binned by where its nearest neighbour of each
//! species is in its body frame. It reads positions, velocities and headings only, so it maps learned,
//! rule-based and plugin agents alike. Beside the response fields ([`super::response`]), which read a
//! policy off its actor, this is what an observer of the swarm would measure.
//!
//! Turning at step t is the change of heading from t to t + 1 (wrapped to (−π, π]) over dt, in rad/s,
//! positive to the left; speeding is the change of speed over dt, in m/s². A bin with fewer than
//! [`MIN_COUNT`] samples is left blank: its mean is noise.

use crate::scene::Scene;
use crate::sim::space::Arena;
use bevy::math::DVec2;
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// Bins per side of a map (the focal agent in the centre bin).
pub(crate) const GRID: usize = 21;

/// Samples a bin needs before its mean is shown.
pub(crate) const MIN_COUNT: usize = 20;

/// One agent at one step, as the trajectory holds it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct State {
    pub(crate) id: u64,
    pub(crate) species: usize,
    pub(crate) position: DVec2,
    pub(crate) velocity: DVec2,
    pub(crate) theta: f64,
}

/// The map of one focal species against its nearest neighbour of one species.
#[derive(Clone, Debug, PartialEq)]
pub struct ForceMap {
    pub species: String,
    pub observed: String,
    /// Bin centres along each axis, in metres (ahead, to the left).
    pub centres: Vec<f64>,
    /// `[row][column]` (row along "left"): samples, and mean turning (rad/s) and speeding (m/s²); NaN
    /// where a bin has fewer than [`MIN_COUNT`] samples.
    pub count: Vec<Vec<usize>>,
    pub turning: Vec<Vec<f64>>,
    pub speeding: Vec<Vec<f64>>,
}

/// The maps of `steps` (each step's agents, consecutive steps in order) in `arena`, with `names` the
/// species' names and `dt` the step: every ordered pair of species with a neighbour to find, over
/// [−`reach`, `reach`]² around the focal agent.
pub fn maps(steps: &[Vec<State>], names: &[String], arena: &Arena, dt: f64, reach: f64) -> Vec<ForceMap> {
    let n = names.len();
    let centres: Vec<f64> = (0..GRID).map(|k| reach * (2.0 * (k as f64 + 0.5) / GRID as f64 - 1.0)).collect();
    let bin = |x: f64| {
        let k = ((x / reach + 1.0) / 2.0 * GRID as f64).floor();
        (0.0..GRID as f64).contains(&k).then_some(k as usize)
    };
    // Sums per (focal species, observed species): count, turning, speeding per bin.
    let mut sums = vec![vec![vec![[0.0f64; 3]; GRID * GRID]; n]; n];
    // Each step's agents grouped by species, one cell grid a species: the nearest neighbour of each is a
    // query of a few cells, so a step costs ~O(agents), as a simulation step does (sim::space).
    let mut grids = vec![crate::sim::space::CellGrid::default(); n];
    let mut found = Vec::new();
    for pair in steps.windows(2) {
        let next: BTreeMap<u64, &State> = pair[1].iter().map(|a| (a.id, a)).collect();
        let mut order: Vec<usize> = (0..pair[0].len()).collect();
        order.sort_by_key(|&i| pair[0][i].species);
        let positions: Vec<DVec2> = order.iter().map(|&i| pair[0][i].position).collect();
        let mut first = 0;
        for (t, grid) in grids.iter_mut().enumerate() {
            let end = first + order[first..].iter().take_while(|&&i| pair[0][i].species == t).count();
            grid.rebuild(arena, &positions, first..end);
            first = end;
        }
        for (k, a) in order.iter().map(|&i| &pair[0][i]).enumerate() {
            let Some(b) = next.get(&a.id) else { continue };
            let turning = wrap(b.theta - a.theta) / dt;
            let speeding = (b.velocity.length() - a.velocity.length()) / dt;
            let h = DVec2::new(a.theta.cos(), a.theta.sin());
            for (t, sum) in sums[a.species].iter_mut().enumerate() {
                grids[t].k_nearest(arena, a.position, 1, f64::INFINITY, k as u32, &mut found);
                let Some(&(_, j)) = found.first() else { continue };
                let d = arena.delta(a.position, positions[j as usize]);
                let (ahead, left) = (d.dot(h), d.dot(DVec2::new(-h.y, h.x)));
                if let (Some(c), Some(r)) = (bin(ahead), bin(left)) {
                    let cell = &mut sum[r * GRID + c];
                    cell[0] += 1.0;
                    cell[1] += turning;
                    cell[2] += speeding;
                }
            }
        }
    }
    let mut out = Vec::new();
    for (s, per_observed) in sums.iter().enumerate() {
        for (t, cells) in per_observed.iter().enumerate() {
            if cells.iter().all(|c| c[0] == 0.0) {
                continue;
            }
            let grid = |k: usize| -> Vec<Vec<f64>> {
                (0..GRID)
                    .map(|r| {
                        (0..GRID)
                            .map(|c| {
                                let cell = cells[r * GRID + c];
                                if cell[0] >= MIN_COUNT as f64 {
                                    cell[k] / cell[0]
                                } else {
                                    f64::NAN
                                }
                            })
                            .collect()
                    })
                    .collect()
            };
            out.push(ForceMap {
                species: names[s].clone(),
                observed: names[t].clone(),
                centres: centres.clone(),
                count: (0..GRID).map(|r| (0..GRID).map(|c| cells[r * GRID + c][0] as usize).collect()).collect(),
                turning: grid(1),
                speeding: grid(2),
            });
        }
    }
    out
}

/// An angle wrapped to (−π, π].
fn wrap(a: f64) -> f64 {
    let tau = std::f64::consts::TAU;
    let w = a.rem_euclid(tau);
    if w > std::f64::consts::PI {
        w - tau
    } else {
        w
    }
}

/// The states of a trajectory CSV (`run::record::HEADER`), grouped by step in order; species by their
/// index in `names`. Refused, naming the file and line, when a row does not parse or names a species the
/// scene does not have.
pub fn read(path: &Path, names: &[String]) -> crate::error::Result<Vec<Vec<State>>> {
    let text = crate::io::read_text(path, crate::io::MAX_TEXT_BYTES)?;
    let mut lines = text.lines();
    let header = lines.next().unwrap_or_default();
    if !header.starts_with("step,id,species,x,y,vx,vy,theta") {
        return Err(format!(
            "{}: not a trajectory (its header is not `{}`): record one with `coevo --record`",
            path.display(),
            crate::run::record::HEADER
        )
        .into());
    }
    let mut steps: Vec<Vec<State>> = Vec::new();
    let mut step_of: Option<u64> = None;
    // Each id once a step and of one species throughout: an agent's change of heading is read between
    // its rows, so a repeated or re-labelled id would mix two agents.
    let mut species_of: std::collections::HashMap<u64, usize> = std::collections::HashMap::new();
    let mut seen: std::collections::HashSet<u64> = std::collections::HashSet::new();
    for (k, line) in lines.enumerate() {
        let bad = |what: &str| format!("{}: line {}: {what}", path.display(), k + 2);
        let cells: Vec<&str> = line.split(',').collect();
        if cells.len() < 8 {
            return Err(bad("fewer than 8 columns").into());
        }
        let number = |i: usize| -> crate::error::Result<f64> {
            cells[i]
                .parse::<f64>()
                .ok()
                .filter(|x| x.is_finite())
                .ok_or_else(|| bad(&format!("column {} is not a number", i + 1)).into())
        };
        let step = cells[0].parse::<u64>().map_err(|_| bad("step is not a whole number"))?;
        let id = cells[1].parse::<u64>().map_err(|_| bad("id is not a whole number"))?;
        let species = names
            .iter()
            .position(|n| n == cells[2])
            .ok_or_else(|| bad(&format!("species {:?} is not one of the scene's ({})", cells[2], names.join(", "))))?;
        if step_of != Some(step) {
            if step_of.is_some_and(|s| step != s + 1) {
                return Err(bad("steps must follow one another (one continuous trajectory)").into());
            }
            steps.push(Vec::new());
            step_of = Some(step);
            seen.clear();
        }
        if !seen.insert(id) {
            return Err(bad(&format!("id {id} appears twice at step {step}")).into());
        }
        if let Some(&was) = species_of.get(&id).filter(|&&was| was != species) {
            return Err(bad(&format!("id {id} was a {} earlier and is a {} here", names[was], names[species])).into());
        }
        species_of.insert(id, species);
        steps.last_mut().expect("pushed above").push(State {
            id,
            species,
            position: DVec2::new(number(3)?, number(4)?),
            velocity: DVec2::new(number(5)?, number(6)?),
            theta: number(7)?,
        });
    }
    Ok(steps)
}

/// `force-map.csv`: one row per map and bin with samples.
pub(crate) fn csv(maps: &[ForceMap]) -> String {
    let mut out = String::from("species,observed,ahead,left,count,turning,speeding\n");
    for m in maps {
        for (r, &left) in m.centres.iter().enumerate() {
            for (c, &ahead) in m.centres.iter().enumerate() {
                if m.count[r][c] == 0 {
                    continue;
                }
                let shown = |v: f64| if v.is_finite() { format!("{v:.5}") } else { String::new() };
                writeln!(
                    out,
                    "{},{},{ahead:.4},{left:.4},{},{},{}",
                    m.species,
                    m.observed,
                    m.count[r][c],
                    shown(m.turning[r][c]),
                    shown(m.speeding[r][c])
                )
                .unwrap();
            }
        }
    }
    out
}

/// `--force-map TRAJ.csv`.
#[derive(clap::Args, Debug, Clone, Default)]
pub(crate) struct ForceMapArgs {
    /// Force maps of a recorded trajectory (--record): each species' mean turning and speeding against
    /// where its nearest neighbour of each species is (bins with fewer than 20 samples blank), in the
    /// arena of --scene (or the run's with --run); writes TRAJ-force-map.csv and heat maps beside it.
    #[arg(long, help_heading = "Modes", value_name = "TRAJ.csv")]
    pub(crate) force_map: Option<PathBuf>,
}

impl crate::run::args::Mode for ForceMapArgs {
    const MODE: &'static str = "force_map";
    const TAKES: &'static [&'static str] = &["scene", "run", "overwrite"];
}

/// Agent-steps above which `--force-map` says what it is about to cost before it starts.
const COSTLY_AGENT_STEPS: usize = 1_000_000;

/// The files `--force-map TRAJ.csv` writes for `maps`, all beside the trajectory and named by appending to
/// its name less a `.csv` ending, so that none can be the trajectory itself or lose part of a name with dots
/// (`exp.v2.csv` gives `exp.v2-force-map.csv` and `exp.v2-force-map-prey-predator.svg`): the CSV, then each
/// map's figure stem.
fn outputs(trajectory: &Path, maps: &[ForceMap]) -> (PathBuf, Vec<PathBuf>) {
    let name = trajectory.file_name().unwrap_or_default().to_string_lossy();
    let stem = name.strip_suffix(".csv").unwrap_or(&name);
    let beside = |suffix: String| trajectory.with_file_name(format!("{stem}-force-map{suffix}"));
    let figures = maps.iter().map(|m| beside(format!("-{}-{}", m.species, m.observed))).collect();
    (beside(".csv".into()), figures)
}

/// Writes the force maps of a trajectory recorded in `scene`: every output checked before the first is
/// written (refused if it exists, unless `overwrite`), and each announced once it is written.
pub(crate) fn main(trajectory: &Path, scene: &Scene, overwrite: bool) -> crate::error::Result<()> {
    let names: Vec<String> = scene.species.iter().map(|d| d.name.clone()).collect();
    let steps = read(trajectory, &names)?;
    if steps.len() < 2 {
        return Err(format!("{}: fewer than two steps, so no change to measure", trajectory.display()).into());
    }
    let arena = Arena { edge: scene.world.arena_edge, boundary: scene.world.boundary };
    // Positions lie within half the edge of the centre; a body pressed into a wall sinks at most its
    // radius and two steps' travel beyond it (as `perception::observation_high` bounds it). A position
    // farther out is no agent of this arena: another scene's trajectory, or a corrupt one.
    let sink = match scene.world.boundary {
        crate::scene::Boundary::Walls => {
            scene.species.iter().map(|s| s.radius + s.max_speed * scene.world.dt * 2.0).fold(0.0, f64::max)
        }
        crate::scene::Boundary::Periodic => 0.0,
    };
    let limit = arena.half() + sink;
    if let Some((t, a)) = steps
        .iter()
        .enumerate()
        .find_map(|(t, s)| s.iter().find(|a| a.position.abs().max_element() > limit).map(|a| (t, a)))
    {
        return Err(format!(
            "{}: agent {} at step {t} of the file is at ({}, {}), outside the scene's {} m arena: pass the scene it was recorded in (--scene or --run)",
            trajectory.display(),
            a.id,
            a.position.x,
            a.position.y,
            arena.edge
        )
        .into());
    }
    let agent_steps: usize = steps.iter().map(Vec::len).sum();
    if agent_steps >= COSTLY_AGENT_STEPS {
        crate::errln!(
            "coevo: {agent_steps} agent-steps of {} species: about {:.0} s (an estimate); Ctrl-C stops it",
            names.len(),
            (agent_steps * names.len()) as f64 * SECONDS_PER_QUERY
        )?;
    }
    let maps = maps(&steps, &names, &arena, scene.world.dt, arena.half());
    let (csv_path, figures) = outputs(trajectory, &maps);
    let mut every = vec![csv_path.clone()];
    every.extend(figures.iter().flat_map(|f| crate::analysis::plot::files(f)));
    let existing = if overwrite { crate::io::Existing::Replace } else { crate::io::Existing::Refuse };
    crate::io::check_targets(&every, existing)?;
    crate::io::write_file(&csv_path, existing, csv(&maps).as_bytes())?;
    crate::outln!("wrote {}", csv_path.display())?;
    for (m, figure) in maps.iter().zip(&figures) {
        let map = |what: &str, values: &[Vec<f64>]| {
            let title = format!("{}: {what}, nearest {}", m.species, m.observed);
            super::plot::Heatmap::body_frame(title, &m.centres, values, true)
        };
        super::plot::save_heatmaps(
            figure,
            &[map("turning (rad/s, + left)", &m.turning), map("speeding (m/s²)", &m.speeding)],
        )?;
        crate::outln!("wrote {}.svg (and .png)", figure.display())?;
    }
    Ok(())
}

/// Seconds one nearest-neighbour query (an agent at a step, against one species) takes, for the estimate.
const SECONDS_PER_QUERY: f64 = 1e-6;

#[cfg(test)]
mod tests {
    use super::*;

    fn state(id: u64, species: usize, x: f64, y: f64, theta: f64, speed: f64) -> State {
        State { id, species, position: DVec2::new(x, y), velocity: DVec2::new(theta.cos(), theta.sin()) * speed, theta }
    }

    #[test]
    fn a_focal_agent_turning_away_from_a_neighbour_on_its_left_maps_to_a_right_turn_there() {
        let arena = Arena { edge: 2.0, boundary: crate::scene::Boundary::Periodic };
        let names = vec!["prey".to_string(), "predator".to_string()];
        // Each step: a prey at the origin heading east, a predator 0.3 m to its left; the prey turns right
        // by 0.01 rad and speeds up by 0.01 m/s per step of 0.1 s.
        let steps: Vec<Vec<State>> = (0..=MIN_COUNT)
            .map(|t| {
                let theta = -0.01 * t as f64;
                let h = DVec2::new(theta.cos(), theta.sin());
                let left = DVec2::new(-h.y, h.x) * 0.3;
                vec![state(0, 0, 0.0, 0.0, theta, 0.5 + 0.01 * t as f64), state(1, 1, left.x, left.y, theta, 0.5)]
            })
            .collect();
        let maps = maps(&steps, &names, &arena, 0.1, 1.0);
        let m = maps.iter().find(|m| m.species == "prey" && m.observed == "predator").unwrap();
        let nearest =
            |x: f64| (0..GRID).min_by(|&a, &b| (m.centres[a] - x).abs().total_cmp(&(m.centres[b] - x).abs())).unwrap();
        let (r, c) = (nearest(0.3), nearest(0.0));
        assert_eq!(m.count[r][c], MIN_COUNT);
        assert!((m.turning[r][c] + 0.1).abs() < 1e-9, "{}", m.turning[r][c]);
        assert!((m.speeding[r][c] - 0.1).abs() < 1e-9, "{}", m.speeding[r][c]);
        // Every other bin is empty, and a bin with fewer samples than MIN_COUNT is blank.
        assert_eq!(m.count.iter().flatten().sum::<usize>(), MIN_COUNT);
        let short = maps_of(&steps[..MIN_COUNT], &names, &arena);
        let m = short.iter().find(|m| m.species == "prey" && m.observed == "predator").unwrap();
        assert!(m.turning[r][c].is_nan());
        // The prey has no kin: no prey–prey map.
        assert!(!maps_of(&steps, &names, &arena).iter().any(|m| m.species == "prey" && m.observed == "prey"));
    }

    fn maps_of(steps: &[Vec<State>], names: &[String], arena: &Arena) -> Vec<ForceMap> {
        maps(steps, names, arena, 0.1, 1.0)
    }

    #[test]
    fn the_cell_grid_finds_the_same_nearest_neighbours_as_a_scan_of_every_agent() {
        // The maps as a scan of every pair makes them (quadratic), against maps(), on both boundaries.
        use rand::{Rng, SeedableRng};
        let names = vec!["prey".to_string(), "predator".to_string()];
        for boundary in [crate::scene::Boundary::Periodic, crate::scene::Boundary::Walls] {
            let arena = Arena { edge: 2.0, boundary };
            let mut rng = rand::rngs::StdRng::seed_from_u64(7);
            let mut agent = |id: u64| {
                let theta: f64 = rng.gen_range(-3.0..3.0);
                state(id, id.is_multiple_of(5) as usize, rng.gen_range(-1.0..1.0), rng.gen_range(-1.0..1.0), theta, 0.3)
            };
            let steps: Vec<Vec<State>> = (0..30).map(|_| (0..200).map(&mut agent).collect()).collect();
            let mut sums = vec![vec![vec![0usize; GRID * GRID]; 2]; 2];
            let bin = |x: f64| {
                let k = ((x + 1.0) / 2.0 * GRID as f64).floor();
                (0.0..GRID as f64).contains(&k).then_some(k as usize)
            };
            for step in &steps[..steps.len() - 1] {
                for a in step {
                    let h = DVec2::new(a.theta.cos(), a.theta.sin());
                    for (t, sum) in sums[a.species].iter_mut().enumerate() {
                        let d = step
                            .iter()
                            .filter(|o| o.species == t && o.id != a.id)
                            .map(|o| arena.delta(a.position, o.position))
                            .min_by(|p, q| p.length_squared().total_cmp(&q.length_squared()))
                            .unwrap();
                        if let (Some(c), Some(r)) = (bin(d.dot(h)), bin(d.dot(DVec2::new(-h.y, h.x)))) {
                            sum[r * GRID + c] += 1;
                        }
                    }
                }
            }
            let maps = maps_of(&steps, &names, &arena);
            assert_eq!(maps.len(), 4);
            for m in &maps {
                let (s, t) = (
                    names.iter().position(|n| *n == m.species).unwrap(),
                    names.iter().position(|n| *n == m.observed).unwrap(),
                );
                let counts: Vec<usize> = m.count.iter().flatten().copied().collect();
                assert_eq!(counts, sums[s][t], "{boundary:?}: {} against {}", m.species, m.observed);
            }
        }
    }

    #[test]
    fn outputs_append_to_the_trajectory_name_and_keep_its_dots() {
        let m = |s: &str, o: &str| ForceMap {
            species: s.into(),
            observed: o.into(),
            centres: vec![],
            count: vec![],
            turning: vec![],
            speeding: vec![],
        };
        let (csv, figures) = outputs(Path::new("d/exp.v2.csv"), &[m("prey", "prey"), m("prey", "predator")]);
        assert_eq!(csv, Path::new("d/exp.v2-force-map.csv"));
        assert_eq!(figures, [Path::new("d/exp.v2-force-map-prey-prey"), Path::new("d/exp.v2-force-map-prey-predator")]);
        let files: Vec<PathBuf> = figures.iter().flat_map(|f| crate::analysis::plot::files(f)).collect();
        assert_eq!(files[3], Path::new("d/exp.v2-force-map-prey-predator.png"));
        assert_eq!(outputs(Path::new("traj"), &[]).0, Path::new("traj-force-map.csv"));
    }

    #[test]
    fn headings_wrap_across_pi() {
        assert!((wrap(3.1 - (-3.1)) - (6.2 - std::f64::consts::TAU)).abs() < 1e-12);
        assert_eq!(wrap(0.5), 0.5);
        assert!((wrap(-0.5) + 0.5).abs() < 1e-12);
    }
}
