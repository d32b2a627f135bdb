//! The forward and backward passes of the DDPG update computed directly, without dfdx's machinery: the
//! same products on the same gemm kernels, into buffers allocated at the first update and reused, the
//! bias and the activation applied to each product in one pass, and only the gradients the update
//! needs (no critic parameter gradients in the actor step, only the action columns of the critic's input
//! gradient, no input gradients anywhere else).
//!
//! `ddpg.rs` strings these into Algorithm 1's update ([`super::ddpg::Ddpg::update`]); dfdx computes the same
//! update with its tape ([`super::ddpg::Ddpg::update_reference`]) and stays the reference: the tests there
//! train the same networks both ways and require the same parameters.
//!
//! Matrices are row-major; a network's weights are (out, in), PyTorch's `nn.Linear` layout (`nets.rs`).

use super::bf16::{Epilogue, Forms, Lhs, Rhs};
use super::nets::{Mlp, Output, Own};
use std::ops::Range;

/// One network's forward pass over a batch, kept for its backward pass.
#[derive(Clone, Debug, Default)]
pub(crate) struct Pass {
    rows: usize,
    /// `acts[0]` is the input `[rows × in]`; `acts[l]` is layer l's output after its ReLU / tanh.
    acts: Vec<Vec<f32>>,
    /// The bf16 family's bf16 forms of `acts[l]`, written by the product that computed it (none for the
    /// input, nor under the other families): the next layer's product, and the gradient of this layer's
    /// weights, read them instead of converting the f32 values again.
    forms: Vec<Forms>,
    /// dL/d(pre-activation) of the layer being back-propagated, and of the one below it, with their forms.
    delta: Vec<f32>,
    below: Vec<f32>,
    delta_forms: Forms,
    below_forms: Forms,
}

thread_local! {
    /// A forward pass per thread for batched inference ([`with_pass`]), its buffers reused step after step.
    static INFERENCE: std::cell::RefCell<Pass> = std::cell::RefCell::new(Pass::default());
}

/// Runs `f` with this thread's inference pass.
pub(crate) fn with_pass<R>(f: impl FnOnce(&mut Pass) -> R) -> R {
    INFERENCE.with(|pass| f(&mut pass.borrow_mut()))
}

impl Pass {
    /// Sizes the buffers for `rows` rows of `net` (allocates only the first time or when shapes grow).
    fn shape_for(&mut self, net: &Mlp, rows: usize) {
        self.rows = rows;
        self.acts.resize_with(net.layers.len() + 1, Vec::new);
        self.forms.resize_with(net.layers.len() + 1, Forms::default);
        self.forms.iter_mut().for_each(Forms::clear);
        self.acts[0].resize(rows * net.input_width(), 0.0);
        for (l, layer) in net.layers.iter().enumerate() {
            self.acts[l + 1].resize(rows * layer.outputs(), 0.0);
        }
    }

    /// The forward pass of `net` on the row-wise concatenation `[a | b]` (b may be empty): the critic's
    /// input (o, a) is built in place.
    pub(crate) fn forward(&mut self, net: &Mlp, rows: usize, a: &[f32], b: &[f32]) {
        self.run_forward(net, rows, a, b, false);
    }

    /// [`Pass::forward`] for a backward pass that computes the weight gradients: the bf16 family then
    /// also keeps the hidden layers' outputs as pairs of rows, the form a weight gradient reads (another
    /// pass would only write them).
    pub(crate) fn forward_to_learn(&mut self, net: &Mlp, rows: usize, a: &[f32], b: &[f32]) {
        self.run_forward(net, rows, a, b, true);
    }

