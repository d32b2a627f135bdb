//! The `avx512-direct` kernel family: the update's matrix products computed straight from their operands
//! with AVX-512, without gemm's packing and dispatch. Every product of the update has one narrow operand
//! (at most 64 columns: a layer's width) whose rows are contiguous; each output row is then at most four
//! 16-lane registers, and six output rows (24 accumulators) are summed at once over the inner dimension,
//! the other operand broadcast one element at a time.
//!
//! Each output element is summed over the inner dimension in order, one fused multiply-add per term,
//! starting from zero: `((a₀b₀ + a₁b₁) + a₂b₂) + …` rounded as `f32::mul_add` rounds. That order depends on
//! nothing but the shapes (no blocking of the inner dimension, no threads), so the family gives the same
//! bits at any thread count, and [`tests`] check every shape against a scalar loop summing in that order.

#[cfg(target_arch = "x86_64")]
use std::arch::x86_64::*;

/// The widest narrow operand: four AVX-512 registers.
pub(crate) const MAX_WIDTH: usize = 64;

/// Output rows summed together: 6 × 4 accumulators, the rest of the 32 registers for the narrow operand's
/// row and the broadcast.
const ROWS: usize = 6;

/// Whether this CPU runs the family.
pub(crate) fn available() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx512f")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// dst `[m × n]` (row stride `dst_rs`) = A·B, A(i, p) = `a[i·a_rs + p·a_cs]` (`m × k`), B `[k × n]` with
/// contiguous rows `b_rs` apart; n ≤ [`MAX_WIDTH`].
///
/// # Safety
/// The CPU has AVX-512F ([`available`]); every element the strides address lies inside its buffer (B's
/// rows are read only up to column n: the last register's load is masked).
#[cfg(target_arch = "x86_64")]
#[allow(clippy::too_many_arguments)]
#[target_feature(enable = "avx512f")]
pub(crate) unsafe fn product(
    m: usize,
    n: usize,
    k: usize,
    dst: *mut f32,
    dst_rs: usize,
    a: *const f32,
    (a_rs, a_cs): (usize, usize),
    b: *const f32,
    b_rs: usize,
) {
    assert!(n > 0 && n <= MAX_WIDTH, "a direct product is at most {MAX_WIDTH} columns wide");
    // The last register's columns: 1 to 16.
    let mask = lanes(n - (n.div_ceil(16) - 1) * 16);
    let op = Operands { k, dst, dst_rs, a, a_rs, a_cs, b, b_rs, mask };
    match n.div_ceil(16) {
        1 => rows::<1>(m, &op),
        2 => rows::<2>(m, &op),
        3 => rows::<3>(m, &op),
        _ => rows::<4>(m, &op),
    }
}

/// Lanes `0 .. left` of a 16-lane register (all 16 from 16 on): the mask of a register's columns or
/// rows that lie inside an operand.
#[cfg(target_arch = "x86_64")]
#[inline]
pub(super) fn lanes(left: usize) -> u16 {
    match left {
        l if l >= 16 => u16::MAX,
        l => (1u16 << l) - 1,
    }
}

/// A product's operands (see [`product`]); `mask` selects the last register's columns.
#[cfg(target_arch = "x86_64")]
struct Operands {
    k: usize,
    dst: *mut f32,
    dst_rs: usize,
    a: *const f32,
    a_rs: usize,
    a_cs: usize,
    b: *const f32,
    b_rs: usize,
    mask: u16,
}

/// Every output row of `m` from `$from`, `ROWS` (6) at a time, then the 1–5 left: `$block::<NV, R>(i0,
/// $op)` for each block of R rows from i0 (`NV` the registers per row, as where it is used). The bodies of
/// this family's and `super::bf16`'s `rows`, each compiled with its own features.
macro_rules! each_block {
    ($m:expr, $op:expr, $block:ident, $from:expr) => {{
        let mut i = $from;
        while i + ROWS <= $m {
            $block::<NV, ROWS>(i, $op);
            i += ROWS;
        }
        match $m - i {
            5 => $block::<NV, 5>(i, $op),
            4 => $block::<NV, 4>(i, $op),
            3 => $block::<NV, 3>(i, $op),
            2 => $block::<NV, 2>(i, $op),
            1 => $block::<NV, 1>(i, $op),
            _ => {}
        }
    }};
}
pub(crate) use each_block;

/// Every output row, [`ROWS`] at a time, then the rest.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
unsafe fn rows<const NV: usize>(m: usize, op: &Operands) {
    each_block!(m, op, block, 0)
}

/// Output rows `i0 .. i0 + R`: R × NV accumulators summed over the whole inner dimension, then stored.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
#[inline]
unsafe fn block<const NV: usize, const R: usize>(i0: usize, op: &Operands) {
    let mut acc = [[_mm512_setzero_ps(); NV]; R];
    let a = op.a.add(i0 * op.a_rs);
    for p in 0..op.k {
        let row = op.b.add(p * op.b_rs);
        let mut bv = [_mm512_setzero_ps(); NV];
        for (v, b) in bv.iter_mut().enumerate() {
            *b = if v + 1 < NV {
                _mm512_loadu_ps(row.add(16 * v))
            } else {
                _mm512_maskz_loadu_ps(op.mask, row.add(16 * v))
            };
        }
        let ap = a.add(p * op.a_cs);
        for (r, acc) in acc.iter_mut().enumerate() {
            let x = _mm512_set1_ps(*ap.add(r * op.a_rs));
            for (s, b) in acc.iter_mut().zip(&bv) {
                *s = _mm512_fmadd_ps(x, *b, *s);
            }
        }
    }
    for (r, acc) in acc.iter().enumerate() {
        let out = op.dst.add((i0 + r) * op.dst_rs);
        for (v, s) in acc.iter().enumerate() {
            if v + 1 < NV {
                _mm512_storeu_ps(out.add(16 * v), *s);
            } else {
                _mm512_mask_storeu_ps(out.add(16 * v), op.mask, *s);
            }
        }
    }
}

