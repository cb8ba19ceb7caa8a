//! The robot: legs, joints, their order, geometry, nominal pose and limits.
//!
//! Joint order everywhere (observations, actions, CAN node ids): legs RF, RM, RR, LF, LM, LR,
//! each hip (yaw), thigh (pitch), shank (pitch); `index = 3 * leg + joint`.
//!
//! Conventions: base frame x forward, y left, z up. A leg's frame is the base frame turned
//! about z by the leg's mount yaw, so its x axis points outward along the leg at zero hip
//! yaw. Thigh and shank turn about the leg frame's y axis; positive angles move the foot
//! down. Zero thigh and shank angles stretch the leg horizontally.
//!
//! `assets/hexapod.urdf` is generated from these numbers (`hexapod-sim urdf`, checked fresh
//! in CI with `--check`); `host-sim` also checks the file it loads against them.

use core::f32::consts::FRAC_PI_4;

/// Number of legs.
pub const NUM_LEGS: usize = 6;
/// Joints per leg.
pub const JOINTS_PER_LEG: usize = 3;
/// Number of actuated joints.
pub const NUM_JOINTS: usize = NUM_LEGS * JOINTS_PER_LEG;

/// A leg, in the paper's order.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u8)]
pub enum Leg {
    /// Right front.
    RightFront = 0,
    /// Right middle.
    RightMiddle = 1,
    /// Right rear.
    RightRear = 2,
    /// Left front.
    LeftFront = 3,
    /// Left middle.
    LeftMiddle = 4,
    /// Left rear.
    LeftRear = 5,
}

impl Leg {
    /// All legs in order.
    pub const ALL: [Leg; NUM_LEGS] = [
        Leg::RightFront,
        Leg::RightMiddle,
        Leg::RightRear,
        Leg::LeftFront,
        Leg::LeftMiddle,
        Leg::LeftRear,
    ];

    /// Position in the joint order.
    pub const fn index(self) -> usize {
        self as usize
    }

    /// Short name as used in the URDF (`rf`, `rm`, ...).
    pub const fn name(self) -> &'static str {
        LEG_NAMES[self as usize]
    }

    /// True for the right side (y < 0).
    pub const fn is_right(self) -> bool {
        (self as usize) < 3
    }

    /// The tripod set the leg belongs to.
    pub const fn tripod(self) -> Tripod {
        match self {
            Leg::RightFront | Leg::LeftMiddle | Leg::RightRear => Tripod::A,
            _ => Tripod::B,
        }
    }
}

/// Leg names as used in URDF link and joint names.
pub const LEG_NAMES: [&str; NUM_LEGS] = ["rf", "rm", "rr", "lf", "lm", "lr"];

/// A joint within a leg.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u8)]
pub enum Joint {
    /// Hip yaw (about the base z axis).
    Hip = 0,
    /// Thigh pitch.
    Thigh = 1,
    /// Shank pitch.
    Shank = 2,
}

impl Joint {
    /// All joints of a leg in order.
    pub const ALL: [Joint; JOINTS_PER_LEG] = [Joint::Hip, Joint::Thigh, Joint::Shank];

    /// Short name as used in URDF joint names.
    pub const fn name(self) -> &'static str {
        match self {
            Joint::Hip => "hip",
            Joint::Thigh => "thigh",
            Joint::Shank => "shank",
        }
    }
}

/// Index of a joint in the global joint order.
pub const fn joint_index(leg: Leg, joint: Joint) -> usize {
    JOINTS_PER_LEG * leg as usize + joint as usize
}

/// URDF joint names in the global joint order (`rf_hip`, `rf_thigh`, ...).
pub const JOINT_NAMES: [&str; NUM_JOINTS] = [
    "rf_hip", "rf_thigh", "rf_shank", "rm_hip", "rm_thigh", "rm_shank", "rr_hip", "rr_thigh",
    "rr_shank", "lf_hip", "lf_thigh", "lf_shank", "lm_hip", "lm_thigh", "lm_shank", "lr_hip",
    "lr_thigh", "lr_shank",
];

/// A tripod set: three legs that swing together.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Tripod {
    /// RF, LM, RR.
    A,
    /// LF, RM, LR.
    B,
}

/// Legs of tripod A = {RF, LM, RR}.
pub const TRIPOD_A: [Leg; 3] = [Leg::RightFront, Leg::LeftMiddle, Leg::RightRear];
/// Legs of tripod B = {LF, RM, LR}.
pub const TRIPOD_B: [Leg; 3] = [Leg::LeftFront, Leg::RightMiddle, Leg::LeftRear];
/// Contact mask (bit i = leg i on the ground) of tripod A in stance.
pub const TRIPOD_A_MASK: u8 = (1 << 0) | (1 << 4) | (1 << 2);
/// Contact mask of tripod B in stance.
pub const TRIPOD_B_MASK: u8 = (1 << 3) | (1 << 1) | (1 << 5);

