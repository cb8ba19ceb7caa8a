//! The AMP discriminator (paper Sec. III-C): a least-squares GAN on AMP transitions
//! `(s_t, s_t+1)` (122 = 2 x 61, normalized by running statistics `normalizer.amp`), prior
//! transitions -> +1, policy transitions -> -1, with a gradient penalty on prior samples,
//! and the style reward `max(0, 1 - 0.25 (d - 1)^2)`.
//!
//! The penalty's input gradient is an explicit forward expression (see
//! [`Mlp::input_gradient`]), so its gradient with respect to the weights is exact without
//! candle's double backward (which detaches unless `CANDLE_GRAD_DO_NOT_DETACH=1`).

use crate::nn::mlp::Mlp;
use crate::nn::normalizer::EmpiricalNormalizer;
use crate::nn::seeded_init::seeded_var_builder;
use candle_core::{DType, Device, Result, Tensor};
use candle_nn::VarMap;
use hexapod_core::amp::{AMP_GROUPS, AMP_STATE_DIM};

/// Discriminator input size.
pub const DISC_IN: usize = 2 * AMP_STATE_DIM;

/// The discriminator's losses and diagnostics for one minibatch.
pub struct DiscriminatorLoss {
    /// `0.5 (E[(D(prior) - 1)^2] + E[(D(policy) + 1)^2]) + alpha_gp / 2 E[|grad D(prior)|^2]`.
    pub total: Tensor,
    /// The least-squares part.
    pub ls_loss: f32,
    /// The gradient penalty (weighted).
    pub grad_penalty: f32,
    /// Mean D on prior transitions.
    pub d_prior: f32,
    /// Mean D on policy transitions.
    pub d_policy: f32,
}

/// The discriminator and its input normalizer.
pub struct Discriminator {
    /// The network `122 -> hidden -> 1`.
    pub net: Mlp,
    /// Running statistics of single AMP states (applied to both halves).
    pub norm: EmpiricalNormalizer,
    device: Device,
    dtype: DType,
}

impl Discriminator {
    /// Builds the network under `discriminator.*` in `params` (fresh weights drawn from
    /// `seed`, see [`seeded_var_builder`]), the normalizer in `stats`.
    pub fn new(
        hidden: &[usize],
        params: &VarMap,
        stats: &VarMap,
        seed: u64,
        dtype: DType,
        device: &Device,
    ) -> Result<Self> {
        let vb = seeded_var_builder(params, seed, dtype, device);
        Ok(Self {
            net: Mlp::new(DISC_IN, hidden, 1, vb.pp("discriminator"))?,
            norm: EmpiricalNormalizer::new(stats, "amp", AMP_STATE_DIM, device)?,
            device: device.clone(),
            dtype,
        })
    }

    /// Normalized discriminator input `[n, 122]` from flat `[n, 61]` buffers.
    pub fn input(&self, states: &[f32], next_states: &[f32]) -> Result<Tensor> {
        let n = states.len() / AMP_STATE_DIM;
        let s = Tensor::from_slice(states, (n, AMP_STATE_DIM), &self.device)?;
        let sn = Tensor::from_slice(next_states, (n, AMP_STATE_DIM), &self.device)?;
        let s = self.norm.normalize(&s)?.to_dtype(self.dtype)?;
        let sn = self.norm.normalize(&sn)?.to_dtype(self.dtype)?;
        Tensor::cat(&[&s, &sn], 1)
    }

    /// Discriminator outputs `[n]` for normalized inputs `[n, 122]`.
    pub fn forward(&self, x: &Tensor) -> Result<Tensor> {
        self.net.forward(x)?.squeeze(1)
    }

    /// Style rewards `[n]` (unweighted) and raw outputs `d` for policy transitions.
    pub fn style_reward(
        &self,
        states: &[f32],
        next_states: &[f32],
    ) -> Result<(Vec<f32>, Vec<f32>)> {
        let d = self
            .forward(&self.input(states, next_states)?)?
            .to_dtype(DType::F32)?
            .to_vec1::<f32>()?;
        let r = d.iter().map(|&d| style_reward_of(d)).collect();
        Ok((r, d))
    }

