//! Adding a bias along the last dimension, `y = x + b`, with its gradient `∂b = Σ_rows g`
//! summed by one contiguous pass (candle sums over leading dimensions element by element with
//! two integer divisions each: most of a training step's backward pass went there).

use candle_core::{CpuStorage, CustomOp1, CustomOp2, Layout, Result, Shape, Tensor};

use super::{fused, slice};

/// `x + b` with `b` of `x`'s last size, broadcast over the other dimensions (candle's
/// parallel broadcast when no gradient is tracked).
pub fn bias_add(x: &Tensor, b: &Tensor) -> Result<Tensor> {
    if fused(x) && (x.track_op() || b.track_op()) && b.dims1()? == x.dim(candle_core::D::Minus1)? {
        x.contiguous()?.apply_op2(&b.contiguous()?, BiasAdd)
    } else {
        x.broadcast_add(b)
    }
}

struct BiasAdd;

impl CustomOp2 for BiasAdd {
    fn name(&self) -> &'static str {
        "echo-bias-add"
    }

    fn cpu_fwd(
        &self,
        s1: &CpuStorage,
        l1: &Layout,
        s2: &CpuStorage,
        l2: &Layout,
    ) -> Result<(CpuStorage, Shape)> {
        let (x, b) = (slice(s1, l1)?, slice(s2, l2)?);
        let n = b.len().max(1);
        let mut y = x.to_vec();
        for row in y.chunks_exact_mut(n) {
            for (y, b) in row.iter_mut().zip(b) {
                *y += b;
            }
        }
        Ok((CpuStorage::F32(y), l1.shape().clone()))
    }

    fn bwd(
        &self,
        _x: &Tensor,
        b: &Tensor,
        _res: &Tensor,
        grad: &Tensor,
    ) -> Result<(Option<Tensor>, Option<Tensor>)> {
        let db = grad
            .contiguous()?
            .apply_op1_no_bwd(&SumRows { n: b.dim(0)? })?;
        Ok((Some(grad.clone()), Some(db)))
    }
}

/// (rows of n values) → their sum, (n).
struct SumRows {
    n: usize,
}

impl CustomOp1 for SumRows {
    fn name(&self) -> &'static str {
        "echo-sum-rows"
    }

    fn cpu_fwd(&self, s: &CpuStorage, l: &Layout) -> Result<(CpuStorage, Shape)> {
        let g = slice(s, l)?;
        let mut out = vec![0f32; self.n];
        for row in g.chunks_exact(self.n.max(1)) {
            for (o, g) in out.iter_mut().zip(row) {
                *o += g;
            }
        }
        Ok((CpuStorage::F32(out), Shape::from(self.n)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use candle_core::{Device, Var};

    #[test]
    fn matches_broadcast_add_in_value_and_gradient() {
        let dev = Device::Cpu;
        let x = Var::from_tensor(&Tensor::randn(0f32, 1.0, (4, 3, 10), &dev).unwrap()).unwrap();
        let b = Var::from_tensor(&Tensor::randn(0f32, 1.0, 10, &dev).unwrap()).unwrap();
        let w = Tensor::randn(0f32, 1.0, (4, 3, 10), &dev).unwrap();
        let run = |fused: bool| {
            let y = if fused {
                bias_add(&x, &b).unwrap()
            } else {
                x.broadcast_add(&b).unwrap()
            };
            let g = (&y * &w).unwrap().sum_all().unwrap().backward().unwrap();
            let flat = |t: &Tensor| t.flatten_all().unwrap().to_vec1::<f32>().unwrap();
            [flat(&y), flat(g.get(&x).unwrap()), flat(g.get(&b).unwrap())]
        };
        let (ours, theirs) = (run(true), run(false));
        for (k, (a, c)) in ours.iter().zip(&theirs).enumerate() {
            assert_eq!(a.len(), c.len());
            for (u, v) in a.iter().zip(c) {
                assert!((u - v).abs() < 1e-5, "part {k}: {u} against {v}");
            }
        }
    }
}
