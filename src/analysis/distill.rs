//! Distilled rules: the trained actors of a run replaced by rules a collective-behaviour researcher can
//! read, fitted to what the actors do. Prey get a zonal rule (Couzin et al., J. Theor. Biol. 2002:
//! repulsion, alignment, attraction; plus evasion of predators), predators a pursuit rule (the nearest
//! prey, the centre of the prey in view, the most isolated one), both [`crate::scene`] policies that run
//! everywhere a rule-based policy runs.
//!
//! The data: the trained swarm at the counts asked for ([`super::swarm::record`]), every learned agent's
//! observation and the action its actor took on it, step by step. The first half of the episodes fits,
//! the second half is held out.
//!
//! The loss: least squares on the two normalized actions together (thrust and turn in [−1, 1]), the rule
//! linear in its gains. The zones' radii are chosen from [`RADII`] (fractions of the arena's edge) by
//! exhaustive search, each choice with its least-squares gains; a small ridge keeps the gain of an empty
//! zone at zero. How well a rule fits is the fraction of each action's variance it explains, as the rule
//! acts (clamped to [−1, 1]), on the held-out episodes and on the fitted ones.

use crate::scene::{Overrides, Policy, PursuitGains, PursuitRule, RuleForm, Scene, ZonalRule, ZonalThrust, ZonalTurn};
use crate::sim::rules::{observed, observed_of, Own, PursuitFeatures, Seen};
use crate::sim::species::{SpeciesRegistry, ACTION_DIM};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// The radii a zone may end at, as fractions of the arena's edge: 0 leaves a zone empty, 1.5 reaches
/// every agent (the torus's farthest is 0.71 edges away, a box's 1.41).
pub(crate) const RADII: [f64; 12] = [0.0, 0.025, 0.05, 0.075, 0.1, 0.15, 0.2, 0.3, 0.4, 0.5, 0.75, 1.5];

/// The ridge added to every diagonal of the normal equations, per row: small enough not to shrink a
/// gain that has data (1e-9 of a unit feature's sum of squares), large enough to zero one that has none.
const RIDGE: f64 = 1e-9;

/// What `--distill` wrote for one species.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Distilled {
    pub(crate) species: String,
    pub(crate) form: RuleForm,
    /// `Zonal(..)` for a species that has predators, `Pursuit(..)` for one that only has prey.
    pub(crate) policy: Policy,
    /// Rows (agent-steps) fitted, and held out.
    pub(crate) rows_fitted: usize,
    pub(crate) rows_held_out: usize,
    /// Fraction of each action's variance the rule explains on the held-out episodes, [thrust, turn]
    /// (None for an action that never varied).
    pub(crate) explained_held_out: [Option<f64>; ACTION_DIM],
    /// The same on the fitted episodes.
    pub(crate) explained_fitted: [Option<f64>; ACTION_DIM],
}

/// `distilled.ron`: the rules fitted to a run, and the evaluation they were fitted on.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DistilledFile {
    pub counts: Vec<(String, usize)>,
    pub episodes: usize,
    pub steps: usize,
    pub(crate) seed: u64,
    pub species: Vec<Distilled>,
}

impl DistilledFile {
    pub fn read(path: &Path) -> crate::error::Result<DistilledFile> {
        let text = crate::io::read_text(path, crate::io::MAX_TEXT_BYTES)?;
        crate::scene::parse_ron(&text, &path.display().to_string())
    }

    /// The policy fitted to `species` in `form`.
    pub fn policy(&self, species: &str, form: RuleForm) -> Option<&Policy> {
        self.species.iter().find(|d| d.species == species && d.form == form).map(|d| &d.policy)
    }
}

/// The rule `--distill` fits to species `s`, with every gain zero: a zonal rule where it has predators,
/// else a pursuit rule where it has prey; None for a species with neither.
pub(crate) fn rule_for(registry: &SpeciesRegistry, s: usize) -> Option<Policy> {
    if registry.predators_of(s).next().is_some() {
        Some(Policy::Zonal(ZonalRule::default()))
    } else if registry.prey_of(s).next().is_some() {
        Some(Policy::Pursuit(PursuitRule::default()))
    } else {
        None
    }
}

/// The names of how much a rule explains on the held-out episodes, [thrust, turn].
pub(crate) const EXPLAINED: [&str; ACTION_DIM] = ["explained_thrust", "explained_turn"];

