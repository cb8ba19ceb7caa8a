//! Foot trajectories for a fixed tripod schedule: Raibert footholds in stance, min-jerk
//! swings with clearance.
//!
//! Each stance foothold is placed so that the foot passes under its nominal stance position
//! (forward kinematics of `Q0_RAD`) at mid-stance, which for a constant command is Raibert's
//! rule `p_touchdown = p_nominal + v * T_stance / 2` generalized to turning: the foothold is
//! the nominal position carried by the command's motion. Stance feet are fixed in the world.
//! A swing moves the foot in a straight world-frame line from lift-off to the next foothold
//! with min-jerk timing, while its height follows `h * 64 s^3 (1 - s)^3` (apex `h` at mid-swing,
//! zero vertical velocity and acceleration at lift-off and touch-down), plus, when a contact
//! speed `v` is set, `v T_swing s (1 - s) (1 - 2 s)^2`: the foot leaves and meets the ground at
//! `v` while the apex stays `h` at mid-swing. A foot that meets the ground with some speed
//! touches down when planned even if the body sits a few millimetres off its plan; at zero
//! speed the last millimetres take several frames and the three feet of a tripod land apart.
//! A swing lead widens the foot's path beyond the scheduled swing on both sides
//! ([`FootPlan::with_swing_lead_s`]).
//!
//! Positions are foot sphere centres in the command frame C(t) of [`GaitCommand`].

use super::body::nominal_feet_m;
use super::command::GaitCommand;
use super::geom::{add, mul_mv, rot_z, scale, sub, V3};
use super::schedule::TripodSchedule;
use hexapod_core::robot::Leg;

/// Foot trajectories of one gait.
#[derive(Clone, Debug)]
pub struct FootPlan {
    command: GaitCommand,
    schedule: TripodSchedule,
    clearance_m: f64,
    contact_speed_m_s: f64,
    swing_lead_s: f64,
    nominal_m: [V3; 6],
}

impl FootPlan {
    /// Feet for `command` on `schedule`, lifting `clearance_m` above the ground in swing.
    pub fn new(command: GaitCommand, schedule: TripodSchedule, clearance_m: f64) -> Self {
        Self {
            command,
            schedule,
            clearance_m,
            contact_speed_m_s: 0.0,
            swing_lead_s: 0.0,
            nominal_m: nominal_feet_m(),
        }
    }

    /// The same plan with swing feet leaving and meeting the ground at `speed_m_s` vertically.
    pub fn with_contact_speed_m_s(mut self, speed_m_s: f64) -> Self {
        self.contact_speed_m_s = speed_m_s;
        self
    }

    /// Foot sphere centre of `leg` at time `t_s`, in C(t) coordinates, and whether it is in
    /// stance (by the schedule).
    pub fn foot_m(&self, leg: Leg, t_s: f64) -> (V3, bool) {
        let s = &self.schedule;
        let since_scheduled_lift_off = s.time_since_lift_off_s(leg, t_s);
        let in_stance = since_scheduled_lift_off >= s.swing_s();
        // The foot's path swings over the scheduled swing widened by the lead on both sides;
        // the middle of its stance stays the scheduled one.
        let (t_sw, t_st) = (
            s.swing_s() + 2.0 * self.swing_lead_s,
            s.stance_s() - 2.0 * self.swing_lead_s,
        );
        let since_lift_off =
            (since_scheduled_lift_off + self.swing_lead_s).rem_euclid(s.period_s());
        let nominal = self.nominal_m[leg.index()];
        if since_lift_off >= t_sw {
            // Stance: tau from the middle of this stance.
            let tau = since_lift_off - t_sw - 0.5 * t_st;
            return (self.command.to_later_frame(nominal, tau), in_stance);
        }
        // Swing, interpolated in the (inertial) frame C(t_lift_off).
        let lift_off = self.command.to_later_frame(nominal, 0.5 * t_st);
        let tau_next = t_sw + 0.5 * t_st;
        let touch_down = add(
            self.command.displacement_m(tau_next),
            mul_mv(&rot_z(self.command.yaw_rad(tau_next)), nominal),
        );
        let u = since_lift_off / t_sw;
        let blend = 10.0 * u.powi(3) - 15.0 * u.powi(4) + 6.0 * u.powi(5);
        let mut p = add(lift_off, scale(blend, sub(touch_down, lift_off)));
        p[2] = nominal[2]
            + self.clearance_m * 64.0 * u.powi(3) * (1.0 - u).powi(3)
            + self.contact_speed_m_s * t_sw * u * (1.0 - u) * (1.0 - 2.0 * u).powi(2);
        (self.command.to_later_frame(p, since_lift_off), in_stance)
    }

    /// The same plan with each foot's path leaving the ground `lead_s` before the scheduled
    /// lift-off and meeting it `lead_s` after the scheduled touch-down (contact flags and
    /// forces keep the schedule). Under the drives a loaded foot stays on the ground until
    /// its leg has unloaded, and the body sits lower than planned so a swinging foot meets
    /// the ground early; the lead lets both happen at the scheduled instants. At most just
    /// under half a stance.
    pub fn with_swing_lead_s(mut self, lead_s: f64) -> Self {
        self.swing_lead_s = lead_s.clamp(0.0, 0.49 * self.schedule.stance_s());
        self
    }

    /// The schedule.
    pub fn schedule(&self) -> &TripodSchedule {
        &self.schedule
    }

