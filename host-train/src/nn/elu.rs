//! Fused ELU (alpha = 1) and its derivative as single-pass custom ops.
//!
//! candle's built-in `elu` backward makes about ten passes over the activation (masks,
//! casts, products, sums), each a fresh allocation; on the learner's `[24576, 512]`
//! activations that dominates a PPO step. Here the forward is one pass, the backward one
//! pass reading only the output (`elu'(x) = 1` where `y > 0`, `y + 1` elsewhere), and the
//! derivative `elu'(z) = exp(min(z, 0))` used by the discriminator's explicit input gradient
//! is one pass with a one-pass backward, so the gradient penalty stays exact.

use crate::nn::simd::{self, Level};
use candle_core::{CpuStorage, CustomOp1, CustomOp2, Layout, Result, Shape, Tensor};
use rayon::prelude::*;

/// Elements per parallel chunk.
pub(crate) const CHUNK: usize = 1 << 15;

/// The elements of a contiguous input (an error naming `op` otherwise).
pub(crate) fn slice<'a, T>(data: &'a [T], layout: &Layout, op: &str) -> Result<&'a [T]> {
    match layout.contiguous_offsets() {
        Some((start, end)) => Ok(&data[start..end]),
        None => Err(candle_core::Error::Msg(format!(
            "{op}: input must be contiguous"
        ))),
    }
}

/// `f` over `x`, in parallel chunks, each a plain loop the compiler vectorizes for the
/// widest vector unit the CPU has ([`simd`]).
fn map1<T: Copy + Send + Sync>(x: &[T], f: impl Fn(T) -> T + Sync) -> Vec<T> {
    map1_at(Level::detected(), x, f)
}

/// [`map1`] with the loops compiled for `level`.
fn map1_at<T: Copy + Send + Sync>(level: Level, x: &[T], f: impl Fn(T) -> T + Sync) -> Vec<T> {
    let mut out: Vec<T> = Vec::with_capacity(x.len());
    out.spare_capacity_mut()[..x.len()]
        .par_chunks_mut(CHUNK)
        .zip(x.par_chunks(CHUNK))
        .for_each(|(o, c)| {
            simd::at(
                level,
                simd::Map1 {
                    out: o,
                    x: c,
                    f: &f,
                },
            )
        });
    // SAFETY: the loop above wrote every one of the first `x.len()` elements.
    unsafe { out.set_len(x.len()) };
    out
}

/// `f` over `a` and `b` element by element, as `map1`.
fn map2<T: Copy + Send + Sync>(a: &[T], b: &[T], f: impl Fn(T, T) -> T + Sync) -> Vec<T> {
    map2_at(Level::detected(), a, b, f)
}

/// [`map2`] with the loops compiled for `level`.
fn map2_at<T: Copy + Send + Sync>(
    level: Level,
    a: &[T],
    b: &[T],
    f: impl Fn(T, T) -> T + Sync,
) -> Vec<T> {
    assert_eq!(a.len(), b.len());
    let mut out: Vec<T> = Vec::with_capacity(a.len());
    out.spare_capacity_mut()[..a.len()]
        .par_chunks_mut(CHUNK)
        .zip(a.par_chunks(CHUNK).zip(b.par_chunks(CHUNK)))
        .for_each(|(o, (ca, cb))| {
            simd::at(
                level,
                simd::Map2 {
                    out: o,
                    a: ca,
                    b: cb,
                    f: &f,
                },
            )
        });
    // SAFETY: the loop above wrote every one of the first `a.len()` elements.
    unsafe { out.set_len(a.len()) };
    out
}

