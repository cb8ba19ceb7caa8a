//! Simulator tracking of the priors: the clip is replayed in the simulator, its drives
//! tracking the clip's joint trajectories (CSP law, no feedforward), and the robot must stay
//! upright and walk at the commanded velocity.
//!
//! The robot starts in the clip's first pose, settles for `settle_s` holding it, then plays
//! `cycles` gait cycles; targets are linearly interpolated between frames at the physics
//! rate. Velocities are averaged in the base frame after `warmup_cycles`. The AMP states of
//! the replay are computed by `hexapod_core::amp::amp_state`, the function that makes the
//! clip's states, and compared frame by frame.
//!
//! Played as is, the clip's joint trajectories are followed with the drives' lag and sag
//! (the loaded stance legs bend: the base walks about 2.5 cm low, feet land early). With
//! `learning_passes` the replay learns a correction of the targets first, by iterative
//! learning control on the periodic motion (Arimoto et al., 1984; Bristow et al., "A survey
//! of iterative learning control", IEEE CSM 2006): after each pass, every frame's targets
//! move by `learning_gain` times the joint error the pass measured at that phase (mean over
//! the recorded cycles), within the joint limits. The recorded pass is the last one, so the
//! states are still the simulated robot's own, with joints closer to the clip's.

use super::clip::MotionClip;
use hexapod_core::amp::{amp_state, AMP_JOINT_POS, AMP_STATE_DIM};
use hexapod_core::robot::{
    NUM_JOINTS, NUM_LEGS, Q_MAX_RAD, Q_MIN_RAD, TRIPOD_A_MASK, TRIPOD_B_MASK,
};
use hexapod_core::timing::DECIMATION;
use host_sim::frames::{rotate, rotate_inverse};
use host_sim::reference::ReferenceState;
use host_sim::robot::{RobotState, RobotWorld};

/// A simulated robot that can replay joint trajectories.
pub trait ReplayPlant {
    /// Places the robot at rest.
    fn reset(
        &mut self,
        base_pos_world_m: [f32; 3],
        base_quat_xyzw: [f32; 4],
        q_rad: &[f32; NUM_JOINTS],
    );
    /// One physics step with the drives tracking `q_target_rad`.
    fn step(&mut self, q_target_rad: &[f32; NUM_JOINTS]);
    /// The robot's state (velocities in the world frame).
    fn state(&self) -> RobotState;
    /// Feet in stance (bit i = leg i), by the rewards' and eval's contact-force threshold.
    fn stance_mask(&self) -> u8;
}

impl ReplayPlant for RobotWorld {
    fn reset(
        &mut self,
        base_pos_world_m: [f32; 3],
        base_quat_xyzw: [f32; 4],
        q_rad: &[f32; NUM_JOINTS],
    ) {
        RobotWorld::reset(self, base_pos_world_m, base_quat_xyzw, q_rad);
    }

    fn step(&mut self, q_target_rad: &[f32; NUM_JOINTS]) {
        RobotWorld::step(self, q_target_rad);
    }

    fn state(&self) -> RobotState {
        RobotWorld::state(self)
    }

    fn stance_mask(&self) -> u8 {
        host_sim::rewards::stance_mask(&self.contacts().foot_force_world_n)
    }
}

/// Replay settings and pass criteria.
#[derive(Clone, Debug)]
pub struct ReplayConfig {
    /// Standing time in the first pose before playing, s.
    pub settle_s: f32,
    /// Gait cycles played.
    pub cycles: usize,
    /// Cycles ignored before averaging velocities.
    pub warmup_cycles: usize,
    /// Allowed relative velocity error (0.25: within 25 % of the command).
    pub rel_tolerance: f32,
    /// Planar velocity tolerance when no planar velocity is commanded, m/s.
    pub zero_lin_tolerance_m_s: f32,
    /// Yaw-rate tolerance when no yaw rate is commanded, rad/s.
    pub zero_yaw_tolerance_rad_s: f32,
    /// Largest tilt of the base z axis from vertical, rad.
    pub max_tilt_rad: f32,
    /// Lowest base height, m.
    pub min_height_m: f32,
    /// Passes of iterative learning control before the recorded one (0: the clip's joint
    /// trajectories played as they are).
    pub learning_passes: usize,
    /// Share of a pass's joint error added to the targets for the next pass.
    pub learning_gain: f32,
}

