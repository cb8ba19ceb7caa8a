//! `hexapod sim2sim`: a checkpoint's policy in MuJoCo beside rapier, the check before
//! hardware. Both simulators run the nominal model (no domain randomization, no pushes, no
//! observation noise, flat ground), one robot each from the nominal pose at the origin, at
//! `hexapod eval`'s fixed commands, measured by eval's own [`track_command`]. MuJoCo only
//! integrates (`bench/mujoco_sim2sim.py`); observations, the action path and the
//! termination rule are the simulator's ([`host_sim::mujoco_env`]).

use crate::checkpoint::{display_name, load_for_inference, resolve_dir};
use crate::cli::eval::{
    table_header, table_row, track_command, CommandResult, EstimatorError, EVAL_COMMANDS,
    SETTLE_STEPS,
};
use anyhow::Context;
use clap::Args;
use hexapod_core::timing::POLICY_DT_S;
use host_sim::config::EnvConfig;
use host_sim::env::{HexapodEnv, SpawnPose};
use host_sim::mujoco_env::MujocoEnv;
use host_sim::vec_env::VecEnv;
use serde::Serialize;
use std::path::PathBuf;

/// What both simulators run, as the report states it.
pub const NOMINAL_MODEL: &str =
    "nominal model in both simulators: no domain randomization, no pushes, no observation noise, flat ground, one robot from the nominal pose";

/// Arguments of `hexapod sim2sim`.
#[derive(Args, Debug)]
pub struct Sim2SimArgs {
    /// Checkpoint directory (policy.safetensors + config.toml), or a run directory (its
    /// latest checkpoint).
    #[arg(long)]
    pub checkpoint: PathBuf,
    /// Policy steps per command (50 per second); the first 50 are the settle time.
    #[arg(long, default_value_t = 500)]
    pub steps: usize,
    /// Report file (default `runs/sim2sim/<checkpoint name>.json`).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Python interpreter with the `mujoco` and `numpy` packages (default `$HEXAPOD_PYTHON`,
    /// else `python3`).
    #[arg(long)]
    pub python: Option<String>,
}