/// `exp(x) - 1` for `x <= 0` in f32, branch-free so that the element loops vectorize (libm's
/// `expm1f` is a scalar call per element, which made ELU a sixth of a PPO step): `x = n ln 2
/// + r` with `|r| <= ln 2 / 2` (Cody-Waite, two-part `ln 2`), `e^r - 1` by its Taylor
/// polynomial to degree 8 (truncation below 1e-9), then `2^n (e^r - 1) + (2^n - 1)`, with
/// `2^n` built from the rounding sum's bits in integer lanes (a float-to-int conversion
/// would be scalar per element on the baseline target). Relative error within 3e-7 of libm
/// (tested); `x < -87` gives -1.
#[inline(always)]
pub fn expm1_nonpositive_f32(x: f32) -> f32 {
    const LN2_HI: f32 = 0.693_145_75;
    const LN2_LO: f32 = 1.428_606_8e-6;
    const ROUND: f32 = 12_582_912.0; // 1.5 * 2^23: adding it rounds to an integer.
    let x = x.clamp(-87.0, 0.0);
    let t = x * std::f32::consts::LOG2_E + ROUND; // ROUND + n, n = round(x / ln 2)
    let n = t - ROUND;
    let r = (x - n * LN2_HI) - n * LN2_LO;
    // e^r - 1 = r + r^2/2! + ... + r^8/8!, Horner.
    let p = r
        * (1.0
            + r * (1.0 / 2.0
                + r * (1.0 / 6.0
                    + r * (1.0 / 24.0
                        + r * (1.0 / 120.0
                            + r * (1.0 / 720.0 + r * (1.0 / 5040.0 + r * (1.0 / 40320.0))))))));
    // t in [2^23, 2^24) has a unit ulp, so its bits are ROUND's plus n (-126 <= n <= 0):
    // 2^n is the exponent field n + 127 (1..=127, a normal number).
    let biased = t.to_bits().wrapping_sub(ROUND.to_bits()).wrapping_add(127);
    let two_n = f32::from_bits(biased << 23);
    two_n * p + (two_n - 1.0)
}

/// `elu(x)`.
#[inline(always)]
pub(crate) fn elu_f32(x: f32) -> f32 {
    if x > 0.0 {
        x
    } else {
        expm1_nonpositive_f32(x)
    }
}

/// `g * elu'(x)` from the output `y = elu(x)`.
#[inline(always)]
fn elu_backward_f32(g: f32, y: f32) -> f32 {
    if y > 0.0 {
        g
    } else {
        g * (y + 1.0)
    }
}

/// `elu(x)` in f64.
#[inline(always)]
pub(crate) fn elu_f64(x: f64) -> f64 {
    if x > 0.0 {
        x
    } else {
        x.exp_m1()
    }
}

/// `elu'(z)`.
#[inline(always)]
fn elu_derivative_f32(z: f32) -> f32 {
    if z > 0.0 {
        1.0
    } else {
        expm1_nonpositive_f32(z) + 1.0
    }
}

/// `g * elu''(z)`.
#[inline(always)]
fn elu_derivative_backward_f32(g: f32, z: f32) -> f32 {
    if z > 0.0 {
        0.0
    } else {
        g * (expm1_nonpositive_f32(z) + 1.0)
    }
}

macro_rules! unary_cpu {
    ($storage:expr, $layout:expr, $name:expr, $f32:expr, $f64:expr) => {{
        let shape = $layout.shape().clone();
        match $storage {
            CpuStorage::F32(v) => Ok((
                CpuStorage::F32(map1(slice(v, $layout, $name)?, $f32)),
                shape,
            )),
            CpuStorage::F64(v) => Ok((
                CpuStorage::F64(map1(slice(v, $layout, $name)?, $f64)),
                shape,
            )),
            _ => Err(candle_core::Error::Msg(format!(
                "{}: f32 or f64 only",
                $name
            ))),
        }
    }};
}

macro_rules! binary_cpu {
    ($s1:expr, $l1:expr, $s2:expr, $l2:expr, $name:expr, $f32:expr, $f64:expr) => {{
        if $l1.shape() != $l2.shape() {
            return Err(candle_core::Error::Msg(format!(
                "{}: shape mismatch",
                $name
            )));
        }
        let shape = $l1.shape().clone();
        match ($s1, $s2) {
            (CpuStorage::F32(a), CpuStorage::F32(b)) => Ok((
                CpuStorage::F32(map2(slice(a, $l1, $name)?, slice(b, $l2, $name)?, $f32)),
                shape,
            )),
            (CpuStorage::F64(a), CpuStorage::F64(b)) => Ok((
                CpuStorage::F64(map2(slice(a, $l1, $name)?, slice(b, $l2, $name)?, $f64)),
                shape,
            )),
            _ => Err(candle_core::Error::Msg(format!(
                "{}: f32 or f64 only",
                $name
            ))),
        }
    }};
}

/// `y = x` for `x > 0`, `exp(x) - 1` otherwise.
struct Elu;

