//! A scripted policy for the loop: host-sim's open-loop tripod gait at the RC command's
//! velocity, expressed as the policy's actions (`q_d = q0 + ACTION_SCALE_RAD * a`). It
//! proves that the loop (RC, control step, RPDOs, drives, physics) can carry a walking
//! gait, and exercises the speed check the trained policy must pass.

use hexapod_core::control::Policy;
use hexapod_core::obs::ProprioHistory;
use hexapod_core::robot::{NUM_JOINTS, Q0_RAD};
use hexapod_core::timing::{ACTION_SCALE_RAD, POLICY_DT_S};
use host_sim::gait::TripodGait;

/// The tripod gait as a [`Policy`].
#[derive(Clone, Debug, Default)]
pub struct GaitPolicy {
    gait: TripodGait,
    steps: u32,
}

impl Policy for GaitPolicy {
    fn act(
        &mut self,
        command: [f32; 3],
        _prev_action: &[f32; NUM_JOINTS],
        _history: &ProprioHistory,
    ) -> Option<[f32; NUM_JOINTS]> {
        self.gait.velocity_m_s = [command[0], command[1]];
        let q = self.gait.joint_targets(self.steps as f32 * POLICY_DT_S);
        self.steps += 1;
        let mut action = [0.0; NUM_JOINTS];
        for ((a, q), q0) in action.iter_mut().zip(q).zip(Q0_RAD) {
            *a = (q - q0) / ACTION_SCALE_RAD;
        }
        Some(action)
    }
}
