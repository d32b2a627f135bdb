//! Feed-forward networks with widths chosen at run time (d_o depends on the scene), on dfdx's CPU tensors,
//! and the Adam optimizer over their parameters.
//!
//! Weights are stored in PyTorch's `nn.Linear` layout, (out, in), so a saved actor loads into
//! `torch.nn.Linear` layers by name (see `checkpoint.rs`).

use dfdx::prelude::*;
use rand::Rng;
use rand_chacha::ChaCha8Rng;

pub type Dev = Cpu;

/// A family of matrix-product kernels: gemm's (0.19, for dfdx's products and the fused update's) or one of
/// coevo's own for the update's products. Results are bit-identical within a family at any thread count;
/// across families they may differ in the last bits, so a run records its family (`provenance.ron`, by
/// [`Kernels::name`]) and is resumed only on the same one.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Kernels {
    /// gemm's AVX-512 kernels.
    Avx512,
    /// `super::direct`: coevo's f32 AVX-512 kernels for the update's products.
    Avx512Direct,
    /// `super::bf16`: bf16 operands, f32 sums, on AVX512-BF16.
    Avx512Bf16,
    /// gemm's AVX2/FMA kernels (`--kernels avx2`).
    Avx2Fma,
    /// gemm's portable code.
    Portable,
}

impl Kernels {
    pub const ALL: [Kernels; 5] =
        [Kernels::Avx512, Kernels::Avx512Direct, Kernels::Avx512Bf16, Kernels::Avx2Fma, Kernels::Portable];

    /// As runs record it.
    pub fn name(self) -> &'static str {
        match self {
            Kernels::Avx512 => "avx512",
            Kernels::Avx512Direct => "avx512-direct",
            Kernels::Avx512Bf16 => "avx512-bf16",
            Kernels::Avx2Fma => "avx2-fma",
            Kernels::Portable => "portable",
        }
    }

    /// A family as a record, `--kernels` or an experiment file names it (`avx2` is `avx2-fma`).
    pub fn parse(name: &str) -> Option<Kernels> {
        match name {
            "avx2" => Some(Kernels::Avx2Fma),
            name => Kernels::ALL.into_iter().find(|k| k.name() == name),
        }
    }

    /// Which of coevo's own kernels run the update's products instead of gemm's, if any.
    fn own(self) -> Own {
        match self {
            Kernels::Avx512Direct => Own::Direct,
            Kernels::Avx512Bf16 => Own::Bf16,
            Kernels::Avx512 | Kernels::Avx2Fma | Kernels::Portable => Own::None,
        }
    }
}

impl std::fmt::Display for Kernels {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// As experiment files name a family (`kernels: Some("avx512-bf16")`).
impl<'de> serde::Deserialize<'de> for Kernels {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Kernels, D::Error> {
        let name = String::deserialize(d)?;
        Kernels::parse(&name).ok_or_else(|| {
            serde::de::Error::custom(format!(
                "{name:?} is no kernel family: avx512, avx512-direct, avx512-bf16, avx2 or portable"
            ))
        })
    }
}

/// What `--kernels` and `COEVO_KERNELS` ask for: a family, or gemm's choice for this CPU.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum KernelChoice {
    Auto,
    Family(Kernels),
}

impl std::str::FromStr for KernelChoice {
    type Err = String;

    fn from_str(text: &str) -> Result<KernelChoice, String> {
        match text {
            "auto" => Ok(KernelChoice::Auto),
            name => Kernels::parse(name)
                .map(KernelChoice::Family)
                .ok_or_else(|| format!("must be {KERNEL_CHOICES} (got {text:?})")),
        }
    }
}

/// The family this process runs: as gemm chooses at run time (AVX-512 where the CPU has it, else
/// AVX2/FMA, else portable code) unless pinned by [`pin_kernels`].
pub(crate) fn kernels() -> Kernels {
    match own_kernels() {
        Own::Direct => return Kernels::Avx512Direct,
        Own::Bf16 => return Kernels::Avx512Bf16,
        Own::None => {}
    }
    #[cfg(target_arch = "x86_64")]
    {
        use gemm_common::kernel_cap::{get, AUTO, AVX2_FMA};
        if get() == AUTO && std::arch::is_x86_feature_detected!("avx512f") {
            return Kernels::Avx512;
        }
        if get() <= AVX2_FMA && std::arch::is_x86_feature_detected!("fma") {
            return Kernels::Avx2Fma;
        }
    }
    Kernels::Portable
}

