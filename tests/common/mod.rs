//! Helpers shared by the integration tests: scenes with known populations and agents placed by hand.
#![allow(dead_code)]

use bevy::math::DVec2;
use coevo::scene::{Boundary, Policy, Scene};
use coevo::sim::components::*;
use coevo::sim::perception::Perceive;
use coevo::sim::Simulation;

/// The `paper` preset with the given counts and policies, on the given boundary.
pub fn scene(predators: usize, prey: usize, policy: Policy, boundary: Boundary) -> Scene {
    let mut s = Scene::preset("paper").unwrap();
    s.world.boundary = boundary;
    s.species[0].count = predators;
    s.species[1].count = prey;
    for sp in &mut s.species {
        sp.policy = policy.clone();
    }
    s
}

/// Puts agent `id` at `x` with velocity `v` and heading `theta`, then re-perceives the state so contact
/// forces and observations match.
pub fn place(sim: &mut Simulation, id: u32, x: DVec2, v: DVec2, theta: f64) {
    let world = sim.world_mut();
    let mut q = world.query::<(&AgentId, &mut Position, &mut Velocity, &mut Heading)>();
    for (aid, mut p, mut vel, mut h) in q.iter_mut(world) {
        if aid.0 == id {
            p.0 = x;
            vel.0 = v;
            h.0 = theta;
        }
    }
    world.run_schedule(Perceive);
}

/// Every agent's position, by id.
pub fn positions(sim: &mut Simulation) -> Vec<(u32, DVec2)> {
    let world = sim.world_mut();
    let mut q = world.query::<(&AgentId, &Position)>();
    let mut at: Vec<(u32, DVec2)> = q.iter(world).map(|(id, x)| (id.0, x.0)).collect();
    at.sort_by_key(|a| a.0);
    at
}

/// A component of agent `id`.
pub fn get<C: bevy::prelude::Component + Copy>(sim: &mut Simulation, id: u32) -> C {
    let world = sim.world_mut();
    let mut q = world.query::<(&AgentId, &C)>();
    *q.iter(world).find(|(a, _)| a.0 == id).expect("agent exists").1
}

/// A simulation whose `Plugin("test")` species are decided by the test itself, writing the action batch.
pub fn manual(scene: Scene) -> Simulation {
    Simulation::with_plugins(scene, |app| coevo::sim::policy::PolicyPlugins::register(app, "test"))
}

/// Records the run's snapshots as they are now in its checkpoint's manifest, as if training had written
/// them (what a test that edits snapshots on purpose needs).
pub fn reseal_snapshots(run: &std::path::Path) {
    use coevo::store::manifest::{Digest, Manifest, MANIFEST};
    let dir = run.join("checkpoint");
    let mut manifest = Manifest::read(&dir).unwrap().unwrap();
    for (name, digest) in manifest.snapshots.iter_mut() {
        *digest = Digest::of_file(&run.join("snapshots").join(name)).unwrap();
    }
    std::fs::write(dir.join(MANIFEST), manifest.to_ron()).unwrap();
}