    fn run_forward(&mut self, net: &Mlp, rows: usize, a: &[f32], b: &[f32], learn: bool) {
        self.shape_for(net, rows);
        let (wa, wb) = (a.len() / rows, b.len() / rows);
        debug_assert_eq!(wa + wb, net.input_width());
        if wb == 0 {
            self.acts[0].copy_from_slice(&a[..rows * wa]);
        } else {
            for (r, x) in self.acts[0].chunks_exact_mut(wa + wb).enumerate() {
                x[..wa].copy_from_slice(&a[r * wa..(r + 1) * wa]);
                x[wa..].copy_from_slice(&b[r * wb..(r + 1) * wb]);
            }
        }
        let last = net.layers.len() - 1;
        for (l, layer) in net.layers.iter().enumerate() {
            let (below, above) = self.acts.split_at_mut(l + 1);
            let (x, z) = (&below[l], &mut above[0]);
            let (forms_below, forms_above) = self.forms.split_at_mut(l + 1);
            let (inputs, outputs) = (layer.inputs(), layer.outputs());
            let bias = layer.bias.as_slice();
            // z = x·Wᵀ, then z + b and the activation: the same sums as writing b into z first and
            // accumulating the product onto it (one product pass at these sizes, and b + s = s + b
            // exactly), without a copy of b into every row. The bf16 family adds b and applies the ReLU as
            // it stores each output (from its packed Wᵀ, and x's forms), and keeps the hidden layers'
            // outputs in bf16 too; the others in a pass over z after the product.
            let epilogue = Epilogue::Bias { bias, relu: l != last };
            let x_f32 = Lhs::F32 { a: x.as_ptr(), rs: inputs, cs: 1 };
            // SAFETY: z is rows × outputs, x rows × inputs.
            let done = unsafe {
                bf16_product(
                    (rows, outputs, inputs),
                    z.as_mut_ptr(),
                    || forms_below[l].rows_of(rows, inputs).unwrap_or(x_f32),
                    || Rhs::Packed(net.bf16_transposed(l)),
                    epilogue,
                    (l != last).then_some(&mut forms_above[0]),
                    learn,
                )
            };
            if !done {
                let w = layer.weight.as_slice();
                // Coevo's own kernels read Wᵀ by contiguous rows: from the transposed copy.
                let wt: (*const f32, (usize, usize)) = match super::nets::own_kernels() {
                    Own::Direct | Own::Bf16 => (net.transposed(l).as_ptr(), (outputs, 1)),
                    Own::None => (w.as_ptr(), (1, inputs)),
                };
                // SAFETY: every pointer and stride below addresses only the buffers' own extents:
                // z is rows × outputs, x is rows × inputs, Wᵀ is read as inputs × outputs from W (outputs ×
                // inputs) or from its transposed copy.
                unsafe {
                    product(rows, outputs, inputs, z.as_mut_ptr(), outputs, false, x.as_ptr(), (inputs, 1), wt.0, wt.1);
                }
                let rows_of = |z: &mut [f32], f: fn(f32) -> f32| {
                    z.chunks_exact_mut(outputs)
                        .for_each(|row| row.iter_mut().zip(bias).for_each(|(v, b)| *v = f(*v + b)))
                };
                match (l == last, net.output) {
                    (false, _) => super::wide::run(|| rows_of(z, |v| v.max(0.0))),
                    (true, Output::Tanh) => rows_of(z, f32::tanh),
                    (true, Output::Linear) => rows_of(z, |v| v),
                }
            } else if l == last && net.output == Output::Tanh {
                z.iter_mut().for_each(|v| *v = v.tanh());
            }
        }
    }

    /// The network's output `[rows × out]`.
    pub(crate) fn output(&self) -> &[f32] {
        self.acts.last().expect("a forward pass ran")
    }

