//! Response fields: what a policy does (its thrust and its turn) as a function of where one neighbour is,
//! the rule an agent follows read straight off its actor, as Katz et al. (PNAS 2011) and Herbert-Read et
//! al. (PNAS 2011) read it off schooling fish and Heras et al. (2019) off a trained network.
//!
//! The focal agent moves straight ahead at its top speed, without a previous turn, away from walls; one
//! agent of an observed species sits at (ahead, left) in its body frame, heading `rel_heading` radians to
//! the left of the focal agent's heading; every other slot is empty, as the observation layout leaves a
//! slot no one fills (zeros, `sim::perception`). In a world-frame scene the focal agent sits at the
//! origin heading along +x, so "ahead" is +x and "left" is +y there too. A cell beyond the perception
//! radius holds no value: no agent there is observed. Beside each field, the action with no one in view
//! (`alone`), which a neighbour's effect is read against. The action is the normalized one in [−1, 1]: thrust
//! (−1 none, +1 full) and turn (+1 the fastest turn to the left, −1 to the right).

use crate::learning::{Learners, Mode};
use crate::scene::{ObservationFrame, Policy, Scene};
use crate::sim::species::{SpeciesRegistry, ACTION_DIM, NEIGHBOUR_DIM, OWN_STATE_DIM};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// Cells per side of a field's grid (odd, so the focal agent sits in the centre cell).
pub const GRID: usize = 41;

/// The relative headings of the neighbour a field is computed for (radians to the left of the focal
/// agent's heading): parallel, crossing to the left, facing it, crossing to the right. The figures draw
/// the parallel one, Katz et al.'s case.
pub const REL_HEADINGS: [f64; 4] =
    [0.0, std::f64::consts::FRAC_PI_2, std::f64::consts::PI, -std::f64::consts::FRAC_PI_2];

/// The response of one species' policy to one neighbour of one observed species.
#[derive(Clone, Debug, PartialEq)]
pub struct Field {
    /// The focal species and the observed one, by name.
    pub species: String,
    pub observed: String,
    pub rel_heading: f64,
    /// The grid's cell centres along each axis, in metres (ahead, and to the left).
    pub centres: Vec<f64>,
    /// `thrust[row][column]` and `turn[row][column]`: row along "left", column along "ahead"; NaN where
    /// the neighbour would not be observed (beyond the perception radius, or at the focal agent).
    pub thrust: Vec<Vec<f64>>,
    pub turn: Vec<Vec<f64>>,
    /// The action with every slot empty (no one in view): what a neighbour's response is read against.
    pub alone: [f64; ACTION_DIM],
}

/// A policy as a function of a batch of observations (`rows` of them, one after the other): `rows` ×
/// [`ACTION_DIM`] normalized actions.
pub type Actor<'a> = dyn Fn(usize, &[f32], usize) -> Vec<f32> + 'a;

/// The fields of every species `decides` (an actor per species index, None for a species without one),
/// for every species it observes (not blind to, with at least one slot), at every [`REL_HEADINGS`].
pub fn fields(scene: &Scene, decides: &[bool], act: &Actor) -> Vec<Field> {
    let registry = SpeciesRegistry::from_scene(scene);
    let mut out = Vec::new();
    for s in (0..registry.len()).filter(|&s| decides.get(s).copied().unwrap_or(false)) {
        let layout = &registry.layouts[s];
        let speed = registry.defs[s].max_speed;
        let own: [f32; OWN_STATE_DIM] = match scene.observation_frame {
            ObservationFrame::World => [0.0, 0.0, speed as f32, 0.0, 1.0, 0.0],
            ObservationFrame::Body => [speed as f32, 0.0, 0.0, 0.0, 0.0, 0.0],
        };
        let mut blank = vec![0.0f32; layout.dim()];
        // A full energy budget: the authors' energy input 2·E/E_max − 1.
        layout.place_own(&mut blank, own, 1.0);
        let alone = act(s, &blank, 1);
        let alone = [alone[0] as f64, alone[1] as f64];
        for t in (0..registry.len()).filter(|&t| registry.slots(s, t) > 0 && !registry.blind[s][t]) {
            // Within the perception radius, and within the half edge (a neighbour farther on the torus is
            // nearer through the other side).
            let reach = registry.perception_radii[s][t].min(scene.world.arena_edge / 2.0);
            let centres: Vec<f64> = (0..GRID).map(|k| reach * (2.0 * (k as f64 + 0.5) / GRID as f64 - 1.0)).collect();
            let at = registry.block_offset(s, t);
            for &phi in &REL_HEADINGS {
                let mut batch = Vec::with_capacity(GRID * GRID * blank.len());
                for &left in &centres {
                    for &ahead in &centres {
                        let mut obs = blank.clone();
                        let slot = [ahead, left, phi.cos() - 1.0, phi.sin()];
                        obs[at..at + NEIGHBOUR_DIM].copy_from_slice(&slot.map(|c| c as f32));
                        batch.extend_from_slice(&obs);
                    }
                }
                let actions = act(s, &batch, GRID * GRID);
                let cell = |row: usize, column: usize, k: usize| {
                    let (ahead, left) = (centres[column], centres[row]);
                    let seen = ahead.hypot(left) <= registry.perception_radii[s][t] && (ahead, left) != (0.0, 0.0);
                    if seen {
                        actions[(row * GRID + column) * ACTION_DIM + k] as f64
                    } else {
                        f64::NAN
                    }
                };
                let grid = |k: usize| (0..GRID).map(|r| (0..GRID).map(|c| cell(r, c, k)).collect()).collect();
                out.push(Field {
                    species: registry.defs[s].name.clone(),
                    observed: registry.defs[t].name.clone(),
                    rel_heading: phi,
                    centres: centres.clone(),
                    thrust: grid(0),
                    turn: grid(1),
                    alone,
                });
            }
        }
    }
    out
}

