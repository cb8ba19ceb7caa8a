//! One frame of a motion clip and its flat layout in the JSON files.
//!
//! Frame layout (73 numbers, SI units, joint order of `hexapod_core::robot`):
//!
//! | range | field | frame / unit |
//! |---|---|---|
//! | 0..3 | `base_pos` | base origin, world, m (ground at z = 0, so z is the height) |
//! | 3..7 | `base_quat` | base orientation, world, unit quaternion x y z w |
//! | 7..25 | `joint_pos` | joint angles, rad |
//! | 25..43 | `foot_pos` | foot sphere centres, base frame, leg-major, m |
//! | 43..46 | `lin_vel` | base linear velocity, base frame, m/s |
//! | 46..49 | `ang_vel` | base angular velocity, base frame, rad/s |
//! | 49..67 | `joint_vel` | joint velocities, rad/s |
//! | 67..73 | `contact` | foot contact flags (1 on the ground, 0 in swing), leg order |
//!
//! The AMP state of a frame is `hexapod_core::amp::amp_state` of its joint positions and
//! velocities, base velocities and height, exactly as the simulator computes it.

use hexapod_core::amp::{amp_state, AMP_STATE_DIM};
use hexapod_core::robot::{NUM_JOINTS, NUM_LEGS};
use std::ops::Range;

/// Numbers per frame.
pub const FRAME_DIM: usize = 73;
/// Base position, world.
pub const FRAME_BASE_POS: Range<usize> = 0..3;
/// Base orientation quaternion (x, y, z, w), world.
pub const FRAME_BASE_QUAT: Range<usize> = 3..7;
/// Joint positions.
pub const FRAME_JOINT_POS: Range<usize> = 7..25;
/// Foot positions, base frame.
pub const FRAME_FOOT_POS: Range<usize> = 25..43;
/// Base linear velocity, base frame.
pub const FRAME_LIN_VEL: Range<usize> = 43..46;
/// Base angular velocity, base frame.
pub const FRAME_ANG_VEL: Range<usize> = 46..49;
/// Joint velocities.
pub const FRAME_JOINT_VEL: Range<usize> = 49..67;
/// Contact flags.
pub const FRAME_CONTACT: Range<usize> = 67..73;

/// Name of the field at index `i` of a frame, e.g. `joint_pos[4]` or `base_quat[3]`.
pub fn field_name(i: usize) -> String {
    let fields: [(&str, Range<usize>); 8] = [
        ("base_pos", FRAME_BASE_POS),
        ("base_quat", FRAME_BASE_QUAT),
        ("joint_pos", FRAME_JOINT_POS),
        ("foot_pos", FRAME_FOOT_POS),
        ("lin_vel", FRAME_LIN_VEL),
        ("ang_vel", FRAME_ANG_VEL),
        ("joint_vel", FRAME_JOINT_VEL),
        ("contact", FRAME_CONTACT),
    ];
    for (name, range) in fields {
        if range.contains(&i) {
            return format!("{name}[{}]", i - range.start);
        }
    }
    format!("index {i}")
}

/// One instant of a motion.
#[derive(Clone, Debug, PartialEq)]
pub struct Frame {
    /// Base origin, world.
    pub base_pos_world_m: [f32; 3],
    /// Base orientation, world (x, y, z, w).
    pub base_quat_xyzw: [f32; 4],
    /// Joint angles.
    pub joint_pos_rad: [f32; NUM_JOINTS],
    /// Foot sphere centres, base frame.
    pub foot_pos_base_m: [[f32; 3]; NUM_LEGS],
    /// Base linear velocity, base frame.
    pub lin_vel_base_m_s: [f32; 3],
    /// Base angular velocity, base frame.
    pub ang_vel_base_rad_s: [f32; 3],
    /// Joint velocities.
    pub joint_vel_rad_s: [f32; NUM_JOINTS],
    /// Feet on the ground.
    pub contacts: [bool; NUM_LEGS],
}