    /// Back-propagates `d_output` (dL/d output, `[rows × out]`) through `net`, whose forward pass this
    /// holds. Writes the parameter gradients into `gradients` (in [`Mlp::parameters`] order) when asked,
    /// and dL/d input for the input columns `columns` into `d_input` (`[rows × columns.len()]`) when asked.
    pub(crate) fn backward(
        &mut self,
        net: &Mlp,
        d_output: &[f32],
        mut gradients: Option<&mut [Vec<f32>]>,
        d_input: Option<(Range<usize>, &mut [f32])>,
    ) {
        let rows = self.rows;
        let mut delta = std::mem::take(&mut self.delta);
        let mut below = std::mem::take(&mut self.below);
        let mut delta_forms = std::mem::take(&mut self.delta_forms);
        let mut below_forms = std::mem::take(&mut self.below_forms);
        // Both hold any layer's rows × width: grown once, not resized (and zeroed) layer by layer.
        let widest = rows * net.layers.iter().map(|l| l.inputs().max(l.outputs())).max().unwrap_or(0);
        for buffer in [&mut delta, &mut below] {
            if buffer.len() < widest {
                buffer.resize(widest, 0.0);
            }
        }
        // Through the output activation (a pass of its own: no forms).
        delta_forms.clear();
        let d = &mut delta[..d_output.len()];
        match net.output {
            Output::Tanh => {
                d.iter_mut().zip(d_output.iter().zip(self.output())).for_each(|(d, (g, y))| *d = g * (1.0 - y * y))
            }
            Output::Linear => d.copy_from_slice(d_output),
        }
        let mut d_input = d_input;
        // Whether δ's column sums are already in its layer's bias gradient.
        let mut delta_summed = false;
        for l in (0..net.layers.len()).rev() {
            let layer = &net.layers[l];
            let (inputs, outputs) = (layer.inputs(), layer.outputs());
            let (x, x_forms) = (&self.acts[l], &self.forms[l]);
            let w = layer.weight.as_slice();
            // δ as a product's A, from its forms where the product that computed it kept them.
            let delta_f32 = Lhs::F32 { a: delta.as_ptr(), rs: outputs, cs: 1 };
            let delta_lhs = || delta_forms.rows_of(rows, outputs).unwrap_or(delta_f32);
            if let Some(g) = gradients.as_deref_mut() {
                let (dw, db) = g[2 * l..2 * l + 2].split_at_mut(1);
                let (dw, db) = (&mut dw[0], &mut db[0]);
                // dW = δᵀ·x: δᵀ (outputs × rows) read from δ (rows × outputs).
                let delta_t = Lhs::F32 { a: delta.as_ptr(), rs: 1, cs: outputs };
                let x_rhs = Rhs::F32 { b: x.as_ptr(), rs: inputs };
                // SAFETY: dw is outputs × inputs, δ rows × outputs, x rows × inputs.
                let done = unsafe {
                    bf16_product(
                        (outputs, inputs, rows),
                        dw.as_mut_ptr(),
                        || delta_forms.transposed_of(rows, outputs).unwrap_or(delta_t),
                        || x_forms.pairs_of(rows, inputs).unwrap_or(x_rhs),
                        Epilogue::None,
                        None,
                        false,
                    )
                };
                if !done {
                    // SAFETY: as above.
                    unsafe {
                        product(
                            outputs,
                            inputs,
                            rows,
                            dw.as_mut_ptr(),
                            inputs,
                            false,
                            delta.as_ptr(),
                            (1, outputs),
                            x.as_ptr(),
                            (inputs, 1),
                        );
                    }
                }
                // db = Σ rows of δ, in order from zero: summed here unless the product that computed δ
                // summed it as it stored each row (below).
                if !delta_summed {
                    db.fill(0.0);
                    super::wide::run(|| {
                        for row in delta[..rows * outputs].chunks_exact(outputs) {
                            db.iter_mut().zip(row).for_each(|(s, d)| *s += d);
                        }
                    });
                }
            }
            if l > 0 {
                // δ_below = (δ·W) ⊙ ReLU'(x): x is the ReLU output below, positive exactly where its input was.
                // A multiplication by 0 or 1, not a branch: it vectorizes (a branch here took a third of an
                // update), and it is dfdx's own ReLU backward, bit for bit. The bf16 family applies it as it
                // stores each output (from its packed W) and keeps δ_below's forms; the others in a pass
                // after the product.
                let below_rows = &mut below[..rows * inputs];
                // The bias gradient of the layer below, db = Σ rows of δ_below, summed by the product as it
                // stores them.
                let sums = match gradients.as_deref_mut() {
                    Some(g) => {
                        let db = &mut g[2 * (l - 1) + 1];
                        db.fill(0.0);
                        db.as_mut_ptr()
                    }
                    None => std::ptr::null_mut(),
                };
                let mask = Epilogue::ReluMask { x: x.as_ptr(), x_rs: inputs, sums };
                // SAFETY: below is rows × inputs, δ rows × outputs, x rows × inputs.
                let done = unsafe {
                    bf16_product(
                        (rows, inputs, outputs),
                        below_rows.as_mut_ptr(),
                        delta_lhs,
                        || Rhs::Packed(net.bf16_weights(l)),
                        mask,
                        Some(&mut below_forms),
                        !sums.is_null(),
                    )
                };
                delta_summed = done && !sums.is_null();
                if !done {
                    below_forms.clear();
                    // SAFETY: below is rows × inputs, δ rows × outputs, W outputs × inputs.
                    unsafe {
                        product(
                            rows,
                            inputs,
                            outputs,
                            below_rows.as_mut_ptr(),
                            inputs,
                            false,
                            delta.as_ptr(),
                            (outputs, 1),
                            w.as_ptr(),
                            (inputs, 1),
                        );
                    }
                    super::wide::run(|| {
                        below_rows.iter_mut().zip(x).for_each(|(d, &x)| *d *= if x > 0.0 { 1.0 } else { 0.0 })
                    });
                }
                std::mem::swap(&mut delta, &mut below);
                std::mem::swap(&mut delta_forms, &mut below_forms);
            } else if let Some((columns, out)) = d_input.take() {
                let n = columns.len();
                assert!(columns.end <= inputs && out.len() == rows * n, "input gradient shape");
                // dL/dx[:, columns] = δ·W[:, columns].
                // SAFETY: out is rows × n; W[:, columns] is read from W (outputs × inputs) at offset
                // columns.start, n ≤ inputs − columns.start columns per row.
                let w_columns = unsafe { w.as_ptr().add(columns.start) };
                // SAFETY: as above.
                let done = unsafe {
                    bf16_product(
                        (rows, n, outputs),
                        out.as_mut_ptr(),
                        delta_lhs,
                        || Rhs::F32 { b: w_columns, rs: inputs },
                        Epilogue::None,
                        None,
                        false,
                    )
                };
                if !done {
                    // SAFETY: as above.
                    unsafe {
                        product(
                            rows,
                            n,
                            outputs,
                            out.as_mut_ptr(),
                            n,
                            false,
                            delta.as_ptr(),
                            (outputs, 1),
                            w_columns,
                            (inputs, 1),
                        );
                    }
                }
            }
        }
        self.delta = delta;
        self.below = below;
        self.delta_forms = delta_forms;
        self.below_forms = below_forms;
    }
}

