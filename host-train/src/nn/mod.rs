//! Network building blocks: ELU MLPs, empirical normalization, the asymmetric actor-critic.

pub mod actor_critic;
pub mod bias;
pub mod elu;
pub mod mlp;
pub mod normalizer;
pub mod seeded_init;
pub(crate) mod simd;

/// The values of `map`'s variables whose names start with `prefix`, sorted by name (tests
/// compare networks with it; panics when none match).
#[cfg(test)]
pub(crate) fn var_values(map: &candle_nn::VarMap, prefix: &str) -> Vec<(String, Vec<f32>)> {
    let data = map.data().lock().unwrap();
    let mut out: Vec<(String, Vec<f32>)> = data
        .iter()
        .filter(|(k, _)| k.starts_with(prefix))
        .map(|(k, v)| {
            let x = v.as_tensor().flatten_all().unwrap().to_vec1::<f32>();
            (k.clone(), x.unwrap())
        })
        .collect();
    out.sort_by(|a, b| a.0.cmp(&b.0));
    assert!(!out.is_empty(), "no variable under `{prefix}`");
    out
}

/// Helpers for the tests that hold a fused operation to the bits of the operations it fuses.
#[cfg(test)]
pub(crate) mod bit_exact {
    use candle_core::{Tensor, Var};

    /// The bit patterns of an f32 tensor's elements.
    pub(crate) fn f32_bits(t: &Tensor) -> Vec<u32> {
        let v = t.flatten_all().unwrap().to_vec1::<f32>().unwrap();
        v.into_iter().map(f32::to_bits).collect()
    }

    /// Asserts that `fused` and `apart` (two expressions of `vars`) hold the same bits, and
    /// so do the gradients of `sum(y * w)` for each of `vars`.
    pub(crate) fn assert_same_bits_and_gradients(
        fused: &Tensor,
        apart: &Tensor,
        w: &Tensor,
        vars: &[&Var],
    ) {
        assert_eq!(f32_bits(fused), f32_bits(apart), "values");
        let grads = |y: &Tensor| y.mul(w).unwrap().sum_all().unwrap().backward().unwrap();
        let (g1, g2) = (grads(fused), grads(apart));
        for (k, v) in vars.iter().enumerate() {
            let (a, b) = (g1.get(v).unwrap(), g2.get(v).unwrap());
            assert_eq!(f32_bits(a), f32_bits(b), "gradient of variable {k}");
        }
    }
}
