//! Degree of sparsity and degree of alignment (Section "Results", Eqs. for DoS and DoA):
//!
//! ```text
//!   DoS = 1/(T·N·D) Σ_t Σ_j ‖x_j(t) − x_k(t)‖        k = the positionally nearest other agent of j's species
//!   DoA = 1/(2·T·N) Σ_t Σ_j ‖h_j(t) + h_k(t)‖         same k
//! ```
//!
//! D is the largest possible distance (√2 on the periodic 2 m arena, 2√2 with walls); distances are
//! minimum-image on the torus. Both are computed for every species with at least two agents; the paper
//! reports them for prey. Per step ([`SwarmMetrics::now`]) and per episode ([`EpisodeLog`]), with catches
//! (predator–prey pairs in contact) and each species' mean return per agent.

use crate::components::*;
use crate::perception::Population;
use crate::space::{Arena, CellGrid};
use crate::species::SpeciesRegistry;
use crate::SimSet;
use bevy::math::DVec2;
use bevy::prelude::*;

/// The order of one group at one instant: the paper's DoS and DoA, and two order parameters of collective
/// motion that tell a flock from a mill (not in the paper):
///
/// ```text
///   polarization P = ‖(1/N) Σ_j h_j‖                        1 = all aligned, ~1/√N for random headings
///   milling      M = |(1/N) Σ_j (r̂_j × h_j)_z|,  r_j = x_j − c    1 = a perfect mill, ~0 for a flock
/// ```
///
/// c is the group's centre: the mean position with walls, and on the torus the circular mean per axis
/// (each coordinate mapped to an angle on its periodic axis, the angles averaged as unit vectors, mapped
/// back), with r_j the minimum image of x_j − c. Swirling shows as M high with P low.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct Swarming {
    pub dos: f64,
    pub doa: f64,
    pub polarization: f64,
    pub milling: f64,
}

/// The group's centre c (see [`Swarming`]).
pub fn centre(arena: &Arena, positions: &[DVec2]) -> DVec2 {
    let n = positions.len().max(1) as f64;
    match arena.boundary {
        crate::scene::Boundary::Walls => positions.iter().copied().sum::<DVec2>() / n,
        crate::scene::Boundary::Periodic => {
            let turn = std::f64::consts::TAU / arena.edge;
            let axis = |get: fn(&DVec2) -> f64| {
                let (s, c) = positions.iter().fold((0.0, 0.0), |(s, c), p| (s + (get(p) * turn).sin(), c + (get(p) * turn).cos()));
                s.atan2(c) / turn
            };
            DVec2::new(axis(|p| p.x), axis(|p| p.y))
        }
    }
}

/// Polarization and milling of a group of positions and unit headings (see [`Swarming`]).
pub fn polarization_and_milling(arena: &Arena, positions: &[DVec2], headings: &[DVec2]) -> (f64, f64) {
    let n = positions.len().max(1) as f64;
    let c = centre(arena, positions);
    let polarization = headings.iter().copied().sum::<DVec2>().length() / n;
    let rotation: f64 = positions
        .iter()
        .zip(headings)
        .map(|(&x, h)| {
            let r = arena.delta(c, x);
            let d = r.length();
            if d > 0.0 { (r.x * h.y - r.y * h.x) / d } else { 0.0 }
        })
        .sum();
    (polarization, (rotation / n).abs())
}

/// DoS and DoA of the agents `members` of a population at one instant, using `grid` (built over
/// `members`) for the nearest-neighbour search, or `known_nearest[j]` where perception already found
/// j's nearest kin. None with fewer than two agents.
pub fn swarming(
    arena: &Arena,
    positions: &[DVec2],
    headings: &[DVec2],
    grid: &CellGrid,
    members: std::ops::Range<usize>,
    known_nearest: &[Option<u32>],
) -> Option<Swarming> {
    let n = members.len();
    if n < 2 {
        return None;
    }
    let members_start = members.start;
    let mut nearest = Vec::with_capacity(1);
    let (mut distance, mut alignment) = (0.0, 0.0);
    for j in members {
        let k = match known_nearest.get(j).copied().flatten() {
            Some(k) => k as usize,
            None => {
                grid.k_nearest(arena, positions[j], 1, f64::INFINITY, j as u32, &mut nearest);
                nearest[0].1 as usize
            }
        };
        distance += arena.delta(positions[j], positions[k]).length();
        alignment += (headings[j] + headings[k]).length();
    }
    let range = members_start..members_start + n;
    let (polarization, milling) = polarization_and_milling(arena, &positions[range.clone()], &headings[range]);
    Some(Swarming { dos: distance / (n as f64 * arena.max_distance()), doa: alignment / (2.0 * n as f64), polarization, milling })
}

