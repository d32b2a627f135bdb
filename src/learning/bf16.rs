//! The `avx512-bf16` kernel family: the update's matrix products of [`super::direct`], with their operands
//! rounded to bfloat16 and their sums kept in f32, on the CPUs that have AVX512-BF16 (`VDPBF16PS`: 32
//! bf16 products per instruction into 16 f32 sums, twice an f32 FMA's work). Weights, Adam's state, the
//! targets and the replay buffer stay f32: only the two operands of a product are rounded, as they enter
//! it (mixed precision as large learners are trained; Kalamkar et al., arXiv:1905.12322, 2019).
//!
//! **Rounding.** Each operand is rounded to bf16 to nearest, ties to even (8 significant bits); an operand
//! too small for a normal f32 counts as zero, as `VDPBF16PS` reads it. A product of two bf16 numbers is
//! exact in f32 (16 significant bits), and `VDPBF16PS` adds each product to its f32 sum with one rounding
//! to nearest (results too small for a normal f32 flushed to zero). The inner dimension is taken in pairs
//! (p, p + 1), the odd term added before the even one, pairs in order, from zero: an order fixed by the
//! shapes alone, so the family gives the same bits at any thread count, and [`tests`] check every shape
//! against a scalar loop summing in that order.
//!
//! **The error, derived.** With u = 2⁻⁸ (bf16's unit roundoff) and v = 2⁻²⁴ (f32's), each rounded
//! operand is x(1 + δ), |δ| ≤ u, so each exact product is ab(1 + ε), |ε| ≤ 2u + u²; k sums in f32 add at
//! most γₖ = kv/(1 − kv) of the running magnitudes. So |ŝ − s| ≤ (2u + u² + γₖ(1 + u)²)·Σ|aᵢbᵢ|, about
//! 0.0078·Σ|aᵢbᵢ| for the update's widths, plus k·2⁻¹²⁶ for sums flushed to zero ([`bound`]), for
//! operands with no subnormal value (a subnormal operand counts as zero: its term, under 2⁻¹²⁶ times the
//! other operand, is dropped) and none beyond bf16's range (rounded to ±∞). [`tests`] hold every product
//! against it. A product the family does not take (wider than [`MAX_WIDTH`], accumulating, or dfdx's
//! own) runs on gemm in f32, as under `avx512-direct`. Its bits are those of this project's AMD EPYC;
//! another vendor's `VDPBF16PS` is not yet checked against the same test.

#[cfg(target_arch = "x86_64")]
use std::arch::x86_64::*;

/// The widest narrow operand, as [`super::direct::MAX_WIDTH`].
pub(crate) use super::direct::MAX_WIDTH;

/// Output rows summed together: 6 × 4 accumulators, as [`super::direct`].
const ROWS: usize = 6;

/// Whether this CPU runs the family: AVX512-BF16, and AVX512-BW for packing the operands.
pub(crate) fn available() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx512f")
            && std::arch::is_x86_feature_detected!("avx512bf16")
            && std::arch::is_x86_feature_detected!("avx512bw")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// `x` rounded to bf16 (its upper 16 bits), to nearest with ties to even; a subnormal counts as a signed
/// zero, a NaN stays a NaN. What `VCVTNE2PS2BF16` gives for every normal input.
pub(crate) fn to_bf16(x: f32) -> u16 {
    let bits = x.to_bits();
    if x.is_nan() {
        return ((bits >> 16) | 0x40) as u16;
    }
    if bits & 0x7f80_0000 == 0 {
        return ((bits >> 16) & 0x8000) as u16;
    }
    ((bits + 0x7fff + ((bits >> 16) & 1)) >> 16) as u16
}

/// The f32 a bf16 number stands for.
#[cfg(test)]
fn from_bf16(h: u16) -> f32 {
    f32::from_bits((h as u32) << 16)
}

/// The derived bound on |ŝ − s| for an inner dimension of `k` whose terms' magnitudes sum to `magnitude`
/// (Σ|aᵢbᵢ| in exact arithmetic), no operand subnormal: the [module docs](self)' bound, and k sums
/// flushed below 2⁻¹²⁶.
#[cfg(test)]
fn bound(k: usize, magnitude: f64) -> f64 {
    let (u, v) = (2f64.powi(-8), 2f64.powi(-24));
    let gamma = k as f64 * v / (1.0 - k as f64 * v);
    // A sum flushed to zero is carried through the later roundings too: (1 + γₖ) on the flushed part.
    (2.0 * u + u * u + gamma * (1.0 + u) * (1.0 + u)) * magnitude + k as f64 * 2f64.powi(-126) * (1.0 + gamma)
}

