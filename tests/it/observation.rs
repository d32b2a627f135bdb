//! The observation vector (Appendix B; parameters.md "Observation"): own state, then up to 6 predators,
//! then up to 6 prey, nearest first, within the perception radius, minimum image, never itself, zeros
//! where nobody is seen.

use crate::common::{place, positions, scene};
use bevy::math::DVec2;
use coevo::scene::{Boundary, Perception, Policy};
use coevo::sim::perception::Batches;
use coevo::sim::space::min_image;
use coevo::sim::Simulation;
use std::f64::consts::{FRAC_PI_2, FRAC_PI_6};

/// 2 predators (ids 0, 1) and 9 prey (ids 2..=10). Prey 2 is the observer at (0.95, 0) facing +x; prey
/// 2+k sits 0.1·k m away in direction 0.7·k rad (k = 1..=8), facing +y, several across the seam.
/// Predator 0 is 0.3 m away, predator 1 0.9 m away.
fn configured(perception: Perception) -> (Simulation, Vec<DVec2>) {
    configured_with(|s| s.species[1].perception = perception)
}

/// [`configured`] with the scene changed by `change` first.
fn configured_with(change: impl FnOnce(&mut coevo::scene::Scene)) -> (Simulation, Vec<DVec2>) {
    let mut s = scene(2, 9, Policy::Still, Boundary::Periodic);
    change(&mut s);
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
fn blind_to_zeroes_exactly_the_named_blocks_in_both_frames_and_keeps_d_o() {
    for frame in [coevo::scene::ObservationFrame::World, coevo::scene::ObservationFrame::Body] {
        let (sim, _) = configured_with(|s| s.observation_frame = frame);
        let seeing = observation_of_prey_observer(&sim);
        let predators = sim.world().resource::<Batches>().species[0].observations.clone();
        for (blind_to, block) in [("prey", 30..54), ("predator", 6..30)] {
            let (sim, _) = configured_with(|s| {
                s.observation_frame = frame;
                s.species[1].blind_to = vec![blind_to.into()];
            });
            let obs = observation_of_prey_observer(&sim);
            let mut by_hand = seeing.clone();
            by_hand[block.clone()].fill(0.0);
            assert!(seeing[block].iter().any(|&x| x != 0.0), "{frame:?}: the block had something to hide");
            assert_eq!(obs, by_hand, "{frame:?}, blind_to {blind_to}: the block zeroed, nothing else changed");
            assert_eq!(obs.len(), 54, "d_o unchanged");
            let batches = sim.world().resource::<Batches>();
            assert_eq!(batches.species[0].observations, predators, "the predators are untouched");
        }
    }
}

#[test]
fn perception_of_sets_the_radius_per_observed_species() {
    let (full, offsets) = configured(Perception::Full);
    let full = observation_of_prey_observer(&full);
    // Predators within 0.45 m only (predator 0 at 0.3 m is seen, predator 1 at 0.9 m is not); prey as with
    // full perception.
    let (sim, _) =
        configured_with(|s| s.species[1].perception_of = vec![("predator".into(), Perception::Radius(0.45))]);
    let obs = observation_of_prey_observer(&sim);
    assert!(close(&obs[6..10], &[0.0, 0.3, -1.0, 1.0]), "{:?}", &obs[6..10]);
    assert!(obs[10..30].iter().all(|&x| x == 0.0), "the predator 0.9 m away is beyond its R = 0.45");
    assert_eq!(obs[30..54], full[30..54], "prey are seen within the species' own R = D");
    // The other way round: R = 0.45 m for everything but prey, which are seen within D.
    let (sim, _) = configured_with(|s| {
        s.species[1].perception = Perception::Radius(0.45);
        s.species[1].perception_of = vec![("prey".into(), Perception::Full)];
    });
    let obs = observation_of_prey_observer(&sim);
    assert!(obs[10..30].iter().all(|&x| x == 0.0));
    for (n, d) in offsets.iter().take(6).enumerate() {
        let at = 30 + 4 * n;
        assert!(close(&obs[at..at + 4], &[d.x, d.y, -1.0, 1.0]), "prey slot {n}");
    }
}

#[test]
fn a_field_of_view_hides_the_blind_sector_behind_and_nothing_else() {
    // The observer faces +x: predator 1 is straight behind, predator 0 90° to its left; prey k sit at
    // 0.7·k rad, so prey 4 (160°) and 5 (−159°) lie in the 60° blind sector of a 300° field of view.
    let (all, _) = configured(Perception::Full);
    let (blind, offsets) = configured_with(|s| s.species[1].field_of_view = 300.0);
    let (a, b) = (observation_of_prey_observer(&all), observation_of_prey_observer(&blind));
    assert!(close(&a[10..14], &[-0.9, 0.0, -1.0, 1.0]), "360°: the predator behind is seen");
    assert!(close(&b[6..10], &[0.0, 0.3, -1.0, 1.0]), "{:?}", &b[6..10]);
    assert!(b[10..30].iter().all(|&x| x == 0.0), "300°: the predator behind is absent, its slot zero");
    // The six prey in view fill the six slots, nearest first: the two behind are skipped, not zeroed.
    for (n, k) in [1, 2, 3, 6, 7, 8].into_iter().enumerate() {
        let d = offsets[k - 1];
        let at = 30 + 4 * n;
        assert!(close(&b[at..at + 2], &[d.x, d.y]), "slot {n}: prey {k} {:?}", &b[at..at + 4]);
    }
    // Per observed species: predators all around, prey within 300°.
    let (mixed, _) = configured_with(|s| {
        s.species[1].field_of_view = 300.0;
        s.species[1].field_of_view_of = vec![("predator".into(), 360.0)];
    });
    let m = observation_of_prey_observer(&mixed);
    assert_eq!(&m[6..30], &a[6..30]);
    assert_eq!(&m[30..], &b[30..]);
    // The edges of the sector, on each side: 150° from the heading is in view, a thousandth of a radian
    // further is not.
    let edge = 150f64.to_radians();
    for (side, angle, seen) in
        [(1.0, edge - 1e-9, true), (-1.0, edge - 1e-9, true), (1.0, edge + 1e-3, false), (-1.0, edge + 1e-3, false)]
    {
        let (mut sim, _) = configured_with(|s| s.species[1].field_of_view = 300.0);
        let me = DVec2::new(0.95, 0.0);
        let at = me + 0.5 * DVec2::from_angle(side * angle);
        place(&mut sim, 1, DVec2::new(min_image(at.x, 2.0), min_image(at.y, 2.0)), DVec2::ZERO, FRAC_PI_2);
        let obs = observation_of_prey_observer(&sim);
        let behind = obs[6..14]
            .chunks(4)
            .any(|c| (c[0] as f64 - (at - me).x).abs() < 1e-5 && (c[1] as f64 - (at - me).y).abs() < 1e-5);
        assert_eq!(behind, seen, "{side:+} · {angle} rad");
    }
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

#[test]
fn topological_limit_of_narrows_one_block_and_nothing_else() {
    let (sim, offsets) = configured_with(|s| s.species[1].topological_limit_of = vec![("predator".into(), 1)]);
    let obs = observation_of_prey_observer(&sim);
    let (paper, _) = configured(Perception::Full);
    let paper = observation_of_prey_observer(&paper);
    assert_eq!(obs.len(), 6 + 4 * (1 + 6));
    assert_eq!(obs[..6], paper[..6], "own state");
    assert!(close(&obs[6..10], &[0.0, 0.3, -1.0, 1.0]), "the nearest predator only: {:?}", &obs[6..10]);
    assert_eq!(obs[10..], paper[30..], "the same six prey, one predator slot earlier");
    assert_eq!(offsets.len(), 8);
    let b = sim.world().resource::<Batches>();
    assert_eq!(b.species[0].obs_dim, 54, "the predators' limits are their own");
}

/// The authors' observation (WindyLab/Gym-PPS `gym/envs/pps/pps.py` `_get_obs`, Polar dynamics, with
/// `custom_param.json`'s 2 predator and 5 prey slots), written out by hand for the configured state:
/// `[x, y, v_x, v_y]`, the two predators, the five nearest prey, `2/1000·E − 1`, `[h_x, h_y]`.
#[test]
fn the_authors_layout_is_what_pps_get_obs_writes() {
    use coevo::scene::ObservationLayout;
    use coevo::sim::components::{AgentId, Energy};
    let (mut sim, offsets) = configured_with(|s| {
        s.observation_layout = ObservationLayout::Authors;
        s.world.energy_budget = true;
        for def in &mut s.species {
            def.topological_limit = 5;
            def.topological_limit_of = vec![("predator".into(), 2)];
        }
    });
    let world = sim.world_mut();
    let mut q = world.query::<(&AgentId, &mut Energy)>();
    q.iter_mut(world).find(|(id, _)| id.0 == 2).expect("the observer has a budget").1 .0 = 250.0;
    world.run_schedule(coevo::sim::perception::Perceive);
    let obs = observation_of_prey_observer(&sim);
    let mut want = vec![0.95, 0.0, 0.1, -0.2, 0.0, 0.3, -1.0, 1.0, -0.9, 0.0, -1.0, 1.0];
    for d in offsets.iter().take(5) {
        want.extend([d.x, d.y, -1.0, 1.0]);
    }
    want.extend([2.0 / 1000.0 * 250.0 - 1.0, 1.0, 0.0]);
    assert_eq!(want.len(), 35, "d_o = (2 + 2·(2 + 5))·2 + 1 + 2");
    assert!(close(&obs, &want), "{obs:?}\n{want:?}");
    // A predator: itself never, the other predator first, then the prey; a full budget reads +1.
    let pred0 = sim.world().resource::<Batches>().species[0].observation(0).to_vec();
    assert_eq!(pred0.len(), 35);
    assert!(close(&pred0[4..8], &[-0.9, -0.3, 0.0, 0.0]) && pred0[8..12] == [0.0; 4], "{:?}", &pred0[4..12]);
    assert!(close(&pred0[32..], &[1.0, 0.0, 1.0]), "energy +1, heading (0, 1): {:?}", &pred0[32..]);
}

/// The same configuration observed in the body frame, its world turned by 90° about the origin (a symmetry
/// of the square torus): every body-frame observation must be the same, and so must a network's action.
#[test]
fn body_frame_observations_are_hand_rotated_and_invariant_under_turning_the_world() {
    use coevo::scene::ObservationFrame;
    let build = |turn: bool| {
        let mut s = scene(2, 4, Policy::Still, Boundary::Periodic);
        s.observation_frame = ObservationFrame::Body;
        let mut sim = Simulation::new(s);
        // Observer prey 2 at (0.5, 0.2) heading 30° (π/6), moving; others around it, one across the seam.
        let agents = [
            (0u32, DVec2::new(0.6, 0.5), 2.0),
            (1, DVec2::new(-0.9, 0.2), -1.0),
            (2, DVec2::new(0.5, 0.2), FRAC_PI_6),
            (3, DVec2::new(0.7, 0.1), 1.2),
            (4, DVec2::new(0.95, 0.9), -2.5),
            (5, DVec2::new(-0.95, 0.25), 0.1),
        ];
        let rot = |p: DVec2| if turn { DVec2::new(-p.y, p.x) } else { p };
        for (id, x, theta) in agents {
            let v = if id == 2 { DVec2::new(0.2, 0.05) } else { DVec2::ZERO };
            place(&mut sim, id, rot(x), rot(v), theta + if turn { FRAC_PI_2 } else { 0.0 });
        }
        sim
    };
    let (plain, turned) = (build(false), build(true));
    let obs = observation_of_prey_observer(&plain);
    // By hand: forward h = (cos 30°, sin 30°), left = (−sin 30°, cos 30°).
    let (h, left) = (DVec2::from_angle(FRAC_PI_6), DVec2::from_angle(FRAC_PI_6 + FRAC_PI_2));
    let v = DVec2::new(0.2, 0.05);
    assert!(close(&obs[..6], &[v.dot(h), v.dot(left), 0.0, 0.0, 0.0, 0.0]), "own {:?}", &obs[..6]);
    // The nearest prey is prey 3 at Δ = (0.2, −0.1), heading 1.2 rad.
    let d = DVec2::new(0.2, -0.1);
    let dh = DVec2::from_angle(1.2 - FRAC_PI_6) - DVec2::X;
    assert!(close(&obs[30..34], &[d.dot(h), d.dot(left), dh.x, dh.y]), "nearest prey {:?}", &obs[30..34]);
    for s in 0..2 {
        let a = &plain.world().resource::<Batches>().species[s].observations;
        let b = &turned.world().resource::<Batches>().species[s].observations;
        assert!(a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-5), "species {s}: {a:?} vs {b:?}");
    }
    // A network reading them acts the same in both worlds.
    let dev = coevo::learning::nets::Dev::default();
    let mut rng = <rand_chacha::ChaCha8Rng as rand::SeedableRng>::seed_from_u64(3);
    let ddpg =
        coevo::learning::ddpg::Ddpg::new(&dev, 54, &coevo::scene::Scene::preset("paper").unwrap().learning, &mut rng);
    let act = |sim: &Simulation| ddpg.act(&dev, &sim.world().resource::<Batches>().species[1].observations, 4);
    assert!(act(&plain).iter().zip(act(&turned)).all(|(x, y)| (x - y).abs() < 1e-5));
}

#[test]
fn body_frame_walls_are_the_nearest_wall_point_ahead_or_beside() {
    use coevo::scene::ObservationFrame;
    let mut s = scene(0, 2, Policy::Still, Boundary::Walls);
    s.observation_frame = ObservationFrame::Body;
    let mut sim = Simulation::new(s);
    // Facing +y, 0.1 m from the right wall (x = 1): the wall is 0.1 m to the observer's right.
    place(&mut sim, 0, DVec2::new(0.9, 0.0), DVec2::ZERO, FRAC_PI_2);
    place(&mut sim, 1, DVec2::new(-0.5, -0.5), DVec2::ZERO, 0.0);
    let obs = observation_of_prey_observer(&sim);
    assert!(close(&obs[3..5], &[0.0, -0.1]), "wall {:?}", &obs[3..5]);
}

#[test]
fn large_populations_see_the_same_neighbours_as_a_brute_force_search() {
    // Above 512 agents perception runs in parallel chunks over a grid of ~700 cells; every prey row must
    // still hold exactly its own nearest-first prey by minimum-image distance, ties by slot, and its nearest
    // kin. Random walkers, some in a tight swarm, on both boundaries, with a finite perception radius.
    use coevo::sim::perception::Population;
    for boundary in [Boundary::Periodic, Boundary::Walls] {
        let mut s = scene(3, 1_500, Policy::Random, boundary);
        s.world.arena_edge = 2.0 * (1_503.0f64 / 13.0).sqrt();
        let radius = 1.5;
        s.species[1].perception = Perception::Radius(radius);
        let mut sim = Simulation::new(s);
        let world = sim.world_mut();
        let mut q = world.query::<(&coevo::sim::components::AgentId, &mut coevo::sim::components::Position)>();
        for (id, mut x) in q.iter_mut(world).filter(|(id, _)| (3..600).contains(&id.0)) {
            let a = 0.01 * id.0 as f64;
            x.0 = DVec2::new(a.cos(), a.sin()) * 0.4 * (id.0 % 7) as f64 / 7.0;
        }
        for _ in 0..3 {
            sim.step();
        }
        let pop = sim.world().resource::<Population>();
        let (arena, batch) =
            (sim.world().resource::<coevo::sim::space::Arena>(), &sim.world().resource::<Batches>().species[1]);
        let prey = pop.ranges[1].clone();
        for i in prey.clone() {
            let mut near: Vec<(f64, usize)> = prey
                .clone()
                .filter(|&j| j != i)
                .map(|j| (arena.delta(pop.position[i], pop.position[j]).length_squared(), j))
                .filter(|&(d2, _)| d2 <= radius * radius)
                .collect();
            near.sort_by(|a, b| a.partial_cmp(b).unwrap());
            let row = batch.observation(i - prey.start);
            for n in 0..6 {
                let at = 30 + 4 * n;
                let want = near.get(n).map_or([0.0; 2], |&(_, j)| {
                    let d = arena.delta(pop.position[i], pop.position[j]);
                    [d.x as f32, d.y as f32]
                });
                assert_eq!(row[at..at + 2], want, "{boundary:?} prey slot {i}, neighbour {n}");
            }
            assert_eq!(pop.nearest_kin[i], near.first().map(|&(_, j)| j as u32), "{boundary:?} slot {i}");
        }
    }
}

/// Rule-based agents read their own heading and nearest neighbour wherever the layout puts them: chasing
/// predators and fleeing prey move exactly alike whether they observe in the paper's order or the
/// authors' (the nearest of each species is slot 0 in both).
#[test]
fn rule_based_agents_act_alike_in_either_layout() {
    use coevo::scene::ObservationLayout;
    let run = |layout: ObservationLayout| {
        let mut s = scene(3, 10, Policy::FleeNearest, Boundary::Periodic);
        s.species[0].policy = Policy::ChaseNearest;
        s.observation_layout = layout;
        for def in &mut s.species {
            def.topological_limit = 5;
            def.topological_limit_of = vec![("predator".into(), 2)];
        }
        let mut sim = Simulation::new(s);
        for _ in 0..60 {
            sim.step();
        }
        positions(&mut sim)
    };
    let (paper, authors) = (run(ObservationLayout::Paper), run(ObservationLayout::Authors));
    assert_eq!(paper, authors);
    let start = positions(&mut Simulation::new(scene(3, 10, Policy::FleeNearest, Boundary::Periodic)));
    assert!(paper.iter().all(|(_, x)| !start.iter().any(|(_, s)| s == x)), "everyone moved");
}
