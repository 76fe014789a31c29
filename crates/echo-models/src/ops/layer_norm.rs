//! Layer norm over the last dimension, `y = (x − μ)/√(σ² + ε)·γ + β`, with its gradient:
//! with `x̂ = (x − μ)/√(σ² + ε)` and `h = g·γ` per row of n values,
//! `∂x = (h − mean(h) − x̂·mean(h·x̂))/√(σ² + ε)`, `∂γ = Σ_rows g·x̂`, `∂β = Σ_rows g`.

use candle_core::{CpuStorage, CustomOp2, CustomOp3, Layout, Result, Shape, Tensor};

use super::{fused, slice, with_grad};

/// Layer norm of `x` over its last dimension with gain `gamma` and shift `beta` (both of that
/// size): with a gradient to track, fused on the CPU; without, candle's parallel kernel;
/// candle's composed operations on other devices.
pub fn layer_norm(x: &Tensor, gamma: &Tensor, beta: &Tensor, eps: f32) -> Result<Tensor> {
    let n = x.dim(candle_core::D::Minus1)?;
    if gamma.dims1()? != n || beta.dims1()? != n {
        candle_core::bail!(
            "layer norm: {:?} against gain {:?} and shift {:?}",
            x.shape(),
            gamma.shape(),
            beta.shape()
        );
    }
    if fused(x) && (x.track_op() || gamma.track_op() || beta.track_op()) {
        x.contiguous()?
            .apply_op3(&gamma.contiguous()?, &beta.contiguous()?, LayerNorm { eps })
    } else if fused(x) {
        // No gradient wanted: candle's kernel, parallel over rows.
        candle_nn::ops::layer_norm(&x.contiguous()?, gamma, beta, eps)
    } else {
        candle_nn::ops::layer_norm_slow(x, gamma, beta, eps)
    }
}

/// Mean and 1/√(σ² + ε) of a row.
#[inline(always)]
fn stats(row: &[f32], eps: f32) -> (f32, f32) {
    let n = row.len() as f32;
    let mean = row.iter().sum::<f32>() / n;
    let var = row.iter().map(|v| (v - mean) * (v - mean)).sum::<f32>() / n;
    (mean, 1.0 / (var + eps).sqrt())
}

struct LayerNorm {
    eps: f32,
}

impl CustomOp3 for LayerNorm {
    fn name(&self) -> &'static str {
        "echo-layer-norm"
    }

    fn cpu_fwd(
        &self,
        s1: &CpuStorage,
        l1: &Layout,
        s2: &CpuStorage,
        l2: &Layout,
        s3: &CpuStorage,
        l3: &Layout,
    ) -> Result<(CpuStorage, Shape)> {
        let (x, gamma, beta) = (slice(s1, l1)?, slice(s2, l2)?, slice(s3, l3)?);
        let n = gamma.len();
        let mut y = vec![0f32; x.len()];
        for (xr, yr) in x.chunks_exact(n).zip(y.chunks_exact_mut(n)) {
            let (mean, rstd) = stats(xr, self.eps);
            for (((y, &x), &g), &b) in yr.iter_mut().zip(xr).zip(gamma).zip(beta) {
                *y = (x - mean) * rstd * g + b;
            }
        }
        Ok((CpuStorage::F32(y), l1.shape().clone()))
    }

    fn bwd(
        &self,
        x: &Tensor,
        gamma: &Tensor,
        _beta: &Tensor,
        _res: &Tensor,
        grad: &Tensor,
    ) -> Result<(Option<Tensor>, Option<Tensor>, Option<Tensor>)> {
        let grad = grad.contiguous()?;
        let dx = x.apply_op3_no_bwd(gamma, &grad, &LayerNormGradInput { eps: self.eps })?;
        let dp = x.apply_op2_no_bwd(&grad, &LayerNormGradParams { eps: self.eps })?;
        Ok((Some(dx), Some(dp.get(0)?), Some(dp.get(1)?)))
    }
}

/// (x, γ, g) → ∂x.
struct LayerNormGradInput {
    eps: f32,
}

