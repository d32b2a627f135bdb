//! Decide and Act: a policy per species fills its batch of normalized actions in [−1, 1]², then Act
//! rescales every agent's row to physical units (Appendix B): a_F ∈ [0, max thrust], a_R ∈ [−max, max].
//!
//! Rule-based policies live here and read the same observation batch a network would, so they perceive
//! exactly what a learned agent perceives. `Learned` and `Frozen` species are decided by the learning
//! plugin, `Plugin(name)` species by whatever plugin registered that name.

use super::schedule::{ActiveScene, SimSet};
use crate::scene::{ObservationFrame, Policy};
use crate::sim::components::*;
use crate::sim::episode::SimRng;
use crate::sim::perception::{neighbour_slot, Batches};
use crate::sim::species::{SpeciesRegistry, ACTION_DIM};
use bevy::prelude::*;
use rand::Rng;

pub(crate) struct PolicyPlugin;

/// The names of the `Plugin(name)` policies that some plugin of this app decides. A plugin that writes a
/// species' actions registers its name ([`PolicyPlugins::register`]); a scene that names a policy nobody
/// registered is refused at start-up ([`PolicyPlugins::check`]) instead of moving at half thrust forever.
#[derive(Resource, Clone, Debug, Default)]
pub struct PolicyPlugins(pub std::collections::BTreeSet<String>);

impl PolicyPlugins {
    /// Declares that a system of this app decides the species whose policy is `Plugin(name)`.
    pub fn register(app: &mut App, name: &str) {
        app.world_mut().get_resource_or_insert_with(PolicyPlugins::default).0.insert(name.to_string());
    }

    /// Err naming the first species whose `Plugin(name)` policy nothing registered.
    pub(crate) fn check(&self, scene: &crate::scene::Scene) -> crate::error::Result<()> {
        for def in &scene.species {
            if let Policy::Plugin(name) = &def.policy {
                if !self.0.contains(name) {
                    let known = if self.0.is_empty() {
                        "none".to_string()
                    } else {
                        self.0.iter().cloned().collect::<Vec<_>>().join(", ")
                    };
                    return Err(format!(
                        "species[{}].policy: no plugin decides Plugin({name:?}) in this program (registered: {known})",
                        def.name
                    )
                    .into());
                }
            }
        }
        Ok(())
    }
}

impl Plugin for PolicyPlugin {
    fn build(&self, app: &mut App) {
        app.init_resource::<PolicyPlugins>();
        app.add_systems(FixedUpdate, (decide_rule_based.in_set(SimSet::Decide), act.in_set(SimSet::Act)));
    }
}

/// Maps a normalized action to physical units: thrust from [−1, 1] to [0, max], turn rate to [−max, max].
pub fn rescale(action: [f32; ACTION_DIM], max_thrust: f64, max_turn_rate: f64) -> Action {
    let [u_f, u_r] = action.map(|u| (u as f64).clamp(-1.0, 1.0));
    Action { thrust: (u_f + 1.0) / 2.0 * max_thrust, turn_rate: u_r * max_turn_rate }
}

/// Normalized turn command that rotates heading `h` toward direction `d` as fast as allowed, without
/// overshooting within one step.
fn turn_toward(h: [f32; 2], d: [f32; 2], max_turn_rate: f64, dt: f64) -> f32 {
    let cross = (h[0] * d[1] - h[1] * d[0]) as f64;
    let dot = (h[0] * d[0] + h[1] * d[1]) as f64;
    let error = cross.atan2(dot);
    if max_turn_rate == 0.0 {
        0.0
    } else {
        (error / dt / max_turn_rate).clamp(-1.0, 1.0) as f32
    }
}

/// The nearest observed agent among `species`, as its displacement [Δx, Δy].
fn nearest_observed(
    obs: &[f32],
    registry: &SpeciesRegistry,
    observer: usize,
    species: impl Iterator<Item = usize>,
) -> Option<[f32; 2]> {
    species
        .filter_map(|t| neighbour_slot(obs, registry, observer, t, 0))
        .map(|slot| [slot[0], slot[1]])
        .min_by(|a, b| (a[0].hypot(a[1])).total_cmp(&b[0].hypot(b[1])))
}

