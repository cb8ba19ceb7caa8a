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

/// `v` given in the world frame, expressed in the base frame (`R^T v`).
pub fn world_to_base(
    q_base_to_world: &UnitQuaternion<f32>,
    v_world: &Vector3<f32>,
) -> Vector3<f32> {
    q_base_to_world.inverse_transform_vector(v_world)
}

/// `v` given in the base frame, expressed in the world frame (`R v`).
pub fn base_to_world(q_base_to_world: &UnitQuaternion<f32>, v_base: &Vector3<f32>) -> Vector3<f32> {
    q_base_to_world.transform_vector(v_base)
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
