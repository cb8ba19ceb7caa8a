//! The rewards of the paper's Table I (task r_g and regularization r_l; the style reward
//! r_s belongs to the learner, which owns the discriminator).
//!
//! As in legged_gym, each term is multiplied by its scale and by the policy period
//! (`POLICY_DT_S`), so sums over an episode do not depend on the control rate. A scale of
//! zero switches a term off; `task` and `regularization` switch whole groups (the paper's
//! ablations g+s, g+l, g+s+l).
//!
//! Two terms are not in Table I and are off by default:
//! - `tripod_contact` rewards each step whose stance set is exactly one of the two tripods
//!   while the robot is commanded to move. `configs/flat-tripod.toml` leaves it off (the gait
//!   is the style reward's); the rough-terrain presets, which continue the behavior-cloned
//!   `assets/policies/flat-tripod`, keep it.
//! - `feet_stumble` penalizes each step in which a foot pushes into a riser's face, after
//!   legged_gym's `_reward_feet_stumble`: a blind robot's foot jammed against a riser.

use hexapod_core::robot::{NUM_JOINTS, NUM_LEGS, TRIPOD_A_MASK, TRIPOD_B_MASK};

/// A foot is in stance above this contact-force norm, N (also `hexapod eval`'s threshold).
pub const STANCE_FORCE_N: f32 = 5.0;
/// Commands below this speed (m/s, and rad/s for yaw) count as standing still.
pub const MOVING_COMMAND_MIN: f32 = 0.05;
/// A foot stumbles when the horizontal part of the ground's normal force on it exceeds this
/// multiple of the vertical part: when the face it touches is steeper than 60 deg (tan 60 deg).
///
/// legged_gym's `_reward_feet_stumble` uses 5 on the full contact force against vertical
/// walls. Here the force is the normal part alone, so the ratio is the face's steepness, and
/// the ground is a heightfield of 5 cm cells whose risers are ramps one cell wide: a 20 cm
/// riser's face leans at 76 deg (ratio 4.0, under legged_gym's 5), a 10 cm one's at 63 deg.
/// The steepest slopes trained (36 deg, 0.73) stay well below.
pub const STUMBLE_RATIO: f32 = 1.732;
use serde::{Deserialize, Serialize};

/// Scales of the reward terms (the paper's values by default).
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RewardScales {
    /// Include the task terms r_g.
    pub task: bool,
    /// Include the regularization terms r_l.
    pub regularization: bool,
    /// exp(-|v_xy - v_xy_des|^2 / sigma).
    pub tracking_lin_vel: f32,
    /// exp(-(w_z - w_z_des)^2 / sigma).
    pub tracking_ang_vel: f32,
    /// Tracking kernel width sigma: (m/s)^2 and (rad/s)^2 for the squared kernel, m/s and
    /// rad/s for the norm kernel.
    pub tracking_sigma: f32,
    /// Form of the tracking kernel: `squared`, `exp(-|e|^2 / sigma)` (the default, as in
    /// legged_gym and AMP_for_hardware), or `norm`, `exp(-|e| / sigma)` (Table I as printed,
    /// with its missing minus sign): at sigma 0.15 a 0.05 m/s error costs 1.7 % of the
    /// term with the first and 28 % with the second.
    pub tracking_kernel: TrackingKernel,
    /// v_z^2.
    pub lin_vel_z: f32,
    /// |w_xy|^2.
    pub ang_vel_xy: f32,
    /// |tau|^2.
    pub torques: f32,
    /// |qddot|^2.
    pub joint_acc: f32,
    /// |a_t - a_t-1|^2.
    pub action_rate: f32,
    /// Number of thighs and shanks touching the ground.
    pub collision: f32,
    /// Sum of torque above `soft_torque_limit` x limit, N m.
    pub torque_limits: f32,
    /// Sum of joint speed above `soft_velocity_limit` x limit (each clipped at 1), rad/s.
    pub joint_vel_limits: f32,
    /// Sum of foot force above `max_contact_force_n`, N.
    pub contact_forces: f32,
    /// Fraction of the torque limit where the penalty starts.
    pub soft_torque_limit: f32,
    /// Fraction of the velocity limit where the penalty starts.
    pub soft_velocity_limit: f32,
    /// Foot force where the penalty starts, N.
    pub max_contact_force_n: f32,
    /// Stance set is exactly tripod A or B while commanded to move (not in Table I; 0 = off).
    pub tripod_contact: f32,
    /// Some foot pushes into a riser's face: its normal force's horizontal part above
    /// [`STUMBLE_RATIO`] x the vertical one (after legged_gym's `feet_stumble`; not in
    /// Table I; 0 = off).
    pub feet_stumble: f32,
}

