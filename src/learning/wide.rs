//! The update's elementwise passes compiled for the widest vectors this CPU has. The binary's baseline is
//! x86-64 (SSE2), so the compiler vectorizes loops four lanes wide; the matrix products pick AVX-512 or
//! AVX2 at run time ([`super::direct`], gemm), and so do, through [`run`], the passes between them: the
//! bias and activation after each product, the ReLU masks, the bias gradients, Adam and the soft target
//! update. Each output of these passes is computed from its own inputs by the same operations in the same
//! order at any vector width (Rust never fuses a multiply and an add on its own), so the bits are those of
//! the four-lane code: default runs stay byte-identical (the fingerprint run and
//! `the_fused_update_trains_the_networks_dfdx_trains` check it).

/// Runs `pass` compiled with AVX-512F where the CPU has it, else with AVX2 where it has that, else as
/// compiled. `pass` is inlined into the chosen function, whose target features its loops then use.
#[inline(always)]
pub(crate) fn run<R>(pass: impl FnOnce() -> R) -> R {
    #[cfg(target_arch = "x86_64")]
    {
        if std::arch::is_x86_feature_detected!("avx512f") {
            // SAFETY: the CPU has AVX-512F.
            return unsafe { avx512(pass) };
        }
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU has AVX2.
            return unsafe { avx2(pass) };
        }
    }
    pass()
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
unsafe fn avx512<R>(pass: impl FnOnce() -> R) -> R {
    pass()
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn avx2<R>(pass: impl FnOnce() -> R) -> R {
    pass()
}