/// A rule's parameters by name ([`ZonalRule::numbers`], [`PursuitRule::numbers`]); none for another policy.
fn parameters(policy: &Policy) -> Vec<(&'static str, f64)> {
    match policy {
        Policy::Zonal(rule) => rule.numbers().to_vec(),
        Policy::Pursuit(rule) => rule.numbers().to_vec(),
        _ => vec![],
    }
}

/// The numbers of a fitted rule, by name: its policy's parameters and how much it explains on the
/// held-out episodes ([`EXPLAINED`]; NaN for an action that never varied).
pub(crate) fn numbers(d: &Distilled) -> Vec<(String, f64)> {
    let explained = EXPLAINED.into_iter().zip(d.explained_held_out.map(|v| v.unwrap_or(f64::NAN)));
    // A gain the ridge held at zero may be −0: the same number, shown as 0.
    parameters(&d.policy).into_iter().chain(explained).map(|(name, v)| (name.to_string(), v + 0.0)).collect()
}

/// Every name [`numbers`] gives, of either rule.
pub(crate) fn names() -> Vec<&'static str> {
    let mut names: Vec<&str> = vec![];
    for policy in [Policy::Zonal(ZonalRule::default()), Policy::Pursuit(PursuitRule::default())] {
        names
            .extend(parameters(&policy).into_iter().map(|(n, _)| n).filter(|n| !names.contains(n)).collect::<Vec<_>>());
    }
    names.extend(EXPLAINED);
    names
}

/// A run's fitted numbers by (species, form, name); empty without `distilled.ron`.
pub(crate) fn read_numbers(
    path: &Path,
) -> crate::error::Result<std::collections::BTreeMap<(String, RuleForm, String), f64>> {
    if !path.exists() {
        return Ok(Default::default());
    }
    let file = DistilledFile::read(path)?;
    Ok(file
        .species
        .iter()
        .flat_map(|d| numbers(d).into_iter().map(|(name, v)| ((d.species.clone(), d.form, name), v)))
        .collect())
}

/// The rules `--distill` fits on runs of `scene`, each with the names of its numbers ([`numbers`]): for
/// every learned species ([`rule_for`]), in both forms.
pub(crate) fn rules(scene: &Scene) -> Vec<(String, RuleForm, Vec<&'static str>)> {
    let registry = SpeciesRegistry::from_scene(scene);
    let mut out = vec![];
    for (s, def) in scene.species.iter().enumerate().filter(|(_, d)| d.policy == Policy::Learned) {
        let Some(policy) = rule_for(&registry, s) else { continue };
        let names: Vec<&str> = parameters(&policy).into_iter().map(|(n, _)| n).chain(EXPLAINED).collect();
        for form in [RuleForm::Memoryless, RuleForm::Inertial] {
            out.push((def.name.clone(), form, names.clone()));
        }
    }
    out
}

/// The (species, form, name) of every number `--distill` fits on runs of `scene` ([`rules`]).
pub(crate) fn columns(scene: &Scene) -> Vec<(String, RuleForm, String)> {
    rules(scene)
        .into_iter()
        .flat_map(|(species, form, names)| names.into_iter().map(move |n| (species.clone(), form, n.to_string())))
        .collect()
}

/// Least squares with [`RIDGE`]: the gains β minimising |y − Xβ|² given XᵀX (`gram`, k×k, row-major),
/// Xᵀy (`cross`) and the number of rows; also the sum of squared errors given yᵀy.
fn least_squares(gram: &[f64], cross: &[f64], yy: f64, rows: usize) -> (Vec<f64>, f64) {
    let k = cross.len();
    let mut a = gram.to_vec();
    for i in 0..k {
        a[i * k + i] += RIDGE * rows.max(1) as f64;
    }
    // Cholesky: a = L Lᵀ (a is symmetric positive definite with the ridge).
    let mut l = vec![0.0; k * k];
    for i in 0..k {
        for j in 0..=i {
            let sum: f64 = (0..j).map(|m| l[i * k + m] * l[j * k + m]).sum();
            l[i * k + j] = if i == j {
                (a[i * k + i] - sum).max(f64::MIN_POSITIVE).sqrt()
            } else {
                (a[i * k + j] - sum) / l[j * k + j]
            };
        }
    }
    let mut z = vec![0.0; k];
    for i in 0..k {
        z[i] = (cross[i] - (0..i).map(|m| l[i * k + m] * z[m]).sum::<f64>()) / l[i * k + i];
    }
    let mut beta = vec![0.0; k];
    for i in (0..k).rev() {
        beta[i] = (z[i] - (i + 1..k).map(|m| l[m * k + i] * beta[m]).sum::<f64>()) / l[i * k + i];
    }
    let fitted: f64 = (0..k).map(|i| beta[i] * cross[i]).sum();
    let quad: f64 = (0..k).map(|i| (0..k).map(|j| beta[i] * gram[i * k + j] * beta[j]).sum::<f64>()).sum();
    (beta, (yy - 2.0 * fitted + quad).max(0.0))
}

