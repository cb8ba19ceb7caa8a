//! `hexapod eval`: tracking at fixed commands (error, mean velocity, speed error), fall
//! rate under the environment's random pushes, a tripod score (fraction of time the stance
//! set is exactly one of the two tripods), and a push test (0.5 m/s shoves every 4 s for a
//! 20 s episode), for a checkpoint. `--suite paper` runs the paper's experiments instead,
//! for one or several checkpoints ([`crate::cli::suite`]). With `--rerun` (a build with the
//! `rerun` feature), a rerun recording of the first robot at every command.

use crate::algo::ppo::Ppo;
use crate::checkpoint::load_for_inference;
use crate::cli::play::PlayEnv;
use crate::cli::recording::{require_rerun, Recording};
use crate::cli::style_probe::{self, StyleProbe};
use crate::cli::terrain_walk::{terrain_walk, TerrainWalkResult};
use crate::config::EnvKind;
use anyhow::Context;
use clap::Args;
use hexapod_core::amp::{AMP_BASE_ANG_VEL, AMP_STATE_DIM};
use hexapod_core::obs::{
    CONTACT_FORCE_SCALE, LIN_VEL_SCALE, PRIVILEGED_DIM, PRIV_BASE_HEIGHT, PRIV_CONTACT_FORCES,
    PRIV_LIN_VEL,
};
use hexapod_core::robot::{NUM_LEGS, TRIPOD_A_MASK, TRIPOD_B_MASK};
use hexapod_core::timing::POLICY_DT_S;
use host_sim::mujoco_env::MujocoEnv;
use host_sim::vec_env::{Observations, StepResult, VecEnv};
use serde::Serialize;
use std::path::PathBuf;

/// A foot is in contact above this force, N (the simulator's stance definition).
pub const CONTACT_THRESHOLD_N: f32 = host_sim::rewards::STANCE_FORCE_N;
/// Every this many policy steps a robot's AMP transition is kept for the style probe.
pub const STYLE_PROBE_EVERY_STEPS: usize = 5;
/// Steps ignored after each reset before tracking is measured (1 s).
pub const SETTLE_STEPS: usize = 50;
/// The fixed commands `(vx m/s, vy m/s, wz rad/s)` evaluated by default.
pub const EVAL_COMMANDS: [[f32; 3]; 6] = [
    [0.3, 0.0, 0.0],
    [0.6, 0.0, 0.0],
    [-0.3, 0.0, 0.0],
    [0.0, 0.3, 0.0],
    [0.0, 0.0, 0.5],
    [0.4, 0.0, 0.3],
];

