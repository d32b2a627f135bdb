//! Measures of collective behaviour the paper shows only as pictures and words (not in the paper):
//! group structure, the local order a shared heading attractor cannot fake, marginal predation and the
//! confusion effect. Pure functions of one instant; [`crate::sim::metrics`] applies them every step.
//!
//! ```text
//!   clusters        groups of agents linked by chains of neighbours closer than ℓ (single linkage),
//!                   ℓ = cluster_link · 2·radius (the scene's `cluster_link`, default 2 body diameters)
//!   nn correlation  C_nn = Σ_j δh_j·δh_k(j) / Σ_j |δh_j|²,   δh_j = h_j − (1/N) Σ_i h_i,  k(j) = j's nearest
//!                   the connected correlation of heading fluctuations at nearest-neighbour distance:
//!                   0 when each agent's deviation from the mean heading ignores its neighbour's (as for
//!                   agents steered to one absolute heading without interaction), 1 when neighbours
//!                   deviate together (Cavagna et al., PNAS 2010, at the first shell)
//!   edge rank       for a caught prey in a group of n ≥ 3: the number of the group's other members
//!                   nearer the group's centre than it, ties counting ½, over n − 1. 0 = caught at the
//!                   centre, 1 = at the edge; its mean over catches is 0.5 without marginal predation
//! ```

use crate::scene::Boundary;
use crate::sim::space::{Arena, CellGrid};
use bevy::math::DVec2;
use std::ops::Range;

/// Single-linkage clusters of `members` (indices into `positions`, the members of `grid`): the cluster
/// label of each member, in member order, labels 0..k numbered by first appearance.
pub(crate) fn cluster_labels(
    arena: &Arena,
    positions: &[DVec2],
    grid: &CellGrid,
    members: Range<usize>,
    link: f64,
) -> Vec<u32> {
    let start = members.start;
    let mut parent: Vec<u32> = (0..members.len() as u32).collect();
    fn root(parent: &mut [u32], mut i: u32) -> u32 {
        while parent[i as usize] != i {
            parent[i as usize] = parent[parent[i as usize] as usize];
            i = parent[i as usize];
        }
        i
    }
    let link2 = link * link;
    // The linked pairs (j, i > j), searched on all cores for large groups, then joined; the labels depend
    // only on which members end up connected, never on the order of the joins.
    let pairs = crate::parallel::map_ranges(members.len(), |r| {
        let mut pairs = Vec::new();
        for (j, &xj) in positions.iter().enumerate().take(r.end + start).skip(r.start + start) {
            grid.for_each_near(xj, link, |i, x| {
                let i = i as usize;
                if i > j && arena.delta(xj, x).length_squared() <= link2 {
                    pairs.push(((j - start) as u32, (i - start) as u32));
                }
            });
        }
        pairs
    });
    for &(j, i) in pairs.iter().flatten() {
        let (a, b) = (root(&mut parent, j), root(&mut parent, i));
        parent[a.max(b) as usize] = a.min(b);
    }
    let mut label = vec![u32::MAX; members.len()];
    let mut next = 0;
    (0..members.len())
        .map(|m| {
            let r = root(&mut parent, m as u32) as usize;
            if label[r] == u32::MAX {
                label[r] = next;
                next += 1;
            }
            label[r]
        })
        .collect()
}

/// Sizes of the clusters of [`cluster_labels`], by label.
pub(crate) fn cluster_sizes(labels: &[u32]) -> Vec<usize> {
    let mut sizes = vec![0; labels.iter().map(|&l| l as usize + 1).max().unwrap_or(0)];
    labels.iter().for_each(|&l| sizes[l as usize] += 1);
    sizes
}