/// dst `[m × n]` (rows contiguous; `shape` = (m, n, k)) = A·B by the bf16 family, its operands as `a` and
/// `b` give them (asked for only when the family takes the product: a packed one may be made on demand),
/// `epilogue` applied as each output is stored, and the outputs' forms written into `forms` when given.
/// False, and nothing written, where the family does not take the product: another family, or n over
/// `bf16::MAX_WIDTH`.
///
/// # Safety
/// Every element the operands and the epilogue address lies inside its buffer; dst holds m × n.
unsafe fn bf16_product<'a>(
    (m, n, k): (usize, usize, usize),
    dst: *mut f32,
    a: impl FnOnce() -> Lhs<'a>,
    b: impl FnOnce() -> Rhs<'a>,
    epilogue: Epilogue,
    forms: Option<&mut Forms>,
    pairs: bool,
) -> bool {
    if n > super::bf16::MAX_WIDTH || super::nets::own_kernels() != Own::Bf16 {
        return false;
    }
    #[cfg(target_arch = "x86_64")]
    // SAFETY: the family is chosen only on a CPU with AVX512-BF16 and -BW; the extents are the caller's.
    unsafe {
        super::bf16::product_with(m, n, k, dst, n, a(), b(), epilogue, forms, pairs)
    };
    #[cfg(not(target_arch = "x86_64"))]
    unreachable!(
        "the bf16 family runs only on x86_64 ({m} × {n} × {k} at {dst:?}: {:?}, {:?}, {epilogue:?}, {forms:?})",
        a(),
        b()
    );
    true
}