thread_local! {
    /// The packed operands of the last product on this thread, reused (no allocation per product).
    static PACKED: std::cell::RefCell<(Vec<u32>, Vec<u32>)> = const { std::cell::RefCell::new((Vec::new(), Vec::new())) };
}

/// dst `[m × n]` (row stride `dst_rs`) = A·B with both operands rounded to bf16 and f32 sums, A(i, p) =
/// `a[i·a_rs + p·a_cs]` (`m × k`), B `[k × n]` with contiguous rows `b_rs` apart; n ≤ [`MAX_WIDTH`]. The
/// contract of [`super::direct::product`].
///
/// # Safety
/// The CPU runs the family ([`available`]); every element the strides address lies inside its buffer.
#[cfg(target_arch = "x86_64")]
#[allow(clippy::too_many_arguments)]
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
    assert!(n > 0 && n <= MAX_WIDTH, "a bf16 product is at most {MAX_WIDTH} columns wide");
    let (pairs, nv) = (k.div_ceil(2), n.div_ceil(16));
    PACKED.with_borrow_mut(|(pa, pb)| {
        // B: pair-row q holds, per column j (padded to whole registers with zeros), B(2q, j) in its low
        // half and B(2q + 1, j) in its high half.
        // Every word is written below (no zeroing pass): the buffers only grow.
        if pb.len() < pairs * nv * 16 {
            pb.resize(pairs * nv * 16, 0);
        }
        for q in 0..pairs {
            let (row0, row1) = (b.add(2 * q * b_rs), (2 * q + 1 < k).then(|| b.add((2 * q + 1) * b_rs)));
            interleave(n, row0, row1, pb.as_mut_ptr().add(q * nv * 16));
            pb[q * nv * 16 + n..(q + 1) * nv * 16].fill(0);
        }
        // A: per output row i and pair q, A(i, 2q) low and A(i, 2q + 1) high, laid out so that the
        // pairs are written in runs: by row when A's rows are contiguous, by pair when its columns are.
        if pa.len() < m * pairs {
            pa.resize(m * pairs, 0);
        }
        let by_pair = a_rs == 1 && a_cs != 1;
        let (prs, pcs) = if by_pair { (1, m) } else { (pairs, 1) };
        if by_pair {
            for q in 0..pairs {
                let (col0, col1) = (a.add(2 * q * a_cs), (2 * q + 1 < k).then(|| a.add((2 * q + 1) * a_cs)));
                interleave(m, col0, col1, pa.as_mut_ptr().add(q * m));
            }
        } else if a_cs == 1 && a_rs == k && k.is_multiple_of(2) {
            // Dense rows of an even length: row i's pairs are its words, and the rows follow each other, so
            // the packed A is the whole block's bf16 words in order (one pass, not one call per row).
            convert(m * k, a, pa.as_mut_ptr().cast());
        } else if a_cs == 1 {
            // A row's pairs are its consecutive elements: its bf16 words in order (an odd k's last high
            // word stays zero).
            for i in 0..m {
                convert(k, a.add(i * a_rs), pa.as_mut_ptr().add(i * pairs).cast());
                if k % 2 == 1 {
                    pa[i * pairs + pairs - 1] &= 0xffff;
                }
            }
        } else {
            for i in 0..m {
                let row = a.add(i * a_rs);
                for q in 0..pairs {
                    let lo = to_bf16(*row.add(2 * q * a_cs)) as u32;
                    let hi = if 2 * q + 1 < k { to_bf16(*row.add((2 * q + 1) * a_cs)) as u32 } else { 0 };
                    pa[i * pairs + q] = lo | hi << 16;
                }
            }
        }
        let tail = n - (nv - 1) * 16;
        let mask = if tail == 16 { u16::MAX } else { (1u16 << tail) - 1 };
        let op = Packed { pairs, dst, dst_rs, a: pa.as_ptr(), prs, pcs, b: pb.as_ptr(), bs: nv * 16, mask };
        match nv {
            1 => rows::<1>(m, &op),
            2 => rows::<2>(m, &op),
            3 => rows::<3>(m, &op),
            _ => rows::<4>(m, &op),
        }
    });
}

