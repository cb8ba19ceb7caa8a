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
//!
//! RMA's teacher (`[rma]`, phase `teacher`): the environment-factor encoder mu maps
//! `concat(normalized privileged, normalized heights)` to a latent of the memory latent's
//! size, and the actor acts on that latent instead of `h` (mu is trained end to end by PPO;
//! the memory encoder waits, untrained, for the adaptation phase, which regresses `h` onto
//! mu's latent). [`ActorCritic::policy`] is always the deployed path (memory latent);
//! [`ActorCritic::acting_policy`] is the one that acts in training and evaluation.

use crate::config::{PolicyConfig, RmaConfig, RmaPhase};
use crate::nn::mlp::Mlp;
use crate::nn::normalizer::EmpiricalNormalizer;
use crate::nn::seeded_init::seeded_var_builder;
use candle_core::{DType, Device, Result, Tensor};
use candle_nn::{Init, VarMap};
use hexapod_core::nets::{ACTOR_OUT, ESTIMATOR_OUT};
use hexapod_core::obs::{ACTOR_OBS_DIM, HEIGHT_SCAN_DIM, HISTORY_DIM, PRIVILEGED_DIM};

/// `0.5 * ln(2 pi)`.
const HALF_LN_2PI: f64 = 0.918_938_533_204_672_8;