impl CustomOp1 for Elu {
    fn name(&self) -> &'static str {
        "fused-elu"
    }
    fn cpu_fwd(&self, storage: &CpuStorage, layout: &Layout) -> Result<(CpuStorage, Shape)> {
        unary_cpu!(storage, layout, "fused-elu", elu_f32, elu_f64)
    }
    fn bwd(&self, _arg: &Tensor, res: &Tensor, grad_res: &Tensor) -> Result<Option<Tensor>> {
        Ok(Some(backward_from_output(grad_res, res)?))
    }
}

/// The gradient through an ELU, `g * elu'(x)`, from its output `y`.
pub(crate) fn backward_from_output(g: &Tensor, y: &Tensor) -> Result<Tensor> {
    g.contiguous()?
        .apply_op2_no_bwd(&y.contiguous()?, &EluBackward)
}

/// `g * elu'(x)` from the output `y`: `g` where `y > 0`, `g * (y + 1)` elsewhere.
struct EluBackward;

impl CustomOp2 for EluBackward {
    fn name(&self) -> &'static str {
        "fused-elu-backward"
    }
    fn cpu_fwd(
        &self,
        s1: &CpuStorage,
        l1: &Layout,
        s2: &CpuStorage,
        l2: &Layout,
    ) -> Result<(CpuStorage, Shape)> {
        binary_cpu!(
            s1,
            l1,
            s2,
            l2,
            "fused-elu-backward",
            elu_backward_f32,
            |g: f64, y: f64| if y > 0.0 { g } else { g * (y + 1.0) }
        )
    }
}

/// `d = elu'(z) = 1` for `z > 0`, `exp(z)` otherwise.
struct EluDerivative;

impl CustomOp1 for EluDerivative {
    fn name(&self) -> &'static str {
        "elu-derivative"
    }
    fn cpu_fwd(&self, storage: &CpuStorage, layout: &Layout) -> Result<(CpuStorage, Shape)> {
        unary_cpu!(
            storage,
            layout,
            "elu-derivative",
            elu_derivative_f32,
            |z: f64| if z > 0.0 { 1.0 } else { z.exp() }
        )
    }
    fn bwd(&self, arg: &Tensor, _res: &Tensor, grad_res: &Tensor) -> Result<Option<Tensor>> {
        Ok(Some(grad_res.contiguous()?.apply_op2_no_bwd(
            &arg.contiguous()?,
            &EluDerivativeBackward,
        )?))
    }
}

/// `g * elu''(z)`: 0 for `z > 0`, `g * exp(z)` otherwise.
struct EluDerivativeBackward;

impl CustomOp2 for EluDerivativeBackward {
    fn name(&self) -> &'static str {
        "elu-derivative-backward"
    }
    fn cpu_fwd(
        &self,
        s1: &CpuStorage,
        l1: &Layout,
        s2: &CpuStorage,
        l2: &Layout,
    ) -> Result<(CpuStorage, Shape)> {
        binary_cpu!(
            s1,
            l1,
            s2,
            l2,
            "elu-derivative-backward",
            elu_derivative_backward_f32,
            |g: f64, z: f64| if z > 0.0 { 0.0 } else { g * z.exp() }
        )
    }
}

/// `g * elu'(z)`: the input gradient's step through a hidden layer, one pass instead of
/// [`elu_derivative`] and a product.
struct TimesEluDerivative;

impl CustomOp2 for TimesEluDerivative {
    fn name(&self) -> &'static str {
        "times-elu-derivative"
    }
    fn cpu_fwd(
        &self,
        s1: &CpuStorage,
        l1: &Layout,
        s2: &CpuStorage,
        l2: &Layout,
    ) -> Result<(CpuStorage, Shape)> {
        binary_cpu!(
            s1,
            l1,
            s2,
            l2,
            "times-elu-derivative",
            |g: f32, z: f32| g * elu_derivative_f32(z),
            |g: f64, z: f64| g * if z > 0.0 { 1.0 } else { z.exp() }
        )
    }
    /// `d/dg = u * elu'(z)` (this op again), `d/dz = (u * g) * elu''(z)`: the bits of the
    /// product's and [`EluDerivative`]'s backward passes.
    fn bwd(
        &self,
        g: &Tensor,
        z: &Tensor,
        _res: &Tensor,
        grad_res: &Tensor,
    ) -> Result<(Option<Tensor>, Option<Tensor>)> {
        let (u, z) = (grad_res.contiguous()?, z.contiguous()?);
        let grad_g = u.apply_op2_no_bwd(&z, &TimesEluDerivative)?;
        let grad_z = u
            .mul(&g.contiguous()?)?
            .apply_op2_no_bwd(&z, &EluDerivativeBackward)?;
        Ok((Some(grad_g), Some(grad_z)))
    }
}