impl Default for RewardScales {
    fn default() -> Self {
        Self {
            task: true,
            regularization: true,
            tracking_lin_vel: 1.0,
            tracking_ang_vel: 0.5,
            tracking_sigma: 0.15,
            tracking_kernel: TrackingKernel::Squared,
            lin_vel_z: -1.0,
            ang_vel_xy: -0.08,
            torques: -2e-6,
            joint_acc: -1.5e-7,
            action_rate: -0.01,
            collision: -0.05,
            torque_limits: -0.05,
            joint_vel_limits: -0.5,
            contact_forces: -0.1,
            soft_torque_limit: 0.8,
            soft_velocity_limit: 0.9,
            max_contact_force_n: 150.0,
            tripod_contact: 0.0,
            feet_stumble: 0.0,
        }
    }
}

/// Form of the velocity-tracking kernel ([`RewardScales::tracking_kernel`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum TrackingKernel {
    /// `exp(-|e|^2 / sigma)`.
    Squared,
    /// `exp(-|e| / sigma)`.
    Norm,
}

impl TrackingKernel {
    /// The kernel's value for a squared error `err_sq` and width `sigma`.
    pub fn value(self, err_sq: f32, sigma: f32) -> f32 {
        match self {
            TrackingKernel::Squared => (-err_sq / sigma).exp(),
            TrackingKernel::Norm => (-err_sq.sqrt() / sigma).exp(),
        }
    }
}

/// Names of the terms, in the order of [`RewardTerms::values`].
pub const TERM_NAMES: [&str; NUM_TERMS] = [
    "tracking_lin_vel",
    "tracking_ang_vel",
    "lin_vel_z",
    "ang_vel_xy",
    "torques",
    "joint_acc",
    "action_rate",
    "collision",
    "torque_limits",
    "joint_vel_limits",
    "contact_forces",
    "feet_stumble",
    "tripod_contact",
];

/// Number of reward terms.
pub const NUM_TERMS: usize = 13;

/// What the rewards are computed from (one policy step, one robot).
pub struct RewardInputs<'a> {
    /// Command (vx, vy, wz).
    pub command: [f32; 3],
    /// Base linear velocity, base frame, m/s.
    pub lin_vel_base_m_s: [f32; 3],
    /// Base angular velocity, base frame, rad/s.
    pub ang_vel_base_rad_s: [f32; 3],
    /// Joint torques, N m.
    pub torque_nm: &'a [f32; NUM_JOINTS],
    /// Joint torque limits, N m.
    pub torque_limit_nm: &'a [f32; NUM_JOINTS],
    /// Joint velocities, rad/s.
    pub qdot_rad_s: &'a [f32; NUM_JOINTS],
    /// Joint velocity limits, rad/s.
    pub velocity_limit_rad_s: &'a [f32; NUM_JOINTS],
    /// Joint accelerations, rad/s^2.
    pub qddot_rad_s2: &'a [f32; NUM_JOINTS],
    /// Action and previous action.
    pub action: &'a [f32; NUM_JOINTS],
    /// Previous action.
    pub prev_action: &'a [f32; NUM_JOINTS],
    /// Thighs and shanks touching the ground.
    pub collisions: u32,
    /// Foot forces, N.
    pub foot_force_n: &'a [[f32; 3]; NUM_LEGS],
}

/// The weighted terms of one step (already multiplied by scale and dt).
#[derive(Clone, Copy, Debug, Default)]
pub struct RewardTerms {
    /// In the order of [`TERM_NAMES`].
    pub values: [f32; NUM_TERMS],
}

impl RewardTerms {
    /// Sum of all terms.
    pub fn total(&self) -> f32 {
        self.values.iter().sum()
    }
}

fn sq(v: &[f32]) -> f32 {
    v.iter().map(|x| x * x).sum()
}

