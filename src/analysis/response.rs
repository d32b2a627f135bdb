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
//!
//! A network need not add its inputs' effects, so the same field is also read on a realistic background
//! ([`Background::Swarm`]): the focal agent's own state and every other slot taken from observations of the
//! trained swarm (the run's actors deployed without noise, one observation of each agent every
//! [`SWARM_EVERY`] steps), the probe neighbour placed among the recorded ones by distance as perception
//! would (a probe farther than every neighbour of a full block is not seen, as in the swarm), and the
//! actions averaged over the backgrounds; `alone` is then the mean action on the backgrounds themselves.

use crate::learning::{Learners, Mode};
use crate::scene::{ObservationFrame, Policy, Scene};
use crate::sim::species::{SpeciesRegistry, ACTION_DIM, NEIGHBOUR_DIM, OWN_STATE_DIM};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// Cells per side of a field's grid (odd, so the focal agent sits in the centre cell).
pub(crate) const GRID: usize = 41;

/// The relative headings of the neighbour a field is computed for (radians to the left of the focal
/// agent's heading): parallel, crossing to the left, facing it, crossing to the right. The figures draw
/// the parallel one, Katz et al.'s case.
pub(crate) const REL_HEADINGS: [f64; 4] =
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

/// What surrounds the probe neighbour of a field.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Background {
    /// No one else in view: the focal agent straight ahead at its top speed, every other slot empty.
    Empty,
    /// Observations recorded in the trained swarm.
    Swarm,
}

/// How many observations of the swarm a field averages over at most, per focal species.
pub(crate) const SWARM_BACKGROUNDS: usize = 64;

/// Steps between two recorded observations of the swarm (so the backgrounds are not one moment).
pub(crate) const SWARM_EVERY: usize = 25;

/// A policy as a function of a batch of observations (`rows` of them, one after the other): `rows` ×
/// [`ACTION_DIM`] normalized actions.
pub(crate) type Actor<'a> = dyn Fn(usize, &[f32], usize) -> Vec<f32> + 'a;

/// The fields of every species `decides` (an actor per species index, None for a species without one),
/// for every species it observes (not blind to, with at least one slot), at every [`REL_HEADINGS`], with
/// no one else in view.
#[cfg(test)]
pub(crate) fn fields(scene: &Scene, decides: &[bool], act: &Actor) -> Vec<Field> {
    fields_on(scene, decides, act, &[], &REL_HEADINGS)
}

