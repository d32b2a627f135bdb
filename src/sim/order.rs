//! The order of one group at one instant ([`Swarming`]): the paper's DoS and DoA and the order
//! parameters of collective motion beside them (polarization, milling, clusters, C_nn), computed from
//! positions and headings alone. [`super::metrics`] measures them every step and sums them per episode.

use crate::sim::collective;
use crate::sim::space::{Arena, CellGrid};
use bevy::math::DVec2;

/// The one definition of the order parameters: each line a field of [`Swarming`], in column order, with
/// the label report tables give it and the digits they show. `metrics.csv`, the evaluations' CSVs,
/// experiment summaries, claims (`EvalOrder`), report tables and figures take their columns from
/// [`Swarming::NAMES`], [`Swarming::LABELS`] and [`Swarming::DIGITS`]: adding a line here (and computing
/// it in [`swarming`]) adds the order parameter everywhere.
macro_rules! order_parameters {
    ($(#[$sdoc:meta])* pub struct Swarming {
        $($(#[$doc:meta])* $field:ident : $label:literal, $digits:literal;)*
    }) => {
        $(#[$sdoc])*
        #[derive(Clone, Copy, Debug, PartialEq, Default)]
        pub struct Swarming {
            $($(#[$doc])* pub $field: f64,)*
        }

        impl Swarming {
            /// How many there are.
            pub const N: usize = [$(stringify!($field)),*].len();
            /// Column names, in the order of [`Swarming::values`] (CSV headers append `_<species>`).
            pub const NAMES: [&'static str; Self::N] = [$(stringify!($field)),*];
            /// How report tables head each column.
            pub(crate) const LABELS: [&'static str; Self::N] = [$($label),*];
            /// Digits report tables show of each.
            pub(crate) const DIGITS: [usize; Self::N] = [$($digits),*];

            pub fn values(&self) -> [f64; Self::N] {
                [$(self.$field),*]
            }

            pub(crate) fn from_values(v: [f64; Self::N]) -> Self {
                let [$($field),*] = v;
                Swarming { $($field),* }
            }
        }
    };
}

order_parameters! {
    /// The order of one group at one instant: the paper's DoS and DoA, and order parameters of collective
    /// motion that tell a flock from a mill and from agents that merely share a heading (not in the paper):
    ///
    /// ```text
    ///   polarization P = ‖(1/N) Σ_j h_j‖                        1 = all aligned, ~1/√N for random headings
    ///   milling      M = |(1/N) Σ_j (r̂_j × h_j)_z|,  r_j = x_j − c    1 = a perfect mill, ~0 for a flock
    ///   clusters, largest_cluster (a fraction of N), nn_correlation C_nn: see crate::sim::collective
    /// ```
    ///
    /// c is the group's centre: the mean position with walls, and on the torus the circular mean per axis
    /// (each coordinate mapped to an angle on its periodic axis, the angles averaged as unit vectors, mapped
    /// back), with r_j the minimum image of x_j − c. Swirling shows as M high with P low.
    pub struct Swarming {
        /// Degree of sparsity (per step; the paper's DoS).
        dos: "DoS", 3;
        /// Degree of alignment (per step; the paper's DoA).
        doa: "DoA", 3;
        polarization: "polarization", 2;
        milling: "milling", 2;
        /// Number of single-linkage clusters.
        clusters: "clusters", 1;
        /// Size of the largest cluster over N.
        largest_cluster: "largest", 2;
        /// Connected correlation of heading fluctuations between nearest neighbours.
        nn_correlation: "C_nn", 2;
    }
}

/// The group's centre c (see [`Swarming`]).
pub fn centre(arena: &Arena, positions: &[DVec2]) -> DVec2 {
    centre_of(arena, positions, positions.iter().map(|&p| circular_terms(arena, p)))
}

/// One position's terms of the circular mean on the torus: the sine and cosine of each coordinate's
/// angle on its periodic axis, `[sin x, cos x, sin y, cos y]`.
fn circular_terms(arena: &Arena, p: DVec2) -> [f64; 4] {
    let turn = std::f64::consts::TAU / arena.edge;
    let (x, y) = (p.x * turn, p.y * turn);
    [x.sin(), x.cos(), y.sin(), y.cos()]
}

/// [`centre`] given each position's [`circular_terms`] (read only on the torus), summed in order.
fn centre_of(arena: &Arena, positions: &[DVec2], terms: impl Iterator<Item = [f64; 4]>) -> DVec2 {
    match arena.boundary {
        crate::scene::Boundary::Walls => positions.iter().copied().sum::<DVec2>() / positions.len().max(1) as f64,
        crate::scene::Boundary::Periodic => {
            let turn = std::f64::consts::TAU / arena.edge;
            let [sx, cx, sy, cy] = terms.fold([0.0; 4], |sum, t| std::array::from_fn(|a| sum[a] + t[a]));
            DVec2::new(sx.atan2(cx) / turn, sy.atan2(cy) / turn)
        }
    }
}

/// Polarization and milling of a group of positions and unit headings (see [`Swarming`]).
pub fn polarization_and_milling(arena: &Arena, positions: &[DVec2], headings: &[DVec2]) -> (f64, f64) {
    order_about(arena, centre(arena, positions), positions, headings)
}

/// Polarization and milling about the centre `c`.
fn order_about(arena: &Arena, c: DVec2, positions: &[DVec2], headings: &[DVec2]) -> (f64, f64) {
    let n = positions.len().max(1) as f64;
    let polarization = headings.iter().copied().sum::<DVec2>().length() / n;
    let rotation: f64 = positions
        .iter()
        .zip(headings)
        .map(|(&x, h)| {
            let r = arena.delta(c, x);
            let d = r.length();
            if d > 0.0 {
                (r.x * h.y - r.y * h.x) / d
            } else {
                0.0
            }
        })
        .sum();
    (polarization, (rotation / n).abs())
}

/// The order of the agents `members` of a population at one instant, using `grid` (built over
/// `members`) for the nearest-neighbour search, or `known_nearest[j]` where perception already found
/// j's nearest kin, and their cluster `labels` ([`collective::cluster_labels`]); `nn_distances` gets each
/// member's nearest-neighbour distance in metres. None with fewer than two agents.
// The measure system already holds each of these per species; a struct around them would only be unpacked.
#[allow(clippy::too_many_arguments)]
pub fn swarming(
    arena: &Arena,
    positions: &[DVec2],
    headings: &[DVec2],
    grid: &CellGrid,
    members: std::ops::Range<usize>,
    known_nearest: &[Option<u32>],
    labels: &[u32],
    nn_distances: &mut Vec<f64>,
) -> Option<Swarming> {
    let n = members.len();
    nn_distances.clear();
    if n < 2 {
        return None;
    }
    let start = members.start;
    // Each member alone (on all cores for large groups): its nearest kin k, ‖x_j − x_k‖, ‖h_j + h_k‖
    // and its terms of the circular mean, the dearest part (sines and cosines). Then everything is
    // summed in member order, so no sum depends on the split or the thread count.
    let periodic = arena.boundary == crate::scene::Boundary::Periodic;
    let terms = crate::parallel::map_ranges(n, |r| {
        let mut found = Vec::with_capacity(1);
        r.map(|m| {
            let j = start + m;
            let k = match known_nearest.get(j).copied().flatten() {
                Some(k) => k as usize,
                None => {
                    grid.k_nearest(arena, positions[j], 1, f64::INFINITY, j as u32, &mut found);
                    found[0].1 as usize
                }
            };
            let d = arena.delta(positions[j], positions[k]).length();
            let circular = if periodic { circular_terms(arena, positions[j]) } else { [0.0; 4] };
            (d, (headings[j] + headings[k]).length(), k - start, circular)
        })
        .collect::<Vec<_>>()
    });
    let terms = || terms.iter().flatten();
    let (mut distance, mut alignment) = (0.0, 0.0);
    let mut nearest = Vec::with_capacity(n);
    for &(d, a, k, _) in terms() {
        nn_distances.push(d);
        distance += d;
        alignment += a;
        nearest.push(k);
    }
    let (positions, headings) = (&positions[members.clone()], &headings[members.clone()]);
    let c = centre_of(arena, positions, terms().map(|t| t.3));
    let (polarization, milling) = order_about(arena, c, positions, headings);
    let sizes = collective::cluster_sizes(labels);
    Some(Swarming {
        dos: distance / (n as f64 * arena.max_distance()),
        doa: alignment / (2.0 * n as f64),
        polarization,
        milling,
        clusters: sizes.len() as f64,
        largest_cluster: sizes.iter().copied().max().unwrap_or(0) as f64 / n as f64,
        nn_correlation: collective::nn_correlation(headings, &nearest),
    })
}

/// Convenience for callers without a grid: the order of a whole set of positions and unit headings,
/// clusters linked within `link` metres.
pub fn swarming_of(arena: &Arena, positions: &[DVec2], headings: &[DVec2], link: f64) -> Option<Swarming> {
    let mut grid = CellGrid::default();
    grid.rebuild(arena, positions, 0..positions.len());
    let labels = collective::cluster_labels(arena, positions, &grid, 0..positions.len(), link);
    swarming(arena, positions, headings, &grid, 0..positions.len(), &[], &labels, &mut Vec::new())
}
