//! Observation layouts, scales and noise, defined once for simulator, trainer and firmware.
//!
//! Scales and noise follow legged_gym: each raw quantity is multiplied by its scale; the
//! simulator adds uniform noise in `+-(noise * scale)` per entry (noise level 1). Clipping
//! at `+-OBS_CLIP` follows the scaling.

use crate::robot::{NUM_JOINTS, NUM_LEGS, Q0_RAD};
use core::ops::Range;
use nalgebra::Vector3;

// ---------------------------------------------------------------------------------------
// Scales (legged_gym's `normalization.obs_scales`).
// ---------------------------------------------------------------------------------------

/// Base linear velocity scale.
pub const LIN_VEL_SCALE: f32 = 2.0;
/// Base angular velocity scale.
pub const ANG_VEL_SCALE: f32 = 0.25;
/// Projected gravity scale.
pub const GRAVITY_SCALE: f32 = 1.0;
/// Joint position (q - q0) scale.
pub const JOINT_POS_SCALE: f32 = 1.0;
/// Joint velocity scale.
pub const JOINT_VEL_SCALE: f32 = 0.05;
/// Height measurement scale.
pub const HEIGHT_SCALE: f32 = 5.0;
/// Command scales (vx, vy, wz).
pub const COMMAND_SCALE: [f32; 3] = [LIN_VEL_SCALE, LIN_VEL_SCALE, ANG_VEL_SCALE];
/// Observation clip after scaling.
pub const OBS_CLIP: f32 = 100.0;
/// Action clip.
pub const ACTION_CLIP: f32 = 100.0;

// ---------------------------------------------------------------------------------------
// Noise (legged_gym's `noise.noise_scales`, in raw units before scaling).
// ---------------------------------------------------------------------------------------

/// Joint position noise, rad.
pub const JOINT_POS_NOISE_RAD: f32 = 0.01;
/// Joint velocity noise, rad/s.
pub const JOINT_VEL_NOISE_RAD_S: f32 = 1.5;
/// Linear velocity noise, m/s.
pub const LIN_VEL_NOISE_M_S: f32 = 0.1;
/// Angular velocity noise, rad/s.
pub const ANG_VEL_NOISE_RAD_S: f32 = 0.2;
/// Projected gravity noise.
pub const GRAVITY_NOISE: f32 = 0.05;
/// Height measurement noise, m.
pub const HEIGHT_NOISE_M: f32 = 0.1;

// ---------------------------------------------------------------------------------------
// Proprioception o^p (42).
// ---------------------------------------------------------------------------------------

/// Size of the proprioceptive observation.
pub const PROPRIO_DIM: usize = 42;
/// Base angular velocity (base frame) x ANG_VEL_SCALE.
pub const PROPRIO_ANG_VEL: Range<usize> = 0..3;
/// Gravity direction in the base frame (unit vector) x GRAVITY_SCALE.
pub const PROPRIO_GRAVITY: Range<usize> = 3..6;
/// (q - q0) x JOINT_POS_SCALE.
pub const PROPRIO_JOINT_POS: Range<usize> = 6..24;
/// qdot x JOINT_VEL_SCALE.
pub const PROPRIO_JOINT_VEL: Range<usize> = 24..42;

/// Number of proprioceptive observations in the history.
pub const HISTORY_LEN: usize = 5;
/// Size of the flattened history, oldest first.
pub const HISTORY_DIM: usize = HISTORY_LEN * PROPRIO_DIM;

// ---------------------------------------------------------------------------------------
// Actor observation (63): command, previous action, proprioception.
// ---------------------------------------------------------------------------------------

/// Size of the actor's direct observation.
pub const ACTOR_OBS_DIM: usize = 63;
/// Velocity command (vx, vy, wz) x COMMAND_SCALE.
pub const ACTOR_COMMAND: Range<usize> = 0..3;
/// Previous action (unscaled).
pub const ACTOR_PREV_ACTION: Range<usize> = 3..21;
/// Proprioception.
pub const ACTOR_PROPRIO: Range<usize> = 21..63;

// ---------------------------------------------------------------------------------------
// Privileged state s^p (42) and terrain i^e (187), critic only.
// ---------------------------------------------------------------------------------------

/// Size of the privileged state.
pub const PRIVILEGED_DIM: usize = 42;
/// Base linear velocity (base frame) x LIN_VEL_SCALE.
pub const PRIV_LIN_VEL: Range<usize> = 0..3;
/// Base height above terrain (m).
pub const PRIV_BASE_HEIGHT: usize = 3;
/// Foot friction coefficient.
pub const PRIV_FRICTION: usize = 4;
/// Foot contact forces (world frame, leg-major) / 100 N.
pub const PRIV_CONTACT_FORCES: Range<usize> = 5..23;
/// External perturbation: last push velocity change (m/s, world) 3 and its unit direction 3.
pub const PRIV_PERTURBATION: Range<usize> = 23..29;
/// Collision flags (0/1): trunk, thighs (6), shanks (6).
pub const PRIV_COLLISIONS: Range<usize> = 29..42;
/// Contact force scale of the privileged state, 1/N.
pub const CONTACT_FORCE_SCALE: f32 = 0.01;

