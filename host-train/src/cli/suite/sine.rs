//! Sinusoidal commands (the paper's Fig. 3): on flat ground, vx, vy and the yaw rate each
//! follow a sine for 20 s (after 1 s standing), one command axis per run. Per run: the RMSE
//! of the commanded axis, the mean |vz|, the roll and pitch RMS, the gait (tripod score and
//! feet-down histogram while the command is at least half its amplitude), and the traces
//! (the mean over the trials) of commanded against measured for the plots (not in the JSON).

use super::batch::{drive, heading_velocity_m_s, roll_pitch_rad, seed_trials, steps, Conditions};
use super::controller::SuiteController;
use crate::config::TrainConfig;
use hexapod_core::robot::{TRIPOD_A_MASK, TRIPOD_B_MASK};
use hexapod_core::timing::POLICY_DT_S;
use host_sim::env::HexapodEnv;
use serde::Serialize;

/// Standing before the sine starts, s.
pub const STAND_S: f32 = 1.0;
/// Length of the sine, s.
pub const DURATION_S: f32 = 20.0;
/// Period of every sine, s.
pub const PERIOD_S: f32 = 4.0;
/// Amplitudes: vx m/s, vy m/s, yaw rate rad/s.
pub const AMPLITUDES: [f32; 3] = [0.3, 0.2, 0.5];
/// The gait is measured while |command| is at least this fraction of the amplitude.
pub const GAIT_MIN_COMMAND_FRACTION: f32 = 0.5;
/// Names of the command axes.
pub const AXES: [&str; 3] = ["vx", "vy", "yaw_rate"];

/// One command axis's run.
#[derive(Clone, Debug, Serialize)]
pub struct SineRun {
    /// `vx`, `vy` or `yaw_rate`.
    pub axis: String,
    /// Amplitude (m/s or rad/s).
    pub amplitude: f32,
    /// Period, s.
    pub period_s: f32,
    /// Trials (robots).
    pub trials: usize,
    /// Trials that fell (their samples after the fall are left out).
    pub falls: usize,
    /// RMSE of the commanded axis (m/s or rad/s).
    pub tracking_rmse: f64,
    /// RMS of the two other command axes (their command is 0): planar m/s for `yaw_rate`,
    /// otherwise the other planar axis, m/s.
    pub cross_axis_rms: f64,
    /// Mean |vz|, m/s.
    pub mean_abs_vz_m_s: f64,
    /// Roll RMS, deg.
    pub roll_rms_deg: f64,
    /// Pitch RMS, deg.
    pub pitch_rms_deg: f64,
    /// Fraction of the gait samples (command at least half its amplitude) whose stance set
    /// is exactly one tripod (eval's tripod score).
    pub tripod_score: f64,
    /// Fraction of the gait samples with 0..=6 feet on the ground.
    pub feet_down_fraction: [f64; 7],
    /// Time of each sample, s from the sine's start.
    #[serde(skip)]
    pub time_s: Vec<f32>,
    /// Commanded value per sample.
    #[serde(skip)]
    pub commanded: Vec<f32>,
    /// Measured value per sample (mean over the standing trials).
    #[serde(skip)]
    pub measured: Vec<f32>,
    /// vz per sample (mean over the trials), m/s.
    #[serde(skip)]
    pub vz_m_s: Vec<f32>,
    /// Roll per sample (mean over the trials), deg.
    #[serde(skip)]
    pub roll_deg: Vec<f32>,
    /// Pitch per sample (mean over the trials), deg.
    #[serde(skip)]
    pub pitch_deg: Vec<f32>,
}

/// The command at time `t_s` after the sine's start on `axis`.
pub fn command(axis: usize, t_s: f32) -> [f32; 3] {
    let mut c = [0.0; 3];
    if t_s >= 0.0 {
        c[axis] = AMPLITUDES[axis] * (std::f32::consts::TAU * t_s / PERIOD_S).sin();
    }
    c
}