/// Sums over rows of f fᵀ and of f·y per action, for features f of each row.
struct Normal {
    k: usize,
    rows: usize,
    gram: Vec<f64>,
    cross: [Vec<f64>; ACTION_DIM],
    yy: [f64; ACTION_DIM],
}

impl Normal {
    fn new(k: usize) -> Normal {
        Normal { k, rows: 0, gram: vec![0.0; k * k], cross: [vec![0.0; k], vec![0.0; k]], yy: [0.0; ACTION_DIM] }
    }

    fn add(&mut self, f: &[f64], action: &[f32]) {
        self.rows += 1;
        for i in 0..self.k {
            if f[i] == 0.0 {
                continue;
            }
            for j in 0..self.k {
                self.gram[i * self.k + j] += f[i] * f[j];
            }
            for (a, &y) in action.iter().enumerate() {
                self.cross[a][i] += f[i] * y as f64;
            }
        }
        for (a, &y) in action.iter().enumerate() {
            self.yy[a] += y as f64 * y as f64;
        }
    }

    /// The normal equations of the features that sum `columns[c]` of this one's, for action `a`.
    fn combined(&self, columns: &[Vec<usize>], a: usize) -> (Vec<f64>, Vec<f64>) {
        let k = columns.len();
        let mut gram = vec![0.0; k * k];
        for (i, ci) in columns.iter().enumerate() {
            for (j, cj) in columns.iter().enumerate() {
                gram[i * k + j] = ci
                    .iter()
                    .flat_map(|&p| cj.iter().map(move |&q| (p, q)))
                    .map(|(p, q)| self.gram[p * self.k + q])
                    .sum();
            }
        }
        let cross = columns.iter().map(|c| c.iter().map(|&p| self.cross[a][p]).sum()).collect();
        (gram, cross)
    }
}

/// The zone bins of [`RADII`] in metres: bin b holds distances in [edges[b], edges[b + 1]).
fn edges(scene: &Scene) -> Vec<f64> {
    RADII.iter().map(|r| r * scene.world.arena_edge).collect()
}

/// Columns of [`binned`] before the bins: a constant, the previous turn, the speed.
const LEADING: usize = 3;

/// A prey's features by distance bin: [`LEADING`], then per bin the kin's Σ ahead, Σ left,
/// Σ sin(Δheading), then per bin the predators' Σ ahead, Σ left.
fn binned(own: Own, kin: &[Seen], predators: &[Seen], edges: &[f64]) -> Vec<f64> {
    let bins = edges.len() - 1;
    let mut f = vec![0.0; LEADING + 5 * bins];
    f[..LEADING].copy_from_slice(&[1.0, own.turn, own.speed]);
    let bin = |d: f64| (0..bins).find(|&b| d >= edges[b] && d < edges[b + 1]);
    for k in kin {
        if let Some(b) = bin(k.distance()) {
            let u = k.unit();
            f[LEADING + 3 * b] += u[0];
            f[LEADING + 1 + 3 * b] += u[1];
            f[LEADING + 2 + 3 * b] += k.sin_heading;
        }
    }
    for p in predators {
        if let Some(b) = bin(p.distance()) {
            let u = p.unit();
            f[LEADING + 3 * bins + 2 * b] += u[0];
            f[LEADING + 1 + 3 * bins + 2 * b] += u[1];
        }
    }
    f
}

