//! The fixed tripod contact schedule: which feet are on the ground at each frame.
//!
//! One gait cycle has `frames_per_cycle` frames of `POLICY_DT_S`. Tripod A swings first,
//! tripod B half a cycle later; each swing lasts `swing_frames` frames, so every leg is on the
//! ground for `frames_per_cycle - swing_frames` frames (duty factor >= 0.5 when
//! `swing_frames <= frames_per_cycle / 2`). Swing intervals are placed half a frame after a
//! frame instant, so lift-off and touch-down fall between frames and no frame sits exactly on
//! a contact switch.

use hexapod_core::robot::{Leg, Tripod, NUM_LEGS};
use hexapod_core::timing::POLICY_DT_S;

/// Why a schedule cannot be built.
#[derive(Debug, thiserror::Error, PartialEq, Eq)]
pub enum ScheduleError {
    /// The cycle must have an even number of frames (so B starts exactly half a cycle after A).
    #[error("frames per cycle must be even and at least 4, got {0}")]
    FramesPerCycle(usize),
    /// Swing must be at least one frame and leave a duty factor of at least 0.5.
    #[error("swing frames must be in 1..={max}, got {got}")]
    SwingFrames {
        /// Requested swing length.
        got: usize,
        /// Longest swing with duty factor >= 0.5.
        max: usize,
    },
}

/// A periodic tripod schedule on the policy frame grid.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TripodSchedule {
    frames_per_cycle: usize,
    swing_frames: usize,
}

impl TripodSchedule {
    /// A schedule of `frames_per_cycle` frames in which each tripod swings for `swing_frames`.
    pub fn new(frames_per_cycle: usize, swing_frames: usize) -> Result<Self, ScheduleError> {
        if frames_per_cycle < 4 || !frames_per_cycle.is_multiple_of(2) {
            return Err(ScheduleError::FramesPerCycle(frames_per_cycle));
        }
        let max = frames_per_cycle / 2;
        if swing_frames == 0 || swing_frames > max {
            return Err(ScheduleError::SwingFrames {
                got: swing_frames,
                max,
            });
        }
        Ok(Self {
            frames_per_cycle,
            swing_frames,
        })
    }

    /// Frames in one cycle.
    pub fn frames_per_cycle(&self) -> usize {
        self.frames_per_cycle
    }

    /// Frame duration (the policy period).
    pub fn frame_dt_s(&self) -> f64 {
        POLICY_DT_S as f64
    }

    /// Cycle period.
    pub fn period_s(&self) -> f64 {
        self.frames_per_cycle as f64 * self.frame_dt_s()
    }

    /// Swing duration of one leg.
    pub fn swing_s(&self) -> f64 {
        self.swing_frames as f64 * self.frame_dt_s()
    }

    /// Stance duration of one leg.
    pub fn stance_s(&self) -> f64 {
        self.period_s() - self.swing_s()
    }

    /// Fraction of the cycle a leg spends on the ground.
    pub fn duty_factor(&self) -> f64 {
        1.0 - self.swing_frames as f64 / self.frames_per_cycle as f64
    }

    /// Time at which the leg lifts off within the cycle (`[0, period)`).
    pub fn lift_off_s(&self, leg: Leg) -> f64 {
        let offset_frames = match leg.tripod() {
            Tripod::A => 0.5,
            Tripod::B => 0.5 + (self.frames_per_cycle / 2) as f64,
        };
        offset_frames * self.frame_dt_s()
    }

    /// Time of the middle of the stance that ends at [`Self::lift_off_s`].
    pub fn stance_mid_s(&self, leg: Leg) -> f64 {
        self.lift_off_s(leg) - 0.5 * self.stance_s()
    }

    /// Time since lift-off, wrapped into `[0, period)`.
    pub fn time_since_lift_off_s(&self, leg: Leg, t_s: f64) -> f64 {
        (t_s - self.lift_off_s(leg)).rem_euclid(self.period_s())
    }

    /// True if the leg is on the ground at frame `k` (any integer; the schedule is periodic).
    pub fn in_stance(&self, leg: Leg, k: i64) -> bool {
        let t = k as f64 * self.frame_dt_s();
        self.time_since_lift_off_s(leg, t) > self.swing_s()
    }

    /// Contact flags of all legs at frame `k`.
    pub fn contacts(&self, k: i64) -> [bool; NUM_LEGS] {
        Leg::ALL.map(|leg| self.in_stance(leg, k))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use hexapod_core::robot::{TRIPOD_A, TRIPOD_B};

    #[test]
    fn rejects_bad_schedules() {
        assert_eq!(
            TripodSchedule::new(29, 10),
            Err(ScheduleError::FramesPerCycle(29))
        );
        assert!(matches!(
            TripodSchedule::new(30, 16),
            Err(ScheduleError::SwingFrames { .. })
        ));
        assert!(matches!(
            TripodSchedule::new(30, 0),
            Err(ScheduleError::SwingFrames { .. })
        ));
    }

    #[test]
    fn tripods_alternate_and_never_swing_together() {
        let s = TripodSchedule::new(30, 13).unwrap();
        let n = s.frames_per_cycle() as i64;
        let mut swing_starts = Vec::new();
        for k in 0..n {
            let c = s.contacts(k);
            // Legs of one tripod always share their contact state.
            for set in [TRIPOD_A, TRIPOD_B] {
                assert!(
                    set.iter().all(|l| c[l.index()] == c[set[0].index()]),
                    "frame {k}"
                );
            }
            let a = c[TRIPOD_A[0].index()];
            let b = c[TRIPOD_B[0].index()];
            assert!(a || b, "frame {k}: both tripods in the air");
            let a_prev = s.in_stance(TRIPOD_A[0], k - 1);
            let b_prev = s.in_stance(TRIPOD_B[0], k - 1);
            if a_prev && !a {
                swing_starts.push(('A', k));
            }
            if b_prev && !b {
                swing_starts.push(('B', k));
            }
        }
        // One swing of each tripod per cycle, A then B, half a cycle apart.
        assert_eq!(swing_starts, vec![('A', 1), ('B', 16)]);
    }

    #[test]
    fn duty_factor_is_at_least_one_half() {
        for (n, sw) in [(30, 13), (28, 14), (30, 15), (24, 10)] {
            let s = TripodSchedule::new(n, sw).unwrap();
            assert!(s.duty_factor() >= 0.5);
            for leg in Leg::ALL {
                let stance = (0..n as i64).filter(|&k| s.in_stance(leg, k)).count();
                assert_eq!(stance, n - sw, "{leg:?}");
                assert!(stance as f64 / n as f64 >= 0.5);
            }
        }
    }

    #[test]
    fn stance_middle_is_half_a_stance_before_lift_off() {
        let s = TripodSchedule::new(30, 13).unwrap();
        for leg in Leg::ALL {
            let mid = s.stance_mid_s(leg);
            assert!((s.lift_off_s(leg) - mid - s.stance_s() / 2.0).abs() < 1e-12);
            // The middle of the stance is on the ground.
            assert!(s.time_since_lift_off_s(leg, mid) > s.swing_s());
        }
    }
}