/// Computes the weighted reward terms of one policy step of length `dt_s`.
pub fn compute(scales: &RewardScales, x: &RewardInputs, dt_s: f32) -> RewardTerms {
    let mut raw = [0.0f32; NUM_TERMS];
    let lin_err = (x.lin_vel_base_m_s[0] - x.command[0]).powi(2)
        + (x.lin_vel_base_m_s[1] - x.command[1]).powi(2);
    let kernel = scales.tracking_kernel;
    raw[0] = kernel.value(lin_err, scales.tracking_sigma);
    raw[1] = kernel.value(
        (x.ang_vel_base_rad_s[2] - x.command[2]).powi(2),
        scales.tracking_sigma,
    );
    raw[2] = x.lin_vel_base_m_s[2].powi(2);
    raw[3] = x.ang_vel_base_rad_s[0].powi(2) + x.ang_vel_base_rad_s[1].powi(2);
    raw[4] = sq(x.torque_nm);
    raw[5] = sq(x.qddot_rad_s2);
    raw[6] = x
        .action
        .iter()
        .zip(x.prev_action)
        .map(|(a, b)| (a - b).powi(2))
        .sum();
    raw[7] = x.collisions as f32;
    raw[8] = (0..NUM_JOINTS)
        .map(|j| (x.torque_nm[j].abs() - scales.soft_torque_limit * x.torque_limit_nm[j]).max(0.0))
        .sum();
    raw[9] = (0..NUM_JOINTS)
        .map(|j| {
            (x.qdot_rad_s[j].abs() - scales.soft_velocity_limit * x.velocity_limit_rad_s[j])
                .clamp(0.0, 1.0)
        })
        .sum();
    raw[10] = x
        .foot_force_n
        .iter()
        .map(|f| (sq(f).sqrt() - scales.max_contact_force_n).max(0.0))
        .sum();
    raw[11] = f32::from(u8::from(
        x.foot_force_n
            .iter()
            .any(|f| f[0].hypot(f[1]) > STUMBLE_RATIO * f[2].abs()),
    ));
    let mask = stance_mask(x.foot_force_n);
    let moving = x.command[0].hypot(x.command[1]) > MOVING_COMMAND_MIN
        || x.command[2].abs() > MOVING_COMMAND_MIN;
    raw[12] = f32::from(u8::from(
        moving && (mask == TRIPOD_A_MASK || mask == TRIPOD_B_MASK),
    ));
    let s = [
        scales.tracking_lin_vel,
        scales.tracking_ang_vel,
        scales.lin_vel_z,
        scales.ang_vel_xy,
        scales.torques,
        scales.joint_acc,
        scales.action_rate,
        scales.collision,
        scales.torque_limits,
        scales.joint_vel_limits,
        scales.contact_forces,
        scales.feet_stumble,
        scales.tripod_contact,
    ];
    let mut terms = RewardTerms::default();
    for k in 0..NUM_TERMS {
        // The gait term (last) is switched by its scale alone.
        let on = if k < 2 {
            scales.task
        } else {
            k == NUM_TERMS - 1 || scales.regularization
        };
        terms.values[k] = if on { s[k] * raw[k] * dt_s } else { 0.0 };
    }
    terms
}