/// The families `--kernels` and `COEVO_KERNELS` accept.
pub(crate) const KERNEL_CHOICES: &str = "auto, avx512, avx512-direct, avx512-bf16, avx2 or portable";

/// Which of coevo's own kernels run the update's products instead of gemm's, if any.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Own {
    None,
    /// `super::direct`: f32, AVX-512.
    Direct,
    /// `super::bf16`: bf16 operands, f32 sums, AVX512-BF16.
    Bf16,
}

/// [`Own`] as pinned ([`pin_kernels`]): 0 none, 1 direct, 2 bf16.
static OWN: std::sync::atomic::AtomicU8 = std::sync::atomic::AtomicU8::new(0);

/// Which of coevo's own kernel families this process runs.
pub(crate) fn own_kernels() -> Own {
    match OWN.load(std::sync::atomic::Ordering::Relaxed) {
        1 => Own::Direct,
        2 => Own::Bf16,
        _ => Own::None,
    }
}

/// Pins the kernel family, so that machines with different CPUs compute identical runs: e.g. `avx2` on a
/// cluster whose nodes only partly have AVX-512. gemm fixes its choice at its first product, so this must
/// run before the first network is used (the CLI does it first). Err names a family this CPU cannot run.
pub(crate) fn pin_kernels(choice: KernelChoice) -> Result<(), String> {
    use gemm_common::kernel_cap::{set, AUTO, AVX2_FMA, PORTABLE};
    #[cfg(target_arch = "x86_64")]
    let (avx512, fma) = (std::arch::is_x86_feature_detected!("avx512f"), std::arch::is_x86_feature_detected!("fma"));
    #[cfg(not(target_arch = "x86_64"))]
    let (avx512, fma) = (false, false);
    let runs = |can: bool, family: Kernels| match can {
        true => Ok(()),
        false => Err(format!("this CPU cannot run the {family} kernels (it runs {})", kernels())),
    };
    let (cap, own) = match choice {
        KernelChoice::Auto => (AUTO, Own::None),
        KernelChoice::Family(family) => {
            let cap = match family {
                Kernels::Avx512Direct => runs(super::direct::available(), family).map(|()| AUTO)?,
                Kernels::Avx512Bf16 => runs(super::bf16::available(), family).map(|()| AUTO)?,
                Kernels::Avx512 => runs(avx512, family).map(|()| AUTO)?,
                Kernels::Avx2Fma => runs(fma, family).map(|()| AVX2_FMA)?,
                Kernels::Portable => PORTABLE,
            };
            (cap, family.own())
        }
    };
    let own = match own {
        Own::None => 0,
        Own::Direct => 1,
        Own::Bf16 => 2,
    };
    OWN.store(own, std::sync::atomic::Ordering::Relaxed);
    set(cap);
    Ok(())
}

pub(crate) type Matrix<T = NoneTape> = Tensor<(usize, usize), f32, Dev, T>;
pub(crate) type Vector = Tensor<(usize,), f32, Dev>;

/// One fully connected layer: y = x·Wᵀ + b.
#[derive(Clone, Debug)]
pub(crate) struct Dense {
    /// (out, in).
    pub(crate) weight: Matrix,
    /// (out,).
    pub(crate) bias: Vector,
}

impl Dense {
    pub(crate) fn inputs(&self) -> usize {
        self.weight.shape().1
    }

    pub(crate) fn outputs(&self) -> usize {
        self.weight.shape().0
    }

    pub(crate) fn weight_len(&self) -> usize {
        self.inputs() * self.outputs()
    }
}

/// What follows the last layer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Output {
    /// The actor: tanh into [−1, 1].
    Tanh,
    /// The critic: a plain value.
    Linear,
}

