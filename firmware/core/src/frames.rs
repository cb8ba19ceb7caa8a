//! Frame conversions between the world and the base, on nalgebra's types (the version
//! rapier uses, so the simulator's quaternions and vectors convert without copies of
//! formulas). Orientations are base -> world; arrays are (w, x, y, z) for quaternions and
//! (x, y, z) for vectors.

use nalgebra::{Quaternion, UnitQuaternion, Vector3};

/// A base -> world orientation from (w, x, y, z), taken as given (a unit quaternion up to
/// rounding; not renormalized, so the conversion is exact).
pub fn orientation_wxyz(q: [f32; 4]) -> UnitQuaternion<f32> {
    UnitQuaternion::new_unchecked(Quaternion::new(q[0], q[1], q[2], q[3]))
}

/// The rotation matrix (rows) of a base -> world orientation, each entry written out from
/// (w, x, y, z) as the array version of the IMU model had it (diagonal `1 - 2 (..)`).
/// nalgebra's `transform_vector` (`v + w t + q_v x t`, `t = 2 q_v x v`) and
/// `to_rotation_matrix` (diagonal `w^2 + x^2 - ..`) round differently; these conversions
/// keep the array version's bits.
fn rotation_rows(q: &UnitQuaternion<f32>) -> [[f32; 3]; 3] {
    let (w, x, y, z) = (q.w, q.i, q.j, q.k);
    [
        [
            1.0 - 2.0 * (y * y + z * z),
            2.0 * (x * y - w * z),
            2.0 * (x * z + w * y),
        ],
        [
            2.0 * (x * y + w * z),
            1.0 - 2.0 * (x * x + z * z),
            2.0 * (y * z - w * x),
        ],
        [
            2.0 * (x * z - w * y),
            2.0 * (y * z + w * x),
            1.0 - 2.0 * (x * x + y * y),
        ],
    ]
}

/// `v` given in the world frame, expressed in the base frame (`R^T v`).
pub fn world_to_base(
    q_base_to_world: &UnitQuaternion<f32>,
    v_world: &Vector3<f32>,
) -> Vector3<f32> {
    let r = rotation_rows(q_base_to_world);
    let v = v_world;
    Vector3::new(
        r[0][0] * v.x + r[1][0] * v.y + r[2][0] * v.z,
        r[0][1] * v.x + r[1][1] * v.y + r[2][1] * v.z,
        r[0][2] * v.x + r[1][2] * v.y + r[2][2] * v.z,
    )
}

/// `v` given in the base frame, expressed in the world frame (`R v`).
pub fn base_to_world(q_base_to_world: &UnitQuaternion<f32>, v_base: &Vector3<f32>) -> Vector3<f32> {
    let r = rotation_rows(q_base_to_world);
    let v = v_base;
    Vector3::new(
        r[0][0] * v.x + r[0][1] * v.y + r[0][2] * v.z,
        r[1][0] * v.x + r[1][1] * v.y + r[1][2] * v.z,
        r[2][0] * v.x + r[2][1] * v.y + r[2][2] * v.z,
    )
}

/// Unit gravity direction in the base frame (the observation's projected gravity).
pub fn projected_gravity(q_base_to_world: &UnitQuaternion<f32>) -> Vector3<f32> {
    -crate::attitude::up_in_base(q_base_to_world)
}

/// [`world_to_base`] on arrays: orientation (w, x, y, z), vector (x, y, z).
pub fn world_to_base_wxyz(q: [f32; 4], v_world: [f32; 3]) -> [f32; 3] {
    world_to_base(&orientation_wxyz(q), &v_world.into()).into()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The IMU model's array formula before the move to nalgebra (`R^T v`).
    fn world_to_base_array(q: [f32; 4], v: [f32; 3]) -> [f32; 3] {
        let [w, x, y, z] = q;
        let r = [
            [
                1.0 - 2.0 * (y * y + z * z),
                2.0 * (x * y - w * z),
                2.0 * (x * z + w * y),
            ],
            [
                2.0 * (x * y + w * z),
                1.0 - 2.0 * (x * x + z * z),
                2.0 * (y * z - w * x),
            ],
            [
                2.0 * (x * z - w * y),
                2.0 * (y * z + w * x),
                1.0 - 2.0 * (x * x + y * y),
            ],
        ];
        [
            r[0][0] * v[0] + r[1][0] * v[1] + r[2][0] * v[2],
            r[0][1] * v[0] + r[1][1] * v[1] + r[2][1] * v[2],
            r[0][2] * v[0] + r[1][2] * v[1] + r[2][2] * v[2],
        ]
    }

    #[test]
    fn world_to_base_keeps_the_array_formulas_bits() {
        let mut s: u32 = 0x2545_f491;
        let mut next = || {
            s ^= s << 13;
            s ^= s >> 17;
            s ^= s << 5;
            (s >> 8) as f32 / (1 << 24) as f32 * 2.0 - 1.0
        };
        for _ in 0..2000 {
            let q = [1.0 + 0.2 * next(), 0.2 * next(), 0.2 * next(), next()];
            let n = libm::sqrtf(q.iter().map(|a| a * a).sum());
            let q = q.map(|a| a / n);
            let v = [next(), next(), -9.8 + next()];
            let got = world_to_base_wxyz(q, v).map(f32::to_bits);
            assert_eq!(
                got,
                world_to_base_array(q, v).map(f32::to_bits),
                "{q:?} {v:?}"
            );
        }
    }

    #[test]
    fn rolled_base_sees_gravity_sideways() {
        // Rolled by 0.3 rad about x: the world's down (0, 0, -1) in the base frame.
        let (s, c) = (0.15f32.sin(), 0.15f32.cos());
        let q = [c, s, 0.0, 0.0];
        let g = world_to_base_wxyz(q, [0.0, 0.0, -1.0]);
        assert!(
            (g[1] + 0.3f32.sin()).abs() < 1e-6 && (g[2] + 0.3f32.cos()).abs() < 1e-6,
            "{g:?}"
        );
        let pg = projected_gravity(&orientation_wxyz(q));
        for k in 0..3 {
            assert!((pg[k] - g[k]).abs() < 1e-6);
        }
        let back = base_to_world(&orientation_wxyz(q), &g.into());
        assert!((back - Vector3::new(0.0, 0.0, -1.0)).norm() < 1e-6);
    }
}