/// Feet in stance (bit i = leg i): contact-force norm above [`STANCE_FORCE_N`].
pub fn stance_mask(foot_force_n: &[[f32; 3]; NUM_LEGS]) -> u8 {
    (0..NUM_LEGS)
        .filter(|&l| sq(&foot_force_n[l]).sqrt() > STANCE_FORCE_N)
        .fold(0, |m, l| m | (1 << l))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn inputs<'a>(
        zeros: &'a [f32; NUM_JOINTS],
        feet: &'a [[f32; 3]; NUM_LEGS],
    ) -> RewardInputs<'a> {
        RewardInputs {
            command: [0.3, 0.0, 0.0],
            lin_vel_base_m_s: [0.3, 0.0, 0.0],
            ang_vel_base_rad_s: [0.0; 3],
            torque_nm: zeros,
            torque_limit_nm: &hexapod_core::robot::TORQUE_LIMIT_NM,
            qdot_rad_s: zeros,
            velocity_limit_rad_s: &hexapod_core::robot::VELOCITY_LIMIT_RAD_S,
            qddot_rad_s2: zeros,
            action: zeros,
            prev_action: zeros,
            collisions: 2,
            foot_force_n: feet,
        }
    }

    #[test]
    fn the_norm_kernel_charges_small_errors_more_than_the_squared_one() {
        let err_sq = 0.05f32 * 0.05;
        let squared = TrackingKernel::Squared.value(err_sq, 0.15);
        let norm = TrackingKernel::Norm.value(err_sq, 0.15);
        assert!((squared - (-0.0025f32 / 0.15).exp()).abs() < 1e-6);
        assert!((norm - (-1.0f32 / 3.0).exp()).abs() < 1e-6);
        assert_eq!(TrackingKernel::Norm.value(0.0, 0.15), 1.0);
        let parsed: RewardScales = toml::from_str("tracking_kernel = \"norm\"").unwrap();
        assert_eq!(parsed.tracking_kernel, TrackingKernel::Norm);
        assert!(toml::from_str::<RewardScales>("tracking_kernel = \"cubic\"").is_err());
    }

    #[test]
    fn perfect_tracking_earns_full_task_reward() {
        let z = [0.0; NUM_JOINTS];
        let feet = [[0.0; 3]; NUM_LEGS];
        let t = compute(&RewardScales::default(), &inputs(&z, &feet), 0.02);
        assert!((t.values[0] - 0.02).abs() < 1e-7);
        assert!((t.values[1] - 0.01).abs() < 1e-7);
        assert!((t.values[7] + 0.05 * 2.0 * 0.02).abs() < 1e-7);
    }

    #[test]
    fn groups_switch_off() {
        let z = [0.0; NUM_JOINTS];
        let feet = [[0.0; 3]; NUM_LEGS];
        let scales = RewardScales {
            regularization: false,
            ..Default::default()
        };
        let t = compute(&scales, &inputs(&z, &feet), 0.02);
        assert_eq!(t.values[7], 0.0);
        let scales = RewardScales {
            task: false,
            ..Default::default()
        };
        let t = compute(&scales, &inputs(&z, &feet), 0.02);
        assert_eq!(t.values[0], 0.0);
    }

    #[test]
    fn contact_force_penalty_starts_at_the_limit() {
        let z = [0.0; NUM_JOINTS];
        let mut feet = [[0.0; 3]; NUM_LEGS];
        feet[0] = [0.0, 0.0, 200.0];
        let t = compute(&RewardScales::default(), &inputs(&z, &feet), 1.0);
        assert!((t.values[10] + 0.1 * 50.0).abs() < 1e-4);
    }

    #[test]
    fn tripod_contact_rewards_only_a_tripod_stance_while_moving() {
        let z = [0.0; NUM_JOINTS];
        let scales = RewardScales {
            tripod_contact: 0.5,
            ..Default::default()
        };
        let mut feet = [[0.0; 3]; NUM_LEGS];
        for leg in (0..NUM_LEGS).filter(|l| TRIPOD_A_MASK & (1 << l) != 0) {
            feet[leg] = [0.0, 0.0, 80.0];
        }
        assert_eq!(stance_mask(&feet), TRIPOD_A_MASK);
        let t = compute(&scales, &inputs(&z, &feet), 1.0);
        assert_eq!(t.values[12], 0.5);
        // Off by default (the paper's Table I).
        assert_eq!(
            compute(&RewardScales::default(), &inputs(&z, &feet), 1.0).values[12],
            0.0
        );
        // Standing still: no gait reward.
        let mut standing = inputs(&z, &feet);
        standing.command = [0.0; 3];
        assert_eq!(compute(&scales, &standing, 1.0).values[12], 0.0);
        // A fourth foot down (below the threshold it does not count).
        feet[1] = [0.0, 0.0, 4.0];
        assert_eq!(compute(&scales, &inputs(&z, &feet), 1.0).values[12], 0.5);
        feet[1] = [0.0, 0.0, 6.0];
        assert_eq!(compute(&scales, &inputs(&z, &feet), 1.0).values[12], 0.0);
    }

    #[test]
    fn a_foot_pushing_into_a_riser_stumbles_a_foot_on_a_tread_does_not() {
        let z = [0.0; NUM_JOINTS];
        let scales = RewardScales {
            feet_stumble: -1.0,
            ..Default::default()
        };
        let mut feet = [[0.0; 3]; NUM_LEGS];
        feet[2] = [12.0, 5.0, 60.0];
        assert_eq!(compute(&scales, &inputs(&z, &feet), 1.0).values[11], 0.0);
        // On a 36 deg slope the normal force leans 36 deg: no stumble.
        feet[1] = [0.73 * 80.0, 0.0, 80.0];
        assert_eq!(compute(&scales, &inputs(&z, &feet), 1.0).values[11], 0.0);
        // Against a 20 cm riser's face (76 deg in the heightfield): a stumble.
        feet[0] = [108.0, 0.0, 27.0];
        assert_eq!(compute(&scales, &inputs(&z, &feet), 1.0).values[11], -1.0);
        // One penalty per step, however many feet stumble; off by default.
        feet[3] = [-40.0, 10.0, 2.0];
        assert_eq!(compute(&scales, &inputs(&z, &feet), 1.0).values[11], -1.0);
        let default = compute(&RewardScales::default(), &inputs(&z, &feet), 1.0);
        assert_eq!(default.values[11], 0.0);
    }
}
