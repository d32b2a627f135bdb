//! The parameters of the field's two reference models, as policies any species can take: Vicsek et al.'s
//! alignment with noise (Phys. Rev. Lett. 75, 1226, 1995) and Couzin et al.'s nested zones (J. Theor.
//! Biol. 218, 1, 2002). What they do with an observation is `sim::classic`.
//!
//! Both act through coevo's unicycle as every policy does: each step they choose a direction, turn toward
//! it by at most the species' `max_turn_rate`·dt (Couzin's turning rate θ·τ; Vicsek's particles turn at
//! once, so a Vicsek species needs `max_turn_rate`·dt ≥ π to do the same), and thrust fully, so they move
//! at the constant speed the thrust holds against drag (`max_thrust` / drag, clipped at `max_speed`), after
//! the few steps it takes to reach it from rest. Where they differ from the originals: they see only what
//! the observation holds (the nearest `topological_limit` of each species within the perception radius,
//! so a metric neighbourhood needs a limit above the number of neighbours it holds), bodies in contact
//! push apart (coevo's elastic contacts; a small `radius` makes them rare), Couzin's blind angle α is the
//! species' `field_of_view`, and both live on coevo's torus or in its walled box rather than Vicsek's
//! periodic square or Couzin's open space.

use serde::{Deserialize, Serialize};

/// Vicsek et al. (1995): each agent heads for the mean direction of the agents within `radius` (itself
/// included), plus an angle drawn uniformly from [−`noise`/2, `noise`/2]. Their η is `noise` (radians, in
/// [0, 2π]), their r is `radius` (metres); their speed v is the species' constant speed.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct VicsekRule {
    pub(crate) radius: f64,
    pub(crate) noise: f64,
}

/// Couzin et al. (2002): conspecifics closer than `repulsion_radius` (r_r) are turned away from, and
/// nothing else counts while any is; otherwise the agent aligns with those in the orientation zone (from
/// r_r out to r_o = r_r + `orientation_width`, Δr_o) and heads toward those in the attraction zone (from
/// r_o out to r_o + `attraction_width`, Δr_a), the two unit directions averaged when both zones hold
/// someone; with nobody in any zone it keeps its heading. The chosen direction is then turned by an angle
/// drawn from a normal distribution of standard deviation `noise` (σ, radians). Lengths in metres (the
/// original's unit is a body length: r_r = 1). Other species are not seen by the rule.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CouzinRule {
    pub(crate) repulsion_radius: f64,
    pub(crate) orientation_width: f64,
    pub(crate) attraction_width: f64,
    pub(crate) noise: f64,
}

impl VicsekRule {
    /// Every number of the rule with its field name, for validation.
    pub(crate) fn numbers(&self) -> [(&'static str, f64); 2] {
        [("radius", self.radius), ("noise", self.noise)]
    }
}

impl CouzinRule {
    /// Every number of the rule with its field name, for validation.
    pub(crate) fn numbers(&self) -> [(&'static str, f64); 4] {
        [
            ("repulsion_radius", self.repulsion_radius),
            ("orientation_width", self.orientation_width),
            ("attraction_width", self.attraction_width),
            ("noise", self.noise),
        ]
    }
}
