//! The on-policy runner (rsl_rl's `OnPolicyRunner`): act, step, style reward, store,
//! returns, update, log, save; with resume from a checkpoint and a NaN guard.

use crate::algo::ppo::{Ppo, UpdateStats};
use crate::algo::storage::{RolloutStorage, Transition};
use crate::amp::prior_source::{MotionPriorSource, PriorSourceError};
use crate::checkpoint;
use crate::config::TrainConfig;
use crate::curriculum_carry::carry_tiles;
use crate::error::TrainError;
use crate::metrics::MetricsLog;
use hexapod_core::amp::{AMP_BASE_ANG_VEL, AMP_GROUPS, AMP_STATE_DIM};
use hexapod_core::obs::{
    ACTOR_COMMAND, ACTOR_OBS_DIM, COMMAND_SCALE, LIN_VEL_SCALE, PRIVILEGED_DIM, PRIV_LIN_VEL,
};
use host_sim::vec_env::{Observations, VecEnv};
use indicatif::{ProgressBar, ProgressStyle};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// What one rollout measured.
#[derive(Clone, Debug, Default)]
pub struct RolloutStats {
    /// Mean per-step total reward.
    pub reward_total: f64,
    /// Mean per-step environment reward (task + penalties).
    pub reward_env: f64,
    /// Mean per-step style reward (weighted).
    pub reward_style: f64,
    /// Mean discriminator output on the rollout's policy transitions.
    pub d_rollout: f64,
    /// Mean planar velocity tracking error, m/s.
    pub lin_vel_error_m_s: f64,
    /// Mean yaw-rate tracking error, rad/s.
    pub yaw_rate_error_rad_s: f64,
    /// RMS estimator error, m/s.
    pub estimator_error_m_s: f64,
    /// Episodes that ended in this rollout.
    pub episodes: usize,
    /// Mean return of those episodes.
    pub episode_return: f64,
    /// Mean length of those episodes, steps.
    pub episode_length: f64,
    /// Of those, the fraction that ended by termination (not time-out).
    pub termination_rate: f64,
    /// Mean of each episode statistic the environment reported.
    pub env_log: BTreeMap<String, f64>,
    /// Environment steps taken.
    pub env_steps: usize,
}

/// The training loop and everything it owns.
pub struct Runner {
    /// The learner.
    pub ppo: Ppo,
    env: Box<dyn VecEnv>,
    priors: Option<Box<dyn MotionPriorSource>>,
    storage: RolloutStorage,
    obs: Observations,
    /// Output directory (metrics, plots, checkpoints).
    pub run_dir: PathBuf,
    /// Metrics so far.
    pub metrics: MetricsLog,
    /// Next iteration to run.
    pub iteration: usize,
    ep_len: Vec<usize>,
    ep_ret: Vec<f64>,
    last_checkpoint: Option<PathBuf>,
    stop_requested: Option<std::sync::Arc<std::sync::atomic::AtomicBool>>,
}

/// Errors with the run's context (last good checkpoint).
#[derive(Debug, thiserror::Error)]
#[error("{source}; last good checkpoint: {}", last_checkpoint.as_ref().map(|p| p.display().to_string()).unwrap_or_else(|| "none yet".into()))]
pub struct RunError {
    /// What failed.
    pub source: TrainError,
    /// The newest checkpoint written before the failure.
    pub last_checkpoint: Option<PathBuf>,
}

impl Runner {
    /// A runner over `env` (which must have `cfg.env.num_envs` robots) writing into `run_dir`.
    pub fn new(
        cfg: &TrainConfig,
        mut env: Box<dyn VecEnv>,
        priors: Option<Box<dyn MotionPriorSource>>,
        run_dir: &Path,
    ) -> Result<Self, TrainError> {
        let ppo = Ppo::new(cfg)?;
        if ppo.disc.is_some() && priors.is_none() {
            return Err(TrainError::Priors(PriorSourceError(
                "the style reward is on but no motion priors were given".into(),
            )));
        }
        if let Some(p) = &priors {
            let references = p.reference_states();
            if !references.is_empty() {
                env.set_reference_states(references.into());
            }
        }
        let n = env.num_envs();
        let obs = env.reset();
        std::fs::create_dir_all(run_dir).map_err(|source| TrainError::Io {
            path: run_dir.display().to_string(),
            source,
        })?;
        Ok(Self {
            ppo,
            env,
            priors,
            storage: RolloutStorage::new(n, cfg.ppo.num_steps_per_env),
            obs,
            run_dir: run_dir.to_path_buf(),
            metrics: MetricsLog::new(),
            iteration: 0,
            ep_len: vec![0; n],
            ep_ret: vec![0.0; n],
            last_checkpoint: None,
            stop_requested: None,
        })
    }