/// C_nn of unit `headings` given each one's nearest neighbour `nearest[j]` (an index into `headings`).
/// 0 when the headings do not fluctuate at all (a perfectly polarized group has nothing to correlate).
pub(crate) fn nn_correlation(headings: &[DVec2], nearest: &[usize]) -> f64 {
    let n = headings.len().max(1) as f64;
    let mean = headings.iter().copied().sum::<DVec2>() / n;
    let variance: f64 = headings.iter().map(|h| (*h - mean).length_squared()).sum();
    if variance <= 1e-12 * n {
        0.0
    } else {
        let covariance: f64 = headings.iter().zip(nearest).map(|(h, &k)| (*h - mean).dot(headings[k] - mean)).sum();
        covariance / variance
    }
}

/// Adds one instant to the spatial correlation function of heading fluctuations (Cavagna et al., PNAS
/// 2010): for every pair (i, j) at minimum-image distance r in bin ⌊r / width⌋, `bins[b]` collects
/// Σ δh_i·δh_j and the pair count; `variance` collects Σ_j |δh_j|² and the agents, to normalize:
/// C(r) = (Σ_pairs δh_i·δh_j / pairs) / (Σ |δh|² / N). Pairs beyond the last bin are left out.
pub(crate) fn add_heading_correlation(
    arena: &Arena,
    positions: &[DVec2],
    headings: &[DVec2],
    width: f64,
    bins: &mut [(f64, u64)],
    variance: &mut (f64, u64),
) {
    let n = headings.len();
    if n < 2 {
        return;
    }
    let mean = headings.iter().copied().sum::<DVec2>() / n as f64;
    let delta: Vec<DVec2> = headings.iter().map(|h| *h - mean).collect();
    variance.0 += delta.iter().map(|d| d.length_squared()).sum::<f64>();
    variance.1 += n as u64;
    let pairs = Pairs::new(arena, positions, &delta, width);
    // Large groups compute their terms on another core while this one adds them up.
    let pipelined = n * (n - 1) / 2 > 4 * PIPELINE_BATCH && crate::parallel::threads() > 1;
    pairs.add_to(bins, pipelined);
}

/// Pairs' terms are computed a block of one agent's pairs at a time.
const BLOCK: usize = 512;
/// Pairs per batch handed from the computing core to the adding one.
const PIPELINE_BATCH: usize = 1 << 17;

/// The bins and products of consecutive pairs in (i, j) order.
#[derive(Default)]
struct Batch {
    bin_of: Vec<u32>,
    product: Vec<f64>,
}

impl Batch {
    /// Adds the batch's products to `bins`, in order (pairs beyond the last bin are left out).
    fn add_to(&self, bins: &mut [(f64, u64)]) {
        for (&b, &p) in self.bin_of.iter().zip(&self.product) {
            if let Some(bin) = bins.get_mut(b as usize) {
                bin.0 += p;
                bin.1 += 1;
            }
        }
    }
}

/// The terms of [`add_heading_correlation`]'s pairs: positions x and heading fluctuations δh.
struct Pairs<'a> {
    arena: Arena,
    width: f64,
    x: &'a [DVec2],
    dh: &'a [DVec2],
}

impl<'a> Pairs<'a> {
    fn new(arena: &Arena, x: &'a [DVec2], dh: &'a [DVec2], width: f64) -> Self {
        Pairs { arena: *arena, width, x, dh }
    }

    /// Adds every pair (i, j > i) to `bins`, in (i, j) order, the order that fixes every sum's rounding:
    /// the terms a block at a time in a loop without branches that vectorizes, then added. `pipelined`:
    /// the terms computed on another thread, batch by batch, while this one adds them (the same order).
    fn add_to(&self, bins: &mut [(f64, u64)], pipelined: bool) {
        let mut at = (0, 1);
        if !pipelined {
            let mut batch = Batch::default();
            while self.fill(&mut at, &mut batch, BLOCK) {
                batch.add_to(bins);
            }
            return;
        }
        let (full, filled) = std::sync::mpsc::sync_channel::<Batch>(2);
        let (empty, emptied) = std::sync::mpsc::channel::<Batch>();
        let pipelined = std::thread::scope(|scope| {
            let started = std::thread::Builder::new().spawn_scoped(scope, move || loop {
                let mut batch = emptied.try_recv().unwrap_or_default();
                if !self.fill(&mut at, &mut batch, PIPELINE_BATCH) || full.send(batch).is_err() {
                    return;
                }
            });
            if started.is_err() {
                return false;
            }
            for batch in filled {
                batch.add_to(bins);
                let _ = empty.send(batch); // for reuse; the computing thread may have finished
            }
            true
        });
        // A thread the system refuses (a process limit): the same terms, in the same order, on this one.
        if !pipelined {
            self.add_to(bins, false);
        }
    }