/// The fields of a run's trained actors (its `Learned` and `Frozen` species) and of its rule-based
/// species (the rules read the same observations).
pub fn of_run(run: &Path) -> crate::error::Result<(Scene, Vec<Field>)> {
    let dir = a_run(run)?;
    let scene = Scene::load(&dir.scene())?;
    let mut learners = Learners::new(&scene, Mode::Evaluate);
    learners.load_actors(&scene, Some(run))?;
    let registry = SpeciesRegistry::from_scene(&scene);
    let decides: Vec<bool> =
        (0..registry.len()).map(|s| !matches!(registry.policy(s), Policy::Plugin(_) | Policy::Random)).collect();
    let dev = crate::learning::nets::Dev::default();
    let mut rng = rand::rngs::mock::StepRng::new(0, 0);
    let rng = std::cell::RefCell::new(&mut rng);
    let act = |s: usize, batch: &[f32], rows: usize| -> Vec<f32> {
        match &learners.species[s] {
            Some(l) => l.ddpg.act(&dev, batch, rows),
            None => batch
                .chunks_exact(registry.observation_dim(s))
                .flat_map(|obs| {
                    crate::sim::policy::rule_action(obs, &registry, s, &scene, &mut **rng.borrow_mut())
                        .unwrap_or([0.0; ACTION_DIM])
                })
                .collect(),
        }
    };
    let fields = fields(&scene, &decides, &act);
    Ok((scene, fields))
}

/// `run` as a run folder with trained actors this program can deploy (its species plugins).
fn a_run(run: &Path) -> crate::error::Result<crate::run::RunDir> {
    let dir = crate::run::RunDir::new(run);
    if !dir.has_actors() {
        return Err(format!("--response {}: not a run folder with trained actors", run.display()).into());
    }
    dir.check_plugins()?;
    Ok(dir)
}

/// `response.csv`: one row per field and cell with a value.
pub fn csv(fields: &[Field]) -> String {
    let mut out =
        String::from("species,observed,rel_heading,ahead,left,distance,bearing,thrust,turn,thrust_alone,turn_alone\n");
    for f in fields {
        for (row, &left) in f.centres.iter().enumerate() {
            for (column, &ahead) in f.centres.iter().enumerate() {
                let (thrust, turn) = (f.thrust[row][column], f.turn[row][column]);
                if !thrust.is_finite() {
                    continue;
                }
                writeln!(
                    out,
                    "{},{},{:.4},{ahead:.4},{left:.4},{:.4},{:.4},{thrust:.5},{turn:.5},{:.5},{:.5}",
                    f.species,
                    f.observed,
                    f.rel_heading,
                    ahead.hypot(left),
                    left.atan2(ahead),
                    f.alone[0],
                    f.alone[1]
                )
                .unwrap();
            }
        }
    }
    out
}

/// `--response RUN`.
#[derive(clap::Args, Debug, Clone, Default)]
pub struct ResponseArgs {
    /// The rule each species of a run follows: its thrust and turn as a function of where one neighbour of
    /// each observed species is (the response field, read off the trained actors and the rules); writes
    /// DIR/response.csv and heat maps in DIR/figures/.
    #[arg(long, help_heading = "Modes", value_name = "DIR")]
    pub response: Option<PathBuf>,
}

impl crate::run::args::Mode for ResponseArgs {
    const MODE: &'static str = "response";
    const TAKES: &'static [&'static str] = &["quiet"];
}