    /// Continues from a checkpoint: weights, normalizers, optimizer state, iteration. The
    /// robots' episode clocks start at random steps of their episodes, as the episodes of an
    /// uninterrupted run are spread out by then (without it every robot would time out,
    /// be pushed and resample its command at the same moments for hundreds of iterations).
    pub fn resume(&mut self, dir: &Path) -> Result<(), TrainError> {
        checkpoint::load(dir, &mut self.ppo, true)?;
        let state = checkpoint::load_state(dir)?;
        self.iteration = state.iteration;
        self.restore_curriculum(dir, state.terrain_tiles.as_deref());
        self.env.randomize_episode_clocks();
        self.last_checkpoint = Some(dir.to_path_buf());
        // Resuming into a run directory that has a history: keep it up to the checkpoint.
        let csv = self.run_dir.join("metrics.csv");
        if csv.is_file() {
            self.metrics =
                MetricsLog::resume_from_csv(&csv, self.iteration).map_err(|e| TrainError::Io {
                    path: csv.display().to_string(),
                    source: std::io::Error::other(e),
                })?;
        }
        Ok(())
    }

    /// Puts the robots back on the terrain tiles a checkpoint recorded, and resets them
    /// there. Without tiles in the checkpoint (older checkpoints, flat ground) the robots
    /// stay on their initial rows. A checkpoint of another tile layout or number of robots
    /// carries its rows per tile kind ([`crate::curriculum_carry`]), and that is said.
    fn restore_curriculum(&mut self, dir: &Path, tiles: Option<&[[usize; 2]]>) {
        let (Some(tiles), Some(now)) = (tiles, self.env.terrain_tiles()) else {
            return;
        };
        let columns = &self.ppo.cfg.sim.terrain.columns;
        let saved_columns = match checkpoint::load_config(dir) {
            Ok(cfg) => cfg.sim.terrain.columns,
            Err(e) => {
                eprintln!("{e}; the curriculum is read as on this run's tile layout");
                columns.clone()
            }
        };
        if tiles.len() != now.len() || &saved_columns != columns {
            eprintln!(
                "{}: the curriculum of {} robots on {:?} carries over per tile kind to this run's {} robots on {:?}",
                dir.display(),
                tiles.len(),
                saved_columns,
                now.len(),
                columns
            );
        }
        let carried = carry_tiles(tiles, &saved_columns, &now, columns);
        self.env.set_terrain_tiles(&carried);
        self.obs = self.env.reset();
    }

    /// The last rollout.
    pub fn storage(&self) -> &RolloutStorage {
        &self.storage
    }