/// The privileged state's parts by name, in physical units; [`PrivilegedState::to_obs`]
/// scales each into its `PRIV_*` range.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PrivilegedState {
    /// Base linear velocity, base frame, m/s.
    pub lin_vel_base_m_s: [f32; 3],
    /// Base height above the terrain, m.
    pub base_height_m: f32,
    /// Foot friction coefficient.
    pub friction: f32,
    /// Foot contact forces, world frame, N (leg order).
    pub foot_force_world_n: [[f32; 3]; NUM_LEGS],
    /// The last push's velocity change, world frame, m/s (zero when none).
    pub push_world_m_s: [f32; 3],
    /// The trunk touches something.
    pub trunk_collision: bool,
    /// Each thigh touches something (leg order).
    pub thigh_collisions: [bool; NUM_LEGS],
    /// Each shank touches something (leg order).
    pub shank_collisions: [bool; NUM_LEGS],
}

impl PrivilegedState {
    /// The privileged vector: each part scaled into its `PRIV_*` range.
    pub fn to_obs(&self) -> [f32; PRIVILEGED_DIM] {
        let mut p = [0.0; PRIVILEGED_DIM];
        for k in 0..3 {
            p[PRIV_LIN_VEL.start + k] = self.lin_vel_base_m_s[k] * LIN_VEL_SCALE;
        }
        p[PRIV_BASE_HEIGHT] = self.base_height_m;
        p[PRIV_FRICTION] = self.friction;
        for (leg, force) in self.foot_force_world_n.iter().enumerate() {
            for k in 0..3 {
                p[PRIV_CONTACT_FORCES.start + 3 * leg + k] = force[k] * CONTACT_FORCE_SCALE;
            }
        }
        let push = self.push_world_m_s;
        let norm = libm::sqrtf(push[0] * push[0] + push[1] * push[1] + push[2] * push[2]);
        for k in 0..3 {
            p[PRIV_PERTURBATION.start + k] = push[k];
            p[PRIV_PERTURBATION.start + 3 + k] = if norm > 1e-6 { push[k] / norm } else { 0.0 };
        }
        p[PRIV_COLLISIONS.start] = self.trunk_collision as u8 as f32;
        for leg in 0..NUM_LEGS {
            p[PRIV_COLLISIONS.start + 1 + leg] = self.thigh_collisions[leg] as u8 as f32;
            p[PRIV_COLLISIONS.start + 1 + NUM_LEGS + leg] = self.shank_collisions[leg] as u8 as f32;
        }
        p
    }
}

/// Height scan rows along x.
pub const HEIGHT_SCAN_NX: usize = 17;
/// Height scan columns along y.
pub const HEIGHT_SCAN_NY: usize = 11;
/// Height scan spacing, m.
pub const HEIGHT_SCAN_SPACING_M: f32 = 0.1;
/// Size of the height scan.
pub const HEIGHT_SCAN_DIM: usize = HEIGHT_SCAN_NX * HEIGHT_SCAN_NY;
/// Height scan offset: `(base_z - 0.3 - h) * HEIGHT_SCALE` (legged_gym's convention).
pub const HEIGHT_SCAN_OFFSET_M: f32 = 0.3;

/// Scan point `k` (x-major) relative to the base, in the yaw-aligned frame, metres.
pub fn height_scan_point_m(k: usize) -> [f32; 2] {
    let ix = k / HEIGHT_SCAN_NY;
    let iy = k % HEIGHT_SCAN_NY;
    [
        (ix as f32 - (HEIGHT_SCAN_NX as f32 - 1.0) / 2.0) * HEIGHT_SCAN_SPACING_M,
        (iy as f32 - (HEIGHT_SCAN_NY as f32 - 1.0) / 2.0) * HEIGHT_SCAN_SPACING_M,
    ]
}

/// Builds o^p from raw sensor quantities (no noise): the one place scales are applied.
pub fn proprio_obs(
    ang_vel_base_rad_s: [f32; 3],
    gravity_base: [f32; 3],
    q_rad: &[f32; NUM_JOINTS],
    qdot_rad_s: &[f32; NUM_JOINTS],
) -> [f32; PROPRIO_DIM] {
    proprio_obs_vec(
        &ang_vel_base_rad_s.into(),
        &gravity_base.into(),
        q_rad,
        qdot_rad_s,
    )
}

/// [`proprio_obs`] with the base's angular velocity (base frame, rad/s) and the unit
/// gravity direction (base frame) as nalgebra vectors.
pub fn proprio_obs_vec(
    ang_vel_base_rad_s: &Vector3<f32>,
    gravity_base: &Vector3<f32>,
    q_rad: &[f32; NUM_JOINTS],
    qdot_rad_s: &[f32; NUM_JOINTS],
) -> [f32; PROPRIO_DIM] {
    let mut o = [0.0; PROPRIO_DIM];
    o[PROPRIO_ANG_VEL].copy_from_slice((ang_vel_base_rad_s * ANG_VEL_SCALE).as_slice());
    o[PROPRIO_GRAVITY].copy_from_slice((gravity_base * GRAVITY_SCALE).as_slice());
    for j in 0..NUM_JOINTS {
        o[PROPRIO_JOINT_POS.start + j] = (q_rad[j] - Q0_RAD[j]) * JOINT_POS_SCALE;
        o[PROPRIO_JOINT_VEL.start + j] = qdot_rad_s[j] * JOINT_VEL_SCALE;
    }
    clip_all(&mut o);
    o
}

