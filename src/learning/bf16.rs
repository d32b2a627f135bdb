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

#[cfg(target_arch = "x86_64")]
use super::direct::lanes;
/// The widest narrow operand, as [`super::direct::MAX_WIDTH`].
pub(crate) use super::direct::MAX_WIDTH;

/// Output rows summed together: 6 × 4 accumulators, as [`super::direct`].
const ROWS: usize = 6;
// Pairs of output rows never straddle two blocks ([`Forms`]' pairs of rows).
const _: () = assert!(ROWS.is_multiple_of(2));

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
    /// input the product's output is the gradient of. Each output row is then added to `sums` (n
    /// columns; null: none), rows in order: the bias gradient, summed as `fused.rs` sums it.
    ReluMask { x: *const f32, x_rs: usize, sums: *mut f32 },
}

/// A product's left operand A `[m × k]`: f32 elements, or bf16 words packed beforehand (a product's
/// [`Forms`]).
#[derive(Clone, Copy, Debug)]
pub(crate) enum Lhs<'a> {
    /// A(i, p) = `a[i·rs + p·cs]`, rounded to bf16 as the product packs it.
    F32 { a: *const f32, rs: usize, cs: usize },
    /// The words of A's pair (i, q), A(i, 2q) low and A(i, 2q + 1) high, at `words[i·prs + q·pcs]`.
    Packed { words: &'a [u32], prs: usize, pcs: usize },
}

/// A product's right operand B `[k × n]`, n ≤ [`MAX_WIDTH`]: f32 rows, or packed beforehand as [`pack_b`]
/// packs them.
#[derive(Clone, Copy, Debug)]
pub(crate) enum Rhs<'a> {
    /// B(p, j) = `b[p·rs + j]`.
    F32 {
        b: *const f32,
        rs: usize,
    },
    Packed(&'a [u32]),
}

/// The bf16 forms of an `m × n` matrix a product wrote, for the products that read it next, as the
/// product would have packed it from the f32 values it stored (the same instruction on the same values,
/// so the same words): `rows`, each row's words in order (⌈n/2⌉ a row, an odd n's last high half zero),
/// a row-major A; `pairs`, rows 2q and 2q + 1 interleaved column by column (⌈n/16⌉·16 words a pair-row,
/// zeros past n and past an odd m's last row): [`pack_b`]'s B, and an A read by columns (Aᵀ).
#[derive(Clone, Debug, Default)]
pub(crate) struct Forms {
    rows: Vec<u32>,
    pairs: Vec<u32>,
    /// (m, n) of the matrix the forms hold, None until a product writes them.
    shape: Option<(usize, usize)>,
    /// Whether `pairs` holds it too.
    pairs_held: bool,
}

impl Forms {
    /// No forms: the matrix was written by another family's product, or not by a product.
    pub(crate) fn clear(&mut self) {
        self.shape = None;
    }

    /// The matrix `[m × n]` as a product's A, if these forms hold it.
    pub(crate) fn rows_of(&self, m: usize, n: usize) -> Option<Lhs<'_>> {
        (self.shape == Some((m, n))).then(|| Lhs::Packed { words: &self.rows, prs: n.div_ceil(2), pcs: 1 })
    }

    /// Its transpose `[n × m]` as a product's A (its columns paired), if these forms hold it.
    pub(crate) fn transposed_of(&self, m: usize, n: usize) -> Option<Lhs<'_>> {
        (self.shape == Some((m, n)) && self.pairs_held).then(|| Lhs::Packed {
            words: &self.pairs,
            prs: 1,
            pcs: n.div_ceil(16) * 16,
        })
    }

    /// The matrix as a product's B, if these forms hold it.
    pub(crate) fn pairs_of(&self, m: usize, n: usize) -> Option<Rhs<'_>> {
        (self.shape == Some((m, n)) && self.pairs_held).then_some(Rhs::Packed(&self.pairs))
    }

    /// Room for the forms of an `[m × n]` matrix.
    fn shape_for(&mut self, m: usize, n: usize) {
        self.shape = None;
        grow(&mut self.rows, m * n.div_ceil(2));
        grow(&mut self.pairs, m.div_ceil(2) * n.div_ceil(16) * 16);
    }
}

/// `v` holds at least `len` words (its contents are overwritten before they are read).
fn grow(v: &mut Vec<u32>, len: usize) {
    if v.len() < len {
        v.resize(len, 0);
    }
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
    let (a, b) = (Lhs::F32 { a, rs: a_rs, cs: a_cs }, Rhs::F32 { b, rs: b_rs });
    product_with(m, n, k, dst, dst_rs, a, b, Epilogue::None, None, false);
}