/// Arguments of `hexapod eval`.
#[derive(Args, Debug)]
pub struct EvalArgs {
    /// Checkpoint directory (with `--suite`, repeat it to compare controllers side by side).
    #[arg(long, required_unless_present = "mpc")]
    pub checkpoint: Vec<PathBuf>,
    /// With `--suite`: also run the model-based MPC as a controller, with its default
    /// parameters or those of a TOML file (e.g. configs/mpc/default.toml).
    #[arg(long, requires = "suite", num_args = 0..=1, value_name = "PARAMS_TOML")]
    pub mpc: Option<Option<PathBuf>>,
    /// Robots per command.
    #[arg(long, default_value_t = 16)]
    pub num_envs: usize,
    /// Policy steps per command (50 per second).
    #[arg(long, default_value_t = 500)]
    pub steps: usize,
    /// Report file (default `runs/eval/<checkpoint name>.json`); with `--suite`, the report's
    /// directory (required).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Run a suite of experiments instead (`paper`: the paper's Table III, Fig. 3, 4, 5 and
    /// the outdoor step) and write its report (JSON, Markdown, plots) into `--out`.
    #[arg(long, requires = "out")]
    pub suite: Option<String>,
    /// The suite's protocols to run, comma-separated (default all: push, terrain, step,
    /// beyond, friction, sine, curriculum).
    #[arg(long, value_delimiter = ',', requires = "suite")]
    pub protocol: Vec<String>,
    /// The suite's quick variant (2 trials, one feature per terrain kind, one bisection round).
    #[arg(long, requires = "suite")]
    pub quick: bool,
    /// Trials (robots) per test point of the suite (default 10; quick 2).
    #[arg(long, requires = "suite")]
    pub trials: Option<usize>,
    /// Seed of the suite.
    #[arg(long, default_value_t = 1, requires = "suite")]
    pub seed: u64,
    /// Length of each trial of the suite's terrain, step, beyond and friction tests, s
    /// (default 10, the protocol's): longer shows whether a slow climber gets there with time.
    #[arg(long, requires = "suite")]
    pub terrain_duration_s: Option<f32>,
    /// Range of friction coefficients of the feet's contacts with the ground the suite's
    /// robots draw from, `LO,HI` (default 0.6,1.2; the paper's simulator met its ground at
    /// 0.55,1.75: foot friction [0.1, 2.5] averaged with the ground's 1.0).
    #[arg(long, requires = "suite", value_delimiter = ',', num_args = 1)]
    pub contact_friction: Option<Vec<f32>>,
    /// Cell of the suite's course height grid, m (default 0.05). The grid draws each riser
    /// as a ramp one cell wide (a 20 cm riser leans at 76 deg on 5 cm cells, 83 deg on
    /// 0.025); real risers, and legged_gym's, are vertical.
    #[arg(long, requires = "suite")]
    pub course_cell_m: Option<f32>,
    /// Environment override (`sim` or `fake`).
    #[arg(long, value_parser = ["sim", "fake"])]
    pub env: Option<String>,
    /// Also run the terrain test for a policy trained on flat ground (it always runs for a
    /// policy trained on terrain tiles).
    #[arg(long)]
    pub terrain: bool,
    /// Robots per tile kind in the terrain test.
    #[arg(long, default_value_t = 4)]
    pub terrain_robots: usize,
    /// Also write a rerun recording of the first robot at every command, one after another
    /// on its `sim_time` timeline, beside the report (`<report>.rrd`; view it with `rerun
    /// <file>`). Needs the simulator and a build with the `rerun` feature
    /// (`cargo run --release -p host-train --features rerun --bin hexapod -- eval ...`).
    #[arg(long, conflicts_with = "suite")]
    pub rerun: bool,
    /// Evaluate these commands instead of the default set, each `VX,VY,WZ` (m/s, m/s,
    /// rad/s); repeat it for several, e.g. a speed sweep `--command 0.2,0,0 --command
    /// 0.3,0,0`.
    #[arg(long, value_parser = parse_command, conflicts_with = "suite", allow_hyphen_values = true)]
    pub command: Vec<[f32; 3]>,
    /// Sample the actions from the policy's distribution, as in training, instead of taking
    /// its mean (the tracking measurement only; the push and terrain tests stay
    /// deterministic).
    #[arg(long, conflicts_with = "suite")]
    pub stochastic: bool,
}

/// Parses a `VX,VY,WZ` command of `--command` (eval's and play's).
pub fn parse_command(text: &str) -> Result<[f32; 3], String> {
    let parts: Vec<&str> = text.split(',').map(str::trim).collect();
    let [vx, vy, wz] = parts.as_slice() else {
        return Err(format!(
            "`{text}`: a command is three comma-separated numbers VX,VY,WZ (m/s, m/s, rad/s)"
        ));
    };
    let mut command = [0.0f32; 3];
    for (value, (part, name)) in command.iter_mut().zip([(vx, "VX"), (vy, "VY"), (wz, "WZ")]) {
        *value = part
            .parse::<f32>()
            .ok()
            .filter(|v| v.is_finite())
            .ok_or_else(|| format!("`{text}`: {name} `{part}` is not a finite number"))?;
    }
    Ok(command)
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
    /// Fraction of steps with k = 0..=6 feet on the ground.
    pub feet_down_fraction: [f64; 7],
    /// Each leg's fraction of steps in stance (its duty factor), legs in joint order (RF,
    /// RM, RR, LF, LM, LR): a tripod gait has six alike, a leg that never lifts shows 1.
    pub stance_fraction_per_leg: [f64; NUM_LEGS],
    /// Error of the mean speed along the command, percent of the commanded speed (the yaw
    /// rate for a pure turn): how well the average gait tracks, without the within-stride
    /// oscillation that `lin_vel_error_m_s` includes.
    pub speed_error_pct: f64,
    /// Error of the median speed along the command (of the samples' speeds along it, the
    /// yaw rate for a pure turn), percent of the commanded speed. Against
    /// `speed_error_pct`, the skew of the speed within a stride: the norm tracking kernel
    /// (`exp(-|e| / sigma)`) pays most where the median speed meets the command, the
    /// squared one where the mean does.
    pub median_speed_error_pct: f64,
    /// Mean of the estimator's planar velocity estimate over the same samples as
    /// `mean_velocity` (absent without an estimator): against `mean_velocity`, the
    /// estimator's bias at this command.
    pub mean_estimated_velocity: Option<[f64; 2]>,
    /// The trained discriminator's verdict on the gait at this command and the speed it
    /// associates with it ([`crate::cli::style_probe`]; absent without AMP).
    pub style: Option<StyleProbe>,
}

