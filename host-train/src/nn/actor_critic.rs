//! The asymmetric actor-critic of the paper (Table II).
//!
//! Actor side (deployed): the estimator maps the normalized proprioceptive history (210) to
//! the scaled base linear velocity `v_hat` (3, supervised on `privileged[0..3]`); the memory
//! encoder maps the same history to a latent `h`; the low-level actor maps
//! `concat(normalized actor_obs, v_hat, h)` to the action mean (18); `actor.log_std` is a
//! state-independent log standard deviation.
//!
//! Gradients: `v_hat` enters the actor *detached* (the estimator learns only from its
//! supervised loss, as in concurrent state estimation, so the policy cannot bend the estimate
//! into a latent); the memory encoder has no target of its own and is trained end to end by
//! the PPO loss through the actor.
//!
//! Critic side (training only): `g_p` encodes the normalized privileged state (42) into
//! `l^p`, `g_e` the normalized height scan (187) into `l^e`; the critic reads
//! `concat(normalized actor_obs, l^p, l^e)`. Without privileged information ("Baseline",
//! "Concurrent") the critic reads `concat(normalized actor_obs, normalized history)`.

use crate::config::PolicyConfig;
use crate::nn::mlp::Mlp;
use crate::nn::normalizer::EmpiricalNormalizer;
use candle_core::{DType, Device, Result, Tensor};
use candle_nn::{Init, VarBuilder, VarMap};
use hexapod_core::nets::{ACTOR_OUT, ESTIMATOR_OUT};
use hexapod_core::obs::{ACTOR_OBS_DIM, HEIGHT_SCAN_DIM, HISTORY_DIM, PRIVILEGED_DIM};

/// `0.5 * ln(2 pi)`.
const HALF_LN_2PI: f64 = 0.918_938_533_204_672_8;

/// Critic-side inputs of a batch.
pub struct CriticInput<'a> {
    /// Actor observation `[B, 63]` (raw).
    pub actor_obs: &'a Tensor,
    /// History `[B, 210]` (raw).
    pub history: &'a Tensor,
    /// Privileged state `[B, 42]` (raw).
    pub privileged: &'a Tensor,
    /// Height scan `[B, 187]` (raw).
    pub heights: &'a Tensor,
}

/// What the actor side computes for a batch.
pub struct PolicyOutput {
    /// Action mean `[B, 18]`.
    pub mean: Tensor,
    /// Velocity estimate `[B, 3]` (scaled like `privileged[0..3]`), when the estimator is used.
    pub estimate: Option<Tensor>,
}

/// The networks and normalizers of the actor-critic.
pub struct ActorCritic {
    /// Estimator (history -> v_hat).
    pub estimator: Option<Mlp>,
    /// Memory encoder (history -> h).
    pub memory: Mlp,
    /// Low-level actor.
    pub actor: Mlp,
    /// Log standard deviation `[18]`.
    pub log_std: Tensor,
    /// Critic.
    pub critic: Mlp,
    /// Privileged encoder g_p.
    pub privileged_encoder: Option<Mlp>,
    /// Terrain encoder g_e.
    pub terrain_encoder: Option<Mlp>,
    /// Normalizer of the actor observation.
    pub norm_actor: EmpiricalNormalizer,
    /// Normalizer of the history.
    pub norm_history: EmpiricalNormalizer,
    /// Normalizer of the privileged state (critic).
    pub norm_privileged: EmpiricalNormalizer,
    /// Normalizer of the height scan (critic).
    pub norm_heights: EmpiricalNormalizer,
}