/// B `[k × n]` (contiguous rows `b_rs` apart, n ≤ [`MAX_WIDTH`]) packed for [`product_with`] into `out`:
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
        grow(out, pairs * width);
        for q in 0..pairs {
            let (row0, row1) = (b.add(2 * q * b_rs), (2 * q + 1 < k).then(|| b.add((2 * q + 1) * b_rs)));
            interleave(n, row0, row1, out.as_mut_ptr().add(q * width), width);
        }
    }
}

/// Wᵀ of a layer's weights W (`outputs × inputs`, row-major) packed as [`pack_b`] packs a B of `inputs`
/// rows and `outputs` columns (the forward pass's z = x·Wᵀ): the same words, made from W's rows without a
/// transposed f32 copy. Pair-row q, column j holds W(j, 2q) and W(j, 2q + 1), two neighbours in W's row
/// j: each row is converted to its bf16 words (as [`convert`] converts a row-major A), and the words are
/// transposed 16 × 16 at a time in registers.
///
/// # Safety
/// The CPU runs the family ([`available`]).
pub(crate) unsafe fn pack_transposed(w: &[f32], outputs: usize, inputs: usize, out: &mut Vec<u32>) {
    assert!(outputs > 0 && outputs <= MAX_WIDTH && w.len() == outputs * inputs, "a bf16 product's weights");
    #[cfg(not(target_arch = "x86_64"))]
    unreachable!("the bf16 family runs only on x86_64 ({outputs} × {inputs}, {})", out.len());
    #[cfg(target_arch = "x86_64")]
    WORDS.with_borrow_mut(|words| transpose_words(w, outputs, inputs, words, out));
}