/// The push test: robots walk at a fixed command for a full episode and are shoved at a
/// fixed speed in random horizontal directions at a fixed interval.
#[derive(Debug, Serialize)]
pub struct PushTestResult {
    /// Command (vx, vy, wz).
    pub command: [f32; 3],
    /// Speed change of every push, m/s.
    pub push_m_s: f32,
    /// Time between pushes, s (the first one after half an interval).
    pub interval_s: f32,
    /// Test length, s.
    pub duration_s: f32,
    /// Pushes each robot received.
    pub pushes_per_robot: usize,
    /// Robots tested.
    pub robots: usize,
    /// Fraction of robots that fell (terminated) at least once.
    pub fall_rate: f64,
    /// Mean forward speed over the test, m/s.
    pub mean_vx_m_s: f64,
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
    /// The push test (simulator only).
    pub push_test: Option<PushTestResult>,
    /// The terrain test (simulator only; policies trained on tiles, or on request).
    pub terrain_test: Option<TerrainWalkResult>,
}

/// Speed change of the push test's pushes, m/s.
pub const PUSH_TEST_M_S: f32 = 0.5;
/// Time between the push test's pushes, s.
pub const PUSH_TEST_INTERVAL_S: f32 = 4.0;
/// Length of the push test (one full training episode), s.
pub const PUSH_TEST_DURATION_S: f32 = 20.0;
/// Command of the push test.
pub const PUSH_TEST_COMMAND: [f32; 3] = [0.3, 0.0, 0.0];

/// Percent error of the mean velocity along the command (yaw rate for a pure turn).
pub fn speed_error_pct(command: [f32; 3], mean_velocity: [f64; 3]) -> f64 {
    match (
        along_command(command, mean_velocity),
        commanded_speed(command),
    ) {
        (Some(along), Some(speed)) => 100.0 * (along - speed).abs() / speed.abs(),
        _ => f64::NAN,
    }
}

/// The commanded speed [`along_command`] measures against: the planar speed of a linear
/// command, the yaw rate of a pure turn, `None` for standing.
fn commanded_speed(command: [f32; 3]) -> Option<f64> {
    along_command(command, command.map(|c| c as f64))
}

/// A velocity `(vx, vy, wz)` projected on the command's axis: the planar velocity along a
/// linear command (m/s), the yaw rate for a pure turn (rad/s), `None` for standing.
pub fn along_command(command: [f32; 3], velocity: [f64; 3]) -> Option<f64> {
    let c = [command[0] as f64, command[1] as f64, command[2] as f64];
    let speed = (c[0] * c[0] + c[1] * c[1]).sqrt();
    if speed > 1e-6 {
        Some((velocity[0] * c[0] + velocity[1] * c[1]) / speed)
    } else if c[2].abs() > 1e-6 {
        Some(velocity[2])
    } else {
        None
    }
}

/// The median of `values` (NaN for none); sorts them.
fn median(values: &mut [f64]) -> f64 {
    if values.is_empty() {
        return f64::NAN;
    }
    values.sort_by(f64::total_cmp);
    let mid = values.len() / 2;
    if values.len() % 2 == 1 {
        values[mid]
    } else {
        0.5 * (values[mid - 1] + values[mid])
    }
}

