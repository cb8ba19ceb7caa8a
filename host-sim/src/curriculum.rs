//! The terrain curriculum: which row of tiles a robot walks on next, from how far it got
//! along its commands against how far they asked it to walk ([`CommandProgress`]).
//!
//! legged_gym compares the straight-line distance from the spawn with `|v_xy| * T`. Under
//! random commands resampled within an episode (turns, reversals) that distance says
//! little: with it, robots on *flat* tiles of a six-row grid stayed at a mean row of 0.6
//! of 5. Progress along the command counts what a robot on a hard tile fails at (it stops
//! at a riser, it slides back down a slope) and nothing else.

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

/// The curriculum rule: up after making good half the tile's side or 80% of the commanded
/// distance, whichever is shorter; down after less than half of it. legged_gym asks for
/// half the tile alone, which this robot's 0.5 m/s commands rarely reach in 20 s (4 m on an
/// 8 m tile).
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

/// How far a robot got along its commands over an episode, against how far they asked.
///
/// Both are path lengths in the base frame: every policy step adds the commanded planar
/// speed to the commanded length, and the base's planar velocity projected on the
/// commanded direction to the progress. A robot that tracks a turning command walks a
/// circle and makes full progress; one stuck at a riser, or drifting sideways off its
/// command, makes none; walking back and forth cancels. Heading drift does not count
/// against it (the displacement of the commanded path, or legged_gym's straight-line
/// distance, would punish a small yaw-rate error over 20 s as much as a fall).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CommandProgress {
    progress_m: f32,
    commanded_m: f32,
}

/// Commanded planar speeds below this carry no direction (standing commands), m/s.
const MIN_COMMAND_SPEED_M_S: f32 = 0.02;

impl CommandProgress {
    /// Adds one step of `dt_s` with `command` (vx, vy, m/s; yaw rate, rad/s) and the base's
    /// planar velocity in the base frame.
    pub fn advance(&mut self, command: [f32; 3], velocity_base_m_s: [f32; 2], dt_s: f32) {
        let speed = command[0].hypot(command[1]);
        if speed < MIN_COMMAND_SPEED_M_S {
            return;
        }
        let along = (velocity_base_m_s[0] * command[0] + velocity_base_m_s[1] * command[1]) / speed;
        self.progress_m += along * dt_s;
        self.commanded_m += speed * dt_s;
    }

    /// Distance made good along the commands, m.
    pub fn progress_m(&self) -> f32 {
        self.progress_m
    }

    /// The commanded path length of the episode, plus the current command's speed over
    /// the `remaining_s` an early fall cut short, m.
    pub fn commanded_m(&self, command: [f32; 3], remaining_s: f32) -> f32 {
        self.commanded_m + command[0].hypot(command[1]) * remaining_s.max(0.0)
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

    fn follow(command: [f32; 3], velocity_base_m_s: [f32; 2], duration_s: f32) -> CommandProgress {
        let mut p = CommandProgress::default();
        for _ in 0..(duration_s / 0.02).round() as usize {
            p.advance(command, velocity_base_m_s, 0.02);
        }
        p
    }

    #[test]
    fn tracking_a_turn_makes_full_progress() {
        // 0.3 m/s at 2*pi/20 rad/s: a circle, back at the start, yet 6 m walked as asked.
        let wz = std::f32::consts::TAU / 20.0;
        let p = follow([0.3, 0.0, wz], [0.3, 0.0], 20.0);
        assert!((p.progress_m() - 6.0).abs() < 1e-3);
        assert!((p.commanded_m([0.3, 0.0, wz], 0.0) - 6.0).abs() < 1e-3);
        assert_eq!(
            curriculum_step(p.progress_m(), p.commanded_m([0.3, 0.0, wz], 0.0), 8.0),
            LevelChange::Up
        );
    }

    #[test]
    fn stalling_drifting_and_pacing_make_no_progress() {
        let stuck = follow([0.0, -0.2, 0.0], [0.0, 0.0], 10.0);
        assert_eq!(stuck.progress_m(), 0.0);
        assert!((stuck.commanded_m([0.0, -0.2, 0.0], 0.0) - 2.0).abs() < 1e-3);
        // Walking sideways when told forward: no progress.
        let drift = follow([0.3, 0.0, 0.0], [0.0, 0.3], 10.0);
        assert!(drift.progress_m().abs() < 1e-4);
        // Back and forth cancels.
        let mut pacing = follow([0.3, 0.0, 0.0], [0.3, 0.0], 5.0);
        for _ in 0..250 {
            pacing.advance([0.3, 0.0, 0.0], [-0.3, 0.0], 0.02);
        }
        assert!(pacing.progress_m().abs() < 1e-3);
        // Standing commands count neither way.
        let stand = follow([0.0, 0.0, 0.5], [0.1, 0.0], 10.0);
        assert_eq!(
            (stand.progress_m(), stand.commanded_m([0.0, 0.0, 0.5], 0.0)),
            (0.0, 0.0)
        );
    }

    #[test]
    fn an_early_fall_still_owes_the_rest_of_the_episode() {
        let p = follow([0.3, 0.0, 0.0], [0.3, 0.0], 5.0);
        let commanded = p.commanded_m([0.3, 0.0, 0.0], 15.0);
        assert!((commanded - 6.0).abs() < 1e-3);
        assert_eq!(
            curriculum_step(p.progress_m(), commanded, 8.0),
            LevelChange::Down
        );
    }
}
