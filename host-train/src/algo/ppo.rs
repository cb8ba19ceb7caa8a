//! PPO in the manner of rsl_rl with an AMP discriminator updated in the same minibatch loop:
//! clipped surrogate, clipped value loss, entropy bonus, adaptive-KL learning rate, global
//! gradient-norm clipping, the estimator's supervised loss, and the discriminator's
//! least-squares loss with gradient penalty (its own Adam, same backward pass).

use crate::algo::adam::Adam;
use crate::algo::storage::{gather_rows, RolloutStorage};
use crate::amp::discriminator::Discriminator;
use crate::amp::prior_source::MotionPriorSource;
use crate::amp::transition_buffer::TransitionBuffer;
use crate::config::{LrSchedule, TrainConfig};
use crate::nn::actor_critic::{ActorCritic, BatchInput};
use candle_core::{DType, Device, Result, Tensor};
use candle_nn::VarMap;
use hexapod_core::amp::{AMP_GROUPS, AMP_STATE_DIM};
use hexapod_core::nets::{ACTOR_OUT, ESTIMATOR_OUT};
use hexapod_core::obs::{
    ACTOR_OBS_DIM, HEIGHT_SCAN_DIM, HISTORY_DIM, PRIVILEGED_DIM, PRIV_LIN_VEL,
};
use hexapod_core::timing::POLICY_DT_S;
use host_sim::vec_env::Observations;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

