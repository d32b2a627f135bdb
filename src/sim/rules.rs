//! What the distilled rules do with an observation ([`crate::scene::ZonalRule`],
//! [`crate::scene::BinnedRule`], [`crate::scene::PursuitRule`]): the observed agents read in the focal agent's body frame, summed into
//! the rule's features, and the features weighted by its gains. `analysis::distill` fits the gains to
//! a trained actor on the same features, so a fitted rule acts exactly as it was fitted.

use crate::scene::{BinnedRule, ObservationFrame, PursuitGains, PursuitRule, ZonalRule};
use crate::sim::perception::neighbour_slot;
use crate::sim::species::{SpeciesRegistry, ACTION_DIM};

/// One observed agent in the focal agent's body frame: where it is (metres ahead, to the left) and the
/// sine and cosine of its heading relative to the focal agent's (sine + when it heads to the left of it).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Seen {
    pub(crate) ahead: f64,
    pub(crate) left: f64,
    pub(crate) sin_heading: f64,
    pub(crate) cos_heading: f64,
}

impl Seen {
    pub(crate) fn distance(&self) -> f64 {
        self.ahead.hypot(self.left)
    }

    /// The unit direction to it, [ahead, left]; zero for an agent at the focal agent's centre.
    pub(crate) fn unit(&self) -> [f64; 2] {
        let d = self.distance();
        if d > 0.0 {
            [self.ahead / d, self.left / d]
        } else {
            [0.0, 0.0]
        }
    }
}

/// The agents of species `t` in an observation `obs` of species `s`, nearest first, in the body frame
/// whatever the scene's observation frame (a world-frame observation is turned by the observer's heading).
pub(crate) fn observed(
    obs: &[f32],
    registry: &SpeciesRegistry,
    s: usize,
    t: usize,
    frame: ObservationFrame,
) -> Vec<Seen> {
    let heading = match frame {
        ObservationFrame::World => {
            let h = registry.layouts[s].heading();
            Some([obs[h.start] as f64, obs[h.start + 1] as f64])
        }
        ObservationFrame::Body => None,
    };
    (0..registry.slots(s, t))
        .filter_map(|n| neighbour_slot(obs, registry, s, t, n))
        .map(|slot| {
            let [dx, dy, dhx, dhy] = slot.map(|c| c as f64);
            match heading {
                // Body frame: the observer faces [1, 0], so the other's heading is [1 + Δh_x, Δh_y].
                None => Seen { ahead: dx, left: dy, sin_heading: dhy, cos_heading: 1.0 + dhx },
                Some([hx, hy]) => {
                    let (jx, jy) = (hx + dhx, hy + dhy);
                    Seen {
                        ahead: dx * hx + dy * hy,
                        left: hx * dy - hy * dx,
                        sin_heading: hx * jy - hy * jx,
                        cos_heading: hx * jx + hy * jy,
                    }
                }
            }
        })
        .collect()
}

/// What a rule reads of the agent itself: its previous turn command in [−1, 1] (the body-frame
/// observation's turn state; 0 in the world frame, which does not hold it) and its speed along its heading
/// as a fraction of its top speed.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct Own {
    pub(crate) turn: f64,
    pub(crate) speed: f64,
}

impl Own {
    pub(crate) fn of(obs: &[f32], registry: &SpeciesRegistry, s: usize, frame: ObservationFrame) -> Own {
        let top = registry.defs[s].max_speed;
        match frame {
            // Own state [v ahead, v left, turn, wall ahead, wall left, 0].
            ObservationFrame::Body => Own { turn: obs[2] as f64, speed: obs[0] as f64 / top },
            ObservationFrame::World => {
                let h = registry.layouts[s].heading();
                let along = obs[2] as f64 * obs[h.start] as f64 + obs[3] as f64 * obs[h.start + 1] as f64;
                Own { turn: 0.0, speed: along / top }
            }
        }
    }
}

/// The sums a [`ZonalRule`] weighs: per zone the unit directions [ahead, left] of its members, and the
/// alignment zone's Σ sin(Δheading).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct ZonalFeatures {
    pub(crate) own: Own,
    pub(crate) repulsion: [f64; 2],
    pub(crate) alignment: f64,
    pub(crate) attraction: [f64; 2],
    pub(crate) evasion: [f64; 2],
}