/// dst `[m × n]` (row stride `dst_rs`) = lhs `[m × k]` · rhs `[k × n]`, plus dst's previous contents when
/// `accumulate`; lhs and rhs given by pointer and (row stride, column stride). One thread: the cores are
/// used at a coarser grain (`crate::parallel`).
///
/// # Safety
/// Every element the strides address must lie inside the pointed-to buffers.
#[allow(clippy::too_many_arguments)]
pub(crate) unsafe fn product(
    m: usize,
    n: usize,
    k: usize,
    dst: *mut f32,
    dst_rs: usize,
    accumulate: bool,
    lhs: *const f32,
    (lhs_rs, lhs_cs): (usize, usize),
    rhs: *const f32,
    (rhs_rs, rhs_cs): (usize, usize),
) {
    #[cfg(target_arch = "x86_64")]
    if rhs_cs == 1 && n > 0 && n <= super::direct::MAX_WIDTH && !accumulate {
        use super::nets::{own_kernels, Own};
        match own_kernels() {
            // SAFETY: the family is chosen only on a CPU with AVX-512F; the extents are the caller's.
            Own::Direct => {
                return unsafe { super::direct::product(m, n, k, dst, dst_rs, lhs, (lhs_rs, lhs_cs), rhs, rhs_rs) }
            }
            // SAFETY: the family is chosen only on a CPU with AVX512-BF16 and -BW; the extents are the caller's.
            Own::Bf16 => {
                return unsafe { super::bf16::product(m, n, k, dst, dst_rs, lhs, (lhs_rs, lhs_cs), rhs, rhs_rs) }
            }
            Own::None => {}
        }
    }
    gemm::gemm(
        m,
        n,
        k,
        dst,
        1,
        dst_rs as isize,
        accumulate,
        lhs,
        lhs_cs as isize,
        lhs_rs as isize,
        rhs,
        rhs_cs as isize,
        rhs_rs as isize,
        1.0,
        1.0,
        false,
        false,
        false,
        gemm::Parallelism::None,
    );
}

/// Buffers of one species' update, allocated at its first update and reused by every later one.
#[derive(Debug, Default)]
pub(crate) struct Workspace {
    /// μ'(o') and Q'(o', μ'(o')): the TD target's passes.
    pub(crate) target_actor: Pass,
    pub(crate) target_critic: Pass,
    /// Q(o, a): the critic step's pass.
    pub(crate) critic: Pass,
    /// μ(o) and Q(o, μ(o)): the actor step's passes.
    pub(crate) actor: Pass,
    pub(crate) actor_value: Pass,
    /// dL/dQ per row, reused by both steps.
    pub(crate) d_q: Vec<f32>,
    /// dL/dμ(o) `[rows × actions]`: the critic's input gradient in its action columns.
    pub(crate) d_actions: Vec<f32>,
    pub(crate) critic_gradients: Vec<Vec<f32>>,
    pub(crate) actor_gradients: Vec<Vec<f32>>,
}

/// A copy of a learner starts without buffers, as a new one does: every update writes them before it reads
/// them, so they carry nothing from one update to the next, and the copy kept at each episode's end
/// (`learning::learn`'s last good state) need not duplicate them.
impl Clone for Workspace {
    fn clone(&self) -> Workspace {
        Workspace::default()
    }
}

/// Gradient buffers shaped like `net`'s parameters (allocated once).
pub(crate) fn gradients_like(buffers: &mut Vec<Vec<f32>>, net: &Mlp) {
    if buffers.len() != 2 * net.layers.len() {
        *buffers = net.layers.iter().flat_map(|l| [vec![0.0; l.weight_len()], vec![0.0; l.outputs()]]).collect();
    }
}
