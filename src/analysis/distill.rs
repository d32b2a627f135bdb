//! Distilled rules: the actors of a run replaced by rules a collective-behaviour researcher can read,
//! fitted to what the agents do. Prey get a zonal rule (Couzin et al., J. Theor. Biol. 2002: repulsion,
//! alignment, attraction; plus evasion of predators) and a binned rule (the same kinds of term with a gain
//! per distance bin: an additive model per neighbour whose pull may change with distance in any way),
//! predators a pursuit rule (the nearest prey, the centre of the prey in view, the most isolated one), all
//! [`crate::scene`] policies that run everywhere a rule-based policy runs.
//!
//! The data: the swarm at the counts asked for ([`super::swarm::record`]), every agent's observation and
//! the action it took on it, step by step, for every species that acts by an actor or a rule (so a swarm
//! whose rule is known can be read as a trained one is: `tests/it/distill.rs`). The first half of the
//! episodes fits, the second half is held out.
//!
//! The fit ([`rule_fit`]): least squares per action (thrust and turn in [−1, 1]), the rule linear in its
//! gains. The zones' radii are chosen from [`RADII`] (fractions of the arena's edge) among choices in
//! which every zone holds at least one bin, by how well each predicts out of sample within the fitted
//! episodes (two folds of agents), so no gain is zero because its zone was left empty; the binned rule
//! has a gain for every bin and no zones to choose, its bins of one kind reported as one term. Each term is
//! reported per standard deviation of its feature with a cluster-bootstrap interval, and with its held-out
//! value (ΔR² of leaving it out). How well a rule fits as a whole is the fraction of each action's variance
//! it explains, as the rule acts (clamped to [−1, 1]), on the held-out episodes and on the fitted ones.

use super::rule_fit::{self, Design, Term, TermFit};
use crate::scene::{
    BinnedGains, BinnedRule, Overrides, Policy, PursuitGains, PursuitRule, RuleForm, Scene, ZonalRule, ZonalThrust,
    ZonalTurn,
};
use crate::sim::rules::{observed, observed_of, Own, PursuitFeatures, Seen};
use crate::sim::species::{SpeciesRegistry, ACTION_DIM};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// The radii a zone may end at, as fractions of the arena's edge: 0 leaves a zone empty, 1.5 reaches
/// every agent (the torus's farthest is 0.71 edges away, a box's 1.41).
pub(crate) const RADII: [f64; 12] = [0.0, 0.025, 0.05, 0.075, 0.1, 0.15, 0.2, 0.3, 0.4, 0.5, 0.75, 1.5];

/// What `--distill` wrote for one species.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Distilled {
    pub species: String,
    pub form: RuleForm,
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
    /// Every term but the constants: its gain per standard deviation and its held-out value, each with
    /// its interval.
    #[serde(default)]
    pub(crate) terms: Vec<TermFit>,
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

/// Whether `--distill` fits a rule to species `s` of `scene`: one with prey or predators ([`rule_for`])
/// whose actions coevo decides, by an actor or a rule (not a plugin's system).
pub(crate) fn fitted_species(scene: &Scene, registry: &SpeciesRegistry, s: usize) -> bool {
    !matches!(scene.species[s].policy, Policy::Plugin(_)) && rule_for(registry, s).is_some()
}

/// The names of how much a rule explains on the held-out episodes, [thrust, turn].
pub(crate) const EXPLAINED: [&str; ACTION_DIM] = ["explained_thrust", "explained_turn"];

/// What is reported of each term ([`TermFit`]), as suffixes of its name: the gain per SD and its
/// interval, the held-out ΔR² and its interval.
pub(crate) const STATISTICS: [&str; 6] =
    ["per_sd", "per_sd.low", "per_sd.high", "held_out", "held_out.low", "held_out.high"];