/// Raw inputs of a batch: the critic reads all four, an RMA teacher's actor too.
pub struct BatchInput<'a> {
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
    /// RMA's environment-factor encoder mu (privileged + heights -> latent), with `[rma]`.
    pub env_factor_encoder: Option<Mlp>,
    /// Whether the acting actor reads mu's latent (an RMA teacher) instead of `h`.
    pub teacher_latent: bool,
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
    /// Builds the networks in `params` (trainable; fresh weights drawn from `seed`, see
    /// [`seeded_var_builder`]) and the normalizers in `stats`; `rma` adds mu (and, for a
    /// teacher, makes the actor act on its latent).
    pub fn new(
        cfg: &PolicyConfig,
        rma: Option<&RmaConfig>,
        params: &VarMap,
        stats: &VarMap,
        seed: u64,
        dtype: DType,
        device: &Device,
    ) -> Result<Self> {
        let vb = seeded_var_builder(params, seed, dtype, device);
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
        let env_factor_encoder = match rma {
            Some(r) => Some(Mlp::new(
                PRIVILEGED_DIM + HEIGHT_SCAN_DIM,
                &r.encoder_hidden,
                cfg.memory_latent,
                vb.pp("env_factor_encoder"),
            )?),
            None => None,
        };
        Ok(Self {
            estimator,
            memory,
            actor,
            log_std,
            critic,
            privileged_encoder,
            terrain_encoder,
            teacher_latent: rma.is_some_and(|r| r.phase == RmaPhase::Teacher),
            env_factor_encoder,
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

    /// The deployed actor side: action mean and velocity estimate from raw
    /// `actor_obs [B,63]`, `history [B,210]` (the memory encoder's latent).
    pub fn policy(&self, actor_obs: &Tensor, history: &Tensor) -> Result<PolicyOutput> {
        let h = self.norm_history.normalize(history)?;
        let latent = self.memory.forward(&h)?;
        self.actor_on_latent(actor_obs, &h, &latent)
    }

    /// The actor side that acts (rollouts, evaluation): for an RMA teacher the actor on
    /// mu's latent, otherwise [`ActorCritic::policy`].
    pub fn acting_policy(&self, x: &BatchInput) -> Result<PolicyOutput> {
        if !self.teacher_latent {
            return self.policy(x.actor_obs, x.history);
        }
        let latent = self.env_factor_latent(x.privileged, x.heights)?;
        let h = self.norm_history.normalize(x.history)?;
        self.actor_on_latent(x.actor_obs, &h, &latent)
    }

    /// mu's latent `[B, memory_latent]` from raw `privileged [B,42]`, `heights [B,187]`.
    ///
    /// # Panics
    /// Without `[rma]` (no mu built): a caller's bug, [`ActorCritic::acting_policy`]
    /// calls it only for a teacher.
    pub fn env_factor_latent(&self, privileged: &Tensor, heights: &Tensor) -> Result<Tensor> {
        let mu = self
            .env_factor_encoder
            .as_ref()
            .expect("the environment-factor encoder exists with [rma]");
        let p = self.norm_privileged.normalize(privileged)?;
        let e = self.norm_heights.normalize(heights)?;
        mu.forward(&Tensor::cat(&[&p, &e], 1)?)
    }

    /// The memory encoder's latent `[B, memory_latent]` from the raw history.
    pub fn memory_latent(&self, history: &Tensor) -> Result<Tensor> {
        self.memory.forward(&self.norm_history.normalize(history)?)
    }

    /// The low-level actor (and the estimator) on raw `actor_obs`, the *normalized*
    /// history `h` and a latent.
    pub fn actor_on_latent(
        &self,
        actor_obs: &Tensor,
        h: &Tensor,
        latent: &Tensor,
    ) -> Result<PolicyOutput> {
        let a = self.norm_actor.normalize(actor_obs)?;
        let (input, estimate) = match &self.estimator {
            Some(est) => {
                let v_hat = est.forward(h)?;
                (Tensor::cat(&[&a, &v_hat.detach(), latent], 1)?, Some(v_hat))
            }
            None => (Tensor::cat(&[&a, latent], 1)?, None),
        };
        Ok(PolicyOutput {
            mean: self.actor.forward(&input)?,
            estimate,
        })
    }

    /// Critic side: values `[B]`.
    pub fn value(&self, x: &BatchInput) -> Result<Tensor> {
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
        let ac =
            ActorCritic::new(&cfg, None, &params, &stats, 1, DType::F32, &Device::Cpu).unwrap();
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

    /// The acting actor of an RMA teacher: output from mu's latent, which moves with the
    /// privileged input and not with the history (without the estimator, whose `v_hat` is
    /// the history's other way in); the deployed path still reads the memory's latent.
    #[test]
    fn an_rma_teachers_actor_acts_on_mu() {
        let dev = Device::Cpu;
        let (params, stats) = (VarMap::new(), VarMap::new());
        let cfg = PolicyConfig {
            use_estimator: false,
            ..Default::default()
        };
        let rma = RmaConfig::default();
        let ac = ActorCritic::new(&cfg, Some(&rma), &params, &stats, 1, DType::F32, &dev).unwrap();
        assert!(ac.teacher_latent);
        let w = |k: &str| params.data().lock().unwrap()[k].dims().to_vec();
        assert_eq!(w("env_factor_encoder.layers.0.weight"), vec![256, 42 + 187]);
        assert_eq!(w("env_factor_encoder.layers.2.weight"), vec![16, 128]);
        let ramp = |n: usize, dim: usize, k: f32| {
            let v: Vec<f32> = (0..n * dim).map(|i| (i as f32 * k).sin()).collect();
            Tensor::from_vec(v, (n, dim), &dev).unwrap()
        };
        let (obs, heights) = (ramp(2, 63, 0.3), ramp(2, 187, 0.05));
        let (hist_a, hist_b) = (ramp(2, 210, 0.7), ramp(2, 210, 1.9));
        let (priv_a, priv_b) = (ramp(2, 42, 0.4), ramp(2, 42, 1.3));
        let mean = |history: &Tensor, privileged: &Tensor| {
            ac.acting_policy(&BatchInput {
                actor_obs: &obs,
                history,
                privileged,
                heights: &heights,
            })
            .unwrap()
            .mean
            .to_vec2::<f32>()
            .unwrap()
        };
        assert_eq!(mean(&hist_a, &priv_a), mean(&hist_b, &priv_a));
        assert_ne!(mean(&hist_a, &priv_a), mean(&hist_a, &priv_b));
        let deployed = |history: &Tensor| {
            ac.policy(&obs, history)
                .unwrap()
                .mean
                .to_vec2::<f32>()
                .unwrap()
        };
        assert_ne!(deployed(&hist_a), deployed(&hist_b));
        assert_ne!(deployed(&hist_a), mean(&hist_a, &priv_a));
    }

    #[test]
    fn log_prob_and_entropy_match_the_gaussian_formula() {
        let (params, stats) = (VarMap::new(), VarMap::new());
        let cfg = PolicyConfig {
            init_noise_std: 0.5,
            ..Default::default()
        };
        let ac =
            ActorCritic::new(&cfg, None, &params, &stats, 1, DType::F32, &Device::Cpu).unwrap();
        let mean = Tensor::zeros((1, 18), DType::F32, &Device::Cpu).unwrap();
        let act = Tensor::ones((1, 18), DType::F32, &Device::Cpu).unwrap();
        let lp = ac.log_prob(&mean, &act).unwrap().to_vec1::<f32>().unwrap()[0] as f64;
        let per = -0.5 * (1.0f64 / 0.5).powi(2) - 0.5f64.ln() - HALF_LN_2PI;
        assert!((lp - 18.0 * per).abs() < 1e-4, "{lp}");
        let ent = ac.entropy().unwrap().to_scalar::<f32>().unwrap() as f64;
        assert!((ent - 18.0 * (0.5 + HALF_LN_2PI + 0.5f64.ln())).abs() < 1e-4);
    }
}
