//! Empirical observation normalization (rsl_rl's `EmpiricalNormalization`): running mean and
//! variance over everything seen, applied as `(x - mean) / std` where the stored `std`
//! already includes the epsilon. The statistics live in variables `normalizer.<name>.mean|std`
//! (and `.count`), so the exported checkpoint carries them.

use crate::nn::bias::check_rows;
use crate::nn::elu::slice as contiguous;
use crate::nn::simd;
use candle_core::{CpuStorage, CustomOp3, DType, Device, Layout, Result, Shape, Tensor, Var};
use candle_nn::VarMap;

/// Added to the standard deviation (rsl_rl's default).
pub const NORMALIZER_EPS: f64 = 1e-2;

/// Running normalization of one observation group.
#[derive(Debug)]
pub struct EmpiricalNormalizer {
    dim: usize,
    count: f64,
    mean: Vec<f64>,
    var: Vec<f64>,
    mean_var: Var,
    std_var: Var,
    count_var: Var,
}

fn register(map: &VarMap, key: &str, init: Tensor) -> Result<Var> {
    let mut data = map.data().lock().expect("var map lock");
    let var = Var::from_tensor(&init)?;
    data.insert(key.to_string(), var.clone());
    Ok(var)
}

impl EmpiricalNormalizer {
    /// Registers `normalizer.<name>.*` in `map` with identity statistics.
    pub fn new(map: &VarMap, name: &str, dim: usize, device: &Device) -> Result<Self> {
        let prefix = format!("normalizer.{name}");
        let mean_var = register(
            map,
            &format!("{prefix}.mean"),
            Tensor::zeros(dim, DType::F32, device)?,
        )?;
        let std_var = register(
            map,
            &format!("{prefix}.std"),
            Tensor::ones(dim, DType::F32, device)?,
        )?;
        let count_var = register(
            map,
            &format!("{prefix}.count"),
            Tensor::zeros(1, DType::F32, device)?,
        )?;
        Ok(Self {
            dim,
            count: 0.0,
            mean: vec![0.0; dim],
            var: vec![1.0; dim],
            mean_var,
            std_var,
            count_var,
        })
    }

    /// Size of one observation.
    pub fn dim(&self) -> usize {
        self.dim
    }

    /// Number of samples seen.
    pub fn count(&self) -> f64 {
        self.count
    }

    /// Folds a batch `[n, dim]` (flat, row-major) into the statistics (Chan et al.'s merge).
    pub fn update(&mut self, batch: &[f32]) -> Result<()> {
        let n = batch.len() / self.dim;
        if n == 0 {
            return Ok(());
        }
        let mut b_mean = vec![0.0f64; self.dim];
        for row in batch.chunks_exact(self.dim) {
            for (m, &x) in b_mean.iter_mut().zip(row) {
                *m += x as f64;
            }
        }
        b_mean.iter_mut().for_each(|m| *m /= n as f64);
        let mut b_var = vec![0.0f64; self.dim];
        for row in batch.chunks_exact(self.dim) {
            for ((v, &x), m) in b_var.iter_mut().zip(row).zip(&b_mean) {
                let d = x as f64 - m;
                *v += d * d;
            }
        }
        b_var.iter_mut().for_each(|v| *v /= n as f64);
        let total = self.count + n as f64;
        let (wa, wb) = (self.count / total, n as f64 / total);
        for i in 0..self.dim {
            let delta = b_mean[i] - self.mean[i];
            let var = if self.count == 0.0 {
                b_var[i]
            } else {
                wa * self.var[i] + wb * b_var[i] + wa * wb * delta * delta
            };
            self.mean[i] += wb * delta;
            self.var[i] = var;
        }
        self.count = total;
        self.write_vars()
    }

    fn write_vars(&self) -> Result<()> {
        let device = self.mean_var.device().clone();
        let mean: Vec<f32> = self.mean.iter().map(|&m| m as f32).collect();
        let std: Vec<f32> = self
            .var
            .iter()
            .map(|&v| (v.sqrt() + NORMALIZER_EPS) as f32)
            .collect();
        self.mean_var
            .set(&Tensor::from_vec(mean, self.dim, &device)?)?;
        self.std_var
            .set(&Tensor::from_vec(std, self.dim, &device)?)?;
        self.count_var
            .set(&Tensor::from_vec(vec![self.count as f32], 1, &device)?)
    }

    /// Re-reads the statistics from the variables (after a checkpoint was loaded into them).
    pub fn sync_from_vars(&mut self) -> Result<()> {
        let mean = self.mean_var.as_tensor().to_vec1::<f32>()?;
        let std = self.std_var.as_tensor().to_vec1::<f32>()?;
        self.count = self.count_var.as_tensor().to_vec1::<f32>()?[0] as f64;
        self.mean = mean.iter().map(|&m| m as f64).collect();
        self.var = std
            .iter()
            .map(|&s| (s as f64 - NORMALIZER_EPS).max(0.0).powi(2))
            .collect();
        Ok(())
    }

