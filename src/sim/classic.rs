//! What the classic models do with an observation ([`crate::scene::VicsekRule`],
//! [`crate::scene::CouzinRule`]; their parameters and how they map onto coevo's dynamics are documented
//! there): each chooses a direction in the focal agent's body frame from the conspecifics the observation
//! holds, and [`steer`] turns toward it as far as the species may in one step, at full thrust.

use super::rules::Seen;
use crate::scene::{CouzinRule, VicsekRule};
use rand::Rng;
use rand_distr::{Distribution, Normal};

/// The normalized action that heads for `direction` ([ahead, left] in the body frame): the turn that
/// reaches its angle this step, clamped to the species' turn rate, and full thrust.
pub(crate) fn steer(direction: [f64; 2], max_turn: f64, dt: f64) -> [f32; 2] {
    let angle = direction[1].atan2(direction[0]);
    let reach = max_turn * dt;
    let turn = if reach > 0.0 { (angle / reach).clamp(-1.0, 1.0) } else { 0.0 };
    [1.0, turn as f32]
}

/// An angle's direction rotated by `by`: [ahead, left] of unit length (a zero direction is ahead).
fn turned(direction: [f64; 2], by: f64) -> [f64; 2] {
    let angle = if direction == [0.0, 0.0] { 0.0 } else { direction[1].atan2(direction[0]) } + by;
    [angle.cos(), angle.sin()]
}

/// Vicsek et al. (1995): the mean heading of the conspecifics within `radius` and of the agent itself
/// (its own heading is [1, 0] in its body frame), turned by uniform noise in [−η/2, η/2].
pub(crate) fn vicsek_direction(rule: &VicsekRule, kin: &[Seen], rng: &mut impl Rng) -> [f64; 2] {
    let mut sum = [1.0, 0.0];
    for k in kin.iter().filter(|k| k.distance() < rule.radius) {
        sum[0] += k.cos_heading;
        sum[1] += k.sin_heading;
    }
    let noise = if rule.noise > 0.0 { rng.gen_range(-rule.noise / 2.0..=rule.noise / 2.0) } else { 0.0 };
    turned(sum, noise)
}