impl Default for ReplayConfig {
    fn default() -> Self {
        Self {
            settle_s: 0.5,
            cycles: 5,
            warmup_cycles: 1,
            rel_tolerance: 0.25,
            zero_lin_tolerance_m_s: 0.05,
            zero_yaw_tolerance_rad_s: 0.1,
            max_tilt_rad: 0.35,
            min_height_m: 0.15,
            learning_passes: 0,
            learning_gain: 0.5,
        }
    }
}

/// What a replay measured.
#[derive(Clone, Debug)]
pub struct ReplayReport {
    /// Clip name.
    pub name: String,
    /// Commanded (vx, vy, wz).
    pub command: [f32; 3],
    /// Mean base-frame (vx, vy) and yaw rate after the warm-up.
    pub mean_velocity: [f32; 3],
    /// Planar velocity error `|v_xy - v_cmd|`, m/s.
    pub lin_error_m_s: f32,
    /// Its tolerance, m/s.
    pub lin_tolerance_m_s: f32,
    /// Yaw-rate error, rad/s.
    pub yaw_error_rad_s: f32,
    /// Its tolerance, rad/s.
    pub yaw_tolerance_rad_s: f32,
    /// Largest tilt of the base from vertical, rad.
    pub max_tilt_rad: f32,
    /// Lowest base height, m.
    pub min_height_m: f32,
    /// Mean base height, m (the clip's mean for comparison in `clip_height_m`).
    pub mean_height_m: f32,
    /// The clip's mean base height, m.
    pub clip_height_m: f32,
    /// RMS difference of joint positions between replay and clip at equal phase, rad.
    pub joint_rms_rad: f32,
    /// Fraction of policy steps after the warm-up with 0..=6 feet in stance (eval's
    /// feet-down histogram).
    pub feet_down_fraction: [f32; 7],
    /// Fraction of those steps whose stance set is exactly one tripod (eval's tripod score).
    pub tripod_score: f32,
    /// The same score by the clip's own contact flags: the most the replay can reach.
    pub clip_tripod_score: f32,
    /// RMS joint error of each pass of iterative learning control, then of the recorded
    /// pass (its last entry is `joint_rms_rad`), rad.
    pub joint_rms_per_pass_rad: Vec<f32>,
    /// True when upright and within the velocity tolerances.
    pub passed: bool,
    /// The simulator's states at every policy step after the warm-up: the clip as the
    /// simulated robot performs it (the reachable reference motion).
    pub states: Vec<ReferenceState>,
}

impl ReplayReport {
    /// One line for the console.
    pub fn summary(&self) -> String {
        format!(
            "{:<28} {} cmd ({:+.2}, {:+.2}, {:+.2}) sim ({:+.3}, {:+.3}, {:+.3})  |dv| {:.3}/{:.3} m/s  |dw| {:.3}/{:.3} rad/s  tilt {:.3} rad  height min {:.3} mean {:.3} (clip {:.3}) m  joint rms {:.3} rad  tripod {:.2} (clip {:.2}), all feet down {:.2}",
            self.name,
            if self.passed { "PASS" } else { "FAIL" },
            self.command[0],
            self.command[1],
            self.command[2],
            self.mean_velocity[0],
            self.mean_velocity[1],
            self.mean_velocity[2],
            self.lin_error_m_s,
            self.lin_tolerance_m_s,
            self.yaw_error_rad_s,
            self.yaw_tolerance_rad_s,
            self.max_tilt_rad,
            self.min_height_m,
            self.mean_height_m,
            self.clip_height_m,
            self.joint_rms_rad,
            self.tripod_score,
            self.clip_tripod_score,
            self.feet_down_fraction[NUM_LEGS],
        )
    }
}

/// The AMP state the simulator sees in `s` (flat ground at z = 0), by the clip's function.
pub fn sim_amp_state(s: &RobotState) -> [f32; AMP_STATE_DIM] {
    let lin_vel = rotate_inverse(s.base_quat_xyzw, s.base_lin_vel_world_m_s);
    let ang_vel = rotate_inverse(s.base_quat_xyzw, s.base_ang_vel_world_rad_s);
    amp_state(
        &s.q_rad,
        &s.qdot_rad_s,
        lin_vel,
        ang_vel,
        rotate_inverse(s.base_quat_xyzw, [0.0, 0.0, 1.0]),
    )
}

