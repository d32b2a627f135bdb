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

use super::schedule::SimSet;
use crate::sim::collective::{self, ConfusionBin, CONFUSION_BINS};
use crate::sim::components::*;
use crate::sim::perception::Population;
use crate::sim::space::Arena;
use crate::sim::species::SpeciesRegistry;
use bevy::math::DVec2;
use bevy::prelude::*;

pub use super::order::{centre, polarization_and_milling, swarming, swarming_of, Swarming};

/// The running mean over the last `window` values (fewer at the start): the paper's 100-episode curves,
/// the viewer's live plots and the experiment figures.
pub(crate) fn running_mean(values: &[f64], window: usize) -> Vec<f64> {
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

/// Per-step metrics of the current state and the running sums of the current episode (a new population
/// starts them afresh).
#[derive(Resource, Default, Debug, Clone)]
pub struct SwarmMetrics {
    /// Per species; None with fewer than two agents.
    pub now: Vec<Option<Swarming>>,
    /// Predator–prey pairs in contact at the current state.
    pub catches_now: u32,
    /// The same by catcher species (per pair when a species catches one species, as in every shipped
    /// scene and example).
    pub(crate) catches_now_by: Vec<u32>,
    /// Per species: each agent's nearest-neighbour distance (m) at this state.
    pub nn_distances_now: Vec<Vec<f64>>,
    /// Per prey species: the edge ranks of the prey caught at this step (contacts that began with it),
    /// among groups of three or more ([`collective::edge_rank`]).
    pub(crate) edge_ranks_now: Vec<Vec<f64>>,
    /// Prey in view of each agent at the previous state of this episode (index as [`Population`]): the
    /// decision taken there is scored at the next step.
    in_view: Vec<u32>,
    episode: EpisodeSums,
}

/// The confusion curve since the scene started: per species (empty bins for species that catch
/// nothing), predator decisions by [`collective::CONFUSION_BINS`] of prey in view.
#[derive(Resource, Default, Debug, Clone)]
pub(crate) struct Confusion(pub Vec<[ConfusionBin; CONFUSION_BINS.len()]>);

#[derive(Default, Debug, Clone)]
struct EpisodeSums {
    steps: usize,
    /// Per species, the authors' DoS and DoA ([`authors_dos_doa`]) summed over the states measured.
    authors: Vec<[f64; 2]>,
    authors_states: usize,
    swarming: Vec<[f64; Swarming::N]>,
    catches: u64,
    catches_by: Vec<u64>,
    rewards: Vec<f64>,
    agents: Vec<usize>,
    edge_ranks: Vec<(f64, u64)>,
}

/// One episode's summary: the time averages of the paper's figures.
#[derive(Clone, Debug, PartialEq)]
pub struct EpisodeSummary {
    pub(crate) episode: usize,
    pub(crate) steps: usize,
    /// Per species, time-averaged; None where the species had fewer than two agents.
    pub(crate) swarming: Vec<Option<Swarming>>,
    /// Catches summed over the episode's steps.
    pub(crate) catches: u64,
    /// The same by catcher species.
    pub(crate) catches_by: Vec<u64>,
    /// Per species: summed reward over the episode divided by the number of agents (mean return).
    pub(crate) mean_return: Vec<f64>,
    /// Per species: the mean edge rank of its prey caught this episode; None without a ranked catch.
    pub(crate) edge_rank: Vec<Option<f64>>,
    /// Per species, the authors' DoS and DoA averaged over the episode's states 0…T−1 ([`authors_dos_doa`]),
    /// None where it had fewer than two agents; empty unless the scene asks (`authors_metrics`).
    pub authors: Vec<Option<[f64; 2]>>,
}

/// Every finished episode, in order.
#[derive(Resource, Default, Debug, Clone)]
pub struct EpisodeLog {
    pub episodes: Vec<EpisodeSummary>,
}

impl SwarmMetrics {
    /// Closes the running episode into a summary and starts a new one.
    pub(crate) fn finish_episode(&mut self, episode: usize) -> EpisodeSummary {
        let sums = std::mem::take(&mut self.episode);
        let t = sums.steps.max(1) as f64;
        EpisodeSummary {
            episode,
            steps: sums.steps,
            swarming: sums
                .swarming
                .iter()
                .zip(&sums.agents)
                .map(|(s, &n)| (n >= 2).then(|| Swarming::from_values(s.map(|v| v / t))))
                .collect(),
            catches: sums.catches,
            catches_by: sums.catches_by,
            mean_return: sums
                .rewards
                .iter()
                .zip(&sums.agents)
                .map(|(r, &n)| if n > 0 { r / n as f64 } else { 0.0 })
                .collect(),
            edge_rank: sums.edge_ranks.iter().map(|&(sum, n)| (n > 0).then(|| sum / n as f64)).collect(),
            authors: sums
                .authors
                .iter()
                .zip(&sums.agents)
                .map(|(a, &n)| (n >= 2).then(|| a.map(|v| v / sums.authors_states.max(1) as f64)))
                .collect(),
        }
    }
}

pub(crate) struct MetricsPlugin;

impl Plugin for MetricsPlugin {
    fn build(&self, app: &mut App) {
        app.init_resource::<SwarmMetrics>().init_resource::<EpisodeLog>().init_resource::<Confusion>();
        app.add_systems(FixedUpdate, measure.in_set(SimSet::Measure));
        app.add_systems(
            FixedUpdate,
            measure_authors
                .in_set(SimSet::Decide)
                .run_if(|scene: Res<super::schedule::ActiveScene>| scene.0.authors_metrics),
        );
    }
}

/// DoS and DoA of one species as the authors' shipped code computes them (WindyLab/Gym-PPS
/// `gym/wrappers/njp.py`, `dos_and_doa`; differences 9–10 of docs/src/results/authors-code.md): each agent's plain Euclidean distance to
/// its nearest other (no minimum image on the torus) over n·D with D = √2·edge/2 (the code's √2 on its
/// 2 m arena), and ‖h_j + h_k‖ over 2n with k the agent whose heading is most opposed to j's (argmin over
/// all k ≠ j), not j's nearest neighbour. None with fewer than two agents.
pub fn authors_dos_doa(edge: f64, positions: &[DVec2], headings: &[DVec2]) -> Option<[f64; 2]> {
    let n = positions.len();
    if n < 2 {
        return None;
    }
    let nearest =
        |j: usize, value: &dyn Fn(usize) -> f64| (0..n).filter(|&k| k != j).map(value).fold(f64::INFINITY, f64::min);
    let (mut dos, mut doa) = (0.0, 0.0);
    for j in 0..n {
        dos += nearest(j, &|k| (positions[j] - positions[k]).length());
        doa += nearest(j, &|k| (headings[j] + headings[k]).length());
    }
    Some([dos / (n as f64 * edge * std::f64::consts::SQRT_2 / 2.0), doa / (2.0 * n as f64)])
}

/// The authors' DoS and DoA of the state the agents decide on (rows 9–11): measured before the step, so
/// an episode of T steps sums its states 0…T−1, the spawn state included, as `NJP_algorithm/main.py`
/// stores positions and headings before each `env.step`.
fn measure_authors(pop: Res<Population>, arena: Res<Arena>, mut metrics: ResMut<SwarmMetrics>) {
    let e = &mut metrics.episode;
    e.authors.resize(pop.ranges.len(), [0.0; 2]);
    for (sum, range) in e.authors.iter_mut().zip(&pop.ranges) {
        let edge = 2.0 * arena.half();
        if let Some(v) = authors_dos_doa(edge, &pop.position[range.clone()], &pop.heading[range.clone()]) {
            sum[0] += v[0];
            sum[1] += v[1];
        }
    }
    e.authors_states += 1;
}

fn measure(
    pop: Res<Population>,
    arena: Res<Arena>,
    registry: Res<SpeciesRegistry>,
    scene: Res<super::schedule::ActiveScene>,
    mut metrics: ResMut<SwarmMetrics>,
    mut confusion: ResMut<Confusion>,
    agents: Query<(&Slot, &Contacts, &Reward)>,
) {
    let n_species = registry.len();
    let m = &mut *metrics;
    // Contacts by population index.
    let mut contacts = vec![ContactCounts::default(); pop.len()];
    let mut started = vec![false; pop.len()];
    m.episode.rewards.resize(n_species, 0.0);
    m.catches_now = 0;
    m.catches_now_by.clear();
    m.catches_now_by.resize(n_species, 0);
    for (slot, c, reward) in &agents {
        let i = slot.index as usize;
        contacts[i] = c.now;
        started[i] = c.now.caught > 0 && c.before.caught == 0;
        m.catches_now += c.now.catching;
        m.catches_now_by[pop.species[i]] += c.now.catching;
        m.episode.rewards[pop.species[i]] += reward.0;
    }
    let labels: Vec<Vec<u32>> = (0..n_species)
        .map(|s| {
            let link = scene.0.cluster_link * 2.0 * registry.defs[s].radius;
            collective::cluster_labels(&arena, &pop.position, &pop.grids[s], pop.ranges[s].clone(), link)
        })
        .collect();
    m.nn_distances_now.resize(n_species, Vec::new());
    // Refilled in place (as the population's vectors are, sim::perception::index_population).
    m.now.clear();
    m.now.extend((0..n_species).map(|s| {
        let out = &mut m.nn_distances_now[s];
        swarming(
            &arena,
            &pop.position,
            &pop.heading,
            &pop.grids[s],
            pop.ranges[s].clone(),
            &pop.nearest_kin,
            &labels[s],
            out,
        )
    }));
    // Marginal predation: where in its group each newly caught prey was.
    m.edge_ranks_now.resize(n_species, Vec::new());
    for (s, ranks) in m.edge_ranks_now.iter_mut().enumerate() {
        ranks.clear();
        let range = pop.ranges[s].clone();
        for j in range.clone().filter(|&j| started[j]) {
            let label = labels[s][j - range.start];
            let group: Vec<usize> = range.clone().filter(|&i| labels[s][i - range.start] == label).collect();
            ranks.extend(collective::edge_rank(&arena, &pop.position, &group, j));
        }
    }
    // Confusion: each predator's last decision against the prey it had in view when taking it.
    confusion.0.resize(n_species, Default::default());
    let in_view: Vec<u32> = (0..pop.len())
        .map(|i| {
            let s = pop.species[i];
            let radius = scene.0.confusion_radius.unwrap_or(registry.perception_radius[s]);
            let mut n = 0;
            for t in registry.prey_of(s) {
                pop.grids[t].for_each_near(pop.position[i], radius, |_, x| {
                    n += (arena.delta(pop.position[i], x).length() <= radius) as u32
                });
            }
            n
        })
        .collect();
    if m.in_view.len() == pop.len() {
        for (i, &n) in m.in_view.iter().enumerate() {
            let s = pop.species[i];
            if registry.prey_of(s).next().is_some() {
                let speed = pop.velocity[i].length() / registry.defs[s].max_speed;
                confusion.0[s][collective::confusion_bin(n)].add(pop.turn[i], speed, contacts[i].catching);
            }
        }
    }
    m.in_view.clear();
    m.in_view.extend_from_slice(&in_view);
    // The episode's running sums.
    let e = &mut m.episode;
    e.swarming.resize(n_species, [0.0; Swarming::N]);
    e.edge_ranks.resize(n_species, (0.0, 0));
    e.agents.clear();
    e.agents.extend((0..n_species).map(|s| pop.count(s)));
    for (sum, now) in e.swarming.iter_mut().zip(&m.now) {
        if let Some(now) = now {
            sum.iter_mut().zip(now.values()).for_each(|(a, v)| *a += v);
        }
    }
    for (sum, ranks) in e.edge_ranks.iter_mut().zip(&m.edge_ranks_now) {
        sum.0 += ranks.iter().sum::<f64>();
        sum.1 += ranks.len() as u64;
    }
    e.catches += m.catches_now as u64;
    e.catches_by.resize(n_species, 0);
    e.catches_by.iter_mut().zip(&m.catches_now_by).for_each(|(a, &b)| *a += b as u64);
    e.steps += 1;
}

/// The paper's running-mean window, in episodes (its learning curves are 100-episode running means).
pub(crate) const WINDOW: usize = 100;

/// Uniform random positions, `n` of them in the arena, through the DoS formula (Eq. 2): the DoS a
/// population has without any cohesion, at that density (a Monte Carlo estimate, fixed seed).
pub fn random_dos(arena: &crate::sim::space::Arena, n: usize) -> Option<f64> {
    use rand::{Rng, SeedableRng};
    if n < 2 {
        return None;
    }
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(0);
    let (samples, half) = (400, arena.half());
    let mut sum = 0.0;
    for _ in 0..samples {
        let x: Vec<bevy::math::DVec2> =
            (0..n).map(|_| bevy::math::DVec2::new(rng.gen_range(-half..half), rng.gen_range(-half..half))).collect();
        for (i, a) in x.iter().enumerate() {
            let nearest = x.iter().enumerate().filter(|(j, _)| *j != i).map(|(_, b)| arena.delta(*a, *b).length());
            sum += nearest.fold(f64::INFINITY, f64::min);
        }
    }
    Some(sum / (samples * n) as f64 / arena.max_distance())
}

/// Uniform random positions in the arena and independent uniform headings, `n` agents, through the
/// authors' formulas ([`authors_dos_doa`]): their DoS and DoA of a population without any order (a Monte
/// Carlo estimate, fixed seed), the chance level a claim on them is told apart from. The most opposed
/// partner puts the code's DoA of random headings at 0.154 for 10 agents, not the paper's 2/π.
pub(crate) fn random_authors(edge: f64, n: usize) -> Option<[f64; 2]> {
    use rand::{Rng, SeedableRng};
    if n < 2 {
        return None;
    }
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(0);
    let (samples, half) = (2000, edge / 2.0);
    let mut sum = [0.0; 2];
    for _ in 0..samples {
        let x: Vec<DVec2> =
            (0..n).map(|_| DVec2::new(rng.gen_range(-half..half), rng.gen_range(-half..half))).collect();
        let h: Vec<DVec2> =
            (0..n).map(|_| DVec2::from_angle(rng.gen_range(-std::f64::consts::PI..std::f64::consts::PI))).collect();
        let [dos, doa] = authors_dos_doa(edge, &x, &h)?;
        sum[0] += dos;
        sum[1] += doa;
    }
    Some(sum.map(|s| s / samples as f64))
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
            let pos: Vec<DVec2> =
                (0..50).map(|_| DVec2::new(rng.gen_range(-1.0..1.0), rng.gen_range(-1.0..1.0))).collect();
            let head: Vec<DVec2> = (0..50)
                .map(|_| DVec2::from_angle(rng.gen_range(-std::f64::consts::PI..std::f64::consts::PI)))
                .collect();
            total += swarming_of(&arena, &pos, &head, 0.1).unwrap().doa;
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
        let pos: Vec<DVec2> = (0..24)
            .map(|i| arena.wrap(centre + 0.3 * DVec2::from_angle(i as f64 * std::f64::consts::TAU / 24.0)))
            .collect();
        let tangent: Vec<DVec2> = (0..24)
            .map(|i| DVec2::from_angle(i as f64 * std::f64::consts::TAU / 24.0 + std::f64::consts::FRAC_PI_2))
            .collect();
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
            let pos: Vec<DVec2> =
                (0..n).map(|_| DVec2::new(rng.gen_range(-1.0..1.0), rng.gen_range(-1.0..1.0))).collect();
            let head: Vec<DVec2> = (0..n).map(|_| DVec2::from_angle(rng.gen_range(-3.15..3.15))).collect();
            total += polarization_and_milling(&Arena { edge: 2.0, boundary: Boundary::Walls }, &pos, &head).0;
        }
        // E‖mean of N unit vectors‖ = √(π/(4N)) for large N.
        let expected = (std::f64::consts::PI / (4.0 * n as f64)).sqrt();
        assert!((total / samples as f64 - expected).abs() < 0.1 * expected, "{} vs {expected}", total / samples as f64);
        // The per-instant measure reports both.
        let s = swarming_of(&arena, &pos, &tangent, 0.1).unwrap();
        assert!(s.polarization < 1e-9 && (s.milling - 1.0).abs() < 1e-9);
    }

    #[test]
    fn aligned_agents_have_doa_one() {
        let arena = Arena { edge: 2.0, boundary: Boundary::Walls };
        let pos = [DVec2::new(0.0, 0.0), DVec2::new(0.3, 0.1), DVec2::new(-0.5, 0.7)];
        let head = [DVec2::from_angle(0.7); 3];
        assert!((swarming_of(&arena, &pos, &head, 0.1).unwrap().doa - 1.0).abs() < 1e-12);
    }

    #[test]
    fn dos_of_a_known_configuration() {
        // Torus of edge 2: agents at x = ±0.95 are 0.1 apart across the seam; the third is 0.5 from the
        // nearest. Nearest distances 0.1, 0.1, 0.5 → DoS = 0.7 / (3·√2).
        let arena = Arena { edge: 2.0, boundary: Boundary::Periodic };
        let pos = [DVec2::new(0.95, 0.0), DVec2::new(-0.95, 0.0), DVec2::new(-0.45, 0.0)];
        let head = [DVec2::X, DVec2::Y, -DVec2::X];
        let s = swarming_of(&arena, &pos, &head, 0.1).unwrap();
        assert!((s.dos - 0.7 / (3.0 * 2f64.sqrt())).abs() < 1e-12, "{}", s.dos);
        // Pairs: (X,Y) → √2, (Y,X) → √2, (−X, Y) → √2: DoA = 3·√2 / 6.
        assert!((s.doa - 2f64.sqrt() / 2.0).abs() < 1e-12, "{}", s.doa);
        assert!(swarming_of(&arena, &pos[..1], &head[..1], 0.1).is_none());
    }

    #[test]
    fn the_authors_dos_and_doa_of_a_known_configuration_and_their_random_levels() {
        // The same agents as above, by the authors' code: plain Euclidean distances (1.9 across the seam
        // instead of 0.1), so nearest distances 1.4, 0.5, 0.5 → DoS = 2.4 / (3·√2); DoA's partner is the
        // most opposed heading: X with −X (0), Y with either (√2), −X with X (0) → √2 / 6.
        let pos = [DVec2::new(0.95, 0.0), DVec2::new(-0.95, 0.0), DVec2::new(-0.45, 0.0)];
        let head = [DVec2::X, DVec2::Y, -DVec2::X];
        let [dos, doa] = authors_dos_doa(2.0, &pos, &head).unwrap();
        assert!((dos - 2.4 / (3.0 * 2f64.sqrt())).abs() < 1e-12, "{dos}");
        assert!((doa - 2f64.sqrt() / 6.0).abs() < 1e-12, "{doa}");
        assert!(authors_dos_doa(2.0, &pos[..1], &head[..1]).is_none());
        // Independent random headings: the most opposed partner makes the level fall with n (docs/src/results/authors-code.md: 0.154
        // at 10 prey, 0.031 at 50), where the paper's DoA stays at 2/π.
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        for (n, level) in [(10, 0.154), (50, 0.031)] {
            let draws = 4000 / n * 10;
            let mean = (0..draws)
                .map(|_| {
                    let h: Vec<DVec2> = (0..n)
                        .map(|_| DVec2::from_angle(rng.gen_range(-std::f64::consts::PI..std::f64::consts::PI)))
                        .collect();
                    authors_dos_doa(2.0, &vec![DVec2::ZERO; n], &h).unwrap()[1]
                })
                .sum::<f64>()
                / draws as f64;
            assert!((mean - level).abs() < 0.004, "n = {n}: {mean}");
            // The chance level claims are judged against is the same number.
            let chance = random_authors(2.0, n).unwrap()[1];
            assert!((chance - level).abs() < 0.004, "n = {n}: chance {chance}");
        }
        // Positions are plain Euclidean in the 2 m box: the code's DoS of 10 uniform agents (its √2 over 2
        // of the edge is D) lies above the paper's minimum-image 0.226, since no distance wraps.
        let dos = random_authors(2.0, 10).unwrap()[0];
        let wrapped = random_dos(&crate::sim::space::Arena { edge: 2.0, boundary: Boundary::Periodic }, 10).unwrap();
        assert!(dos > wrapped && dos < 0.4, "{dos} against {wrapped}");
        assert!(random_authors(2.0, 1).is_none());
    }
}
