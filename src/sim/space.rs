//! Geometry of the arena (torus or walled box) and the cell grid that finds neighbours in ~O(1) per
//! query, so a step costs ~O(n) at fixed density instead of O(n²).

use crate::scene::{self, Boundary};
use bevy::math::DVec2;
use bevy::prelude::*;

/// The square arena centred on the origin.
#[derive(Resource, Clone, Copy, Debug, PartialEq)]
pub struct Arena {
    pub edge: f64,
    pub boundary: Boundary,
}

impl Arena {
    pub fn half(&self) -> f64 {
        self.edge / 2.0
    }

    /// D, the largest possible distance between two agents (definition of DoS).
    pub(crate) fn max_distance(&self) -> f64 {
        scene::max_distance(self.boundary, self.edge)
    }

    /// The displacement from `from` to `to`: the minimum image on the torus, plain difference with walls.
    pub fn delta(&self, from: DVec2, to: DVec2) -> DVec2 {
        let d = to - from;
        match self.boundary {
            Boundary::Walls => d,
            Boundary::Periodic => DVec2::new(min_image(d.x, self.edge), min_image(d.y, self.edge)),
        }
    }

    /// Periodic wrap (Appendix B): leaving one edge re-enters at the opposite one by the overshoot.
    /// Walls leave the position as it is (the wall force keeps bodies in).
    pub(crate) fn wrap(&self, p: DVec2) -> DVec2 {
        match self.boundary {
            Boundary::Walls => p,
            Boundary::Periodic => DVec2::new(wrap_coord(p.x, self.half()), wrap_coord(p.y, self.half())),
        }
    }

    /// Hooke force of every wall a body of `radius` at `x` penetrates, plus damping on the normal
    /// velocity component, and the number of walls touched. Zero on the torus.
    pub(crate) fn wall_contact(&self, x: DVec2, v: DVec2, radius: f64, stiffness: f64, damping: f64) -> (DVec2, u32) {
        if self.boundary == Boundary::Periodic {
            return (DVec2::ZERO, 0);
        }
        let h = self.half();
        let mut force = DVec2::ZERO;
        let mut touched = 0;
        for axis in 0..2 {
            // The low wall pushes +, the high wall pushes −.
            for (penetration, inward) in [(radius - (x[axis] + h), 1.0), (x[axis] + radius - h, -1.0)] {
                if penetration > 0.0 {
                    force[axis] += inward * stiffness * penetration - damping * v[axis];
                    touched += 1;
                }
            }
        }
        (force, touched)
    }
}

/// The shortest signed displacement along one periodic axis of length `edge`.
///
/// The three candidates are all computed and one is selected by bit masks: which one applies follows the
/// data (about half of the pairs on a small torus cross its seam), and a branch there would be
/// mispredicted once per pair; the value is the same either way.
#[inline]
pub fn min_image(d: f64, edge: f64) -> f64 {
    let half = edge / 2.0;
    let select = |take: bool, a: f64, b: f64| {
        let mask = (take as u64).wrapping_neg();
        f64::from_bits((a.to_bits() & mask) | (b.to_bits() & !mask))
    };
    select(d > half, d - edge, select(d < -half, d + edge, d))
}

/// Wraps one coordinate into [−half, half) by the overshoot. One step never moves more than an edge.
pub(crate) fn wrap_coord(x: f64, half: f64) -> f64 {
    if x >= half {
        x - 2.0 * half
    } else if x < -half {
        x + 2.0 * half
    } else {
        x
    }
}

/// A uniform grid over the arena holding indices of one species' agents, rebuilt every step by a
/// counting sort (no allocation once warm). Cells are sized for ~2 agents each, so a k-nearest query
/// visits a handful of cells; with few agents it degenerates to a scan of all of them.
#[derive(Clone, Debug, Default)]
pub struct CellGrid {
    cells_per_side: usize,
    cell: f64,
    half: f64,
    periodic: bool,
    /// `start[c]..start[c + 1]` indexes `items` for cell c.
    start: Vec<u32>,
    items: Vec<u32>,
    /// `positions[items[i]]`, so a cell's candidates are read from contiguous memory.
    item_positions: Vec<DVec2>,
}

/// Grids with at most this many cells per side are scanned whole (a ring search would revisit cells).
const SCAN_ALL_BELOW: usize = 4;
/// Ring cells sorted by distance before visiting (rings 1–3 fit).
const SORTED_RING_CELLS: usize = 24;

