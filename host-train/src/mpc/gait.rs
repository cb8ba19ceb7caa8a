//! The gait clock: a tripod phase in [0, 1) that runs while the robot is commanded to move
//! and stops, once no leg is in the air, when the command is zero (the robot then stands on
//! all six feet).
//!
//! Tripod A swings for phases in `[0, s)`, tripod B for `[0.5, 0.5 + s)` with `s` the swing
//! fraction; both tripods stand in `[s, 0.5)` and `[0.5 + s, 1)`. A clock at rest sits at
//! phase `s` (A just landed, B about to lift).

use hexapod_core::robot::{Leg, Tripod};

/// The phase clock of one robot.
#[derive(Clone, Copy, Debug)]
pub struct GaitClock {
    phase: f64,
    period_s: f64,
    swing_fraction: f64,
}

/// Where a leg is in its cycle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LegPhase {
    /// On the ground.
    Stance,
    /// In the air: progress through the swing in [0, 1).
    Swing(f64),
}

impl GaitClock {
    /// A clock at rest.
    pub fn new(period_s: f64, swing_fraction: f64) -> Self {
        Self {
            phase: swing_fraction,
            period_s,
            swing_fraction,
        }
    }

    /// The phase in [0, 1).
    pub fn phase(&self) -> f64 {
        self.phase
    }

    /// Phase at which `leg` lifts off.
    fn lift_off_phase(&self, leg: Leg) -> f64 {
        match leg.tripod() {
            Tripod::A => 0.0,
            Tripod::B => 0.5,
        }
    }

    /// The leg's phase at clock phase `phase`.
    pub fn leg_phase_at(&self, leg: Leg, phase: f64) -> LegPhase {
        let since = (phase - self.lift_off_phase(leg)).rem_euclid(1.0);
        // The tolerance keeps a clock stopped at the end of a swing (phase s or 0.5 + s, up to
        // rounding) in stance.
        if since < self.swing_fraction - 1e-9 {
            LegPhase::Swing(since / self.swing_fraction)
        } else {
            LegPhase::Stance
        }
    }

    /// The leg's phase now.
    pub fn leg_phase(&self, leg: Leg) -> LegPhase {
        self.leg_phase_at(leg, self.phase)
    }

    /// True if some leg swings at `phase`.
    fn any_swing(&self, phase: f64) -> bool {
        Leg::ALL
            .iter()
            .any(|&l| matches!(self.leg_phase_at(l, phase), LegPhase::Swing(_)))
    }

    /// The phase `dt_s` from now: advancing while `moving`, otherwise only to the end of a
    /// swing in progress.
    pub fn phase_after(&self, dt_s: f64, moving: bool) -> f64 {
        let advanced = self.phase + dt_s / self.period_s;
        if moving {
            return advanced.rem_euclid(1.0);
        }
        if !self.any_swing(self.phase) {
            return self.phase;
        }
        // The swing in progress ends at s (tripod A) or 0.5 + s (tripod B).
        let end = if self.phase < 0.5 {
            self.swing_fraction
        } else {
            0.5 + self.swing_fraction
        };
        advanced.min(end).rem_euclid(1.0)
    }

    /// Advances the clock by `dt_s`.
    pub fn advance(&mut self, dt_s: f64, moving: bool) {
        self.phase = self.phase_after(dt_s, moving);
    }

    /// Time from now until `leg` touches down, s (for a leg in swing, with the clock running).
    pub fn time_to_touch_down_s(&self, leg: Leg) -> f64 {
        match self.leg_phase(leg) {
            LegPhase::Swing(u) => (1.0 - u) * self.swing_fraction * self.period_s,
            LegPhase::Stance => 0.0,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tripods_alternate_and_the_clock_stops_on_all_feet() {
        let mut c = GaitClock::new(0.6, 0.43);
        assert!(Leg::ALL.iter().all(|&l| c.leg_phase(l) == LegPhase::Stance));
        // Standing: the clock does not move.
        c.advance(0.3, false);
        assert_eq!(c.phase(), 0.43);
        // Walking: B lifts at 0.5, A at 1.0; never both in the air.
        let mut b_swings = false;
        for _ in 0..60 {
            c.advance(0.01, true);
            let a = matches!(c.leg_phase(Leg::RightFront), LegPhase::Swing(_));
            let b = matches!(c.leg_phase(Leg::LeftFront), LegPhase::Swing(_));
            assert!(!(a && b));
            b_swings |= b;
        }
        assert!(b_swings);
        // Stopping mid-swing finishes the swing, then rests.
        let mut c = GaitClock::new(0.6, 0.43);
        c.advance(0.1 * 0.6, true); // phase 0.53: B in swing
        assert!(matches!(c.leg_phase(Leg::LeftFront), LegPhase::Swing(_)));
        for _ in 0..100 {
            c.advance(0.02, false);
        }
        assert!((c.phase() - 0.93).abs() < 1e-9, "{}", c.phase());
        assert!(Leg::ALL.iter().all(|&l| c.leg_phase(l) == LegPhase::Stance));
    }
}
