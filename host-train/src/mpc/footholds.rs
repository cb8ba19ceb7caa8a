//! Footholds and swing trajectories, in the world frame.
//!
//! A swinging foot lands where its nominal stance position (the forward kinematics of
//! `Q0_RAD`) will be at the middle of its next stance if the base follows the command:
//! Raibert's rule `p = p_nominal + v T_stance / 2` carried along the commanded turn, as the
//! motion priors place their footholds ([`crate::priors::feet`]), plus Raibert's feedback
//! `k (v - v_cmd)` on the measured velocity. The foothold is recomputed at every control step,
//! so the swing follows the robot's actual motion. The swing moves in a straight line from
//! lift-off to the foothold with min-jerk timing while its height follows
//! `h 64 u^3 (1 - u)^3` above the ground (apex `h` at mid-swing), as the priors' swings do.

/// Largest foothold shift of Raibert's feedback term, m (keeps the foothold reachable).
pub const MAX_FEEDBACK_SHIFT_M: f64 = 0.10;

/// Planar rotation of `v` by `angle_rad`.
pub fn rotate_xy(angle_rad: f64, v: [f64; 2]) -> [f64; 2] {
    let (s, c) = angle_rad.sin_cos();
    [c * v[0] - s * v[1], s * v[0] + c * v[1]]
}

/// World displacement of a base that starts at heading `yaw_rad` and moves at the body-frame
/// velocity `v_body` (vx, vy) while turning at `wz_rad_s`, after `t_s`.
pub fn displacement_m(yaw_rad: f64, v_body: [f64; 2], wz_rad_s: f64, t_s: f64) -> [f64; 2] {
    if (wz_rad_s * t_s).abs() < 1e-6 {
        return rotate_xy(yaw_rad, [v_body[0] * t_s, v_body[1] * t_s]);
    }
    let (a, b) = (yaw_rad, yaw_rad + wz_rad_s * t_s);
    // Integral of R(yaw + w t) v over [0, t].
    let int_cos = (b.sin() - a.sin()) / wz_rad_s;
    let int_sin = (a.cos() - b.cos()) / wz_rad_s;
    [
        v_body[0] * int_cos - v_body[1] * int_sin,
        v_body[0] * int_sin + v_body[1] * int_cos,
    ]
}

/// What a foothold depends on.
#[derive(Clone, Copy, Debug)]
pub struct FootholdInput {
    /// Base position in the world, xy, m.
    pub base_xy_m: [f64; 2],
    /// Base heading, rad.
    pub yaw_rad: f64,
    /// Command: body-frame velocity (vx, vy), m/s, and yaw rate, rad/s.
    pub command: [f64; 3],
    /// Measured base velocity in the world, xy, m/s.
    pub velocity_xy_m_s: [f64; 2],
    /// Stance time of a leg, s.
    pub stance_s: f64,
    /// Raibert's feedback gain, s.
    pub raibert_gain_s: f64,
}

/// World xy of the foothold of a foot whose nominal position in the base frame is
/// `nominal_xy_m` and which touches down `t_touch_down_s` from now.
pub fn foothold_xy_m(i: &FootholdInput, nominal_xy_m: [f64; 2], t_touch_down_s: f64) -> [f64; 2] {
    let v_cmd = [i.command[0], i.command[1]];
    let wz = i.command[2];
    let tau = t_touch_down_s + 0.5 * i.stance_s;
    let d = displacement_m(i.yaw_rad, v_cmd, wz, tau);
    let n = rotate_xy(i.yaw_rad + wz * tau, nominal_xy_m);
    let v_cmd_world = rotate_xy(i.yaw_rad, v_cmd);
    let fb = [0, 1].map(|k| {
        (i.raibert_gain_s * (i.velocity_xy_m_s[k] - v_cmd_world[k]))
            .clamp(-MAX_FEEDBACK_SHIFT_M, MAX_FEEDBACK_SHIFT_M)
    });
    [0, 1].map(|k| i.base_xy_m[k] + d[k] + n[k] + fb[k])
}