impl CellGrid {
    /// Rebuilds the grid over `members`, which index `positions`.
    pub(crate) fn rebuild(&mut self, arena: &Arena, positions: &[DVec2], members: std::ops::Range<usize>) {
        let n = members.len();
        let per_side = ((n as f64 / 2.0).sqrt().floor() as usize).clamp(1, 2048);
        self.cells_per_side = per_side;
        self.cell = arena.edge / per_side as f64;
        self.half = arena.half();
        self.periodic = arena.boundary == Boundary::Periodic;
        let cells = per_side * per_side;
        self.start.clear();
        self.start.resize(cells + 1, 0);
        for i in members.clone() {
            let c = self.cell_index(positions[i]);
            self.start[c + 1] += 1;
        }
        for c in 0..cells {
            self.start[c + 1] += self.start[c];
        }
        self.items.clear();
        self.items.resize(n, 0);
        self.item_positions.clear();
        self.item_positions.resize(n, DVec2::ZERO);
        let mut fill = self.start.clone();
        for i in members {
            let c = self.cell_index(positions[i]);
            self.items[fill[c] as usize] = i as u32;
            self.item_positions[fill[c] as usize] = positions[i];
            fill[c] += 1;
        }
    }

    fn cell_coord(&self, x: f64) -> usize {
        // Truncation is floor for the non-negative values that matter; negatives clamp to 0 either way.
        (((x + self.half) / self.cell).max(0.0) as usize).min(self.cells_per_side - 1)
    }

    fn cell_index(&self, p: DVec2) -> usize {
        self.cell_coord(p.y) * self.cells_per_side + self.cell_coord(p.x)
    }

    fn cell_range(&self, cx: usize, cy: usize) -> std::ops::Range<usize> {
        let c = cy * self.cells_per_side + cx;
        self.start[c] as usize..self.start[c + 1] as usize
    }

    /// Maps a cell offset to a cell on this grid: wrapped on the torus, None outside the walls.
    fn offset(&self, c: usize, d: isize) -> Option<usize> {
        // Offsets stay within one grid width, so one add or subtract wraps (no integer division).
        let n = self.cells_per_side as isize;
        let x = c as isize + d;
        if (0..n).contains(&x) {
            Some(x as usize)
        } else if !self.periodic {
            None
        } else if x < 0 {
            Some((x + n) as usize)
        } else {
            Some((x - n) as usize)
        }
    }

    /// Calls `f` with every member (index, position) that may lie within `radius` of `p` (a superset:
    /// callers check the distance). Each member at most once.
    pub(crate) fn for_each_near(&self, p: DVec2, radius: f64, mut f: impl FnMut(u32, DVec2)) {
        let n = self.cells_per_side;
        let floor = |v: f64| {
            let t = v as isize;
            t - ((t as f64) > v) as isize
        };
        let span = |x: f64| (floor((x - radius + self.half) / self.cell), floor((x + radius + self.half) / self.cell));
        let ((mut x_lo, mut x_hi), (mut y_lo, mut y_hi)) = (span(p.x), span(p.y));
        if !self.periodic {
            // Members pressed beyond a wall are filed in the edge cells, so the box is clamped to the
            // grid rather than cut: a box wholly beyond a wall still covers the edge cells.
            let last = n as isize - 1;
            (x_lo, x_hi, y_lo, y_hi) =
                (x_lo.clamp(0, last), x_hi.clamp(0, last), y_lo.clamp(0, last), y_hi.clamp(0, last));
        }
        if n < SCAN_ALL_BELOW || (x_hi - x_lo + 1) as usize >= n || (y_hi - y_lo + 1) as usize >= n {
            self.items.iter().zip(&self.item_positions).for_each(|(&i, &x)| f(i, x));
            return;
        }
        // Only the cells the disk's bounding box touches (usually one: bodies are small next to cells).
        for y in y_lo..=y_hi {
            let Some(y) = self.offset(0, y) else { continue };
            for x in x_lo..=x_hi {
                let Some(x) = self.offset(0, x) else { continue };
                let range = self.cell_range(x, y);
                self.items[range.clone()].iter().zip(&self.item_positions[range]).for_each(|(&i, &x)| f(i, x));
            }
        }
    }