// ---------------------------------------------------------------------------------------
// Geometry (metres, radians) and masses (kilograms).
// ---------------------------------------------------------------------------------------

/// Trunk box size (x, y, z).
pub const TRUNK_SIZE_M: [f32; 3] = [0.60, 0.30, 0.12];
/// Trunk mass.
pub const TRUNK_MASS_KG: f32 = 14.8;
/// Nominal standing height of the base above flat ground, at [`Q0_RAD`] (kinematics with the
/// foot radius: 0.308 m), rounded to the centimetre.
pub const NOMINAL_BASE_HEIGHT_M: f32 = 0.31;
/// Hip joint positions in the base frame, per leg.
pub const HIP_POS_BASE_M: [[f32; 3]; NUM_LEGS] = [
    [0.25, -0.15, 0.0],
    [0.0, -0.15, 0.0],
    [-0.25, -0.15, 0.0],
    [0.25, 0.15, 0.0],
    [0.0, 0.15, 0.0],
    [-0.25, 0.15, 0.0],
];
/// Mount yaw of each leg: the leg's direction at zero hip yaw.
pub const MOUNT_YAW_RAD: [f32; NUM_LEGS] = [
    -FRAC_PI_4,
    -2.0 * FRAC_PI_4,
    -3.0 * FRAC_PI_4,
    FRAC_PI_4,
    2.0 * FRAC_PI_4,
    3.0 * FRAC_PI_4,
];
/// Coxa length (hip yaw axis to thigh axis) per leg; the middle legs reach 0.137 m further.
pub const COXA_LENGTH_M: [f32; NUM_LEGS] = [0.08, 0.217, 0.08, 0.08, 0.217, 0.08];
/// Coxa mass per leg.
pub const COXA_MASS_KG: [f32; NUM_LEGS] = [0.5, 0.6, 0.5, 0.5, 0.6, 0.5];
/// Thigh length (thigh axis to shank axis).
pub const THIGH_LENGTH_M: f32 = 0.20;
/// Thigh mass.
pub const THIGH_MASS_KG: f32 = 0.9;
/// Shank length (shank axis to foot sphere centre).
pub const SHANK_LENGTH_M: f32 = 0.22;
/// Shank mass (foot included).
pub const SHANK_MASS_KG: f32 = 0.35;
/// Foot sphere radius.
pub const FOOT_RADIUS_M: f32 = 0.02;
/// Coxa radius (its inertia as a solid cylinder; the coxa has no collision shape).
pub const COXA_RADIUS_M: f32 = 0.035;
/// Thigh radius (a solid cylinder: inertia and collision shape).
pub const THIGH_RADIUS_M: f32 = 0.03;
/// Shank radius (a solid cylinder: inertia and collision shape; the foot sphere at its end).
pub const SHANK_RADIUS_M: f32 = 0.018;
/// Total mass of the robot.
pub const TOTAL_MASS_KG: f32 =
    TRUNK_MASS_KG + 4.0 * 0.5 + 2.0 * 0.6 + NUM_LEGS as f32 * (THIGH_MASS_KG + SHANK_MASS_KG);

// ---------------------------------------------------------------------------------------
// Nominal pose and limits, per joint kind (the same for every leg).
// ---------------------------------------------------------------------------------------

/// Nominal (standing) angles of hip, thigh, shank: hip 0, thigh 20 deg down, shank vertical.
pub const Q0_LEG_RAD: [f32; JOINTS_PER_LEG] = [0.0, 0.349_065_85, 1.221_730_5];
/// Folded (sitting) pose used before stand-up and after sit-down: belly just on the ground.
pub const Q_SIT_LEG_RAD: [f32; JOINTS_PER_LEG] = [0.0, -0.75, 2.35];
/// Lower position limits of hip, thigh, shank.
pub const Q_MIN_LEG_RAD: [f32; JOINTS_PER_LEG] = [-0.785, -0.8, -0.2];
/// Upper position limits of hip, thigh, shank.
pub const Q_MAX_LEG_RAD: [f32; JOINTS_PER_LEG] = [0.785, 1.5, 2.6];
/// Peak torque of hip, thigh, shank drives.
pub const TORQUE_LIMIT_LEG_NM: [f32; JOINTS_PER_LEG] = [30.0, 45.0, 45.0];
/// Speed limit of hip, thigh, shank drives.
pub const VELOCITY_LIMIT_LEG_RAD_S: [f32; JOINTS_PER_LEG] = [12.0, 12.0, 12.0];
/// Reflected rotor inertia (armature) of each drive.
pub const ARMATURE_KG_M2: f32 = 0.01;