/// The normal equations of a zonal rule's binned features ([`binned`]) over species `s`'s observations
/// and actions, which every form and choice of radii is fitted from.
fn zonal_normal(scene: &Scene, registry: &SpeciesRegistry, s: usize, data: (&[f32], &[f32], usize)) -> Normal {
    let (obs, actions, dim) = data;
    let edges = edges(scene);
    let frame = scene.observation_frame;
    let mut normal = Normal::new(LEADING + 5 * (edges.len() - 1));
    for (o, a) in obs.chunks_exact(dim).zip(actions.chunks_exact(ACTION_DIM)) {
        let kin = observed(o, registry, s, s, frame);
        let predators = observed_of(o, registry, s, registry.predators_of(s), frame);
        normal.add(&binned(Own::of(o, registry, s, frame), &kin, &predators, &edges), a);
    }
    normal
}

/// Fits a [`ZonalRule`] in `form` from its normal equations ([`zonal_normal`]).
fn fit_zonal(scene: &Scene, normal: &Normal, form: RuleForm) -> ZonalRule {
    // A memoryless rule's own-state columns are empty: the ridge holds their gains at zero.
    let own = |column: usize| if form == RuleForm::Inertial { vec![column] } else { vec![] };
    let edges = edges(scene);
    let bins = edges.len() - 1;
    let (ahead, left, sin) =
        (|b: usize| LEADING + 3 * b, |b: usize| LEADING + 1 + 3 * b, |b: usize| LEADING + 2 + 3 * b);
    let (p_ahead, p_left) = (|b: usize| LEADING + 3 * bins + 2 * b, |b: usize| LEADING + 1 + 3 * bins + 2 * b);
    let mut best: Option<(f64, ZonalRule)> = None;
    for r in 0..RADII.len() {
        for o in r..RADII.len() {
            for at in o..RADII.len() {
                for p in 0..RADII.len() {
                    let zone = |from: usize, to: usize, column: &dyn Fn(usize) -> usize| {
                        (from..to).map(column).collect::<Vec<_>>()
                    };
                    let turn =
                        [vec![0], own(1), zone(0, r, &left), zone(r, o, &sin), zone(o, at, &left), zone(0, p, &p_left)];
                    let thrust = [vec![0], own(2), zone(0, r, &ahead), zone(o, at, &ahead), zone(0, p, &p_ahead)];
                    let (gram, cross) = normal.combined(&thrust, 0);
                    let (bf, ef) = least_squares(&gram, &cross, normal.yy[0], normal.rows);
                    let (gram, cross) = normal.combined(&turn, 1);
                    let (bt, et) = least_squares(&gram, &cross, normal.yy[1], normal.rows);
                    if best.as_ref().is_some_and(|(e, _)| *e <= ef + et) {
                        continue;
                    }
                    let rule = ZonalRule {
                        repulsion_radius: edges[r],
                        alignment_radius: edges[o],
                        attraction_radius: edges[at],
                        evasion_radius: edges[p],
                        turn: ZonalTurn {
                            bias: bt[0],
                            persistence: bt[1],
                            repulsion: bt[2],
                            alignment: bt[3],
                            attraction: bt[4],
                            evasion: bt[5],
                        },
                        thrust: ZonalThrust {
                            bias: bf[0],
                            speed: bf[1],
                            repulsion: bf[2],
                            attraction: bf[3],
                            evasion: bf[4],
                        },
                    };
                    best = Some((ef + et, rule));
                }
            }
        }
    }
    best.expect("at least one choice of radii").1
}

/// The normal equations of a pursuit rule's features over species `s`'s observations and actions.
fn pursuit_normal(scene: &Scene, registry: &SpeciesRegistry, s: usize, data: (&[f32], &[f32], usize)) -> Normal {
    let (obs, actions, dim) = data;
    // Per row: a constant, the previous turn, the speed, then the nearest's, the centre's and the most
    // isolated's [ahead, left].
    let frame = scene.observation_frame;
    let mut normal = Normal::new(9);
    for (o, a) in obs.chunks_exact(dim).zip(actions.chunks_exact(ACTION_DIM)) {
        let own = Own::of(o, registry, s, frame);
        let f = PursuitFeatures::of(own, &observed_of(o, registry, s, registry.prey_of(s), frame));
        let row = [
            1.0,
            own.turn,
            own.speed,
            f.nearest[0],
            f.nearest[1],
            f.centre[0],
            f.centre[1],
            f.isolated[0],
            f.isolated[1],
        ];
        normal.add(&row, a);
    }
    normal
}

