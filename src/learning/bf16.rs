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
    /// The packed operands of the last product on this thread, reused (no allocation per product): A's,
    /// and B's for a product whose B is not packed beforehand.
    static PACKED_A: std::cell::RefCell<Vec<u32>> = const { std::cell::RefCell::new(Vec::new()) };
    static PACKED_B: std::cell::RefCell<Vec<u32>> = const { std::cell::RefCell::new(Vec::new()) };
}

/// What a product does to each output before storing it: the forward pass's bias and ReLU, or the backward
/// pass's ReLU derivative. The same operations in the same order as the separate passes they replace
/// (`fused.rs`), so the same bits, without a second pass over the output.
#[derive(Clone, Copy, Debug)]
pub(crate) enum Epilogue<'a> {
    /// The sums as they are.
    None,
    /// s + b(j) for column j, then max(·, 0) when `relu` (a NaN gives 0, as `f32::max`).
    Bias { bias: &'a [f32], relu: bool },
    /// s · (1 if x(i, j) > 0 else 0): `x` is `[m × n]` with rows `x_rs` apart, the ReLU output whose
    /// input the product's output is the gradient of.
    ReluMask { x: *const f32, x_rs: usize },
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
    a_strides: (usize, usize),
    b: *const f32,
    b_rs: usize,
) {
    PACKED_B.with_borrow_mut(|pb| {
        pack_b(k, n, b, b_rs, pb);
        product_packed(m, n, k, dst, dst_rs, a, a_strides, pb, Epilogue::None);
    });
}

/// B `[k × n]` (contiguous rows `b_rs` apart, n ≤ [`MAX_WIDTH`]) packed for [`product_packed`] into `out`:
/// pair-row q holds, per column j (padded to whole registers with zeros), bf16(B(2q, j)) in its low half
/// and bf16(B(2q + 1, j)) in its high half (zero past an odd k).
///
/// # Safety
/// The CPU runs the family ([`available`]); B's k rows of n lie inside its buffer.
pub(crate) unsafe fn pack_b(k: usize, n: usize, b: *const f32, b_rs: usize, out: &mut Vec<u32>) {
    assert!(n > 0 && n <= MAX_WIDTH, "a bf16 product is at most {MAX_WIDTH} columns wide");
    #[cfg(not(target_arch = "x86_64"))]
    unreachable!("the bf16 family runs only on x86_64 ({k} × {n} at {b:?}, {b_rs}, {})", out.len());
    #[cfg(target_arch = "x86_64")]
    {
        let (pairs, width) = (k.div_ceil(2), n.div_ceil(16) * 16);
        // Every word is written below (no zeroing pass): the buffer only grows.
        if out.len() < pairs * width {
            out.resize(pairs * width, 0);
        }
        for q in 0..pairs {
            let (row0, row1) = (b.add(2 * q * b_rs), (2 * q + 1 < k).then(|| b.add((2 * q + 1) * b_rs)));
            interleave(n, row0, row1, out.as_mut_ptr().add(q * width), width);
        }
    }
}

/// Wᵀ of a layer's weights W (`outputs × inputs`, row-major) packed as [`pack_b`] packs a B of `inputs`
/// rows and `outputs` columns (the forward pass's z = x·Wᵀ): the same words, read from W's rows, without
/// a transposed copy. Pair-row q, column j holds W(j, 2q) and W(j, 2q + 1): two neighbours in W's row j.
///
/// # Safety
/// The CPU runs the family ([`available`]).
pub(crate) unsafe fn pack_transposed(w: &[f32], outputs: usize, inputs: usize, out: &mut Vec<u32>) {
    assert!(outputs > 0 && outputs <= MAX_WIDTH && w.len() == outputs * inputs, "a bf16 product's weights");
    #[cfg(not(target_arch = "x86_64"))]
    unreachable!("the bf16 family runs only on x86_64 ({outputs} × {inputs}, {})", out.len());
    #[cfg(target_arch = "x86_64")]
    {
        let (pairs, width) = (inputs.div_ceil(2), outputs.div_ceil(16) * 16);
        out.clear();
        out.resize(pairs * width, 0);
        PACKED_A.with_borrow_mut(|row| {
            if row.len() < pairs {
                row.resize(pairs, 0);
            }
            for j in 0..outputs {
                // W's row j has `inputs` elements, `row` room for their `pairs` words.
                convert(inputs, w.as_ptr().add(j * inputs), row.as_mut_ptr().cast());
                if inputs % 2 == 1 {
                    row[pairs - 1] &= 0xffff;
                }
                for (q, &word) in row[..pairs].iter().enumerate() {
                    out[q * width + j] = word;
                }
            }
        });
    }
}

