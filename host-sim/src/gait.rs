//! A scripted open-loop tripod gait: foot trajectories in the base frame turned into joint
//! targets by hexapod-core's inverse kinematics. Used by the demo, the MuJoCo comparison
//! and as a sanity check of the drives; the learned policy replaces it.

use hexapod_core::kinematics::{foot_positions_base, leg_inverse_kinematics};
use hexapod_core::robot::{Leg, NUM_JOINTS, NUM_LEGS, Q0_RAD, TRIPOD_A_MASK};

/// Parameters of the scripted gait.
#[derive(Clone, Copy, Debug)]
pub struct TripodGait {
    /// Gait period, s.
    pub period_s: f32,
    /// Base velocity to walk at (x forward, y left), m/s.
    pub velocity_m_s: [f32; 2],
    /// Yaw rate to turn at (counter-clockwise seen from above), rad/s.
    pub yaw_rate_rad_s: f32,
    /// Foot lift at mid-swing, m.
    pub step_height_m: f32,
}

impl Default for TripodGait {
    fn default() -> Self {
        Self {
            period_s: 0.6,
            velocity_m_s: [0.2, 0.0],
            yaw_rate_rad_s: 0.0,
            step_height_m: 0.06,
        }
    }
}

impl TripodGait {
    /// Joint targets at time `t_s`. Tripod A swings in the first half period, B in the second.
    pub fn joint_targets(&self, t_s: f32) -> [f32; NUM_JOINTS] {
        let nominal = foot_positions_base(&Q0_RAD);
        let phase = (t_s / self.period_s).rem_euclid(1.0);
        let half_period_s = self.period_s / 2.0;
        let [vx, vy] = self.velocity_m_s;
        let wz = self.yaw_rate_rad_s;
        let mut q = Q0_RAD;
        for leg in Leg::ALL {
            let in_a = TRIPOD_A_MASK & (1 << leg.index()) != 0;
            let leg_phase = if in_a { phase } else { (phase + 0.5) % 1.0 };
            // leg_phase in [0, 0.5): swing forward; [0.5, 1): stance, foot moves backward.
            let (s, lift) = if leg_phase < 0.5 {
                let u = leg_phase / 0.5;
                let smooth = u * u * (3.0 - 2.0 * u);
                (-0.5 + smooth, (std::f32::consts::PI * u).sin())
            } else {
                let u = (leg_phase - 0.5) / 0.5;
                (0.5 - u, 0.0)
            };
            let n = nominal[leg.index()];
            // Stride: how far the ground under this foot moves in the base frame while the
            // foot stands on it, (v + w x p) over half a period.
            let stride = [
                (vx - wz * n[1]) * half_period_s,
                (vy + wz * n[0]) * half_period_s,
            ];
            let foot = [
                n[0] + s * stride[0],
                n[1] + s * stride[1],
                n[2] + lift * self.step_height_m,
            ];
            if let Ok(angles) = leg_inverse_kinematics(leg, foot) {
                q[3 * leg.index()..3 * leg.index() + 3].copy_from_slice(&angles);
            }
        }
        q
    }

    /// Which feet the schedule has on the ground at `t_s` (bit i = leg i).
    pub fn stance_mask(&self, t_s: f32) -> u8 {
        let phase = (t_s / self.period_s).rem_euclid(1.0);
        let a_swings = phase < 0.5;
        let mut mask = 0;
        for leg in 0..NUM_LEGS {
            let in_a = TRIPOD_A_MASK & (1 << leg) != 0;
            if in_a != a_swings {
                mask |= 1 << leg;
            }
        }
        mask
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stance_alternates_between_tripods() {
        let g = TripodGait::default();
        assert_eq!(g.stance_mask(0.1), !TRIPOD_A_MASK & 0b11_1111);
        assert_eq!(g.stance_mask(0.4), TRIPOD_A_MASK);
    }

    #[test]
    fn targets_are_continuous() {
        let g = TripodGait::default();
        let mut prev = g.joint_targets(0.0);
        for k in 1..300 {
            let q = g.joint_targets(k as f32 * 0.005);
            for j in 0..NUM_JOINTS {
                assert!((q[j] - prev[j]).abs() < 0.05, "jump at step {k}, joint {j}");
            }
            prev = q;
        }
    }

    #[test]
    fn turning_in_place_sweeps_stance_feet_around_the_base() {
        // At t = 0.3 s tripod A is at the start of its stance and at t = 0.6 s at its end;
        // turning left at w, a stance foot at p must move by -(w x p) * T/2 in the base frame.
        let g = TripodGait {
            velocity_m_s: [0.0, 0.0],
            yaw_rate_rad_s: 0.4,
            ..Default::default()
        };
        let (start, end) = (
            foot_positions_base(&g.joint_targets(0.3)),
            foot_positions_base(&g.joint_targets(0.6 - 1e-4)),
        );
        let nominal = foot_positions_base(&Q0_RAD);
        for leg in 0..NUM_LEGS {
            if TRIPOD_A_MASK & (1 << leg) == 0 {
                continue;
            }
            let p = nominal[leg];
            let want = [0.4 * p[1] * 0.3, -0.4 * p[0] * 0.3];
            for k in 0..2 {
                let moved = end[leg][k] - start[leg][k];
                assert!(
                    (moved - want[k]).abs() < 2e-3,
                    "leg {leg} axis {k}: {moved} vs {}",
                    want[k]
                );
            }
        }
    }
}