/// `out[j]` = bf16(x0[j]) low | bf16(x1[j]) high for j < len (x1 None: zeros high), both runs contiguous:
/// 16 at a time with `VCVTNE2PS2BF16` and a permute, the last 1–15 masked. The instruction reads a
/// subnormal as zero, as [`to_bf16`] does.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512bw,avx512bf16")]
unsafe fn interleave(len: usize, x0: *const f32, x1: Option<*const f32>, out: *mut u32) {
    // Lanes 0–15 of the converted pair are x0's, 16–31 x1's: word 2j takes x0[j], 2j + 1 x1[j].
    let order = _mm512_set_epi16(
        31, 15, 30, 14, 29, 13, 28, 12, 27, 11, 26, 10, 25, 9, 24, 8, 23, 7, 22, 6, 21, 5, 20, 4, 19, 3, 18, 2, 17, 1,
        16, 0,
    );
    let mut j = 0;
    while j < len {
        let mask: u16 = if len - j >= 16 { u16::MAX } else { (1u16 << (len - j)) - 1 };
        let lo = _mm512_maskz_loadu_ps(mask, x0.add(j));
        let hi = x1.map_or(_mm512_setzero_ps(), |x1| _mm512_maskz_loadu_ps(mask, x1.add(j)));
        let both = std::mem::transmute::<__m512bh, __m512i>(_mm512_cvtne2ps_pbh(hi, lo));
        _mm512_mask_storeu_epi32(out.add(j).cast(), mask, _mm512_permutexvar_epi16(order, both));
        j += 16;
    }
}

/// `out[j]` = bf16(x[j]) for j < len: 32 at a time with `VCVTNE2PS2BF16`, the last 1–31 masked.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512bw,avx512bf16")]
unsafe fn convert(len: usize, x: *const f32, out: *mut u16) {
    let mut j = 0;
    while j < len {
        let left = len - j;
        let mask = |from: usize| -> u16 {
            match left.saturating_sub(from) {
                n if n >= 16 => u16::MAX,
                n => (1u16 << n) - 1,
            }
        };
        let (lo, hi) =
            (_mm512_maskz_loadu_ps(mask(0), x.add(j)), _mm512_maskz_loadu_ps(mask(16), x.wrapping_add(j + 16)));
        let words = std::mem::transmute::<__m512bh, __m512i>(_mm512_cvtne2ps_pbh(hi, lo));
        let keep: u32 = if left >= 32 { u32::MAX } else { (1u32 << left) - 1 };
        _mm512_mask_storeu_epi16(out.add(j).cast(), keep, words);
        j += 32;
    }
}

/// A product's packed operands ([`product`]): A's pair (i, q) at `a[i·prs + q·pcs]`, B's pair-row q at
/// `b[q·bs ..]`; `mask` selects the last register's columns.
#[cfg(target_arch = "x86_64")]
struct Packed {
    pairs: usize,
    dst: *mut f32,
    dst_rs: usize,
    a: *const u32,
    prs: usize,
    pcs: usize,
    b: *const u32,
    bs: usize,
    mask: u16,
}

/// Every output row, [`ROWS`] at a time, then the rest.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512bf16")]
unsafe fn rows<const NV: usize>(m: usize, op: &Packed) {
    super::direct::each_block!(m, op, block)
}