/// Why the learner could not be built or updated.
#[derive(Debug, thiserror::Error)]
pub enum PpoError {
    /// A tensor operation failed.
    #[error("tensor error: {0}")]
    Candle(#[from] candle_core::Error),
    /// A loss became NaN or infinite; training stopped before applying it.
    #[error("non-finite {what} at iteration {iteration} (surrogate {surrogate}, value {value}, estimator {estimator}, discriminator {discriminator}); the weights were not updated with it")]
    NonFiniteLoss {
        /// Which loss.
        what: &'static str,
        /// Iteration.
        iteration: usize,
        /// Surrogate loss value.
        surrogate: f32,
        /// Value loss value.
        value: f32,
        /// Estimator loss value.
        estimator: f32,
        /// Discriminator loss value.
        discriminator: f32,
    },
}

/// What the policy does for one batch of observations.
pub struct ActOutput {
    /// Sampled actions `[N, 18]`.
    pub actions: Vec<f32>,
    /// Action means `[N, 18]`.
    pub mean: Vec<f32>,
    /// Values `[N]`.
    pub values: Vec<f32>,
    /// Log-probabilities of the sampled actions `[N]`.
    pub log_probs: Vec<f32>,
    /// Velocity estimates `[N, 3]` (scaled), empty without estimator.
    pub estimate: Vec<f32>,
}

/// One minibatch of rollout data as tensors (`B` rows).
pub struct Minibatch {
    /// `[B, 63]`.
    pub actor: Tensor,
    /// `[B, 210]`.
    pub history: Tensor,
    /// `[B, 42]`.
    pub privileged: Tensor,
    /// `[B, 187]`.
    pub heights: Tensor,
    /// `[B, 18]`.
    pub actions: Tensor,
    /// Action means at rollout time `[B, 18]`.
    pub old_mean: Tensor,
    /// `[B]`.
    pub old_log_probs: Tensor,
    /// Normalized advantages `[B]`.
    pub advantages: Tensor,
    /// `[B]`.
    pub old_values: Tensor,
    /// `[B]`.
    pub returns: Tensor,
}

impl Minibatch {
    /// Gathers rows `idx` of the storage.
    pub fn gather(storage: &RolloutStorage, idx: &[usize], dev: &Device) -> Result<Self> {
        let col = |v: &[f32]| Tensor::from_vec(gather_rows(v, 1, idx), idx.len(), dev);
        Ok(Self {
            actor: tensor(
                gather_rows(&storage.actor_obs, ACTOR_OBS_DIM, idx),
                ACTOR_OBS_DIM,
                dev,
            )?,
            history: tensor(
                gather_rows(&storage.history, HISTORY_DIM, idx),
                HISTORY_DIM,
                dev,
            )?,
            privileged: tensor(
                gather_rows(&storage.privileged, PRIVILEGED_DIM, idx),
                PRIVILEGED_DIM,
                dev,
            )?,
            heights: tensor(
                gather_rows(&storage.heights, HEIGHT_SCAN_DIM, idx),
                HEIGHT_SCAN_DIM,
                dev,
            )?,
            actions: tensor(
                gather_rows(&storage.actions, ACTOR_OUT, idx),
                ACTOR_OUT,
                dev,
            )?,
            old_mean: tensor(
                gather_rows(&storage.action_mean, ACTOR_OUT, idx),
                ACTOR_OUT,
                dev,
            )?,
            old_log_probs: col(&storage.log_probs)?,
            advantages: col(&storage.advantages)?,
            old_values: col(&storage.values)?,
            returns: col(&storage.returns)?,
        })
    }
}

/// AMP transitions for one minibatch, flat `[B, 61]` each.
pub struct AmpBatch {
    /// Policy `s_t` (from the transition buffer).
    pub policy_s: Vec<f32>,
    /// Policy `s_t+1`.
    pub policy_sn: Vec<f32>,
    /// Prior `s_t`.
    pub prior_s: Vec<f32>,
    /// Prior `s_t+1`.
    pub prior_sn: Vec<f32>,
}

/// Means over one update's minibatches.
#[derive(Clone, Debug, Default)]
pub struct UpdateStats {
    /// Clipped surrogate loss.
    pub surrogate: f32,
    /// Value loss.
    pub value: f32,
    /// Entropy.
    pub entropy: f32,
    /// Estimator MSE (scaled units).
    pub estimator: f32,
    /// Mean KL between the rollout policy and the updated policy.
    pub kl: f32,
    /// KL on the first minibatch, before any step: the rollout/update mismatch (should be ~0).
    pub kl_first: f32,
    /// Learning rate after the update.
    pub learning_rate: f64,
    /// Gradient norm before clipping.
    pub grad_norm: f32,
    /// Discriminator least-squares loss.
    pub disc_loss: f32,
    /// Gradient penalty (weighted).
    pub grad_penalty: f32,
    /// Mean D on prior transitions.
    pub d_prior: f32,
    /// Mean D on policy transitions.
    pub d_policy: f32,
    /// The discriminator's saliency per AMP feature group on the first minibatch's policy
    /// transitions ([`crate::amp::discriminator::Discriminator::saliency`]); `None` when
    /// no discriminator trained.
    pub disc_saliency: Option<[f32; AMP_GROUPS.len()]>,
    /// Mean action standard deviation.
    pub action_std: f32,
}

/// Policy transitions the discriminator's saliency diagnostic is measured on, per update
/// (already a random sample of the transition buffer). It is a mean of absolute input
/// gradients, which this many rows estimate well; on a whole 1,536-row minibatch its forward
/// and input-gradient passes through the paper's 1024-512 discriminator cost about half a
/// PPO step (a tenth of that with `flat-tripod`'s 256-128 one).
const SALIENCY_ROWS: usize = 256;

/// The PPO + AMP learner: networks, normalizers, optimizers, transition buffer.
pub struct Ppo {
    /// Resolved configuration.
    pub cfg: TrainConfig,
    /// Device (CPU).
    pub device: Device,
    /// Trainable actor-critic variables.
    pub params: VarMap,
    /// Normalizer statistics (not trained by gradient).
    pub stats: VarMap,
    /// Trainable discriminator variables.
    pub disc_params: VarMap,
    /// The actor-critic.
    pub ac: ActorCritic,
    /// The discriminator (when the style reward is on).
    pub disc: Option<Discriminator>,
    /// Adam over the actor-critic.
    pub opt: Adam,
    /// Adam over the discriminator.
    pub disc_opt: Option<Adam>,
    /// Policy transitions for the discriminator.
    pub transitions: Option<TransitionBuffer>,
    /// Learner randomness (action noise, minibatches, transition sampling).
    pub rng: ChaCha8Rng,
}

/// Per-sample PPO losses for a minibatch (all `[B]` tensors but the clip), returning
/// (surrogate loss, value loss) as scalar tensors:
/// `L_clip = mean(max(-A r, -A clip(r, 1-e, 1+e)))`, `r = exp(logp - logp_old)`;
/// `L_V = mean(max((V - R)^2, (V_old + clip(V - V_old, -e, e) - R)^2))` (or plain MSE).
#[allow(clippy::too_many_arguments)]
pub fn ppo_losses(
    log_probs: &Tensor,
    old_log_probs: &Tensor,
    advantages: &Tensor,
    values: &Tensor,
    old_values: &Tensor,
    returns: &Tensor,
    clip: f64,
    clipped_value: bool,
) -> Result<(Tensor, Tensor)> {
    let ratio = log_probs.sub(old_log_probs)?.exp()?;
    let neg_adv = advantages.neg()?;
    let surr = neg_adv.mul(&ratio)?;
    let surr_clipped = neg_adv.mul(&ratio.clamp(1.0 - clip, 1.0 + clip)?)?;
    let surrogate = surr.maximum(&surr_clipped)?.mean_all()?;
    let value_loss = if clipped_value {
        let v_clipped = (old_values + values.sub(old_values)?.clamp(-clip, clip)?)?;
        let a = values.sub(returns)?.sqr()?;
        let b = v_clipped.sub(returns)?.sqr()?;
        a.maximum(&b)?.mean_all()?
    } else {
        values.sub(returns)?.sqr()?.mean_all()?
    };
    Ok((surrogate, value_loss))
}

/// The discriminator's L2 weight decay for variable `name`: `logit_weight_decay` on the
/// output layer's weight, `weight_decay` on hidden weights, none on biases.
fn disc_weight_decay(amp: &crate::config::AmpConfig, name: &str) -> f64 {
    let output = format!(
        "discriminator.layers.{}.weight",
        amp.discriminator_hidden.len()
    );
    if name == output {
        amp.logit_weight_decay
    } else if name.ends_with(".weight") {
        amp.weight_decay
    } else {
        0.0
    }
}

/// `x + N(0, sigma^2)` element-wise from the learner's seeded generator (`x` when sigma is 0).
fn with_noise(x: Tensor, sigma: f32, rng: &mut ChaCha8Rng) -> Result<Tensor> {
    if sigma <= 0.0 {
        return Ok(x);
    }
    let noise: Vec<f32> = (0..x.elem_count())
        .map(|_| {
            let z: f32 = StandardNormal.sample(rng);
            sigma * z
        })
        .collect();
    let noise = Tensor::from_vec(noise, x.shape(), x.device())?.to_dtype(x.dtype())?;
    x + noise
}

/// Mean KL(old || new) of diagonal Gaussians, rsl_rl's formula.
pub fn gaussian_kl(
    old_mean: &Tensor,
    old_log_std: &Tensor,
    mean: &Tensor,
    log_std: &Tensor,
) -> Result<f32> {
    let var_ratio = old_log_std.sub(log_std)?.affine(2.0, 0.0)?.exp()?; // sigma_old^2 / sigma^2
    let inv_var = log_std.affine(-2.0, 0.0)?.exp()?;
    let d2 = old_mean.sub(mean)?.sqr()?.broadcast_mul(&inv_var)?; // (mu_old - mu)^2 / sigma^2
    let per = d2
        .broadcast_add(&var_ratio)?
        .affine(0.5, -0.5)?
        .broadcast_add(&log_std.sub(old_log_std)?)?;
    per.sum(1)?.mean_all()?.to_scalar::<f32>()
}

fn tensor(data: Vec<f32>, cols: usize, device: &Device) -> Result<Tensor> {
    let rows = data.len() / cols.max(1);
    Tensor::from_vec(data, (rows, cols), device)
}

impl Ppo {
    /// Builds networks and optimizers from a config.
    pub fn new(cfg: &TrainConfig) -> std::result::Result<Self, PpoError> {
        let device = Device::Cpu;
        let (params, stats, disc_params) = (VarMap::new(), VarMap::new(), VarMap::new());
        let ac = ActorCritic::new(
            &cfg.policy,
            cfg.rma.as_ref(),
            &params,
            &stats,
            cfg.runner.seed,
            DType::F32,
            &device,
        )?;
        let (disc, disc_opt, transitions) = if cfg.amp_enabled() {
            let d = Discriminator::new(
                &cfg.amp.discriminator_hidden,
                &disc_params,
                &stats,
                cfg.runner.seed,
                DType::F32,
                &device,
            )?;
            let opt = Adam::new(&disc_params, cfg.amp.learning_rate)?
                .with_weight_decay(|name| disc_weight_decay(&cfg.amp, name));
            (
                Some(d),
                Some(opt),
                Some(TransitionBuffer::new(cfg.amp.replay_buffer_size)),
            )
        } else {
            (None, None, None)
        };
        let opt = Adam::new(&params, cfg.ppo.learning_rate)?;
        Ok(Self {
            cfg: cfg.clone(),
            device,
            params,
            stats,
            disc_params,
            ac,
            disc,
            opt,
            disc_opt,
            transitions,
            rng: ChaCha8Rng::seed_from_u64(cfg.runner.seed),
        })
    }