    /// Normalizes `[B, dim]`. The statistics enter as constants (detached from their
    /// variables, which no optimizer trains), so normalized data tracks no gradient and
    /// the backward pass neither differentiates the normalization nor forms the input
    /// gradient of the first layer it feeds.
    ///
    /// Data that tracks no gradient (observations, as the trainer feeds them) is normalized
    /// in one pass ([`NormalizeRows`]); anything else by candle's broadcast operations, which
    /// the one pass equals bit for bit (tested).
    pub fn normalize(&self, x: &Tensor) -> Result<Tensor> {
        let (mean, std) = (self.mean_var.as_tensor(), self.std_var.as_tensor());
        if !x.track_op() && x.dtype() == DType::F32 && x.dims().len() == 2 {
            return x.contiguous()?.apply_op3_no_bwd(mean, std, &NormalizeRows);
        }
        x.broadcast_sub(&mean.detach())?
            .broadcast_div(&std.detach())
    }
}

/// `(x [B, N] - mean [N]) / std [N]` in one pass (f32; no gradient).
struct NormalizeRows;

impl CustomOp3 for NormalizeRows {
    fn name(&self) -> &'static str {
        "normalize-rows"
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
        let name = self.name();
        check_rows(name, l1, l2.shape().elem_count(), "a mean")?;
        check_rows(name, l1, l3.shape().elem_count(), "a standard deviation")?;
        let (CpuStorage::F32(x), CpuStorage::F32(mean), CpuStorage::F32(std)) = (s1, s2, s3) else {
            return Err(candle_core::Error::Msg(format!("{name}: f32 only")));
        };
        let (x, mean, std) = (
            contiguous(x, l1, name)?,
            contiguous(mean, l2, name)?,
            contiguous(std, l3, name)?,
        );
        let mut out: Vec<f32> = Vec::with_capacity(x.len());
        simd::widest(simd::NormalizeRows {
            out: &mut out.spare_capacity_mut()[..x.len()],
            x,
            mean,
            std,
        });
        // SAFETY: `x` is whole rows of `n` (checked above), each element written by the loop.
        unsafe { out.set_len(x.len()) };
        Ok((CpuStorage::F32(out), l1.shape().clone()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn merged_statistics_equal_the_batch_statistics() {
        let map = VarMap::new();
        let mut n = EmpiricalNormalizer::new(&map, "x", 2, &Device::Cpu).unwrap();
        let data: Vec<f32> = (0..20)
            .map(|i| (i as f32 * 0.7).sin() * 3.0 + (i % 2) as f32)
            .collect();
        n.update(&data[..6]).unwrap();
        n.update(&data[6..]).unwrap();
        for d in 0..2 {
            let col: Vec<f64> = data.iter().skip(d).step_by(2).map(|&x| x as f64).collect();
            let mean = col.iter().sum::<f64>() / col.len() as f64;
            let var = col.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / col.len() as f64;
            assert!((n.mean[d] - mean).abs() < 1e-9 && (n.var[d] - var).abs() < 1e-9);
        }
        let x = Tensor::from_vec(
            vec![n.mean[0] as f32, n.mean[1] as f32 + 1.0],
            (1, 2),
            &Device::Cpu,
        )
        .unwrap();
        let y = n.normalize(&x).unwrap().to_vec2::<f32>().unwrap();
        assert!(y[0][0].abs() < 1e-6);
        assert!((y[0][1] - 1.0 / (n.var[1].sqrt() + NORMALIZER_EPS) as f32).abs() < 1e-5);
        assert!(map.data().lock().unwrap().contains_key("normalizer.x.std"));
    }

    #[test]
    fn normalized_data_tracks_no_gradient() {
        let map = VarMap::new();
        let n = EmpiricalNormalizer::new(&map, "x", 2, &Device::Cpu).unwrap();
        let x = Tensor::ones((3, 2), DType::F32, &Device::Cpu).unwrap();
        assert!(!n.normalize(&x).unwrap().track_op());
    }

    #[test]
    fn one_pass_normalization_is_candles_bit_for_bit() {
        let map = VarMap::new();
        let mut n = EmpiricalNormalizer::new(&map, "x", 37, &Device::Cpu).unwrap();
        let data: Vec<f32> = (0..37 * 300)
            .map(|i| ((i * 7919 % 1009) as f32 - 400.0) * 0.013 + (i % 37) as f32)
            .collect();
        n.update(&data).unwrap();
        let x = Tensor::from_vec(data, (300, 37), &Device::Cpu).unwrap();
        let fused = n.normalize(&x).unwrap();
        let reference = x
            .broadcast_sub(n.mean_var.as_tensor())
            .unwrap()
            .broadcast_div(n.std_var.as_tensor())
            .unwrap();
        use crate::nn::bit_exact::f32_bits;
        assert_eq!(f32_bits(&fused), f32_bits(&reference));
        assert!(!fused.track_op());
        // A tensor that tracks gradients keeps them through the normalization.
        let v = candle_core::Var::from_tensor(&x).unwrap();
        let g = n
            .normalize(v.as_tensor())
            .unwrap()
            .sum_all()
            .unwrap()
            .backward()
            .unwrap();
        assert!(g.get(v.as_tensor()).is_some());
    }
}