/// Min-jerk blend of progress `u` in [0, 1].
pub fn min_jerk(u: f64) -> f64 {
    let u = u.clamp(0.0, 1.0);
    u * u * u * (10.0 - 15.0 * u + 6.0 * u * u)
}

/// World position of a swinging foot (sphere centre) at progress `u`: from `lift_off_m`
/// to `(foothold_xy_m, landing_z_m)`, `lift_m` above the straight line at mid-swing.
pub fn swing_point_m(
    lift_off_m: [f64; 3],
    foothold_xy_m: [f64; 2],
    landing_z_m: f64,
    lift_m: f64,
    u: f64,
) -> [f64; 3] {
    let b = min_jerk(u);
    let u = u.clamp(0.0, 1.0);
    let bump = 64.0 * u.powi(3) * (1.0 - u).powi(3);
    [
        lift_off_m[0] + b * (foothold_xy_m[0] - lift_off_m[0]),
        lift_off_m[1] + b * (foothold_xy_m[1] - lift_off_m[1]),
        lift_off_m[2] + b * (landing_z_m - lift_off_m[2]) + lift_m * bump,
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn turning_displacement_matches_integration() {
        let (yaw, v, w, t) = (0.4, [0.3, -0.1], 0.7, 0.9);
        let mut p = [0.0; 2];
        let n = 100_000;
        for k in 0..n {
            let tk = (k as f64 + 0.5) * t / n as f64;
            let r = rotate_xy(yaw + w * tk, v);
            p[0] += r[0] * t / n as f64;
            p[1] += r[1] * t / n as f64;
        }
        let d = displacement_m(yaw, v, w, t);
        assert!((d[0] - p[0]).abs() < 1e-9 && (d[1] - p[1]).abs() < 1e-9);
        let s = displacement_m(yaw, v, 0.0, t);
        let r = rotate_xy(yaw, [v[0] * t, v[1] * t]);
        assert!((s[0] - r[0]).abs() < 1e-12 && (s[1] - r[1]).abs() < 1e-12);
    }

    #[test]
    fn foothold_is_raibert_at_constant_velocity() {
        // Walking straight at 0.3 m/s, on command: the foot lands T_st / 2 ahead of where its
        // nominal point is at touch-down.
        let i = FootholdInput {
            base_xy_m: [1.0, 2.0],
            yaw_rad: 0.0,
            command: [0.3, 0.0, 0.0],
            velocity_xy_m_s: [0.3, 0.0],
            stance_s: 0.34,
            raibert_gain_s: 0.1,
        };
        let f = foothold_xy_m(&i, [0.3, -0.2], 0.1);
        assert!((f[0] - (1.0 + 0.3 * 0.1 + 0.3 + 0.3 * 0.17)).abs() < 1e-12);
        assert!((f[1] - (2.0 - 0.2)).abs() < 1e-12);
        // Too slow: the foot lands further back (closer), by the gain times the error.
        let slow = FootholdInput {
            velocity_xy_m_s: [0.1, 0.0],
            ..i
        };
        let g = foothold_xy_m(&slow, [0.3, -0.2], 0.1);
        assert!((f[0] - g[0] - 0.02).abs() < 1e-12);
    }

    #[test]
    fn swing_starts_and_ends_on_the_ground_and_peaks_at_the_lift_height() {
        let lo = [0.0, 0.0, 0.02];
        let p0 = swing_point_m(lo, [0.2, 0.1], 0.02, 0.08, 0.0);
        let p1 = swing_point_m(lo, [0.2, 0.1], 0.02, 0.08, 1.0);
        let mid = swing_point_m(lo, [0.2, 0.1], 0.02, 0.08, 0.5);
        assert_eq!(p0, lo);
        assert!((p1[0] - 0.2).abs() < 1e-12 && (p1[1] - 0.1).abs() < 1e-12);
        assert!((p1[2] - 0.02).abs() < 1e-12);
        assert!((mid[2] - 0.10).abs() < 1e-12 && (mid[0] - 0.1).abs() < 1e-12);
    }
}
