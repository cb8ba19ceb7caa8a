//! `hexapod eval`: tracking error at fixed commands, fall rate (under the environment's
//! random pushes), and a tripod score (fraction of time the stance set is exactly one of
//! the two tripods), for a checkpoint.

use crate::checkpoint::load_for_inference;
use crate::cli::play::set_command;
use crate::config::EnvKind;
use crate::env::make_env;
use anyhow::Context;
use clap::Args;
use hexapod_core::amp::{AMP_BASE_ANG_VEL, AMP_STATE_DIM};
use hexapod_core::obs::{CONTACT_FORCE_SCALE, LIN_VEL_SCALE, PRIVILEGED_DIM, PRIV_CONTACT_FORCES, PRIV_LIN_VEL};
use hexapod_core::robot::{NUM_LEGS, TRIPOD_A_MASK, TRIPOD_B_MASK};
use serde::Serialize;
use std::path::PathBuf;

/// A foot is in contact above this force, N.
pub const CONTACT_THRESHOLD_N: f32 = 5.0;
/// Steps ignored after each reset before tracking is measured (1 s).
pub const SETTLE_STEPS: usize = 50;
/// The fixed commands `(vx m/s, vy m/s, wz rad/s)` evaluated by default.
pub const EVAL_COMMANDS: [[f32; 3]; 6] =
    [[0.3, 0.0, 0.0], [0.6, 0.0, 0.0], [-0.3, 0.0, 0.0], [0.0, 0.3, 0.0], [0.0, 0.0, 0.5], [0.4, 0.0, 0.3]];

/// Arguments of `hexapod eval`.
#[derive(Args, Debug)]
pub struct EvalArgs {
    /// Checkpoint directory.
    #[arg(long)]
    pub checkpoint: PathBuf,
    /// Robots per command.
    #[arg(long, default_value_t = 16)]
    pub num_envs: usize,
    /// Policy steps per command (50 per second).
    #[arg(long, default_value_t = 500)]
    pub steps: usize,
    /// Report file (default `<checkpoint>/eval.json`).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Environment override (`sim` or `fake`).
    #[arg(long, value_parser = ["sim", "fake"])]
    pub env: Option<String>,
}

/// Results at one fixed command.
#[derive(Debug, Serialize)]
pub struct CommandResult {
    /// The command (vx, vy, wz).
    pub command: [f32; 3],
    /// Mean planar velocity error, m/s.
    pub lin_vel_error_m_s: f64,
    /// Mean yaw-rate error, rad/s.
    pub yaw_rate_error_rad_s: f64,
    /// Mean measured (vx, vy, wz).
    pub mean_velocity: [f64; 3],
    /// Fraction of robots that fell (terminated) at least once.
    pub fall_rate: f64,
    /// Fraction of steps whose stance set is exactly tripod A or B.
    pub tripod_score: f64,
}

/// The evaluation report.
#[derive(Debug, Serialize)]
pub struct EvalReport {
    /// Checkpoint evaluated.
    pub checkpoint: String,
    /// Environment used.
    pub env: String,
    /// Robots per command.
    pub num_envs: usize,
    /// Steps per command.
    pub steps: usize,
    /// Per-command results.
    pub commands: Vec<CommandResult>,
    /// Mean over commands.
    pub mean_lin_vel_error_m_s: f64,
    /// Mean over commands.
    pub mean_fall_rate: f64,
    /// Mean over commands.
    pub mean_tripod_score: f64,
    /// RMS estimator error, m/s (NaN without estimator).
    pub estimator_error_m_s: f64,
}

/// Stance mask (bit i = leg i) from a privileged state row.
pub fn contact_mask(privileged: &[f32]) -> u8 {
    let mut mask = 0u8;
    for leg in 0..NUM_LEGS {
        let f = &privileged[PRIV_CONTACT_FORCES.start + 3 * leg..PRIV_CONTACT_FORCES.start + 3 * leg + 3];
        let norm_n = (f[0] * f[0] + f[1] * f[1] + f[2] * f[2]).sqrt() / CONTACT_FORCE_SCALE;
        if norm_n > CONTACT_THRESHOLD_N {
            mask |= 1 << leg;
        }
    }
    mask
}