/// Nominal joint angles in joint order.
pub const Q0_RAD: [f32; NUM_JOINTS] = per_joint(Q0_LEG_RAD);
/// Sitting joint angles in joint order.
pub const Q_SIT_RAD: [f32; NUM_JOINTS] = per_joint(Q_SIT_LEG_RAD);
/// Lower position limits in joint order.
pub const Q_MIN_RAD: [f32; NUM_JOINTS] = per_joint(Q_MIN_LEG_RAD);
/// Upper position limits in joint order.
pub const Q_MAX_RAD: [f32; NUM_JOINTS] = per_joint(Q_MAX_LEG_RAD);
/// Torque limits in joint order.
pub const TORQUE_LIMIT_NM: [f32; NUM_JOINTS] = per_joint(TORQUE_LIMIT_LEG_NM);
/// Velocity limits in joint order.
pub const VELOCITY_LIMIT_RAD_S: [f32; NUM_JOINTS] = per_joint(VELOCITY_LIMIT_LEG_RAD_S);

/// Repeats a per-leg triple for all six legs.
const fn per_joint(leg: [f32; JOINTS_PER_LEG]) -> [f32; NUM_JOINTS] {
    let mut out = [0.0; NUM_JOINTS];
    let mut i = 0;
    while i < NUM_JOINTS {
        out[i] = leg[i % JOINTS_PER_LEG];
        i += 1;
    }
    out
}

// ---------------------------------------------------------------------------------------
// CAN wiring.
// ---------------------------------------------------------------------------------------

/// CANopen node id of a joint's drive: 1..=18 in joint order.
pub const fn can_node_id(joint_index: usize) -> u8 {
    joint_index as u8 + 1
}

/// CAN bus of a joint's drive: 0 (FDCAN1) for the right legs, 1 (FDCAN2) for the left legs.
pub const fn can_bus(joint_index: usize) -> usize {
    if joint_index < NUM_JOINTS / 2 {
        0
    } else {
        1
    }
}

/// Joint index of a CANopen node id, if it is one of ours.
pub const fn joint_of_node(node_id: u8) -> Option<usize> {
    if node_id >= 1 && node_id as usize <= NUM_JOINTS {
        Some(node_id as usize - 1)
    } else {
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nominal_base_height_is_the_standing_pose_to_the_centimetre() {
        for leg in Leg::ALL {
            let foot = crate::kinematics::foot_position_base(leg, Q0_LEG_RAD);
            let height_m = -foot[2] + FOOT_RADIUS_M;
            assert!(
                (height_m - NOMINAL_BASE_HEIGHT_M).abs() < 0.005,
                "{leg:?}: {height_m}"
            );
        }
    }

    #[test]
    fn total_mass_is_25_5_kg() {
        assert!((TOTAL_MASS_KG - 25.5).abs() < 1e-4, "{TOTAL_MASS_KG}");
    }

    #[test]
    fn tripods_partition_the_legs() {
        assert_eq!(TRIPOD_A_MASK & TRIPOD_B_MASK, 0);
        assert_eq!(TRIPOD_A_MASK | TRIPOD_B_MASK, 0b11_1111);
        for leg in TRIPOD_A {
            assert_eq!(leg.tripod(), Tripod::A);
        }
        for leg in TRIPOD_B {
            assert_eq!(leg.tripod(), Tripod::B);
        }
    }

    #[test]
    fn joint_names_follow_the_order() {
        for leg in Leg::ALL {
            for joint in Joint::ALL {
                let name = JOINT_NAMES[joint_index(leg, joint)];
                assert!(name.starts_with(leg.name()) && name.ends_with(joint.name()));
            }
        }
    }

    #[test]
    fn nominal_pose_within_limits() {
        for i in 0..NUM_JOINTS {
            assert!(Q_MIN_RAD[i] < Q0_RAD[i] && Q0_RAD[i] < Q_MAX_RAD[i]);
            assert!(Q_MIN_RAD[i] < Q_SIT_RAD[i] && Q_SIT_RAD[i] < Q_MAX_RAD[i]);
        }
    }

    #[test]
    fn can_ids_split_right_and_left() {
        for i in 0..NUM_JOINTS {
            assert_eq!(joint_of_node(can_node_id(i)), Some(i));
            assert_eq!(can_bus(i), if Leg::ALL[i / 3].is_right() { 0 } else { 1 });
        }
        assert_eq!(joint_of_node(0), None);
        assert_eq!(joint_of_node(19), None);
    }
}