/// Output rows `i0 .. i0 + R`: R × NV accumulators summed over every pair of the inner dimension, then
/// stored.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512bf16")]
#[inline]
unsafe fn block<const NV: usize, const R: usize>(i0: usize, op: &Packed) {
    let mut acc = [[_mm512_setzero_ps(); NV]; R];
    for q in 0..op.pairs {
        let row = op.b.add(q * op.bs);
        let mut bv: [__m512bh; NV] = [std::mem::transmute::<__m512i, __m512bh>(_mm512_setzero_si512()); NV];
        for (v, b) in bv.iter_mut().enumerate() {
            *b = std::mem::transmute::<__m512i, __m512bh>(_mm512_loadu_si512(row.add(16 * v).cast()));
        }
        for (r, acc) in acc.iter_mut().enumerate() {
            let pair = *op.a.add((i0 + r) * op.prs + q * op.pcs);
            let x = std::mem::transmute::<__m512i, __m512bh>(_mm512_set1_epi32(pair as i32));
            for (s, b) in acc.iter_mut().zip(&bv) {
                *s = _mm512_dpbf16_ps(*s, x, *b);
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

/// This core's rate of bf16 dot products (FLOP/s: 32 products and 32 sums per `VDPBF16PS`), on 12
/// independent chains as [`super::direct::fma_peak`] times FMAs; None without the family.
pub(crate) fn dot_peak(budget: std::time::Duration) -> Option<f64> {
    #[cfg(target_arch = "x86_64")]
    {
        #[target_feature(enable = "avx512f,avx512bf16")]
        unsafe fn chains(n: usize) -> f32 {
            let x = std::mem::transmute::<__m512i, __m512bh>(_mm512_set1_epi32(0x3f80_3f80));
            let y = std::mem::transmute::<__m512i, __m512bh>(_mm512_set1_epi32(0x3a80_3a80));
            let mut acc = [_mm512_setzero_ps(); 12];
            for _ in 0..n {
                for a in acc.iter_mut() {
                    *a = _mm512_dpbf16_ps(*a, x, y);
                }
            }
            // Every chain summed, so that none is computed for nothing.
            acc.iter().map(|&a| _mm512_reduce_add_ps(a)).sum()
        }
        if !available() {
            return None;
        }
        // SAFETY: the family's features were detected just above.
        let rounds = crate::parallel::per_second(budget, 3, || {
            std::hint::black_box(unsafe { chains(1_000_000) });
        });
        Some(rounds * 1e6 * 12.0 * 64.0)
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        let _ = budget;
        None
    }
}

#[cfg(all(test, target_arch = "x86_64"))]
mod tests {
    use super::super::direct::{cases, Case};
    use super::*;

    /// The same product summed by a scalar loop in the family's order: pairs in order, the odd term
    /// before the even one, each exact product added to an f32 sum with one rounding.
    fn reference(c: &Case) -> Vec<f32> {
        let ((a_rs, a_cs), (n, k)) = (c.strides, (c.n, c.k));
        let r = |x: f32| from_bf16(to_bf16(x));
        let mut out = vec![0.0f32; c.m * n];
        for i in 0..c.m {
            for j in 0..n {
                let term = |p: usize| r(c.a[i * a_rs + p * a_cs]) * r(c.b[p * c.b_rs + j]);
                let mut s = 0.0f32;
                for q in 0..k.div_ceil(2) {
                    if 2 * q + 1 < k {
                        s += term(2 * q + 1);
                    }
                    s += term(2 * q);
                }
                out[i * n + j] = s;
            }
        }
        out
    }

    #[test]
    fn rounding_to_bf16_is_to_nearest_even() {
        // 1 + 2⁻⁸ lies halfway between 1 and 1 + 2⁻⁷: to the even one, 1; a little more goes up.
        assert_eq!(from_bf16(to_bf16(1.0 + 2f32.powi(-8))), 1.0);
        assert_eq!(from_bf16(to_bf16(1.0 + 2f32.powi(-8) + 2f32.powi(-20))), 1.0 + 2f32.powi(-7));
        // 1 + 3·2⁻⁸ lies halfway between 1 + 2⁻⁷ (odd) and 1 + 2⁻⁶: up, to the even one.
        assert_eq!(from_bf16(to_bf16(1.0 + 3.0 * 2f32.powi(-8))), 1.0 + 2f32.powi(-6));
        assert_eq!(from_bf16(to_bf16(-2.5)), -2.5);
        assert_eq!(from_bf16(to_bf16(f32::MIN_POSITIVE / 2.0)), 0.0);
        assert!(from_bf16(to_bf16(f32::NAN)).is_nan());
    }

    #[test]
    fn every_shape_sums_in_order_and_within_the_derived_bound() {
        if !available() {
            eprintln!("skipped: no AVX512-BF16 here");
            return;
        }
        for c in cases() {
            let Case { m, n, k, ref a, strides, ref b, b_rs } = c;
            let mut dst = vec![f32::NAN; m * n];
            // SAFETY: this CPU runs the family; A is m·k, B k rows of b_rs ≥ n, dst m × n.
            unsafe { product(m, n, k, dst.as_mut_ptr(), n, a.as_ptr(), strides, b.as_ptr(), b_rs) };
            let expected = reference(&c);
            let at = |i: usize, p: usize| a[i * strides.0 + p * strides.1] as f64;
            for i in 0..m {
                for j in 0..n {
                    let got = dst[i * n + j];
                    assert_eq!(got.to_bits(), expected[i * n + j].to_bits(), "{m} × {n} × {k}, {strides:?}");
                    let exact: f64 = (0..k).map(|p| at(i, p) * b[p * b_rs + j] as f64).sum();
                    let magnitude: f64 = (0..k).map(|p| (at(i, p) * b[p * b_rs + j] as f64).abs()).sum();
                    assert!(
                        (got as f64 - exact).abs() <= bound(k, magnitude),
                        "{m} × {n} × {k}: {got} against {exact}, beyond {}",
                        bound(k, magnitude)
                    );
                }
            }
        }
    }
}
