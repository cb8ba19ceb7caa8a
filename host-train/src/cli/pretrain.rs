//! `hexapod pretrain`: a warm start for PPO + AMP by behavior cloning. An expert drives the
//! simulated robots, following each robot's sampled command, with Gaussian noise on the
//! executed actions so the data covers the states around its gait; the actor (with its
//! memory encoder) regresses the expert's clean action, the estimator the true base
//! velocity, and the critic the discounted task return. The result is an iteration-0
//! checkpoint that `hexapod train --resume` fine-tunes. Without it, PPO from a random
//! policy needs far more samples than a 2-core machine gives to find stepping at all.
//!
//! Two experts (`--expert`): `priors` (the default) plays the motion priors themselves,
//! blended between the clips of the command grid ([`PriorExpert`]), so the warm start walks
//! the gait the discriminator rewards; `scripted` is host-sim's `TripodGait` with the
//! priors' period and clearance (duty factor 0.5, sine lift, fixed footholds), a different
//! gait the discriminator separates from the first iteration.

use crate::algo::adam::Adam;
use crate::algo::ppo::Ppo;
use crate::algo::storage::gather_rows;
use crate::checkpoint;
use crate::config::{EnvKind, TrainConfig};
use crate::nn::actor_critic::BatchInput;
use crate::priors::dataset::MotionDataset;
use crate::priors::expert::PriorExpert;
use anyhow::Context;
use candle_core::{Device, Tensor};
use clap::Args;
use hexapod_core::obs::{
    ACTOR_COMMAND, ACTOR_OBS_DIM, COMMAND_SCALE, HEIGHT_SCAN_DIM, HISTORY_DIM, PRIVILEGED_DIM,
    PRIV_LIN_VEL,
};
use hexapod_core::robot::{NUM_JOINTS, Q0_RAD};
use hexapod_core::timing::{ACTION_SCALE_RAD, POLICY_DT_S};
use host_sim::gait::TripodGait;
use host_sim::vec_env::VecEnv;
use rand::seq::SliceRandom;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use std::path::PathBuf;

/// Gait cycle of the expert, s (the motion priors' 30 frames).
pub const EXPERT_PERIOD_S: f32 = 0.6;
/// Swing apex of the expert, m (the motion priors' clearance).
pub const EXPERT_STEP_HEIGHT_M: f32 = 0.08;

/// Arguments of `hexapod pretrain`.
#[derive(Args, Debug)]
pub struct PretrainArgs {
    /// Preset (TOML) whose networks, environment and seed are used.
    #[arg(long, short)]
    pub config: PathBuf,
    /// Checkpoint directory to write.
    #[arg(long)]
    pub out: PathBuf,
    /// Policy steps collected per robot (50 per second).
    #[arg(long, default_value_t = 1000)]
    pub steps: usize,
    /// Passes over the collected data.
    #[arg(long, default_value_t = 20)]
    pub epochs: usize,
    /// Standard deviation of the noise on the executed actions (action units).
    #[arg(long, default_value_t = 0.3)]
    pub exec_noise: f32,
    /// Adam learning rate.
    #[arg(long, default_value_t = 1e-3)]
    pub learning_rate: f64,
    /// Samples per gradient step.
    #[arg(long, default_value_t = 2048)]
    pub batch: usize,
    /// The gait to clone: the motion priors (`amp.priors_dir` of the preset) or host-sim's
    /// scripted tripod gait.
    #[arg(long, value_enum, default_value_t = ExpertKind::Priors)]
    pub expert: ExpertKind,
    /// Override any config key, as `hexapod train --set` (for example
    /// `--set sim.terrain.tiles=false` to clone on flat ground a preset that trains on tiles).
    #[arg(long = "set", value_name = "KEY=VALUE")]
    pub overrides: Vec<String>,
}

/// Which gait `hexapod pretrain` clones.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum ExpertKind {
    /// The motion priors, blended between the clips of the command grid.
    Priors,
    /// host-sim's scripted tripod gait.
    Scripted,
}

/// The expert of a pretraining run.
enum Expert {
    Priors(PriorExpert),
    Scripted,
}