/// One simulator's results.
#[derive(Debug, Serialize)]
pub struct SimResults {
    /// Per-command results, as `hexapod eval` reports them.
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

impl SimResults {
    fn new(commands: Vec<CommandResult>, estimator: EstimatorError) -> Self {
        let m = commands.len().max(1) as f64;
        Self {
            mean_lin_vel_error_m_s: commands.iter().map(|r| r.lin_vel_error_m_s).sum::<f64>() / m,
            mean_fall_rate: commands.iter().map(|r| r.fall_rate).sum::<f64>() / m,
            mean_tripod_score: commands.iter().map(|r| r.tripod_score).sum::<f64>() / m,
            estimator_error_m_s: estimator.rms_m_s(),
            commands,
        }
    }
}

/// The sim-to-sim report.
#[derive(Debug, Serialize)]
pub struct Sim2SimReport {
    /// Checkpoint run.
    pub checkpoint: String,
    /// Policy steps per command.
    pub steps: usize,
    /// What both simulators run.
    pub model: String,
    /// Version of the `mujoco` package.
    pub mujoco_version: String,
    /// host-sim (rapier3d).
    pub rapier: SimResults,
    /// MuJoCo.
    pub mujoco: SimResults,
}

/// The simulator config of the comparison: the checkpoint's, nominal, one robot on flat
/// ground.
pub fn nominal_sim(mut sim: EnvConfig) -> EnvConfig {
    sim.num_envs = 1;
    sim.randomization.enabled = false;
    sim.push.enabled = false;
    sim.observation_noise = false;
    sim.terrain.tiles = false;
    sim.curriculum = false;
    sim.reference_init_probability = 0.0;
    sim
}

/// The nominal rapier environment, its robot at the origin facing +x (where MuJoCo's starts).
pub fn rapier_env(sim: &EnvConfig) -> anyhow::Result<Box<dyn VecEnv>> {
    let mut env = HexapodEnv::new(sim.clone())?;
    env.set_spawn_pose(
        0,
        Some(SpawnPose {
            position_m: [0.0, 0.0],
            yaw_rad: 0.0,
        }),
    );
    Ok(Box::new(env))
}

/// The MuJoCo environment with the episode length and tilt limit of `sim`.
pub fn mujoco_env(sim: &EnvConfig, python: &str) -> anyhow::Result<MujocoEnv> {
    MujocoEnv::new(python, sim.episode_length_s, sim.max_tilt_deg)
}

/// The interpreter: `--python`, else `$HEXAPOD_PYTHON`, else `python3`.
pub fn python_interpreter(given: Option<&str>) -> String {
    given
        .map(str::to_string)
        .or_else(|| std::env::var("HEXAPOD_PYTHON").ok())
        .unwrap_or_else(|| "python3".into())
}

/// Mean number of feet on the ground.
fn mean_feet_down(r: &CommandResult) -> f64 {
    r.feet_down_fraction
        .iter()
        .enumerate()
        .map(|(k, f)| k as f64 * f)
        .sum()
}

/// Runs `hexapod sim2sim`.
pub fn run(args: Sim2SimArgs) -> anyhow::Result<()> {
    let checkpoint = resolve_dir(&args.checkpoint)?;
    anyhow::ensure!(
        args.steps > SETTLE_STEPS,
        "--steps {} leaves nothing to measure: the first {SETTLE_STEPS} steps ({:.1} s) are the settle time",
        args.steps,
        SETTLE_STEPS as f32 * POLICY_DT_S
    );
    let (cfg, mut ppo) = load_for_inference(&checkpoint)?;
    let sim = nominal_sim(cfg.resolved_sim());
    let python = python_interpreter(args.python.as_deref());
    let mut mujoco = mujoco_env(&sim, &python)?;
    let mut rapier = rapier_env(&sim)?;
    println!(
        "sim2sim: {}, {} steps ({:.0} s) per command; {NOMINAL_MODEL} (MuJoCo {})",
        checkpoint.display(),
        args.steps,
        args.steps as f32 * POLICY_DT_S,
        mujoco.mujoco_version()
    );
    let (mut rapier_rows, mut mujoco_rows) = (Vec::new(), Vec::new());
    let (mut rapier_est, mut mujoco_est) = (EstimatorError::default(), EstimatorError::default());
    for command in EVAL_COMMANDS {
        rapier_rows.push(track_command(
            &mut rapier,
            &mut ppo,
            command,
            false,
            args.steps,
            &mut rapier_est,
            None,
        )?);
        mujoco_rows.push(track_command(
            &mut mujoco,
            &mut ppo,
            command,
            false,
            args.steps,
            &mut mujoco_est,
            None,
        )?);
    }
    let report = Sim2SimReport {
        checkpoint: checkpoint.display().to_string(),
        steps: args.steps,
        model: NOMINAL_MODEL.into(),
        mujoco_version: mujoco.mujoco_version().to_string(),
        rapier: SimResults::new(rapier_rows, rapier_est),
        mujoco: SimResults::new(mujoco_rows, mujoco_est),
    };
    print_report(&report);
    let out = args.out.unwrap_or_else(|| {
        PathBuf::from("runs/sim2sim").join(format!("{}.json", display_name(&checkpoint)))
    });
    if let Some(dir) = out.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    }
    std::fs::write(&out, serde_json::to_string_pretty(&report)?)
        .with_context(|| format!("writing {}", out.display()))?;
    eprintln!("report: {}", out.display());
    Ok(())
}

/// Prints `hexapod eval`'s table with one row per simulator and command, plus the mean
/// number of feet down, then the means.
pub fn print_report(report: &Sim2SimReport) {
    println!("{:>7} {} {:>10}", "sim", table_header(), "feet down");
    for (r, m) in report.rapier.commands.iter().zip(&report.mujoco.commands) {
        println!(
            "{:>7} {} {:>10.2}",
            "rapier",
            table_row(r),
            mean_feet_down(r)
        );
        println!(
            "{:>7} {} {:>10.2}",
            "mujoco",
            table_row(m),
            mean_feet_down(m)
        );
    }
    for (name, s) in [("rapier", &report.rapier), ("mujoco", &report.mujoco)] {
        println!(
            "mean {name}: lin err {:.3} m/s, fall rate {:.2}, tripod score {:.2}, estimator error {:.3} m/s",
            s.mean_lin_vel_error_m_s, s.mean_fall_rate, s.mean_tripod_score, s.estimator_error_m_s
        );
    }
}