/// `g * elu'(z)` (same shapes, f32 or f64), differentiable in both; the same bits as
/// `g.mul(&elu_derivative(z))`.
pub fn times_elu_derivative(g: &Tensor, z: &Tensor) -> Result<Tensor> {
    g.contiguous()?
        .apply_op2(&z.contiguous()?, TimesEluDerivative)
}

/// Fused ELU (alpha 1) with a one-pass backward.
pub fn elu(x: &Tensor) -> Result<Tensor> {
    x.contiguous()?.apply_op1(Elu)
}

/// `elu'(z) = exp(min(z, 0))`, differentiable (one-pass backward).
pub fn elu_derivative(z: &Tensor) -> Result<Tensor> {
    z.contiguous()?.apply_op1(EluDerivative)
}

#[cfg(test)]
mod tests {
    use super::*;
    use candle_core::{Device, Var};

    #[test]
    fn fast_expm1_matches_libm() {
        let mut worst = 0.0f64;
        for i in 0..=200_000 {
            let x = -30.0 * (i as f32 / 200_000.0).powi(3); // dense near 0, out to -30
            let fast = expm1_nonpositive_f32(x) as f64;
            let exact = (x as f64).exp_m1();
            let rel = (fast - exact).abs() / exact.abs().max(1e-30);
            if x != 0.0 {
                worst = worst.max(rel);
            }
        }
        assert!(worst < 3e-7, "worst relative error {worst}");
        assert_eq!(expm1_nonpositive_f32(0.0), 0.0);
        assert_eq!(expm1_nonpositive_f32(-200.0), -1.0);
        assert_eq!(expm1_nonpositive_f32(f32::NEG_INFINITY), -1.0);
    }

    /// The function as it was before `2^n` came from the rounding sum's bits: `n as i32`
    /// (a scalar conversion per element on the baseline target).
    fn expm1_by_conversion(x: f32) -> f32 {
        const ROUND: f32 = 12_582_912.0;
        let x = x.clamp(-87.0, 0.0);
        let n = (x * std::f32::consts::LOG2_E + ROUND) - ROUND;
        let r = (x - n * 0.693_145_75) - n * 1.428_606_8e-6;
        let p = r
            * (1.0
                + r * (1.0 / 2.0
                    + r * (1.0 / 6.0
                        + r * (1.0 / 24.0
                            + r * (1.0 / 120.0
                                + r * (1.0 / 720.0 + r * (1.0 / 5040.0 + r * (1.0 / 40320.0))))))));
        let two_n = f32::from_bits(((n as i32 + 127) << 23) as u32);
        two_n * p + (two_n - 1.0)
    }

    /// Inputs over the ELUs' working range, negative ones dense, plus the edges.
    fn inputs() -> Vec<f32> {
        let mut x: Vec<f32> = (0..100_003)
            .map(|i| {
                let u = ((i as u64 * 2_654_435_761) % 1_000_003) as f32 / 1_000_003.0;
                -90.0 * u * u * u + if i % 3 == 0 { 5.0 * u } else { 0.0 }
            })
            .collect();
        x.extend([
            0.0,
            -0.0,
            -87.0,
            -87.5,
            -1e-30,
            1e-30,
            f32::NEG_INFINITY,
            3.0,
        ]);
        x
    }

    #[test]
    fn two_to_the_n_from_bits_is_the_conversion() {
        for &x in &inputs() {
            let (got, was) = (expm1_nonpositive_f32(x), expm1_by_conversion(x));
            assert_eq!(got.to_bits(), was.to_bits(), "x {x}: {got} against {was}");
        }
    }