    /// Runs one rollout of `num_steps_per_env` steps into the storage.
    pub fn collect(&mut self) -> Result<RolloutStats, TrainError> {
        let n = self.env.num_envs();
        let gamma = self.ppo.cfg.ppo.gamma;
        self.storage.clear();
        let mut st = RolloutStats::default();
        let (mut est_sq, mut est_count) = (0.0f64, 0usize);
        let mut env_log_n: BTreeMap<String, usize> = BTreeMap::new();
        let mut terminated = 0usize;
        let steps = self.ppo.cfg.ppo.num_steps_per_env;
        for _ in 0..steps {
            let obs = &self.obs;
            let act = self.ppo.act(obs, false)?;
            let res = self.env.step(&act.actions);
            let (style, d_raw) = self.ppo.style_rewards(&obs.amp, &res.amp_next)?;
            self.ppo
                .record_policy_transitions(&obs.amp, &res.amp_next, &res.invalid_actions);
            let mut rewards = res.rewards.clone();
            if self.ppo.cfg.rewards.only_positive_env_reward {
                // `f32::max` would turn a NaN into 0 and hide a broken environment.
                rewards
                    .iter_mut()
                    .filter(|r| **r < 0.0)
                    .for_each(|r| *r = 0.0);
            }
            for i in 0..n {
                st.reward_env += res.rewards[i] as f64;
                st.reward_style += style[i] as f64;
                st.d_rollout += d_raw[i] as f64;
                rewards[i] += style[i];
                st.reward_total += rewards[i] as f64;
                self.ep_ret[i] += rewards[i] as f64;
                self.ep_len[i] += 1;
                // Time-outs: bootstrap with the value of the state the step started from.
                if res.time_outs[i] {
                    rewards[i] += gamma * act.values[i];
                }
                let a = &obs.actor[i * ACTOR_OBS_DIM..(i + 1) * ACTOR_OBS_DIM];
                let p = &obs.privileged[i * PRIVILEGED_DIM..(i + 1) * PRIVILEGED_DIM];
                let cmd_x = a[ACTOR_COMMAND.start] / COMMAND_SCALE[0];
                let cmd_y = a[ACTOR_COMMAND.start + 1] / COMMAND_SCALE[1];
                let cmd_wz = a[ACTOR_COMMAND.start + 2] / COMMAND_SCALE[2];
                let vx = p[PRIV_LIN_VEL.start] / LIN_VEL_SCALE;
                let vy = p[PRIV_LIN_VEL.start + 1] / LIN_VEL_SCALE;
                let wz = obs.amp[i * AMP_STATE_DIM + AMP_BASE_ANG_VEL.start + 2];
                st.lin_vel_error_m_s +=
                    (((vx - cmd_x).powi(2) + (vy - cmd_y).powi(2)) as f64).sqrt();
                st.yaw_rate_error_rad_s += (wz - cmd_wz).abs() as f64;
                if !act.estimate.is_empty() {
                    for k in 0..3 {
                        let e =
                            (act.estimate[i * 3 + k] - p[PRIV_LIN_VEL.start + k]) / LIN_VEL_SCALE;
                        est_sq += (e * e) as f64;
                        est_count += 1;
                    }
                }
                if res.dones[i] {
                    st.episodes += 1;
                    st.episode_return += self.ep_ret[i];
                    st.episode_length += self.ep_len[i] as f64;
                    if !res.time_outs[i] {
                        terminated += 1;
                    }
                    self.ep_ret[i] = 0.0;
                    self.ep_len[i] = 0;
                }
            }
            for (k, v) in &res.episode_log {
                *st.env_log.entry(k.clone()).or_default() += *v as f64;
                *env_log_n.entry(k.clone()).or_default() += 1;
            }
            self.storage.add(&Transition {
                actor_obs: &obs.actor,
                history: &obs.history,
                privileged: &obs.privileged,
                heights: &obs.heights,
                actions: &act.actions,
                action_mean: &act.mean,
                rewards: &rewards,
                dones: &res.dones,
                values: &act.values,
                log_probs: &act.log_probs,
            });
            self.obs = res.obs;
        }
        let last_values = self.ppo.values(&self.obs)?;
        self.storage
            .compute_returns(&last_values, gamma, self.ppo.cfg.ppo.lam);
        let samples = (n * steps) as f64;
        for v in [
            &mut st.reward_total,
            &mut st.reward_env,
            &mut st.reward_style,
            &mut st.d_rollout,
            &mut st.lin_vel_error_m_s,
            &mut st.yaw_rate_error_rad_s,
        ] {
            *v /= samples;
        }
        st.estimator_error_m_s = if est_count > 0 {
            (est_sq / est_count as f64).sqrt()
        } else {
            f64::NAN
        };
        if st.episodes > 0 {
            st.episode_return /= st.episodes as f64;
            st.episode_length /= st.episodes as f64;
            st.termination_rate = terminated as f64 / st.episodes as f64;
        } else {
            st.episode_return = f64::NAN;
            st.episode_length = f64::NAN;
            st.termination_rate = f64::NAN;
        }
        for (k, v) in st.env_log.iter_mut() {
            *v /= env_log_n[k] as f64;
        }
        st.env_steps = n * steps;
        Ok(st)
    }

