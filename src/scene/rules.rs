//! The parameters of the distilled rules: a prey rule in the spirit of Couzin et al.'s zones (J. Theor.
//! Biol. 2002) with predator evasion, and a predator's pursuit. `coevo --distill RUN` fits them to a
//! trained run's actors (`analysis::distill`); a scene names them with their parameters, like any
//! rule-based policy. What they do with an observation is `sim::rules`.
//!
//! Both are linear in their gains on the normalized action, clamped to [−1, 1]: every neighbour adds its
//! unit direction (ahead, left) in the focal agent's body frame, the left part to the turn and the ahead
//! part to the thrust, weighted by the gain of the zone it falls in. A positive turn gain on a zone turns
//! toward its members (attraction), a negative one away (repulsion, evasion); a positive thrust gain
//! speeds up for members ahead and slows for members behind. Two terms read the agent itself:
//! `persistence` weighs its previous turn command (the body-frame observation's turn state; zero in a
//! world-frame scene, which does not observe it) and `speed` its speed along its heading as a fraction of
//! its top speed: the inertia of its turning and the regulation of its speed.

use serde::{Deserialize, Serialize};

/// A prey's zonal rule. Conspecifics fall in nested zones by distance d: repulsion d < `repulsion_radius`,
/// alignment `repulsion_radius` ≤ d < `alignment_radius`, attraction `alignment_radius` ≤ d <
/// `attraction_radius`; predators within `evasion_radius` are evaded. A zone whose inner and outer radii
/// are equal is empty. Only the agents the observation holds count (the nearest `topological_limit`).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ZonalRule {
    /// Outer radius of each zone, in metres.
    pub(crate) repulsion_radius: f64,
    pub(crate) alignment_radius: f64,
    pub(crate) attraction_radius: f64,
    pub(crate) evasion_radius: f64,
    pub(crate) turn: ZonalTurn,
    pub(crate) thrust: ZonalThrust,
}

/// The turn of a [`ZonalRule`]: `bias` + `persistence`·(previous turn) + `repulsion`·Σ left +
/// `alignment`·Σ sin(Δheading) + `attraction`·Σ left + `evasion`·Σ left, each sum over the members of its
/// zone (left: the left component of the unit direction to a member; Δheading: the member's heading
/// relative to the focal one).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ZonalTurn {
    pub(crate) bias: f64,
    pub(crate) persistence: f64,
    pub(crate) repulsion: f64,
    pub(crate) alignment: f64,
    pub(crate) attraction: f64,
    pub(crate) evasion: f64,
}

/// The thrust of a [`ZonalRule`]: `bias` + `speed`·(speed / top speed) + `repulsion`·Σ ahead +
/// `attraction`·Σ ahead + `evasion`·Σ ahead (ahead: the component of the unit direction to a member along
/// the focal agent's heading).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ZonalThrust {
    pub(crate) bias: f64,
    pub(crate) speed: f64,
    pub(crate) repulsion: f64,
    pub(crate) attraction: f64,
    pub(crate) evasion: f64,
}

/// Which rule a fit reads: the zonal rule on the neighbours only (`Memoryless`, Couzin et al.'s zones:
/// `persistence` and `speed` held at zero) or also on the agent's own state (`Inertial`); or, for prey,
/// the [`BinnedRule`] (`Binned`), in which each neighbour's pull is a step function of its distance. A
/// one-step fit gives the own state what it can explain first, so `Memoryless` and `Inertial` differ in
/// their neighbour gains, not only by two terms.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Serialize, Deserialize)]
pub enum RuleForm {
    #[default]
    Memoryless,
    Inertial,
    Binned,
}

/// A term of a [`ZonalRule`], for ablations: [`ZonalRule::without`] zeroes its gains.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Serialize, Deserialize)]
pub enum ZonalTerm {
    Repulsion,
    Alignment,
    Attraction,
    Evasion,
}

impl ZonalRule {
    /// The same rule with the gains of `terms` set to zero (turn and thrust): an ablation.
    pub(crate) fn without(&self, terms: &[ZonalTerm]) -> ZonalRule {
        let mut rule = self.clone();
        for term in terms {
            match term {
                ZonalTerm::Repulsion => (rule.turn.repulsion, rule.thrust.repulsion) = (0.0, 0.0),
                ZonalTerm::Alignment => rule.turn.alignment = 0.0,
                ZonalTerm::Attraction => (rule.turn.attraction, rule.thrust.attraction) = (0.0, 0.0),
                ZonalTerm::Evasion => (rule.turn.evasion, rule.thrust.evasion) = (0.0, 0.0),
            }
        }
        rule
    }

