//! The bias add of a linear layer, `y = x + b` over a batch, as a custom op whose backward
//! sums the incoming gradient over the batch in one row-by-row pass.
//!
//! candle's `broadcast_add` backward reduces the `[B, N]` gradient over its first dimension
//! with a strided scalar loop (`sum_keepdim(0)`), about an eighth of a PPO minibatch step at
//! 1,536 rows (`perf`, BENCHMARKS.md). Accumulating whole rows into the `[N]` sum reads the
//! gradient once, in order, and vectorizes.

use crate::nn::elu::slice as contiguous;
use candle_core::{CpuStorage, CustomOp1, CustomOp2, Layout, Result, Shape, Tensor};

fn add_rows<T: Copy + std::ops::Add<Output = T>>(x: &[T], b: &[T]) -> Vec<T> {
    let mut out = Vec::with_capacity(x.len());
    for row in x.chunks_exact(b.len()) {
        out.extend(row.iter().zip(b).map(|(&x, &b)| x + b));
    }
    out
}

fn sum_rows<T: Copy + Default + std::ops::AddAssign>(g: &[T], n: usize) -> Vec<T> {
    let mut acc = vec![T::default(); n];
    for row in g.chunks_exact(n) {
        for (a, &x) in acc.iter_mut().zip(row) {
            *a += x;
        }
    }
    acc
}

/// `x [B, N] + b [N]`.
struct BiasAdd;

impl CustomOp2 for BiasAdd {
    fn name(&self) -> &'static str {
        "bias-add"
    }
    fn cpu_fwd(
        &self,
        s1: &CpuStorage,
        l1: &Layout,
        s2: &CpuStorage,
        l2: &Layout,
    ) -> Result<(CpuStorage, Shape)> {
        let n = l2.shape().elem_count();
        if l1.dims().len() != 2 || l1.dims()[1] != n || n == 0 {
            return Err(candle_core::Error::Msg(format!(
                "bias-add: x {:?} against a bias of {n}",
                l1.dims()
            )));
        }
        let out = match (s1, s2) {
            (CpuStorage::F32(x), CpuStorage::F32(b)) => CpuStorage::F32(add_rows(
                contiguous(x, l1, "bias-add")?,
                contiguous(b, l2, "bias-add")?,
            )),
            (CpuStorage::F64(x), CpuStorage::F64(b)) => CpuStorage::F64(add_rows(
                contiguous(x, l1, "bias-add")?,
                contiguous(b, l2, "bias-add")?,
            )),
            _ => return Err(candle_core::Error::Msg("bias-add: f32 or f64 only".into())),
        };
        Ok((out, l1.shape().clone()))
    }
    fn bwd(
        &self,
        _x: &Tensor,
        _b: &Tensor,
        _res: &Tensor,
        grad: &Tensor,
    ) -> Result<(Option<Tensor>, Option<Tensor>)> {
        let grad = grad.contiguous()?;
        let sums = grad.apply_op1_no_bwd(&SumRows)?;
        Ok((Some(grad), Some(sums)))
    }
}

/// `[B, N] -> [N]`: the sum over the rows.
struct SumRows;

impl CustomOp1 for SumRows {
    fn name(&self) -> &'static str {
        "sum-rows"
    }
    fn cpu_fwd(&self, s: &CpuStorage, l: &Layout) -> Result<(CpuStorage, Shape)> {
        let &[_, n] = l.dims() else {
            return Err(candle_core::Error::Msg("sum-rows: [B, N] only".into()));
        };
        let out = match s {
            CpuStorage::F32(g) => CpuStorage::F32(sum_rows(contiguous(g, l, "sum-rows")?, n)),
            CpuStorage::F64(g) => CpuStorage::F64(sum_rows(contiguous(g, l, "sum-rows")?, n)),
            _ => return Err(candle_core::Error::Msg("sum-rows: f32 or f64 only".into())),
        };
        Ok((out, Shape::from(n)))
    }
}

/// `x [B, N] + b [N]` (f32 or f64), differentiable in both.
pub fn add_bias(x: &Tensor, b: &Tensor) -> Result<Tensor> {
    x.contiguous()?.apply_op2(&b.contiguous()?, BiasAdd)
}

#[cfg(test)]
mod tests {
    use super::*;
    use candle_core::{Device, Var};

    #[test]
    fn forward_and_gradients_match_broadcast_add() {
        let dev = Device::Cpu;
        let x = Var::new(&[[1.0f32, 2.0, 3.0], [4.0, 5.0, 6.0]], &dev).unwrap();
        let b = Var::new(&[0.5f32, -1.0, 2.0], &dev).unwrap();
        let w = Tensor::new(&[[1.0f32, 2.0, 3.0], [-1.0, 0.5, 0.25]], &dev).unwrap();
        let ours = add_bias(x.as_tensor(), b.as_tensor()).unwrap();
        let theirs = x.as_tensor().broadcast_add(b.as_tensor()).unwrap();
        assert_eq!(
            ours.to_vec2::<f32>().unwrap(),
            theirs.to_vec2::<f32>().unwrap()
        );
        let grads = |y: &Tensor| y.mul(&w)?.sqr()?.sum_all()?.backward();
        let (g1, g2) = (grads(&ours).unwrap(), grads(&theirs).unwrap());
        for v in [&x, &b] {
            let (a, e) = (g1.get(v).unwrap(), g2.get(v).unwrap());
            assert_eq!(
                a.flatten_all().unwrap().to_vec1::<f32>().unwrap(),
                e.flatten_all().unwrap().to_vec1::<f32>().unwrap()
            );
        }
        assert!(add_bias(
            x.as_tensor(),
            &Tensor::zeros(2, candle_core::DType::F32, &dev).unwrap()
        )
        .is_err());
    }
}