/// Dense layers with ReLU between them (Appendix B: three hidden layers of 64).
#[derive(Clone, Debug)]
pub struct Mlp {
    pub(crate) layers: Vec<Dense>,
    pub(crate) output: Output,
    /// Forms of each layer's weights that coevo's own kernels multiply by, each made at its first use after
    /// the parameters last changed. Every change goes through [`Mlp::parameters_mut`] or
    /// [`Mlp::set_parameters`], which retire them. `avx512-direct`'s forward pass reads Wᵀ (inputs ×
    /// outputs); `avx512-bf16`'s forward pass reads Wᵀ and its backward pass W, both packed in bf16 pairs.
    transposed: Derived<Vec<Vec<f32>>>,
    bf16_transposed: Derived<Vec<Vec<u32>>>,
    bf16_weights: Derived<Vec<Vec<u32>>>,
}

/// A value computed from a network's parameters at its first use after they last changed ([`Derived::get`]),
/// shared by every thread that reads the network; retired at each change ([`Derived::retire`]) and then
/// recomputed into the same buffers, so keeping it allocates nothing from one update to the next. A copy
/// of the network starts without it.
#[derive(Debug, Default)]
struct Derived<T> {
    ready: std::sync::OnceLock<T>,
    /// The last retired value, whose buffers the next one reuses.
    spare: std::sync::Mutex<Option<T>>,
}

impl<T: Default> Derived<T> {
    /// The value, made by `fill` (into the spare buffers, or new ones) if the parameters changed since.
    fn get(&self, fill: impl FnOnce(&mut T)) -> &T {
        self.ready.get_or_init(|| {
            let mut value = self.spare.lock().unwrap_or_else(|e| e.into_inner()).take().unwrap_or_default();
            fill(&mut value);
            value
        })
    }

    /// The parameters are about to change.
    fn retire(&mut self) {
        if let Some(value) = self.ready.take() {
            *self.spare.get_mut().unwrap_or_else(|e| e.into_inner()) = Some(value);
        }
    }
}

impl<T: Default> Clone for Derived<T> {
    fn clone(&self) -> Self {
        Derived::default()
    }
}

impl Mlp {
    /// Layers of the given widths, initialised as PyTorch's `nn.Linear`: U(−1/√in, 1/√in).
    pub(crate) fn new(dev: &Dev, widths: &[usize], output: Output, rng: &mut ChaCha8Rng) -> Mlp {
        let layers = widths
            .windows(2)
            .map(|w| {
                let (fan_in, fan_out) = (w[0], w[1]);
                let bound = 1.0 / (fan_in as f32).sqrt();
                let mut draw = |n: usize| (0..n).map(|_| rng.gen_range(-bound..bound)).collect::<Vec<f32>>();
                Dense {
                    weight: dev.tensor_from_vec(draw(fan_out * fan_in), (fan_out, fan_in)),
                    bias: dev.tensor_from_vec(draw(fan_out), (fan_out,)),
                }
            })
            .collect();
        Mlp {
            layers,
            output,
            transposed: Derived::default(),
            bf16_transposed: Derived::default(),
            bf16_weights: Derived::default(),
        }
    }

    pub(crate) fn input_width(&self) -> usize {
        self.layers[0].weight.shape().1
    }

    #[cfg(test)]
    pub(crate) fn output_width(&self) -> usize {
        self.layers.last().unwrap().weight.shape().0
    }

    /// Forward pass of a batch `[n × in]`; the tape of `x` (if any) records every operation.
    pub(crate) fn forward<T: Tape<f32, Dev> + Merge<T>>(&self, x: Matrix<T>) -> Matrix<T> {
        let last = self.layers.len() - 1;
        let mut h = x;
        for (i, layer) in self.layers.iter().enumerate() {
            let w = layer.weight.retaped::<T>().permute::<(usize, usize), Axes2<1, 0>>();
            let z = h.matmul(w);
            let shape = *z.shape();
            let b = layer.bias.retaped::<T>().broadcast_like::<(usize, usize), Axis<0>>(&shape);
            let z = z + b;
            h = if i < last {
                z.relu()
            } else {
                match self.output {
                    Output::Tanh => z.tanh(),
                    Output::Linear => z,
                }
            };
        }
        h
    }