    /// Samples actions for observations; `deterministic` returns the means.
    pub fn act(&mut self, obs: &Observations, deterministic: bool) -> Result<ActOutput> {
        let dev = &self.device;
        let actor = Tensor::from_slice(
            &obs.actor,
            (obs.actor.len() / ACTOR_OBS_DIM, ACTOR_OBS_DIM),
            dev,
        )?;
        let n = actor.dims()[0];
        let history = Tensor::from_slice(&obs.history, (n, HISTORY_DIM), dev)?;
        let privileged = Tensor::from_slice(&obs.privileged, (n, PRIVILEGED_DIM), dev)?;
        let heights = Tensor::from_slice(&obs.heights, (n, HEIGHT_SCAN_DIM), dev)?;
        let input = BatchInput {
            actor_obs: &actor,
            history: &history,
            privileged: &privileged,
            heights: &heights,
        };
        let out = self.ac.acting_policy(&input)?;
        let mean = out.mean.flatten_all()?.to_vec1::<f32>()?;
        let std: Vec<f32> = self.ac.log_std.exp()?.to_vec1::<f32>()?;
        let actions: Vec<f32> = if deterministic {
            mean.clone()
        } else {
            mean.iter()
                .enumerate()
                .map(|(i, &m)| {
                    let z: f32 = StandardNormal.sample(&mut self.rng);
                    m + std[i % ACTOR_OUT] * z
                })
                .collect()
        };
        let actions_t = Tensor::from_slice(&actions, (n, ACTOR_OUT), dev)?;
        let log_probs = self.ac.log_prob(&out.mean, &actions_t)?.to_vec1::<f32>()?;
        let values = self.ac.value(&input)?.to_vec1::<f32>()?;
        let estimate = match out.estimate {
            Some(e) => e.flatten_all()?.to_vec1::<f32>()?,
            None => Vec::new(),
        };
        Ok(ActOutput {
            actions,
            mean,
            values,
            log_probs,
            estimate,
        })
    }