/// The reference state of the simulator's state `s` (flat ground at z = 0).
pub fn sim_reference_state(s: &RobotState) -> ReferenceState {
    ReferenceState {
        q_rad: s.q_rad,
        qdot_rad_s: s.qdot_rad_s,
        lin_vel_base_m_s: rotate_inverse(s.base_quat_xyzw, s.base_lin_vel_world_m_s),
        ang_vel_base_rad_s: rotate_inverse(s.base_quat_xyzw, s.base_ang_vel_world_rad_s),
        up_base: rotate_inverse(s.base_quat_xyzw, [0.0, 0.0, 1.0]),
        base_height_m: s.base_pos_world_m[2],
    }
}

/// `rel * magnitude`, or `zero_tol` when nothing is commanded.
fn tolerance(magnitude: f32, rel: f32, zero_tol: f32) -> f32 {
    if magnitude > 1e-6 {
        rel * magnitude
    } else {
        zero_tol
    }
}

/// True when exactly one tripod is in stance.
fn is_tripod(stance_mask: u8) -> bool {
    stance_mask == TRIPOD_A_MASK || stance_mask == TRIPOD_B_MASK
}

/// Replays `clip` on `plant` and checks it, after `cfg.learning_passes` passes of
/// iterative learning control on the targets.
pub fn replay_clip<P: ReplayPlant>(
    plant: &mut P,
    clip: &MotionClip,
    cfg: &ReplayConfig,
) -> ReplayReport {
    let mut targets: Vec<[f32; NUM_JOINTS]> = clip.frames.iter().map(|f| f.joint_pos_rad).collect();
    let mut rms_per_pass = Vec::with_capacity(cfg.learning_passes + 1);
    for _ in 0..cfg.learning_passes {
        let (report, mean_q) = replay_pass(plant, clip, cfg, &targets);
        rms_per_pass.push(report.joint_rms_rad);
        for (p, target) in targets.iter_mut().enumerate() {
            let clip_q = &clip.frames[p].joint_pos_rad;
            for j in 0..NUM_JOINTS {
                let corrected = target[j] + cfg.learning_gain * (clip_q[j] - mean_q[p][j]);
                target[j] = corrected.clamp(Q_MIN_RAD[j], Q_MAX_RAD[j]);
            }
        }
    }
    let (mut report, _) = replay_pass(plant, clip, cfg, &targets);
    rms_per_pass.push(report.joint_rms_rad);
    report.joint_rms_per_pass_rad = rms_per_pass;
    report
}