impl Expert {
    fn load(kind: ExpertKind, cfg: &TrainConfig) -> anyhow::Result<Self> {
        Ok(match kind {
            ExpertKind::Scripted => Self::Scripted,
            ExpertKind::Priors => {
                let dir = std::path::Path::new(&cfg.amp.priors_dir);
                let data = MotionDataset::load_dir(dir)?;
                Self::Priors(
                    PriorExpert::new(data.clips()).with_context(|| dir.display().to_string())?,
                )
            }
        })
    }

    /// The action for `command`, `step` policy steps after the episode start.
    fn action(&self, command: [f32; 3], step: usize) -> [f32; NUM_JOINTS] {
        match self {
            Self::Scripted => expert_action(command, step as f32 * POLICY_DT_S),
            // The target of the coming policy step is the next frame.
            Self::Priors(expert) => {
                let q = expert.joint_targets(command, step + 1);
                std::array::from_fn(|j| (q[j] - Q0_RAD[j]) / ACTION_SCALE_RAD)
            }
        }
    }
}

/// The command `(vx, vy, wz)` a robot's actor observation carries.
pub fn command_of(actor_row: &[f32]) -> [f32; 3] {
    std::array::from_fn(|k| actor_row[ACTOR_COMMAND.start + k] / COMMAND_SCALE[k])
}

/// The expert's action for `command` at `t_s` after the episode start: the gait's joint
/// targets at the end of the coming policy step, in action units.
pub fn expert_action(command: [f32; 3], t_s: f32) -> [f32; NUM_JOINTS] {
    let gait = TripodGait {
        period_s: EXPERT_PERIOD_S,
        velocity_m_s: [command[0], command[1]],
        yaw_rate_rad_s: command[2],
        step_height_m: EXPERT_STEP_HEIGHT_M,
    };
    let q = gait.joint_targets(t_s + POLICY_DT_S);
    std::array::from_fn(|j| (q[j] - Q0_RAD[j]) / ACTION_SCALE_RAD)
}

/// Collected samples, row-major.
#[derive(Default)]
struct Dataset {
    actor: Vec<f32>,
    history: Vec<f32>,
    privileged: Vec<f32>,
    heights: Vec<f32>,
    labels: Vec<f32>,
    returns: Vec<f32>,
    /// Rows whose return is trusted (not within a horizon of the unfinished end).
    value_rows: Vec<usize>,
}

impl Dataset {
    fn len(&self) -> usize {
        self.labels.len() / NUM_JOINTS
    }
}

/// Runs the expert on the simulator and records observations, labels and returns.
fn collect(cfg: &TrainConfig, args: &PretrainArgs, expert: &Expert) -> anyhow::Result<Dataset> {
    let mut env = host_sim::env::HexapodEnv::new(cfg.resolved_sim())?;
    let n = env.num_envs();
    let mut rng = ChaCha8Rng::seed_from_u64(cfg.env.seed ^ 0xbc);
    let mut step = vec![0usize; n];
    let mut obs = env.reset();
    let mut data = Dataset::default();
    let (mut rewards, mut dones) = (
        Vec::with_capacity(n * args.steps),
        Vec::with_capacity(n * args.steps),
    );
    let mut expert_vx = (0.0f64, 0.0f64, 0usize);
    for _ in 0..args.steps {
        let mut exec = Vec::with_capacity(n * NUM_JOINTS);
        for i in 0..n {
            let command = command_of(&obs.actor[i * ACTOR_OBS_DIM..(i + 1) * ACTOR_OBS_DIM]);
            let label = expert.action(command, step[i]);
            data.labels.extend_from_slice(&label);
            exec.extend(label.iter().map(|&a| {
                let z: f32 = StandardNormal.sample(&mut rng);
                a + args.exec_noise * z
            }));
            if command[1].abs() < 0.05 && command[2].abs() < 0.1 && command[0] > 0.2 {
                let v = obs.privileged[i * PRIVILEGED_DIM + PRIV_LIN_VEL.start]
                    / hexapod_core::obs::LIN_VEL_SCALE;
                expert_vx.0 += v as f64;
                expert_vx.1 += command[0] as f64;
                expert_vx.2 += 1;
            }
        }
        data.actor.extend_from_slice(&obs.actor);
        data.history.extend_from_slice(&obs.history);
        data.privileged.extend_from_slice(&obs.privileged);
        data.heights.extend_from_slice(&obs.heights);
        let res = env.step(&exec);
        for i in 0..n {
            step[i] = if res.dones[i] { 0 } else { step[i] + 1 };
        }
        rewards.extend_from_slice(&res.rewards);
        dones.extend(res.dones.iter().zip(&res.time_outs).map(|(&d, &t)| d && !t));
        obs = res.obs;
    }
    // Discounted returns, backwards per robot; the last `horizon` steps have a truncated
    // tail and are left out of the value regression.
    let gamma = cfg.ppo.gamma;
    let horizon = ((3.0 / (1.0 - gamma)) as usize).min(args.steps / 2);
    data.returns = vec![0.0; n * args.steps];
    for i in 0..n {
        let mut g = 0.0f32;
        for k in (0..args.steps).rev() {
            let row = k * n + i;
            if dones[row] {
                g = 0.0;
            }
            g = rewards[row] + gamma * g;
            data.returns[row] = g;
        }
    }
    data.value_rows = (0..(args.steps - horizon) * n).collect();
    if expert_vx.2 > 0 {
        eprintln!(
            "expert: mean forward speed {:.3} m/s at mean command {:.3} m/s (straight commands above 0.2 m/s)",
            expert_vx.0 / expert_vx.2 as f64,
            expert_vx.1 / expert_vx.2 as f64
        );
    }
    Ok(data)
}