    /// Values `[N]` of observations (for the bootstrap after the last step).
    pub fn values(&self, obs: &Observations) -> Result<Vec<f32>> {
        let dev = &self.device;
        let n = obs.actor.len() / ACTOR_OBS_DIM;
        let actor = Tensor::from_slice(&obs.actor, (n, ACTOR_OBS_DIM), dev)?;
        let history = Tensor::from_slice(&obs.history, (n, HISTORY_DIM), dev)?;
        let privileged = Tensor::from_slice(&obs.privileged, (n, PRIVILEGED_DIM), dev)?;
        let heights = Tensor::from_slice(&obs.heights, (n, HEIGHT_SCAN_DIM), dev)?;
        self.ac
            .value(&BatchInput {
                actor_obs: &actor,
                history: &history,
                privileged: &privileged,
                heights: &heights,
            })?
            .to_vec1::<f32>()
    }

    /// Sets every action dimension's standard deviation to `std` (the actor's `log_std`), as
    /// a fine-tuning stage's restart of exploration; the action means are unchanged.
    pub fn set_action_std(&mut self, std: f32) -> Result<()> {
        if !(std.is_finite() && std > 0.0) {
            candle_core::bail!("the action standard deviation must be positive, got {std}");
        }
        let var = self.log_std_var()?;
        var.set(&Tensor::full(std.ln(), var.shape(), var.device())?)
    }