    /// Replaces `batch` with the terms of the pairs from `at` = (i, first j) on, in (i, j) order, whole
    /// blocks up to `capacity` pairs; moves `at` past them. False when no pair is left.
    fn fill(&self, at: &mut (usize, usize), batch: &mut Batch, capacity: usize) -> bool {
        let n = self.x.len();
        batch.bin_of.clear();
        batch.product.clear();
        while at.0 < n && batch.bin_of.len() + BLOCK <= capacity {
            let (i, from) = *at;
            if from >= n {
                *at = (i + 1, i + 2);
                continue;
            }
            let (len, to) = (batch.bin_of.len(), (from + BLOCK).min(n));
            batch.bin_of.resize(len + to - from, 0);
            batch.product.resize(len + to - from, 0.0);
            self.terms(i, from, &mut batch.bin_of[len..], &mut batch.product[len..]);
            at.1 = to;
        }
        !batch.bin_of.is_empty()
    }

    /// For agent i and the agents from `from` on, one per slot of `bin_of`: the bin ⌊‖x_j − x_i‖ / width⌋
    /// (saturating, so beyond every bin when huge) and δh_i·δh_j, on AVX-512 where the CPU has it.
    fn terms(&self, i: usize, from: usize, bin_of: &mut [u32], product: &mut [f64]) {
        #[cfg(target_arch = "x86_64")]
        {
            #[target_feature(enable = "avx512f,avx512vl")]
            fn wide(p: &Pairs, i: usize, from: usize, bin_of: &mut [u32], product: &mut [f64]) {
                p.terms_portable(i, from, bin_of, product)
            }
            if crate::sim::space::has_avx512() {
                // SAFETY: the features were detected on this CPU.
                return unsafe { wide(self, i, from, bin_of, product) };
            }
        }
        self.terms_portable(i, from, bin_of, product)
    }

    /// [`Pairs::terms`] as `Arena::delta`, `length` and `dot` compute them: IEEE operations, so the same
    /// bits at any vector width; the boundary decided once per block, so that the loop vectorizes.
    #[inline(always)]
    fn terms_portable(&self, i: usize, from: usize, bin_of: &mut [u32], product: &mut [f64]) {
        let (periodic, edge) = (self.arena.boundary == Boundary::Periodic, self.arena.edge);
        let image = |d: f64| if periodic { crate::sim::space::min_image(d, edge) } else { d };
        let (xi, di) = (self.x[i], self.dh[i]);
        let others = self.x[from..].iter().zip(&self.dh[from..]);
        for ((b, p), (x, d)) in bin_of.iter_mut().zip(product.iter_mut()).zip(others) {
            let (dx, dy) = (image(x.x - xi.x), image(x.y - xi.y));
            *b = ((dx * dx + dy * dy).sqrt() / self.width) as u32;
            *p = di.x * d.x + di.y * d.y;
        }
    }
}

/// C(r) per bin from [`add_heading_correlation`]'s sums (None for empty bins or no fluctuation), and
/// the correlation length: the r where C first crosses zero, interpolated between bin centres (None if
/// it stays positive).
pub(crate) fn heading_correlation(
    bins: &[(f64, u64)],
    variance: (f64, u64),
    width: f64,
) -> (Vec<Option<f64>>, Option<f64>) {
    let v = if variance.1 > 0 { variance.0 / variance.1 as f64 } else { 0.0 };
    let c: Vec<Option<f64>> = bins.iter().map(|&(sum, n)| (n > 0 && v > 1e-12).then(|| sum / n as f64 / v)).collect();
    let centre = |b: usize| (b as f64 + 0.5) * width;
    let mut last: Option<(f64, f64)> = None;
    for (b, value) in c.iter().enumerate() {
        let Some(value) = *value else { continue };
        if value <= 0.0 {
            return (
                c.clone(),
                Some(match last {
                    Some((r0, c0)) => r0 + (centre(b) - r0) * c0 / (c0 - value),
                    None => centre(b),
                }),
            );
        }
        last = Some((centre(b), value));
    }
    (c, None)
}