/// [`product`] with B packed beforehand by [`pack_b`] or [`pack_transposed`] (`pb`), and `epilogue` applied
/// to every output as it is stored.
///
/// # Safety
/// As [`product`]; `pb` holds a packing of a `k × n` B; the epilogue's `x` addresses `[m × n]`.
#[cfg(target_arch = "x86_64")]
#[allow(clippy::too_many_arguments)]
pub(crate) unsafe fn product_packed(
    m: usize,
    n: usize,
    k: usize,
    dst: *mut f32,
    dst_rs: usize,
    a: *const f32,
    (a_rs, a_cs): (usize, usize),
    pb: &[u32],
    epilogue: Epilogue,
) {
    assert!(n > 0 && n <= MAX_WIDTH, "a bf16 product is at most {MAX_WIDTH} columns wide");
    let (pairs, nv) = (k.div_ceil(2), n.div_ceil(16));
    assert!(pb.len() >= pairs * nv * 16, "a packed B of {k} × {n}");
    if let Epilogue::Bias { bias, .. } = epilogue {
        assert!(bias.len() >= n, "a bias per column");
    }
    PACKED_A.with_borrow_mut(|pa| {
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
                interleave(m, col0, col1, pa.as_mut_ptr().add(q * m), m);
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
        let op = Packed { pairs, dst, dst_rs, a: pa.as_ptr(), prs, pcs, b: pb.as_ptr(), bs: nv * 16, mask, epilogue };
        match nv {
            1 => rows::<1>(m, &op),
            2 => rows::<2>(m, &op),
            3 => rows::<3>(m, &op),
            _ => rows::<4>(m, &op),
        }
    });
}

