//! Gait commands (the velocity a clip walks at) and the reference motion they define.
//!
//! A constant command (vx, vy in the base frame, yaw rate wz) moves a reference frame C
//! along a circular arc (a straight line when wz = 0) at ground level: C turns at wz and
//! translates at (vx, vy) in its own axes. The motion is time-homogeneous: the transform from
//! C(t) to C(t + tau) depends on tau only, which is what makes an optimized cycle periodic in
//! C coordinates and repeatable in the world.

use super::geom::{mul_mtv, rot_z, sub, V3};

/// One commanded motion of the dataset.
#[derive(Clone, Debug, PartialEq)]
pub struct GaitCommand {
    /// Clip name (file stem).
    pub name: String,
    /// Forward velocity, base frame.
    pub vx_m_s: f64,
    /// Lateral velocity (left positive), base frame.
    pub vy_m_s: f64,
    /// Yaw rate (counter-clockwise positive).
    pub wz_rad_s: f64,
}

impl GaitCommand {
    /// A named command.
    pub fn new(name: &str, vx_m_s: f64, vy_m_s: f64, wz_rad_s: f64) -> Self {
        Self {
            name: name.to_string(),
            vx_m_s,
            vy_m_s,
            wz_rad_s,
        }
    }

    /// The command as (vx, vy, wz).
    pub fn as_array(&self) -> [f64; 3] {
        [self.vx_m_s, self.vy_m_s, self.wz_rad_s]
    }

    /// Position of C(t + tau) in C(t) coordinates (z = 0) after `tau_s`.
    pub fn displacement_m(&self, tau_s: f64) -> V3 {
        let (vx, vy, w) = (self.vx_m_s, self.vy_m_s, self.wz_rad_s);
        if w.abs() < 1e-9 {
            return [vx * tau_s, vy * tau_s, 0.0];
        }
        let (s, c) = (w * tau_s).sin_cos();
        [
            (s * vx - (1.0 - c) * vy) / w,
            ((1.0 - c) * vx + s * vy) / w,
            0.0,
        ]
    }

    /// Heading of C(t + tau) relative to C(t).
    pub fn yaw_rad(&self, tau_s: f64) -> f64 {
        self.wz_rad_s * tau_s
    }

    /// A point given in C(t) coordinates, expressed in C(t + tau) coordinates.
    pub fn to_later_frame(&self, point_m: V3, tau_s: f64) -> V3 {
        mul_mtv(
            &rot_z(self.yaw_rad(tau_s)),
            sub(point_m, self.displacement_m(tau_s)),
        )
    }
}

/// The dataset's commands: forward and backward at two speeds, lateral, turning, and
/// combinations (forward with turning, diagonals), plus slower variants.
pub fn default_commands() -> Vec<GaitCommand> {
    vec![
        GaitCommand::new("forward_0.1", 0.1, 0.0, 0.0),
        GaitCommand::new("forward_0.2", 0.2, 0.0, 0.0),
        GaitCommand::new("forward_0.3", 0.3, 0.0, 0.0),
        GaitCommand::new("forward_0.4", 0.4, 0.0, 0.0),
        GaitCommand::new("backward_0.2", -0.2, 0.0, 0.0),
        GaitCommand::new("backward_0.4", -0.4, 0.0, 0.0),
        GaitCommand::new("left_0.2", 0.0, 0.2, 0.0),
        GaitCommand::new("right_0.2", 0.0, -0.2, 0.0),
        GaitCommand::new("turn_left_0.5", 0.0, 0.0, 0.5),
        GaitCommand::new("turn_right_0.5", 0.0, 0.0, -0.5),
        GaitCommand::new("forward_0.3_turn_left_0.4", 0.3, 0.0, 0.4),
        GaitCommand::new("forward_0.3_turn_right_0.4", 0.3, 0.0, -0.4),
        GaitCommand::new("diagonal_front_left_0.2", 0.14, 0.14, 0.0),
        GaitCommand::new("diagonal_front_right_0.2", 0.14, -0.14, 0.0),
        GaitCommand::new("diagonal_back_left_0.2", -0.14, 0.14, 0.0),
        GaitCommand::new("diagonal_back_right_0.2", -0.14, -0.14, 0.0),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn displacement_composes_over_time() {
        let cmd = GaitCommand::new("t", 0.3, -0.1, 0.4);
        let (a, b) = (0.17, 0.29);
        // Going a then b equals going a + b.
        let d_a = cmd.displacement_m(a);
        let d_b = cmd.displacement_m(b);
        let rot_a = rot_z(cmd.yaw_rad(a));
        let composed = super::super::geom::add(d_a, super::super::geom::mul_mv(&rot_a, d_b));
        let direct = cmd.displacement_m(a + b);
        for i in 0..3 {
            assert!((composed[i] - direct[i]).abs() < 1e-12);
        }
        // Small tau: velocity equals the command.
        let d = cmd.displacement_m(1e-6);
        assert!((d[0] / 1e-6 - 0.3).abs() < 1e-6 && (d[1] / 1e-6 + 0.1).abs() < 1e-6);
    }

    #[test]
    fn a_fixed_point_moves_backwards_in_the_moving_frame() {
        let cmd = GaitCommand::new("f", 0.2, 0.0, 0.0);
        let p = cmd.to_later_frame([0.5, 0.1, 0.0], 0.5);
        assert!((p[0] - 0.4).abs() < 1e-12 && (p[1] - 0.1).abs() < 1e-12);
    }
}
