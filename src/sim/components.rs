//! The data of an agent: one entity per predator or prey, in the paper's terms.
//!
//! Physics runs in f64 so trajectories can be compared with float64 implementations (the authors' NumPy
//! code) step by step; observations and networks are f32.

use bevy::math::DVec2;
use bevy::prelude::*;

/// Stable identity of an agent within an episode: spawn order, species by species. Every agent has a
/// [`Slot`] (perception indexes only entities that have one).
#[derive(Component, Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
#[require(Slot)]
pub struct AgentId(pub u32);

/// Index of the agent's species in the [`crate::sim::species::SpeciesRegistry`].
#[derive(Component, Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct SpeciesId(pub usize);

/// x in metres, inside the arena.
#[derive(Component, Clone, Copy, Debug, PartialEq, Default)]
pub struct Position(pub DVec2);

/// v in m/s; not necessarily along the heading (contacts push sideways).
#[derive(Component, Clone, Copy, Debug, PartialEq, Default)]
pub struct Velocity(pub DVec2);

/// Heading angle θ in (−π, π]; h = (cos θ, sin θ).
#[derive(Component, Clone, Copy, Debug, PartialEq, Default)]
pub struct Heading(pub f64);

impl Heading {
    /// The unit heading vector h.
    pub(crate) fn unit(self) -> DVec2 {
        DVec2::new(self.0.cos(), self.0.sin())
    }
}

/// The body: mass m_i in kg and radius in m.
#[derive(Component, Clone, Copy, Debug, PartialEq)]
pub struct Body {
    pub(crate) mass: f64,
    pub radius: f64,
}

/// The action applied from t to t+1, in physical units: thrust a_F in N along h, turn rate a_R in rad/s.
#[derive(Component, Clone, Copy, Debug, PartialEq, Default)]
pub struct Action {
    pub thrust: f64,
    pub turn_rate: f64,
}

/// The reward of the agent's last transition t → t+1.
#[derive(Component, Clone, Copy, Debug, PartialEq, Default)]
pub struct Reward(pub f64);

/// Sum of the Hooke forces f_a from every overlapping agent at the current state (Eq. 1).
#[derive(Component, Clone, Copy, Debug, PartialEq, Default)]
pub struct ContactForce(pub DVec2);

/// Contacts at a state: how many agents this one catches / is caught by, what those contacts pay, and
/// walls touched.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct ContactCounts {
    /// Agents of species this one catches that overlap it (a predator's catches).
    pub catching: u32,
    /// Agents of species that catch this one that overlap it (a prey being caught).
    pub caught: u32,
    /// Walls the body penetrates (0 on the torus, 2 in a corner).
    pub walls: u32,
    /// The summed contact rewards of those contacts, pair by pair
    /// ([`crate::sim::species::SpeciesRegistry::contact_reward`]).
    pub(crate) contact_reward: f64,
}

/// Contacts at the current state and at the state before it (for rewards judged before the move).
#[derive(Component, Clone, Copy, Debug, PartialEq, Default)]
pub struct Contacts {
    pub now: ContactCounts,
    pub before: ContactCounts,
}

/// The authors' energy budget (`gym-pps` preset only).
#[derive(Component, Clone, Copy, Debug, PartialEq)]
pub struct Energy(pub f64);

/// Where the agent sits in this step's perceived state: `index` into [`crate::sim::perception::Population`]
/// and `row` in its species' observation / action batch.
#[derive(Component, Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct Slot {
    pub index: u32,
    pub(crate) row: u32,
}

/// Everything an agent is spawned with.
#[derive(Bundle, Clone, Debug)]
pub(crate) struct AgentBundle {
    pub(crate) id: AgentId,
    pub(crate) species: SpeciesId,
    pub(crate) position: Position,
    pub(crate) velocity: Velocity,
    pub(crate) heading: Heading,
    pub(crate) body: Body,
    pub(crate) action: Action,
    pub(crate) reward: Reward,
    pub(crate) contact_force: ContactForce,
    pub(crate) contacts: Contacts,
    pub(crate) slot: Slot,
}