/// `out[j]` = bf16(x0[j]) low | bf16(x1[j]) high for j < len (x1 None: zeros high), both runs contiguous,
/// and 0 for len ≤ j < `out_len` (whole registers' padding): 16 at a time with `VCVTNE2PS2BF16` and a
/// permute, the last 1–15 masked. The instruction reads a subnormal as zero, as [`to_bf16`] does.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512bw,avx512bf16")]
unsafe fn interleave(len: usize, x0: *const f32, x1: Option<*const f32>, out: *mut u32, out_len: usize) {
    debug_assert!(out_len >= len);
    // Lanes 0–15 of the converted pair are x0's, 16–31 x1's: word 2j takes x0[j], 2j + 1 x1[j].
    let order = _mm512_set_epi16(
        31, 15, 30, 14, 29, 13, 28, 12, 27, 11, 26, 10, 25, 9, 24, 8, 23, 7, 22, 6, 21, 5, 20, 4, 19, 3, 18, 2, 17, 1,
        16, 0,
    );
    let mut j = 0;
    while j < out_len {
        let mask: u16 = if len.saturating_sub(j) >= 16 { u16::MAX } else { (1u16 << len.saturating_sub(j)) - 1 };
        let lo = _mm512_maskz_loadu_ps(mask, x0.wrapping_add(j));
        let hi = x1.map_or(_mm512_setzero_ps(), |x1| _mm512_maskz_loadu_ps(mask, x1.wrapping_add(j)));
        let both = std::mem::transmute::<__m512bh, __m512i>(_mm512_cvtne2ps_pbh(hi, lo));
        // Lanes past len are zeros (masked loads): stored up to out_len.
        let store: u16 = if out_len - j >= 16 { u16::MAX } else { (1u16 << (out_len - j)) - 1 };
        _mm512_mask_storeu_epi32(out.add(j).cast(), store, _mm512_permutexvar_epi16(order, both));
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
/// `b[q·bs ..]`; `mask` selects the last register's columns; `epilogue` applies to each output stored.
#[cfg(target_arch = "x86_64")]
struct Packed<'a> {
    pairs: usize,
    dst: *mut f32,
    dst_rs: usize,
    a: *const u32,
    prs: usize,
    pcs: usize,
    b: *const u32,
    bs: usize,
    mask: u16,
    epilogue: Epilogue<'a>,
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
    let (zero, one) = (_mm512_setzero_ps(), _mm512_set1_ps(1.0));
    for (r, acc) in acc.iter().enumerate() {
        let out = op.dst.add((i0 + r) * op.dst_rs);
        for (v, &s) in acc.iter().enumerate() {
            let mask = if v + 1 < NV { u16::MAX } else { op.mask };
            let s = match op.epilogue {
                Epilogue::None => s,
                Epilogue::Bias { bias, relu } => {
                    let s = _mm512_add_ps(s, _mm512_maskz_loadu_ps(mask, bias.as_ptr().add(16 * v)));
                    // MAXPS returns its second operand when either is a NaN: 0, as f32::max(NaN, 0).
                    if relu {
                        _mm512_max_ps(s, zero)
                    } else {
                        s
                    }
                }
                Epilogue::ReluMask { x, x_rs } => {
                    let x = _mm512_maskz_loadu_ps(mask, x.add((i0 + r) * x_rs + 16 * v));
                    _mm512_mul_ps(s, _mm512_mask_blend_ps(_mm512_cmp_ps_mask::<_CMP_GT_OQ>(x, zero), zero, one))
                }
            };
            if v + 1 < NV {
                _mm512_storeu_ps(out.add(16 * v), s);
            } else {
                _mm512_mask_storeu_ps(out.add(16 * v), op.mask, s);
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

    #[test]
    fn weights_packed_from_w_are_the_words_of_its_transposed_copy_packed() {
        if !available() {
            eprintln!("skipped: no AVX512-BF16 here");
            return;
        }
        for (outputs, inputs) in [(64, 54), (64, 64), (2, 64), (1, 64), (17, 5), (33, 1), (16, 3)] {
            let w: Vec<f32> = (0..outputs * inputs).map(|i| ((i * 7919) % 1000) as f32 / 997.0 - 0.5).collect();
            let mut t = vec![0.0; w.len()];
            for j in 0..outputs {
                for p in 0..inputs {
                    t[p * outputs + j] = w[j * inputs + p];
                }
            }
            let (mut from_w, mut from_t) = (vec![u32::MAX; 3], vec![u32::MAX; 5000]);
            // SAFETY: this CPU runs the family; t is inputs rows of `outputs`.
            unsafe {
                pack_transposed(&w, outputs, inputs, &mut from_w);
                pack_b(inputs, outputs, t.as_ptr(), outputs, &mut from_t);
            }
            assert_eq!(from_w[..], from_t[..from_w.len()], "{outputs} × {inputs}");
        }
    }

    #[test]
    fn epilogues_give_the_bits_of_the_passes_they_replace() {
        if !available() {
            eprintln!("skipped: no AVX512-BF16 here");
            return;
        }
        for c in cases().into_iter().filter(|c| c.strides.1 == 1) {
            let Case { m, n, k, ref a, strides, ref b, b_rs } = c;
            // Every kind of value the passes meet: signs, zeros of both signs, a NaN.
            let special = [0.0, -0.0, f32::NAN, -1.5, 2.0];
            let bias: Vec<f32> =
                (0..n).map(|j| if j % 7 == 3 { special[j % 5] } else { j as f32 / 9.0 - 2.0 }).collect();
            let x: Vec<f32> = (0..m * n).map(|i| special[i % 5] * (i % 3) as f32).collect();
            let mut plain = vec![0.0; m * n];
            let mut pb = vec![];
            // SAFETY: this CPU runs the family; A is m·k, B k rows of b_rs ≥ n, dst and x m × n.
            unsafe {
                product(m, n, k, plain.as_mut_ptr(), n, a.as_ptr(), strides, b.as_ptr(), b_rs);
                pack_b(k, n, b.as_ptr(), b_rs, &mut pb);
            }
            let with = |epilogue: Epilogue| {
                let mut dst = vec![f32::NAN; m * n];
                // SAFETY: as above.
                unsafe { product_packed(m, n, k, dst.as_mut_ptr(), n, a.as_ptr(), strides, &pb, epilogue) };
                dst.iter().map(|v| v.to_bits()).collect::<Vec<u32>>()
            };
            let passes = |f: &dyn Fn(usize, f32) -> f32| {
                plain.iter().enumerate().map(|(i, &v)| f(i, v).to_bits()).collect::<Vec<u32>>()
            };
            assert_eq!(with(Epilogue::None), passes(&|_, v| v), "{m} × {n} × {k}");
            assert_eq!(with(Epilogue::Bias { bias: &bias, relu: false }), passes(&|i, v| v + bias[i % n]));
            // Zeros' signs may differ from `f32::max`'s (either sign is a maximum of ±0): they never change
            // a later sum, which starts from +0. Compared as values, and NaN as NaN.
            let relu = with(Epilogue::Bias { bias: &bias, relu: true });
            for (i, (&got, &v)) in relu.iter().zip(&plain).enumerate() {
                let want = (v + bias[i % n]).max(0.0);
                assert!(f32::from_bits(got) == want || (f32::from_bits(got).is_nan() && want.is_nan()), "ReLU at {i}");
            }
            let mask = Epilogue::ReluMask { x: x.as_ptr(), x_rs: n };
            assert_eq!(with(mask), passes(&|i, v| v * if x[i] > 0.0 { 1.0 } else { 0.0 }), "{m} × {n} × {k}");
        }
    }
}