/// A term's numbers by [`STATISTICS`] (NaN for one that could not be had).
fn statistics(t: &TermFit) -> [f64; 6] {
    let (sd, ho) = (t.per_sd_interval.map(|i| i.map(Some)), t.held_out_gain_interval.map(|i| i.map(Some)));
    let [sd_low, sd_high] = sd.unwrap_or([None; 2]);
    let [ho_low, ho_high] = ho.unwrap_or([None; 2]);
    [t.per_sd, sd_low, sd_high, t.held_out_gain, ho_low, ho_high].map(|v| v.unwrap_or(f64::NAN))
}

/// A rule's parameters by name ([`ZonalRule::numbers`], [`PursuitRule::numbers`], a binned rule's gains
/// as [`BinnedRule::numbers`] names them, its edges left out: they are [`RADII`]); none for another policy.
fn parameters(policy: &Policy) -> Vec<(String, f64)> {
    let named = |numbers: &[(&str, f64)]| numbers.iter().map(|&(n, v)| (n.to_string(), v)).collect();
    match policy {
        Policy::Zonal(rule) => named(&rule.numbers()),
        Policy::Pursuit(rule) => named(&rule.numbers()),
        Policy::Binned(rule) => rule.numbers().into_iter().filter(|(n, _)| !n.starts_with("edges")).collect(),
        _ => vec![],
    }
}

/// The rule `--distill` fits in `form` to a species whose rule is of `kind` ([`rule_for`]), every gain zero.
fn template(kind: &Policy, form: RuleForm) -> Policy {
    match (kind, form) {
        (Policy::Zonal(_), RuleForm::Binned) => {
            let terms = binned_terms(RADII.len() - 1);
            Policy::Binned(binned_rule(&RADII, &terms, &vec![0.0; terms.len()]))
        }
        _ => kind.clone(),
    }
}

/// The names of the terms reported of `kind`'s rule in `form` (the constants left out; a binned rule's
/// bins of one kind under one name).
fn term_names(kind: &Policy, form: RuleForm) -> Vec<&'static str> {
    let terms = match (kind, form) {
        (Policy::Zonal(_), RuleForm::Binned) => binned_terms(RADII.len() - 1),
        (Policy::Zonal(_), _) => zonal_terms(form, [1, 2, 3, 1], RADII.len() - 1),
        _ => pursuit_terms(form),
    };
    let mut names: Vec<&str> = vec![];
    for name in terms.iter().map(|t| t.name).filter(|n| !n.ends_with("bias")) {
        if !names.contains(&name) {
            names.push(name);
        }
    }
    names
}

/// The forms `--distill` fits to a species of `kind` ([`rule_for`]): both zonal forms and the binned rule
/// to prey, both pursuit forms to predators.
pub(crate) fn forms_of(kind: &Policy) -> &'static [RuleForm] {
    match kind {
        Policy::Zonal(_) => &[RuleForm::Memoryless, RuleForm::Inertial, RuleForm::Binned],
        _ => &[RuleForm::Memoryless, RuleForm::Inertial],
    }
}

/// The names of a rule's numbers: its parameters, how much it explains, and each term's [`STATISTICS`].
fn number_names(kind: &Policy, form: RuleForm) -> Vec<String> {
    let statistics = term_names(kind, form).into_iter().flat_map(|t| STATISTICS.map(|s| format!("{t}.{s}")));
    parameters(&template(kind, form))
        .into_iter()
        .map(|(n, _)| n)
        .chain(EXPLAINED.map(String::from))
        .chain(statistics)
        .collect()
}

/// The numbers of a fitted rule, by name ([`number_names`]; NaN for what could not be had: an action
/// that never varied, a term that never did).
pub(crate) fn numbers(d: &Distilled) -> Vec<(String, f64)> {
    let explained = EXPLAINED.into_iter().zip(d.explained_held_out.map(|v| v.unwrap_or(f64::NAN)));
    let fixed = parameters(&d.policy).into_iter().chain(explained.map(|(name, v)| (name.to_string(), v)));
    let terms =
        d.terms.iter().flat_map(|t| STATISTICS.iter().zip(statistics(t)).map(|(s, v)| (format!("{}.{s}", t.name), v)));
    // A gain held at zero may be −0: the same number, shown as 0.
    fixed.chain(terms).map(|(name, v)| (name, v + 0.0)).collect()
}

