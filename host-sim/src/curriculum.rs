//! The terrain curriculum: which row of tiles a robot walks on next, from how far it got
//! against how far its commands would have taken it.
//!
//! The commanded distance is the displacement of the *command path*: the base pose
//! integrated from the commands alone (body-frame vx, vy rotated by the integrated yaw
//! rate), from the spawn pose. A robot told to turn 0.5 rad/s for 20 s walks a circle and
//! ends near its start: legged_gym's `|v_xy| * T` would demote it for tracking perfectly.

/// What the terrain curriculum does with a robot at the end of an episode.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LevelChange {
    /// To the next harder row (past the hardest: a random row, as legged_gym).
    Up,
    /// To the next easier row.
    Down,
    /// Same row.
    Stay,
}

/// Shortest commanded distance over an episode that can earn a promotion, m.
pub const MIN_PROMOTION_COMMAND_M: f32 = 1.0;

/// The curriculum rule: up after walking out of the tile (half its side) or 80% of the
/// commanded distance, whichever is shorter; down after less than half of it. legged_gym
/// asks for half the tile alone, which this robot's 0.5 m/s commands rarely reach in 20 s
/// (4 m on an 8 m tile).
pub fn curriculum_step(walked_m: f32, commanded_m: f32, tile_size_m: f32) -> LevelChange {
    let goal_m = (tile_size_m / 2.0).min(0.8 * commanded_m);
    if commanded_m >= MIN_PROMOTION_COMMAND_M && walked_m > goal_m {
        LevelChange::Up
    } else if walked_m < 0.5 * commanded_m {
        LevelChange::Down
    } else {
        LevelChange::Stay
    }
}

/// Where the commands alone would have taken the robot since its spawn.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CommandPath {
    start_m: [f32; 2],
    position_m: [f32; 2],
    yaw_rad: f32,
}

impl CommandPath {
    /// A path starting at the spawn position and heading.
    pub fn new(start_m: [f32; 2], yaw_rad: f32) -> Self {
        Self { start_m, position_m: start_m, yaw_rad }
    }

    /// Follows `command` (vx, vy in the body frame, m/s; yaw rate, rad/s) for `dt_s`.
    pub fn advance(&mut self, command: [f32; 3], dt_s: f32) {
        // Midpoint heading: exact for the yaw, second-order for the position.
        let yaw_mid = self.yaw_rad + 0.5 * command[2] * dt_s;
        let (sin, cos) = yaw_mid.sin_cos();
        self.position_m[0] += (cos * command[0] - sin * command[1]) * dt_s;
        self.position_m[1] += (sin * command[0] + cos * command[1]) * dt_s;
        self.yaw_rad += command[2] * dt_s;
    }

    /// The commanded distance of an episode: the path's displacement so far, plus the
    /// current command's speed over the `remaining_s` an early fall cut short.
    pub fn commanded_distance_m(&self, command: [f32; 3], remaining_s: f32) -> f32 {
        let dx = self.position_m[0] - self.start_m[0];
        let dy = self.position_m[1] - self.start_m[1];
        (dx * dx + dy * dy).sqrt() + command[0].hypot(command[1]) * remaining_s.max(0.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn curriculum_promotes_on_the_commanded_distance_and_demotes_on_half_of_it() {
        // 0.3 m/s for 20 s is 6 m commanded: half the 8 m tile earns the next row, under
        // 3 m loses one.
        assert_eq!(curriculum_step(4.1, 6.0, 8.0), LevelChange::Up);
        // 0.2 m/s: 4 m commanded, 80% of it (3.2 m) earns the next row.
        assert_eq!(curriculum_step(3.3, 4.0, 8.0), LevelChange::Up);
        assert_eq!(curriculum_step(3.1, 4.0, 8.0), LevelChange::Stay);
        assert_eq!(curriculum_step(3.5, 6.0, 8.0), LevelChange::Stay);
        assert_eq!(curriculum_step(2.9, 6.0, 8.0), LevelChange::Down);
        // Fast commands: half the tile suffices.
        assert_eq!(curriculum_step(4.1, 10.0, 8.0), LevelChange::Up);
        // Standing still neither promotes nor demotes.
        assert_eq!(curriculum_step(0.2, 0.0, 8.0), LevelChange::Stay);
        assert_eq!(curriculum_step(0.9, 0.8, 8.0), LevelChange::Stay);
    }

    fn follow(command: [f32; 3], duration_s: f32, yaw_rad: f32) -> CommandPath {
        let mut path = CommandPath::new([1.0, -2.0], yaw_rad);
        for _ in 0..(duration_s / 0.02).round() as usize {
            path.advance(command, 0.02);
        }
        path
    }

    #[test]
    fn straight_commands_cover_speed_times_time_in_the_heading() {
        let path = follow([0.3, 0.0, 0.0], 20.0, std::f32::consts::FRAC_PI_2);
        assert!((path.commanded_distance_m([0.3, 0.0, 0.0], 0.0) - 6.0).abs() < 1e-3);
        // Heading +90 deg: body x is world y.
        assert!((path.position_m[0] - 1.0).abs() < 1e-3);
        assert!((path.position_m[1] - 4.0).abs() < 1e-3);
        let sideways = follow([0.0, -0.2, 0.0], 10.0, 0.0);
        assert!((sideways.position_m[1] - (-4.0)).abs() < 1e-3);
    }

    #[test]
    fn a_full_turn_commands_no_distance() {
        // 0.3 m/s at 2*pi/20 rad/s: one circle of radius 0.95 m in 20 s, back at the start.
        let wz = std::f32::consts::TAU / 20.0;
        let path = follow([0.3, 0.0, wz], 20.0, 0.4);
        assert!(path.commanded_distance_m([0.3, 0.0, wz], 0.0) < 0.01);
        // Half a turn: the circle's diameter.
        let half = follow([0.3, 0.0, wz], 10.0, 0.4);
        let diameter_m = 2.0 * 0.3 / wz;
        assert!((half.commanded_distance_m([0.3, 0.0, wz], 0.0) - diameter_m).abs() < 1e-2);
    }

    #[test]
    fn an_early_fall_still_owes_the_rest_of_the_episode() {
        let path = follow([0.3, 0.0, 0.0], 5.0, 0.0);
        let commanded = path.commanded_distance_m([0.3, 0.0, 0.0], 15.0);
        assert!((commanded - 6.0).abs() < 1e-3);
    }
}