impl CustomOp3 for LayerNormGradInput {
    fn name(&self) -> &'static str {
        "echo-layer-norm-grad-input"
    }

    fn cpu_fwd(
        &self,
        s1: &CpuStorage,
        l1: &Layout,
        s2: &CpuStorage,
        l2: &Layout,
        s3: &CpuStorage,
        l3: &Layout,
    ) -> Result<(CpuStorage, Shape)> {
        let (x, g) = with_grad("layer norm", (s1, l1), (s3, l3))?;
        let gamma = slice(s2, l2)?;
        let n = gamma.len();
        let mut dx = vec![0f32; x.len()];
        let mut h = vec![0f32; n];
        let mut xh = vec![0f32; n];
        for ((xr, gr), dr) in x
            .chunks_exact(n)
            .zip(g.chunks_exact(n))
            .zip(dx.chunks_exact_mut(n))
        {
            let (mean, rstd) = stats(xr, self.eps);
            let (mut m1, mut m2) = (0f32, 0f32);
            for i in 0..n {
                xh[i] = (xr[i] - mean) * rstd;
                h[i] = gr[i] * gamma[i];
                m1 += h[i];
                m2 += h[i] * xh[i];
            }
            let (m1, m2) = (m1 / n as f32, m2 / n as f32);
            for i in 0..n {
                dr[i] = (h[i] - m1 - xh[i] * m2) * rstd;
            }
        }
        Ok((CpuStorage::F32(dx), l1.shape().clone()))
    }
}

/// (x, g) → [∂γ; ∂β], shape (2, n).
struct LayerNormGradParams {
    eps: f32,
}

impl CustomOp2 for LayerNormGradParams {
    fn name(&self) -> &'static str {
        "echo-layer-norm-grad-params"
    }

    fn cpu_fwd(
        &self,
        s1: &CpuStorage,
        l1: &Layout,
        s2: &CpuStorage,
        l2: &Layout,
    ) -> Result<(CpuStorage, Shape)> {
        let (x, g) = with_grad("layer norm", (s1, l1), (s2, l2))?;
        let n = l1.shape().dims().last().copied().unwrap_or(1);
        if n == 0 {
            candle_core::bail!("layer norm gradient: rows of no values");
        }
        let mut out = vec![0f32; 2 * n];
        let (dgamma, dbeta) = out.split_at_mut(n);
        for (xr, gr) in x.chunks_exact(n).zip(g.chunks_exact(n)) {
            let (mean, rstd) = stats(xr, self.eps);
            for i in 0..n {
                dgamma[i] += gr[i] * (xr[i] - mean) * rstd;
                dbeta[i] += gr[i];
            }
        }
        Ok((CpuStorage::F32(out), Shape::from((2, n))))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use candle_core::{Device, Var};

    /// Values and gradients of the fused norm against candle's composed one.
    #[test]
    fn matches_the_composed_norm_in_value_and_gradient() {
        let dev = Device::Cpu;
        let x = Var::from_tensor(&Tensor::randn(0.3f32, 2.0, (3, 5, 24), &dev).unwrap()).unwrap();
        let g = Var::from_tensor(&Tensor::randn(1f32, 0.3, 24, &dev).unwrap()).unwrap();
        let b = Var::from_tensor(&Tensor::randn(0f32, 0.3, 24, &dev).unwrap()).unwrap();
        // A loss that weighs every output differently.
        let w = Tensor::randn(0f32, 1.0, (3, 5, 24), &dev).unwrap();
        let run = |fused: bool| {
            let y = if fused {
                layer_norm(&x, &g, &b, 1e-5).unwrap()
            } else {
                candle_nn::ops::layer_norm_slow(&x, &g, &b, 1e-5).unwrap()
            };
            let grads = (&y * &w).unwrap().sum_all().unwrap().backward().unwrap();
            let flat = |t: &Tensor| t.flatten_all().unwrap().to_vec1::<f32>().unwrap();
            [
                flat(&y),
                flat(grads.get(&x).unwrap()),
                flat(grads.get(&g).unwrap()),
                flat(grads.get(&b).unwrap()),
            ]
        };
        let (ours, theirs) = (run(true), run(false));
        for (k, (a, b)) in ours.iter().zip(&theirs).enumerate() {
            assert_eq!(a.len(), b.len());
            for (u, v) in a.iter().zip(b) {
                assert!((u - v).abs() < 1e-4, "part {k}: {u} against {v}");
            }
        }
    }

    #[test]
    fn wrong_parameter_sizes_are_an_error() {
        let dev = Device::Cpu;
        let x = Tensor::zeros((2, 8), candle_core::DType::F32, &dev).unwrap();
        let p = Tensor::zeros(7, candle_core::DType::F32, &dev).unwrap();
        assert!(layer_norm(&x, &p, &p, 1e-5).is_err());
    }
}