    /// What the discriminator's verdict rests on: the mean of `|dD/dx|` over the normalized
    /// inputs `[n, 122]`, per feature group of [`AMP_GROUPS`] (the group's features of both
    /// states of the transition, averaged). The inputs are standardized, so the groups
    /// compare: a group far above the others is where the inputs differ from the priors in
    /// a way the discriminator has learned to see.
    pub fn saliency(&self, x: &Tensor) -> Result<[f32; AMP_GROUPS.len()]> {
        let (_, pre) = self.net.forward_with_preactivations(x)?;
        let per_input = self
            .net
            .input_gradient(&pre)?
            .abs()?
            .mean(0)?
            .to_dtype(DType::F32)?
            .to_vec1::<f32>()?;
        let mut out = [0.0f32; AMP_GROUPS.len()];
        for (o, (_, range)) in out.iter_mut().zip(AMP_GROUPS.iter()) {
            let sum: f32 = range
                .clone()
                .map(|i| per_input[i] + per_input[AMP_STATE_DIM + i])
                .sum();
            *o = sum / (2 * range.len()) as f32;
        }
        Ok(out)
    }

    /// The least-squares loss with gradient penalty on prior inputs `[n, 122]` and policy
    /// inputs `[m, 122]` (both normalized).
    pub fn loss(
        &self,
        prior: &Tensor,
        policy: &Tensor,
        grad_penalty_weight: f64,
    ) -> Result<DiscriminatorLoss> {
        let (d_prior_out, pre) = self.net.forward_with_preactivations(prior)?;
        let d_prior = d_prior_out.squeeze(1)?;
        let d_policy = self.forward(policy)?;
        let prior_loss = (d_prior.clone() - 1.0)?.sqr()?.mean_all()?;
        let policy_loss = (d_policy.clone() + 1.0)?.sqr()?.mean_all()?;
        let ls = ((prior_loss + policy_loss)? * 0.5)?;
        let grad = self.net.input_gradient(&pre)?;
        let penalty = (grad.sqr()?.sum(1)?.mean_all()? * (0.5 * grad_penalty_weight))?;
        let total = (&ls + &penalty)?;
        let scalar = |t: &Tensor| -> Result<f32> { t.to_dtype(DType::F32)?.to_scalar::<f32>() };
        Ok(DiscriminatorLoss {
            ls_loss: scalar(&ls)?,
            grad_penalty: scalar(&penalty)?,
            d_prior: scalar(&d_prior.mean_all()?)?,
            d_policy: scalar(&d_policy.mean_all()?)?,
            total,
        })
    }
}