    /// Every parameter as a flat vector, in layer order (weight, bias).
    pub fn parameters(&self) -> Vec<Vec<f32>> {
        self.layers.iter().flat_map(|l| [l.weight.as_vec(), l.bias.as_vec()]).collect()
    }

    /// Overwrites every parameter from flat vectors in `parameters()` order.
    pub fn set_parameters(&mut self, values: &[Vec<f32>]) {
        self.retire_derived();
        for (l, pair) in self.layers.iter_mut().zip(values.chunks(2)) {
            l.weight.copy_from(&pair[0]);
            l.bias.copy_from(&pair[1]);
        }
    }

    /// Every parameter in place, in `parameters()` order.
    pub(crate) fn parameters_mut(&mut self) -> impl Iterator<Item = &mut [f32]> {
        self.retire_derived();
        self.layers.iter_mut().flat_map(|l| [l.weight.as_mut_slice(), l.bias.as_mut_slice()])
    }

    fn retire_derived(&mut self) {
        self.transposed.retire();
        self.bf16_transposed.retire();
        self.bf16_weights.retire();
    }

    /// Layer `l`'s Wᵀ, laid out (inputs × outputs).
    pub(crate) fn transposed(&self, l: usize) -> &[f32] {
        self.per_layer(&self.transposed, l, |_, layer, t| {
            let (inputs, outputs) = (layer.inputs(), layer.outputs());
            let w = layer.weight.as_slice();
            t.resize(w.len(), 0.0);
            for (i, column) in t.chunks_exact_mut(outputs).enumerate() {
                column.iter_mut().zip(w[i..].iter().step_by(inputs)).for_each(|(t, &w)| *t = w);
            }
        })
    }

    /// Layer `l`'s Wᵀ packed for a bf16 product (`super::bf16::pack_transposed`): the forward pass's
    /// z = x·Wᵀ. Only for layers at most `bf16::MAX_WIDTH` wide.
    pub(crate) fn bf16_transposed(&self, l: usize) -> &[u32] {
        self.per_layer(&self.bf16_transposed, l, |_, layer, t| {
            let (inputs, outputs) = (layer.inputs(), layer.outputs());
            if outputs <= super::bf16::MAX_WIDTH {
                // SAFETY: a packed form is asked for only under the bf16 family, on a CPU that runs it.
                unsafe { super::bf16::pack_transposed(layer.weight.as_slice(), outputs, inputs, t) };
            }
        })
    }

    /// Layer `l`'s W packed for a bf16 product (`super::bf16::pack_b`): the backward pass's δ·W. Only for
    /// layers above the first with at most `bf16::MAX_WIDTH` inputs.
    pub(crate) fn bf16_weights(&self, l: usize) -> &[u32] {
        self.per_layer(&self.bf16_weights, l, |l, layer, t| {
            let (inputs, outputs) = (layer.inputs(), layer.outputs());
            // The first layer's W is never multiplied by: no gradient is taken of the input but for the
            // critic's action columns, which read W unpacked.
            if l > 0 && inputs <= super::bf16::MAX_WIDTH {
                // SAFETY: as above; W is `outputs` rows of `inputs`.
                unsafe { super::bf16::pack_b(outputs, inputs, layer.weight.as_slice().as_ptr(), inputs, t) };
            }
        })
    }

