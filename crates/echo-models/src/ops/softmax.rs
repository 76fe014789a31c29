//! Softmax over the last dimension, `y_i = e^{x_i − max x} / Σ_j e^{x_j − max x}`, with its
//! gradient `∂x = y·(g − Σ_j g_j y_j)` per row.

use candle_core::{CpuStorage, CustomOp1, CustomOp2, Layout, Result, Shape, Tensor, D};

use super::{fused, slice, with_grad};

/// Softmax of `x` over its last dimension: with a gradient to track, fused on the CPU;
/// without, candle's parallel kernel; candle's composed operations on other devices.
pub fn softmax_last_dim(x: &Tensor) -> Result<Tensor> {
    if fused(x) && x.track_op() {
        x.contiguous()?.apply_op1(Softmax)
    } else if fused(x) {
        // No gradient wanted: candle's kernel, parallel over rows.
        candle_nn::ops::softmax_last_dim(x)
    } else {
        candle_nn::ops::softmax(x, D::Minus1)
    }
}

/// Softmax of each row of `n` values.
#[inline(always)]
fn rows(x: &[f32], y: &mut [f32], n: usize) {
    for (xr, yr) in x.chunks_exact(n).zip(y.chunks_exact_mut(n)) {
        let max = xr.iter().copied().fold(f32::NEG_INFINITY, f32::max);
        let mut sum = 0f32;
        for (y, &x) in yr.iter_mut().zip(xr) {
            *y = super::exp(x - max);
            sum += *y;
        }
        let inv = 1.0 / sum;
        yr.iter_mut().for_each(|y| *y *= inv);
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn rows_avx2(x: &[f32], y: &mut [f32], n: usize) {
    rows(x, y, n)
}

struct Softmax;

impl CustomOp1 for Softmax {
    fn name(&self) -> &'static str {
        "echo-softmax"
    }

    fn cpu_fwd(&self, s: &CpuStorage, l: &Layout) -> Result<(CpuStorage, Shape)> {
        let x = slice(s, l)?;
        let n = l.shape().dims().last().copied().unwrap_or(1).max(1);
        let mut y = vec![0f32; x.len()];
        #[cfg(target_arch = "x86_64")]
        if super::has_avx2() {
            // SAFETY: the CPU has AVX2 and FMA (checked just above).
            unsafe { rows_avx2(x, &mut y, n) };
            return Ok((CpuStorage::F32(y), l.shape().clone()));
        }
        rows(x, &mut y, n);
        Ok((CpuStorage::F32(y), l.shape().clone()))
    }

    fn bwd(&self, _arg: &Tensor, res: &Tensor, grad: &Tensor) -> Result<Option<Tensor>> {
        Ok(Some(
            res.apply_op2_no_bwd(&grad.contiguous()?, &SoftmaxGrad)?,
        ))
    }
}

/// (y, g) → ∂x.
struct SoftmaxGrad;

impl CustomOp2 for SoftmaxGrad {
    fn name(&self) -> &'static str {
        "echo-softmax-grad"
    }

    fn cpu_fwd(
        &self,
        s1: &CpuStorage,
        l1: &Layout,
        s2: &CpuStorage,
        l2: &Layout,
    ) -> Result<(CpuStorage, Shape)> {
        let (y, g) = with_grad("softmax", (s1, l1), (s2, l2))?;
        let n = l1.shape().dims().last().copied().unwrap_or(1).max(1);
        let mut dx = vec![0f32; y.len()];
        for ((yr, gr), dr) in y
            .chunks_exact(n)
            .zip(g.chunks_exact(n))
            .zip(dx.chunks_exact_mut(n))
        {
            let dot: f32 = yr.iter().zip(gr).map(|(y, g)| y * g).sum();
            for i in 0..n {
                dr[i] = yr[i] * (gr[i] - dot);
            }
        }
        Ok((CpuStorage::F32(dx), l1.shape().clone()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use candle_core::{Device, Var};

    #[test]
    fn matches_the_composed_softmax_in_value_and_gradient() {
        let dev = Device::Cpu;
        let x = Var::from_tensor(&Tensor::randn(0f32, 3.0, (2, 4, 6, 9), &dev).unwrap()).unwrap();
        let w = Tensor::randn(0f32, 1.0, (2, 4, 6, 9), &dev).unwrap();
        let run = |fused: bool| {
            let y = if fused {
                softmax_last_dim(&x).unwrap()
            } else {
                candle_nn::ops::softmax(&x, D::Minus1).unwrap()
            };
            let grads = (&y * &w).unwrap().sum_all().unwrap().backward().unwrap();
            let flat = |t: &Tensor| t.flatten_all().unwrap().to_vec1::<f32>().unwrap();
            [flat(&y), flat(grads.get(&x).unwrap())]
        };
        let (ours, theirs) = (run(true), run(false));
        for (k, (a, b)) in ours.iter().zip(&theirs).enumerate() {
            for (u, v) in a.iter().zip(b) {
                assert!((u - v).abs() < 1e-5, "part {k}: {u} against {v}");
            }
        }
        // Rows sum to one.
        let y = softmax_last_dim(&x).unwrap().sum(D::Minus1).unwrap();
        for s in y.flatten_all().unwrap().to_vec1::<f32>().unwrap() {
            assert!((s - 1.0).abs() < 1e-5);
        }
    }
}
