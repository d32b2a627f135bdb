//! The observation vector (Appendix B; parameters.md "Observation"): own state, then up to 6 predators,
//! then up to 6 prey, nearest first, within the perception radius, minimum image, never itself, zeros
//! where nobody is seen.

mod common;
use bevy::math::DVec2;
use coevo::perception::Batches;
use coevo::scene::{Boundary, Perception, Policy};
use coevo::space::min_image;
use coevo::Simulation;
use common::{place, scene};
use std::f64::consts::FRAC_PI_2;

/// 2 predators (ids 0, 1) and 9 prey (ids 2..=10). Prey 2 is the observer at (0.95, 0) facing +x; prey
/// 2+k sits 0.1·k m away in direction 0.7·k rad (k = 1..=8), facing +y, several across the seam.
/// Predator 0 is 0.3 m away, predator 1 0.9 m away.
fn configured(perception: Perception) -> (Simulation, Vec<DVec2>) {
    let mut s = scene(2, 9, Policy::Still, Boundary::Periodic);
    s.species[1].perception = perception;
    let mut sim = Simulation::new(s);
    let me = DVec2::new(0.95, 0.0);
    let wrap = |p: DVec2| DVec2::new(min_image(p.x, 2.0), min_image(p.y, 2.0));
    place(&mut sim, 2, me, DVec2::new(0.1, -0.2), 0.0);
    let mut offsets = vec![];
    for k in 1..=8u32 {
        let d = 0.1 * k as f64 * DVec2::from_angle(0.7 * k as f64);
        offsets.push(d);
        place(&mut sim, 2 + k, wrap(me + d), DVec2::ZERO, FRAC_PI_2);
    }
    place(&mut sim, 0, wrap(me + DVec2::new(0.0, 0.3)), DVec2::ZERO, FRAC_PI_2);
    place(&mut sim, 1, wrap(me + DVec2::new(-0.9, 0.0)), DVec2::ZERO, FRAC_PI_2);
    (sim, offsets)
}

fn observation_of_prey_observer(sim: &Simulation) -> Vec<f32> {
    // Prey rows are in id order; the observer (id 2) is the first prey.
    sim.world().resource::<Batches>().species[1].observation(0).to_vec()
}

fn close(a: &[f32], b: &[f64]) -> bool {
    a.len() == b.len() && a.iter().zip(b).all(|(x, y)| (*x as f64 - y).abs() < 1e-5)
}

#[test]
fn layout_ordering_limit_and_minimum_image() {
    let (sim, offsets) = configured(Perception::Full);
    let obs = observation_of_prey_observer(&sim);
    assert_eq!(obs.len(), 6 + 4 * (6 + 6), "d_o = 54 for the paper's species");
    assert!(close(&obs[..6], &[0.95, 0.0, 0.1, -0.2, 1.0, 0.0]), "own state {:?}", &obs[..6]);
    // Predators, nearest first: 0.3 m then 0.9 m; heading difference (0,1) − (1,0).
    assert!(close(&obs[6..10], &[0.0, 0.3, -1.0, 1.0]), "{:?}", &obs[6..10]);
    assert!(close(&obs[10..14], &[-0.9, 0.0, -1.0, 1.0]), "{:?}", &obs[10..14]);
    assert!(obs[14..30].iter().all(|&x| x == 0.0), "four empty predator slots are zeros");
    // Prey: the 6 nearest of 8 (topological limit), nearest first, as minimum-image displacements.
    for (n, d) in offsets.iter().take(6).enumerate() {
        let at = 30 + 4 * n;
        assert!(close(&obs[at..at + 4], &[d.x, d.y, -1.0, 1.0]), "prey slot {n}: {:?} vs {d}", &obs[at..at + 4]);
    }
}

#[test]
fn perception_radius_masks_the_far_ones_and_never_the_self() {
    let (sim, offsets) = configured(Perception::Radius(0.45));
    let obs = observation_of_prey_observer(&sim);
    assert!(close(&obs[6..10], &[0.0, 0.3, -1.0, 1.0]));
    assert!(obs[10..30].iter().all(|&x| x == 0.0), "the predator 0.9 m away is beyond R = 0.45");
    for (n, d) in offsets.iter().take(4).enumerate() {
        let at = 30 + 4 * n;
        assert!(close(&obs[at..at + 4], &[d.x, d.y, -1.0, 1.0]));
    }
    assert!(obs[46..54].iter().all(|&x| x == 0.0), "prey at 0.5 m and beyond are masked");
    // Fraction of D resolves against D = √2: 0.45/√2 of D is the same radius.
    let (sim2, _) = configured(Perception::FractionOfD(0.45 / 2f64.sqrt()));
    assert_eq!(observation_of_prey_observer(&sim2), obs);
}

#[test]
fn predators_see_the_same_layout() {
    let (sim, _) = configured(Perception::Full);
    let batches = sim.world().resource::<Batches>();
    assert_eq!(batches.species[0].n, 2);
    assert_eq!(batches.species[0].obs_dim, 54);
    let pred0 = batches.species[0].observation(0);
    // Predator 0's first predator slot is predator 1 (it never sees itself): 0.9 m west, 0.3 m south.
    assert!(close(&pred0[6..10], &[-0.9, -0.3, 0.0, 0.0]), "{:?}", &pred0[6..10]);
    assert!(pred0[10..30].iter().all(|&x| x == 0.0));
}

#[test]
fn topological_limit_sets_the_width() {
    let mut s = scene(3, 10, Policy::Still, Boundary::Periodic);
    s.species[1].topological_limit = 2;
    let sim = Simulation::new(s);
    let b = sim.world().resource::<Batches>();
    assert_eq!(b.species[1].obs_dim, 6 + 4 * (2 + 2));
    assert_eq!(b.species[0].obs_dim, 54);
    assert_eq!(b.species[1].observations.len(), 10 * 22, "one contiguous [n × d_o] batch");
}
