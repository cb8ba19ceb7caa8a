//! RMA's adaptation phase (Kumar et al. 2021, phase 2): the teacher's actor, estimator and
//! environment-factor encoder mu stay frozen, and the memory encoder (history -> latent)
//! learns to regress mu's latent by MSE, on the states the *student* visits (the actor fed
//! by the memory's latent: RMA's on-policy data collection).
//!
//! Each iteration rolls out `steps_per_iteration` policy steps of every robot, acting with
//! action means (the deployed behaviour, no exploration noise). Early iterations mix in the
//! teacher as DAgger does: each robot's executed action at each step is the teacher's with
//! probability `beta_k = max(0, 1 - k / teacher_mix_iterations)`, else the student's, so the
//! first rollouts are not spent falling while the memory's latent is still random. The
//! regression target is mu's latent of every visited state, whichever policy acted. Then
//! `epochs` passes of `mini_batches` Adam steps over that rollout update the memory encoder
//! alone (its own Adam over the `memory.*` variables); the normalizers stay the teacher's
//! (the history normalizer also feeds the frozen estimator).

use crate::algo::adam::Adam;
use crate::algo::ppo::{Ppo, PpoError};
use crate::algo::storage::gather_rows;
use candle_core::{Result, Tensor};
use candle_nn::VarMap;
use hexapod_core::nets::ACTOR_OUT;
use hexapod_core::obs::{ACTOR_OBS_DIM, HEIGHT_SCAN_DIM, HISTORY_DIM, PRIVILEGED_DIM};
use host_sim::vec_env::{Observations, VecEnv};
use rand::seq::SliceRandom;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Why adaptation could not start or continue.
#[derive(Debug, thiserror::Error)]
pub enum AdaptError {
    /// The learner's config is not an RMA teacher.
    #[error("not an RMA teacher: its config has {found}; train one with `hexapod train -c configs/rma.toml`")]
    NotATeacher {
        /// What the config has instead.
        found: String,
    },
    /// A setting is out of range.
    #[error("invalid adaptation setting: {0}")]
    Invalid(String),
    /// A tensor operation failed.
    #[error("tensor error: {0}")]
    Candle(#[from] candle_core::Error),
    /// The learner could not be built.
    #[error(transparent)]
    Ppo(#[from] PpoError),
    /// The regression loss became NaN or infinite; the memory encoder was not updated with it.
    #[error("non-finite latent regression loss at adaptation iteration {0}")]
    NonFiniteLoss(usize),
}

/// Settings of the adaptation phase.
#[derive(Clone, Debug)]
pub struct AdaptationConfig {
    /// Policy steps per robot per iteration.
    pub steps_per_iteration: usize,
    /// Passes over each iteration's rollout.
    pub epochs: usize,
    /// Minibatches per pass.
    pub mini_batches: usize,
    /// Adam learning rate of the memory encoder.
    pub learning_rate: f64,
    /// Global gradient-norm clip.
    pub max_grad_norm: f64,
    /// Iterations over which the teacher's share of executed actions falls from 1 to 0
    /// (0: the student acts from the start).
    pub teacher_mix_iterations: usize,
    /// Seed of the mixing draws and the minibatch order.
    pub seed: u64,
}

impl Default for AdaptationConfig {
    fn default() -> Self {
        Self {
            steps_per_iteration: 24,
            epochs: 4,
            mini_batches: 4,
            learning_rate: 5e-4,
            max_grad_norm: 1.0,
            teacher_mix_iterations: 20,
            seed: 1,
        }
    }
}

/// What one adaptation iteration measured.
#[derive(Clone, Debug, Default)]
pub struct AdaptationStats {
    /// Iteration (0-based).
    pub iteration: usize,
    /// Probability that a step executed the teacher's action.
    pub teacher_share: f64,
    /// MSE between the memory's and mu's latents on the rollout, before the update.
    pub latent_mse: f64,
    /// Variance of mu's latent on the rollout (the MSE of predicting its mean).
    pub latent_variance: f64,
    /// Mean regression loss over the update's minibatches.
    pub regression_loss: f64,
    /// Mean regression loss of the update's last pass.
    pub regression_loss_last_epoch: f64,
    /// RMS difference of the student's and the teacher's action means (action units).
    pub action_gap_rms: f64,
    /// Mean per-step environment reward.
    pub reward_per_step: f64,
    /// Episodes that ended by termination (falls), not time-out.
    pub terminations: usize,
    /// Episodes that ended.
    pub episodes: usize,
    /// Environment steps taken.
    pub env_steps: usize,
}

/// One rollout's regression data.
struct Rollout {
    /// `[M, 210]`.
    history: Vec<f32>,
    /// mu's latents `[M, latent]`.
    targets: Vec<f32>,
}

/// The adaptation learner: the frozen teacher, the environment, the memory's optimizer.
pub struct Adaptation {
    /// The teacher's learner; only `memory.*` changes.
    pub ppo: Ppo,
    env: Box<dyn VecEnv>,
    obs: Observations,
    opt: Adam,
    rng: ChaCha8Rng,
    cfg: AdaptationConfig,
    latent_dim: usize,
    /// Next iteration to run.
    pub iteration: usize,
}

/// The teacher's share of executed actions at `iteration`: `max(0, 1 - k / mix)`.
pub fn teacher_share(iteration: usize, mix_iterations: usize) -> f64 {
    if mix_iterations == 0 {
        return 0.0;
    }
    (1.0 - iteration as f64 / mix_iterations as f64).max(0.0)
}

/// The `memory.*` variables of `params`, as their own map (sharing storage).
fn memory_vars(params: &VarMap) -> VarMap {
    let sub = VarMap::new();
    {
        let src = params.data().lock().expect("var map lock");
        let mut dst = sub.data().lock().expect("var map lock");
        for (k, v) in src.iter().filter(|(k, _)| k.starts_with("memory.")) {
            dst.insert(k.clone(), v.clone());
        }
    }
    sub
}

impl Adaptation {
    /// Adaptation of `ppo` (an RMA teacher, weights loaded) on `env`.
    pub fn new(
        ppo: Ppo,
        mut env: Box<dyn VecEnv>,
        cfg: AdaptationConfig,
    ) -> std::result::Result<Self, AdaptError> {
        if !ppo.cfg.rma_teacher() {
            let found = match &ppo.cfg.rma {
                None => "no [rma] section".to_string(),
                Some(r) => format!("rma.phase = {:?} (already adapted)", r.phase),
            };
            return Err(AdaptError::NotATeacher { found });
        }
        if cfg.steps_per_iteration == 0 || cfg.epochs == 0 || cfg.mini_batches == 0 {
            return Err(AdaptError::Invalid(
                "steps per iteration, epochs and minibatches must be positive".into(),
            ));
        }
        if cfg.steps_per_iteration * env.num_envs() < cfg.mini_batches {
            return Err(AdaptError::Invalid(format!(
                "{} samples per iteration cannot fill {} minibatches",
                cfg.steps_per_iteration * env.num_envs(),
                cfg.mini_batches
            )));
        }
        if cfg.learning_rate.is_nan() || cfg.learning_rate <= 0.0 {
            return Err(AdaptError::Invalid(
                "the learning rate must be positive".into(),
            ));
        }
        let opt = Adam::new(&memory_vars(&ppo.params), cfg.learning_rate)?;
        let obs = env.reset();
        Ok(Self {
            latent_dim: ppo.cfg.policy.memory_latent,
            rng: ChaCha8Rng::seed_from_u64(cfg.seed),
            ppo,
            env,
            obs,
            opt,
            cfg,
            iteration: 0,
        })
    }

    /// One iteration: a rollout with the student (the teacher mixed in early), then the
    /// memory encoder's regression onto mu's latent.
    pub fn iterate(&mut self) -> std::result::Result<AdaptationStats, AdaptError> {
        let beta = teacher_share(self.iteration, self.cfg.teacher_mix_iterations);
        let mut st = AdaptationStats {
            iteration: self.iteration,
            teacher_share: beta,
            ..Default::default()
        };
        let data = self.collect(beta, &mut st)?;
        let (mean, last) = self.update(&data)?;
        st.regression_loss = mean;
        st.regression_loss_last_epoch = last;
        self.iteration += 1;
        Ok(st)
    }

    fn collect(&mut self, beta: f64, st: &mut AdaptationStats) -> Result<Rollout> {
        let n = self.env.num_envs();
        let steps = self.cfg.steps_per_iteration;
        let dev = self.ppo.device.clone();
        let mut data = Rollout {
            history: Vec::with_capacity(n * steps * HISTORY_DIM),
            targets: Vec::with_capacity(n * steps * self.latent_dim),
        };
        let (mut gap_sq, mut latent_sq) = (0.0f64, 0.0f64);
        for _ in 0..steps {
            let obs = &self.obs;
            let actor = Tensor::from_slice(&obs.actor, (n, ACTOR_OBS_DIM), &dev)?;
            let history = Tensor::from_slice(&obs.history, (n, HISTORY_DIM), &dev)?;
            let privileged = Tensor::from_slice(&obs.privileged, (n, PRIVILEGED_DIM), &dev)?;
            let heights = Tensor::from_slice(&obs.heights, (n, HEIGHT_SCAN_DIM), &dev)?;
            let ac = &self.ppo.ac;
            let h = ac.norm_history.normalize(&history)?;
            let target = ac.env_factor_latent(&privileged, &heights)?;
            let student_latent = ac.memory.forward(&h)?;
            let teacher = ac
                .actor_on_latent(&actor, &h, &target)?
                .mean
                .flatten_all()?
                .to_vec1::<f32>()?;
            let student = ac
                .actor_on_latent(&actor, &h, &student_latent)?
                .mean
                .flatten_all()?
                .to_vec1::<f32>()?;
            latent_sq += student_latent
                .sub(&target)?
                .sqr()?
                .sum_all()?
                .to_scalar::<f32>()? as f64;
            let mut actions = student.clone();
            for i in 0..n {
                let row = i * ACTOR_OUT..(i + 1) * ACTOR_OUT;
                for (s, t) in student[row.clone()].iter().zip(&teacher[row.clone()]) {
                    gap_sq += ((s - t) * (s - t)) as f64;
                }
                if beta > 0.0 && self.rng.gen::<f64>() < beta {
                    actions[row.clone()].copy_from_slice(&teacher[row]);
                }
            }
            data.history.extend_from_slice(&obs.history);
            data.targets
                .extend_from_slice(&target.flatten_all()?.to_vec1::<f32>()?);
            let res = self.env.step(&actions);
            for i in 0..n {
                st.reward_per_step += res.rewards[i] as f64;
                if res.dones[i] {
                    st.episodes += 1;
                    if !res.time_outs[i] {
                        st.terminations += 1;
                    }
                }
            }
            self.obs = res.obs;
        }
        let samples = (n * steps) as f64;
        st.env_steps = n * steps;
        st.reward_per_step /= samples;
        st.action_gap_rms = (gap_sq / (samples * ACTOR_OUT as f64)).sqrt();
        st.latent_mse = latent_sq / (samples * self.latent_dim as f64);
        st.latent_variance = variance_per_column(&data.targets, self.latent_dim);
        Ok(data)
    }

    /// The regression passes; returns (mean loss, mean loss of the last pass).
    fn update(&mut self, data: &Rollout) -> std::result::Result<(f64, f64), AdaptError> {
        let dev = self.ppo.device.clone();
        let rows = data.targets.len() / self.latent_dim;
        let batch = rows / self.cfg.mini_batches;
        let (mut sum, mut count, mut last) = (0.0f64, 0usize, 0.0f64);
        for _ in 0..self.cfg.epochs {
            let mut order: Vec<usize> = (0..rows).collect();
            order.shuffle(&mut self.rng);
            let mut epoch_sum = 0.0f64;
            for idx in order.chunks_exact(batch).take(self.cfg.mini_batches) {
                let history = Tensor::from_vec(
                    gather_rows(&data.history, HISTORY_DIM, idx),
                    (idx.len(), HISTORY_DIM),
                    &dev,
                )?;
                let target = Tensor::from_vec(
                    gather_rows(&data.targets, self.latent_dim, idx),
                    (idx.len(), self.latent_dim),
                    &dev,
                )?;
                let loss = self.latent_loss(&history, &target)?;
                let value = loss.to_scalar::<f32>()? as f64;
                if !value.is_finite() {
                    return Err(AdaptError::NonFiniteLoss(self.iteration));
                }
                let grads = loss.backward()?;
                self.opt.step(&grads, Some(self.cfg.max_grad_norm))?;
                epoch_sum += value;
                sum += value;
                count += 1;
            }
            last = epoch_sum / self.cfg.mini_batches as f64;
        }
        Ok((sum / count.max(1) as f64, last))
    }

    /// MSE between the memory's and mu's latents on a batch of raw observations.
    pub fn latent_mse(&self, obs: &Observations) -> Result<f64> {
        let dev = &self.ppo.device;
        let n = obs.history.len() / HISTORY_DIM;
        let history = Tensor::from_slice(&obs.history, (n, HISTORY_DIM), dev)?;
        let privileged = Tensor::from_slice(&obs.privileged, (n, PRIVILEGED_DIM), dev)?;
        let heights = Tensor::from_slice(&obs.heights, (n, HEIGHT_SCAN_DIM), dev)?;
        let target = self.ppo.ac.env_factor_latent(&privileged, &heights)?;
        let mse = self.latent_loss(&history, &target)?;
        Ok(mse.to_scalar::<f32>()? as f64)
    }

    /// The regression loss: mean squared error of the memory's latent on raw `history`
    /// against `target` (mu's latent).
    fn latent_loss(&self, history: &Tensor, target: &Tensor) -> Result<Tensor> {
        self.ppo
            .ac
            .memory_latent(history)?
            .sub(target)?
            .sqr()?
            .mean_all()
    }

    /// The current observations of the environment's robots.
    pub fn observations(&self) -> &Observations {
        &self.obs
    }

    /// Marks the learner as adapted: its config says `rma.phase = "adapted"` and its actor
    /// acts on the memory's latent, as a checkpoint of it will load.
    pub fn into_adapted(mut self) -> Ppo {
        if let Some(r) = &mut self.ppo.cfg.rma {
            r.phase = crate::config::RmaPhase::Adapted;
        }
        self.ppo.ac.teacher_latent = false;
        self.ppo
    }
}

/// Mean over columns of each column's variance, `[rows, dim]` row-major.
fn variance_per_column(x: &[f32], dim: usize) -> f64 {
    let rows = x.len() / dim.max(1);
    if rows == 0 {
        return f64::NAN;
    }
    let mut total = 0.0f64;
    for c in 0..dim {
        let col = x.iter().skip(c).step_by(dim).map(|&v| v as f64);
        let mean = col.clone().sum::<f64>() / rows as f64;
        total += col.map(|v| (v - mean).powi(2)).sum::<f64>() / rows as f64;
    }
    total / dim as f64
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::{EnvKind, PriorKind, RmaConfig, TrainConfig};
    use crate::env::make_env;
    use crate::nn::var_values;

    /// A small teacher on the point-mass environment (untrained: the adaptation's mechanics
    /// do not need a good one).
    fn teacher_config() -> TrainConfig {
        let mut c = TrainConfig::default();
        c.env.kind = EnvKind::Fake;
        c.env.num_envs = 8;
        c.policy.estimator_hidden = vec![16];
        c.policy.memory_hidden = vec![32];
        c.policy.actor_hidden = vec![16];
        c.policy.critic_hidden = vec![8];
        c.policy.privileged_encoder_hidden = vec![8];
        c.policy.terrain_encoder_hidden = vec![8];
        c.rewards.style = false;
        c.amp.prior_kind = PriorKind::Synthetic;
        c.rma = Some(RmaConfig {
            encoder_hidden: vec![16],
            ..Default::default()
        });
        c
    }

    #[test]
    fn the_regression_loss_falls_and_only_the_memory_encoder_moves() {
        let mut cfg = teacher_config();
        cfg.runner.seed = 5;
        // Ppo::new draws the first weights from runner.seed.
        let mut ppo = Ppo::new(&cfg).unwrap();
        // Teacher statistics as after training, so the normalizers are not the identity.
        let mut env = make_env(&cfg).unwrap();
        let o = env.reset();
        ppo.ac
            .update_normalizers(&o.actor, &o.history, &o.privileged, &o.heights)
            .unwrap();
        let frozen: Vec<_> = ["actor.", "estimator.", "env_factor_encoder.", "critic."]
            .iter()
            .map(|p| var_values(&ppo.params, p))
            .collect();
        let norms = var_values(&ppo.stats, "normalizer.");
        let memory_before = var_values(&ppo.params, "memory.");
        let acfg = AdaptationConfig {
            steps_per_iteration: 8,
            epochs: 4,
            mini_batches: 2,
            learning_rate: 1e-3,
            teacher_mix_iterations: 2,
            seed: 3,
            ..Default::default()
        };
        let mut adapt = Adaptation::new(ppo, make_env(&cfg).unwrap(), acfg).unwrap();
        let probe = adapt.observations().clone();
        let before = adapt.latent_mse(&probe).unwrap();
        let stats: Vec<AdaptationStats> = (0..6).map(|_| adapt.iterate().unwrap()).collect();
        let after = adapt.latent_mse(&probe).unwrap();
        assert!(after < 0.6 * before, "latent MSE {before} -> {after}");
        assert!(
            stats[5].latent_mse < stats[0].latent_mse,
            "{} -> {}",
            stats[0].latent_mse,
            stats[5].latent_mse
        );
        assert_eq!(
            stats.iter().map(|s| s.teacher_share).collect::<Vec<_>>(),
            vec![1.0, 0.5, 0.0, 0.0, 0.0, 0.0]
        );
        let ppo = adapt.into_adapted();
        for (p, want) in ["actor.", "estimator.", "env_factor_encoder.", "critic."]
            .iter()
            .zip(&frozen)
        {
            assert_eq!(&var_values(&ppo.params, p), want, "{p} changed");
        }
        assert_eq!(var_values(&ppo.stats, "normalizer."), norms);
        assert_ne!(var_values(&ppo.params, "memory."), memory_before);
        assert!(!ppo.ac.teacher_latent && !ppo.cfg.rma_teacher());
    }

    #[test]
    fn only_a_teacher_is_adapted() {
        let mut cfg = teacher_config();
        cfg.rma = None;
        let env = make_env(&cfg).unwrap();
        let err = Adaptation::new(Ppo::new(&cfg).unwrap(), env, AdaptationConfig::default())
            .err()
            .unwrap()
            .to_string();
        assert!(
            err.contains("not an RMA teacher") && err.contains("no [rma]"),
            "{err}"
        );
        assert_eq!(teacher_share(0, 4), 1.0);
        assert_eq!(teacher_share(3, 4), 0.25);
        assert_eq!(teacher_share(9, 4), 0.0);
        assert_eq!(teacher_share(0, 0), 0.0);
    }
}