/// Runs the push test on the simulator with the environment's own random pushes off.
fn push_test(
    cfg: &crate::config::TrainConfig,
    ppo: &mut crate::algo::ppo::Ppo,
    n: usize,
) -> anyhow::Result<PushTestResult> {
    use host_sim::vec_env::VecEnv;
    use rand::{Rng, SeedableRng};
    let mut sim = cfg.resolved_sim();
    sim.num_envs = n;
    sim.push.enabled = false;
    sim.episode_length_s = PUSH_TEST_DURATION_S + 1.0;
    let mut env = host_sim::env::HexapodEnv::new(sim)?;
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(cfg.env.seed ^ 0x9e37);
    let dt = hexapod_core::timing::POLICY_DT_S;
    let steps = (PUSH_TEST_DURATION_S / dt).round() as usize;
    let every = (PUSH_TEST_INTERVAL_S / dt).round() as usize;
    for i in 0..n {
        env.set_command(i, PUSH_TEST_COMMAND);
    }
    let mut obs = env.reset();
    let (mut fell, mut pushes, mut vx, mut samples) = (vec![false; n], 0usize, 0.0f64, 0usize);
    for step in 0..steps {
        if step >= every / 2 && (step - every / 2).is_multiple_of(every) {
            for i in 0..n {
                let angle: f32 = rng.gen_range(0.0..std::f32::consts::TAU);
                env.push(
                    i,
                    [
                        PUSH_TEST_M_S * angle.cos(),
                        PUSH_TEST_M_S * angle.sin(),
                        0.0,
                    ],
                );
            }
            pushes += 1;
        }
        let act = ppo.act(&obs, true)?;
        let res = env.step(&act.actions);
        for i in 0..n {
            vx += (obs.privileged[i * PRIVILEGED_DIM + PRIV_LIN_VEL.start] / LIN_VEL_SCALE) as f64;
            samples += 1;
            fell[i] |= res.dones[i] && !res.time_outs[i];
        }
        obs = res.obs;
    }
    Ok(PushTestResult {
        command: PUSH_TEST_COMMAND,
        push_m_s: PUSH_TEST_M_S,
        interval_s: PUSH_TEST_INTERVAL_S,
        duration_s: PUSH_TEST_DURATION_S,
        pushes_per_robot: pushes,
        robots: n,
        fall_rate: fell.iter().filter(|&&f| f).count() as f64 / n as f64,
        mean_vx_m_s: vx / samples.max(1) as f64,
    })
}

/// Stance mask (bit i = leg i) from a privileged state row.
pub fn contact_mask(privileged: &[f32]) -> u8 {
    let mut mask = 0u8;
    for leg in 0..NUM_LEGS {
        let f = &privileged
            [PRIV_CONTACT_FORCES.start + 3 * leg..PRIV_CONTACT_FORCES.start + 3 * leg + 3];
        let norm_n = (f[0] * f[0] + f[1] * f[1] + f[2] * f[2]).sqrt() / CONTACT_FORCE_SCALE;
        if norm_n > CONTACT_THRESHOLD_N {
            mask |= 1 << leg;
        }
    }
    mask
}

/// An environment the tracking measurement drives: the trainer's [`VecEnv`]s, or the
/// MuJoCo environment, whose steps can fail.
pub trait TrackEnv {
    /// Number of robots.
    fn num_envs(&self) -> usize;
    /// Fixes robot `i`'s command (rewards and the next observations carry it).
    fn set_command(&mut self, i: usize, command: [f32; 3]);
    /// Resets all robots.
    fn reset(&mut self) -> anyhow::Result<Observations>;
    /// One policy step.
    fn step(&mut self, actions: &[f32]) -> anyhow::Result<StepResult>;
    /// The rapier simulator behind it, if it is one (what a recording draws).
    fn sim(&self) -> Option<&host_sim::env::HexapodEnv> {
        None
    }
}

impl TrackEnv for PlayEnv {
    fn num_envs(&self) -> usize {
        match self {
            PlayEnv::Sim(env) => VecEnv::num_envs(env),
            PlayEnv::Other(env) => env.num_envs(),
        }
    }
    fn set_command(&mut self, i: usize, command: [f32; 3]) {
        self.env().set_command(i, command)
    }
    fn reset(&mut self) -> anyhow::Result<Observations> {
        Ok(self.env().reset())
    }
    fn step(&mut self, actions: &[f32]) -> anyhow::Result<StepResult> {
        Ok(self.env().step(actions))
    }
    fn sim(&self) -> Option<&host_sim::env::HexapodEnv> {
        match self {
            PlayEnv::Sim(env) => Some(env),
            PlayEnv::Other(_) => None,
        }
    }
}