    /// The command.
    pub fn command(&self) -> &GaitCommand {
        &self.command
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::priors::geom::norm;
    use hexapod_core::robot::FOOT_RADIUS_M;

    fn plan(vx: f64, vy: f64, wz: f64) -> FootPlan {
        FootPlan::new(
            GaitCommand::new("t", vx, vy, wz),
            TripodSchedule::new(30, 13).unwrap(),
            0.08,
        )
    }

    #[test]
    fn trajectories_are_continuous_and_periodic() {
        let p = plan(0.3, 0.1, 0.4);
        let period = p.schedule().period_s();
        for leg in Leg::ALL {
            let mut prev = p.foot_m(leg, -1e-4).0;
            let steps = 3000;
            for i in 0..=steps {
                let t = i as f64 * period / steps as f64;
                let (x, _) = p.foot_m(leg, t);
                // 0.2 ms steps: the foot moves less than 1 mm (5 m/s bound).
                assert!(norm(sub(x, prev)) < 1e-3, "{leg:?} t={t}");
                prev = x;
            }
            let a = p.foot_m(leg, 0.0).0;
            let b = p.foot_m(leg, period).0;
            assert!(norm(sub(a, b)) < 1e-9);
        }
    }

    #[test]
    fn stance_feet_stay_on_the_ground_and_fixed_in_the_world() {
        let p = plan(0.4, 0.0, 0.5);
        let cmd = p.command().clone();
        let dt = 0.01;
        for leg in Leg::ALL {
            for i in 0..60 {
                let t = i as f64 * dt;
                let (a, a_st) = p.foot_m(leg, t);
                let (b, b_st) = p.foot_m(leg, t + dt);
                if a_st && b_st {
                    assert!((a[2] - FOOT_RADIUS_M as f64).abs() < 1e-12);
                    // The world point a, seen from the frame dt later, is b.
                    assert!(
                        norm(sub(cmd.to_later_frame(a, dt), b)) < 1e-9,
                        "{leg:?} {t}"
                    );
                }
            }
        }
    }

    #[test]
    fn swing_meets_the_ground_at_the_contact_speed_and_keeps_its_apex() {
        let speed_m_s = 0.3;
        let p = plan(0.2, 0.0, 0.0).with_contact_speed_m_s(speed_m_s);
        let s = *p.schedule();
        let h = 1e-6;
        for leg in Leg::ALL {
            let (lift_off, touch_down) = (s.lift_off_s(leg), s.lift_off_s(leg) + s.swing_s());
            let up = (p.foot_m(leg, lift_off + h).0[2] - p.foot_m(leg, lift_off).0[2]) / h;
            let down = (p.foot_m(leg, touch_down).0[2] - p.foot_m(leg, touch_down - h).0[2]) / h;
            assert!((up - speed_m_s).abs() < 1e-3, "{leg:?} lift-off {up}");
            assert!((down + speed_m_s).abs() < 1e-3, "{leg:?} touch-down {down}");
            let (apex, _) = p.foot_m(leg, lift_off + 0.5 * s.swing_s());
            assert!((apex[2] - FOOT_RADIUS_M as f64 - 0.08).abs() < 1e-9);
            // Never below the ground in swing.
            for i in 1..100 {
                let (x, stance) = p.foot_m(leg, lift_off + s.swing_s() * i as f64 / 100.0);
                assert!(!stance && x[2] > FOOT_RADIUS_M as f64, "{leg:?} {i}");
            }
        }
    }

    #[test]
    fn a_swing_lead_widens_the_path_and_keeps_the_schedule() {
        let lead_s = 0.04;
        let p = plan(0.3, 0.1, 0.4)
            .with_contact_speed_m_s(0.2)
            .with_swing_lead_s(lead_s);
        let plain = plan(0.3, 0.1, 0.4);
        let s = *p.schedule();
        let ground = FOOT_RADIUS_M as f64;
        let period = s.period_s();
        for leg in Leg::ALL {
            let (lift_off, touch_down) = (s.lift_off_s(leg), s.lift_off_s(leg) + s.swing_s());
            for (t, on_ground) in [
                (lift_off - lead_s - 1e-3, true),
                (lift_off - 0.5 * lead_s, false),
                (touch_down + 0.5 * lead_s, false),
                (touch_down + lead_s + 1e-3, true),
            ] {
                let (x, stance) = p.foot_m(leg, t);
                // The contact flags are the schedule's, lead or not.
                assert_eq!(stance, plain.foot_m(leg, t).1, "{leg:?} {t}");
                assert_eq!((x[2] - ground).abs() < 1e-12, on_ground, "{leg:?} {t}");
            }
            // Continuous and periodic with the lead.
            let mut prev = p.foot_m(leg, -1e-4).0;
            for i in 0..=3000 {
                let x = p.foot_m(leg, i as f64 * period / 3000.0).0;
                assert!(norm(sub(x, prev)) < 1e-3, "{leg:?} {i}");
                prev = x;
            }
            // The middle of the stance is where it was: under the nominal foot.
            let mid = lift_off - 0.5 * s.stance_s();
            assert!(norm(sub(p.foot_m(leg, mid).0, plain.foot_m(leg, mid).0)) < 1e-12);
        }
    }

    #[test]
    fn swing_reaches_the_clearance_at_mid_swing() {
        let p = plan(0.2, 0.0, 0.0);
        let s = *p.schedule();
        for leg in Leg::ALL {
            let mid = s.lift_off_s(leg) + 0.5 * s.swing_s();
            let (x, stance) = p.foot_m(leg, mid);
            assert!(!stance);
            assert!((x[2] - FOOT_RADIUS_M as f64 - 0.08).abs() < 1e-9);
        }
    }
}