/// The edge rank of agent `j` within `group` (indices into `positions`, j among them); None for groups
/// of fewer than three. The centre is the mean of the members' minimum-image offsets from j, so it is
/// well defined for a group straddling the torus seam.
pub(crate) fn edge_rank(arena: &Arena, positions: &[DVec2], group: &[usize], j: usize) -> Option<f64> {
    if group.len() < 3 {
        return None;
    }
    let offset = |i: usize| arena.delta(positions[j], positions[i]);
    let centre = group.iter().map(|&i| offset(i)).sum::<DVec2>() / group.len() as f64;
    let distance = |i: usize| (offset(i) - centre).length();
    let dj = distance(j);
    let nearer: f64 = group
        .iter()
        .filter(|&&i| i != j)
        .map(|&i| {
            let d = distance(i);
            if (d - dj).abs() <= 1e-12 {
                0.5
            } else if d < dj {
                1.0
            } else {
                0.0
            }
        })
        .sum();
    Some(nearer / (group.len() - 1) as f64)
}

/// The prey a predator at `at` could be going for among those within `radius` of it (the paper's
/// dispersion tactic: "they first move towards the center of a swarm to disperse it and then focus on
/// isolated ones", Discussion): the offsets from `at` to (0) the centre of those prey, (1) the most
/// isolated of them (the largest distance `nn[j]` to its nearest fellow prey; the first of equals), (2) the
/// nearest of them (the first of equals). The centre is the mean of their minimum-image offsets, so it is
/// well defined across the torus seam. None with fewer than three prey in view: with two, each is the
/// other's nearest and neither is more isolated.
pub(crate) fn pursuit_targets(arena: &Arena, at: DVec2, prey: &[DVec2], nn: &[f64], radius: f64) -> Option<[DVec2; 3]> {
    let mut in_view = 0usize;
    let mut sum = DVec2::ZERO;
    // (distance to its nearest fellow, offset) and (distance, offset) of the best so far.
    let mut isolated: Option<(f64, DVec2)> = None;
    let mut nearest: Option<(f64, DVec2)> = None;
    for (&x, &alone) in prey.iter().zip(nn) {
        let offset = arena.delta(at, x);
        let distance = offset.length();
        if distance > radius {
            continue;
        }
        in_view += 1;
        sum += offset;
        if isolated.is_none_or(|(best, _)| alone > best) {
            isolated = Some((alone, offset));
        }
        if nearest.is_none_or(|(best, _)| distance < best) {
            nearest = Some((distance, offset));
        }
    }
    match (in_view >= 3, isolated, nearest) {
        (true, Some((_, isolated)), Some((_, nearest))) => Some([sum / in_view as f64, isolated, nearest]),
        _ => None,
    }
}

/// Whether a `turn` command (positive: counter-clockwise) steers an agent heading `heading` toward a
/// target at `offset`: 1 when it turns to the target's side, −1 when it turns away, 0 without a turn or
/// with the target dead ahead or behind. Unlike the angle between heading and target, it reads the
/// decision itself, not a heading that a limited turn rate keeps lagging behind it.
pub(crate) fn steering(heading: DVec2, offset: DVec2, turn: f64) -> f64 {
    let side = heading.perp_dot(offset);
    if turn == 0.0 || side == 0.0 {
        0.0
    } else {
        turn.signum() * side.signum()
    }
}