impl ZonalFeatures {
    pub(crate) fn of(rule: &ZonalRule, own: Own, kin: &[Seen], predators: &[Seen]) -> ZonalFeatures {
        let mut f = ZonalFeatures { own, ..Default::default() };
        let add = |sum: &mut [f64; 2], u: [f64; 2]| *sum = [sum[0] + u[0], sum[1] + u[1]];
        for k in kin {
            let d = k.distance();
            if d < rule.repulsion_radius {
                add(&mut f.repulsion, k.unit());
            } else if d < rule.alignment_radius {
                f.alignment += k.sin_heading;
            } else if d < rule.attraction_radius {
                add(&mut f.attraction, k.unit());
            }
        }
        for p in predators.iter().filter(|p| p.distance() < rule.evasion_radius) {
            add(&mut f.evasion, p.unit());
        }
        f
    }
}

/// The normalized action [thrust, turn] of a [`ZonalRule`] on its features.
pub(crate) fn zonal_action(rule: &ZonalRule, f: &ZonalFeatures) -> [f32; ACTION_DIM] {
    let (t, u) = (&rule.turn, &rule.thrust);
    let turn = t.bias
        + t.persistence * f.own.turn
        + t.repulsion * f.repulsion[1]
        + t.alignment * f.alignment
        + t.attraction * f.attraction[1]
        + t.evasion * f.evasion[1];
    let thrust = u.bias
        + u.speed * f.own.speed
        + u.repulsion * f.repulsion[0]
        + u.attraction * f.attraction[0]
        + u.evasion * f.evasion[0];
    [thrust.clamp(-1.0, 1.0) as f32, turn.clamp(-1.0, 1.0) as f32]
}

/// The bin of [`BinnedRule`] `edges` a distance falls in; None beyond the last edge.
pub(crate) fn bin_of(edges: &[f64], d: f64) -> Option<usize> {
    (0..edges.len().saturating_sub(1)).find(|&b| d >= edges[b] && d < edges[b + 1])
}

/// The normalized action [thrust, turn] of a [`BinnedRule`] on the agent's own state and the kin and
/// predators seen: each neighbour's unit direction (and a kin's Δheading) weighed by the gain of the bin
/// its distance is in.
pub(crate) fn binned_action(rule: &BinnedRule, own: Own, kin: &[Seen], predators: &[Seen]) -> [f32; ACTION_DIM] {
    let (t, u) = (&rule.turn, &rule.thrust);
    let (mut turn, mut thrust) = (t.bias + rule.persistence * own.turn, u.bias + rule.speed * own.speed);
    for k in kin {
        if let Some(b) = bin_of(&rule.edges, k.distance()) {
            let [ahead, left] = k.unit();
            turn += t.kin[b] * left + t.alignment[b] * k.sin_heading;
            thrust += u.kin[b] * ahead;
        }
    }
    for p in predators {
        if let Some(b) = bin_of(&rule.edges, p.distance()) {
            let [ahead, left] = p.unit();
            turn += t.evasion[b] * left;
            thrust += u.evasion[b] * ahead;
        }
    }
    [thrust.clamp(-1.0, 1.0) as f32, turn.clamp(-1.0, 1.0) as f32]
}

/// The unit directions [ahead, left] a [`PursuitRule`] weighs; zero without prey in view.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct PursuitFeatures {
    pub(crate) own: Own,
    pub(crate) nearest: [f64; 2],
    pub(crate) centre: [f64; 2],
    pub(crate) isolated: [f64; 2],
}

impl PursuitFeatures {
    pub(crate) fn of(own: Own, prey: &[Seen]) -> PursuitFeatures {
        let Some(nearest) = prey.iter().min_by(|a, b| a.distance().total_cmp(&b.distance())) else {
            return PursuitFeatures { own, ..Default::default() };
        };
        let n = prey.len() as f64;
        let centre = Seen {
            ahead: prey.iter().map(|p| p.ahead).sum::<f64>() / n,
            left: prey.iter().map(|p| p.left).sum::<f64>() / n,
            sin_heading: 0.0,
            cos_heading: 1.0,
        };
        // The most isolated: farthest from its nearest fellow in view (the only one, alone in view).
        let gap = |i: usize| {
            let p = &prey[i];
            let others = prey.iter().enumerate().filter(|&(j, _)| j != i);
            others.map(|(_, q)| (p.ahead - q.ahead).hypot(p.left - q.left)).fold(f64::INFINITY, f64::min)
        };
        let isolated = (0..prey.len()).max_by(|&a, &b| gap(a).total_cmp(&gap(b))).expect("one prey at least");
        PursuitFeatures { own, nearest: nearest.unit(), centre: centre.unit(), isolated: prey[isolated].unit() }
    }
}