/// Convenience for callers without a grid: DoS and DoA of a whole set of positions and unit headings.
pub fn swarming_of(arena: &Arena, positions: &[DVec2], headings: &[DVec2]) -> Option<Swarming> {
    let mut grid = CellGrid::default();
    grid.rebuild(arena, positions, 0..positions.len());
    swarming(arena, positions, headings, &grid, 0..positions.len(), &[])
}

/// The running mean over the last `window` values (fewer at the start): the paper's 100-episode curves,
/// the viewer's live plots and the experiment figures.
pub fn running_mean(values: &[f64], window: usize) -> Vec<f64> {
    let mut sum = 0.0;
    values
        .iter()
        .enumerate()
        .map(|(i, v)| {
            sum += v;
            if i >= window {
                sum -= values[i - window];
            }
            sum / (i + 1).min(window) as f64
        })
        .collect()
}

/// Per-step metrics of the current state and the running sums of the current episode.
#[derive(Resource, Default, Debug, Clone)]
pub struct SwarmMetrics {
    /// Per species; None with fewer than two agents.
    pub now: Vec<Option<Swarming>>,
    /// Predator–prey pairs in contact at the current state.
    pub catches_now: u32,
    episode: EpisodeSums,
}

#[derive(Default, Debug, Clone)]
struct EpisodeSums {
    steps: usize,
    swarming: Vec<Swarming>,
    catches: u64,
    rewards: Vec<f64>,
    agents: Vec<usize>,
}

/// One episode's summary: the time averages of the paper's figures.
#[derive(Clone, Debug, PartialEq)]
pub struct EpisodeSummary {
    pub episode: usize,
    pub steps: usize,
    /// Per species, time-averaged; None where the species had fewer than two agents.
    pub swarming: Vec<Option<Swarming>>,
    /// Catches summed over the episode's steps.
    pub catches: u64,
    /// Per species: summed reward over the episode divided by the number of agents (mean return).
    pub mean_return: Vec<f64>,
}

/// Every finished episode, in order.
#[derive(Resource, Default, Debug, Clone)]
pub struct EpisodeLog {
    pub episodes: Vec<EpisodeSummary>,
}

impl SwarmMetrics {
    /// Closes the running episode into a summary and starts a new one.
    pub fn finish_episode(&mut self, episode: usize) -> EpisodeSummary {
        let sums = std::mem::take(&mut self.episode);
        let t = sums.steps.max(1) as f64;
        EpisodeSummary {
            episode,
            steps: sums.steps,
            swarming: sums
                .swarming
                .iter()
                .zip(&sums.agents)
                .map(|(s, &n)| {
                    (n >= 2).then(|| Swarming {
                        dos: s.dos / t,
                        doa: s.doa / t,
                        polarization: s.polarization / t,
                        milling: s.milling / t,
                    })
                })
                .collect(),
            catches: sums.catches,
            mean_return: sums.rewards.iter().zip(&sums.agents).map(|(r, &n)| if n > 0 { r / n as f64 } else { 0.0 }).collect(),
        }
    }
}

pub struct MetricsPlugin;

impl Plugin for MetricsPlugin {
    fn build(&self, app: &mut App) {
        app.init_resource::<SwarmMetrics>().init_resource::<EpisodeLog>();
        app.add_systems(FixedUpdate, measure.in_set(SimSet::Measure));
    }
}