fn rows(data: &[f32], dim: usize, idx: &[usize], device: &Device) -> candle_core::Result<Tensor> {
    Tensor::from_vec(gather_rows(data, dim, idx), (idx.len(), dim), device)
}

/// One epoch of regression; returns (action MSE, estimator MSE, value MSE) means.
fn epoch(
    ppo: &Ppo,
    opt: &mut Adam,
    data: &Dataset,
    batch: usize,
    rng: &mut ChaCha8Rng,
) -> anyhow::Result<[f64; 3]> {
    let dev = ppo.device.clone();
    let mut order: Vec<usize> = (0..data.len()).collect();
    order.shuffle(rng);
    let mut value_order = data.value_rows.clone();
    value_order.shuffle(rng);
    let steps = order.len() / batch;
    let mut sums = [0.0f64; 3];
    for b in 0..steps {
        let idx = &order[b * batch..(b + 1) * batch];
        let actor = rows(&data.actor, ACTOR_OBS_DIM, idx, &dev)?;
        let history = rows(&data.history, HISTORY_DIM, idx, &dev)?;
        let labels = rows(&data.labels, NUM_JOINTS, idx, &dev)?;
        let privileged = rows(&data.privileged, PRIVILEGED_DIM, idx, &dev)?;
        let out = ppo.ac.acting_policy(&BatchInput {
            actor_obs: &actor,
            history: &history,
            privileged: &privileged,
            heights: &rows(&data.heights, HEIGHT_SCAN_DIM, idx, &dev)?,
        })?;
        let action_loss = out.mean.sub(&labels)?.sqr()?.mean_all()?;
        let mut loss = action_loss.clone();
        if let Some(estimate) = &out.estimate {
            let target = privileged.narrow(1, PRIV_LIN_VEL.start, PRIV_LIN_VEL.len())?;
            let est = estimate.sub(&target)?.sqr()?.mean_all()?;
            sums[1] += est.to_scalar::<f32>()? as f64;
            loss = (loss + est)?;
        }
        // The critic takes the b-th batch of its own (shorter) row set, wrapping around.
        if let Some(vidx) = value_order.chunks_exact(batch).cycle().nth(b) {
            let v = ppo.ac.value(&BatchInput {
                actor_obs: &rows(&data.actor, ACTOR_OBS_DIM, vidx, &dev)?,
                history: &rows(&data.history, HISTORY_DIM, vidx, &dev)?,
                privileged: &rows(&data.privileged, PRIVILEGED_DIM, vidx, &dev)?,
                heights: &rows(&data.heights, HEIGHT_SCAN_DIM, vidx, &dev)?,
            })?;
            let target: Vec<f32> = vidx.iter().map(|&r| data.returns[r]).collect();
            let target = Tensor::from_vec(target, vidx.len(), &dev)?;
            let vl = v.sub(&target)?.sqr()?.mean_all()?;
            sums[2] += vl.to_scalar::<f32>()? as f64;
            loss = (loss + vl)?;
        }
        sums[0] += action_loss.to_scalar::<f32>()? as f64;
        let grads = loss.backward()?;
        opt.step(&grads, Some(1.0))?;
    }
    Ok(sums.map(|s| s / steps.max(1) as f64))
}