    /// Layer `l`'s entry of a value kept per layer in `derived` until the parameters change, `fill` making
    /// each layer's (its index, the layer, its buffer to refill).
    fn per_layer<'a, T>(
        &'a self,
        derived: &'a Derived<Vec<Vec<T>>>,
        l: usize,
        fill: impl Fn(usize, &Dense, &mut Vec<T>),
    ) -> &'a [T] {
        &derived.get(|t| {
            t.resize_with(self.layers.len(), Vec::new);
            for (l, (layer, t)) in self.layers.iter().zip(t.iter_mut()).enumerate() {
                fill(l, layer, t);
            }
        })[l]
    }

    /// Every parameter read in place, in `parameters()` order.
    pub(crate) fn parameter_slices(&self) -> impl Iterator<Item = &[f32]> {
        self.layers.iter().flat_map(|l| [l.weight.as_slice(), l.bias.as_slice()])
    }

    /// Gradients of every parameter, in `parameters()` order.
    #[cfg(test)]
    pub(crate) fn gradients(&self, grads: &Gradients<f32, Dev>) -> Vec<Vec<f32>> {
        self.layers.iter().flat_map(|l| [grads.get(&l.weight).as_vec(), grads.get(&l.bias).as_vec()]).collect()
    }

    /// Soft target update θ' ← τ·θ + (1 − τ)·θ' (Algorithm 1, last line), in place.
    pub(crate) fn soft_update_towards(&mut self, online: &Mlp, tau: f32) {
        for (target, online) in self.parameters_mut().zip(online.parameter_slices()) {
            super::wide::run(|| target.iter_mut().zip(online).for_each(|(t, o)| *t = tau * o + (1.0 - tau) * *t));
        }
    }

    /// Whether every parameter is finite.
    pub(crate) fn is_finite(&self) -> bool {
        self.parameter_slices().flatten().all(|x| x.is_finite())
    }
}

/// Adam (Kingma & Ba), with PyTorch's defaults β = (0.9, 0.999), ε = 1e-8.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Adam {
    pub(crate) lr: f32,
    pub(crate) step: u64,
    pub(crate) m: Vec<Vec<f32>>,
    pub(crate) v: Vec<Vec<f32>>,
}

const BETA1: f32 = 0.9;
const BETA2: f32 = 0.999;
const EPSILON: f32 = 1e-8;

impl Adam {
    pub(crate) fn new(lr: f32, net: &Mlp) -> Adam {
        let zeros: Vec<Vec<f32>> = net.parameters().iter().map(|p| vec![0.0; p.len()]).collect();
        Adam { lr, step: 0, m: zeros.clone(), v: zeros }
    }

    /// One descent step of `net` along `gradients` (of a loss to minimise), in place.
    pub(crate) fn update(&mut self, net: &mut Mlp, gradients: &[Vec<f32>]) {
        self.step += 1;
        let correct1 = 1.0 - BETA1.powi(self.step as i32);
        let correct2 = 1.0 - BETA2.powi(self.step as i32);
        let lr = self.lr;
        for (((p, g), m), v) in net.parameters_mut().zip(gradients).zip(&mut self.m).zip(&mut self.v) {
            // Zipped slices, not indices: no bounds checks, so the loop vectorizes (as wide as the CPU allows).
            super::wide::run(|| {
                for (((p, g), m), v) in p.iter_mut().zip(g).zip(m.iter_mut()).zip(v.iter_mut()) {
                    *m = flush_subnormal(BETA1 * *m + (1.0 - BETA1) * g);
                    *v = flush_subnormal(BETA2 * *v + (1.0 - BETA2) * g * g);
                    *p -= lr * (*m / correct1) / ((*v / correct2).sqrt() + EPSILON);
                }
            });
        }
    }
}

/// Zero for magnitudes below f32's normal range. The moments of a parameter whose gradient stays zero (a
/// dead ReLU unit) decay geometrically into subnormal numbers, whose arithmetic is ~100× slower on x86:
/// in a long run Adam then took 10 % of the time. Such a moment moves its parameter by less than 1e-30
/// of the learning rate (ε = 1e-8 dominates the denominator), so flushing it changes nothing measurable.
#[inline]
fn flush_subnormal(x: f32) -> f32 {
    if x.abs() < f32::MIN_POSITIVE {
        0.0
    } else {
        x
    }
}

/// A `[rows × cols]` matrix from row-major data.
pub(crate) fn matrix(dev: &Dev, data: Vec<f32>, rows: usize, cols: usize) -> Matrix {
    dev.tensor_from_vec(data, (rows, cols))
}