    /// One iteration: rollout and update. Returns the metrics row.
    pub fn iterate(&mut self) -> Result<BTreeMap<String, f64>, TrainError> {
        let t0 = Instant::now();
        let ro = self.collect_guarded()?;
        let t1 = Instant::now();
        let priors = self
            .priors
            .as_mut()
            .map(|p| p.as_mut() as &mut dyn MotionPriorSource);
        let up = self.ppo.update(&self.storage, priors, self.iteration)?;
        // Normalizers move between iterations, never within one: the rollout's action
        // log-probabilities and values stay those of the policy being updated.
        let s = &self.storage;
        self.ppo
            .ac
            .update_normalizers(&s.actor_obs, &s.history, &s.privileged, &s.heights)?;
        let t2 = Instant::now();
        let row = metrics_row(
            self.iteration,
            &ro,
            &up,
            (t1 - t0).as_secs_f64(),
            (t2 - t1).as_secs_f64(),
        );
        self.metrics.push(row.clone());
        self.iteration += 1;
        Ok(row)
    }

    /// [`Self::collect`], with a panic inside the environment turned into
    /// [`TrainError::EnvPanic`]. A rollout changes the learner only in the discriminator's
    /// replay buffer, which checkpoints do not hold: the weights, optimizer and normalizers
    /// are still those of the last finished iteration, so `learn` can save them.
    fn collect_guarded(&mut self) -> Result<RolloutStats, TrainError> {
        std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| self.collect())).unwrap_or_else(
            |payload| {
                let message = payload
                    .downcast_ref::<&str>()
                    .map(|s| s.to_string())
                    .or_else(|| payload.downcast_ref::<String>().cloned())
                    .unwrap_or_else(|| "(no message)".into());
                Err(TrainError::EnvPanic {
                    iteration: self.iteration,
                    message,
                })
            },
        )
    }

    /// Writes a checkpoint `checkpoints/model_<iteration>` and returns its directory.
    pub fn save(&mut self) -> Result<PathBuf, TrainError> {
        let dir = self
            .run_dir
            .join("checkpoints")
            .join(format!("model_{:06}", self.iteration));
        let state = checkpoint::RunState {
            iteration: self.iteration,
            terrain_tiles: self.env.terrain_tiles(),
        };
        checkpoint::save_with_state(&dir, &self.ppo, &state)?;
        self.last_checkpoint = Some(dir.clone());
        Ok(dir)
    }

    /// Writes `metrics.csv` and the plots.
    pub fn write_metrics(&self, plots: bool) -> Result<(), TrainError> {
        let csv = self.run_dir.join("metrics.csv");
        self.metrics
            .write_csv(&csv)
            .map_err(|source| TrainError::Io {
                path: csv.display().to_string(),
                source,
            })?;
        if plots {
            let dir = self.run_dir.join("plots");
            std::fs::create_dir_all(&dir).map_err(|source| TrainError::Io {
                path: dir.display().to_string(),
                source,
            })?;
            if let Err(e) = self.metrics.plot(&dir) {
                eprintln!("warning: plots not written: {e}");
            }
        }
        Ok(())
    }

    /// A flag that, once set (by Ctrl-C), ends [`Runner::learn`] after the current
    /// iteration with a checkpoint.
    pub fn set_stop_flag(&mut self, flag: std::sync::Arc<std::sync::atomic::AtomicBool>) {
        self.stop_requested = Some(flag);
    }

    /// True when the stop flag was set.
    pub fn stopped_early(&self) -> bool {
        self.stop_requested
            .as_ref()
            .is_some_and(|f| f.load(std::sync::atomic::Ordering::SeqCst))
    }

    /// Trains until `cfg.runner.max_iterations`, checkpointing every `save_interval`
    /// iterations and at the end (or
    /// after the iteration in which the stop flag was set). A non-finite loss stops the run; the checkpoints written
    /// before it stay as they were.
    #[allow(clippy::result_large_err)]
    pub fn learn(&mut self, show_progress: bool) -> Result<PathBuf, RunError> {
        let max = self.ppo.cfg.runner.max_iterations;
        let save_every = self.ppo.cfg.runner.save_interval;
        let bar = if show_progress {
            ProgressBar::new(max as u64)
        } else {
            ProgressBar::hidden()
        };
        bar.set_style(
            ProgressStyle::with_template(
                "{bar:30} {pos}/{len} [{elapsed_precise}<{eta_precise}] {msg}",
            )
            .expect("valid template"),
        );
        bar.set_position(self.iteration as u64);
        let wrap = |source: TrainError, last: &Option<PathBuf>| RunError {
            source,
            last_checkpoint: last.clone(),
        };
        while self.iteration < max {
            let row = match self.iterate() {
                Ok(r) => r,
                Err(e) => {
                    bar.abandon();
                    if matches!(e, TrainError::EnvPanic { .. }) {
                        // Nothing of the learner is lost: save it as it stands.
                        let _ = self.save();
                    }
                    let _ = self.write_metrics(true);
                    return Err(wrap(e, &self.last_checkpoint));
                }
            };
            bar.set_position(self.iteration as u64);
            bar.set_message(progress_message(&row));
            if self.iteration.is_multiple_of(save_every)
                || self.iteration == max
                || self.stopped_early()
            {
                self.save().map_err(|e| wrap(e, &self.last_checkpoint))?;
                self.write_metrics(true)
                    .map_err(|e| wrap(e, &self.last_checkpoint))?;
            } else {
                self.write_metrics(false)
                    .map_err(|e| wrap(e, &self.last_checkpoint))?;
            }
            if self.stopped_early() {
                bar.abandon();
                break;
            }
        }
        bar.finish();
        let last = match &self.last_checkpoint {
            Some(p) => p.clone(),
            None => self.save().map_err(|e| wrap(e, &None))?,
        };
        Ok(last)
    }
}

