//! Small frame conversions between world and base frames (quaternions as x, y, z, w).

/// Rotates `v` by the inverse of `q`: world vector -> base frame.
pub fn rotate_inverse(q: [f32; 4], v: [f32; 3]) -> [f32; 3] {
    rotate([-q[0], -q[1], -q[2], q[3]], v)
}

/// Rotates `v` by `q`: base vector -> world frame.
pub fn rotate(q: [f32; 4], v: [f32; 3]) -> [f32; 3] {
    let [x, y, z, w] = q;
    // t = 2 * (q_vec x v); v' = v + w t + q_vec x t
    let t = [
        2.0 * (y * v[2] - z * v[1]),
        2.0 * (z * v[0] - x * v[2]),
        2.0 * (x * v[1] - y * v[0]),
    ];
    [
        v[0] + w * t[0] + (y * t[2] - z * t[1]),
        v[1] + w * t[1] + (z * t[0] - x * t[2]),
        v[2] + w * t[2] + (x * t[1] - y * t[0]),
    ]
}

/// Yaw angle of `q`, rad.
pub fn yaw_rad(q: [f32; 4]) -> f32 {
    let [x, y, z, w] = q;
    (2.0 * (w * z + x * y)).atan2(1.0 - 2.0 * (y * y + z * z))
}

/// Quaternion of a yaw rotation.
pub fn quat_from_yaw(yaw_rad: f32) -> [f32; 4] {
    [0.0, 0.0, (yaw_rad / 2.0).sin(), (yaw_rad / 2.0).cos()]
}

/// The Hamilton product `a b` (rotate by `b`, then by `a`).
pub fn quat_mul(a: [f32; 4], b: [f32; 4]) -> [f32; 4] {
    let [ax, ay, az, aw] = a;
    let [bx, by, bz, bw] = b;
    [
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
        aw * bw - ax * bx - ay * by - az * bz,
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn yaw_round_trip_and_rotation() {
        let q = quat_from_yaw(0.7);
        assert!((yaw_rad(q) - 0.7).abs() < 1e-6);
        let v = rotate(q, [1.0, 0.0, 0.0]);
        assert!((v[0] - 0.7f32.cos()).abs() < 1e-6 && (v[1] - 0.7f32.sin()).abs() < 1e-6);
        let back = rotate_inverse(q, v);
        assert!((back[0] - 1.0).abs() < 1e-6 && back[1].abs() < 1e-6);
    }
}
