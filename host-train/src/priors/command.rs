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

/// Forward speeds of the dataset's grid, m/s (the training box is [-0.4, 0.5]).
pub const GRID_VX_M_S: [f64; 6] = [-0.4, -0.2, 0.0, 0.2, 0.4, 0.5];
/// Lateral speeds of the grid, m/s (the box is [-0.2, 0.2]).
pub const GRID_VY_M_S: [f64; 3] = [-0.2, 0.0, 0.2];
/// Yaw rates of the grid, rad/s (the box is [-0.5, 0.5]).
pub const GRID_WZ_RAD_S: [f64; 3] = [-0.5, 0.0, 0.5];

/// A readable clip name for a command: `forward_0.2_left_0.2_turn_right_0.5`, `in_place`.
pub fn command_name(vx_m_s: f64, vy_m_s: f64, wz_rad_s: f64) -> String {
    let mut parts = Vec::new();
    let mut part = |v: f64, pos: &str, neg: &str| {
        if v.abs() > 1e-9 {
            parts.push(format!(
                "{}_{}",
                if v > 0.0 { pos } else { neg },
                format!("{:.2}", v.abs())
                    .trim_end_matches('0')
                    .trim_end_matches('.')
            ));
        }
    };
    part(vx_m_s, "forward", "backward");
    part(vy_m_s, "left", "right");
    part(wz_rad_s, "turn_left", "turn_right");
    if parts.is_empty() {
        "in_place".into()
    } else {
        parts.join("_")
    }
}

/// The dataset's commands: the grid over the training command box (every combination of
/// [`GRID_VX_M_S`], [`GRID_VY_M_S`] and [`GRID_WZ_RAD_S`], stepping in place included),
/// plus forward at 0.1 and 0.3 m/s. Any command of the box is then within 0.1 m/s on each
/// axis and 0.25 rad/s of a clip (`dataset::check_command_coverage`).
pub fn default_commands() -> Vec<GaitCommand> {
    let mut commands = Vec::new();
    for vx in GRID_VX_M_S {
        for vy in GRID_VY_M_S {
            for wz in GRID_WZ_RAD_S {
                commands.push(GaitCommand::new(&command_name(vx, vy, wz), vx, vy, wz));
            }
        }
    }
    for vx in [0.1, 0.3] {
        commands.push(GaitCommand::new(&command_name(vx, 0.0, 0.0), vx, 0.0, 0.0));
    }
    commands
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
    fn names_say_the_command() {
        assert_eq!(command_name(0.2, 0.0, 0.0), "forward_0.2");
        assert_eq!(
            command_name(-0.4, 0.2, -0.5),
            "backward_0.4_left_0.2_turn_right_0.5"
        );
        assert_eq!(command_name(0.0, 0.0, 0.0), "in_place");
        let names: std::collections::BTreeSet<String> =
            default_commands().into_iter().map(|c| c.name).collect();
        assert_eq!(names.len(), 56, "names are unique");
    }

    #[test]
    fn a_fixed_point_moves_backwards_in_the_moving_frame() {
        let cmd = GaitCommand::new("f", 0.2, 0.0, 0.0);
        let p = cmd.to_later_frame([0.5, 0.1, 0.0], 0.5);
        assert!((p[0] - 0.4).abs() < 1e-12 && (p[1] - 0.1).abs() < 1e-12);
    }
}
