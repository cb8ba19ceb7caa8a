//! The bias add of a linear layer, `y = x + b` over a batch, as a custom op whose backward
//! sums the incoming gradient over the batch in one row-by-row pass.
//!
//! candle's `broadcast_add` backward reduces the `[B, N]` gradient over its first dimension
//! with a strided scalar loop (`sum_keepdim(0)`), about an eighth of a PPO minibatch step at
//! 1,536 rows (`perf`, BENCHMARKS.md). Accumulating whole rows into the `[N]` sum reads the
//! gradient once, in order, and vectorizes.

use crate::nn::elu::{self, slice as contiguous};
use crate::nn::simd;
use candle_core::{CpuStorage, CustomOp1, CustomOp2, Layout, Result, Shape, Tensor};
use rayon::prelude::*;

/// `f(x + b)` for each row `x` of `x`, in parallel blocks of rows, each loop compiled for
/// the widest vector unit ([`simd`]).
fn map_rows<T: Copy + Send + Sync + std::ops::Add<Output = T>>(
    x: &[T],
    b: &[T],
    f: impl Fn(T) -> T + Sync,
) -> Vec<T> {
    let n = b.len();
    assert!(
        n > 0 && x.len().is_multiple_of(n),
        "rows of {n} in {} elements",
        x.len()
    );
    let block = (elu::CHUNK / n).max(1) * n;
    let mut out: Vec<T> = Vec::with_capacity(x.len());
    out.spare_capacity_mut()[..x.len()]
        .par_chunks_mut(block)
        .zip(x.par_chunks(block))
        .for_each(|(o, c)| {
            simd::widest(simd::MapRows {
                out: o,
                x: c,
                b,
                f: &f,
            })
        });
    // SAFETY: `x.len()` is a multiple of `n` (asserted above), so the rows above wrote
    // every one of the first `x.len()` elements.
    unsafe { out.set_len(x.len()) };
    out
}

/// An error naming `op` unless `x` is `[B, n]` with `n > 0` (`what` names the `[n]` operand).
pub(crate) fn check_rows(op: &str, x: &Layout, n: usize, what: &str) -> Result<()> {
    if x.dims().len() != 2 || x.dims()[1] != n || n == 0 {
        return Err(candle_core::Error::Msg(format!(
            "{op}: x {:?} against {what} of {n}",
            x.dims()
        )));
    }
    Ok(())
}

/// The column sums of `g`'s rows of `n`, each column added row after row (the same order
/// at every vector width).
fn sum_rows<T: Copy + Default + std::ops::AddAssign>(g: &[T], n: usize) -> Vec<T> {
    let mut acc = vec![T::default(); n];
    simd::widest(simd::AddRows { acc: &mut acc, g });
    acc
}

/// `x [B, N] + b [N]`, then ELU when `elu` (one pass, no tensor for `x + b`).
struct BiasAdd {
    elu: bool,
}

impl CustomOp2 for BiasAdd {
    fn name(&self) -> &'static str {
        if self.elu {
            "bias-add-elu"
        } else {
            "bias-add"
        }
    }
    fn cpu_fwd(
        &self,
        s1: &CpuStorage,
        l1: &Layout,
        s2: &CpuStorage,
        l2: &Layout,
    ) -> Result<(CpuStorage, Shape)> {
        let name = self.name();
        let n = l2.shape().elem_count();
        check_rows(name, l1, n, "a bias")?;
        let out = match (s1, s2) {
            (CpuStorage::F32(x), CpuStorage::F32(b)) => {
                let (x, b) = (contiguous(x, l1, name)?, contiguous(b, l2, name)?);
                CpuStorage::F32(if self.elu {
                    map_rows(x, b, elu::elu_f32)
                } else {
                    map_rows(x, b, |z| z)
                })
            }
            (CpuStorage::F64(x), CpuStorage::F64(b)) => {
                let (x, b) = (contiguous(x, l1, name)?, contiguous(b, l2, name)?);
                CpuStorage::F64(if self.elu {
                    map_rows(x, b, elu::elu_f64)
                } else {
                    map_rows(x, b, |z| z)
                })
            }
            _ => {
                return Err(candle_core::Error::Msg(format!("{name}: f32 or f64 only")));
            }
        };
        Ok((out, l1.shape().clone()))
    }
    fn bwd(
        &self,
        _x: &Tensor,
        _b: &Tensor,
        res: &Tensor,
        grad: &Tensor,
    ) -> Result<(Option<Tensor>, Option<Tensor>)> {
        let grad = if self.elu {
            elu::backward_from_output(grad, res)?
        } else {
            grad.contiguous()?
        };
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
    x.contiguous()?
        .apply_op2(&b.contiguous()?, BiasAdd { elu: false })
}

/// `elu(x [B, N] + b [N])` in one pass (f32 or f64), differentiable in both; the same bits
/// as [`add_bias`] followed by [`crate::nn::elu::elu`], without the intermediate tensor.
pub fn add_bias_elu(x: &Tensor, b: &Tensor) -> Result<Tensor> {
    x.contiguous()?
        .apply_op2(&b.contiguous()?, BiasAdd { elu: true })
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

    #[test]
    fn fused_elu_is_bias_add_then_elu_bit_for_bit() {
        let dev = Device::Cpu;
        let (rows, n) = (300, 70); // several parallel blocks
        let data: Vec<f32> = (0..rows * n)
            .map(|i| ((i * 7919 % 1013) as f32 - 506.0) * 0.013)
            .collect();
        let x = Var::from_vec(data, (rows, n), &dev).unwrap();
        let b = Var::from_vec(
            (0..n).map(|j| (j as f32 - 35.0) * 0.05).collect::<Vec<_>>(),
            n,
            &dev,
        )
        .unwrap();
        let w = Tensor::from_vec(
            (0..rows * n)
                .map(|i| (i % 11) as f32 - 5.0)
                .collect::<Vec<_>>(),
            (rows, n),
            &dev,
        )
        .unwrap();
        let fused = add_bias_elu(x.as_tensor(), b.as_tensor()).unwrap();
        let apart = crate::nn::elu::elu(&add_bias(x.as_tensor(), b.as_tensor()).unwrap()).unwrap();
        crate::nn::bit_exact::assert_same_bits_and_gradients(&fused, &apart, &w, &[&x, &b]);
        let wrong = Tensor::zeros(3, candle_core::DType::F32, &dev).unwrap();
        let err = add_bias_elu(x.as_tensor(), &wrong).unwrap_err().to_string();
        assert!(err.contains("bias-add-elu"), "{err}");
    }
}