    /// The `k` members nearest to `p` within `radius` (distance as `arena.delta`), nearest first, ties
    /// broken by index, skipping `exclude`. `out` holds (squared distance, index).
    pub(crate) fn k_nearest(
        &self,
        arena: &Arena,
        p: DVec2,
        k: usize,
        radius: f64,
        exclude: u32,
        out: &mut Vec<(f64, u32)>,
    ) {
        out.clear();
        if k == 0 || self.items.is_empty() {
            return;
        }
        let q = Knn { arena, p, k, r2: radius * radius, exclude };
        let n = self.cells_per_side;
        if n < SCAN_ALL_BELOW {
            // Under 2 · SCAN_ALL_BELOW² ≤ BLOCK_RANKED members (rebuild's cells a side), so ranked without
            // branches: sorted insertion's branches follow each world's data, which a branch predictor
            // learns for a few worlds stepped in turn but not for a thousand.
            if self.items.len() <= BLOCK_RANKED {
                q.rank_block(self, std::slice::from_ref(&(0..self.items.len())), !self.periodic, out);
            } else {
                q.scan(self, 0..self.items.len(), out);
            }
            return;
        }
        // Expanding square rings of cells around p's cell. A cell at offset (dx, dy) is at least
        // gap(dx)² + gap(dy)² away, with gap the distance from p to that column/row of cells; a cell, and
        // then a whole ring, is skipped once that exceeds the current k-th distance.
        let (cx, cy) = (self.cell_coord(p.x), self.cell_coord(p.y));
        // p's offset in its cell. It can lie outside [0, cell]: by rounding at a cell's edge, and by a
        // body's depth beyond a wall (such bodies are filed in the edge cells). The offsets stay exact so
        // the gaps stay true lower bounds; a gap below zero is zero, as squaring it would overstate it.
        let fx = p.x + self.half - cx as f64 * self.cell;
        let fy = p.y + self.half - cy as f64 * self.cell;
        let gap = |d: isize, f: f64| {
            match d {
                0 => 0.0,
                d if d > 0 => (d - 1) as f64 * self.cell + (self.cell - f),
                d => (-d - 1) as f64 * self.cell + f,
            }
            .max(0.0)
        };
        // Rings 0 and 1 at once: the 3 × 3 block of cells around p's, at most six runs of consecutive
        // items (stored cell by cell, row by row), ranked without branches when it holds few enough
        // candidates. Any visiting order gives the same k: the answer is the k smallest under one total
        // order (distance, then index).
        let (runs, count) = self.block_runs(cx, cy);
        let runs = &runs[..count];
        if runs.iter().map(|r| r.len()).sum::<usize>() <= BLOCK_RANKED {
            let inside = |c: usize| (1..n - 1).contains(&c);
            q.rank_block(self, runs, !self.periodic || (inside(cx) && inside(cy)), out);
        } else {
            runs.iter().for_each(|r| q.scan(self, r.clone(), out));
        }
        let mut ring = 2usize;
        loop {
            if self.periodic && 2 * ring + 1 > n {
                break; // rings would wrap onto visited cells: scan what is left below
            }
            if !self.periodic && ring > cx.max(n - 1 - cx).max(cy).max(n - 1 - cy) {
                return; // every cell visited
            }
            let r = ring as isize;
            let nearest_side = gap(r, fx).min(gap(-r, fx)).min(gap(r, fy)).min(gap(-r, fy));
            if nearest_side * nearest_side > q.worst(out) {
                return;
            }
            // The ring's cells nearest first, so the best candidates arrive early and prune the rest
            // (sorted on the stack; a ring too large for the buffer is visited in row order).
            let mut cells = [(0.0f64, 0usize, 0usize); SORTED_RING_CELLS];
            let mut count = 0;
            for dy in -r..=r {
                let Some(y) = self.offset(cy, dy) else { continue };
                let gy2 = gap(dy, fy).powi(2);
                let step = if dy.abs() == r { 1 } else { (2 * r).max(1) as usize };
                for dx in (-r..=r).step_by(step) {
                    let Some(x) = self.offset(cx, dx) else { continue };
                    let gap2 = gy2 + gap(dx, fx).powi(2);
                    if count < SORTED_RING_CELLS {
                        cells[count] = (gap2, x, y);
                        count += 1;
                    } else if gap2 <= q.worst(out) {
                        q.scan(self, self.cell_range(x, y), out);
                    }
                }
            }
            let cells = &mut cells[..count];
            cells.sort_unstable_by(|a, b| a.0.total_cmp(&b.0));
            for &(gap2, x, y) in cells.iter() {
                if gap2 > q.worst(out) {
                    break;
                }
                q.scan(self, self.cell_range(x, y), out);
            }
            ring += 1;
        }
        // Torus, rings exhausted: the cells not yet visited are those at wrapped Chebyshev distance ≥ ring.
        let wrapped = |a: usize, b: usize| {
            let d = a.abs_diff(b);
            d.min(n - d)
        };
        for y in 0..n {
            for x in 0..n {
                if wrapped(x, cx).max(wrapped(y, cy)) >= ring {
                    q.scan(self, self.cell_range(x, y), out);
                }
            }
        }
    }