/// The push off the walls within [`FLEE_WALL_MARGIN`] of the observer, in its observation's frame: per
/// wall, the inward normal weighted 2·(1 − distance/margin), so a wall at contact outweighs the unit
/// direction away from a predator. None on the torus and away from walls. The world frame reads the
/// observer's own position, the body frame its nearest wall point.
fn off_walls(obs: &[f32], registry: &SpeciesRegistry, s: usize, scene: &crate::scene::Scene) -> Option<[f32; 2]> {
    use crate::scene::{Boundary, FLEE_WALL_MARGIN};
    if scene.world.boundary != Boundary::Walls {
        return None;
    }
    let weight = |distance: f64| 2.0 * (1.0 - distance / FLEE_WALL_MARGIN);
    let mut push = [0.0f64; 2];
    match scene.observation_frame {
        ObservationFrame::World => {
            let half = scene.world.arena_edge / 2.0 - registry.defs[s].radius;
            for (axis, x) in [obs[0] as f64, obs[1] as f64].into_iter().enumerate() {
                for side in [-1.0, 1.0] {
                    let distance = (half - side * x).max(0.0);
                    if distance < FLEE_WALL_MARGIN {
                        push[axis] -= side * weight(distance);
                    }
                }
            }
        }
        ObservationFrame::Body => {
            // Own state [v ahead, v left, turn, wall ahead, wall left, 0]: the nearest wall point.
            let wall = [obs[3] as f64, obs[4] as f64];
            let distance = (wall[0].hypot(wall[1]) - registry.defs[s].radius).max(0.0);
            if distance < FLEE_WALL_MARGIN && wall != [0.0, 0.0] {
                let n = wall[0].hypot(wall[1]);
                push = [-wall[0] / n * weight(distance), -wall[1] / n * weight(distance)];
            }
        }
    }
    (push != [0.0, 0.0]).then_some(push.map(|c| c as f32))
}

fn decide_rule_based(
    registry: Res<SpeciesRegistry>,
    scene: Res<ActiveScene>,
    mut batches: ResMut<Batches>,
    mut rng: ResMut<SimRng>,
) {
    for s in 0..registry.len() {
        let batch = &mut batches.species[s];
        for row in 0..batch.n {
            let Some(action) = rule_action(batch.observation(row), &registry, s, &scene.0, &mut rng.0) else { break };
            batch.actions[row * ACTION_DIM..(row + 1) * ACTION_DIM].copy_from_slice(&action);
        }
    }
}