impl TrackEnv for Box<dyn VecEnv> {
    fn num_envs(&self) -> usize {
        VecEnv::num_envs(self.as_ref())
    }
    fn set_command(&mut self, i: usize, command: [f32; 3]) {
        VecEnv::set_command(self.as_mut(), i, command)
    }
    fn reset(&mut self) -> anyhow::Result<Observations> {
        Ok(VecEnv::reset(self.as_mut()))
    }
    fn step(&mut self, actions: &[f32]) -> anyhow::Result<StepResult> {
        Ok(VecEnv::step(self.as_mut(), actions))
    }
}

impl TrackEnv for MujocoEnv {
    fn num_envs(&self) -> usize {
        1
    }
    fn set_command(&mut self, _i: usize, command: [f32; 3]) {
        MujocoEnv::set_command(self, command)
    }
    fn reset(&mut self) -> anyhow::Result<Observations> {
        MujocoEnv::reset(self)
    }
    fn step(&mut self, actions: &[f32]) -> anyhow::Result<StepResult> {
        MujocoEnv::step(self, actions)
    }
}

/// The estimator's error against the true base velocity, summed over samples.
#[derive(Debug, Default, Clone, Copy)]
pub struct EstimatorError {
    sum_sq_m2_s2: f64,
    samples: usize,
}

impl EstimatorError {
    /// RMS error per velocity component, m/s (NaN without samples: no estimator).
    pub fn rms_m_s(&self) -> f64 {
        if self.samples > 0 {
            (self.sum_sq_m2_s2 / self.samples as f64).sqrt()
        } else {
            f64::NAN
        }
    }
}