#[cfg(all(test, target_arch = "x86_64"))]
mod tests {
    use super::*;

    /// The same product summed by a scalar loop in the family's order.
    fn reference(c: &Case) -> Vec<f32> {
        let ((a_rs, a_cs), n) = (c.strides, c.n);
        let mut out = vec![0.0f32; c.m * n];
        for i in 0..c.m {
            for j in 0..n {
                out[i * n + j] = (0..c.k).fold(0.0f32, |s, p| c.a[i * a_rs + p * a_cs].mul_add(c.b[p * c.b_rs + j], s));
            }
        }
        out
    }

    #[test]
    fn every_shape_sums_in_order_as_the_scalar_loop_does() {
        if !available() {
            eprintln!("skipped: no AVX-512 here");
            return;
        }
        for c in cases() {
            let (m, n, k) = (c.m, c.n, c.k);
            let mut dst = vec![f32::NAN; m * n];
            // SAFETY: this CPU has AVX-512F; A is m·k, B k rows of b_rs ≥ n, dst m × n.
            unsafe { product(m, n, k, dst.as_mut_ptr(), n, c.a.as_ptr(), c.strides, c.b.as_ptr(), c.b_rs) };
            let expected = reference(&c);
            assert!(
                dst.iter().zip(&expected).all(|(x, y)| x.to_bits() == y.to_bits()),
                "{m} × {n} × {k}, strides {:?}",
                c.strides
            );
        }
    }
}

/// A product every kernel family of the update is tested on ([`cases`]).
#[cfg(test)]
pub(crate) struct Case {
    pub(crate) m: usize,
    pub(crate) n: usize,
    pub(crate) k: usize,
    /// A, m × k, read with `strides` (row-major, or transposed: read from k × m).
    pub(crate) a: Vec<f32>,
    pub(crate) strides: (usize, usize),
    /// B, k rows `b_rs` apart (padded past n).
    pub(crate) b: Vec<f32>,
    pub(crate) b_rs: usize,
}

/// The update's shapes and odd ones (every remainder of rows and columns), each with A row-major and
/// transposed, drawn from a fixed generator in [−0.5, 0.5).
#[cfg(test)]
pub(crate) fn cases() -> Vec<Case> {
    let mut seed = 1u32;
    let mut draw = |len: usize| {
        (0..len)
            .map(|_| {
                seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
                (seed >> 8) as f32 / (1u32 << 24) as f32 - 0.5
            })
            .collect::<Vec<f32>>()
    };
    let shapes = [
        (256, 64, 54),
        (256, 54, 64),
        (64, 56, 256),
        (256, 2, 64),
        (13, 64, 64),
        (1, 1, 1),
        (7, 17, 3),
        (11, 33, 5),
        (40, 16, 33),
        (37, 1, 64),
        (300, 1, 37),
        (19, 3, 40),
        (70, 3, 40),
        (40, 4, 21),
    ];
    let mut out = vec![];
    for (m, n, k) in shapes {
        for transposed in [false, true] {
            let a = draw(m * k);
            let b_rs = n + 3;
            let b = draw(k * b_rs);
            let strides = if transposed { (1, m) } else { (k, 1) };
            out.push(Case { m, n, k, a, strides, b, b_rs });
        }
    }
    out
}

/// This core's rate of fused multiply-adds (FLOP/s, two per lane), on 12 independent chains (enough to hide the latency of two pipes, few enough to stay in registers) of AVX-512
/// FMAs when the CPU has them, else of AVX2 ones, else None: the ceiling of any product kernel here.
pub(crate) fn fma_peak(budget: std::time::Duration) -> Option<f64> {
    #[cfg(target_arch = "x86_64")]
    {
        /// `n` rounds of 12 FMA chains, `LANES` wide.
        macro_rules! chains {
            ($name:ident, $feature:literal, $lanes:literal, $set1:ident, $fmadd:ident) => {
                #[target_feature(enable = $feature)]
                unsafe fn $name(n: usize) -> f32 {
                    let (x, y) = ($set1(0.999), $set1(0.001));
                    let mut acc = [$set1(0.0); 12];
                    for _ in 0..n {
                        for a in acc.iter_mut() {
                            *a = $fmadd(*a, x, y);
                        }
                    }
                    // Every chain's lanes summed, so that none is computed for nothing.
                    let mut sum = 0.0;
                    let mut lanes = [0.0f32; $lanes];
                    for a in acc {
                        std::ptr::write_unaligned(lanes.as_mut_ptr().cast(), a);
                        sum += lanes.iter().sum::<f32>();
                    }
                    sum
                }
            };
        }
        chains!(avx512, "avx512f", 16, _mm512_set1_ps, _mm512_fmadd_ps);
        chains!(avx2, "avx2,fma", 8, _mm256_set1_ps, _mm256_fmadd_ps);
        let (lanes, run): (f64, unsafe fn(usize) -> f32) = if std::arch::is_x86_feature_detected!("avx512f") {
            (16.0, avx512)
        } else if std::arch::is_x86_feature_detected!("fma") {
            (8.0, avx2)
        } else {
            return None;
        };
        // SAFETY: the chosen function's features were detected just above.
        let rounds = crate::parallel::per_second(budget, 3, || {
            std::hint::black_box(unsafe { run(1_000_000) });
        });
        Some(rounds * 1e6 * 12.0 * lanes * 2.0)
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        let _ = budget;
        None
    }
}