    /// [`CellGrid::k_nearest`] among the members `keep` accepts (by index): the nearest few are asked
    /// for, and twice as many again while fewer than `k` of them are kept and more lie within `radius`.
    /// The first `k` kept of the nearest `m` are the `k` nearest kept whenever `m` members were found, as
    /// a kept member nearer than those would have been among them.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn k_nearest_where(
        &self,
        arena: &Arena,
        p: DVec2,
        k: usize,
        radius: f64,
        exclude: u32,
        keep: impl Fn(u32) -> bool,
        out: &mut Vec<(f64, u32)>,
    ) {
        out.clear();
        if k == 0 {
            return;
        }
        let mut asked = k;
        let mut found = Vec::with_capacity(k);
        loop {
            self.k_nearest(arena, p, asked, radius, exclude, &mut found);
            out.clear();
            out.extend(found.iter().copied().filter(|&(_, j)| keep(j)).take(k));
            if out.len() == k || found.len() < asked {
                return;
            }
            asked *= 2;
        }
    }

    /// The item ranges of the 3 × 3 block of cells around cell (cx, cy): a run of consecutive cells per
    /// row, split in two where it wraps across the torus' seam, clipped at walls. Needs ≥ 3 cells per
    /// side, so that the block's cells are distinct.
    fn block_runs(&self, cx: usize, cy: usize) -> ([std::ops::Range<usize>; 6], usize) {
        let n = self.cells_per_side;
        let mut runs: [std::ops::Range<usize>; 6] = Default::default();
        let mut count = 0;
        let mut push = |row: usize, lo: usize, hi: usize| {
            runs[count] = self.start[row + lo] as usize..self.start[row + hi + 1] as usize;
            count += 1;
        };
        for dy in -1..=1 {
            let Some(y) = self.offset(cy, dy) else { continue };
            let row = y * n;
            match (cx, self.periodic) {
                (0, true) => {
                    push(row, n - 1, n - 1);
                    push(row, 0, 1);
                }
                (0, false) => push(row, 0, 1),
                (x, true) if x == n - 1 => {
                    push(row, n - 2, n - 1);
                    push(row, 0, 0);
                }
                (x, false) if x == n - 1 => push(row, n - 2, n - 1),
                (x, _) => push(row, x - 1, x + 1),
            }
        }
        (runs, count)
    }
}

/// Candidates up to which a 3 × 3 block is ranked all-against-all rather than scanned into a sorted list
/// (whole vectors of eight).
const BLOCK_RANKED: usize = 48;
const _: () = assert!(BLOCK_RANKED.is_multiple_of(8));
// A grid of fewer than SCAN_ALL_BELOW cells a side holds fewer than 2 · SCAN_ALL_BELOW² members (rebuild).
const _: () = assert!(2 * SCAN_ALL_BELOW * SCAN_ALL_BELOW <= BLOCK_RANKED);

/// One k-nearest query: keeps the best `k` candidates in a short sorted list.
struct Knn<'a> {
    arena: &'a Arena,
    p: DVec2,
    k: usize,
    r2: f64,
    exclude: u32,
}

