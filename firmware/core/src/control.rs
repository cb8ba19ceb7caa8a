//! The 50 Hz control step: observation from drives and IMU, history, the policy, safety
//! clamps on the targets.
//!
//! The policy plugs in through [`Policy`]; [`NnPolicy`] adapts the fixed-point runtime of
//! [`crate::nn`]. The step keeps the history and the previous action exactly as the
//! simulator does after a reset (history filled with the first observation, previous
//! action zero), and guarantees targets that are finite, within the joint limits, and do
//! not move faster than the joints' velocity limits.

use crate::nn::{Kernel, QuantizedPolicy, Scratch};
use crate::obs::{proprio_obs_vec, ProprioHistory, ACTION_CLIP, PROPRIO_DIM};
use crate::robot::{NUM_JOINTS, Q0_RAD, Q_MAX_RAD, Q_MIN_RAD, VELOCITY_LIMIT_RAD_S};
use crate::timing::{ACTION_SCALE_RAD, POLICY_DT_S};
use nalgebra::Vector3;

/// A locomotion policy: command, previous action and history -> action (18, unscaled).
pub trait Policy {
    /// One step. `history.newest()` is the current o^p. `None` when the policy cannot
    /// produce an action (e.g. its runtime rejected the input).
    fn act(
        &mut self,
        command: [f32; 3],
        prev_action: &[f32; NUM_JOINTS],
        history: &ProprioHistory,
    ) -> Option<[f32; NUM_JOINTS]>;
}

/// The generated fixed-point policy as a [`Policy`], with `W` words of scratch.
pub struct NnPolicy<'p, const W: usize> {
    policy: &'p QuantizedPolicy<'p>,
    scratch: Scratch<W>,
    kernel: Kernel,
}

impl<'p, const W: usize> NnPolicy<'p, W> {
    /// Wraps a validated policy; `None` if it is invalid or `W` is too small.
    pub fn new(policy: &'p QuantizedPolicy<'p>, kernel: Kernel) -> Option<Self> {
        policy.validate().ok()?;
        (policy.scratch_words() <= W).then(|| Self {
            policy,
            scratch: Scratch::default(),
            kernel,
        })
    }
}

impl<const W: usize> Policy for NnPolicy<'_, W> {
    fn act(
        &mut self,
        command: [f32; 3],
        prev_action: &[f32; NUM_JOINTS],
        history: &ProprioHistory,
    ) -> Option<[f32; NUM_JOINTS]> {
        self.policy
            .step(
                &mut self.scratch,
                command,
                prev_action,
                history,
                self.kernel,
            )
            .ok()
            .map(|out| out.action)
    }
}

/// What the sensors say this cycle.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Sensors {
    /// Base angular velocity (gyro), base frame, rad/s.
    pub ang_vel_base_rad_s: [f32; 3],
    /// Unit gravity direction in the base frame (attitude filter).
    pub gravity_base: [f32; 3],
    /// Joint positions, rad.
    pub q_rad: [f32; NUM_JOINTS],
    /// Joint velocities, rad/s.
    pub qdot_rad_s: [f32; NUM_JOINTS],
}

impl Sensors {
    /// The gyro's angular velocity as a vector (base frame, rad/s).
    pub fn ang_vel_base(&self) -> Vector3<f32> {
        self.ang_vel_base_rad_s.into()
    }

    /// The projected gravity as a vector (base frame, unit).
    pub fn gravity(&self) -> Vector3<f32> {
        self.gravity_base.into()
    }
}

/// Why a control step produced no targets.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ControlError {
    /// A sensor value is NaN or infinite.
    NonFiniteObservation,
    /// The policy returned nothing, or a NaN or infinite action.
    NonFiniteAction,
}

/// How far a target may move in one policy step: the joint's velocity limit.
pub fn max_target_step_rad(joint: usize) -> f32 {
    VELOCITY_LIMIT_RAD_S[joint] * POLICY_DT_S
}

/// Clamps targets to the joint limits and to a per-step rate limit around `previous`.
pub fn clamp_targets(
    targets: &[f32; NUM_JOINTS],
    previous: &[f32; NUM_JOINTS],
) -> [f32; NUM_JOINTS] {
    let mut out = [0.0; NUM_JOINTS];
    for j in 0..NUM_JOINTS {
        let step = max_target_step_rad(j);
        let t = targets[j].clamp(previous[j] - step, previous[j] + step);
        out[j] = t.clamp(Q_MIN_RAD[j], Q_MAX_RAD[j]);
    }
    out
}

/// The action path the firmware and the simulator share: the policy's action clipped to
/// `ACTION_CLIP`, offset from the nominal pose by `ACTION_SCALE_RAD`, then clamped to the
/// joint limits and to one policy step's travel at the joint's velocity limit from
/// `previous_targets`. Returns the clipped action (what the next observation feeds back)
/// and the targets.
pub fn action_to_targets(
    action: &[f32; NUM_JOINTS],
    previous_targets: &[f32; NUM_JOINTS],
) -> ([f32; NUM_JOINTS], [f32; NUM_JOINTS]) {
    let clipped = action.map(|a| a.clamp(-ACTION_CLIP, ACTION_CLIP));
    let mut targets = [0.0; NUM_JOINTS];
    for j in 0..NUM_JOINTS {
        targets[j] = Q0_RAD[j] + ACTION_SCALE_RAD * clipped[j];
    }
    (clipped, clamp_targets(&targets, previous_targets))
}

/// The control step's state: history, previous action, previous targets.
#[derive(Clone, Debug)]
pub struct ControlStep {
    history: Option<ProprioHistory>,
    prev_action: [f32; NUM_JOINTS],
    prev_targets: [f32; NUM_JOINTS],
}