/// Runs `hexapod pretrain`.
pub fn run(args: PretrainArgs) -> anyhow::Result<()> {
    let cfg = TrainConfig::load_with_overrides(&args.config, &args.overrides)?;
    cfg.validate()?;
    anyhow::ensure!(
        cfg.env.kind == EnvKind::Sim,
        "{}: pretraining needs env.kind = \"sim\"",
        args.config.display()
    );
    anyhow::ensure!(
        args.batch > 0 && args.steps >= 2,
        "--batch and --steps must be positive"
    );
    let expert = Expert::load(args.expert, &cfg)?;
    let mut ppo = Ppo::new(&cfg)?;
    eprintln!(
        "collecting {} steps x {} robots with the {} as the expert",
        args.steps,
        cfg.env.num_envs,
        match args.expert {
            ExpertKind::Priors => "motion priors",
            ExpertKind::Scripted => "scripted tripod gait",
        }
    );
    let data = collect(&cfg, &args, &expert)?;
    ppo.ac
        .update_normalizers(&data.actor, &data.history, &data.privileged, &data.heights)?;
    let mut opt = Adam::new(&ppo.params, args.learning_rate)?;
    let mut rng = ChaCha8Rng::seed_from_u64(cfg.runner.seed ^ 0xbc);
    let label_variance = variance(&data.labels);
    for e in 0..args.epochs {
        let [a, est, v] = epoch(&ppo, &mut opt, &data, args.batch, &mut rng)?;
        eprintln!(
            "epoch {:>3}/{}: action MSE {:.4} (label variance {:.4}), estimator MSE {:.4}, value MSE {:.2e}",
            e + 1,
            args.epochs,
            a,
            label_variance,
            est,
            v
        );
    }
    checkpoint::save(&args.out, &ppo, 0)
        .with_context(|| format!("writing {}", args.out.display()))?;
    eprintln!(
        "checkpoint: {} (resume it with `hexapod train --resume`)",
        args.out.display()
    );
    Ok(())
}

fn variance(x: &[f32]) -> f64 {
    let n = x.len().max(1) as f64;
    let mean = x.iter().map(|&v| v as f64).sum::<f64>() / n;
    x.iter().map(|&v| (v as f64 - mean).powi(2)).sum::<f64>() / n
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn command_round_trips_through_the_actor_observation() {
        let mut obs = host_sim::vec_env::Observations {
            actor: vec![0.0; ACTOR_OBS_DIM],
            ..Default::default()
        };
        obs.set_command(0, [0.3, -0.1, 0.4]);
        let c = command_of(&obs.actor);
        assert!(
            (c[0] - 0.3).abs() < 1e-6 && (c[1] + 0.1).abs() < 1e-6 && (c[2] - 0.4).abs() < 1e-6
        );
    }

    #[test]
    fn expert_stands_still_at_the_nominal_pose_between_swings() {
        // Zero command: the stance legs stay at q0, so their actions are zero.
        let a = expert_action([0.0; 3], 0.1);
        let stance_b = (0..6).filter(|leg| hexapod_core::robot::TRIPOD_A_MASK & (1 << leg) == 0);
        for leg in stance_b {
            for k in 0..3 {
                assert!(
                    a[3 * leg + k].abs() < 1e-4,
                    "leg {leg}: {:?}",
                    &a[3 * leg..3 * leg + 3]
                );
            }
        }
        assert!(a.iter().any(|x| x.abs() > 0.05), "the swing tripod lifts");
    }
}