impl Knn<'_> {
    /// The squared distance beyond which nothing can enter `out`.
    #[inline(always)]
    fn worst(&self, out: &[(f64, u32)]) -> f64 {
        if out.len() == self.k {
            out[self.k - 1].0.min(self.r2)
        } else {
            self.r2
        }
    }

    /// The best `k` of the items in `runs` (at most [`BLOCK_RANKED`], `out` empty): every candidate's rank
    /// is the number of candidates before it, counted without branches (the sorted insertion's
    /// unpredictable branches were most of a query's time); ranks below k go straight to their place.
    /// `plain`: the block lies away from the torus' seam (or within walls), where the minimum image is the
    /// plain difference, so the distances skip its branches and come out the same.
    #[inline(always)]
    fn rank_block(&self, grid: &CellGrid, runs: &[std::ops::Range<usize>], plain: bool, out: &mut Vec<(f64, u32)>) {
        let mut d2 = [f64::INFINITY; BLOCK_RANKED];
        let mut index = [u32::MAX; BLOCK_RANKED];
        let mut m = 0;
        for r in runs {
            for (&i, &x) in grid.items[r.clone()].iter().zip(&grid.item_positions[r.clone()]) {
                let d = if plain { x - self.p } else { self.arena.delta(self.p, x) }.length_squared();
                // Written always, kept only if it counts (no branch): a rejected candidate is overwritten
                // by the next one or reset below. The block holds at most BLOCK_RANKED, so m stays in bounds.
                // A distance that is not a number (a position gone non-finite, which stops the run after
                // this step) is a candidate ranked last, as +∞: a query for the nearest one still finds
                // one, and the ranks stay a permutation (NaN compares false with everything).
                d2[m] = if d.is_nan() { f64::INFINITY } else { d };
                index[m] = i;
                #[allow(clippy::neg_cmp_op_on_partial_ord)] // NaN admitted on purpose, as said above
                let admitted = !(d > self.r2);
                m += (admitted & (i != self.exclude)) as usize;
            }
        }
        if m < BLOCK_RANKED {
            (d2[m], index[m]) = (f64::INFINITY, u32::MAX);
        }
        let k = self.k.min(m);
        out.resize(k, (0.0, 0));
        place_by_rank(&d2, &index, m, out);
    }

    /// Considers the grid items in `range` (a cell, or everything).
    #[inline(always)]
    fn scan(&self, grid: &CellGrid, range: std::ops::Range<usize>, out: &mut Vec<(f64, u32)>) {
        for (&i, &x) in grid.items[range.clone()].iter().zip(&grid.item_positions[range]) {
            let d2 = self.arena.delta(self.p, x).length_squared();
            if d2 > self.r2 || i == self.exclude {
                continue;
            }
            // Ordered by distance, then index (ties are exact only on lattices, but must be deterministic).
            let before = |a: (f64, u32), b: (f64, u32)| a.0 < b.0 || (a.0 == b.0 && a.1 < b.1);
            let cand = (d2, i);
            if out.len() == self.k {
                if !before(cand, out[self.k - 1]) {
                    continue;
                }
                out.pop();
            }
            // Insertion into a short sorted list, shifting in place.
            out.push(cand);
            let mut at = out.len() - 1;
            while at > 0 && before(cand, out[at - 1]) {
                out[at] = out[at - 1];
                at -= 1;
            }
            out[at] = cand;
        }
    }
}

/// Puts each of the first `m` candidates (`d2`, `index`; the rest padded with (∞, u32::MAX)) whose rank
/// is below `out.len()` at `out[rank]`, its rank being the number of candidates before it in (distance,
/// index) order. The comparisons are exact, so every instruction set gives the same answer; with AVX-512
/// a candidate is compared with eight others per instruction.
fn place_by_rank(d2: &[f64; BLOCK_RANKED], index: &[u32; BLOCK_RANKED], m: usize, out: &mut [(f64, u32)]) {
    #[cfg(target_arch = "x86_64")]
    {
        if has_avx512() {
            // SAFETY: the features were detected on this CPU.
            return unsafe { place_by_rank_avx512(d2, index, m, out) };
        }
    }
    place_by_rank_portable(d2, index, m, out)
}

/// Whether this CPU runs AVX-512 (F and VL), detected once. Only exact operations use it here, so it
/// changes how fast, never what is computed.
#[cfg(target_arch = "x86_64")]
pub(crate) fn has_avx512() -> bool {
    static AVX512: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    *AVX512.get_or_init(|| {
        std::arch::is_x86_feature_detected!("avx512f") && std::arch::is_x86_feature_detected!("avx512vl")
    })
}