/// [`fields`] on the observations `backgrounds[s]` of each species s (rows of its layout), averaged over
/// them; a species without any gets the empty background. At the relative headings `headings`.
pub(crate) fn fields_on(
    scene: &Scene,
    decides: &[bool],
    act: &Actor,
    backgrounds: &[Vec<Vec<f32>>],
    headings: &[f64],
) -> Vec<Field> {
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
        let backs: Vec<Vec<f32>> = match backgrounds.get(s) {
            Some(b) if !b.is_empty() => b.clone(),
            _ => vec![blank],
        };
        let mean_of = |actions: &[f32], k: usize| {
            actions.chunks_exact(ACTION_DIM).map(|a| a[k] as f64).sum::<f64>() / backs.len() as f64
        };
        let on_backs = act(s, &backs.concat(), backs.len());
        let alone = [mean_of(&on_backs, 0), mean_of(&on_backs, 1)];
        for t in (0..registry.len()).filter(|&t| registry.slots(s, t) > 0 && !registry.blind[s][t]) {
            // Within the perception radius, and within the half edge (a neighbour farther on the torus is
            // nearer through the other side).
            let reach = registry.perception_radii[s][t].min(scene.world.arena_edge / 2.0);
            let centres: Vec<f64> = (0..GRID).map(|k| reach * (2.0 * (k as f64 + 0.5) / GRID as f64 - 1.0)).collect();
            let (at, slots) = (registry.block_offset(s, t), registry.slots(s, t));
            for &phi in headings {
                let dim = layout.dim();
                let mut batch = Vec::with_capacity(GRID * GRID * backs.len() * dim);
                for &left in &centres {
                    for &ahead in &centres {
                        let slot = [ahead, left, phi.cos() - 1.0, phi.sin()].map(|c| c as f32);
                        for back in &backs {
                            let mut obs = back.clone();
                            place_probe(&mut obs[at..at + slots * NEIGHBOUR_DIM], slot);
                            batch.extend_from_slice(&obs);
                        }
                    }
                }
                let actions = act(s, &batch, GRID * GRID * backs.len());
                let per_cell = backs.len() * ACTION_DIM;
                let cell = |row: usize, column: usize, k: usize| {
                    let (ahead, left) = (centres[column], centres[row]);
                    let seen = ahead.hypot(left) <= registry.perception_radii[s][t] && (ahead, left) != (0.0, 0.0);
                    if seen {
                        let from = (row * GRID + column) * per_cell;
                        mean_of(&actions[from..from + per_cell], k)
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

/// Places the probe `slot` into a block of neighbour slots (nearest first, empty ones zero) where its
/// distance puts it, the farthest dropping out of a full block: as perception would have written the block
/// with one more agent there.
fn place_probe(block: &mut [f32], slot: [f32; NEIGHBOUR_DIM]) {
    let distance = |s: &[f32]| s[0].hypot(s[1]);
    let mut seen: Vec<[f32; NEIGHBOUR_DIM]> = block
        .chunks_exact(NEIGHBOUR_DIM)
        .map(|s| s.try_into().expect("a slot"))
        .filter(|s: &[f32; NEIGHBOUR_DIM]| *s != [0.0; NEIGHBOUR_DIM])
        .collect();
    let k = seen.iter().position(|s| distance(s) > distance(&slot)).unwrap_or(seen.len());
    seen.insert(k, slot);
    block.fill(0.0);
    for (to, from) in block.chunks_exact_mut(NEIGHBOUR_DIM).zip(&seen) {
        to.copy_from_slice(from);
    }
}

/// The fields of a run's trained actors (its `Learned` and `Frozen` species) and of its rule-based
/// species (the rules read the same observations), on `background`: with no one else in view at every
/// [`REL_HEADINGS`], or in the trained swarm for a parallel neighbour.
pub fn of_run(run: &Path, background: Background) -> crate::error::Result<(Scene, Vec<Field>)> {
    let (scene, learners) = deployed(run)?;
    let fields = on(&scene, &learners, run, background)?;
    Ok((scene, fields))
}

/// A run's scene and its trained actors, loaded to be read.
fn deployed(run: &Path) -> crate::error::Result<(Scene, Learners)> {
    let dir = a_run(run)?;
    let scene = Scene::load(&dir.scene())?;
    let mut learners = Learners::new(&scene, Mode::Evaluate);
    crate::store::load_actors(&mut learners, &scene, Some(run))?;
    Ok((scene, learners))
}

/// The fields of a run's species ([`of_run`]), its scene and actors loaded.
fn on(scene: &Scene, learners: &Learners, run: &Path, background: Background) -> crate::error::Result<Vec<Field>> {
    let (backgrounds, headings) = match background {
        Background::Empty => (vec![], &REL_HEADINGS[..]),
        Background::Swarm => (swarm(scene, run)?, &REL_HEADINGS[..1]),
    };
    let registry = SpeciesRegistry::from_scene(scene);
    let decides: Vec<bool> =
        (0..registry.len()).map(|s| !matches!(registry.policy(s), Policy::Plugin(_) | Policy::Random)).collect();
    let dev = crate::learning::nets::Dev::default();
    let act = |s: usize, batch: &[f32], rows: usize| actions(learners, &registry, scene, &dev, s, batch, rows);
    Ok(fields_on(scene, &decides, &act, &backgrounds, headings))
}

/// What species `s` does on `rows` observations (`batch`, one after the other): its actor's actions where
/// it has one (without noise), else its rule's ([`crate::sim::policy::rule_action`]; zeros for a species
/// neither decides, and `Random`'s stream held still).
pub(crate) fn actions(
    learners: &Learners,
    registry: &SpeciesRegistry,
    scene: &Scene,
    dev: &crate::learning::nets::Dev,
    s: usize,
    batch: &[f32],
    rows: usize,
) -> Vec<f32> {
    match learners.species.get(s).and_then(Option::as_ref) {
        Some(l) => l.ddpg.act(dev, batch, rows),
        None => {
            // A rule with noise (Vicsek's, Couzin's) answers with its noise-free turn: the field is its
            // response to a neighbour, not one draw of zero-mean noise (a still stream would give every
            // draw the same end of its range).
            let quiet = without_noise(scene, s);
            let (scene, registry) = match &quiet {
                Some(q) => (q, &SpeciesRegistry::from_scene(q)),
                None => (scene, registry),
            };
            let mut rng = rand::rngs::mock::StepRng::new(0, 0);
            batch
                .chunks_exact(registry.observation_dim(s))
                .flat_map(|obs| {
                    crate::sim::policy::rule_action(obs, registry, s, scene, &mut rng).unwrap_or([0.0; ACTION_DIM])
                })
                .collect()
        }
    }
}

/// The scene with species `s`'s noisy rule (Vicsek's, Couzin's) at zero noise; None when its rule has none.
fn without_noise(scene: &Scene, s: usize) -> Option<Scene> {
    let mut quiet = scene.clone();
    match &mut quiet.species.get_mut(s)?.policy {
        Policy::Vicsek(rule) if rule.noise != 0.0 => rule.noise = 0.0,
        Policy::Couzin(rule) if rule.noise != 0.0 => rule.noise = 0.0,
        _ => return None,
    }
    Some(quiet)
}

/// The field of species `s` for one more agent of species `t`, parallel to it, amid the observation `obs`
/// of one of its agents: the rule that agent follows where it is now (the viewer's overlay).
#[cfg(feature = "viewer")]
pub(crate) fn field_here(scene: &Scene, act: &Actor, s: usize, t: usize, obs: &[f32]) -> Option<Field> {
    let registry = SpeciesRegistry::from_scene(scene);
    let decides: Vec<bool> = (0..registry.len()).map(|k| k == s).collect();
    let mut backgrounds = vec![vec![]; registry.len()];
    backgrounds[s] = vec![obs.to_vec()];
    let observed = registry.defs.get(t)?.name.clone();
    fields_on(scene, &decides, act, &backgrounds, &REL_HEADINGS[..1]).into_iter().find(|f| f.observed == observed)
}

/// Observations of the trained swarm per species, at most [`SWARM_BACKGROUNDS`] each, evenly spread over
/// one episode of the run's scene sampled every [`SWARM_EVERY`] steps.
fn swarm(scene: &Scene, run: &Path) -> crate::error::Result<Vec<Vec<Vec<f32>>>> {
    let recorded = super::swarm::record(scene, run, 1, SWARM_EVERY, &super::swarm::with_actors(scene))?;
    Ok(recorded
        .into_iter()
        .map(|r| {
            let Some(r) = r else { return vec![] };
            let rows: Vec<&[f32]> = r.observations.chunks_exact(r.dim).collect();
            let step = rows.len().div_ceil(SWARM_BACKGROUNDS).max(1);
            rows.into_iter().step_by(step).map(<[f32]>::to_vec).collect()
        })
        .collect())
}

/// `run` as a run folder with trained actors this program can deploy (its species plugins).
fn a_run(run: &Path) -> crate::error::Result<crate::store::RunDir> {
    let dir = crate::store::RunDir::new(run);
    if !dir.has_actors() {
        return Err(format!("--response {}: not a run folder with trained actors", run.display()).into());
    }
    dir.check_plugins()?;
    Ok(dir)
}

/// `response.csv`: one row per field and cell with a value.
pub(crate) fn csv(fields: &[Field]) -> String {
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
pub(crate) struct ResponseArgs {
    /// The rule each species of a run follows: its thrust and turn as a function of where one neighbour of
    /// each observed species is (the response field, read off the trained actors and the rules), with no
    /// one else in view (DIR/response.csv) and amid observations of the trained swarm
    /// (DIR/response-swarm.csv); heat maps of both in DIR/figures/.
    #[arg(long, help_heading = "Modes", value_name = "DIR")]
    pub(crate) response: Option<PathBuf>,
}

impl crate::run::args::Mode for ResponseArgs {
    const MODE: &'static str = "response";
    const TAKES: &'static [&'static str] = &["quiet"];
}

/// Writes a run's response fields: the CSV and, per species and observed species, the turn and thrust
/// maps for a parallel neighbour.
pub(crate) fn main(run: &Path) -> crate::error::Result<()> {
    // Checked before the lock, which would make the folder of a path that is not there.
    let dir = a_run(run)?;
    // A writer of a run: refuses a shipped run and one another process is writing.
    let _lock = dir.lock()?;
    crate::io::check_own_dir(&dir.figures())?;
    let (scene, learners) = deployed(run)?;
    // Both backgrounds' fields first, then every output checked, then written: a refusal (a link or a
    // folder where a file goes) leaves nothing behind, not half the files and an empty figures/.
    let mut outputs = vec![];
    for (background, stem, context) in
        [(Background::Empty, "response", "parallel"), (Background::Swarm, "response-swarm", "parallel, in the swarm")]
    {
        let fields = on(&scene, &learners, run, background)?;
        let figures: Vec<_> = fields
            .iter()
            .filter(|f| f.rel_heading == 0.0)
            .map(|f| (dir.figures().join(format!("{stem}-{}-{}", f.species, f.observed)), f.clone()))
            .collect();
        outputs.push((run.join(format!("{stem}.csv")), fields, figures, context));
    }
    let every: Vec<_> = outputs
        .iter()
        .flat_map(|(csv, _, figures, _)| {
            std::iter::once(csv.clone()).chain(figures.iter().flat_map(|(path, _)| super::plot::files(path)))
        })
        .collect();
    crate::io::check_targets(&every, crate::io::Existing::Replace)?;
    crate::io::own_dir(&dir.figures())?;
    for (csv_path, fields, figures, context) in outputs {
        crate::io::write_file(&csv_path, crate::io::Existing::Replace, csv(&fields).as_bytes())?;
        crate::outln!("wrote {}", csv_path.display())?;
        for (path, f) in figures {
            let map = |what: &str, values: &[Vec<f64>], diverging: bool, alone: f64| {
                let title = format!("{}: {what}, one {} {context} (alone: {alone:+.2})", f.species, f.observed);
                super::plot::Heatmap::body_frame(title, &f.centres, values, diverging)
            };
            let maps = [map("turn (+ left)", &f.turn, true, f.alone[1]), map("thrust", &f.thrust, false, f.alone[0])];
            super::plot::save_heatmaps(&path, &maps)?;
            crate::outln!("wrote {}.svg (and .png)", path.display())?;
        }
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

    /// The rules of `scene` as an actor; every species must have one.
    fn rule_actor<'a>(
        scene: &'a Scene,
        registry: &'a SpeciesRegistry,
    ) -> impl Fn(usize, &[f32], usize) -> Vec<f32> + 'a {
        move |s, batch, _| {
            let mut rng = rand::rngs::mock::StepRng::new(0, 0);
            batch
                .chunks_exact(registry.observation_dim(s))
                .flat_map(|o| crate::sim::policy::rule_action(o, registry, s, scene, &mut rng).unwrap())
                .collect()
        }
    }

    #[test]
    fn a_noisy_rule_answers_with_its_noise_free_turn() {
        // Vicsek prey at η = 1 rad and at η = 0: the same actions, not the low end of η's range.
        let with = |noise: f64| {
            let mut scene = rules();
            for def in scene.species.iter_mut().filter(|d| d.name == "prey") {
                def.policy = Policy::Vicsek(crate::scene::VicsekRule { radius: 0.3, noise });
            }
            scene
        };
        let (noisy, quiet) = (with(1.0), with(0.0));
        let registry = SpeciesRegistry::from_scene(&noisy);
        let prey = registry.defs.iter().position(|d| d.name == "prey").unwrap();
        let learners = crate::learning::Learners::new(&noisy, crate::learning::Mode::Evaluate);
        let dev = crate::learning::nets::Dev::default();
        let rows = 8;
        let batch: Vec<f32> =
            (0..rows * registry.observation_dim(prey)).map(|i| ((i * 37 % 11) as f32 - 5.0) / 10.0).collect();
        let act =
            |scene: &Scene| actions(&learners, &SpeciesRegistry::from_scene(scene), scene, &dev, prey, &batch, rows);
        assert_eq!(act(&noisy), act(&quiet));
    }

    fn rule_fields(scene: &Scene) -> Vec<Field> {
        let registry = SpeciesRegistry::from_scene(scene);
        let act = rule_actor(scene, &registry);
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

    #[test]
    fn a_probe_is_placed_among_the_recorded_neighbours_by_distance() {
        let slot = |d: f32| [d, 0.0, 0.0, 0.0];
        let mut block: Vec<f32> = [slot(0.2), slot(0.5), [0.0; 4]].concat();
        place_probe(&mut block, slot(0.3));
        assert_eq!(block, [slot(0.2), slot(0.3), slot(0.5)].concat());
        // A full block: a nearer probe pushes the farthest out, a farther one is not seen.
        place_probe(&mut block, slot(0.1));
        assert_eq!(block, [slot(0.1), slot(0.2), slot(0.3)].concat());
        place_probe(&mut block, slot(0.7));
        assert_eq!(block, [slot(0.1), slot(0.2), slot(0.3)].concat());
    }

    #[test]
    fn a_field_on_the_empty_background_is_the_field_alone_and_a_swarm_background_averages() {
        let scene = rules();
        let registry = SpeciesRegistry::from_scene(&scene);
        let act = rule_actor(&scene, &registry);
        let decides = vec![true; registry.len()];
        // (compared as their CSV: NaN, where unobserved, equals nothing)
        assert!(csv(&fields_on(&scene, &decides, &act, &[], &REL_HEADINGS)) == csv(&rule_fields(&scene)));
        // A prey background with a predator close on its right: the fleer turns left (+1) there unless the
        // probe predator is nearer; alone (no probe) it turns left.
        let prey = registry.defs.iter().position(|d| d.name == "prey").unwrap();
        let predator = 1 - prey;
        let mut back = vec![0.0f32; registry.observation_dim(prey)];
        let at = registry.block_offset(prey, predator);
        back[at..at + 4].copy_from_slice(&[0.0, -0.2, 0.0, 0.0]);
        let mut backgrounds = vec![vec![]; registry.len()];
        backgrounds[prey] = vec![back];
        let all = fields_on(&scene, &decides, &act, &backgrounds, &REL_HEADINGS[..1]);
        let f = all.iter().find(|f| f.species == "prey" && f.observed == "predator").unwrap();
        assert_eq!(f.alone[1], 1.0);
        assert!(turn_at(f, 0.0, 0.1) < 0.0, "a nearer predator on the left turns it right");
        assert_eq!(turn_at(f, 0.0, 0.5), 1.0, "a farther one leaves the nearest recorded predator to flee");
    }
}