/// The normalized action a rule-based species `s` takes on one observation `obs`; None for a species its
/// rule does not decide (`Learned`, `Frozen`, `Plugin`). A function of the observation alone (and of `rng`
/// for `Random`), so it can also be read off synthetic observations (`analysis::response`).
pub(crate) fn rule_action(
    obs: &[f32],
    registry: &SpeciesRegistry,
    s: usize,
    scene: &crate::scene::Scene,
    rng: &mut impl Rng,
) -> Option<[f32; ACTION_DIM]> {
    let (dt, max_turn) = (scene.world.dt, registry.defs[s].max_turn_rate);
    // In the body frame the observer always faces along its first axis.
    let heading = match scene.observation_frame {
        ObservationFrame::World => {
            let h = registry.layouts[s].heading();
            [obs[h.start], obs[h.start + 1]]
        }
        ObservationFrame::Body => [1.0, 0.0],
    };
    Some(match registry.policy(s) {
        Policy::Random => [rng.gen_range(-1.0..=1.0), rng.gen_range(-1.0..=1.0)],
        Policy::Still => [-1.0, 0.0],
        // The paper's rule (Section "Emergent Swirling Behavior"): turn to the nearest prey, full thrust.
        Policy::ChaseNearest => match nearest_observed(obs, registry, s, registry.prey_of(s)) {
            Some(d) => [1.0, turn_toward(heading, d, max_turn, dt)],
            None => [1.0, 0.0],
        },
        Policy::FleeNearest => match nearest_observed(obs, registry, s, registry.predators_of(s)) {
            Some(d) => [1.0, turn_toward(heading, [-d[0], -d[1]], max_turn, dt)],
            None => [1.0, 0.0],
        },
        Policy::FleeInside => {
            let away = nearest_observed(obs, registry, s, registry.predators_of(s)).map(|d| [-d[0], -d[1]]);
            match (away, off_walls(obs, registry, s, scene)) {
                (Some(away), None) => [1.0, turn_toward(heading, away, max_turn, dt)],
                (away, Some(push)) => {
                    let away = away.map_or([0.0, 0.0], |a| {
                        let n = a[0].hypot(a[1]).max(f32::MIN_POSITIVE);
                        [a[0] / n, a[1] / n]
                    });
                    let to = [away[0] + push[0], away[1] + push[1]];
                    // Facing away from where it should go, it brakes to turn: at full speed the
                    // turning circle (v / max turn rate: 1 m in the paper) is as wide as the box.
                    let facing = heading[0] * to[0] + heading[1] * to[1];
                    [if facing < 0.0 { -1.0 } else { 1.0 }, turn_toward(heading, to, max_turn, dt)]
                }
                (None, None) => [1.0, 0.0],
            }
        }
        Policy::Zonal(rule) => {
            use super::rules::{observed, observed_of, zonal_action, Own, ZonalFeatures};
            let frame = scene.observation_frame;
            let kin = observed(obs, registry, s, s, frame);
            let predators = observed_of(obs, registry, s, registry.predators_of(s), frame);
            zonal_action(rule, &ZonalFeatures::of(rule, Own::of(obs, registry, s, frame), &kin, &predators))
        }
        Policy::Binned(rule) => {
            use super::rules::{binned_action, observed, observed_of, Own};
            let frame = scene.observation_frame;
            let (own, kin) = (Own::of(obs, registry, s, frame), observed(obs, registry, s, s, frame));
            binned_action(rule, own, &kin, &observed_of(obs, registry, s, registry.predators_of(s), frame))
        }
        Policy::Pursuit(rule) => {
            use super::rules::{observed_of, pursuit_action, Own, PursuitFeatures};
            let frame = scene.observation_frame;
            let prey = observed_of(obs, registry, s, registry.prey_of(s), frame);
            pursuit_action(rule, &PursuitFeatures::of(Own::of(obs, registry, s, frame), &prey))
        }
        Policy::Vicsek(rule) => {
            let kin = super::rules::observed(obs, registry, s, s, scene.observation_frame);
            super::classic::steer(super::classic::vicsek_direction(rule, &kin, rng), max_turn, dt)
        }
        Policy::Couzin(rule) => {
            let kin = super::rules::observed(obs, registry, s, s, scene.observation_frame);
            super::classic::steer(super::classic::couzin_direction(rule, &kin, rng), max_turn, dt)
        }
        Policy::Learned | Policy::Frozen(_) | Policy::Plugin(_) => return None,
    })
}

fn act(registry: Res<SpeciesRegistry>, batches: Res<Batches>, mut agents: Query<(&Slot, &SpeciesId, &mut Action)>) {
    for (slot, species, mut action) in &mut agents {
        let def = &registry.defs[species.0];
        *action = rescale(batches.species[species.0].action(slot.row as usize), def.max_thrust, def.max_turn_rate);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rescale_maps_the_unit_box_to_physical_ranges() {
        let a = rescale([-1.0, -1.0], 1.0, 0.5);
        assert_eq!((a.thrust, a.turn_rate), (0.0, -0.5));
        let a = rescale([1.0, 1.0], 2.0, 5.0);
        assert_eq!((a.thrust, a.turn_rate), (2.0, 5.0));
        let a = rescale([0.0, 3.0], 1.0, 0.5);
        assert_eq!((a.thrust, a.turn_rate), (0.5, 0.5), "out-of-range actions are clamped");
    }

    #[test]
    fn turn_toward_saturates_and_does_not_overshoot() {
        // Target 90° to the left: turn left at the maximum rate.
        assert_eq!(turn_toward([1.0, 0.0], [0.0, 1.0], 0.5, 0.1), 1.0);
        assert_eq!(turn_toward([1.0, 0.0], [0.0, -1.0], 0.5, 0.1), -1.0);
        // 0.01 rad off with a 0.05 rad/step budget: exactly the error, not the maximum.
        let u = turn_toward([1.0, 0.0], [0.01f32.cos(), 0.01f32.sin()], 0.5, 0.1);
        assert!((u - 0.2).abs() < 1e-4, "{u}");
    }
}