/// Runs `hexapod eval`.
pub fn run(args: EvalArgs) -> anyhow::Result<()> {
    let (mut cfg, mut ppo) = load_for_inference(&args.checkpoint)?;
    cfg.env.num_envs = args.num_envs;
    if let Some(kind) = &args.env {
        cfg.env.kind = if kind == "fake" { EnvKind::Fake } else { EnvKind::Sim };
    }
    let mut env = make_env(&cfg)?;
    let n = args.num_envs;
    let mut results = Vec::new();
    let (mut est_sq, mut est_n) = (0.0f64, 0usize);
    for command in EVAL_COMMANDS {
        let mut obs = env.reset();
        let mut fell = vec![false; n];
        let (mut lin_err, mut yaw_err, mut mean_v, mut samples) = (0.0f64, 0.0f64, [0.0f64; 3], 0usize);
        let (mut tripod, mut contact_samples) = (0usize, 0usize);
        for step in 0..args.steps {
            set_command(&mut obs.actor, command);
            let act = ppo.act(&obs, true)?;
            let res = env.step(&act.actions);
            for i in 0..n {
                let p = &obs.privileged[i * PRIVILEGED_DIM..(i + 1) * PRIVILEGED_DIM];
                if step >= SETTLE_STEPS {
                    let v = [
                        p[PRIV_LIN_VEL.start] / LIN_VEL_SCALE,
                        p[PRIV_LIN_VEL.start + 1] / LIN_VEL_SCALE,
                        obs.amp[i * AMP_STATE_DIM + AMP_BASE_ANG_VEL.start + 2],
                    ];
                    lin_err += (((v[0] - command[0]).powi(2) + (v[1] - command[1]).powi(2)) as f64).sqrt();
                    yaw_err += (v[2] - command[2]).abs() as f64;
                    for k in 0..3 {
                        mean_v[k] += v[k] as f64;
                    }
                    samples += 1;
                    let mask = contact_mask(p);
                    tripod += usize::from(mask == TRIPOD_A_MASK || mask == TRIPOD_B_MASK);
                    contact_samples += 1;
                }
                if !act.estimate.is_empty() {
                    for k in 0..3 {
                        let e = (act.estimate[i * 3 + k] - p[PRIV_LIN_VEL.start + k]) / LIN_VEL_SCALE;
                        est_sq += (e * e) as f64;
                        est_n += 1;
                    }
                }
                if res.dones[i] && !res.time_outs[i] {
                    fell[i] = true;
                }
            }
            obs = res.obs;
        }
        let s = samples.max(1) as f64;
        results.push(CommandResult {
            command,
            lin_vel_error_m_s: lin_err / s,
            yaw_rate_error_rad_s: yaw_err / s,
            mean_velocity: [mean_v[0] / s, mean_v[1] / s, mean_v[2] / s],
            fall_rate: fell.iter().filter(|&&f| f).count() as f64 / n as f64,
            tripod_score: tripod as f64 / contact_samples.max(1) as f64,
        });
    }
    let m = results.len() as f64;
    let report = EvalReport {
        checkpoint: args.checkpoint.display().to_string(),
        env: format!("{:?}", cfg.env.kind).to_lowercase(),
        num_envs: n,
        steps: args.steps,
        mean_lin_vel_error_m_s: results.iter().map(|r| r.lin_vel_error_m_s).sum::<f64>() / m,
        mean_fall_rate: results.iter().map(|r| r.fall_rate).sum::<f64>() / m,
        mean_tripod_score: results.iter().map(|r| r.tripod_score).sum::<f64>() / m,
        estimator_error_m_s: if est_n > 0 { (est_sq / est_n as f64).sqrt() } else { f64::NAN },
        commands: results,
    };
    println!("{:>22} {:>12} {:>12} {:>10} {:>10}", "command (vx,vy,wz)", "lin err m/s", "yaw err r/s", "fall rate", "tripod");
    for r in &report.commands {
        println!(
            "{:>22} {:>12.3} {:>12.3} {:>10.2} {:>10.2}",
            format!("({:.1},{:.1},{:.1})", r.command[0], r.command[1], r.command[2]),
            r.lin_vel_error_m_s,
            r.yaw_rate_error_rad_s,
            r.fall_rate,
            r.tripod_score
        );
    }
    println!(
        "mean: lin err {:.3} m/s, fall rate {:.2}, tripod score {:.2}, estimator error {:.3} m/s",
        report.mean_lin_vel_error_m_s, report.mean_fall_rate, report.mean_tripod_score, report.estimator_error_m_s
    );
    let out = args.out.clone().unwrap_or_else(|| args.checkpoint.join("eval.json"));
    std::fs::write(&out, serde_json::to_string_pretty(&report)?).with_context(|| format!("writing {}", out.display()))?;
    eprintln!("report: {}", out.display());
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn contact_mask_reads_the_force_norm() {
        let mut p = [0.0f32; PRIVILEGED_DIM];
        for leg in [0usize, 2, 4] {
            p[PRIV_CONTACT_FORCES.start + 3 * leg + 2] = 80.0 * CONTACT_FORCE_SCALE;
        }
        p[PRIV_CONTACT_FORCES.start + 3 + 2] = CONTACT_FORCE_SCALE; // leg 1 at 1 N: below threshold
        assert_eq!(contact_mask(&p), TRIPOD_A_MASK);
    }
}