    /// Every number of the rule with its field name, for validation.
    pub(crate) fn numbers(&self) -> [(&'static str, f64); 15] {
        let (t, f) = (&self.turn, &self.thrust);
        [
            ("repulsion_radius", self.repulsion_radius),
            ("alignment_radius", self.alignment_radius),
            ("attraction_radius", self.attraction_radius),
            ("evasion_radius", self.evasion_radius),
            ("turn.bias", t.bias),
            ("turn.persistence", t.persistence),
            ("turn.repulsion", t.repulsion),
            ("turn.alignment", t.alignment),
            ("turn.attraction", t.attraction),
            ("turn.evasion", t.evasion),
            ("thrust.bias", f.bias),
            ("thrust.speed", f.speed),
            ("thrust.repulsion", f.repulsion),
            ("thrust.attraction", f.attraction),
            ("thrust.evasion", f.evasion),
        ]
    }
}

/// A prey's rule additive over its neighbours, each neighbour's pull a step function of its distance: the
/// zonal rule's terms with a gain per distance bin instead of per zone (no zones to choose, no sign
/// imposed on any distance), plus the agent's own state as the `Inertial` zonal rule reads it. Bin b holds
/// distances in [`edges[b]`, `edges[b + 1]`); a neighbour beyond the last edge counts nowhere. The turn is
/// `bias` + `persistence`·(previous turn) + Σ over kin of `kin[b]`·left + `alignment[b]`·sin Δheading + Σ
/// over predators of `evasion[b]`·left; the thrust `bias` + `speed`·(speed / top speed) + Σ over kin of
/// `kin[b]`·ahead + Σ over predators of `evasion[b]`·ahead (b the neighbour's bin, left and ahead the
/// parts of the unit direction to it). The turn reads what turns with a mirror image (left, sin Δheading), the thrust what
/// does not (ahead), so a rule fitted to a mirror-symmetric agent is mirror-symmetric too.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BinnedRule {
    /// The bins' edges in metres, increasing from 0.
    pub(crate) edges: Vec<f64>,
    pub(crate) turn: BinnedGains,
    pub(crate) thrust: BinnedGains,
    #[serde(default)]
    pub(crate) persistence: f64,
    #[serde(default)]
    pub(crate) speed: f64,
}

/// One action's gains of a [`BinnedRule`], one per bin in each list (`alignment` is empty for the thrust).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BinnedGains {
    pub(crate) bias: f64,
    pub(crate) kin: Vec<f64>,
    #[serde(default)]
    pub(crate) alignment: Vec<f64>,
    pub(crate) evasion: Vec<f64>,
}

impl BinnedRule {
    /// The number of bins.
    pub(crate) fn bins(&self) -> usize {
        self.edges.len().saturating_sub(1)
    }

    /// The same rule with the gains of `terms` set to zero (turn and thrust): an ablation. A binned rule
    /// has no zones, so its kin gains are split by sign: `Repulsion` is every bin whose kin turn gain is
    /// negative (turning away from the kin there), `Attraction` every other bin.
    pub(crate) fn without(&self, terms: &[ZonalTerm]) -> BinnedRule {
        let mut rule = self.clone();
        for term in terms {
            match term {
                ZonalTerm::Alignment => rule.turn.alignment.iter_mut().for_each(|g| *g = 0.0),
                ZonalTerm::Evasion => {
                    rule.turn.evasion.iter_mut().chain(&mut rule.thrust.evasion).for_each(|g| *g = 0.0)
                }
                ZonalTerm::Repulsion | ZonalTerm::Attraction => {
                    let repulsion = *term == ZonalTerm::Repulsion;
                    for b in 0..self.bins() {
                        if (self.turn.kin[b] < 0.0) == repulsion {
                            rule.turn.kin[b] = 0.0;
                            rule.thrust.kin[b] = 0.0;
                        }
                    }
                }
            }
        }
        rule
    }

    /// Every number of the rule with its name (`turn.kin[3]`), for validation.
    pub(crate) fn numbers(&self) -> Vec<(String, f64)> {
        let mut out: Vec<(String, f64)> =
            self.edges.iter().enumerate().map(|(b, &e)| (format!("edges[{b}]"), e)).collect();
        for (part, g, own, v) in
            [("turn", &self.turn, "persistence", self.persistence), ("thrust", &self.thrust, "speed", self.speed)]
        {
            out.push((format!("{part}.bias"), g.bias));
            out.push((format!("{part}.{own}"), v));
            for (name, list) in [("kin", &g.kin), ("alignment", &g.alignment), ("evasion", &g.evasion)] {
                out.extend(list.iter().enumerate().map(|(b, &v)| (format!("{part}.{name}[{b}]"), v)));
            }
        }
        out
    }
}

/// A predator's pursuit rule: the turn and the thrust, each `bias` + `own` + `nearest`·u_nearest +
/// `centre`·u_centre + `isolated`·u_isolated, where u is the unit direction (its left part for the turn,
/// its ahead part for the thrust) to the nearest observed prey, to the centre of the observed prey, and to
/// the most isolated observed prey (the one farthest from its nearest observed fellow: the paper's
/// "marginal predation"), and `own` is `persistence`·(previous turn) for the turn, `speed`·(speed / top
/// speed) for the thrust. Without prey in view, the bias and the own term alone.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PursuitRule {
    pub(crate) turn: PursuitGains,
    pub(crate) thrust: PursuitGains,
    pub(crate) persistence: f64,
    pub(crate) speed: f64,
}

#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PursuitGains {
    pub(crate) bias: f64,
    pub(crate) nearest: f64,
    pub(crate) centre: f64,
    pub(crate) isolated: f64,
}

impl PursuitRule {
    /// Every number of the rule with its field name, for validation.
    pub(crate) fn numbers(&self) -> [(&'static str, f64); 10] {
        let (t, f) = (&self.turn, &self.thrust);
        [
            ("turn.bias", t.bias),
            ("turn.nearest", t.nearest),
            ("turn.centre", t.centre),
            ("turn.isolated", t.isolated),
            ("thrust.bias", f.bias),
            ("thrust.nearest", f.nearest),
            ("thrust.centre", f.centre),
            ("thrust.isolated", f.isolated),
            ("persistence", self.persistence),
            ("speed", self.speed),
        ]
    }
}