/// `max(0, 1 - 0.25 (d - 1)^2)`: 1 for a transition judged fully prior-like, 0 at `d <= -1`.
pub fn style_reward_of(d: f32) -> f32 {
    (1.0 - 0.25 * (d - 1.0) * (d - 1.0)).max(0.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use hexapod_core::amp::AMP_BASE_HEIGHT;

    #[test]
    fn style_reward_shape() {
        assert_eq!(style_reward_of(1.0), 1.0);
        assert_eq!(style_reward_of(-1.0), 0.0);
        assert_eq!(style_reward_of(-3.0), 0.0);
        assert!((style_reward_of(0.0) - 0.75).abs() < 1e-7);
    }

    /// The penalty's gradient with respect to the weights (backward through the explicit
    /// input-gradient expression) against central finite differences of the penalty.
    #[test]
    fn penalty_gradient_matches_finite_differences() {
        let dev = Device::Cpu;
        let (params, stats) = (VarMap::new(), VarMap::new());
        let disc = Discriminator::new(&[9, 7], &params, &stats, 1, DType::F64, &dev).unwrap();
        let n = 4;
        let x: Vec<f64> = (0..n * DISC_IN)
            .map(|i| ((i * 7919 % 101) as f64 / 50.0 - 1.0) * 1.5)
            .collect();
        let prior = Tensor::from_vec(x, (n, DISC_IN), &dev).unwrap();
        let penalty = |d: &Discriminator| -> Tensor {
            let (_, pre) = d.net.forward_with_preactivations(&prior).unwrap();
            let g = d.net.input_gradient(&pre).unwrap();
            (g.sqr().unwrap().sum(1).unwrap().mean_all().unwrap() * 5.0).unwrap()
        };
        let grads = penalty(&disc).backward().unwrap();
        let data = params.data().lock().unwrap();
        let mut checked = 0;
        for key in [
            "discriminator.layers.0.weight",
            "discriminator.layers.1.weight",
            "discriminator.layers.1.bias",
            "discriminator.layers.2.weight",
        ] {
            let var = data.get(key).unwrap().clone();
            let analytic = grads
                .get(var.as_tensor())
                .unwrap()
                .flatten_all()
                .unwrap()
                .to_vec1::<f64>()
                .unwrap();
            let base = var
                .as_tensor()
                .flatten_all()
                .unwrap()
                .to_vec1::<f64>()
                .unwrap();
            let shape = var.shape().clone();
            for k in (0..base.len()).step_by(base.len() / 5 + 1) {
                let eps = 1e-5;
                let eval = |d: f64| {
                    let mut w = base.clone();
                    w[k] += d;
                    var.set(&Tensor::from_vec(w, shape.clone(), &dev).unwrap())
                        .unwrap();
                    penalty(&disc).to_scalar::<f64>().unwrap()
                };
                let fd = (eval(eps) - eval(-eps)) / (2.0 * eps);
                var.set(&Tensor::from_vec(base.clone(), shape.clone(), &dev).unwrap())
                    .unwrap();
                let tol = 1e-6 * (1.0 + fd.abs());
                assert!(
                    (fd - analytic[k]).abs() < tol,
                    "{key}[{k}]: fd {fd} analytic {}",
                    analytic[k]
                );
                checked += 1;
            }
        }
        assert!(checked >= 16);
    }

    /// A discriminator that reads only the base height (the first layer's weights zero but
    /// for that input, in both states) has saliency there and nowhere else.
    #[test]
    fn saliency_finds_the_one_input_the_discriminator_reads() {
        let dev = Device::Cpu;
        let (params, stats) = (VarMap::new(), VarMap::new());
        let disc = Discriminator::new(&[8], &params, &stats, 1, DType::F32, &dev).unwrap();
        {
            let data = params.data().lock().unwrap();
            let w = data.get("discriminator.layers.0.weight").unwrap();
            let mut mask = vec![0.0f32; 8 * DISC_IN];
            for row in 0..8 {
                mask[row * DISC_IN + AMP_BASE_HEIGHT] = 1.0;
                mask[row * DISC_IN + AMP_STATE_DIM + AMP_BASE_HEIGHT] = 1.0;
            }
            let mask = Tensor::from_vec(mask, (8, DISC_IN), &dev).unwrap();
            w.set(&(w.as_tensor() * mask).unwrap()).unwrap();
        }
        let x: Vec<f32> = (0..32 * DISC_IN)
            .map(|i| (i * 7919 % 101) as f32 / 50.0 - 1.0)
            .collect();
        let x = Tensor::from_vec(x, (32, DISC_IN), &dev).unwrap();
        let s = disc.saliency(&x).unwrap();
        let height = AMP_GROUPS
            .iter()
            .position(|(name, _)| *name == "base_height")
            .unwrap();
        assert!(s[height] > 0.0, "{s:?}");
        for (k, v) in s.iter().enumerate() {
            if k != height {
                assert_eq!(*v, 0.0, "{}: {s:?}", AMP_GROUPS[k].0);
            }
        }
    }

    #[test]
    fn training_separates_prior_from_policy() {
        use crate::algo::adam::Adam;
        let dev = Device::Cpu;
        let (params, stats) = (VarMap::new(), VarMap::new());
        let disc = Discriminator::new(&[32, 16], &params, &stats, 1, DType::F32, &dev).unwrap();
        let mut opt = Adam::new(&params, 1e-3).unwrap();
        let n = 64;
        let prior = Tensor::ones((n, DISC_IN), DType::F32, &dev).unwrap();
        let policy = Tensor::ones((n, DISC_IN), DType::F32, &dev)
            .unwrap()
            .neg()
            .unwrap();
        for _ in 0..300 {
            let l = disc.loss(&prior, &policy, 1.0).unwrap();
            opt.step(&l.total.backward().unwrap(), None).unwrap();
        }
        let l = disc.loss(&prior, &policy, 1.0).unwrap();
        assert!(
            l.d_prior > 0.5 && l.d_policy < -0.5,
            "{} {}",
            l.d_prior,
            l.d_policy
        );
    }
}
