//! The generated fixed-point policy (`hexapod-policy`) plugs into the control step through
//! `NnPolicy` and walks in the loop: same actions as the runtime's own `PolicyRunner`, and
//! finite, limited targets with the controller, drives and sensors in the loop.

use hal_mock::harness::Harness;
use hal_mock::plant::JointModel;
use hexapod_core::control::{clamp_targets, ControlStep, NnPolicy, Policy, Sensors};
use hexapod_core::controller::{ControllerConfig, ZeroPolicy};
use hexapod_core::nn::Kernel;
use hexapod_core::obs::proprio_obs;
use hexapod_core::robot::{NUM_JOINTS, Q0_RAD, Q_MAX_RAD, Q_MIN_RAD, Q_SIT_RAD};
use hexapod_core::supervisor::Mode;
use hexapod_policy::{runner, POLICY, SCRATCH_WORDS};

type Generated = NnPolicy<'static, SCRATCH_WORDS>;

fn sensors(k: usize) -> Sensors {
    let mut q = Q0_RAD;
    let mut qdot = [0.0; NUM_JOINTS];
    for j in 0..NUM_JOINTS {
        let phase = 0.3 * k as f32 + j as f32;
        q[j] += 0.05 * phase.sin();
        qdot[j] = 0.5 * phase.cos();
    }
    Sensors {
        ang_vel_base_rad_s: [0.05, -0.02, 0.1],
        gravity_base: [0.02, -0.01, -0.9997],
        q_rad: q,
        qdot_rad_s: qdot,
    }
}

#[test]
fn control_step_matches_the_runtime_runner() {
    let mut adapter = Generated::new(&POLICY, Kernel::Native).expect("valid generated policy");
    let mut reference = runner().unwrap();
    let mut step = ControlStep::new();
    let mut previous_targets = Q0_RAD;
    let command = [0.4, 0.0, 0.2];
    for k in 0..20 {
        let s = sensors(k);
        let targets = step.step(&mut adapter, &s, command).unwrap();
        let o = proprio_obs(
            s.ang_vel_base_rad_s,
            s.gravity_base,
            &s.q_rad,
            &s.qdot_rad_s,
        );
        let expected = reference.step(command, &o).unwrap();
        assert_eq!(step.prev_action(), &expected.action, "step {k}");
        // The runtime's targets after the control step's safety clamps.
        let expected_targets = clamp_targets(&expected.q_target_rad, &previous_targets);
        assert_eq!(targets, expected_targets, "step {k}");
        previous_targets = targets;
    }
}

#[test]
fn generated_policy_runs_in_the_loop() {
    let mut physics = |p: &mut JointModel, dt: f32| p.step(dt);
    let mut h = Harness::new(JointModel::at(&Q_SIT_RAD), ControllerConfig::default(), 5);
    h.start(&mut physics);
    h.run(1.0, &mut ZeroPolicy, &mut physics);
    h.rc.set_arm(true);
    h.rc.set_sticks(0.5, 0.0, 0.0);
    h.run(3.6, &mut ZeroPolicy, &mut physics);
    assert_eq!(h.controller.mode(), Mode::Walking);
    let mut policy = Generated::new(&POLICY, Kernel::Native).unwrap();
    let mut previous = *h.last_command.as_ref().map(|c| &c.targets_rad).unwrap();
    for _ in 0..100 {
        h.cycle(&mut policy, &mut physics);
        assert_eq!(h.controller.mode(), Mode::Walking);
        let t = h.last_command.unwrap().targets_rad;
        for j in 0..NUM_JOINTS {
            assert!(t[j].is_finite() && t[j] >= Q_MIN_RAD[j] && t[j] <= Q_MAX_RAD[j]);
            assert!((t[j] - previous[j]).abs() <= 0.24 + 1e-5, "rate limit");
        }
        previous = t;
    }
    let _: &mut dyn Policy = &mut policy;
}
