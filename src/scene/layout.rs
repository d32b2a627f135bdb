//! The observation and action layout a scene implies (Section "Agent Observation"): own state, then one
//! block of `topological_limit` neighbour slots per species of the scene, in the scene's order.

use super::schema::Scene;

/// Own state in the observation: [x, y, v_x, v_y, h_x, h_y].
pub const OWN_STATE_DIM: usize = 6;
/// Per observed neighbour: [Δx, Δy, h_jx − h_ix, h_jy − h_iy].
pub const NEIGHBOUR_DIM: usize = 4;
/// An action is [thrust, turn rate], normalized to [−1, 1] each.
pub const ACTION_DIM: usize = 2;

/// d_o of a species that observes at most `topological_limit` of each of `species` species.
pub fn observation_dim(topological_limit: usize, species: usize) -> usize {
    OWN_STATE_DIM + NEIGHBOUR_DIM * topological_limit * species
}

impl Scene {
    /// d_o of species `s` of this scene.
    pub fn observation_dim(&self, s: usize) -> usize {
        observation_dim(self.species[s].topological_limit, self.species.len())
    }
}