/// Runs every robot of `env` from a reset at `command` for `steps` policy steps with the
/// deterministic policy and measures tracking, falls, the tripod score and feet down
/// (after [`SETTLE_STEPS`]); adds the estimator's error to `estimator`. With
/// `stochastic`, the actions are sampled as in training.
#[allow(clippy::too_many_arguments)]
pub fn track_command(
    env: &mut dyn TrackEnv,
    ppo: &mut Ppo,
    command: [f32; 3],
    stochastic: bool,
    steps: usize,
    estimator: &mut EstimatorError,
    mut recording: Option<(&mut Recording, f32)>,
) -> anyhow::Result<CommandResult> {
    let n = env.num_envs();
    for i in 0..n {
        env.set_command(i, command);
    }
    let mut obs = env.reset()?;
    let mut fell = vec![false; n];
    let (mut lin_err, mut yaw_err, mut mean_v, mut samples) = (0.0f64, 0.0f64, [0.0f64; 3], 0usize);
    let (mut tripod, mut contact_samples) = (0usize, 0usize);
    let mut feet_down = [0usize; 7];
    let mut leg_stance = [0usize; NUM_LEGS];
    let (mut mean_estimate, mut estimator_seen) = ([0.0f64; 2], false);
    let (mut amp_states, mut amp_next_states) = (Vec::new(), Vec::new());
    let mut speeds_along = Vec::new();
    for step in 0..steps {
        let act = ppo.act(&obs, !stochastic)?;
        if let (Some((rec, t0_s)), Some(sim)) = (recording.as_mut(), env.sim()) {
            let p = &obs.privileged[..PRIVILEGED_DIM];
            let measured = [
                p[PRIV_LIN_VEL.start] / LIN_VEL_SCALE,
                p[PRIV_LIN_VEL.start + 1] / LIN_VEL_SCALE,
                obs.amp[AMP_BASE_ANG_VEL.start + 2],
            ];
            let t_s = *t0_s + step as f32 * POLICY_DT_S;
            rec.record(
                sim.robot_world(0),
                &sim.contacts(0),
                t_s,
                command,
                measured,
                p[PRIV_BASE_HEIGHT],
            );
        }
        let res = env.step(&act.actions)?;
        for i in 0..n {
            let p = &obs.privileged[i * PRIVILEGED_DIM..(i + 1) * PRIVILEGED_DIM];
            if step >= SETTLE_STEPS {
                let v = [
                    p[PRIV_LIN_VEL.start] / LIN_VEL_SCALE,
                    p[PRIV_LIN_VEL.start + 1] / LIN_VEL_SCALE,
                    obs.amp[i * AMP_STATE_DIM + AMP_BASE_ANG_VEL.start + 2],
                ];
                lin_err +=
                    (((v[0] - command[0]).powi(2) + (v[1] - command[1]).powi(2)) as f64).sqrt();
                yaw_err += (v[2] - command[2]).abs() as f64;
                if let Some(along) = along_command(command, v.map(|x| x as f64)) {
                    speeds_along.push(along);
                }
                for k in 0..3 {
                    mean_v[k] += v[k] as f64;
                }
                if !act.estimate.is_empty() {
                    estimator_seen = true;
                    for k in 0..2 {
                        mean_estimate[k] += (act.estimate[i * 3 + k] / LIN_VEL_SCALE) as f64;
                    }
                }
                samples += 1;
                let mask = contact_mask(p);
                tripod += usize::from(mask == TRIPOD_A_MASK || mask == TRIPOD_B_MASK);
                feet_down[mask.count_ones() as usize] += 1;
                for (leg, n) in leg_stance.iter_mut().enumerate() {
                    *n += usize::from(mask & (1 << leg) != 0);
                }
                contact_samples += 1;
            }
            if !act.estimate.is_empty() {
                for k in 0..3 {
                    let e = (act.estimate[i * 3 + k] - p[PRIV_LIN_VEL.start + k]) / LIN_VEL_SCALE;
                    estimator.sum_sq_m2_s2 += (e * e) as f64;
                    estimator.samples += 1;
                }
            }
            if step >= SETTLE_STEPS
                && step.is_multiple_of(STYLE_PROBE_EVERY_STEPS)
                && !res.dones[i]
                && !obs.amp.is_empty()
            {
                let row = i * AMP_STATE_DIM..(i + 1) * AMP_STATE_DIM;
                amp_states.extend_from_slice(&obs.amp[row.clone()]);
                amp_next_states.extend_from_slice(&res.obs.amp[row]);
            }
            if res.dones[i] && !res.time_outs[i] {
                fell[i] = true;
            }
        }
        obs = res.obs;
    }
    let s = samples.max(1) as f64;
    let mean_velocity = [mean_v[0] / s, mean_v[1] / s, mean_v[2] / s];
    let style = match &ppo.disc {
        Some(disc) => style_probe::probe(disc, command, &amp_states, &amp_next_states)?,
        None => None,
    };
    Ok(CommandResult {
        style,
        command,
        lin_vel_error_m_s: lin_err / s,
        yaw_rate_error_rad_s: yaw_err / s,
        mean_velocity,
        speed_error_pct: speed_error_pct(command, mean_velocity),
        median_speed_error_pct: match commanded_speed(command) {
            Some(speed) => 100.0 * (median(&mut speeds_along) - speed).abs() / speed.abs(),
            None => f64::NAN,
        },
        fall_rate: fell.iter().filter(|&&f| f).count() as f64 / n as f64,
        tripod_score: tripod as f64 / contact_samples.max(1) as f64,
        feet_down_fraction: feet_down.map(|k| k as f64 / contact_samples.max(1) as f64),
        stance_fraction_per_leg: leg_stance.map(|k| k as f64 / contact_samples.max(1) as f64),
        mean_estimated_velocity: estimator_seen.then(|| mean_estimate.map(|e| e / s)),
    })
}

/// The header of the per-command table.
pub fn table_header() -> String {
    format!(
        "{:>22} {:>12} {:>12} {:>24} {:>10} {:>11} {:>10} {:>10}  {}",
        "command (vx,vy,wz)",
        "lin err m/s",
        "yaw err r/s",
        "mean (vx,vy,wz)",
        "speed err",
        "median err",
        "fall rate",
        "tripod",
        "stance % RF RM RR LF LM LR"
    )
}