    /// Raises every action dimension's standard deviation below `policy.min_noise_std` to it
    /// (nothing when the floor is 0); the trainer calls it after every optimizer step.
    pub fn apply_action_std_floor(&self) -> Result<()> {
        let floor = self.cfg.policy.min_noise_std;
        if floor <= 0.0 {
            return Ok(());
        }
        let var = self.log_std_var()?;
        let floored = var.as_tensor().maximum(floor.ln())?;
        var.set(&floored)
    }

    fn log_std_var(&self) -> Result<candle_core::Var> {
        let data = self.params.data().lock().expect("var map lock");
        data.get("actor.log_std")
            .cloned()
            .ok_or_else(|| candle_core::Error::Msg("no actor.log_std in the policy".into()))
    }

    /// Style rewards `[N]` (`style_weight * dt * max(0, 1 - 0.25 (d - 1)^2)`) and raw discriminator outputs for policy transitions;
    /// zeros without AMP.
    pub fn style_rewards(&self, amp: &[f32], amp_next: &[f32]) -> Result<(Vec<f32>, Vec<f32>)> {
        let n = amp.len() / AMP_STATE_DIM;
        match &self.disc {
            Some(d) => {
                let (r, raw) = d.style_reward(amp, amp_next)?;
                // Scaled by the policy period like the simulator's terms (legged_gym's
                // convention), so r_s and r_g keep the paper's relative weights (Table I).
                let w = self.cfg.rewards.style_weight * POLICY_DT_S;
                Ok((r.into_iter().map(|x| w * x).collect(), raw))
            }
            None => Ok((vec![0.0; n], vec![0.0; n])),
        }
    }

