//! Species are data: a registry of definitions loaded from the scene. A scene adds a third species with one
//! more entry (see `tests/scenes.rs`), and its policy can be a `Plugin(name)` decided by your own system in
//! `SimSet::Decide`; nothing in the core names "predator" or "prey".

use crate::scene::{Perception, Policy, Scene, SpeciesDef};
use bevy::prelude::*;

/// Own state in the observation: [x, y, v_x, v_y, h_x, h_y].
pub const OWN_STATE_DIM: usize = 6;
/// Per observed neighbour: [Δx, Δy, h_jx − h_ix, h_jy − h_iy].
pub const NEIGHBOUR_DIM: usize = 4;
/// An action is [thrust, turn rate], normalized to [−1, 1] each.
pub const ACTION_DIM: usize = 2;

/// The species of the scene, in registry order (which is also the order of observation blocks).
#[derive(Resource, Clone, Debug)]
pub struct SpeciesRegistry {
    pub defs: Vec<SpeciesDef>,
    /// `catches[a][b]`: species a catches species b on contact.
    pub catches: Vec<Vec<bool>>,
    /// Perception radius R in metres, resolved against D.
    pub perception_radius: Vec<f64>,
}

impl SpeciesRegistry {
    pub fn from_scene(scene: &Scene) -> Self {
        let defs = scene.species.clone();
        let index = |name: &str| defs.iter().position(|d| d.name == name);
        let catches = defs
            .iter()
            .map(|a| {
                let mut row = vec![false; defs.len()];
                for target in &a.catches {
                    if let Some(b) = index(target) {
                        row[b] = true;
                    }
                }
                row
            })
            .collect();
        let d = scene.max_distance();
        let perception_radius = defs
            .iter()
            .map(|s| match s.perception {
                Perception::Full => d,
                Perception::FractionOfD(f) => f * d,
                Perception::Radius(r) => r,
            })
            .collect();
        SpeciesRegistry { defs, catches, perception_radius }
    }

    pub fn len(&self) -> usize {
        self.defs.len()
    }

    pub fn is_empty(&self) -> bool {
        self.defs.is_empty()
    }

    pub fn index_of(&self, name: &str) -> Option<usize> {
        self.defs.iter().position(|d| d.name == name)
    }

    /// d_o for an observer of species `s`: own state, then `topological_limit` neighbour slots for every
    /// species in registry order (54 for the paper's two species and limit 6).
    pub fn observation_dim(&self, s: usize) -> usize {
        OWN_STATE_DIM + NEIGHBOUR_DIM * self.defs[s].topological_limit * self.len()
    }

    /// Offset of the block of species `t` in the observation of species `s`.
    pub fn block_offset(&self, s: usize, t: usize) -> usize {
        OWN_STATE_DIM + NEIGHBOUR_DIM * self.defs[s].topological_limit * t
    }

    /// What decides the actions of species `s`.
    pub fn policy(&self, s: usize) -> &Policy {
        &self.defs[s].policy
    }

    /// Species that species `s` catches.
    pub fn prey_of(&self, s: usize) -> impl Iterator<Item = usize> + '_ {
        (0..self.len()).filter(move |&t| self.catches[s][t])
    }

    /// Species that catch species `s`.
    pub fn predators_of(&self, s: usize) -> impl Iterator<Item = usize> + '_ {
        (0..self.len()).filter(move |&t| self.catches[t][s])
    }
}