/// Fits a [`PursuitRule`] in `form` from its normal equations ([`pursuit_normal`]).
fn fit_pursuit(normal: &Normal, form: RuleForm) -> PursuitRule {
    // The thrust reads the speed and the ahead parts, the turn the previous turn and the left parts.
    let gains = |a: usize, own: usize, component: usize| {
        let own = if form == RuleForm::Inertial { vec![own] } else { vec![] };
        let columns = [vec![0], own, vec![3 + component], vec![5 + component], vec![7 + component]];
        let (gram, cross) = normal.combined(&columns, a);
        let (b, _) = least_squares(&gram, &cross, normal.yy[a], normal.rows);
        (PursuitGains { bias: b[0], nearest: b[2], centre: b[3], isolated: b[4] }, b[1])
    };
    let ((thrust, speed), (turn, persistence)) = (gains(0, 2, 0), gains(1, 1, 1));
    PursuitRule { turn, thrust, persistence, speed }
}

/// The fraction of each action's variance that `policy` explains on these rows, as it acts.
fn explained(
    scene: &Scene,
    s: usize,
    policy: &Policy,
    obs: &[f32],
    actions: &[f32],
    dim: usize,
) -> [Option<f64>; ACTION_DIM] {
    let mut scene = scene.clone();
    scene.species[s].policy = policy.clone();
    let registry = SpeciesRegistry::from_scene(&scene);
    let mut rng = rand::rngs::mock::StepRng::new(0, 0);
    let rows = actions.len() / ACTION_DIM;
    let mut mean = [0.0; ACTION_DIM];
    for a in actions.chunks_exact(ACTION_DIM) {
        (0..ACTION_DIM).for_each(|k| mean[k] += a[k] as f64 / rows.max(1) as f64);
    }
    let (mut residual, mut total) = ([0.0; ACTION_DIM], [0.0; ACTION_DIM]);
    for (o, a) in obs.chunks_exact(dim).zip(actions.chunks_exact(ACTION_DIM)) {
        let predicted = crate::sim::policy::rule_action(o, &registry, s, &scene, &mut rng).expect("a rule");
        for k in 0..ACTION_DIM {
            residual[k] += (a[k] as f64 - predicted[k] as f64).powi(2);
            total[k] += (a[k] as f64 - mean[k]).powi(2);
        }
    }
    // An action that never varied has no variance to explain.
    std::array::from_fn(|k| (total[k] > 0.0).then(|| 1.0 - residual[k] / total[k]))
}

/// Fits the rules of every learned species of `run`, deployed on its scene with `overrides`, over
/// `episodes` episodes (the first half fitted, the rest held out).
pub(crate) fn distill(run: &Path, overrides: &Overrides, episodes: usize) -> crate::error::Result<DistilledFile> {
    if episodes < 2 {
        return Err(
            format!("--episodes {episodes}: --distill needs ≥ 2 (the first half fits, the rest is held out)").into()
        );
    }
    let dir = crate::run::RunDir::new(run);
    let scene = overrides.load(&dir.scene())?;
    let registry = SpeciesRegistry::from_scene(&scene);
    let recorded = super::swarm::record(&scene, run, episodes, 1)?;
    let mut species = vec![];
    for (s, r) in recorded.iter().enumerate() {
        let (Some(r), Some(kind)) = (r, rule_for(&registry, s)) else { continue };
        // The first half of the episodes fits, the rest is held out.
        let (dim, [fit, held_out]) = (&r.dim, r.split(episodes.div_ceil(2)));
        let data = (fit.0, fit.1, *dim);
        // One pass over the rows for both forms.
        let normal = match kind {
            Policy::Zonal(_) => zonal_normal(&scene, &registry, s, data),
            _ => pursuit_normal(&scene, &registry, s, data),
        };
        for form in [RuleForm::Memoryless, RuleForm::Inertial] {
            let policy = match kind {
                Policy::Zonal(_) => Policy::Zonal(fit_zonal(&scene, &normal, form)),
                _ => Policy::Pursuit(fit_pursuit(&normal, form)),
            };
            species.push(Distilled {
                species: registry.defs[s].name.clone(),
                form,
                explained_held_out: explained(&scene, s, &policy, held_out.0, held_out.1, *dim),
                explained_fitted: explained(&scene, s, &policy, fit.0, fit.1, *dim),
                rows_fitted: fit.1.len() / ACTION_DIM,
                rows_held_out: held_out.1.len() / ACTION_DIM,
                policy,
            });
        }
    }
    if species.is_empty() {
        return Err(
            format!("--distill {}: no learned species with prey or predators to fit a rule to", run.display()).into()
        );
    }
    let counts = scene.species.iter().map(|d| (d.name.clone(), d.count)).collect();
    Ok(DistilledFile { counts, episodes, steps: scene.episode_steps, seed: scene.seed, species })
}