/// The normalized action [thrust, turn] of a [`PursuitRule`] on its features.
pub(crate) fn pursuit_action(rule: &PursuitRule, f: &PursuitFeatures) -> [f32; ACTION_DIM] {
    let weigh = |g: &PursuitGains, k: usize| {
        g.bias + g.nearest * f.nearest[k] + g.centre * f.centre[k] + g.isolated * f.isolated[k]
    };
    let thrust = weigh(&rule.thrust, 0) + rule.speed * f.own.speed;
    let turn = weigh(&rule.turn, 1) + rule.persistence * f.own.turn;
    [thrust.clamp(-1.0, 1.0) as f32, turn.clamp(-1.0, 1.0) as f32]
}

/// The agents of every species in `of` seen in `obs`, in one list.
pub(crate) fn observed_of(
    obs: &[f32],
    registry: &SpeciesRegistry,
    s: usize,
    of: impl Iterator<Item = usize>,
    frame: ObservationFrame,
) -> Vec<Seen> {
    of.flat_map(|t| observed(obs, registry, s, t, frame)).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::{PursuitRule, ZonalThrust, ZonalTurn};

    fn seen(ahead: f64, left: f64, sin_heading: f64) -> Seen {
        Seen { ahead, left, sin_heading, cos_heading: (1.0 - sin_heading * sin_heading).sqrt() }
    }

    fn couzin() -> ZonalRule {
        ZonalRule {
            repulsion_radius: 0.1,
            alignment_radius: 0.3,
            attraction_radius: 0.6,
            evasion_radius: 0.6,
            turn: ZonalTurn {
                bias: 0.0,
                persistence: 0.0,
                repulsion: -1.0,
                alignment: 1.0,
                attraction: 1.0,
                evasion: -2.0,
            },
            thrust: ZonalThrust { bias: 0.5, speed: 0.0, repulsion: -0.5, attraction: 0.5, evasion: -1.0 },
        }
    }

    #[test]
    fn each_neighbour_counts_in_the_zone_its_distance_puts_it() {
        let rule = couzin();
        // One close on the left (repulsion), one heading 30° left at 0.2 m (alignment), one ahead at 0.5 m
        // (attraction), one beyond every zone; a predator behind on the right within reach.
        let kin = [seen(0.0, 0.05, 0.0), seen(0.2, 0.0, 0.5), seen(0.5, 0.0, 0.0), seen(0.7, 0.0, 0.0)];
        let f = ZonalFeatures::of(&rule, Own::default(), &kin, &[seen(-0.3, -0.4, 0.0)]);
        assert_eq!(f.repulsion, [0.0, 1.0]);
        assert_eq!(f.alignment, 0.5);
        assert_eq!(f.attraction, [1.0, 0.0]);
        assert!((f.evasion[0] + 0.6).abs() < 1e-12 && (f.evasion[1] + 0.8).abs() < 1e-12);
        // Turn: −1 (away from the close one) + 0.5 (align) + 0 + 1.6 (away from the predator) = 1.1 → 1.
        // Thrust: 0.5 + 0 + 0.5 (the one ahead) + 0.6 (speed away from the one behind) = 1.6 → 1.
        assert_eq!(zonal_action(&rule, &f), [1.0, 1.0]);
        // Without evasion, the turn is the kin's alone: −1 + 0.5 = −0.5.
        assert_eq!(zonal_action(&rule.without(&[crate::scene::ZonalTerm::Evasion]), &f)[1], -0.5);
        // A zone of equal radii is empty: everything between 0.1 and 0.6 m is attraction.
        let mut no_alignment = rule.clone();
        no_alignment.alignment_radius = no_alignment.repulsion_radius;
        let f = ZonalFeatures::of(&no_alignment, Own::default(), &kin, &[]);
        assert_eq!((f.alignment, f.attraction), (0.0, [2.0, 0.0]));
        // Persistence keeps turning the way it turned; speed regulation slows a fast agent.
        let mut inert = ZonalRule { turn: ZonalTurn { persistence: 0.5, ..Default::default() }, ..rule.clone() };
        inert.thrust = ZonalThrust { bias: 1.0, speed: -1.0, ..Default::default() };
        let f = ZonalFeatures::of(&inert, Own { turn: -0.8, speed: 0.75 }, &[], &[]);
        assert_eq!(zonal_action(&inert, &f), [0.25, -0.4]);
    }

    #[test]
    fn a_binned_rule_weighs_each_neighbour_by_its_distance_bin() {
        use crate::scene::{BinnedGains, BinnedRule, ZonalTerm};
        let rule = BinnedRule {
            edges: vec![0.0, 0.1, 0.5],
            turn: BinnedGains { bias: 0.1, kin: vec![-0.5, 0.2], alignment: vec![0.0, 0.4], evasion: vec![-0.3, -0.1] },
            thrust: BinnedGains { bias: 0.5, kin: vec![-0.2, 0.1], alignment: vec![], evasion: vec![-0.4, 0.0] },
            persistence: 0.5,
            speed: -0.4,
        };
        // Kin: one close on the left (bin 0), one at 0.2 m ahead heading 30° left (bin 1), one beyond the
        // last edge; a predator 0.3 m to the right (bin 1).
        let kin = [seen(0.0, 0.05, 0.0), seen(0.2, 0.0, 0.5), seen(0.7, 0.0, 0.0)];
        let predators = [seen(0.0, -0.3, 0.0)];
        // Turn: 0.1 − 0.5 (away from the close one) + 0.4·0.5 (align) + 0.1 (away from the predator) = −0.1.
        // Thrust: 0.5 + 0.1 (toward the one ahead) = 0.6.
        let [thrust, turn] = binned_action(&rule, Own::default(), &kin, &predators);
        assert!((thrust - 0.6).abs() < 1e-6 && (turn + 0.1).abs() < 1e-6, "{thrust} {turn}");
        // Its own state: 0.5 × the previous turn 0.4, −0.4 × its speed 0.5 of the top.
        let [thrust, turn] = binned_action(&rule, Own { turn: 0.4, speed: 0.5 }, &kin, &predators);
        assert!((thrust - 0.4).abs() < 1e-6 && (turn - 0.1).abs() < 1e-6, "{thrust} {turn}");
        // Repulsion is the bins whose kin turn gain is negative; attraction the others.
        let ablated = rule.without(&[ZonalTerm::Repulsion, ZonalTerm::Alignment]);
        assert_eq!((ablated.turn.kin, ablated.thrust.kin), (vec![0.0, 0.2], vec![0.0, 0.1]));
        assert_eq!(ablated.turn.alignment, vec![0.0, 0.0]);
        let ablated = rule.without(&[ZonalTerm::Attraction, ZonalTerm::Evasion]);
        assert_eq!(
            (ablated.turn.kin, ablated.turn.evasion, ablated.thrust.evasion),
            (vec![-0.5, 0.0], vec![0.0; 2], vec![0.0; 2])
        );
    }

    #[test]
    fn a_pursuer_reads_the_nearest_the_centre_and_the_most_isolated() {
        // Two prey close together on the left, one alone ahead-right and nearest.
        let prey = [seen(0.0, 1.0, 0.0), seen(0.1, 1.0, 0.0), seen(0.5, -0.5, 0.0)];
        let f = PursuitFeatures::of(Own::default(), &prey);
        let s = 0.5f64.sqrt();
        assert!((f.nearest[0] - s).abs() < 1e-12 && (f.nearest[1] + s).abs() < 1e-12);
        assert_eq!(f.isolated, f.nearest, "the lone prey is the most isolated");
        assert!(f.centre[1] > 0.0, "the centre lies left");
        let chase = PursuitRule {
            turn: PursuitGains { nearest: 3.0, ..Default::default() },
            thrust: PursuitGains { bias: 1.0, ..Default::default() },
            ..Default::default()
        };
        assert_eq!(pursuit_action(&chase, &f), [1.0, -1.0], "full thrust, hard right toward the nearest");
        assert_eq!(PursuitFeatures::of(Own::default(), &[]), PursuitFeatures::default());
    }
}