fn place_by_rank_portable(d2: &[f64; BLOCK_RANKED], index: &[u32; BLOCK_RANKED], m: usize, out: &mut [(f64, u32)]) {
    for a in 0..m {
        let (da, ia) = (d2[a], index[a]);
        let rank = (0..m).filter(|&b| d2[b] < da || (d2[b] == da && index[b] < ia)).count();
        if rank < out.len() {
            out[rank] = (da, ia);
        }
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512vl")]
fn place_by_rank_avx512(d2: &[f64; BLOCK_RANKED], index: &[u32; BLOCK_RANKED], m: usize, out: &mut [(f64, u32)]) {
    use std::arch::x86_64::*;
    // Whole blocks of eight lanes: the padding is never before a real candidate.
    let blocks = m.div_ceil(8);
    let mut sorted = [(0.0f64, 0u32); BLOCK_RANKED];
    for a in 0..m {
        let (da, ia) = (d2[a], index[a]);
        let (vd, vi) = (_mm512_set1_pd(da), _mm256_set1_epi32(ia as i32));
        let mut rank = 0;
        for c in 0..blocks {
            // SAFETY: c * 8 + 8 <= BLOCK_RANKED, since m <= BLOCK_RANKED and BLOCK_RANKED is a multiple of 8.
            let (d, i) = unsafe {
                (
                    _mm512_loadu_pd(d2.as_ptr().add(c * 8)),
                    _mm256_loadu_si256(index.as_ptr().add(c * 8) as *const __m256i),
                )
            };
            let nearer = _mm512_cmp_pd_mask::<_CMP_LT_OQ>(d, vd);
            let tie = _mm512_cmp_pd_mask::<_CMP_EQ_OQ>(d, vd) & _mm256_cmplt_epu32_mask(i, vi);
            rank += (nearer | tie).count_ones() as usize;
        }
        // Every candidate goes to its place (the ranks are 0..m, each once: distances are never NaN
        // here, rank_block) and the first out.len() are kept: whether a candidate makes the cut follows
        // the data, so it is not a branch.
        sorted[rank] = (da, ia);
    }
    out.copy_from_slice(&sorted[..out.len()]);
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    fn torus() -> Arena {
        Arena { edge: 2.0, boundary: Boundary::Periodic }
    }

    #[test]
    fn minimum_image_crosses_the_seam() {
        let a = torus();
        let d = a.delta(DVec2::new(0.95, -0.95), DVec2::new(-0.95, 0.95));
        assert!((d - DVec2::new(0.1, -0.1)).length() < 1e-12, "{d}");
        let walls = Arena { edge: 2.0, boundary: Boundary::Walls };
        assert!((walls.delta(DVec2::new(0.95, 0.0), DVec2::new(-0.95, 0.0)).x + 1.9).abs() < 1e-12);
    }

    #[test]
    fn minimum_image_selects_what_the_branches_would() {
        let branches = |d: f64, edge: f64| {
            let half = edge / 2.0;
            if d > half {
                d - edge
            } else if d < -half {
                d + edge
            } else {
                d
            }
        };
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let edges = [2.0, 3.7, 100.0];
        let special = [
            0.0,
            -0.0,
            1.0,
            -1.0,
            1.0 + f64::EPSILON,
            -1.0 - f64::EPSILON,
            1.85,
            -1.85,
            50.0,
            -50.0,
            250.0,
            -250.0,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NAN,
        ];
        for &edge in &edges {
            let random = (0..2000).map(|_| rng.gen_range(-edge..edge));
            for d in special.into_iter().chain(random) {
                assert_eq!(min_image(d, edge).to_bits(), branches(d, edge).to_bits(), "d = {d}, edge = {edge}");
            }
        }
    }

    #[test]
    fn wrap_keeps_the_overshoot() {
        let a = torus();
        let p = a.wrap(DVec2::new(1.03, -1.02));
        assert!((p - DVec2::new(-0.97, 0.98)).length() < 1e-12, "{p}");
        assert_eq!(a.wrap(DVec2::new(0.3, -0.4)), DVec2::new(0.3, -0.4));
    }

    /// What `k_nearest` must return, by comparing `p` with every member of `pos`.
    fn brute_nearest(arena: &Arena, pos: &[DVec2], p: DVec2, k: usize, radius: f64, exclude: u32) -> Vec<(f64, u32)> {
        let mut all: Vec<(f64, u32)> = (0..pos.len() as u32)
            .filter(|&i| i != exclude)
            .map(|i| (arena.delta(p, pos[i as usize]).length_squared(), i))
            .filter(|e| e.0 <= radius * radius)
            .collect();
        all.sort_by(|a, b| a.partial_cmp(b).unwrap());
        all.truncate(k);
        all
    }

    /// Every member of `pos` queried for its `(k, radius)` neighbours by a grid over `pos` (itself
    /// excluded) gets brute force's answer, ties broken by index.
    fn every_member_finds_what_brute_force_finds(arena: &Arena, pos: &[DVec2], cases: &[(usize, f64)]) {
        let mut grid = CellGrid::default();
        grid.rebuild(arena, pos, 0..pos.len());
        let mut out = vec![];
        for (q, &p) in pos.iter().enumerate() {
            for &(k, radius) in cases {
                grid.k_nearest(arena, p, k, radius, q as u32, &mut out);
                let brute = brute_nearest(arena, pos, p, k, radius, q as u32);
                assert_eq!(out, brute, "{:?} q={q} k={k}", arena.boundary);
            }
        }
    }

    #[test]
    fn ranking_is_the_same_on_every_instruction_set() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        for m in 0..=BLOCK_RANKED {
            let mut d2 = [f64::INFINITY; BLOCK_RANKED];
            let mut index = [u32::MAX; BLOCK_RANKED];
            for j in 0..m {
                // Few distinct distances, so ties are common; distinct indices, as in a grid.
                d2[j] = rng.gen_range(0..6) as f64 * 0.5;
                index[j] = (j as u32 * 7919) % 1000;
            }
            let k = m.min(rng.gen_range(1..10));
            let (mut fast, mut portable) = (vec![(0.0, 0); k], vec![(0.0, 0); k]);
            place_by_rank(&d2, &index, m, &mut fast);
            place_by_rank_portable(&d2, &index, m, &mut portable);
            let mut sorted: Vec<(f64, u32)> = (0..m).map(|j| (d2[j], index[j])).collect();
            sorted.sort_by(|a, b| a.partial_cmp(b).unwrap());
            sorted.truncate(k);
            assert_eq!(fast, sorted, "m={m}");
            assert_eq!(portable, sorted, "m={m}");
        }
    }

    /// Within walls a crowded body can sit beyond the wall (the spring pushes it back over a few steps):
    /// its offset in its cell is then negative, and no neighbour may be missed for it (the ring search
    /// once squared that negative gap and skipped the next row of cells).
    #[test]
    fn grid_k_nearest_is_exact_for_bodies_pushed_into_a_wall() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let arena = Arena { edge: 2.0, boundary: Boundary::Walls };
        // A crowd pressed against the bottom wall, partly beyond it, above a uniform population.
        let mut pos: Vec<DVec2> =
            (0..1000).map(|_| DVec2::new(rng.gen_range(-1.0..1.0), rng.gen_range(-1.0..1.0))).collect();
        pos.extend((0..600).map(|_| DVec2::new(rng.gen_range(-1.0..1.0), rng.gen_range(-1.06..-0.98))));
        let mut grid = CellGrid::default();
        grid.rebuild(&arena, &pos, 0..pos.len());
        let mut out = vec![];
        for (q, &p) in pos.iter().enumerate().filter(|(_, p)| p.abs().max_element() > 1.0) {
            grid.k_nearest(&arena, p, 6, f64::INFINITY, q as u32, &mut out);
            assert_eq!(out, brute_nearest(&arena, &pos, p, 6, f64::INFINITY, q as u32), "q={q} at {p}");
        }
    }

    #[test]
    fn bodies_beyond_a_wall_still_find_each_other() {
        let arena = Arena { edge: 4.0, boundary: Boundary::Walls };
        let mut pos: Vec<DVec2> =
            (0..400).map(|i| DVec2::new((i % 20) as f64 * 0.2 - 1.9, (i / 20) as f64 * 0.2 - 1.9)).collect();
        // Two bodies 0.05 apart, both 0.3 beyond the left wall: farther out than the search radius.
        pos.extend([DVec2::new(-2.3, 0.0), DVec2::new(-2.3, 0.05)]);
        let mut grid = CellGrid::default();
        grid.rebuild(&arena, &pos, 0..pos.len());
        let mut near = vec![];
        grid.for_each_near(pos[400], 0.1, |i, _| near.push(i));
        assert!(near.contains(&401), "{near:?}");
    }

    /// A query on a cell's edge whose offset rounds to just below zero, with the nearest member two
    /// columns away and a near-tie inside the 3 × 3 block (found by review): clamping the offset to the
    /// cell overstated the ring-2 gap by a rounding error and pruned the true nearest.
    #[test]
    fn a_query_on_a_cell_edge_still_finds_the_nearest_two_cells_away() {
        for boundary in [Boundary::Periodic, Boundary::Walls] {
            let arena = Arena { edge: 79.71428571428571, boundary };
            let mut pos = vec![
                DVec2::new(22.775510204081627, -0.9489795918367392),
                DVec2::new(20.87755102040816, -0.9489795918367392),
                DVec2::new(22.775510204081627, 0.94897959183673),
            ];
            pos.resize(3528, DVec2::new(-17.0, -30.0));
            let mut grid = CellGrid::default();
            grid.rebuild(&arena, &pos, 0..pos.len());
            assert_eq!(grid.cells_per_side, 42);
            let mut out = vec![];
            grid.k_nearest(&arena, pos[0], 1, f64::INFINITY, 0, &mut out);
            assert_eq!(out, vec![(arena.delta(pos[0], pos[1]).length_squared(), 1)], "{boundary:?}");
        }
    }

    #[test]
    fn small_grids_rank_ties_by_index_and_a_non_finite_position_last() {
        for boundary in [Boundary::Periodic, Boundary::Walls] {
            let arena = Arena { edge: 4.0, boundary };
            // 30 members on a lattice (2 cells a side): many equal distances.
            let mut pos: Vec<DVec2> =
                (0..30).map(|i| DVec2::new((i % 6) as f64 * 0.5 - 1.5, (i / 6) as f64 * 0.5 - 1.0)).collect();
            every_member_finds_what_brute_force_finds(&arena, &pos, &[(6, f64::INFINITY), (1, 0.5), (12, 1.0)]);
            // A member whose position is not a number is found last, never in a finite one's place.
            pos[3] = DVec2::NAN;
            let (mut grid, mut out) = (CellGrid::default(), vec![]);
            grid.rebuild(&arena, &pos, 0..pos.len());
            grid.k_nearest(&arena, pos[0], 30, f64::INFINITY, 0, &mut out);
            assert_eq!(out.len(), 29);
            assert_eq!(out.last().map(|&(d, i)| (d, i)), Some((f64::INFINITY, 3)), "{boundary:?}");
            assert!(out[..28].iter().all(|&(d, i)| d.is_finite() && i != 3), "{boundary:?}");
        }
    }

    /// Exact ties everywhere (a lattice) and blocks too crowded to rank (a tight cluster) take the block
    /// path's both branches; the answer must still be brute force's, ties broken by index.
    #[test]
    fn grid_k_nearest_breaks_ties_by_index_and_survives_crowded_blocks() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        for boundary in [Boundary::Periodic, Boundary::Walls] {
            let arena = Arena { edge: 4.0, boundary };
            let mut pos: Vec<DVec2> =
                (0..256).map(|i| DVec2::new((i % 16) as f64 * 0.25 - 2.0, (i / 16) as f64 * 0.25 - 2.0)).collect();
            pos.extend((0..120).map(|_| DVec2::new(rng.gen_range(0.9..1.0), rng.gen_range(-1.0..-0.9))));
            every_member_finds_what_brute_force_finds(&arena, &pos, &[(6, f64::INFINITY), (1, 0.3), (12, 0.6)]);
        }
    }

    #[test]
    fn grid_k_nearest_matches_brute_force_on_both_boundaries() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        for boundary in [Boundary::Periodic, Boundary::Walls] {
            for n in [1usize, 5, 10, 17, 31, 40, 400] {
                let arena = Arena { edge: 4.0, boundary };
                let pos: Vec<DVec2> =
                    (0..n).map(|_| DVec2::new(rng.gen_range(-2.0..2.0), rng.gen_range(-2.0..2.0))).collect();
                let mut grid = CellGrid::default();
                grid.rebuild(&arena, &pos, 0..n);
                let mut out = vec![];
                for q in 0..50 {
                    let p = DVec2::new(rng.gen_range(-2.0..2.0), rng.gen_range(-2.0..2.0));
                    let (k, radius) = ([1, 6, 10][q % 3], [0.3, 1.0, 10.0][q % 3]);
                    let exclude = (q % n.max(1)) as u32;
                    grid.k_nearest(&arena, p, k, radius, exclude, &mut out);
                    let brute = brute_nearest(&arena, &pos, p, k, radius, exclude);
                    assert_eq!(out, brute, "{boundary:?} n={n} q={q}");
                }
            }
        }
    }
}