/// Noise amplitude (after scaling) of each o^p entry.
pub fn proprio_noise_scale() -> [f32; PROPRIO_DIM] {
    let mut n = [0.0; PROPRIO_DIM];
    n[PROPRIO_ANG_VEL].fill(ANG_VEL_NOISE_RAD_S * ANG_VEL_SCALE);
    n[PROPRIO_GRAVITY].fill(GRAVITY_NOISE * GRAVITY_SCALE);
    n[PROPRIO_JOINT_POS].fill(JOINT_POS_NOISE_RAD * JOINT_POS_SCALE);
    n[PROPRIO_JOINT_VEL].fill(JOINT_VEL_NOISE_RAD_S * JOINT_VEL_SCALE);
    n
}

/// Builds the actor's direct observation from command, previous action and o^p.
pub fn actor_obs(
    command: [f32; 3],
    prev_action: &[f32; NUM_JOINTS],
    proprio: &[f32; PROPRIO_DIM],
) -> [f32; ACTOR_OBS_DIM] {
    let mut o = [0.0; ACTOR_OBS_DIM];
    for k in 0..3 {
        o[ACTOR_COMMAND.start + k] = command[k] * COMMAND_SCALE[k];
    }
    o[ACTOR_PREV_ACTION].copy_from_slice(prev_action);
    o[ACTOR_PROPRIO].copy_from_slice(proprio);
    clip_all(&mut o);
    o
}

fn clip_all(values: &mut [f32]) {
    for v in values {
        *v = v.clamp(-OBS_CLIP, OBS_CLIP);
    }
}

/// A fixed-length history of o^p, oldest first, as the estimator and memory read it.
#[derive(Clone, Debug)]
pub struct ProprioHistory {
    frames: [[f32; PROPRIO_DIM]; HISTORY_LEN],
}

impl ProprioHistory {
    /// A history filled with one observation (as after a reset).
    pub fn filled_with(obs: &[f32; PROPRIO_DIM]) -> Self {
        Self {
            frames: [*obs; HISTORY_LEN],
        }
    }

    /// Drops the oldest observation and appends `obs` as the newest.
    pub fn push(&mut self, obs: &[f32; PROPRIO_DIM]) {
        self.frames.rotate_left(1);
        self.frames[HISTORY_LEN - 1] = *obs;
    }

    /// The newest observation.
    pub fn newest(&self) -> &[f32; PROPRIO_DIM] {
        &self.frames[HISTORY_LEN - 1]
    }

    /// The flattened history, oldest first.
    pub fn flatten(&self) -> [f32; HISTORY_DIM] {
        let mut out = [0.0; HISTORY_DIM];
        for (i, frame) in self.frames.iter().enumerate() {
            out[i * PROPRIO_DIM..(i + 1) * PROPRIO_DIM].copy_from_slice(frame);
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn layouts_are_contiguous() {
        assert_eq!(PROPRIO_JOINT_VEL.end, PROPRIO_DIM);
        assert_eq!(ACTOR_PROPRIO.end, ACTOR_OBS_DIM);
        assert_eq!(ACTOR_PROPRIO.len(), PROPRIO_DIM);
        assert_eq!(PRIV_COLLISIONS.end, PRIVILEGED_DIM);
        assert_eq!(PRIV_COLLISIONS.len(), 13);
        assert_eq!(HEIGHT_SCAN_DIM, 187);
        assert_eq!(HISTORY_DIM, 210);
    }

    #[test]
    fn nominal_pose_gives_zero_joint_obs() {
        let o = proprio_obs([0.0, 0.0, 4.0], [0.0, 0.0, -1.0], &Q0_RAD, &[20.0; 18]);
        assert_eq!(o[PROPRIO_ANG_VEL.start + 2], 1.0);
        assert!(o[PROPRIO_JOINT_POS].iter().all(|&x| x == 0.0));
        assert!(o[PROPRIO_JOINT_VEL].iter().all(|&x| x == 1.0));
    }

    #[test]
    fn history_keeps_order() {
        let mut h = ProprioHistory::filled_with(&[0.0; PROPRIO_DIM]);
        for k in 1..=6 {
            h.push(&[k as f32; PROPRIO_DIM]);
        }
        let flat = h.flatten();
        assert_eq!(flat[0], 2.0);
        assert_eq!(flat[HISTORY_DIM - 1], 6.0);
        assert_eq!(h.newest()[0], 6.0);
    }

    #[test]
    fn scan_grid_is_centred() {
        assert_eq!(height_scan_point_m(0), [-0.8, -0.5]);
        assert_eq!(height_scan_point_m(HEIGHT_SCAN_DIM - 1), [0.8, 0.5]);
    }
}