/// One replay of `clip` with these per-frame joint targets; also returns the mean joint
/// positions the robot reached at each frame's phase over the recorded cycles.
fn replay_pass<P: ReplayPlant>(
    plant: &mut P,
    clip: &MotionClip,
    cfg: &ReplayConfig,
    frame_targets: &[[f32; NUM_JOINTS]],
) -> (ReplayReport, Vec<[f32; NUM_JOINTS]>) {
    let n = clip.frames.len();
    let first = &clip.frames[0];
    plant.reset(
        first.base_pos_world_m,
        first.base_quat_xyzw,
        &first.joint_pos_rad,
    );
    let physics_dt_s = clip.frame_duration_s / DECIMATION as f32;
    let settle_steps = (cfg.settle_s / physics_dt_s).round() as usize;
    for _ in 0..settle_steps {
        plant.step(&frame_targets[0]);
    }
    let mut sum_q = vec![[0.0f32; NUM_JOINTS]; n];
    let mut phase_count = vec![0usize; n];
    let clip_states = clip.amp_states();
    let (mut sum_v, mut count) = ([0.0f32; 3], 0usize);
    let (mut max_tilt, mut min_height, mut sum_height) = (0.0f32, f32::MAX, 0.0f32);
    let (mut joint_sq, mut joint_count) = (0.0f32, 0usize);
    let mut feet_down = [0usize; NUM_LEGS + 1];
    let mut tripod = 0usize;
    let mut states = Vec::with_capacity((cfg.cycles - cfg.warmup_cycles.min(cfg.cycles)) * n);
    for k in 0..cfg.cycles * n {
        let (a, b) = (&frame_targets[k % n], &frame_targets[(k + 1) % n]);
        for sub in 0..DECIMATION {
            let u = (sub + 1) as f32 / DECIMATION as f32;
            let target: [f32; NUM_JOINTS] = std::array::from_fn(|j| a[j] + u * (b[j] - a[j]));
            plant.step(&target);
        }
        let s = plant.state();
        let up = rotate(s.base_quat_xyzw, [0.0, 0.0, 1.0]);
        max_tilt = max_tilt.max(up[2].clamp(-1.0, 1.0).acos());
        min_height = min_height.min(s.base_pos_world_m[2]);
        if k >= cfg.warmup_cycles * n {
            let amp = sim_amp_state(&s);
            let v = &amp[hexapod_core::amp::AMP_BASE_LIN_VEL];
            let w = &amp[hexapod_core::amp::AMP_BASE_ANG_VEL];
            sum_v[0] += v[0];
            sum_v[1] += v[1];
            sum_v[2] += w[2];
            sum_height += s.base_pos_world_m[2];
            count += 1;
            feet_down[plant.stance_mask().count_ones() as usize] += 1;
            tripod += usize::from(is_tripod(plant.stance_mask()));
            states.push(sim_reference_state(&s));
            let phase = (k + 1) % n;
            for j in 0..NUM_JOINTS {
                sum_q[phase][j] += s.q_rad[j];
            }
            phase_count[phase] += 1;
            let reference = &clip_states[phase];
            for j in AMP_JOINT_POS {
                joint_sq += (amp[j] - reference[j]).powi(2);
                joint_count += 1;
            }
        }
    }
    let mean = sum_v.map(|x| x / count.max(1) as f32);
    let cmd = clip.command;
    let lin_error = (mean[0] - cmd[0]).hypot(mean[1] - cmd[1]);
    let lin_tol = tolerance(
        cmd[0].hypot(cmd[1]),
        cfg.rel_tolerance,
        cfg.zero_lin_tolerance_m_s,
    );
    let yaw_error = (mean[2] - cmd[2]).abs();
    let yaw_tol = tolerance(
        cmd[2].abs(),
        cfg.rel_tolerance,
        cfg.zero_yaw_tolerance_rad_s,
    );
    let clip_height = clip.frames.iter().map(|f| f.base_height_m()).sum::<f32>() / n as f32;
    let mean_q = sum_q
        .iter()
        .zip(&phase_count)
        .zip(&clip.frames)
        .map(|((q, &c), frame)| match c {
            0 => frame.joint_pos_rad,
            c => q.map(|x| x / c as f32),
        })
        .collect();
    let report = ReplayReport {
        name: clip.name.clone(),
        command: cmd,
        mean_velocity: mean,
        lin_error_m_s: lin_error,
        lin_tolerance_m_s: lin_tol,
        yaw_error_rad_s: yaw_error,
        yaw_tolerance_rad_s: yaw_tol,
        max_tilt_rad: max_tilt,
        min_height_m: min_height,
        mean_height_m: sum_height / count.max(1) as f32,
        clip_height_m: clip_height,
        joint_rms_rad: (joint_sq / joint_count.max(1) as f32).sqrt(),
        feet_down_fraction: feet_down.map(|c| c as f32 / count.max(1) as f32),
        tripod_score: tripod as f32 / count.max(1) as f32,
        clip_tripod_score: clip
            .frames
            .iter()
            .filter(|f| {
                let mask = (0..NUM_LEGS)
                    .filter(|&l| f.contacts[l])
                    .fold(0u8, |m, l| m | 1 << l);
                is_tripod(mask)
            })
            .count() as f32
            / n as f32,
        joint_rms_per_pass_rad: Vec::new(),
        passed: lin_error <= lin_tol
            && yaw_error <= yaw_tol
            && max_tilt <= cfg.max_tilt_rad
            && min_height >= cfg.min_height_m,
        states,
    };
    (report, mean_q)
}