/// The progress bar's line: mean reward per step, mean episode length (policy steps),
/// planar velocity tracking error, the estimator's error, the discriminator's mean output
/// on the rollout (+1 prior-like, -1 not) and throughput; "-" until a value exists (the
/// episode figures need a finished episode).
fn progress_message(row: &BTreeMap<String, f64>) -> String {
    let g = |k: &str, digits: usize| match row.get(k).copied() {
        Some(v) if v.is_finite() => format!("{v:.digits$}"),
        _ => "-".into(),
    };
    format!(
        "reward/step {} | episode {} steps | vel err {} m/s | estimator err {} m/s | D(policy) {} | {} env steps/s",
        g("reward/total", 3),
        g("episode/length", 0),
        g("tracking/lin_vel_error_m_s", 3),
        g("estimator/error_m_s", 3),
        g("amp/d_policy_rollout", 2),
        g("perf/env_steps_per_s", 0)
    )
}

fn metrics_row(
    it: usize,
    ro: &RolloutStats,
    up: &UpdateStats,
    collect_s: f64,
    update_s: f64,
) -> BTreeMap<String, f64> {
    let mut m = BTreeMap::new();
    let mut put = |k: &str, v: f64| {
        m.insert(k.to_string(), v);
    };
    put("iteration", it as f64);
    put("reward/total", ro.reward_total);
    put("reward/env", ro.reward_env);
    put("reward/style", ro.reward_style);
    put("episode/return", ro.episode_return);
    put("episode/length", ro.episode_length);
    put("episode/termination_rate", ro.termination_rate);
    put("amp/d_policy_rollout", ro.d_rollout);
    put("amp/d_prior", up.d_prior as f64);
    put("amp/d_policy", up.d_policy as f64);
    put("tracking/lin_vel_error_m_s", ro.lin_vel_error_m_s);
    put("tracking/yaw_rate_error_rad_s", ro.yaw_rate_error_rad_s);
    put("estimator/error_m_s", ro.estimator_error_m_s);
    put("loss/surrogate", up.surrogate as f64);
    put("loss/value", up.value as f64);
    put("loss/entropy", up.entropy as f64);
    put("loss/estimator", up.estimator as f64);
    put("loss/discriminator", up.disc_loss as f64);
    put("loss/grad_penalty", up.grad_penalty as f64);
    if let Some(saliency) = up.disc_saliency {
        for ((name, _), v) in AMP_GROUPS.iter().zip(saliency) {
            put(&format!("amp_saliency/{name}"), v as f64);
        }
    }
    put("train/kl", up.kl as f64);
    put("train/kl_first", up.kl_first as f64);
    put("train/learning_rate", up.learning_rate);
    put("train/grad_norm", up.grad_norm as f64);
    put("train/action_std", up.action_std as f64);
    put("perf/collect_s", collect_s);
    put("perf/update_s", update_s);
    put(
        "perf/env_steps_per_s",
        ro.env_steps as f64 / (collect_s + update_s),
    );
    for (k, v) in &ro.env_log {
        m.insert(format!("episode/{k}"), *v);
    }
    m
}