    /// One PPO (+ discriminator) update over a full rollout.
    pub fn update(
        &mut self,
        storage: &RolloutStorage,
        priors: Option<&mut dyn MotionPriorSource>,
        iteration: usize,
    ) -> std::result::Result<UpdateStats, PpoError> {
        let p = self.cfg.ppo.clone();
        let old_log_std = self.ac.log_std.detach().copy()?;
        let mut priors = priors;
        let mut st = UpdateStats::default();
        let (mut count, mut disc_count) = (0usize, 0usize);
        let disc_steps = match self.cfg.amp.steps_per_iteration {
            0 => usize::MAX,
            k => k,
        };
        for _epoch in 0..p.num_learning_epochs {
            for idx in storage.minibatch_indices(p.num_mini_batches, &mut self.rng) {
                let mb = Minibatch::gather(storage, &idx, &self.device)?;
                let amp = match (&self.transitions, priors.as_deref_mut()) {
                    (Some(transitions), Some(src))
                        if self.disc.is_some() && disc_count < disc_steps =>
                    {
                        let (policy_s, policy_sn) = transitions.sample(idx.len(), &mut self.rng);
                        let (prior_s, prior_sn) = src.sample(idx.len(), &mut self.rng);
                        Some(AmpBatch {
                            policy_s,
                            policy_sn,
                            prior_s,
                            prior_sn,
                        })
                    }
                    _ => None,
                };
                let step = self.minibatch_step(&mb, &old_log_std, amp.as_ref(), iteration)?;
                if count == 0 {
                    st.kl_first = step.kl;
                }
                if let (Some(disc), Some(a)) = (&self.disc, &amp) {
                    if disc_count == 0 {
                        let rows = SALIENCY_ROWS.min(idx.len()) * AMP_STATE_DIM;
                        let x = disc.input(&a.policy_s[..rows], &a.policy_sn[..rows])?;
                        st.disc_saliency = Some(disc.saliency(&x)?);
                    }
                    st.disc_loss += step.disc_loss;
                    st.grad_penalty += step.grad_penalty;
                    st.d_prior += step.d_prior;
                    st.d_policy += step.d_policy;
                    disc_count += 1;
                }
                st.surrogate += step.surrogate;
                st.value += step.value;
                st.entropy += step.entropy;
                st.estimator += step.estimator;
                st.kl += step.kl;
                st.grad_norm += step.grad_norm;
                count += 1;
            }
        }
        let c = count.max(1) as f32;
        for v in [
            &mut st.surrogate,
            &mut st.value,
            &mut st.entropy,
            &mut st.estimator,
            &mut st.kl,
            &mut st.grad_norm,
        ] {
            *v /= c;
        }
        let dc = disc_count.max(1) as f32;
        for v in [
            &mut st.disc_loss,
            &mut st.grad_penalty,
            &mut st.d_prior,
            &mut st.d_policy,
        ] {
            *v /= dc;
        }
        st.learning_rate = self.opt.lr;
        st.action_std = self.ac.log_std.exp()?.mean_all()?.to_scalar::<f32>()?;
        Ok(st)
    }

    /// One gradient step on a minibatch: adaptive learning rate from the KL, PPO losses,
    /// estimator loss, and (with `amp`) the discriminator loss, one backward pass, Adam
    /// steps for the actor-critic (clipped) and the discriminator.
    pub fn minibatch_step(
        &mut self,
        mb: &Minibatch,
        old_log_std: &Tensor,
        amp: Option<&AmpBatch>,
        iteration: usize,
    ) -> std::result::Result<UpdateStats, PpoError> {
        let p = &self.cfg.ppo;
        let input = BatchInput {
            actor_obs: &mb.actor,
            history: &mb.history,
            privileged: &mb.privileged,
            heights: &mb.heights,
        };
        let out = self.ac.acting_policy(&input)?;
        let kl = gaussian_kl(&mb.old_mean, old_log_std, &out.mean, &self.ac.log_std)?;
        if p.schedule == LrSchedule::Adaptive && kl.is_finite() {
            if kl > 2.0 * p.desired_kl {
                self.opt.lr = (self.opt.lr / 1.5).max(1e-5);
            } else if kl < 0.5 * p.desired_kl && kl > 0.0 {
                self.opt.lr = (self.opt.lr * 1.5).min(1e-2);
            }
        }
        let logp = self.ac.log_prob(&out.mean, &mb.actions)?;
        let values = self.ac.value(&input)?;
        let (surr, vloss) = ppo_losses(
            &logp,
            &mb.old_log_probs,
            &mb.advantages,
            &values,
            &mb.old_values,
            &mb.returns,
            p.clip_param as f64,
            p.use_clipped_value_loss,
        )?;
        let entropy = self.ac.entropy()?;
        let mut loss = ((&surr + (&vloss * p.value_loss_coef as f64)?)?
            - (&entropy * p.entropy_coef as f64)?)?;
        let mut st = UpdateStats {
            kl,
            ..Default::default()
        };
        if let Some(estimate) = &out.estimate {
            let target = mb.privileged.narrow(1, PRIV_LIN_VEL.start, ESTIMATOR_OUT)?;
            let est_loss = estimate.sub(&target)?.sqr()?.mean_all()?;
            st.estimator = est_loss.to_scalar::<f32>()?;
            loss = (loss + (est_loss * p.estimator_loss_coef as f64)?)?;
        }
        if let (Some(disc), Some(a)) = (&self.disc, amp) {
            let sigma = self.cfg.amp.input_noise_std;
            let policy_in =
                with_noise(disc.input(&a.policy_s, &a.policy_sn)?, sigma, &mut self.rng)?;
            let prior_in = with_noise(disc.input(&a.prior_s, &a.prior_sn)?, sigma, &mut self.rng)?;
            let dl = disc.loss(
                &prior_in,
                &policy_in,
                self.cfg.amp.grad_penalty_weight as f64,
            )?;
            (st.disc_loss, st.grad_penalty, st.d_prior, st.d_policy) =
                (dl.ls_loss, dl.grad_penalty, dl.d_prior, dl.d_policy);
            loss = (loss + (dl.total * self.cfg.amp.loss_coef as f64)?)?;
        }
        let loss_v = loss.to_scalar::<f32>()?;
        st.surrogate = surr.to_scalar::<f32>()?;
        st.value = vloss.to_scalar::<f32>()?;
        st.entropy = entropy.to_scalar::<f32>()?;
        if !loss_v.is_finite() {
            return Err(PpoError::NonFiniteLoss {
                what: "total loss",
                iteration,
                surrogate: st.surrogate,
                value: st.value,
                estimator: st.estimator,
                discriminator: st.disc_loss + st.grad_penalty,
            });
        }
        let grads = loss.backward()?;
        st.grad_norm = self.opt.step(&grads, Some(p.max_grad_norm as f64))? as f32;
        self.apply_action_std_floor()?;
        if let Some(dopt) = &mut self.disc_opt {
            if self.cfg.amp.follow_policy_learning_rate {
                dopt.lr = self.opt.lr;
            }
            dopt.step(&grads, None)?;
        }
        if let (Some(disc), Some(a)) = (&mut self.disc, amp) {
            for s in [&a.policy_s, &a.policy_sn, &a.prior_s, &a.prior_sn] {
                disc.norm.update(s)?;
            }
        }
        st.learning_rate = self.opt.lr;
        Ok(st)
    }