/// Writes a run's response fields: the CSV and, per species and observed species, the turn and thrust
/// maps for a parallel neighbour.
pub fn main(run: &Path) -> crate::error::Result<()> {
    // Checked before the lock, which would make the folder of a path that is not there.
    let dir = a_run(run)?;
    // A writer of a run: refuses a shipped run and one another process is writing.
    let _lock = dir.lock()?;
    let (_, fields) = of_run(run)?;
    let csv_path = run.join("response.csv");
    crate::io::write_file(&csv_path, crate::io::Existing::Replace, csv(&fields).as_bytes())?;
    crate::io::own_dir(&dir.figures())?;
    let mut written = vec![csv_path.display().to_string()];
    for f in fields.iter().filter(|f| f.rel_heading == 0.0) {
        let map = |what: &str, values: &[Vec<f64>], diverging: bool, alone: f64| {
            let title = format!("{}: {what}, one {} parallel (alone: {alone:+.2})", f.species, f.observed);
            super::plot::Heatmap::body_frame(title, &f.centres, values, diverging)
        };
        let stem = dir.figures().join(format!("response-{}-{}", f.species, f.observed));
        let maps = [map("turn (+ left)", &f.turn, true, f.alone[1]), map("thrust", &f.thrust, false, f.alone[0])];
        super::plot::save_heatmaps(&stem, &maps)?;
        written.push(format!("{}.svg", stem.display()));
    }
    for line in written {
        crate::outln!("wrote {line}")?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A scene with rule-based species only: prey that flee the nearest predator, predators that chase
    /// the nearest prey, both observing in the body frame.
    fn rules() -> Scene {
        let mut scene = Scene::preset("gym-pps").unwrap();
        scene.observation_frame = ObservationFrame::Body;
        for def in &mut scene.species {
            def.policy = if def.name == "prey" { Policy::FleeNearest } else { Policy::ChaseNearest };
        }
        scene
    }

    fn rule_fields(scene: &Scene) -> Vec<Field> {
        let registry = SpeciesRegistry::from_scene(scene);
        let mut rng = rand::rngs::mock::StepRng::new(0, 0);
        let rng = std::cell::RefCell::new(&mut rng);
        let act = |s: usize, batch: &[f32], _: usize| -> Vec<f32> {
            batch
                .chunks_exact(registry.observation_dim(s))
                .flat_map(|o| crate::sim::policy::rule_action(o, &registry, s, scene, &mut **rng.borrow_mut()).unwrap())
                .collect()
        };
        fields(scene, &vec![true; registry.len()], &act)
    }

    /// The turn at the cell nearest (ahead, left), in a field.
    fn turn_at(f: &Field, ahead: f64, left: f64) -> f64 {
        let nearest = |x: f64| (0..GRID).min_by(|&a, &b| (f.centres[a] - x).abs().total_cmp(&(f.centres[b] - x).abs()));
        f.turn[nearest(left).unwrap()][nearest(ahead).unwrap()]
    }

    #[test]
    fn a_chaser_turns_toward_and_a_fleer_away_from_the_one_it_sees() {
        let scene = rules();
        let all = rule_fields(&scene);
        let field = |s: &str, o: &str| all.iter().find(|f| f.species == s && f.observed == o && f.rel_heading == 0.0);
        // Predators chase prey: a prey to the left makes them turn left (+), to the right right (−).
        let chase = field("predator", "prey").unwrap();
        assert!(turn_at(chase, 0.2, 0.3) > 0.0 && turn_at(chase, 0.2, -0.3) < 0.0);
        // Attraction only: every cell turns toward the neighbour's side (or not at all, dead ahead).
        for (row, &left) in chase.centres.iter().enumerate() {
            for (column, _) in chase.centres.iter().enumerate() {
                let t = chase.turn[row][column];
                assert!(!t.is_finite() || t * left >= 0.0, "row {row}, column {column}: turn {t} for left {left}");
            }
        }
        // Prey flee predators: turn away from the side the predator is on.
        let flee = field("prey", "predator").unwrap();
        assert!(turn_at(flee, 0.2, 0.3) < 0.0 && turn_at(flee, 0.2, -0.3) > 0.0);
        // Neither rule reads its own kind: a flat field, full thrust.
        let kin = field("prey", "prey").unwrap();
        assert!(kin.turn.iter().flatten().filter(|t| t.is_finite()).all(|&t| t == 0.0));
        assert!(kin.thrust.iter().flatten().filter(|t| t.is_finite()).all(|&t| t == 1.0));
    }

    #[test]
    fn cells_beyond_the_perception_radius_hold_no_value() {
        let mut scene = rules();
        for def in &mut scene.species {
            def.perception = crate::scene::Perception::FractionOfD(0.1);
        }
        let all = rule_fields(&scene);
        let f = all.iter().find(|f| f.species == "prey" && f.observed == "predator").unwrap();
        let r = SpeciesRegistry::from_scene(&scene).perception_radii[0][1];
        assert!(turn_at(f, 0.0, 0.9 * r).is_finite());
        // The corner of the grid is farther than the radius from the centre.
        assert!(f.turn[0][0].is_nan() && f.turn[GRID - 1][GRID - 1].is_nan());
        let csv = csv(&all);
        assert!(csv.starts_with("species,observed,rel_heading,ahead,left,distance,bearing,thrust,turn,"));
        // Alone, a fleer runs straight at full thrust.
        assert_eq!(f.alone, [1.0, 0.0]);
        assert!(!csv.contains("NaN"));
    }
}