/// One command's row of the table.
pub fn table_row(r: &CommandResult) -> String {
    format!(
        "{:>22} {:>12.3} {:>12.3} {:>24} {:>9.0}% {:>10.0}% {:>10.2} {:>10.2}  {}",
        format!(
            "({:.2},{:.2},{:.2})",
            r.command[0], r.command[1], r.command[2]
        ),
        r.lin_vel_error_m_s,
        r.yaw_rate_error_rad_s,
        format!(
            "({:+.2},{:+.2},{:+.2})",
            r.mean_velocity[0], r.mean_velocity[1], r.mean_velocity[2]
        ),
        r.speed_error_pct,
        r.median_speed_error_pct,
        r.fall_rate,
        r.tripod_score,
        r.stance_fraction_per_leg
            .map(|f| format!("{:>2.0}", 100.0 * f))
            .join(" ")
    )
}

/// Runs `hexapod eval`.
pub fn run(args: EvalArgs) -> anyhow::Result<()> {
    if args.rerun {
        require_rerun("eval")?;
    }
    if let Some(suite) = &args.suite {
        return crate::cli::suite::run(&crate::cli::suite::SuiteOptions {
            suite: suite.clone(),
            checkpoints: args
                .checkpoint
                .iter()
                .map(|c| crate::checkpoint::resolve_dir(c))
                .collect::<Result<Vec<_>, _>>()?,
            mpc: args.mpc.clone(),
            out: args.out.clone().expect("clap requires --out with --suite"),
            protocols: args.protocol.clone(),
            quick: args.quick,
            trials: args.trials,
            seed: args.seed,
            terrain_duration_s: args.terrain_duration_s,
            contact_friction: args.contact_friction.clone(),
            course_cell_m: args.course_cell_m,
        });
    }
    let [checkpoint] = args.checkpoint.as_slice() else {
        anyhow::bail!("give one --checkpoint (several are compared only with --suite)");
    };
    let checkpoint = crate::checkpoint::resolve_dir(checkpoint)?;
    anyhow::ensure!(
        args.steps > SETTLE_STEPS,
        "--steps {} leaves nothing to measure: the first {SETTLE_STEPS} steps ({:.1} s) are the settle time",
        args.steps,
        SETTLE_STEPS as f32 * hexapod_core::timing::POLICY_DT_S
    );
    let (mut cfg, mut ppo) = load_for_inference(&checkpoint)?;
    cfg.env.num_envs = args.num_envs;
    if let Some(kind) = &args.env {
        cfg.env.kind = if kind == "fake" {
            EnvKind::Fake
        } else {
            EnvKind::Sim
        };
    }
    let mut env = PlayEnv::new(&cfg)?;
    let mut recording = match (&env, args.rerun) {
        (PlayEnv::Sim(sim), true) => Some(Recording::new(sim.robot_world(0))),
        (PlayEnv::Other(_), true) => anyhow::bail!(
            "--rerun records the simulator's robot, not the stand-in (env.kind = \"fake\")"
        ),
        (_, false) => None,
    };
    let n = args.num_envs;
    let mut results = Vec::new();
    let mut estimator = EstimatorError::default();
    let commands = if args.command.is_empty() {
        EVAL_COMMANDS.to_vec()
    } else {
        args.command.clone()
    };
    for (c, command) in commands.into_iter().enumerate() {
        let t0_s = (c * args.steps) as f32 * POLICY_DT_S;
        if let Some(rec) = &mut recording {
            let [vx, vy, wz] = command;
            rec.start_segment(
                t0_s,
                format!("command vx {vx} m/s, vy {vy} m/s, wz {wz} rad/s (robot 0)"),
            );
        }
        let segment = recording.as_mut().map(|rec| (rec, t0_s));
        results.push(track_command(
            &mut env,
            &mut ppo,
            command,
            args.stochastic,
            args.steps,
            &mut estimator,
            segment,
        )?);
    }
    let m = results.len() as f64;
    let push = if cfg.env.kind == EnvKind::Sim {
        Some(push_test(&cfg, &mut ppo, n)?)
    } else {
        None
    };
    let on_tiles = cfg.resolved_sim().terrain.tiles;
    let terrain = if cfg.env.kind == EnvKind::Sim && (args.terrain || on_tiles) {
        Some(terrain_walk(&cfg, &mut ppo, args.terrain_robots)?)
    } else {
        None
    };
    let report = EvalReport {
        push_test: push,
        terrain_test: terrain,
        checkpoint: checkpoint.display().to_string(),
        env: format!("{:?}", cfg.env.kind).to_lowercase(),
        num_envs: n,
        steps: args.steps,
        mean_lin_vel_error_m_s: results.iter().map(|r| r.lin_vel_error_m_s).sum::<f64>() / m,
        mean_fall_rate: results.iter().map(|r| r.fall_rate).sum::<f64>() / m,
        mean_tripod_score: results.iter().map(|r| r.tripod_score).sum::<f64>() / m,
        estimator_error_m_s: estimator.rms_m_s(),
        commands: results,
    };
    println!("{}", table_header());
    for r in &report.commands {
        println!("{}", table_row(r));
    }
    for r in &report.commands {
        if let Some(p) = &r.style {
            println!("{}", style_probe::describe(r.command, p));
        }
    }
    if let Some(p) = &report.push_test {
        println!(
            "push test: {} robots at ({:.1},{:.1},{:.1}) for {:.0} s, {} pushes of {:.1} m/s each: fall rate {:.2}, mean vx {:.3} m/s",
            p.robots, p.command[0], p.command[1], p.command[2], p.duration_s, p.pushes_per_robot, p.push_m_s, p.fall_rate, p.mean_vx_m_s
        );
    }
    if let Some(t) = &report.terrain_test {
        crate::cli::terrain_walk::print(t);
    }
    println!(
        "mean: lin err {:.3} m/s, fall rate {:.2}, tripod score {:.2}, estimator error {:.3} m/s",
        report.mean_lin_vel_error_m_s,
        report.mean_fall_rate,
        report.mean_tripod_score,
        report.estimator_error_m_s
    );
    let out = args.out.clone().unwrap_or_else(|| {
        PathBuf::from("runs/eval").join(format!(
            "{}.json",
            crate::checkpoint::display_name(&checkpoint)
        ))
    });
    if let Some(dir) = out.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    }
    std::fs::write(&out, serde_json::to_string_pretty(&report)?)
        .with_context(|| format!("writing {}", out.display()))?;
    eprintln!("report: {}", out.display());
    if let (Some(rec), PlayEnv::Sim(sim)) = (&recording, &env) {
        let path = out.with_extension("rrd");
        rec.save(&path, sim.terrain())?;
        eprintln!("rerun recording: {}", path.display());
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn commands_parse_or_say_what_is_wrong() {
        assert_eq!(parse_command("0.3,0,-0.5"), Ok([0.3, 0.0, -0.5]));
        assert_eq!(parse_command(" -0.2, 0.1 ,0"), Ok([-0.2, 0.1, 0.0]));
        assert!(parse_command("0.3,0").unwrap_err().contains("three"));
        assert!(parse_command("0.3,x,0").unwrap_err().contains("VY `x`"));
        assert!(parse_command("0.3,0,nan").unwrap_err().contains("WZ"));
    }

    #[test]
    fn speed_error_is_along_the_command() {
        assert!((speed_error_pct([0.3, 0.0, 0.0], [0.24, 0.1, 0.0]) - 20.0).abs() < 1e-4);
        assert!((speed_error_pct([0.0, -0.2, 0.0], [0.0, -0.3, 0.0]) - 50.0).abs() < 1e-4);
        assert!((speed_error_pct([0.0, 0.0, 0.5], [0.0, 0.0, 0.4]) - 20.0).abs() < 1e-4);
        assert!(speed_error_pct([0.0; 3], [0.1; 3]).is_nan());
        assert_eq!(
            along_command([0.0, 0.0, -0.5], [0.1, 0.2, -0.6]),
            Some(-0.6)
        );
        assert_eq!(along_command([0.0; 3], [0.1; 3]), None);
    }

    #[test]
    fn the_median_of_a_skewed_speed_sits_below_its_mean() {
        // A stride of three slow samples and one fast burst: mean 0.35, median 0.3.
        let mut speeds = [0.3, 0.5, 0.3, 0.3];
        assert!((median(&mut speeds) - 0.3).abs() < 1e-12);
        assert!((median(&mut [0.4, 0.1, 0.2]) - 0.2).abs() < 1e-12);
        assert!(median(&mut []).is_nan());
    }

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
