//! The observation and action layout a scene implies (Section "Agent Observation"): own state, then one
//! block of neighbour slots per species of the scene, in the scene's order; in the authors' order
//! (difference 4 of docs/src/results/authors-code.md) own position and velocity, the blocks, an energy input, then own heading.
//!
//! [`Layout`] is the one place that knows where each part of an observation sits: perception writes by it,
//! controls alter its blocks, environments bound it, the viewer labels it.

use super::schema::{ObservationLayout, Scene, SpeciesDef};
use std::ops::Range;

/// Own state in the paper's observation: [x, y, v_x, v_y, h_x, h_y].
pub(crate) const OWN_STATE_DIM: usize = 6;
/// Per observed neighbour: [Δx, Δy, h_jx − h_ix, h_jy − h_iy].
pub(crate) const NEIGHBOUR_DIM: usize = 4;
/// An action is [thrust, turn rate], normalized to [−1, 1] each.
pub(crate) const ACTION_DIM: usize = 2;

/// Where the parts of one species' observation sit.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) struct Layout {
    pub(crate) order: ObservationLayout,
    /// Neighbour slots per observed species, in the scene's species order.
    pub(crate) slots: Vec<usize>,
}

impl Layout {
    /// The numbers of own state before the blocks: the paper's six, or the authors' [x, y, v_x, v_y].
    pub(crate) fn leading(&self) -> usize {
        match self.order {
            ObservationLayout::Paper => OWN_STATE_DIM,
            ObservationLayout::Authors => 4,
        }
    }

    /// Where the block of observed species `t` starts (`t` = the species count: where the blocks end).
    fn offset(&self, t: usize) -> usize {
        self.slots[..t].iter().fold(self.leading(), |at, &k| at.saturating_add(k.saturating_mul(NEIGHBOUR_DIM)))
    }

    /// The block of observed species `t`: `slots[t]` neighbours of [`NEIGHBOUR_DIM`] numbers each.
    pub(crate) fn block(&self, t: usize) -> Range<usize> {
        self.offset(t)..self.offset(t + 1)
    }

    /// Every neighbour block, which lie side by side.
    pub(crate) fn neighbours(&self) -> Range<usize> {
        self.leading()..self.offset(self.slots.len())
    }

    /// The energy input, in the authors' order only.
    pub(crate) fn energy(&self) -> Option<usize> {
        (self.order == ObservationLayout::Authors).then(|| self.neighbours().end)
    }

    /// Own heading [h_x, h_y] (in the body frame, the paper's order holds other own numbers there).
    pub(crate) fn heading(&self) -> Range<usize> {
        match self.energy() {
            None => 4..6,
            Some(e) => e + 1..e + 3,
        }
    }

    /// Writes own state into `out`, a row of this layout: the paper's six numbers `own` in order, or in the
    /// authors' order `own`'s position and velocity first, `energy` after the blocks, then `own`'s heading.
    pub(crate) fn place_own<T: Copy>(&self, out: &mut [T], own: [T; OWN_STATE_DIM], energy: T) {
        match self.energy() {
            None => out[..OWN_STATE_DIM].copy_from_slice(&own),
            Some(e) => {
                out[..4].copy_from_slice(&own[..4]);
                out[e] = energy;
                out[self.heading()].copy_from_slice(&own[4..]);
            }
        }
    }

    /// d_o.
    pub(crate) fn dim(&self) -> usize {
        self.neighbours().end.saturating_add(if self.energy().is_some() { 3 } else { 0 })
    }
}

/// The slots an observer of species `def` has for `observed`: its `topological_limit_of` entry, else its
/// `topological_limit`.
pub(crate) fn slots(def: &SpeciesDef, observed: &str) -> usize {
    def.topological_limit_of.iter().find(|(name, _)| name == observed).map_or(def.topological_limit, |&(_, k)| k)
}

impl Scene {
    /// The layout of species `s`'s observation.
    pub(crate) fn layout(&self, s: usize) -> Layout {
        let def = &self.species[s];
        Layout { order: self.observation_layout, slots: self.species.iter().map(|t| slots(def, &t.name)).collect() }
    }

    /// d_o of species `s` of this scene.
    pub(crate) fn observation_dim(&self, s: usize) -> usize {
        self.layout(s).dim()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_papers_layout_is_own_state_then_six_of_each_species() {
        let scene = Scene::preset("paper").unwrap();
        let l = scene.layout(1);
        assert_eq!(
            (l.block(0), l.block(1), l.neighbours(), l.heading(), l.energy(), l.dim()),
            (6..30, 30..54, 6..54, 4..6, None, 54)
        );
    }

    #[test]
    fn the_authors_layout_is_position_velocity_blocks_energy_heading() {
        // pps.py `_get_obs`, Polar: (2 + 2·(2 + 5))·2 + 1 + 2 = 35.
        let mut scene = Scene::preset("gym-pps").unwrap();
        scene.observation_layout = ObservationLayout::Authors;
        for s in &mut scene.species {
            s.topological_limit = 5;
            s.topological_limit_of = vec![("predator".into(), 2)];
        }
        for s in 0..2 {
            let l = scene.layout(s);
            assert_eq!(
                (l.block(0), l.block(1), l.energy(), l.heading(), l.dim()),
                (4..12, 12..32, Some(32), 33..35, 35)
            );
        }
    }
}