impl Default for ControlStep {
    fn default() -> Self {
        Self::new()
    }
}

impl ControlStep {
    /// A step that starts like a simulator reset at the nominal pose.
    pub const fn new() -> Self {
        Self {
            history: None,
            prev_action: [0.0; NUM_JOINTS],
            prev_targets: Q0_RAD,
        }
    }

    /// Starts a new episode from the current targets (the end of the stand-up).
    pub fn reset(&mut self, current_targets_rad: &[f32; NUM_JOINTS]) {
        self.history = None;
        self.prev_action = [0.0; NUM_JOINTS];
        self.prev_targets = *current_targets_rad;
    }

    /// The action of the last successful step.
    pub fn prev_action(&self) -> &[f32; NUM_JOINTS] {
        &self.prev_action
    }

    /// One step: observation, history, policy, clamps. On error the state is unchanged
    /// apart from the history.
    pub fn step<P: Policy + ?Sized>(
        &mut self,
        policy: &mut P,
        sensors: &Sensors,
        command: [f32; 3],
    ) -> Result<[f32; NUM_JOINTS], ControlError> {
        let finite = sensors
            .ang_vel_base_rad_s
            .iter()
            .chain(&sensors.gravity_base)
            .chain(&sensors.q_rad)
            .chain(&sensors.qdot_rad_s)
            .chain(&command)
            .all(|v| v.is_finite());
        if !finite {
            return Err(ControlError::NonFiniteObservation);
        }
        let o: [f32; PROPRIO_DIM] = proprio_obs_vec(
            &sensors.ang_vel_base(),
            &sensors.gravity(),
            &sensors.q_rad,
            &sensors.qdot_rad_s,
        );
        let history = match &mut self.history {
            Some(h) => {
                h.push(&o);
                h
            }
            none => none.insert(ProprioHistory::filled_with(&o)),
        };
        let action = policy
            .act(command, &self.prev_action, history)
            .filter(|a| a.iter().all(|v| v.is_finite()))
            .ok_or(ControlError::NonFiniteAction)?;
        let (action, targets) = action_to_targets(&action, &self.prev_targets);
        self.prev_action = action;
        self.prev_targets = targets;
        Ok(targets)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::obs::PROPRIO_JOINT_POS;

    /// Returns a fixed action and records what it saw.
    struct Scripted {
        action: [f32; NUM_JOINTS],
        seen_prev: [f32; NUM_JOINTS],
        seen_joint_pos0: f32,
    }

    impl Policy for Scripted {
        fn act(
            &mut self,
            _command: [f32; 3],
            prev_action: &[f32; NUM_JOINTS],
            history: &ProprioHistory,
        ) -> Option<[f32; NUM_JOINTS]> {
            self.seen_prev = *prev_action;
            self.seen_joint_pos0 = history.flatten()[PROPRIO_JOINT_POS.start];
            Some(self.action)
        }
    }

    fn sensors() -> Sensors {
        Sensors {
            ang_vel_base_rad_s: [0.0; 3],
            gravity_base: [0.0, 0.0, -1.0],
            q_rad: Q0_RAD,
            qdot_rad_s: [0.0; NUM_JOINTS],
        }
    }

    #[test]
    fn targets_follow_the_action_and_feed_it_back() {
        let mut p = Scripted {
            action: [0.4; NUM_JOINTS],
            seen_prev: [9.0; 18],
            seen_joint_pos0: 9.0,
        };
        let mut c = ControlStep::new();
        let t = c.step(&mut p, &sensors(), [0.0; 3]).unwrap();
        assert_eq!(p.seen_prev, [0.0; NUM_JOINTS]);
        assert_eq!(
            p.seen_joint_pos0, 0.0,
            "history filled with the first observation"
        );
        assert!((t[0] - (Q0_RAD[0] + 0.1)).abs() < 1e-6);
        c.step(&mut p, &sensors(), [0.0; 3]).unwrap();
        assert_eq!(p.seen_prev, [0.4; NUM_JOINTS]);
    }

    #[test]
    fn clamps_rate_and_limits() {
        let mut p = Scripted {
            action: [100.0; NUM_JOINTS],
            seen_prev: [0.0; 18],
            seen_joint_pos0: 0.0,
        };
        let mut c = ControlStep::new();
        let t = c.step(&mut p, &sensors(), [0.0; 3]).unwrap();
        for j in 0..NUM_JOINTS {
            assert!((t[j] - (Q0_RAD[j] + max_target_step_rad(j)).min(Q_MAX_RAD[j])).abs() < 1e-6);
        }
        let mut t = t;
        for _ in 0..100 {
            t = c.step(&mut p, &sensors(), [0.0; 3]).unwrap();
        }
        assert_eq!(t, Q_MAX_RAD);
    }

    #[test]
    fn non_finite_inputs_and_actions_are_errors() {
        let mut p = Scripted {
            action: [0.0; NUM_JOINTS],
            seen_prev: [0.0; 18],
            seen_joint_pos0: 0.0,
        };
        let mut c = ControlStep::new();
        let mut s = sensors();
        s.qdot_rad_s[3] = f32::NAN;
        assert_eq!(
            c.step(&mut p, &s, [0.0; 3]),
            Err(ControlError::NonFiniteObservation)
        );
        p.action[5] = f32::INFINITY;
        assert_eq!(
            c.step(&mut p, &sensors(), [0.0; 3]),
            Err(ControlError::NonFiniteAction)
        );
    }
}