impl ActorCritic {
    /// Builds the networks in `params` (trainable) and the normalizers in `stats`.
    pub fn new(
        cfg: &PolicyConfig,
        params: &VarMap,
        stats: &VarMap,
        dtype: DType,
        device: &Device,
    ) -> Result<Self> {
        let vb = VarBuilder::from_varmap(params, dtype, device);
        let estimator = if cfg.use_estimator {
            Some(Mlp::new(
                HISTORY_DIM,
                &cfg.estimator_hidden,
                ESTIMATOR_OUT,
                vb.pp("estimator"),
            )?)
        } else {
            None
        };
        let memory = Mlp::new(
            HISTORY_DIM,
            &cfg.memory_hidden,
            cfg.memory_latent,
            vb.pp("memory"),
        )?;
        let actor_in = Self::actor_input_dim(cfg);
        let actor = Mlp::new(actor_in, &cfg.actor_hidden, ACTOR_OUT, vb.pp("actor"))?;
        let log_std = vb.pp("actor").get_with_hints(
            ACTOR_OUT,
            "log_std",
            Init::Const((cfg.init_noise_std as f64).ln()),
        )?;
        let (privileged_encoder, terrain_encoder, critic_in) = if cfg.privileged_critic {
            let gp = Mlp::new(
                PRIVILEGED_DIM,
                &cfg.privileged_encoder_hidden,
                cfg.privileged_latent,
                vb.pp("privileged_encoder"),
            )?;
            let ge = Mlp::new(
                HEIGHT_SCAN_DIM,
                &cfg.terrain_encoder_hidden,
                cfg.terrain_latent,
                vb.pp("terrain_encoder"),
            )?;
            (
                Some(gp),
                Some(ge),
                ACTOR_OBS_DIM + cfg.privileged_latent + cfg.terrain_latent,
            )
        } else {
            (None, None, ACTOR_OBS_DIM + HISTORY_DIM)
        };
        let critic = Mlp::new(critic_in, &cfg.critic_hidden, 1, vb.pp("critic"))?;
        Ok(Self {
            estimator,
            memory,
            actor,
            log_std,
            critic,
            privileged_encoder,
            terrain_encoder,
            norm_actor: EmpiricalNormalizer::new(stats, "actor_obs", ACTOR_OBS_DIM, device)?,
            norm_history: EmpiricalNormalizer::new(stats, "history", HISTORY_DIM, device)?,
            norm_privileged: EmpiricalNormalizer::new(stats, "privileged", PRIVILEGED_DIM, device)?,
            norm_heights: EmpiricalNormalizer::new(stats, "heights", HEIGHT_SCAN_DIM, device)?,
        })
    }

    /// Input size of the low-level actor for a config.
    pub fn actor_input_dim(cfg: &PolicyConfig) -> usize {
        ACTOR_OBS_DIM + if cfg.use_estimator { ESTIMATOR_OUT } else { 0 } + cfg.memory_latent
    }

    /// Actor side: action mean and velocity estimate from raw `actor_obs [B,63]`, `history [B,210]`.
    pub fn policy(&self, actor_obs: &Tensor, history: &Tensor) -> Result<PolicyOutput> {
        let a = self.norm_actor.normalize(actor_obs)?;
        let h = self.norm_history.normalize(history)?;
        let latent = self.memory.forward(&h)?;
        let (input, estimate) = match &self.estimator {
            Some(est) => {
                let v_hat = est.forward(&h)?;
                (
                    Tensor::cat(&[&a, &v_hat.detach(), &latent], 1)?,
                    Some(v_hat),
                )
            }
            None => (Tensor::cat(&[&a, &latent], 1)?, None),
        };
        Ok(PolicyOutput {
            mean: self.actor.forward(&input)?,
            estimate,
        })
    }

    /// Critic side: values `[B]`.
    pub fn value(&self, x: &CriticInput) -> Result<Tensor> {
        let a = self.norm_actor.normalize(x.actor_obs)?;
        let input = match (&self.privileged_encoder, &self.terrain_encoder) {
            (Some(gp), Some(ge)) => {
                let lp = gp.forward(&self.norm_privileged.normalize(x.privileged)?)?;
                let le = ge.forward(&self.norm_heights.normalize(x.heights)?)?;
                Tensor::cat(&[&a, &lp, &le], 1)?
            }
            _ => Tensor::cat(&[&a, &self.norm_history.normalize(x.history)?], 1)?,
        };
        self.critic.forward(&input)?.squeeze(1)
    }