impl Frame {
    /// The flat layout written to the files.
    pub fn to_row(&self) -> [f32; FRAME_DIM] {
        let mut r = [0.0; FRAME_DIM];
        r[FRAME_BASE_POS].copy_from_slice(&self.base_pos_world_m);
        r[FRAME_BASE_QUAT].copy_from_slice(&self.base_quat_xyzw);
        r[FRAME_JOINT_POS].copy_from_slice(&self.joint_pos_rad);
        for (leg, foot) in self.foot_pos_base_m.iter().enumerate() {
            let s = FRAME_FOOT_POS.start + 3 * leg;
            r[s..s + 3].copy_from_slice(foot);
        }
        r[FRAME_LIN_VEL].copy_from_slice(&self.lin_vel_base_m_s);
        r[FRAME_ANG_VEL].copy_from_slice(&self.ang_vel_base_rad_s);
        r[FRAME_JOINT_VEL].copy_from_slice(&self.joint_vel_rad_s);
        for (leg, &c) in self.contacts.iter().enumerate() {
            r[FRAME_CONTACT.start + leg] = if c { 1.0 } else { 0.0 };
        }
        r
    }

    /// A frame from its flat layout (no validation: see [`super::clip`]).
    pub fn from_row(r: &[f32; FRAME_DIM]) -> Self {
        Self {
            base_pos_world_m: read(r, FRAME_BASE_POS.start),
            base_quat_xyzw: read(r, FRAME_BASE_QUAT.start),
            joint_pos_rad: read(r, FRAME_JOINT_POS.start),
            foot_pos_base_m: std::array::from_fn(|leg| read(r, FRAME_FOOT_POS.start + 3 * leg)),
            lin_vel_base_m_s: read(r, FRAME_LIN_VEL.start),
            ang_vel_base_rad_s: read(r, FRAME_ANG_VEL.start),
            joint_vel_rad_s: read(r, FRAME_JOINT_VEL.start),
            contacts: std::array::from_fn(|leg| r[FRAME_CONTACT.start + leg] > 0.5),
        }
    }

    /// Base height above the (flat) ground.
    pub fn base_height_m(&self) -> f32 {
        self.base_pos_world_m[2]
    }

    /// The AMP state of this frame, by the same function the simulator uses.
    pub fn amp_state(&self) -> [f32; AMP_STATE_DIM] {
        amp_state(
            &self.joint_pos_rad,
            &self.joint_vel_rad_s,
            self.lin_vel_base_m_s,
            self.ang_vel_base_rad_s,
            self.up_base(),
        )
    }

    /// The world's up direction in the base frame.
    pub fn up_base(&self) -> [f32; 3] {
        let [x, y, z, w] = self.base_quat_xyzw;
        // Third row of the rotation matrix (base -> world): R^T e_z.
        [
            2.0 * (x * z - w * y),
            2.0 * (y * z + w * x),
            1.0 - 2.0 * (x * x + y * y),
        ]
    }
}

/// `N` consecutive values of a frame row from `start`.
fn read<const N: usize>(r: &[f32; FRAME_DIM], start: usize) -> [f32; N] {
    std::array::from_fn(|i| r[start + i])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn layout_is_contiguous_and_named() {
        let ranges = [
            FRAME_BASE_POS,
            FRAME_BASE_QUAT,
            FRAME_JOINT_POS,
            FRAME_FOOT_POS,
            FRAME_LIN_VEL,
            FRAME_ANG_VEL,
            FRAME_JOINT_VEL,
            FRAME_CONTACT,
        ];
        assert_eq!(ranges[0].start, 0);
        for w in ranges.windows(2) {
            assert_eq!(w[0].end, w[1].start);
        }
        assert_eq!(ranges[7].end, FRAME_DIM);
        assert_eq!(field_name(7), "joint_pos[0]");
        assert_eq!(field_name(72), "contact[5]");
    }

    #[test]
    fn row_round_trip() {
        let row: [f32; FRAME_DIM] = std::array::from_fn(|i| {
            if FRAME_CONTACT.contains(&i) {
                (i % 2) as f32
            } else {
                i as f32 * 0.5
            }
        });
        assert_eq!(Frame::from_row(&row).to_row(), row);
    }
}