    #[test]
    fn every_vector_level_gives_the_same_bits() {
        let x = inputs();
        let g: Vec<f32> = x.iter().map(|v| 0.37 - v * 0.01).collect();
        let bits = |v: Vec<f32>| v.into_iter().map(f32::to_bits).collect::<Vec<_>>();
        let scalar1 = |f: fn(f32) -> f32| bits(x.iter().map(|&v| f(v)).collect());
        let scalar2 =
            |f: fn(f32, f32) -> f32| bits(g.iter().zip(&x).map(|(&a, &b)| f(a, b)).collect());
        let expect = [
            scalar1(elu_f32),
            scalar1(elu_derivative_f32),
            scalar2(elu_backward_f32),
            scalar2(elu_derivative_backward_f32),
        ];
        for level in Level::available() {
            let got = [
                bits(map1_at(level, &x, elu_f32)),
                bits(map1_at(level, &x, elu_derivative_f32)),
                bits(map2_at(level, &g, &x, elu_backward_f32)),
                bits(map2_at(level, &g, &x, elu_derivative_backward_f32)),
            ];
            assert!(got == expect, "{level:?} differs from the scalar loop");
        }
    }

    #[test]
    fn matches_candle_elu_and_its_gradients() {
        let data: Vec<f64> = (0..200)
            .map(|i| (i as f64 - 100.0) * 0.037 + 0.011)
            .collect(); // no kink at 0
        let x = Var::from_vec(data, (10, 20), &Device::Cpu).unwrap();
        let ours = elu(&x).unwrap();
        let reference = x.elu(1.0).unwrap();
        let diff = (&ours - &reference)
            .unwrap()
            .abs()
            .unwrap()
            .max_all()
            .unwrap()
            .to_scalar::<f64>()
            .unwrap();
        assert!(diff < 1e-12);
        let w = Tensor::from_vec(
            (0..200).map(|i| (i % 7) as f64 - 3.0).collect::<Vec<_>>(),
            (10, 20),
            &Device::Cpu,
        )
        .unwrap();
        let g1 = ours.mul(&w).unwrap().sum_all().unwrap().backward().unwrap();
        let g2 = reference
            .mul(&w)
            .unwrap()
            .sum_all()
            .unwrap()
            .backward()
            .unwrap();
        let d = (g1.get(&x).unwrap() - g2.get(&x).unwrap())
            .unwrap()
            .abs()
            .unwrap()
            .max_all()
            .unwrap();
        assert!(d.to_scalar::<f64>().unwrap() < 1e-12);
        // elu' and its derivative against candle's exp(min(z, 0)).
        let d_ours = elu_derivative(&x).unwrap();
        let d_ref = x.minimum(0.0).unwrap().exp().unwrap();
        let diff = (&d_ours - &d_ref)
            .unwrap()
            .abs()
            .unwrap()
            .max_all()
            .unwrap()
            .to_scalar::<f64>()
            .unwrap();
        assert!(diff < 1e-12);
        let g1 = d_ours
            .mul(&w)
            .unwrap()
            .sum_all()
            .unwrap()
            .backward()
            .unwrap();
        let g2 = d_ref
            .mul(&w)
            .unwrap()
            .sum_all()
            .unwrap()
            .backward()
            .unwrap();
        let d = (g1.get(&x).unwrap() - g2.get(&x).unwrap())
            .unwrap()
            .abs()
            .unwrap()
            .max_all()
            .unwrap();
        assert!(d.to_scalar::<f64>().unwrap() < 1e-12);
    }

    #[test]
    fn times_elu_derivative_is_the_product_bit_for_bit() {
        let dev = Device::Cpu;
        let n = 40_000; // two parallel chunks
        let z: Vec<f32> = (0..n)
            .map(|i| ((i * 7919 % 2003) as f32 - 1200.0) * 0.01)
            .collect();
        let g: Vec<f32> = (0..n)
            .map(|i| ((i * 31 % 97) as f32 - 48.0) * 0.1)
            .collect();
        let z = Var::from_vec(z, (200, 200), &dev).unwrap();
        let g = Var::from_vec(g, (200, 200), &dev).unwrap();
        let w = Tensor::from_vec(
            (0..n).map(|i| (i % 13) as f32 - 6.0).collect::<Vec<_>>(),
            (200, 200),
            &dev,
        )
        .unwrap();
        let fused = times_elu_derivative(g.as_tensor(), z.as_tensor()).unwrap();
        let apart = g.mul(&elu_derivative(z.as_tensor()).unwrap()).unwrap();
        crate::nn::bit_exact::assert_same_bits_and_gradients(&fused, &apart, &w, &[&g, &z]);
    }
}