/// The share of `positions` within `band` of a wall (the paper's boundary aggregation, Fig. 9(a)); None on
/// the torus, which has no wall. Uniform positions give [`boundary_share_uniform`].
pub(crate) fn boundary_share(arena: &Arena, positions: &[DVec2], band: f64) -> Option<f64> {
    (arena.boundary == Boundary::Walls && !positions.is_empty()).then(|| {
        let near = positions.iter().filter(|p| arena.half() - p.x.abs().max(p.y.abs()) < band).count();
        near as f64 / positions.len() as f64
    })
}

/// The share of a square arena's area within `band_of_edge` × its edge of a wall: what [`boundary_share`]
/// is for positions spread uniformly, the level without aggregation at the boundary.
pub(crate) fn boundary_share_uniform(band_of_edge: f64) -> f64 {
    1.0 - (1.0 - 2.0 * band_of_edge).max(0.0).powi(2)
}

/// Bins of "prey within the predator's perception radius" for the confusion curve: 0, 1, 2, 3–4, 5–8,
/// 9–16, 17–32, 33+ (doubling, so a few predators among thousands of prey still fill the upper bins).
pub(crate) const CONFUSION_BINS: [(u32, u32); 8] =
    [(0, 0), (1, 1), (2, 2), (3, 4), (5, 8), (9, 16), (17, 32), (33, u32::MAX)];

pub(crate) fn confusion_bin(prey_in_range: u32) -> usize {
    CONFUSION_BINS.iter().position(|&(lo, hi)| (lo..=hi).contains(&prey_in_range)).expect("bins cover u32")
}

pub(crate) fn confusion_bin_label(b: usize) -> String {
    match CONFUSION_BINS[b] {
        (lo, u32::MAX) => format!("{lo}+"),
        (lo, hi) if lo == hi => lo.to_string(),
        (lo, hi) => format!("{lo}-{hi}"),
    }
}

/// One bin of the confusion curve: predator decisions taken with this many prey in view, and what
/// followed (the turn command's magnitude, the speed reached, the catches made).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct ConfusionBin {
    pub(crate) samples: u64,
    /// Σ |turn command|, normalized to [0, 1] (1 = the species' max turn rate).
    pub(crate) turn: f64,
    /// Σ speed / max_speed.
    pub(crate) speed: f64,
    pub(crate) catches: u64,
}

impl ConfusionBin {
    pub(crate) fn add(&mut self, turn: f64, speed: f64, catches: u32) {
        self.samples += 1;
        self.turn += turn.abs();
        self.speed += speed;
        self.catches += catches as u64;
    }

