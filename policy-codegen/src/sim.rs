//! Closed loop in the simulator: the f32 and the fixed-point policy drive the same robots
//! (same seed, same commands, same randomization) in `host-sim`, and the f32 run's
//! observations are recorded for the accuracy report.

use crate::accuracy::HostScratch;
use crate::checkpoint::PolicyF32;
use crate::quantize::OwnedPolicy;
use crate::records::ObsRecord;
use hexapod_core::nn::Kernel;
use hexapod_core::obs::{ACTOR_OBS_DIM, HISTORY_DIM, LIN_VEL_SCALE, PRIVILEGED_DIM, PRIV_LIN_VEL};
use hexapod_core::NUM_JOINTS;
use host_sim::config::EnvConfig;
use host_sim::env::HexapodEnv;
use host_sim::vec_env::{Observations, VecEnv};

/// What a closed-loop run measured.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ClosedLoopReport {
    /// Robots.
    pub num_envs: usize,
    /// Policy steps.
    pub steps: usize,
    /// Mean reward per robot and step.
    pub mean_reward: f64,
    /// Terminations (not time-outs) per robot.
    pub falls_per_robot: f64,
    /// Mean forward base velocity, m/s.
    pub mean_vx_m_s: f64,
    /// Mean |action|.
    pub mean_abs_action: f64,
}

/// The simulator's default robots on flat ground: what `sim-compare` runs.
pub fn flat_config(num_envs: usize, seed: u64) -> EnvConfig {
    EnvConfig {
        num_envs,
        seed,
        ..Default::default()
    }
}

/// The same robots on the training terrain's tiles (every kind, rows 0-9 drawn at random,
/// no curriculum): stairs and slopes up and down.
pub fn terrain_config(num_envs: usize, seed: u64) -> EnvConfig {
    let mut config = EnvConfig {
        num_envs,
        seed,
        curriculum: false,
        ..Default::default()
    };
    config.terrain.tiles = true;
    config.max_initial_level = config.terrain.rows.saturating_sub(1);
    config
}

/// Runs `act` (actor observation, history -> action) on the robots of `config` for
/// `steps` policy steps; pushes every observation into `record` when given.
pub fn closed_loop(
    mut act: impl FnMut(&[f32; ACTOR_OBS_DIM], &[f32; HISTORY_DIM]) -> [f32; NUM_JOINTS],
    config: EnvConfig,
    steps: usize,
    mut record: Option<&mut Vec<ObsRecord>>,
) -> anyhow::Result<ClosedLoopReport> {
    let num_envs = config.num_envs;
    let mut env = HexapodEnv::new(config)?;
    let mut obs: Observations = env.reset();
    let mut report = ClosedLoopReport {
        num_envs,
        steps,
        ..Default::default()
    };
    let mut actions = vec![0.0f32; num_envs * NUM_JOINTS];
    for _ in 0..steps {
        for i in 0..num_envs {
            let mut r = ObsRecord {
                actor_obs: [0.0; ACTOR_OBS_DIM],
                history: [0.0; HISTORY_DIM],
            };
            r.actor_obs
                .copy_from_slice(&obs.actor[i * ACTOR_OBS_DIM..(i + 1) * ACTOR_OBS_DIM]);
            r.history
                .copy_from_slice(&obs.history[i * HISTORY_DIM..(i + 1) * HISTORY_DIM]);
            let a = act(&r.actor_obs, &r.history);
            report.mean_abs_action +=
                a.iter().map(|v| v.abs() as f64).sum::<f64>() / NUM_JOINTS as f64;
            actions[i * NUM_JOINTS..(i + 1) * NUM_JOINTS].copy_from_slice(&a);
            if let Some(rec) = record.as_deref_mut() {
                rec.push(r);
            }
            let vx = obs
                .privileged
                .get(i * PRIVILEGED_DIM + PRIV_LIN_VEL.start)
                .copied()
                .unwrap_or(0.0);
            report.mean_vx_m_s += (vx / LIN_VEL_SCALE) as f64;
        }
        let result = env.step(&actions);
        report.mean_reward += result.rewards.iter().map(|&r| r as f64).sum::<f64>();
        let falls = result
            .dones
            .iter()
            .zip(&result.time_outs)
            .filter(|(d, t)| **d && !**t)
            .count();
        report.falls_per_robot += falls as f64;
        obs = result.obs;
    }
    let samples = (num_envs * steps).max(1) as f64;
    report.mean_reward /= samples;
    report.mean_vx_m_s /= samples;
    report.mean_abs_action /= samples;
    report.falls_per_robot /= num_envs.max(1) as f64;
    Ok(report)
}

/// The f32 and the fixed-point policy in the same closed loop; returns both reports and
/// the observations the f32 run visited.
pub fn compare_closed_loop(
    f32_policy: &PolicyF32,
    fixed: &OwnedPolicy,
    num_envs: usize,
    steps: usize,
    seed: u64,
) -> anyhow::Result<(ClosedLoopReport, ClosedLoopReport, Vec<ObsRecord>)> {
    let mut recorded = Vec::with_capacity(num_envs * steps);
    let f32_report = closed_loop(
        |o, h| f32_policy.act(o, h),
        flat_config(num_envs, seed),
        steps,
        Some(&mut recorded),
    )?;
    let fixed_report = fixed.with_view(|q| {
        let mut scratch = Box::new(HostScratch::default());
        let mut failed = false;
        let report = closed_loop(
            |o, h| match q.step_obs(&mut scratch, o, h, Kernel::Native) {
                Ok(out) => out.action,
                Err(_) => {
                    failed = true;
                    [0.0; NUM_JOINTS]
                }
            },
            flat_config(num_envs, seed),
            steps,
            None,
        );
        anyhow::ensure!(
            !failed,
            "the fixed-point policy rejected a simulator observation"
        );
        report
    })?;
    Ok((f32_report, fixed_report, recorded))
}