/// `--distill RUN`.
#[derive(clap::Args, Debug, Clone, Default)]
pub(crate) struct DistillArgs {
    /// Fit readable rules to a run's trained actors: a zonal rule (repulsion, alignment, attraction,
    /// predator evasion) for prey, a pursuit rule for predators, on the actors deployed without noise
    /// (--episodes, default 4: the first half fits, the rest is held out; --prey, --count, --steps, --seed
    /// as for --eval). Writes DIR/distilled.ron, whose policies a scene or --policy takes as they are.
    #[arg(long, help_heading = "Modes", value_name = "DIR")]
    pub(crate) distill: Option<PathBuf>,
}

impl crate::run::args::Mode for DistillArgs {
    const MODE: &'static str = "distill";
    const TAKES: &'static [&'static str] = &["episodes", "steps", "seed", "prey", "predators", "count", "quiet"];
}

/// The episodes `--distill` deploys the actors for unless told.
pub(crate) const EPISODES: usize = 4;

/// `--distill RUN`: fits, writes `RUN/distilled.ron` and prints each rule with how much it explains.
pub(crate) fn main(run: &Path, overrides: &Overrides, episodes: Option<usize>) -> crate::error::Result<()> {
    let dir = crate::run::RunDir::new(run);
    if !dir.has_actors() {
        return Err(format!("--distill {}: not a run folder with trained actors", run.display()).into());
    }
    dir.check_plugins()?;
    let _lock = dir.lock()?;
    let out = dir.distilled();
    crate::io::check_targets(std::slice::from_ref(&out), crate::io::Existing::Replace)?;
    let file = distill(run, overrides, episodes.unwrap_or(EPISODES))?;
    let text = ron::ser::to_string_pretty(&file, ron::ser::PrettyConfig::default().struct_names(false))
        .map_err(|e| format!("{}: {e}", out.display()))?;
    crate::io::write_file(&out, crate::io::Existing::Replace, format!("{text}\n").as_bytes())?;
    for d in &file.species {
        let shown = |x: Option<f64>| x.map_or("no variance".to_string(), |v| format!("{v:.2}"));
        crate::outln!(
            "{} ({:?}): variance explained on held-out episodes: thrust {}, turn {} ({} rows fitted, {} held out)",
            d.species,
            d.form,
            shown(d.explained_held_out[0]),
            shown(d.explained_held_out[1]),
            d.rows_fitted,
            d.rows_held_out
        )?;
        crate::outln!("  {}", ron::to_string(&d.policy).map_err(|e| e.to_string())?)?;
    }
    crate::outln!("wrote {}", out.display())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::{ObservationFrame, ZonalTerm};

    #[test]
    fn least_squares_recovers_known_gains_and_zeroes_an_empty_column() {
        // y = 0.5 + 2 x on x = 0..9, and a column that is always zero.
        let mut normal = Normal::new(3);
        for x in 0..10 {
            let y = 0.5 + 2.0 * x as f64;
            normal.add(&[1.0, x as f64, 0.0], &[y as f32, 0.0]);
        }
        let (gram, cross) = normal.combined(&[vec![0], vec![1], vec![2]], 0);
        let (b, sse) = least_squares(&gram, &cross, normal.yy[0], normal.rows);
        assert!((b[0] - 0.5).abs() < 1e-6 && (b[1] - 2.0).abs() < 1e-6 && b[2] == 0.0, "{b:?}");
        assert!(sse < 1e-6, "{sse}");
    }

    /// Observations of a prey in the standard scene's layout, with its actions from `rule` itself.
    fn rule_data(scene: &Scene, rule: &ZonalRule, rows: usize) -> (Vec<f32>, Vec<f32>) {
        use rand::{Rng, SeedableRng};
        use std::f32::consts::PI;
        let registry = SpeciesRegistry::from_scene(scene);
        let s = registry.defs.iter().position(|d| d.name == "prey").unwrap();
        let (kin, pred) = (registry.block_offset(s, s), registry.block_offset(s, 1 - s));
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let (mut obs, mut actions) = (vec![], vec![]);
        for _ in 0..rows {
            let mut o = vec![0.0f32; registry.observation_dim(s)];
            for (at, n) in [(kin, registry.slots(s, s)), (pred, registry.slots(s, 1 - s))] {
                for slot in 0..rng.gen_range(0..=n) {
                    let (d, b, h): (f32, f32, f32) =
                        (rng.gen_range(0.01..1.0), rng.gen_range(-PI..PI), rng.gen_range(-PI..PI));
                    let i = at + 4 * slot;
                    o[i..i + 4].copy_from_slice(&[d * b.cos(), d * b.sin(), h.cos() - 1.0, h.sin()]);
                }
            }
            // Own state: speed ahead and the previous turn.
            o[0] = rng.gen_range(0.0..registry.defs[s].max_speed as f32);
            o[2] = rng.gen_range(-1.0..1.0);
            let f = crate::sim::rules::ZonalFeatures::of(
                rule,
                Own::of(&o, &registry, s, ObservationFrame::Body),
                &observed(&o, &registry, s, s, ObservationFrame::Body),
                &observed(&o, &registry, s, 1 - s, ObservationFrame::Body),
            );
            actions.extend(crate::sim::rules::zonal_action(rule, &f));
            obs.extend(o);
        }
        (obs, actions)
    }

    #[test]
    fn a_zonal_rule_is_recovered_from_its_own_actions() {
        let mut scene = Scene::preset("gym-pps").unwrap();
        scene.observation_frame = ObservationFrame::Body;
        let edge = scene.world.arena_edge;
        // Radii on the search grid, gains small enough that the actions rarely saturate.
        let rule = ZonalRule {
            repulsion_radius: 0.05 * edge,
            alignment_radius: 0.2 * edge,
            attraction_radius: 0.4 * edge,
            evasion_radius: 0.3 * edge,
            turn: ZonalTurn {
                bias: 0.05,
                persistence: 0.3,
                repulsion: -0.2,
                alignment: 0.15,
                attraction: 0.1,
                evasion: -0.25,
            },
            thrust: ZonalThrust { bias: 0.3, speed: -0.2, repulsion: -0.1, attraction: 0.1, evasion: -0.2 },
        };
        let registry = SpeciesRegistry::from_scene(&scene);
        let s = registry.defs.iter().position(|d| d.name == "prey").unwrap();
        let (obs, actions) = rule_data(&scene, &rule, 4000);
        let dim = registry.observation_dim(s);
        let normal = zonal_normal(&scene, &registry, s, (&obs, &actions, dim));
        let fitted = fit_zonal(&scene, &normal, RuleForm::Inertial);
        assert_eq!(
            [fitted.repulsion_radius, fitted.alignment_radius, fitted.attraction_radius, fitted.evasion_radius],
            [rule.repulsion_radius, rule.alignment_radius, rule.attraction_radius, rule.evasion_radius]
        );
        for ((name, a), (_, b)) in fitted.numbers().iter().zip(rule.numbers()) {
            assert!((a - b).abs() < 0.02, "{name}: fitted {a}, true {b}");
        }
        let [thrust, turn] = explained(&scene, s, &Policy::Zonal(fitted.clone()), &obs, &actions, dim);
        assert!(thrust.unwrap() > 0.99 && turn.unwrap() > 0.99, "{thrust:?} {turn:?}");
        // Without its alignment the rule explains less of the turn.
        let ablated = Policy::Zonal(fitted.without(&[ZonalTerm::Alignment]));
        assert!(explained(&scene, s, &ablated, &obs, &actions, dim)[1].unwrap() < 0.95);
        // Fitted without its own state, the rule holds persistence and speed at zero.
        let memoryless = fit_zonal(&scene, &normal, RuleForm::Memoryless);
        assert_eq!((memoryless.turn.persistence, memoryless.thrust.speed), (0.0, 0.0));
    }
}
