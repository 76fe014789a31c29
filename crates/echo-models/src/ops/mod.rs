//! Fused CPU kernels for the forecaster's element-wise and row-wise operations, each with its
//! gradient: GELU, layer norm, softmax over the last dimension, bias addition.
//!
//! candle 0.11's fused layer norm and softmax (`candle_nn::ops::layer_norm`,
//! `softmax_last_dim`) have no backward pass: used in training, no gradient flows through them
//! (the layer-norm parameters, the temporal blocks before a norm and the query and key
//! projections before a softmax never learn). These are differentiable, as fast at inference,
//! and fall back to candle's composed (differentiable) operations on other devices and types.

pub mod bias;
pub mod gelu;
pub mod layer_norm;
pub mod softmax;

pub use bias::bias_add;
pub use gelu::gelu;
pub use layer_norm::layer_norm;
pub use softmax::softmax_last_dim;

use candle_core::{CpuStorage, Layout, Result};

/// Whether the CPU has AVX2 and FMA (the kernels' loops are compiled for them as well).
pub(crate) fn has_avx2() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// A contiguous f32 slice of a CPU storage.
pub(crate) fn slice<'a>(s: &'a CpuStorage, l: &Layout) -> Result<&'a [f32]> {
    let CpuStorage::F32(v) = s else {
        candle_core::bail!("fused kernels: f32 only");
    };
    match l.contiguous_offsets() {
        Some((a, b)) => Ok(&v[a..b]),
        None => candle_core::bail!("fused kernels: the input must be contiguous"),
    }
}

/// A tensor's values and the gradient arriving for them, as slices of equal length (`what`
/// names the operation in the error).
pub(crate) fn with_grad<'a>(
    what: &str,
    (s1, l1): (&'a CpuStorage, &Layout),
    (s2, l2): (&'a CpuStorage, &Layout),
) -> Result<(&'a [f32], &'a [f32])> {
    let (x, g) = (slice(s1, l1)?, slice(s2, l2)?);
    if x.len() != g.len() {
        candle_core::bail!("{what} gradient: {} values against {}", g.len(), x.len());
    }
    Ok((x, g))
}

/// Whether `x` takes the fused CPU path.
pub(crate) fn fused(x: &candle_core::Tensor) -> bool {
    x.device().is_cpu() && x.dtype() == candle_core::DType::F32
}

/// `e^x` for f32 without a library call, so loops over it vectorise: `x = n·ln 2 + r` with
/// |r| ≤ ln 2 / 2 (ln 2 in two parts), a degree-6 Taylor polynomial for `e^r`, and `2^n` put
/// into the exponent bits. Relative error below 1e-6 over the range where f32 `e^x` is normal
/// (tested); −∞ and very negative inputs give 0.
#[inline(always)]
pub(crate) fn exp(x: f32) -> f32 {
    let x = x.clamp(-87.3, 88.0);
    let n = (x * std::f32::consts::LOG2_E).round();
    let r = n * -0.693_145_75 + x;
    let r = n * -1.428_606_8e-6 + r;
    let mut p = r * 1.0 / 720.0 + 1.0 / 120.0;
    p = r * p + 1.0 / 24.0;
    p = r * p + 1.0 / 6.0;
    p = r * p + 0.5;
    p = r * p + 1.0;
    p = r * p + 1.0;
    p * f32::from_bits(((n as i32 + 127) as u32) << 23)
}

#[cfg(test)]
mod tests {
    #[test]
    fn exp_is_within_a_millionth_relative() {
        let mut worst = 0f64;
        for i in -870_000..=880_000 {
            let x = i as f32 * 1e-4;
            let e = (x as f64).exp();
            worst = worst.max(((super::exp(x) as f64) - e).abs() / e);
        }
        assert!(worst < 1e-6, "worst relative error {worst}");
        assert!(super::exp(f32::NEG_INFINITY) < 1e-37);
    }
}