/// Each term of a fitted rule (the constants left out) with the 95 % intervals of its gain per SD and of
/// its held-out ΔR² (NaN where there is none), for reading a fit as a whole.
pub fn term_intervals(d: &Distilled) -> Vec<(String, [f64; 2], [f64; 2])> {
    d.terms
        .iter()
        .map(|t| {
            let [_, sd_low, sd_high, _, ho_low, ho_high] = statistics(t);
            (t.name.clone(), [sd_low, sd_high], [ho_low, ho_high])
        })
        .collect()
}

/// Every name [`numbers`] gives, of either rule in either form.
pub(crate) fn names() -> Vec<String> {
    let mut names: Vec<String> = vec![];
    for kind in [Policy::Zonal(ZonalRule::default()), Policy::Pursuit(PursuitRule::default())] {
        for &form in forms_of(&kind) {
            for name in number_names(&kind, form) {
                if !names.contains(&name) {
                    names.push(name);
                }
            }
        }
    }
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

/// The rules `--distill` fits on runs of `scene` that are read in `forms`, each with the names of its
/// numbers ([`numbers`]): for every species it reads ([`fitted_species`]), in each of those forms it is
/// fitted in ([`forms_of`]).
pub(crate) fn rules(scene: &Scene, forms: &[RuleForm]) -> Vec<(String, RuleForm, Vec<String>)> {
    let registry = SpeciesRegistry::from_scene(scene);
    let mut out = vec![];
    for (s, def) in scene.species.iter().enumerate().filter(|&(s, _)| fitted_species(scene, &registry, s)) {
        let Some(kind) = rule_for(&registry, s) else { continue };
        for &form in forms_of(&kind).iter().filter(|f| forms.contains(f)) {
            out.push((def.name.clone(), form, number_names(&kind, form)));
        }
    }
    out
}

/// The (species, form, name) of every number `--distill` fits on runs of `scene` in `forms` ([`rules`]).
pub(crate) fn columns(scene: &Scene, forms: &[RuleForm]) -> Vec<(String, RuleForm, String)> {
    rules(scene, forms)
        .into_iter()
        .flat_map(|(species, form, names)| names.into_iter().map(move |n| (species.clone(), form, n)))
        .collect()
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

/// Species `s`'s rows (observations, actions, clusters) as a design of `features`' columns.
fn design(data: (&[f32], &[f32], &[usize]), dim: usize, k: usize, features: impl Fn(&[f32]) -> Vec<f64>) -> Design {
    let (obs, actions, clusters) = data;
    let mut d = Design::new(k);
    for ((o, a), &c) in obs.chunks_exact(dim).zip(actions.chunks_exact(ACTION_DIM)).zip(clusters) {
        d.push(&features(o), [a[0] as f64, a[1] as f64], c);
    }
    d
}

/// A prey's rows as [`binned`] features.
fn zonal_design(scene: &Scene, registry: &SpeciesRegistry, s: usize, data: (&[f32], &[f32], &[usize])) -> Design {
    let (edges, frame) = (edges(scene), scene.observation_frame);
    design(data, registry.observation_dim(s), LEADING + 5 * (edges.len() - 1), |o| {
        let kin = observed(o, registry, s, s, frame);
        let predators = observed_of(o, registry, s, registry.predators_of(s), frame);
        binned(Own::of(o, registry, s, frame), &kin, &predators, &edges)
    })
}

/// The terms of a zonal rule in `form` whose zones end at bins `r` (repulsion from 0), `o` (alignment
/// from `r`), `at` (attraction from `o`) and `p` (evasion from 0), of `bins` bins.
fn zonal_terms(form: RuleForm, [r, o, at, p]: [usize; 4], bins: usize) -> Vec<Term> {
    let zone = |from: usize, to: usize, column: &dyn Fn(usize) -> usize| (from..to).map(column).collect::<Vec<_>>();
    let (ahead, left, sin) = (|b| LEADING + 3 * b, |b| LEADING + 1 + 3 * b, |b| LEADING + 2 + 3 * b);
    let (p_ahead, p_left) = (|b| LEADING + 3 * bins + 2 * b, |b| LEADING + 1 + 3 * bins + 2 * b);
    let term = |action, name, columns| Term { action, name, columns };
    let inertial = form == RuleForm::Inertial;
    let mut terms = vec![term(1, "turn.bias", vec![0])];
    terms.extend(inertial.then(|| term(1, "turn.persistence", vec![1])));
    terms.extend([
        term(1, "turn.repulsion", zone(0, r, &left)),
        term(1, "turn.alignment", zone(r, o, &sin)),
        term(1, "turn.attraction", zone(o, at, &left)),
        term(1, "turn.evasion", zone(0, p, &p_left)),
        term(0, "thrust.bias", vec![0]),
    ]);
    terms.extend(inertial.then(|| term(0, "thrust.speed", vec![2])));
    terms.extend([
        term(0, "thrust.repulsion", zone(0, r, &ahead)),
        term(0, "thrust.attraction", zone(o, at, &ahead)),
        term(0, "thrust.evasion", zone(0, p, &p_ahead)),
    ]);
    terms
}

/// Every choice of zones a zonal rule is chosen from: each zone holds at least one bin of [`RADII`], so
/// every gain is fitted from data and none is zero because its zone was left empty.
fn zonal_candidates(form: RuleForm, bins: usize) -> impl Iterator<Item = Vec<Term>> {
    (1..=bins).flat_map(move |r| {
        (r + 1..=bins).flat_map(move |o| {
            (o + 1..=bins).flat_map(move |at| (1..=bins).map(move |p| zonal_terms(form, [r, o, at, p], bins)))
        })
    })
}

/// The zonal rule of `terms` ([`zonal_terms`]) with their `gains`: a zone's radius is where its last bin ends.
fn zonal_rule(edges: &[f64], terms: &[Term], gains: &[f64]) -> ZonalRule {
    let gain = |name: &str| terms.iter().zip(gains).find(|(t, _)| t.name == name).map_or(0.0, |(_, &g)| g);
    let outer = |name: &str, first: usize, per_bin: usize| {
        let last = terms.iter().find(|t| t.name == name).and_then(|t| t.columns.last()).copied();
        last.map_or(0.0, |c| edges[(c - first) / per_bin + 1])
    };
    let bins = edges.len() - 1;
    ZonalRule {
        repulsion_radius: outer("turn.repulsion", LEADING + 1, 3),
        alignment_radius: outer("turn.alignment", LEADING + 2, 3),
        attraction_radius: outer("turn.attraction", LEADING + 1, 3),
        evasion_radius: outer("turn.evasion", LEADING + 1 + 3 * bins, 2),
        turn: ZonalTurn {
            bias: gain("turn.bias"),
            persistence: gain("turn.persistence"),
            repulsion: gain("turn.repulsion"),
            alignment: gain("turn.alignment"),
            attraction: gain("turn.attraction"),
            evasion: gain("turn.evasion"),
        },
        thrust: ZonalThrust {
            bias: gain("thrust.bias"),
            speed: gain("thrust.speed"),
            repulsion: gain("thrust.repulsion"),
            attraction: gain("thrust.attraction"),
            evasion: gain("thrust.evasion"),
        },
    }
}

/// The terms of a [`BinnedRule`] on [`binned`]'s columns: the own state's two as the `Inertial` zonal rule
/// has them, and a gain per bin for each kind of neighbour term, the bins of one kind sharing its name
/// (the turn: the kin's left parts, their sin Δheading, the predators' left parts; the thrust: the kin's
/// and the predators' ahead parts).
fn binned_terms(bins: usize) -> Vec<Term> {
    let (ahead, left, sin) = (|b| LEADING + 3 * b, |b| LEADING + 1 + 3 * b, |b| LEADING + 2 + 3 * b);
    let (p_ahead, p_left) = (|b| LEADING + 3 * bins + 2 * b, |b| LEADING + 1 + 3 * bins + 2 * b);
    let per_bin = |action, name, column: &dyn Fn(usize) -> usize| {
        (0..bins).map(move |b| Term { action, name, columns: vec![column(b)] }).collect::<Vec<_>>()
    };
    let mut terms = vec![
        Term { action: 1, name: "turn.bias", columns: vec![0] },
        Term { action: 1, name: "turn.persistence", columns: vec![1] },
    ];
    terms.extend(per_bin(1, "turn.kin", &left));
    terms.extend(per_bin(1, "turn.alignment", &sin));
    terms.extend(per_bin(1, "turn.evasion", &p_left));
    terms.push(Term { action: 0, name: "thrust.bias", columns: vec![0] });
    terms.push(Term { action: 0, name: "thrust.speed", columns: vec![2] });
    terms.extend(per_bin(0, "thrust.kin", &ahead));
    terms.extend(per_bin(0, "thrust.evasion", &p_ahead));
    terms
}

/// The binned rule of `terms` ([`binned_terms`]) with their `gains`, on the bins of `edges`.
fn binned_rule(edges: &[f64], terms: &[Term], gains: &[f64]) -> BinnedRule {
    let of = |name: &str| terms.iter().zip(gains).filter(|(t, _)| t.name == name).map(|(_, &g)| g).collect::<Vec<_>>();
    let one = |name: &str| of(name).first().copied().unwrap_or(0.0);
    BinnedRule {
        edges: edges.to_vec(),
        turn: BinnedGains {
            bias: one("turn.bias"),
            kin: of("turn.kin"),
            alignment: of("turn.alignment"),
            evasion: of("turn.evasion"),
        },
        thrust: BinnedGains {
            bias: one("thrust.bias"),
            kin: of("thrust.kin"),
            alignment: vec![],
            evasion: of("thrust.evasion"),
        },
        persistence: one("turn.persistence"),
        speed: one("thrust.speed"),
    }
}

/// A predator's rows: a constant, the previous turn, the speed, then the nearest's, the centre's and the
/// most isolated's [ahead, left].
fn pursuit_design(scene: &Scene, registry: &SpeciesRegistry, s: usize, data: (&[f32], &[f32], &[usize])) -> Design {
    let frame = scene.observation_frame;
    design(data, registry.observation_dim(s), 9, |o| {
        let own = Own::of(o, registry, s, frame);
        let f = PursuitFeatures::of(own, &observed_of(o, registry, s, registry.prey_of(s), frame));
        let [n, c, i] = [f.nearest, f.centre, f.isolated];
        vec![1.0, own.turn, own.speed, n[0], n[1], c[0], c[1], i[0], i[1]]
    })
}

/// The terms of a pursuit rule in `form` ([`pursuit_design`]'s columns): the thrust reads the speed and
/// the ahead parts, the turn the previous turn and the left parts.
fn pursuit_terms(form: RuleForm) -> Vec<Term> {
    let inertial = form == RuleForm::Inertial;
    let term = |action, name, column| Term { action, name, columns: vec![column] };
    let mut terms = vec![term(1, "turn.bias", 0)];
    terms.extend(inertial.then(|| term(1, "persistence", 1)));
    terms.extend([term(1, "turn.nearest", 4), term(1, "turn.centre", 6), term(1, "turn.isolated", 8)]);
    terms.push(term(0, "thrust.bias", 0));
    terms.extend(inertial.then(|| term(0, "speed", 2)));
    terms.extend([term(0, "thrust.nearest", 3), term(0, "thrust.centre", 5), term(0, "thrust.isolated", 7)]);
    terms
}

/// The pursuit rule of `terms` ([`pursuit_terms`]) with their `gains`.
fn pursuit_rule(terms: &[Term], gains: &[f64]) -> PursuitRule {
    let gain = |name: &str| terms.iter().zip(gains).find(|(t, _)| t.name == name).map_or(0.0, |(_, &g)| g);
    let part = |p: &str| PursuitGains {
        bias: gain(&format!("{p}.bias")),
        nearest: gain(&format!("{p}.nearest")),
        centre: gain(&format!("{p}.centre")),
        isolated: gain(&format!("{p}.isolated")),
    };
    PursuitRule { turn: part("turn"), thrust: part("thrust"), persistence: gain("persistence"), speed: gain("speed") }
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
    let rows = (actions.len() / ACTION_DIM).max(1) as f64;
    // Summed, then divided: a constant action's mean is then that constant to the last bit or two.
    let (mut mean, mut squares) = ([0.0; ACTION_DIM], [0.0; ACTION_DIM]);
    for a in actions.chunks_exact(ACTION_DIM) {
        for k in 0..ACTION_DIM {
            mean[k] += a[k] as f64;
            squares[k] += a[k] as f64 * a[k] as f64;
        }
    }
    mean.iter_mut().for_each(|m| *m /= rows);
    let (mut residual, mut total) = ([0.0; ACTION_DIM], [0.0; ACTION_DIM]);
    for (o, a) in obs.chunks_exact(dim).zip(actions.chunks_exact(ACTION_DIM)) {
        let predicted = crate::sim::policy::rule_action(o, &registry, s, &scene, &mut rng).expect("a rule");
        for k in 0..ACTION_DIM {
            residual[k] += (a[k] as f64 - predicted[k] as f64).powi(2);
            total[k] += (a[k] as f64 - mean[k]).powi(2);
        }
    }
    // An action that never varied (its spread no more than rounding's, relative to its size) has no
    // variance to explain.
    std::array::from_fn(|k| (total[k] > 1e-12 * squares[k]).then(|| 1.0 - residual[k] / total[k]))
}

/// Fits the rules of every learned species of `run`, deployed on its scene with `overrides`, over
/// `episodes` episodes (the first half fitted, the rest held out).
pub(crate) fn distill(run: &Path, overrides: &Overrides, episodes: usize) -> crate::error::Result<DistilledFile> {
    if episodes < 2 {
        return Err(
            format!("--episodes {episodes}: --distill needs ≥ 2 (the first half fits, the rest is held out)").into()
        );
    }
    let dir = crate::store::RunDir::new(run);
    let scene = overrides.load(&dir.scene())?;
    let registry = SpeciesRegistry::from_scene(&scene);
    let read: Vec<bool> = (0..registry.len()).map(|s| fitted_species(&scene, &registry, s)).collect();
    let recorded = super::swarm::record(&scene, run, episodes, 1, &read)?;
    let mut species = vec![];
    for (s, r) in recorded.iter().enumerate() {
        let (Some(r), Some(kind)) = (r, rule_for(&registry, s)) else { continue };
        // The first half of the episodes fits, the rest is held out.
        let (dim, [fit, held_out]) = (r.dim, r.split(episodes.div_ceil(2)));
        let zonal = matches!(kind, Policy::Zonal(_));
        let rows = |data| match zonal {
            true => zonal_design(&scene, &registry, s, data),
            false => pursuit_design(&scene, &registry, s, data),
        };
        let (fit_rows, held_rows) = (rows(fit), rows(held_out));
        // One pass over the fitted rows for both forms.
        let normals = fit_rows.normals();
        for &form in forms_of(&kind) {
            let terms = match (zonal, form) {
                (true, RuleForm::Binned) => binned_terms(RADII.len() - 1),
                (true, _) => rule_fit::choose(&normals, zonal_candidates(form, RADII.len() - 1)),
                (false, _) => pursuit_terms(form),
            };
            let gains = rule_fit::gains(&terms, &normals);
            let policy = match (zonal, form) {
                (true, RuleForm::Binned) => Policy::Binned(binned_rule(&edges(&scene), &terms, &gains)),
                (true, _) => Policy::Zonal(zonal_rule(&edges(&scene), &terms, &gains)),
                (false, _) => Policy::Pursuit(pursuit_rule(&terms, &gains)),
            };
            // The intervals' resamples are drawn from the scene's seed, per species and form.
            let draws = scene.seed ^ ((s as u64) << 32) ^ form as u64;
            species.push(Distilled {
                species: registry.defs[s].name.clone(),
                form,
                explained_held_out: explained(&scene, s, &policy, held_out.0, held_out.1, dim),
                explained_fitted: explained(&scene, s, &policy, fit.0, fit.1, dim),
                rows_fitted: fit_rows.rows(),
                rows_held_out: held_rows.rows(),
                terms: rule_fit::term_fits(&terms, &fit_rows, &held_rows, draws),
                policy,
            });
        }
    }
    if species.is_empty() {
        return Err(format!(
            "--distill {}: no species with prey or predators acting by an actor or a rule to fit a rule to",
            run.display()
        )
        .into());
    }
    let counts = scene.species.iter().map(|d| (d.name.clone(), d.count)).collect();
    Ok(DistilledFile { counts, episodes, steps: scene.episode_steps, seed: scene.seed, species })
}

/// `--distill RUN`.
#[derive(clap::Args, Debug, Clone, Default)]
pub(crate) struct DistillArgs {
    /// Fit readable rules to a run's trained actors: a zonal rule (repulsion, alignment, attraction,
    /// predator evasion) and a binned rule (those terms with a gain per distance bin) for prey, a pursuit
    /// rule for predators, on the actors deployed without noise
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
    let dir = crate::store::RunDir::new(run);
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

    /// Observations of a prey in the standard scene's layout, with its actions from `rule` itself.
    fn rule_data(scene: &Scene, rule: &Policy, rows: usize) -> (Vec<f32>, Vec<f32>) {
        use rand::{Rng, SeedableRng};
        use std::f32::consts::PI;
        let mut scene = scene.clone();
        let s = scene.species.iter().position(|d| d.name == "prey").unwrap();
        scene.species[s].policy = rule.clone();
        let registry = SpeciesRegistry::from_scene(&scene);
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
            actions.extend(crate::sim::policy::rule_action(&o, &registry, s, &scene, &mut rng).expect("a rule"));
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
        let (obs, actions) = rule_data(&scene, &Policy::Zonal(rule.clone()), 4000);
        let dim = registry.observation_dim(s);
        // Clusters of 20 rows, as agents in an episode would be.
        let clusters: Vec<usize> = (0..4000).map(|row| row / 20).collect();
        let rows = zonal_design(&scene, &registry, s, (&obs, &actions, &clusters));
        let normals = rows.normals();
        let fit = |form| {
            let terms = rule_fit::choose(&normals, zonal_candidates(form, RADII.len() - 1));
            zonal_rule(&edges(&scene), &terms, &rule_fit::gains(&terms, &normals))
        };
        let fitted = fit(RuleForm::Inertial);
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
        // An action held constant (a thrust of 0.7 in every row, which f32 cannot hold exactly) has no
        // variance to explain: none, never a huge negative fraction from rounding.
        let constant: Vec<f32> = actions.chunks_exact(ACTION_DIM).flat_map(|a| [0.7, a[1]]).collect();
        let [thrust, turn] = explained(&scene, s, &Policy::Zonal(fitted.clone()), &obs, &constant, dim);
        assert!(thrust.is_none() && turn.is_some(), "{thrust:?} {turn:?}");
        // Fitted without its own state, the rule holds persistence and speed at zero.
        let memoryless = fit(RuleForm::Memoryless);
        assert_eq!((memoryless.turn.persistence, memoryless.thrust.speed), (0.0, 0.0));
    }

    #[test]
    fn a_binned_rule_is_recovered_from_its_own_actions_and_its_absent_alignment_adds_nothing() {
        let mut scene = Scene::preset("gym-pps").unwrap();
        scene.observation_frame = ObservationFrame::Body;
        let registry = SpeciesRegistry::from_scene(&scene);
        let s = registry.defs.iter().position(|d| d.name == "prey").unwrap();
        let (edges, bins) = (edges(&scene), RADII.len() - 1);
        // A pull that changes sign with distance (away close by, toward farther out), no alignment, and an
        // evasion that fades with distance; gains small enough that the actions rarely saturate.
        let ramp = |f: &dyn Fn(f64) -> f64| (0..bins).map(|b| f(b as f64 / bins as f64)).collect::<Vec<_>>();
        let rule = BinnedRule {
            edges: edges.clone(),
            turn: BinnedGains {
                bias: 0.05,
                kin: ramp(&|x| 0.15 * x - 0.05),
                alignment: vec![0.0; bins],
                evasion: ramp(&|x| -0.2 * (1.0 - x)),
            },
            thrust: BinnedGains { bias: 0.3, kin: ramp(&|x| 0.1 * x), alignment: vec![], evasion: ramp(&|x| -0.1 * x) },
            persistence: 0.3,
            speed: -0.2,
        };
        let policy = Policy::Binned(rule.clone());
        let (fit, held) = (rule_data(&scene, &policy, 4000), rule_data(&scene, &policy, 2000));
        let clusters: Vec<usize> = (0..4000).map(|row| row / 20).collect();
        let rows = |(obs, actions): &(Vec<f32>, Vec<f32>)| {
            zonal_design(&scene, &registry, s, (obs, actions, &clusters[..actions.len() / ACTION_DIM]))
        };
        let (fit_rows, held_rows) = (rows(&fit), rows(&held));
        let terms = binned_terms(bins);
        let fitted = binned_rule(&edges, &terms, &rule_fit::gains(&terms, &fit_rows.normals()));
        // The data's neighbours lie within 1 m (`rule_data`): the bins beyond hold none, and their gains
        // stay at zero.
        let bin = |name: &str| name.find('[').map(|at| name[at + 1..name.len() - 1].parse::<usize>().unwrap());
        let seen = |name: &str| name.starts_with("edges") || bin(name).is_none_or(|b| edges[b] < 1.0);
        for ((name, a), (_, b)) in fitted.numbers().iter().zip(rule.numbers()) {
            let b = if seen(name) { b } else { 0.0 };
            assert!((a - b).abs() < 0.02, "{name}: fitted {a}, true {b}");
        }
        let dim = registry.observation_dim(s);
        let [thrust, turn] = explained(&scene, s, &Policy::Binned(fitted), &held.0, &held.1, dim);
        assert!(thrust.unwrap() > 0.99 && turn.unwrap() > 0.99, "{thrust:?} {turn:?}");
        // Each kind of term as a group: alignment, absent, adds nothing held out; evasion and the kin do.
        let fits = rule_fit::term_fits(&terms, &fit_rows, &held_rows, 1);
        let held_out = |name: &str| fits.iter().find(|t| t.name == name).unwrap().held_out_gain.unwrap();
        assert!(held_out("turn.alignment").abs() < 0.005, "{fits:?}");
        assert!(held_out("turn.evasion") > 0.05 && held_out("turn.kin") > 0.02, "{fits:?}");
        assert_eq!(term_names(&Policy::Zonal(ZonalRule::default()), RuleForm::Binned).len(), 7);
    }
}