#[cfg(target_arch = "x86_64")]
thread_local! {
    /// W's rows as bf16 words, padded to whole 16 × 16 blocks ([`pack_transposed`]).
    static WORDS: std::cell::RefCell<Vec<u32>> = const { std::cell::RefCell::new(Vec::new()) };
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512bw,avx512bf16")]
unsafe fn transpose_words(w: &[f32], outputs: usize, inputs: usize, words: &mut Vec<u32>, out: &mut Vec<u32>) {
    let (pairs, width) = (inputs.div_ceil(2), outputs.div_ceil(16) * 16);
    let padded = pairs.div_ceil(16) * 16;
    // Row j's words, and zeros past them (an odd row's last high half too: `convert` writes only `inputs`
    // halves) and in the rows past `outputs`.
    words.clear();
    words.resize(width * padded, 0);
    for j in 0..outputs {
        convert(inputs, w.as_ptr().add(j * inputs), words.as_mut_ptr().add(j * padded).cast());
    }
    // Every word of out is written below: the buffer only grows.
    grow(out, pairs * width);
    for j in (0..width).step_by(16) {
        for q in (0..padded).step_by(16) {
            let mut block: [__m512i; 16] = [_mm512_setzero_si512(); 16];
            for (r, row) in block.iter_mut().enumerate() {
                *row = _mm512_loadu_si512(words.as_ptr().add((j + r) * padded + q).cast());
            }
            let columns = transpose16(&block);
            for (c, column) in columns.iter().enumerate().take(pairs.saturating_sub(q)) {
                _mm512_storeu_si512(out.as_mut_ptr().add((q + c) * width + j).cast(), *column);
            }
        }
    }
}

/// The transpose of 16 rows of 16 words: column c of the result holds word c of every row, in row order.
/// Words interleaved in pairs, then in fours, within 128-bit lanes; then the lanes of four registers
/// exchanged.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
#[inline]
unsafe fn transpose16(r: &[__m512i; 16]) -> [__m512i; 16] {
    // t: rows 2i and 2i + 1 interleaved (lane L: words 4L, 4L + 1 in t[2i]; 4L + 2, 4L + 3 in t[2i + 1]).
    let mut t = [_mm512_setzero_si512(); 16];
    for i in 0..8 {
        t[2 * i] = _mm512_unpacklo_epi32(r[2 * i], r[2 * i + 1]);
        t[2 * i + 1] = _mm512_unpackhi_epi32(r[2 * i], r[2 * i + 1]);
    }
    // u[4g + c], lane L: rows 4g .. 4g + 4 of column 4L + c.
    let mut u = [_mm512_setzero_si512(); 16];
    for g in 0..4 {
        u[4 * g] = _mm512_unpacklo_epi64(t[4 * g], t[4 * g + 2]);
        u[4 * g + 1] = _mm512_unpackhi_epi64(t[4 * g], t[4 * g + 2]);
        u[4 * g + 2] = _mm512_unpacklo_epi64(t[4 * g + 1], t[4 * g + 3]);
        u[4 * g + 3] = _mm512_unpackhi_epi64(t[4 * g + 1], t[4 * g + 3]);
    }
    // Column 4L + c: lane L of u[c], u[4 + c], u[8 + c] and u[12 + c], in that order.
    let mut out = [_mm512_setzero_si512(); 16];
    for c in 0..4 {
        let v0 = _mm512_shuffle_i32x4::<0x44>(u[c], u[4 + c]);
        let v1 = _mm512_shuffle_i32x4::<0xEE>(u[c], u[4 + c]);
        let v2 = _mm512_shuffle_i32x4::<0x44>(u[8 + c], u[12 + c]);
        let v3 = _mm512_shuffle_i32x4::<0xEE>(u[8 + c], u[12 + c]);
        out[c] = _mm512_shuffle_i32x4::<0x88>(v0, v2);
        out[4 + c] = _mm512_shuffle_i32x4::<0xDD>(v0, v2);
        out[8 + c] = _mm512_shuffle_i32x4::<0x88>(v1, v3);
        out[12 + c] = _mm512_shuffle_i32x4::<0xDD>(v1, v3);
    }
    out
}

/// dst `[m × n]` (row stride `dst_rs`) = A·B as [`product`], from operands given either way, `epilogue`
/// applied to every output as it is stored, and the outputs' bf16 [`Forms`] written into `forms` when
/// given: the rows form, and the pairs form too when `keep_pairs` (only a weight gradient reads it).
///
/// # Safety
/// As [`product`]; a packed operand holds a packing of its shape; the epilogue's `x` addresses `[m × n]`.
#[cfg(target_arch = "x86_64")]
#[allow(clippy::too_many_arguments)]
pub(crate) unsafe fn product_with(
    m: usize,
    n: usize,
    k: usize,
    dst: *mut f32,
    dst_rs: usize,
    a: Lhs,
    b: Rhs,
    epilogue: Epilogue,
    forms: Option<&mut Forms>,
    keep_pairs: bool,
) {
    assert!(n > 0 && n <= MAX_WIDTH, "a bf16 product is at most {MAX_WIDTH} columns wide");
    let (pairs, nv) = (k.div_ceil(2), n.div_ceil(16));
    if let Epilogue::Bias { bias, .. } = epilogue {
        assert!(bias.len() >= n, "a bias per column");
    }
    let mut forms = forms;
    let (rows_out, pairs_out) = match forms.as_deref_mut() {
        Some(f) => {
            f.shape_for(m, n);
            (f.rows.as_mut_ptr(), if keep_pairs { f.pairs.as_mut_ptr() } else { std::ptr::null_mut() })
        }
        None => (std::ptr::null_mut(), std::ptr::null_mut()),
    };
    PACKED_B.with_borrow_mut(|packed_b| {
        let pb: &[u32] = match b {
            Rhs::Packed(words) => words,
            Rhs::F32 { b, rs } => {
                pack_b(k, n, b, rs, packed_b);
                packed_b
            }
        };
        assert!(pb.len() >= pairs * nv * 16, "a packed B of {k} × {n}");
        PACKED_A.with_borrow_mut(|pa| {
            let (a, prs, pcs) = match a {
                Lhs::Packed { words, prs, pcs } => {
                    assert!(
                        m == 0 || pairs == 0 || words.len() > (m - 1) * prs + (pairs - 1) * pcs,
                        "a packed A of {m} × {k}"
                    );
                    (words.as_ptr(), prs, pcs)
                }
                Lhs::F32 { a, rs, cs } => pack_a(m, k, a, (rs, cs), pa),
            };
            let mask = lanes(n - (nv - 1) * 16);
            let op = Packed {
                pairs,
                dst,
                dst_rs,
                a,
                prs,
                pcs,
                b: pb.as_ptr(),
                bs: nv * 16,
                mask,
                epilogue,
                rows_out,
                row_words: n.div_ceil(2),
                pairs_out,
            };
            let lanes_for_rows = n <= NARROW && !matches!(epilogue, Epilogue::ReluMask { .. }) && rows_out.is_null();
            match nv {
                1 if lanes_for_rows && (pcs == 1 || prs == 1) => match n {
                    1 => narrow::<1, 8>(m, &op),
                    2 => narrow::<2, 4>(m, &op),
                    3 => narrow::<3, 2>(m, &op),
                    _ => narrow::<4, 2>(m, &op),
                },
                1 => rows::<1, 24>(m, &op),
                2 => rows::<2, 12>(m, &op),
                3 => rows::<3, 8>(m, &op),
                _ => rows::<4, 6>(m, &op),
            }
        });
    });
    if let Some(f) = forms {
        (f.shape, f.pairs_held) = (Some((m, n)), keep_pairs);
    }
}

/// A `[m × k]` (A(i, p) = `a[i·a_rs + p·a_cs]`) packed into `pa`: per output row i and pair q, A(i, 2q) low
/// and A(i, 2q + 1) high, laid out so that the pairs are written in runs: by row when A's rows are
/// contiguous, by pair when its columns are. Returns the packed words and their (row, pair) strides.
#[cfg(target_arch = "x86_64")]
unsafe fn pack_a(
    m: usize,
    k: usize,
    a: *const f32,
    (a_rs, a_cs): (usize, usize),
    pa: &mut Vec<u32>,
) -> (*const u32, usize, usize) {
    let pairs = k.div_ceil(2);
    grow(pa, m * pairs);
    let by_pair = a_rs == 1 && a_cs != 1;
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
    let (prs, pcs) = if by_pair { (1, m) } else { (pairs, 1) };
    (pa.as_ptr(), prs, pcs)
}

/// `out[j]` = bf16(x0[j]) low | bf16(x1[j]) high for j < len (x1 None: zeros high), both runs contiguous,
/// and 0 for len ≤ j < `out_len` (whole registers' padding): 16 at a time with `VCVTNE2PS2BF16` and a
/// permute, the last 1–15 masked. The instruction reads a subnormal as zero, as [`to_bf16`] does.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512bw,avx512bf16")]
unsafe fn interleave(len: usize, x0: *const f32, x1: Option<*const f32>, out: *mut u32, out_len: usize) {
    debug_assert!(out_len >= len);
    let order = pair_order();
    let mut j = 0;
    while j < out_len {
        let mask = lanes(len.saturating_sub(j));
        let lo = _mm512_maskz_loadu_ps(mask, x0.wrapping_add(j));
        let hi = x1.map_or(_mm512_setzero_ps(), |x1| _mm512_maskz_loadu_ps(mask, x1.wrapping_add(j)));
        let both = std::mem::transmute::<__m512bh, __m512i>(_mm512_cvtne2ps_pbh(hi, lo));
        // Lanes past len are zeros (masked loads): stored up to out_len.
        let store = lanes(out_len - j);
        _mm512_mask_storeu_epi32(out.add(j).cast(), store, _mm512_permutexvar_epi16(order, both));
        j += 16;
    }
}

/// The permutation that takes two converted runs (lanes 0–15 from x0, 16–31 from x1) to pairs: word j of
/// the result holds x0[j] low and x1[j] high.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
#[inline]
unsafe fn pair_order() -> __m512i {
    _mm512_set_epi16(
        31, 15, 30, 14, 29, 13, 28, 12, 27, 11, 26, 10, 25, 9, 24, 8, 23, 7, 22, 6, 21, 5, 20, 4, 19, 3, 18, 2, 17, 1,
        16, 0,
    )
}

/// `out[j]` = bf16(x[j]) for j < len: 32 at a time with `VCVTNE2PS2BF16`, the last 1–31 masked.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512bw,avx512bf16")]
unsafe fn convert(len: usize, x: *const f32, out: *mut u16) {
    let mut j = 0;
    while j < len {
        let left = len - j;
        let mask = |from: usize| lanes(left.saturating_sub(from));
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
    /// Where the outputs' [`Forms`] go (null: nowhere): `row_words` words a row, and whole registers a
    /// pair of rows.
    rows_out: *mut u32,
    row_words: usize,
    pairs_out: *mut u32,
}

/// The widest product [`narrow`] takes: the output layers' one or two columns (and a little room).
const NARROW: usize = 4;

/// A product of at most [`NARROW`] columns with the output rows in the registers' lanes, 16 rows a
/// register, where [`rows`] would put the columns there and leave 14 or 15 of every 16 lanes idle: `G`
/// registers of rows at a time (G × N sums going at once, to hide each one's latency), then one. For
/// each pair q, the 16 rows' words of A (read down a column of the packed A, or transposed 16 × 16 in
/// registers from its rows) meet B's word (q, j) broadcast. Each lane sums its row's pairs in order from
/// zero, with the same instruction on the same two words as [`block`] (the two products of a pair do not
/// depend on which operand is which), so every output has the same bits; the epilogue is [`finish`]'s.
/// Neither a mask epilogue nor [`Forms`] (only hidden layers keep them).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512bw,avx512bf16")]
unsafe fn narrow<const N: usize, const G: usize>(m: usize, op: &Packed) {
    debug_assert!(N <= NARROW && op.rows_out.is_null() && (op.pcs == 1 || op.prs == 1));
    let mut i0 = 0;
    while i0 + 16 * G <= m {
        narrow_block::<N, G>(i0, m, op);
        i0 += 16 * G;
    }
    while i0 < m {
        narrow_block::<N, 1>(i0, m, op);
        i0 += 16;
    }
}

/// Rows `i0 .. i0 + 16·G` of a [`narrow`] product (rows past m are zeros, and never stored).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512bw,avx512bf16")]
#[inline]
unsafe fn narrow_block<const N: usize, const G: usize>(i0: usize, m: usize, op: &Packed) {
    let (zero, zero_ps) = (_mm512_setzero_si512(), _mm512_setzero_ps());
    let mut acc = [[zero_ps; N]; G];
    // x[g][c]: pair q0 + c of the rows of register g.
    let mut x = [[zero; 16]; G];
    for q0 in (0..op.pairs).step_by(16) {
        let chunk = (op.pairs - q0).min(16);
        for (g, x) in x.iter_mut().enumerate() {
            let (first, live) = (i0 + 16 * g, m.saturating_sub(i0 + 16 * g).min(16));
            if op.pcs == 1 {
                let mut rows = [zero; 16];
                for (r, row) in rows.iter_mut().enumerate().take(live) {
                    *row = _mm512_maskz_loadu_epi32(lanes(chunk), op.a.add((first + r) * op.prs + q0).cast());
                }
                *x = transpose16(&rows);
            } else {
                for (c, column) in x.iter_mut().enumerate().take(chunk) {
                    *column = _mm512_maskz_loadu_epi32(lanes(live), op.a.add((q0 + c) * op.pcs + first).cast());
                }
            }
        }
        for c in 0..chunk {
            let w: [__m512bh; N] = std::array::from_fn(|j| {
                std::mem::transmute::<__m512i, __m512bh>(_mm512_set1_epi32(*op.b.add((q0 + c) * op.bs + j) as i32))
            });
            for (acc, x) in acc.iter_mut().zip(&x) {
                let x = std::mem::transmute::<__m512i, __m512bh>(x[c]);
                for (acc, w) in acc.iter_mut().zip(&w) {
                    *acc = _mm512_dpbf16_ps(*acc, x, *w);
                }
            }
        }
    }
    for (g, acc) in acc.iter().enumerate() {
        let (first, live) = (i0 + 16 * g, m.saturating_sub(i0 + 16 * g).min(16));
        if live == 0 {
            continue;
        }
        for (j, acc) in acc.iter().enumerate() {
            let s = match op.epilogue {
                Epilogue::None => *acc,
                Epilogue::Bias { bias, relu } => {
                    let s = _mm512_add_ps(*acc, _mm512_set1_ps(bias[j]));
                    // As finish: MAXPS gives 0 for a NaN.
                    if relu {
                        _mm512_max_ps(s, zero_ps)
                    } else {
                        s
                    }
                }
                Epilogue::ReluMask { .. } => unreachable!("a narrow product takes no mask"),
            };
            if N == 1 && op.dst_rs == 1 {
                _mm512_mask_storeu_ps(op.dst.add(first), lanes(live), s);
            } else {
                let mut row = [0.0f32; 16];
                _mm512_storeu_ps(row.as_mut_ptr(), s);
                for (r, v) in row.iter().enumerate().take(live) {
                    *op.dst.add((first + r) * op.dst_rs + j) = *v;
                }
            }
        }
    }
}

/// Every output row: `WIDE` at a time (WIDE × NV = 24 accumulators), then [`ROWS`] at a time, then the
/// rest. A narrow product (one or two registers a row: the output layer's one or two columns) would
/// otherwise keep only 6 or 12 sums going at once, each waiting on the latency of the one before; the
/// order of each output's sum is the same whatever the block.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512bw,avx512bf16")]
unsafe fn rows<const NV: usize, const WIDE: usize>(m: usize, op: &Packed) {
    const { assert!(WIDE.is_multiple_of(2) && WIDE * NV <= 24) };
    let mut i = 0;
    while WIDE > ROWS && i + WIDE <= m {
        block::<NV, WIDE>(i, op);
        i += WIDE;
    }
    super::direct::each_block!(m, op, block, i)
}

/// Output rows `i0 .. i0 + R`: R × NV accumulators summed over every pair of the inner dimension, then
/// stored.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512bw,avx512bf16")]
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
    // Rows in pairs (i0 is even: blocks start at multiples of ROWS), as the pairs form wants them; a last
    // row alone is paired with zeros.
    let sums = match op.epilogue {
        Epilogue::ReluMask { sums, .. } if !sums.is_null() => sums,
        _ => std::ptr::null_mut(),
    };
    let column_mask = |v: usize| if v + 1 < NV { u16::MAX } else { op.mask };
    let mut sum = [_mm512_setzero_ps(); NV];
    if !sums.is_null() {
        for (v, sum) in sum.iter_mut().enumerate() {
            *sum = _mm512_maskz_loadu_ps(column_mask(v), sums.add(16 * v));
        }
    }
    let mut r = 0;
    while r < R {
        let low = finish::<NV>(op, i0 + r, &acc[r]);
        let high = if r + 1 < R { finish::<NV>(op, i0 + r + 1, &acc[r + 1]) } else { [_mm512_setzero_ps(); NV] };
        if !sums.is_null() {
            // Row by row, in order (the columns past n are zeros, and never stored).
            for (v, sum) in sum.iter_mut().enumerate() {
                *sum = _mm512_add_ps(*sum, low[v]);
                if r + 1 < R {
                    *sum = _mm512_add_ps(*sum, high[v]);
                }
            }
        }
        if !op.rows_out.is_null() {
            rows_form::<NV>(op, i0 + r, &low);
            if r + 1 < R {
                rows_form::<NV>(op, i0 + r + 1, &high);
            }
        }
        if !op.pairs_out.is_null() {
            let words = op.pairs_out.add((i0 + r) / 2 * NV * 16);
            for v in 0..NV {
                let both = std::mem::transmute::<__m512bh, __m512i>(_mm512_cvtne2ps_pbh(high[v], low[v]));
                _mm512_storeu_si512(words.add(16 * v).cast(), _mm512_permutexvar_epi16(pair_order(), both));
            }
        }
        r += 2;
    }
    if !sums.is_null() {
        for (v, sum) in sum.iter().enumerate() {
            _mm512_mask_storeu_ps(sums.add(16 * v), column_mask(v), *sum);
        }
    }
}

/// Output row i's sums `acc` through the epilogue, stored; returned with the columns past n zeroed, for
/// the forms (whatever the sums there: a NaN from an infinite A).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512bw,avx512bf16")]
#[inline]
unsafe fn finish<const NV: usize>(op: &Packed, i: usize, acc: &[__m512; NV]) -> [__m512; NV] {
    let (zero, one) = (_mm512_setzero_ps(), _mm512_set1_ps(1.0));
    let dst = op.dst.add(i * op.dst_rs);
    let mut out = [zero; NV];
    for v in 0..NV {
        let mask = if v + 1 < NV { u16::MAX } else { op.mask };
        let s = match op.epilogue {
            Epilogue::None => acc[v],
            Epilogue::Bias { bias, relu } => {
                let s = _mm512_add_ps(acc[v], _mm512_maskz_loadu_ps(mask, bias.as_ptr().add(16 * v)));
                // MAXPS returns its second operand when either is a NaN: 0, as f32::max(NaN, 0).
                if relu {
                    _mm512_max_ps(s, zero)
                } else {
                    s
                }
            }
            Epilogue::ReluMask { x, x_rs, .. } => {
                let x = _mm512_maskz_loadu_ps(mask, x.add(i * x_rs + 16 * v));
                _mm512_mul_ps(acc[v], _mm512_mask_blend_ps(_mm512_cmp_ps_mask::<_CMP_GT_OQ>(x, zero), zero, one))
            }
        };
        if v + 1 < NV {
            _mm512_storeu_ps(dst.add(16 * v), s);
        } else {
            _mm512_mask_storeu_ps(dst.add(16 * v), op.mask, s);
        }
        out[v] = _mm512_maskz_mov_ps(mask, s);
    }
    out
}

/// Row i's words in its rows form: 32 columns (two registers) a conversion, the last one masked.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512bw,avx512bf16")]
#[inline]
unsafe fn rows_form<const NV: usize>(op: &Packed, i: usize, row: &[__m512; NV]) {
    let words = op.rows_out.add(i * op.row_words);
    for v in 0..NV.div_ceil(2) {
        let high = if 2 * v + 1 < NV { row[2 * v + 1] } else { _mm512_setzero_ps() };
        let both = std::mem::transmute::<__m512bh, __m512i>(_mm512_cvtne2ps_pbh(high, row[2 * v]));
        _mm512_mask_storeu_epi32(words.add(16 * v).cast(), lanes(op.row_words - 16 * v), both);
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

    /// The values' bits, for comparing results exactly (NaN included).
    fn bits(v: &[f32]) -> Vec<u32> {
        v.iter().map(|x| x.to_bits()).collect()
    }

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
    fn a_single_row_is_the_same_at_any_row_stride() {
        if !available() {
            eprintln!("skipped: no AVX512-BF16 here");
            return;
        }
        // One output row may be stored at any row stride: also 1, where a narrow product (rows in the
        // lanes) must still put column j at j.
        for c in cases().into_iter().filter(|c| c.m == 1 || c.n <= 4) {
            let Case { n, k, ref a, strides, ref b, b_rs, .. } = c;
            let (mut packed, mut strided) = (vec![f32::NAN; n], vec![f32::NAN; n]);
            // SAFETY: this CPU runs the family; A's first row is k long, B k rows of b_rs ≥ n, dst 1 × n.
            unsafe {
                product(1, n, k, packed.as_mut_ptr(), n, a.as_ptr(), strides, b.as_ptr(), b_rs);
                product(1, n, k, strided.as_mut_ptr(), 1, a.as_ptr(), strides, b.as_ptr(), b_rs);
            }
            assert_eq!(bits(&strided), bits(&packed), "1 × {n} × {k}");
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
                unsafe {
                    let a = Lhs::F32 { a: a.as_ptr(), rs: strides.0, cs: strides.1 };
                    product_with(m, n, k, dst.as_mut_ptr(), n, a, Rhs::Packed(&pb), epilogue, None, false)
                };
                bits(&dst)
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
            let mask = Epilogue::ReluMask { x: x.as_ptr(), x_rs: n, sums: std::ptr::null_mut() };
            let masked = passes(&|i, v| v * if x[i] > 0.0 { 1.0 } else { 0.0 });
            assert_eq!(with(mask), masked, "{m} × {n} × {k}");
            // The column sums it keeps: row by row from zero, as `fused.rs` sums a bias gradient.
            let mut sums = vec![0.0f32; n];
            let summing = Epilogue::ReluMask { x: x.as_ptr(), x_rs: n, sums: sums.as_mut_ptr() };
            assert_eq!(with(summing), masked);
            let mut want = vec![0.0f32; n];
            for row in masked.chunks_exact(n) {
                want.iter_mut().zip(row).for_each(|(s, &d)| *s += f32::from_bits(d));
            }
            assert_eq!(bits(&sums), bits(&want), "{m} × {n} × {k}");
        }
    }

    #[test]
    fn the_forms_a_product_keeps_are_the_words_its_outputs_would_be_packed_into() {
        if !available() {
            eprintln!("skipped: no AVX512-BF16 here");
            return;
        }
        for c in cases() {
            let Case { m, n, k, mut a, strides, ref b, b_rs } = c;
            // An infinite operand makes NaN sums in the padding columns too: the forms keep zeros there,
            // whatever the epilogue does to a NaN (a ReLU gives 0, a mask by 0 keeps it).
            a[0] = f32::INFINITY;
            let bias: Vec<f32> = (0..n).map(|j| j as f32 / 7.0 - 1.0).collect();
            let x: Vec<f32> = (0..m * n).map(|i| if i % 3 == 0 { -1.0 } else { 0.5 }).collect();
            let mut sums = vec![0.0f32; n];
            let epilogues = [
                Epilogue::None,
                Epilogue::Bias { bias: &bias, relu: true },
                Epilogue::Bias { bias: &bias, relu: false },
                Epilogue::ReluMask { x: x.as_ptr(), x_rs: n, sums: std::ptr::null_mut() },
                Epilogue::ReluMask { x: x.as_ptr(), x_rs: n, sums: sums.as_mut_ptr() },
            ];
            for epilogue in epilogues {
                let (mut dst, mut forms) = (vec![0.0f32; m * n], Forms::default());
                let lhs = Lhs::F32 { a: a.as_ptr(), rs: strides.0, cs: strides.1 };
                let rhs = Rhs::F32 { b: b.as_ptr(), rs: b_rs };
                // SAFETY: this CPU runs the family; A is m·k, B k rows of b_rs ≥ n, dst and x m × n, sums n.
                unsafe { product_with(m, n, k, dst.as_mut_ptr(), n, lhs, rhs, epilogue, Some(&mut forms), true) };
                let (mut rows_words, mut pairs_words) = (vec![], vec![]);
                // SAFETY: as above; dst is m rows of n.
                let (rows_ptr, prs, pcs) = unsafe { pack_a(m, n, dst.as_ptr(), (n, 1), &mut rows_words) };
                assert_eq!((prs, pcs, rows_ptr), (n.div_ceil(2), 1, rows_words.as_ptr()));
                unsafe { pack_b(m, n, dst.as_ptr(), n, &mut pairs_words) };
                let Some(Lhs::Packed { words, .. }) = forms.rows_of(m, n) else { panic!("no rows form") };
                assert_eq!(words[..m * prs], rows_words[..m * prs], "{m} × {n} × {k}, {epilogue:?}: rows");
                let Some(Rhs::Packed(words)) = forms.pairs_of(m, n) else { panic!("no pairs form") };
                let pair_words = m.div_ceil(2) * n.div_ceil(16) * 16;
                assert_eq!(words[..pair_words], pairs_words[..pair_words], "{m} × {n} × {k}, {epilogue:?}: pairs");
                assert!(forms.rows_of(m, n + 1).is_none() && forms.pairs_of(m + 1, n).is_none());
            }
        }
    }

    #[test]
    fn products_reading_the_forms_give_the_bits_of_products_reading_the_f32_values() {
        if !available() {
            eprintln!("skipped: no AVX512-BF16 here");
            return;
        }
        let mut seed = 7u32;
        let mut draw = |len: usize| -> Vec<f32> {
            (0..len)
                .map(|_| {
                    seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
                    (seed >> 8) as f32 / (1u32 << 24) as f32 - 0.5
                })
                .collect()
        };
        for (m, n, k) in [(7, 17, 9), (13, 33, 5), (256, 64, 54), (5, 1, 3), (6, 54, 64), (11, 2, 64), (1, 49, 2)] {
            // D = a ReLU mask's output with its forms, as the backward pass makes δ.
            let (a, b, x) = (draw(m * k), draw(k * n), draw(m * n));
            let (mut d, mut forms) = (vec![0.0f32; m * n], Forms::default());
            let mask = Epilogue::ReluMask { x: x.as_ptr(), x_rs: n, sums: std::ptr::null_mut() };
            let (lhs, rhs) = (Lhs::F32 { a: a.as_ptr(), rs: k, cs: 1 }, Rhs::F32 { b: b.as_ptr(), rs: n });
            // SAFETY (every product here): this CPU runs the family; each operand's extents are its shape's.
            unsafe { product_with(m, n, k, d.as_mut_ptr(), n, lhs, rhs, mask, Some(&mut forms), true) };
            let next = |p: usize, q: usize, read: Lhs, b_f32: (&[f32], usize), b_read: Option<Rhs>| {
                let mut out = vec![0.0f32; p * q];
                let b = b_read.unwrap_or(Rhs::F32 { b: b_f32.0.as_ptr(), rs: b_f32.1 });
                unsafe {
                    product_with(
                        p,
                        q,
                        b_f32.0.len() / b_f32.1,
                        out.as_mut_ptr(),
                        q,
                        read,
                        b,
                        Epilogue::None,
                        None,
                        false,
                    )
                };
                bits(&out)
            };
            let plain = |p: usize, q: usize, kk: usize, a: (*const f32, (usize, usize)), b: (&[f32], usize)| {
                let mut out = vec![0.0f32; p * q];
                unsafe { product(p, q, kk, out.as_mut_ptr(), q, a.0, a.1, b.0.as_ptr(), b.1) };
                bits(&out)
            };
            // D as the next product's A (δ·W), Dᵀ as a weight gradient's A (δᵀ·x), D as its B (δᵀ·x's x).
            let w = draw(n * 16);
            let as_rows = forms.rows_of(m, n).expect("rows form");
            assert_eq!(
                next(m, 16, as_rows, (&w, 16), None),
                plain(m, 16, n, (d.as_ptr(), (n, 1)), (&w, 16)),
                "{m} × {n}: rows"
            );
            // And as a narrow product's A (the output layer's), whose rows go in the registers' lanes.
            let w2 = draw(n * 2);
            assert_eq!(
                next(m, 2, as_rows, (&w2, 2), None),
                plain(m, 2, n, (d.as_ptr(), (n, 1)), (&w2, 2)),
                "{m} × {n}: rows, narrow"
            );
            let y = draw(m * 5);
            let as_columns = forms.transposed_of(m, n).expect("pairs form");
            assert_eq!(
                next(n, 5, as_columns, (&y, 5), None),
                plain(n, 5, m, (d.as_ptr(), (1, n)), (&y, 5)),
                "{m} × {n}: Dᵀ"
            );
            let y3 = draw(m * 3);
            assert_eq!(
                next(n, 3, as_columns, (&y3, 3), None),
                plain(n, 3, m, (d.as_ptr(), (1, n)), (&y3, 3)),
                "{m} × {n}: Dᵀ, narrow"
            );
            let z = draw(3 * m);
            let z_lhs = Lhs::F32 { a: z.as_ptr(), rs: m, cs: 1 };
            let as_pairs = forms.pairs_of(m, n);
            assert_eq!(
                next(3, n, z_lhs, (&d, n), as_pairs),
                plain(3, n, m, (z.as_ptr(), (m, 1)), (&d, n)),
                "{m} × {n}: as B"
            );
        }
    }
}