    /// Pushes policy transitions into the transition buffer (skipping robots whose actions were invalid).
    pub fn record_policy_transitions(&mut self, amp: &[f32], amp_next: &[f32], invalid: &[bool]) {
        if let Some(transitions) = &mut self.transitions {
            if invalid.iter().any(|&x| x) {
                let keep: Vec<usize> = (0..invalid.len()).filter(|&i| !invalid[i]).collect();
                transitions.insert(
                    &gather_rows(amp, AMP_STATE_DIM, &keep),
                    &gather_rows(amp_next, AMP_STATE_DIM, &keep),
                );
            } else {
                transitions.insert(amp, amp_next);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn t(v: &[f32]) -> Tensor {
        Tensor::from_slice(v, v.len(), &Device::Cpu).unwrap()
    }

    /// A batch of three samples worked out by hand (clip 0.2):
    /// r = e^{0.5} = 1.6487 (A = 1: clipped to 1.2, loss -1.2),
    /// r = e^{-0.5} = 0.6065 (A = -2: clipped to 0.8, max(1.2131, 1.6) = 1.6),
    /// r = 1 (A = 0.5: -0.5). Surrogate = mean(-1.2, 1.6, -0.5) = -0.0333.
    #[test]
    fn ppo_loss_on_a_hand_checked_batch() {
        let logp = t(&[0.5, -0.5, 0.0]);
        let old = t(&[0.0, 0.0, 0.0]);
        let adv = t(&[1.0, -2.0, 0.5]);
        // Values: V - V_old = 0.5 clipped to 0.2; -0.1 unclipped; 0.
        let v = t(&[1.5, 0.9, 2.0]);
        let v_old = t(&[1.0, 1.0, 2.0]);
        let ret = t(&[2.0, 0.0, 1.0]);
        let (s, vl) = ppo_losses(&logp, &old, &adv, &v, &v_old, &ret, 0.2, true).unwrap();
        let s = s.to_scalar::<f32>().unwrap();
        assert!((s - (-1.2 + 1.6 - 0.5) / 3.0).abs() < 1e-5, "{s}");
        // Sample 0: (1.5-2)^2 = 0.25 vs (1.2-2)^2 = 0.64 -> 0.64; sample 1: 0.81 vs 0.81; sample 2: 1.
        let vl = vl.to_scalar::<f32>().unwrap();
        assert!((vl - (0.64 + 0.81 + 1.0) / 3.0).abs() < 1e-5, "{vl}");
        let (_, plain) = ppo_losses(&logp, &old, &adv, &v, &v_old, &ret, 0.2, false).unwrap();
        assert!((plain.to_scalar::<f32>().unwrap() - (0.25 + 0.81 + 1.0) / 3.0).abs() < 1e-5);
    }

    #[test]
    fn kl_of_identical_policies_is_zero_and_matches_closed_form() {
        let m = Tensor::new(&[[0.0f32, 1.0]], &Device::Cpu).unwrap();
        let ls = t(&[0.0, 0.0]);
        assert!(gaussian_kl(&m, &ls, &m, &ls).unwrap().abs() < 1e-7);
        // KL(N(0,1) || N(1, e^{0.5 * 2}))) per dim: ln(s2/s1) + (s1^2 + d^2)/(2 s2^2) - 1/2.
        let m2 = Tensor::new(&[[1.0f32, 1.0]], &Device::Cpu).unwrap();
        let ls2 = t(&[0.5, 0.0]);
        let s2 = 0.5f32.exp();
        let want = (0.5 + (1.0 + 1.0) / (2.0 * s2 * s2) - 0.5) + 0.0;
        assert!((gaussian_kl(&m, &ls, &m2, &ls2).unwrap() - want).abs() < 1e-5);
    }

    #[test]
    fn set_action_std_sets_every_dimension_and_refuses_bad_values() {
        let cfg = crate::config::TrainConfig::default();
        let mut ppo = Ppo::new(&cfg).unwrap();
        let before = ppo.ac.log_std.to_vec1::<f32>().unwrap();
        assert!(before
            .iter()
            .all(|&l| (l - cfg.policy.init_noise_std.ln()).abs() < 1e-6));
        ppo.set_action_std(0.5).unwrap();
        let after = ppo.ac.log_std.to_vec1::<f32>().unwrap();
        assert_eq!(after.len(), 18);
        assert!(
            after.iter().all(|&l| (l.exp() - 0.5).abs() < 1e-6),
            "{after:?}"
        );
        for bad in [0.0, -1.0, f32::NAN] {
            assert!(ppo.set_action_std(bad).is_err(), "{bad}");
        }
        assert_eq!(ppo.ac.log_std.to_vec1::<f32>().unwrap(), after);
    }

    #[test]
    fn the_action_std_floor_raises_what_is_below_it_and_keeps_what_is_above() {
        // Every dimension's deviation after setting it to `std` and applying the floor.
        let floored = |ppo: &mut Ppo, std: f32| -> Vec<f32> {
            ppo.set_action_std(std).unwrap();
            ppo.apply_action_std_floor().unwrap();
            let ls = ppo.ac.log_std.to_vec1::<f32>().unwrap();
            ls.iter().map(|l| l.exp()).collect()
        };
        let near = |v: &[f32], want: f32| v.iter().all(|s| (s - want).abs() < 1e-6);
        let mut cfg = crate::config::TrainConfig::default();
        let plain = floored(&mut Ppo::new(&cfg).unwrap(), 0.1);
        assert!(near(&plain, 0.1), "no floor by default: {plain:?}");
        cfg.policy.min_noise_std = 0.3;
        let mut ppo = Ppo::new(&cfg).unwrap();
        let below = floored(&mut ppo, 0.1);
        assert!(near(&below, 0.3), "{below:?}");
        let above = floored(&mut ppo, 0.6);
        assert!(near(&above, 0.6), "{above:?}");
    }
}
