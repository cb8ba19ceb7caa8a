//! Seeded initialization of fresh network weights.
//!
//! candle draws a new variable's initial values from an unseeded generator on the CPU
//! (`Device::Cpu` refuses `set_seed`), so two trainings with the same `runner.seed` would
//! start from different weights. [`seeded_var_builder`] builds networks into a [`VarMap`]
//! as `VarBuilder::from_varmap` does, but draws each fresh variable from a ChaCha8 stream
//! seeded by the run's seed and the variable's name: the same seed gives the same weights,
//! whatever order the networks are built in.

use candle_core::{DType, Device, Result, Shape, Tensor, Var};
use candle_nn::init::NormalOrUniform;
use candle_nn::var_builder::SimpleBackend;
use candle_nn::{Init, VarBuilder, VarMap};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

/// A [`VarMap`] whose fresh variables come from a generator seeded by `seed` and their name.
struct SeededVarMap {
    map: VarMap,
    seed: u64,
}

/// FNV-1a of a variable's name: the per-variable part of its generator's seed.
fn name_hash(name: &str) -> u64 {
    name.bytes().fold(0xcbf2_9ce4_8422_2325, |h, b| {
        (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3)
    })
}

/// Draws `init` for `shape` from `rng`, as `candle_nn::Init::var` does from its own
/// generator (the same distributions and parameters).
fn draw(init: Init, shape: &Shape, rng: &mut ChaCha8Rng) -> Result<Vec<f64>> {
    let n = shape.elem_count();
    let uniform = |lo: f64, up: f64, rng: &mut ChaCha8Rng| -> Vec<f64> {
        (0..n).map(|_| rng.gen_range(lo..up)).collect()
    };
    let normal = |mean: f64, stdev: f64, rng: &mut ChaCha8Rng| -> Result<Vec<f64>> {
        let d = Normal::new(mean, stdev).map_err(candle_core::Error::wrap)?;
        Ok((0..n).map(|_| d.sample(rng)).collect())
    };
    Ok(match init {
        Init::Const(v) => vec![v; n],
        Init::Uniform { lo, up } => uniform(lo, up, rng),
        Init::Randn { mean, stdev } => normal(mean, stdev, rng)?,
        Init::Kaiming {
            dist,
            fan,
            non_linearity,
        } => {
            let std = non_linearity.gain() / (fan.for_shape(shape) as f64).sqrt();
            match dist {
                NormalOrUniform::Uniform => {
                    let bound = 3f64.sqrt() * std;
                    uniform(-bound, bound, rng)
                }
                NormalOrUniform::Normal => normal(0.0, std, rng)?,
            }
        }
    })
}

impl SimpleBackend for SeededVarMap {
    fn get(
        &self,
        shape: Shape,
        name: &str,
        init: Init,
        dtype: DType,
        device: &Device,
    ) -> Result<Tensor> {
        let mut data = self.map.data().lock().expect("var map lock");
        if let Some(var) = data.get(name) {
            if var.shape() != &shape {
                candle_core::bail!("shape mismatch on {name}: {shape:?} <> {:?}", var.shape())
            }
            return Ok(var.as_tensor().clone());
        }
        let mut rng = ChaCha8Rng::seed_from_u64(self.seed ^ name_hash(name));
        let values = draw(init, &shape, &mut rng)?;
        let tensor = Tensor::from_vec(values, shape, device)?.to_dtype(dtype)?;
        let var = Var::from_tensor(&tensor)?;
        let out = var.as_tensor().clone();
        data.insert(name.to_string(), var);
        Ok(out)
    }

    fn get_unchecked(&self, name: &str, _dtype: DType, _dev: &Device) -> Result<Tensor> {
        candle_core::bail!("`get_unchecked` does not make sense for a seeded VarMap ({name})")
    }

    fn contains_tensor(&self, name: &str) -> bool {
        self.map
            .data()
            .lock()
            .expect("var map lock")
            .contains_key(name)
    }
}

/// A `VarBuilder` over `map` (as `VarBuilder::from_varmap`) whose fresh variables are drawn
/// from a generator seeded by `seed` and each variable's name.
pub fn seeded_var_builder(
    map: &VarMap,
    seed: u64,
    dtype: DType,
    device: &Device,
) -> VarBuilder<'static> {
    let backend: Box<dyn SimpleBackend> = Box::new(SeededVarMap {
        map: map.clone(),
        seed,
    });
    VarBuilder::from_backend(backend, dtype, device.clone())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::nn::mlp::Mlp;

    fn weights(map: &VarMap) -> Vec<(String, Vec<f32>)> {
        crate::nn::var_values(map, "")
    }

    fn build(seed: u64, order: &[&str]) -> VarMap {
        let map = VarMap::new();
        let vb = seeded_var_builder(&map, seed, DType::F32, &Device::Cpu);
        for name in order {
            Mlp::new(7, &[16, 8], 3, vb.pp(*name)).unwrap();
        }
        map
    }

    #[test]
    fn the_same_seed_gives_the_same_weights_in_any_build_order() {
        let a = weights(&build(5, &["actor", "critic"]));
        let b = weights(&build(5, &["critic", "actor"]));
        assert_eq!(a, b);
        let c = weights(&build(6, &["actor", "critic"]));
        assert!(
            a.iter().zip(&c).all(|(x, y)| x.1 != y.1),
            "another seed, other weights"
        );
    }

    #[test]
    fn fresh_weights_follow_the_torch_linear_bounds() {
        let map = build(1, &["net"]);
        let w = weights(&map);
        let (_, first) = w.iter().find(|(k, _)| k == "net.layers.0.weight").unwrap();
        let bound = 1.0 / 7f32.sqrt();
        assert!(first.iter().all(|x| x.abs() <= bound));
        let spread = first.iter().map(|x| x * x).sum::<f32>() / first.len() as f32;
        // Uniform in +-b has variance b^2 / 3.
        assert!(
            (spread / (bound * bound / 3.0) - 1.0).abs() < 0.25,
            "{spread}"
        );
    }

    #[test]
    fn an_existing_variable_is_returned_not_redrawn() {
        let map = build(1, &["net"]);
        let before = weights(&map);
        let vb = seeded_var_builder(&map, 99, DType::F32, &Device::Cpu);
        Mlp::new(7, &[16, 8], 3, vb.pp("net")).unwrap();
        assert_eq!(before, weights(&map));
        assert!(
            Mlp::new(7, &[16, 9], 3, vb.pp("net")).is_err(),
            "a shape mismatch is refused"
        );
    }
}