    /// Log-probability `[B]` of `actions [B,18]` under N(mean, exp(log_std)).
    pub fn log_prob(&self, mean: &Tensor, actions: &Tensor) -> Result<Tensor> {
        let inv_std = self.log_std.neg()?.exp()?;
        let z = actions.sub(mean)?.broadcast_mul(&inv_std)?;
        let per_dim = (z.sqr()? * -0.5)?.broadcast_sub(&self.log_std)?;
        per_dim.sum(1)? - HALF_LN_2PI * ACTOR_OUT as f64
    }

    /// Entropy of the action distribution (the same for every sample).
    pub fn entropy(&self) -> Result<Tensor> {
        self.log_std.sum_all()? + (0.5 + HALF_LN_2PI) * ACTOR_OUT as f64
    }

    /// Folds a batch of raw observations into the normalizers.
    pub fn update_normalizers(
        &mut self,
        actor_obs: &[f32],
        history: &[f32],
        privileged: &[f32],
        heights: &[f32],
    ) -> Result<()> {
        self.norm_actor.update(actor_obs)?;
        self.norm_history.update(history)?;
        self.norm_privileged.update(privileged)?;
        self.norm_heights.update(heights)
    }

    /// Re-reads normalizer statistics after a checkpoint load.
    pub fn sync_normalizers(&mut self) -> Result<()> {
        self.norm_actor.sync_from_vars()?;
        self.norm_history.sync_from_vars()?;
        self.norm_privileged.sync_from_vars()?;
        self.norm_heights.sync_from_vars()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn paper_shapes_and_keys() {
        let (params, stats) = (VarMap::new(), VarMap::new());
        let cfg = PolicyConfig::default();
        let ac = ActorCritic::new(&cfg, &params, &stats, DType::F32, &Device::Cpu).unwrap();
        let data = params.data().lock().unwrap();
        let shape = |k: &str| data.get(k).unwrap_or_else(|| panic!("{k}")).dims().to_vec();
        assert_eq!(shape("actor.layers.0.weight"), vec![256, 63 + 3 + 16]);
        assert_eq!(shape("actor.layers.3.weight"), vec![18, 64]);
        assert_eq!(shape("memory.layers.3.weight"), vec![16, 128]);
        assert_eq!(shape("estimator.layers.2.weight"), vec![3, 32]);
        assert_eq!(shape("privileged_encoder.layers.2.weight"), vec![8, 32]);
        assert_eq!(shape("terrain_encoder.layers.2.weight"), vec![16, 128]);
        assert_eq!(shape("critic.layers.0.weight"), vec![512, 63 + 8 + 16]);
        assert_eq!(shape("actor.log_std"), vec![18]);
        drop(data);
        let b = 3;
        let obs = Tensor::zeros((b, 63), DType::F32, &Device::Cpu).unwrap();
        let hist = Tensor::zeros((b, 210), DType::F32, &Device::Cpu).unwrap();
        let out = ac.policy(&obs, &hist).unwrap();
        assert_eq!(out.mean.dims(), &[b, 18]);
        assert_eq!(out.estimate.unwrap().dims(), &[b, 3]);
        assert!(stats
            .data()
            .lock()
            .unwrap()
            .contains_key("normalizer.history.mean"));
    }

    #[test]
    fn log_prob_and_entropy_match_the_gaussian_formula() {
        let (params, stats) = (VarMap::new(), VarMap::new());
        let cfg = PolicyConfig {
            init_noise_std: 0.5,
            ..Default::default()
        };
        let ac = ActorCritic::new(&cfg, &params, &stats, DType::F32, &Device::Cpu).unwrap();
        let mean = Tensor::zeros((1, 18), DType::F32, &Device::Cpu).unwrap();
        let act = Tensor::ones((1, 18), DType::F32, &Device::Cpu).unwrap();
        let lp = ac.log_prob(&mean, &act).unwrap().to_vec1::<f32>().unwrap()[0] as f64;
        let per = -0.5 * (1.0f64 / 0.5).powi(2) - 0.5f64.ln() - HALF_LN_2PI;
        assert!((lp - 18.0 * per).abs() < 1e-4, "{lp}");
        let ent = ac.entropy().unwrap().to_scalar::<f32>().unwrap() as f64;
        assert!((ent - 18.0 * (0.5 + HALF_LN_2PI + 0.5f64.ln())).abs() < 1e-4);
    }
}