fn measure(
    pop: Res<Population>,
    arena: Res<Arena>,
    registry: Res<SpeciesRegistry>,
    mut metrics: ResMut<SwarmMetrics>,
    agents: Query<(&SpeciesId, &Contacts, &Reward)>,
) {
    let n_species = registry.len();
    let m = &mut *metrics;
    m.now = (0..n_species)
        .map(|s| swarming(&arena, &pop.position, &pop.heading, &pop.grids[s], pop.ranges[s].clone(), &pop.nearest_kin))
        .collect();
    let e = &mut m.episode;
    e.swarming.resize(n_species, Swarming::default());
    e.rewards.resize(n_species, 0.0);
    e.agents = (0..n_species).map(|s| pop.count(s)).collect();
    for (sum, now) in e.swarming.iter_mut().zip(&m.now) {
        if let Some(now) = now {
            sum.dos += now.dos;
            sum.doa += now.doa;
            sum.polarization += now.polarization;
            sum.milling += now.milling;
        }
    }
    m.catches_now = 0;
    for (species, contacts, reward) in &agents {
        m.catches_now += contacts.now.catching;
        e.rewards[species.0] += reward.0;
    }
    e.catches += m.catches_now as u64;
    e.steps += 1;
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::Boundary;
    use rand::{Rng, SeedableRng};

    #[test]
    fn random_headings_give_two_over_pi() {
        let arena = Arena { edge: 2.0, boundary: Boundary::Periodic };
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
        let (mut total, samples) = (0.0, 400);
        for _ in 0..samples {
            let pos: Vec<DVec2> = (0..50).map(|_| DVec2::new(rng.gen_range(-1.0..1.0), rng.gen_range(-1.0..1.0))).collect();
            let head: Vec<DVec2> = (0..50).map(|_| DVec2::from_angle(rng.gen_range(-std::f64::consts::PI..std::f64::consts::PI))).collect();
            total += swarming_of(&arena, &pos, &head).unwrap().doa;
        }
        let doa = total / samples as f64;
        assert!((doa - 2.0 / std::f64::consts::PI).abs() < 0.02, "DoA of random headings {doa}");
    }

    #[test]
    fn order_parameters_of_a_mill_a_flock_and_random_headings() {
        // A perfect mill around a centre that straddles the torus seam (so the circular mean matters):
        // 24 agents on a circle, each heading along the tangent.
        let arena = Arena { edge: 2.0, boundary: Boundary::Periodic };
        let centre = DVec2::new(0.95, -0.97);
        let pos: Vec<DVec2> = (0..24).map(|i| arena.wrap(centre + 0.3 * DVec2::from_angle(i as f64 * std::f64::consts::TAU / 24.0))).collect();
        let tangent: Vec<DVec2> = (0..24).map(|i| DVec2::from_angle(i as f64 * std::f64::consts::TAU / 24.0 + std::f64::consts::FRAC_PI_2)).collect();
        let c = super::centre(&arena, &pos);
        assert!(arena.delta(c, centre).length() < 1e-9, "centre {c} across the seam");
        let (p, m) = polarization_and_milling(&arena, &pos, &tangent);
        assert!(p < 1e-9 && (m - 1.0).abs() < 1e-9, "mill: P {p}, M {m}");
        // Turning the other way mills just as much.
        let reverse: Vec<DVec2> = tangent.iter().map(|h| -*h).collect();
        assert!((polarization_and_milling(&arena, &pos, &reverse).1 - 1.0).abs() < 1e-9);
        // The same agents all heading one way: a perfectly polarized flock, no rotation.
        let aligned = vec![DVec2::from_angle(0.4); 24];
        let (p, m) = polarization_and_milling(&arena, &pos, &aligned);
        assert!((p - 1.0).abs() < 1e-12 && m < 1e-9, "flock: P {p}, M {m}");
        // Random headings: P ~ 1/√N on average.
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(4);
        let n = 400;
        let (mut total, samples) = (0.0, 200);
        for _ in 0..samples {
            let pos: Vec<DVec2> = (0..n).map(|_| DVec2::new(rng.gen_range(-1.0..1.0), rng.gen_range(-1.0..1.0))).collect();
            let head: Vec<DVec2> = (0..n).map(|_| DVec2::from_angle(rng.gen_range(-3.15..3.15))).collect();
            total += polarization_and_milling(&Arena { edge: 2.0, boundary: Boundary::Walls }, &pos, &head).0;
        }
        // E‖mean of N unit vectors‖ = √(π/(4N)) for large N.
        let expected = (std::f64::consts::PI / (4.0 * n as f64)).sqrt();
        assert!((total / samples as f64 - expected).abs() < 0.1 * expected, "{} vs {expected}", total / samples as f64);
        // The per-instant measure reports both.
        let s = swarming_of(&arena, &pos, &tangent).unwrap();
        assert!(s.polarization < 1e-9 && (s.milling - 1.0).abs() < 1e-9);
    }

    #[test]
    fn aligned_agents_have_doa_one() {
        let arena = Arena { edge: 2.0, boundary: Boundary::Walls };
        let pos = [DVec2::new(0.0, 0.0), DVec2::new(0.3, 0.1), DVec2::new(-0.5, 0.7)];
        let head = [DVec2::from_angle(0.7); 3];
        assert!((swarming_of(&arena, &pos, &head).unwrap().doa - 1.0).abs() < 1e-12);
    }

    #[test]
    fn dos_of_a_known_configuration() {
        // Torus of edge 2: agents at x = ±0.95 are 0.1 apart across the seam; the third is 0.5 from the
        // nearest. Nearest distances 0.1, 0.1, 0.5 → DoS = 0.7 / (3·√2).
        let arena = Arena { edge: 2.0, boundary: Boundary::Periodic };
        let pos = [DVec2::new(0.95, 0.0), DVec2::new(-0.95, 0.0), DVec2::new(-0.45, 0.0)];
        let head = [DVec2::X, DVec2::Y, -DVec2::X];
        let s = swarming_of(&arena, &pos, &head).unwrap();
        assert!((s.dos - 0.7 / (3.0 * 2f64.sqrt())).abs() < 1e-12, "{}", s.dos);
        // Pairs: (X,Y) → √2, (Y,X) → √2, (−X, Y) → √2: DoA = 3·√2 / 6.
        assert!((s.doa - 2f64.sqrt() / 2.0).abs() < 1e-12, "{}", s.doa);
        assert!(swarming_of(&arena, &pos[..1], &head[..1]).is_none());
    }
}