/// Runs the three axes in one batch.
pub fn run(
    cfg: &TrainConfig,
    controller: &mut dyn SuiteController,
    c: &Conditions,
) -> anyhow::Result<Vec<SineRun>> {
    let n = c.robots(AXES.len());
    let mut env = HexapodEnv::new(c.sim_config(cfg, n, STAND_S + DURATION_S))?;
    seed_trials(&mut env, c);
    for i in 0..n {
        env.set_spawn_pose(
            i,
            Some(host_sim::env::SpawnPose {
                position_m: [0.0, 0.0],
                yaw_rad: 0.0,
            }),
        );
    }
    let axis_of = |i: usize| i / c.trials;
    let stand = steps(STAND_S);
    let total = stand + steps(DURATION_S);
    let t_of = |step: usize| (step + 1) as f32 * POLICY_DT_S - STAND_S;
    let mut fell = vec![false; n];
    // Per robot and sample: (commanded axis value, measured axis value, cross-axis, vz, roll, pitch).
    let mut samples: Vec<Vec<[f32; 6]>> = vec![Vec::new(); n];
    // Per robot: the stance masks of the gait samples.
    let mut stances: Vec<Vec<u8>> = vec![Vec::new(); n];
    drive(
        &mut env,
        controller,
        total,
        // The command applied during step `step` is the one at its end time, as measured.
        |step, _, commands| {
            for (i, cmd) in commands.iter_mut().enumerate() {
                *cmd = command(axis_of(i), t_of(step));
            }
        },
        |step, env, res| {
            for i in 0..n {
                fell[i] |= res.dones[i];
                if fell[i] || step < stand {
                    continue;
                }
                let s = env.robot_state(i);
                let v = heading_velocity_m_s(&s);
                let wz = s.base_ang_vel_world_rad_s[2];
                let axis = axis_of(i);
                let measured = [v[0], v[1], wz][axis];
                let cross = match axis {
                    0 => v[1],
                    1 => v[0],
                    _ => v[0].hypot(v[1]),
                };
                let (roll, pitch) = roll_pitch_rad(&s);
                let commanded = command(axis, t_of(step))[axis];
                if commanded.abs() >= GAIT_MIN_COMMAND_FRACTION * AMPLITUDES[axis] {
                    stances[i].push(env.foot_contact_mask(i));
                }
                samples[i].push([
                    commanded,
                    measured,
                    cross,
                    v[2],
                    roll.to_degrees(),
                    pitch.to_degrees(),
                ]);
            }
        },
    )?;
    let sample_count = total - stand;
    let runs = (0..AXES.len())
        .map(|axis| {
            let robots: Vec<usize> = (0..n).filter(|&i| axis_of(i) == axis).collect();
            let all: Vec<&[f32; 6]> = robots.iter().flat_map(|&i| samples[i].iter()).collect();
            let m = all.len().max(1) as f64;
            let rms = |f: &dyn Fn(&[f32; 6]) -> f64| {
                (all.iter().map(|s| f(s).powi(2)).sum::<f64>() / m).sqrt()
            };
            let mean_trace = |k: usize| -> Vec<f32> {
                (0..sample_count)
                    .map(|t| {
                        let v: Vec<f32> = robots
                            .iter()
                            .filter_map(|&i| samples[i].get(t).map(|s| s[k]))
                            .collect();
                        if v.is_empty() {
                            f32::NAN
                        } else {
                            v.iter().sum::<f32>() / v.len() as f32
                        }
                    })
                    .collect()
            };
            let masks: Vec<u8> = robots
                .iter()
                .flat_map(|&i| stances[i].iter().copied())
                .collect();
            let gait_samples = masks.len().max(1) as f64;
            let mut feet_down_fraction = [0.0f64; 7];
            for m in &masks {
                feet_down_fraction[m.count_ones() as usize] += 1.0 / gait_samples;
            }
            let tripod = masks
                .iter()
                .filter(|&&m| m == TRIPOD_A_MASK || m == TRIPOD_B_MASK)
                .count();
            SineRun {
                axis: AXES[axis].into(),
                amplitude: AMPLITUDES[axis],
                period_s: PERIOD_S,
                trials: robots.len(),
                falls: robots.iter().filter(|&&i| fell[i]).count(),
                tracking_rmse: rms(&|s| (s[1] - s[0]) as f64),
                cross_axis_rms: rms(&|s| s[2] as f64),
                mean_abs_vz_m_s: all.iter().map(|s| s[3].abs() as f64).sum::<f64>() / m,
                roll_rms_deg: rms(&|s| s[4] as f64),
                pitch_rms_deg: rms(&|s| s[5] as f64),
                tripod_score: tripod as f64 / gait_samples,
                feet_down_fraction,
                time_s: (stand..total).map(t_of).collect(),
                commanded: (stand..total)
                    .map(|s| command(axis, t_of(s))[axis])
                    .collect(),
                measured: mean_trace(1),
                vz_m_s: mean_trace(3),
                roll_deg: mean_trace(4),
                pitch_deg: mean_trace(5),
            }
        })
        .collect();
    Ok(runs)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sine_commands_one_axis() {
        assert_eq!(command(1, -0.5), [0.0; 3]);
        let c = command(0, 1.0);
        assert!((c[0] - 0.3).abs() < 1e-6 && c[1] == 0.0 && c[2] == 0.0);
        let c = command(2, 3.0);
        assert!((c[2] + 0.5).abs() < 1e-6);
    }
}