/// Couzin et al. (2002): away from everyone in the repulsion zone when anyone is there; otherwise the
/// unit sum of the orientation zone's headings and of the directions to the attraction zone's members,
/// averaged when both hold someone; ahead when nobody is in any zone. Then Gaussian noise of s.d. σ.
pub(crate) fn couzin_direction(rule: &CouzinRule, kin: &[Seen], rng: &mut impl Rng) -> [f64; 2] {
    let r_o = rule.repulsion_radius + rule.orientation_width;
    let r_a = r_o + rule.attraction_width;
    let unit = |v: [f64; 2]| {
        let n = v[0].hypot(v[1]);
        (n > 0.0).then(|| [v[0] / n, v[1] / n])
    };
    let sum = |zone: &dyn Fn(f64) -> bool, term: &dyn Fn(&Seen) -> [f64; 2]| {
        kin.iter().filter(|k| zone(k.distance())).fold(None, |acc: Option<[f64; 2]>, k| {
            let t = term(k);
            Some(acc.map_or(t, |a| [a[0] + t[0], a[1] + t[1]]))
        })
    };
    let repulsion = sum(&|d| d < rule.repulsion_radius, &|k| {
        let u = k.unit();
        [-u[0], -u[1]]
    });
    let direction = match repulsion {
        // Repulsion takes priority; a member exactly at the centre has no direction: keep the heading.
        Some(away) => unit(away).unwrap_or([1.0, 0.0]),
        None => {
            let orientation = sum(&|d| d >= rule.repulsion_radius && d < r_o, &|k| [k.cos_heading, k.sin_heading]);
            let attraction = sum(&|d| d >= r_o && d < r_a, &|k| k.unit());
            match (orientation.and_then(unit), attraction.and_then(unit)) {
                (Some(o), Some(a)) => unit([(o[0] + a[0]) / 2.0, (o[1] + a[1]) / 2.0]).unwrap_or(o),
                (Some(o), None) => o,
                (None, Some(a)) => a,
                (None, None) => [1.0, 0.0],
            }
        }
    };
    let noise = if rule.noise > 0.0 {
        Normal::new(0.0, rule.noise).expect("a positive finite standard deviation (scene validation)").sample(rng)
    } else {
        0.0
    };
    turned(direction, noise)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    fn seen(ahead: f64, left: f64, heading: f64) -> Seen {
        Seen { ahead, left, sin_heading: heading.sin(), cos_heading: heading.cos() }
    }

    fn rng() -> rand_chacha::ChaCha8Rng {
        rand_chacha::ChaCha8Rng::seed_from_u64(1)
    }

    fn angle(d: [f64; 2]) -> f64 {
        d[1].atan2(d[0])
    }

    #[test]
    fn vicsek_heads_for_the_mean_heading_within_its_radius_itself_included() {
        let rule = VicsekRule { radius: 1.0, noise: 0.0 };
        // One neighbour heading 90° left, within r: the mean of 0° and 90° is 45°; one beyond r is ignored.
        let kin = [seen(0.5, 0.0, std::f64::consts::FRAC_PI_2), seen(2.0, 0.0, std::f64::consts::PI)];
        assert!((angle(vicsek_direction(&rule, &kin, &mut rng())) - std::f64::consts::FRAC_PI_4).abs() < 1e-12);
        // The noise stays within ±η/2.
        let noisy = VicsekRule { radius: 1.0, noise: 1.0 };
        let mut r = rng();
        for _ in 0..1000 {
            assert!(angle(vicsek_direction(&noisy, &[], &mut r)).abs() <= 0.5 + 1e-12);
        }
    }

    #[test]
    fn couzin_gives_repulsion_priority_and_averages_orientation_with_attraction() {
        let rule = CouzinRule { repulsion_radius: 0.1, orientation_width: 0.4, attraction_width: 1.0, noise: 0.0 };
        let left = std::f64::consts::FRAC_PI_2;
        // A neighbour within r_r on the left: turn right, whatever else is seen.
        let d = couzin_direction(&rule, &[seen(0.0, 0.05, 0.0), seen(0.0, -0.3, left)], &mut rng());
        assert!((angle(d) + left).abs() < 1e-12, "{d:?}");
        // Orientation only: its heading (90° left).
        let d = couzin_direction(&rule, &[seen(0.3, 0.0, left)], &mut rng());
        assert!((angle(d) - left).abs() < 1e-12, "{d:?}");
        // Attraction only: toward the member (straight right).
        let d = couzin_direction(&rule, &[seen(0.0, -1.0, 0.0)], &mut rng());
        assert!((angle(d) + left).abs() < 1e-12, "{d:?}");
        // Both: the mean of the unit directions, the orientation's (90° left) and the attraction's (ahead).
        let d = couzin_direction(&rule, &[seen(0.3, 0.0, left), seen(1.0, 0.0, 0.0)], &mut rng());
        assert!((angle(d) - std::f64::consts::FRAC_PI_4).abs() < 1e-12, "{d:?}");
        // Nobody within r_a: ahead.
        assert_eq!(couzin_direction(&rule, &[seen(5.0, 0.0, left)], &mut rng()), [1.0, 0.0]);
    }

    #[test]
    fn steering_turns_at_most_the_species_rate() {
        assert_eq!(steer([1.0, 0.0], 0.5, 0.1), [1.0, 0.0]);
        assert_eq!(steer([0.0, 1.0], 0.5, 0.1), [1.0, 1.0]);
        let small = steer([1.0, 0.01], 0.5, 0.1);
        assert!((small[1] as f64 - 0.01f64.atan2(1.0) / 0.05).abs() < 1e-6);
    }
}
