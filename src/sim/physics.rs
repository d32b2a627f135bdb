//! Agent dynamics, Eq. (1) of the paper, discretised as in Appendix B:
//!
//! ```text
//!   θ(t+1) = θ(t) + a_R·Δt                      wrapped to (−π, π]
//!   h      = (cos θ(t+1), sin θ(t+1))
//!   v(t+1) = v(t) + (a_F·h + f_d + f_a + f_b)·Δt / m_i,   f_d = −drag·v(t)
//!   v(t+1) ← clip(v(t+1), max speed)           norm (paper) or per component (authors' code)
//!   x(t+1) = x(t) + v(t+1)·Δt                   semi-implicit Euler, then periodic wrap
//! ```
//!
//! f_a (agent contacts) comes from [`crate::sim::perception`], computed on the positions at t when state t
//! was perceived; f_b (walls) is computed here from x(t), v(t). Appendix B writes v(t) in the position
//! update; the authors' code uses the updated velocity, which is also the stable choice with stiff
//! springs (parameters.md, "Integration order").

use super::schedule::{ActiveScene, SimSet};
use crate::scene::SpeedClip;
use crate::sim::components::*;
use crate::sim::space::Arena;
use crate::sim::species::SpeciesRegistry;
use bevy::math::DVec2;
use bevy::prelude::*;
use std::f64::consts::PI;

/// The stages of one physics step, in order.
#[derive(SystemSet, Clone, Debug, PartialEq, Eq, Hash)]
pub(crate) enum PhysicsSet {
    /// Forces, heading, velocity and position updates.
    Integrate,
    /// Periodic wrap.
    Boundary,
}

pub(crate) struct PhysicsPlugin;

/// The first agent whose state stopped being physical during a step (a non-finite velocity or position,
/// or a body that left a walled arena). Validated scenes keep the integrator stable
/// ([`crate::scene::Scene::validate`]); this guard catches whatever still goes wrong, so a run stops with one
/// line naming the agent instead of writing NaN as results. Checked by [`crate::sim::Simulation::check`].
#[derive(Resource, Clone, Debug, Default, PartialEq)]
pub(crate) struct StateFault(pub Option<Fault>);

#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Fault {
    /// Episode index and the step (1-based) during which it happened.
    pub(crate) episode: usize,
    pub(crate) step: usize,
    pub(crate) agent: u32,
    pub(crate) species: usize,
    /// What went wrong, e.g. "velocity is not finite".
    pub(crate) what: String,
}

impl StateFault {
    /// Keeps the first fault of a run: agent `agent` of species `species` went wrong during the step that
    /// follows `episode`'s current one.
    fn report(
        &mut self,
        episode: &crate::sim::clock::Episode,
        agent: u32,
        species: usize,
        what: impl FnOnce() -> String,
    ) {
        if self.0.is_none() {
            self.0 = Some(Fault { episode: episode.index, step: episode.step + 1, agent, species, what: what() });
        }
    }
}

impl Plugin for PhysicsPlugin {
    fn build(&self, app: &mut App) {
        app.init_resource::<StateFault>();
        app.configure_sets(FixedUpdate, (PhysicsSet::Integrate, PhysicsSet::Boundary).chain().in_set(SimSet::Physics));
        app.add_systems(
            FixedUpdate,
            (integrate.in_set(PhysicsSet::Integrate), apply_boundary.in_set(PhysicsSet::Boundary)),
        );
    }
}

/// Wraps an angle to (−π, π].
pub fn wrap_angle(theta: f64) -> f64 {
    let t = (theta + PI).rem_euclid(2.0 * PI) - PI;
    if t <= -PI {
        t + 2.0 * PI
    } else {
        t
    }
}

/// Enforces the speed limit.
pub fn clip_speed(v: DVec2, max_speed: f64, how: SpeedClip) -> DVec2 {
    match how {
        SpeedClip::Norm => {
            let speed = v.length();
            if speed > max_speed {
                v * (max_speed / speed)
            } else {
                v
            }
        }
        SpeedClip::PerComponent => v.clamp(DVec2::splat(-max_speed), DVec2::splat(max_speed)),
    }
}

/// Energy below which an exhausted agent stops (the authors' energy budget).
const EXHAUSTED: f64 = 0.5;
/// Full energy, and the starting value.
pub(crate) const FULL_ENERGY: f64 = 1000.0;

type IntegrateQuery<'w, 's> = Query<
    'w,
    's,
    (
        &'static AgentId,
        &'static mut Position,
        &'static mut Velocity,
        &'static mut Heading,
        &'static Body,
        &'static Action,
        &'static ContactForce,
        &'static SpeciesId,
        Option<&'static mut Energy>,
    ),
>;

fn integrate(
    scene: Res<ActiveScene>,
    arena: Res<Arena>,
    registry: Res<SpeciesRegistry>,
    episode: Res<crate::sim::clock::Episode>,
    mut fault: ResMut<StateFault>,
    mut agents: IntegrateQuery,
) {
    let w = &scene.0.world;
    let dt = w.dt;
    for (id, mut x, mut v, mut theta, body, action, contact, species, energy) in &mut agents {
        let (wall_force, _) = arena.wall_contact(x.0, v.0, body.radius, w.wall_stiffness, w.wall_damping);
        let drag = -w.drag * v.0;
        theta.0 = wrap_angle(theta.0 + action.turn_rate * dt);
        let h = theta.unit();
        let force = action.thrust * h + drag + contact.0 + wall_force;
        let mut new_v = clip_speed(v.0 + force * dt / body.mass, registry.defs[species.0].max_speed, w.speed_clip);
        if let Some(mut energy) = energy {
            // The authors' budget: an exhausted agent stops; moving costs |v| per step, resting restores.
            if energy.0 < EXHAUSTED {
                new_v = DVec2::ZERO;
            }
            let speed = new_v.length();
            energy.0 = (energy.0 - speed + if speed < 0.01 { 0.1 } else { 0.0 }).min(FULL_ENERGY);
        }
        v.0 = new_v;
        x.0 += new_v * dt;
        if !(new_v.is_finite() && x.0.is_finite() && theta.0.is_finite()) {
            let quantity = if !new_v.is_finite() {
                "velocity"
            } else if !x.0.is_finite() {
                "position"
            } else {
                "heading"
            };
            fault.report(&episode, id.0, species.0, || format!("{quantity} is not finite"));
        }
    }
}

fn apply_boundary(
    arena: Res<Arena>,
    scene: Res<ActiveScene>,
    registry: Res<SpeciesRegistry>,
    episode: Res<crate::sim::clock::Episode>,
    mut fault: ResMut<StateFault>,
    mut agents: Query<(&AgentId, &SpeciesId, &Body, &mut Position)>,
) {
    for (id, species, body, mut x) in &mut agents {
        x.0 = arena.wrap(x.0);
        // With walls, a body can sink into a wall by at most one step's travel before the spring turns it
        // back; a centre beyond that has escaped the arena.
        let reach = arena.half() + body.radius + registry.defs[species.0].max_speed * scene.0.world.dt * 2.0;
        if x.0.abs().max_element() > reach {
            fault
                .report(&episode, id.0, species.0, || format!("left the arena (centre at {:.3}, {:.3})", x.0.x, x.0.y));
        }
    }
}