    /// (mean |turn|, mean speed fraction, catches per predator-step); None when empty.
    pub(crate) fn means(&self) -> Option<(f64, f64, f64)> {
        (self.samples > 0).then(|| {
            let n = self.samples as f64;
            (self.turn / n, self.speed / n, self.catches as f64 / n)
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    fn grid(arena: &Arena, pos: &[DVec2]) -> CellGrid {
        let mut g = CellGrid::default();
        g.rebuild(arena, pos, 0..pos.len());
        g
    }

    #[test]
    fn clusters_link_chains_across_the_seam() {
        let arena = Arena { edge: 2.0, boundary: Boundary::Periodic };
        // A chain of three across the seam (steps of 0.08 < ℓ = 0.1), a pair, and a loner.
        let pos = [
            DVec2::new(0.96, 0.0),
            DVec2::new(-0.96, 0.0),
            DVec2::new(-0.88, 0.0),
            DVec2::new(0.0, 0.5),
            DVec2::new(0.05, 0.55),
            DVec2::new(0.5, -0.5),
        ];
        let labels = cluster_labels(&arena, &pos, &grid(&arena, &pos), 0..pos.len(), 0.1);
        assert_eq!(labels, vec![0, 0, 0, 1, 1, 2]);
        assert_eq!(cluster_sizes(&labels), vec![3, 2, 1]);
        // With walls the seam does not join them.
        let walls = Arena { edge: 2.0, boundary: Boundary::Walls };
        let labels = cluster_labels(&walls, &pos, &grid(&walls, &pos), 0..pos.len(), 0.1);
        assert_eq!(cluster_sizes(&labels), vec![1, 2, 2, 1]);
    }

    #[test]
    fn nn_correlation_tells_interaction_from_a_shared_attractor() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        // Pairs of nearest neighbours. Independent headings around a common mean: C_nn ≈ 0.
        let n = 20_000;
        let nearest: Vec<usize> = (0..n).map(|j| j ^ 1).collect();
        let independent: Vec<DVec2> = (0..n).map(|_| DVec2::from_angle(0.3 + rng.gen_range(-0.8..0.8))).collect();
        let c = nn_correlation(&independent, &nearest);
        assert!(c.abs() < 0.05, "{c}");
        // Each pair shares its deviation: C_nn = 1.
        let shared: Vec<DVec2> =
            (0..n / 2).map(|_| DVec2::from_angle(0.3 + rng.gen_range(-0.8..0.8))).flat_map(|h| [h, h]).collect();
        assert!((nn_correlation(&shared, &nearest) - 1.0).abs() < 1e-12);
        // Opposite deviations: C_nn = −1.
        let opposite: Vec<DVec2> = (0..n / 2)
            .map(|_| rng.gen_range(-0.8..0.8))
            .flat_map(|d: f64| [DVec2::from_angle(d), DVec2::from_angle(-d)])
            .collect();
        assert!(nn_correlation(&opposite, &nearest) < -0.9);
        // A perfect flock has no fluctuations to correlate.
        assert_eq!(nn_correlation(&[DVec2::X; 4], &[1, 0, 3, 2]), 0.0);
    }

    #[test]
    fn edge_rank_of_a_catch_at_the_edge_and_at_the_centre() {
        let arena = Arena { edge: 2.0, boundary: Boundary::Periodic };
        // A ring of 8 around a centre prey, the group straddling the seam.
        let c = DVec2::new(0.98, 0.2);
        let mut pos: Vec<DVec2> = (0..8).map(|i| arena.wrap(c + 0.1 * DVec2::from_angle(i as f64 * 0.785))).collect();
        pos.push(c);
        // One more farther out, on the edge.
        pos.push(arena.wrap(c + DVec2::new(0.0, 0.25)));
        let group: Vec<usize> = (0..pos.len()).collect();
        assert_eq!(edge_rank(&arena, &pos, &group, 9), Some(1.0));
        assert_eq!(edge_rank(&arena, &pos, &group, 8), Some(0.0));
        // A ring member: the centre prey is nearer, the far one is not, and the other seven tie with it.
        let r = edge_rank(&arena, &pos, &group, 0).unwrap();
        assert!(r > 0.1 && r < 0.9, "{r}");
        assert_eq!(edge_rank(&arena, &pos, &group[..2], 0), None);
        // Averaged over every member, ranks are 0.5: no edge effect when catches are random.
        let mean: f64 =
            group.iter().map(|&j| edge_rank(&arena, &pos, &group, j).unwrap()).sum::<f64>() / group.len() as f64;
        assert!((mean - 0.5).abs() < 1e-12, "{mean}");
    }

    #[test]
    fn heading_correlation_sums_every_pair_in_the_order_of_the_plain_double_loop() {
        // The blocked, vectorized sums against the plain double loop they replace, bit for bit: on the
        // torus (pairs across the seam) and within walls (bodies beyond them), more agents than a block,
        // and bins that stop short of the farthest pairs.
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(12);
        for boundary in [Boundary::Periodic, Boundary::Walls] {
            let arena = Arena { edge: 6.0, boundary };
            let pos: Vec<DVec2> =
                (0..1300).map(|_| DVec2::new(rng.gen_range(-3.2..3.2), rng.gen_range(-3.2..3.2))).collect();
            let head: Vec<DVec2> = (0..1300).map(|_| DVec2::from_angle(rng.gen_range(-3.1..3.1))).collect();
            let (mut bins, mut var) = (vec![(0.0, 0); 23], (0.0, 0));
            add_heading_correlation(&arena, &pos, &head, 0.17, &mut bins, &mut var);
            let mean = head.iter().copied().sum::<DVec2>() / head.len() as f64;
            // Both ways of adding them: on one thread, and computed on another.
            let delta: Vec<DVec2> = head.iter().map(|h| *h - mean).collect();
            let pairs = Pairs::new(&arena, &pos, &delta, 0.17);
            let both = [false, true].map(|pipelined| {
                let mut bins = vec![(0.0, 0); 23];
                pairs.add_to(&mut bins, pipelined);
                bins
            });
            let mut plain = vec![(0.0, 0); 23];
            for i in 0..pos.len() {
                for j in i + 1..pos.len() {
                    let b = (arena.delta(pos[i], pos[j]).length() / 0.17) as usize;
                    if let Some(bin) = plain.get_mut(b) {
                        bin.0 += (head[i] - mean).dot(head[j] - mean);
                        bin.1 += 1;
                    }
                }
            }
            for bins in [&bins, &both[0], &both[1]] {
                assert!(
                    bins.iter().zip(&plain).all(|(a, b)| a.0.to_bits() == b.0.to_bits() && a.1 == b.1),
                    "{boundary:?}"
                );
            }
            assert!(plain.iter().map(|b| b.1).sum::<u64>() < 1300 * 1299 / 2, "some pairs beyond the last bin");
            // This CPU's kernel against the portable loop, directly (the sums above used the former).
            let (mut b1, mut p1, mut b2, mut p2) = (vec![0; 1290], vec![0.0; 1290], vec![0; 1290], vec![0.0; 1290]);
            pairs.terms(3, 10, &mut b1, &mut p1);
            pairs.terms_portable(3, 10, &mut b2, &mut p2);
            assert!(b1 == b2 && p1.iter().zip(&p2).all(|(a, b)| a.to_bits() == b.to_bits()), "{boundary:?}");
        }
    }

    #[test]
    fn heading_correlation_of_a_vortex_crosses_zero_and_independent_headings_do_not_correlate() {
        let arena = Arena { edge: 20.0, boundary: Boundary::Walls };
        // Agents on a line, each heading turned by its position: neighbours deviate alike, distant ones
        // oppositely, so C(r) starts near 1 and crosses zero.
        let pos: Vec<DVec2> = (0..200).map(|i| DVec2::new(-5.0 + 0.05 * i as f64, 0.0)).collect();
        let head: Vec<DVec2> = pos.iter().map(|p| DVec2::from_angle(0.3 * p.x)).collect();
        let (mut bins, mut var) = (vec![(0.0, 0); 40], (0.0, 0));
        add_heading_correlation(&arena, &pos, &head, 0.25, &mut bins, &mut var);
        let (c, xi) = heading_correlation(&bins, var, 0.25);
        assert!(c[0].unwrap() > 0.9, "{:?}", c[0]);
        let xi = xi.expect("it crosses zero");
        assert!(xi > 1.0 && xi < 6.0, "ξ = {xi}");
        // Independent headings: C ≈ 0 at every distance.
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(9);
        let (mut bins, mut var) = (vec![(0.0, 0); 4], (0.0, 0));
        for _ in 0..50 {
            let pos: Vec<DVec2> =
                (0..100).map(|_| DVec2::new(rng.gen_range(-1.0..1.0), rng.gen_range(-1.0..1.0))).collect();
            let head: Vec<DVec2> = (0..100).map(|_| DVec2::from_angle(rng.gen_range(-3.1..3.1))).collect();
            add_heading_correlation(&arena, &pos, &head, 0.5, &mut bins, &mut var);
        }
        let (c, _) = heading_correlation(&bins, var, 0.5);
        assert!(c.iter().flatten().all(|v| v.abs() < 0.05), "{c:?}");
    }

    #[test]
    fn pursuit_targets_are_the_centre_the_most_isolated_and_the_nearest_in_view() {
        let arena = Arena { edge: 10.0, boundary: Boundary::Periodic };
        // Three prey in a tight group to the east, one isolated to the north; one far beyond view.
        let prey = [
            DVec2::new(2.0, 0.0),
            DVec2::new(2.1, 0.0),
            DVec2::new(2.0, 0.1),
            DVec2::new(0.0, 1.5),
            DVec2::new(-4.0, 0.0),
        ];
        let nn = [0.1, 0.1, 0.1, 2.0, 3.0];
        let [centre, isolated, nearest] = pursuit_targets(&arena, DVec2::ZERO, &prey, &nn, 2.5).unwrap();
        assert!((centre - DVec2::new(1.525, 0.4)).length() < 1e-12, "{centre}");
        assert_eq!((isolated, nearest), (DVec2::new(0.0, 1.5), DVec2::new(0.0, 1.5)));
        // Across the seam: a predator at x = 4.5 sees the group at x = 2 about 2.5 m west and the prey at
        // x = −4 1.5 m east, the short way round a 10 m torus; that one is the nearest and the most isolated.
        let [_, isolated, nearest] = pursuit_targets(&arena, DVec2::new(4.5, 0.0), &prey, &nn, 2.6).unwrap();
        assert!((isolated - DVec2::new(1.5, 0.0)).length() < 1e-12 && isolated == nearest, "{isolated} {nearest}");
        // Fewer than three in view: no reading.
        assert_eq!(pursuit_targets(&arena, DVec2::ZERO, &prey, &nn, 1.6), None);
    }

    #[test]
    fn steering_is_the_side_a_turn_takes_against_the_side_of_the_target() {
        let (east, north_east, south_east) = (DVec2::X, DVec2::new(1.0, 1.0), DVec2::new(1.0, -1.0));
        assert_eq!(steering(east, north_east, 0.3), 1.0, "a left turn toward a target on the left");
        assert_eq!(steering(east, south_east, 0.3), -1.0, "a left turn away from a target on the right");
        assert_eq!(steering(east, south_east, -1.0), 1.0);
        assert_eq!(steering(east, DVec2::new(2.0, 0.0), 0.5), 0.0, "dead ahead");
        assert_eq!(steering(east, north_east, 0.0), 0.0, "no turn");
    }

    #[test]
    fn boundary_share_of_uniform_positions_is_the_bands_area() {
        use rand::{Rng, SeedableRng};
        let arena = Arena { edge: 2.0, boundary: Boundary::Walls };
        let mut rng = rand::rngs::StdRng::seed_from_u64(7);
        let positions: Vec<DVec2> =
            (0..200_000).map(|_| DVec2::new(rng.gen_range(-1.0..1.0), rng.gen_range(-1.0..1.0))).collect();
        let share = boundary_share(&arena, &positions, 0.2).unwrap();
        assert!((boundary_share_uniform(0.1) - 0.36).abs() < 1e-12);
        assert!((share - 0.36).abs() < 0.005, "{share}");
        assert_eq!(boundary_share(&arena, &[DVec2::new(0.95, 0.0), DVec2::ZERO], 0.2), Some(0.5));
        assert_eq!(boundary_share(&Arena { edge: 2.0, boundary: Boundary::Periodic }, &positions, 0.2), None);
    }

    #[test]
    fn confusion_bins_cover_every_count() {
        assert_eq!(confusion_bin(0), 0);
        assert_eq!(confusion_bin(4), 3);
        assert_eq!(confusion_bin(9), 5);
        assert_eq!(confusion_bin(1_000_000), 7);
        assert_eq!(confusion_bin_label(3), "3-4");
        assert_eq!(confusion_bin_label(7), "33+");
        let mut b = ConfusionBin::default();
        assert_eq!(b.means(), None);
        b.add(-0.5, 0.8, 1);
        b.add(0.25, 0.4, 0);
        assert_eq!(b.means(), Some((0.375, 0.6000000000000001, 0.5)));
    }
}
