//! Fault reactions with physics: RC failsafe and a drive EMCY lower the robot slowly and
//! cut torque only once seated; tilt beyond the limit cuts torque at once; 5 % frame loss
//! on both buses does not stop the robot.

use hexapod_core::canopen::cia402::PowerState;
use hexapod_core::controller::ZeroPolicy;
use hexapod_core::supervisor::{Fault, Mode};
use hexapod_core::timing::POLICY_DT_S;
use sil_tests::sil::{generated_policy, Sil};
use sil_tests::sim_plant::sitting_height_m;
use sil_tests::trace::Trace;

/// A seated robot whose trunk meets the ground afterwards meets it slower than this, m/s.
const MAX_TRUNK_TOUCHDOWN_M_S: f32 = 0.3;

fn standing(seed: u64) -> Sil {
    let mut sil = Sil::new(seed).unwrap();
    sil.stand_up().expect("stands up");
    sil.run(0.5, &mut ZeroPolicy);
    sil
}

/// After a fault at `t_fault_s` (the sit-down starting at `t_sit_s`, later when the fault
/// takes time to detect): the body went down slowly to the sitting height with the trunk
/// clear of the ground, torque went off only then, and any later trunk touchdown is soft.
/// The sink speed is the sit-down's: before it the robot is still walking, and a walking
/// trunk bobs at 0.2 m/s.
fn assert_safe_sit_down(trace: &Trace, t_fault_s: f32, t_sit_s: f32, min_duration_s: f32) {
    let off = *trace.torque_off(t_fault_s).expect("torque goes off");
    assert!(
        off.t_s - t_fault_s >= min_duration_s,
        "torque off {:.2} s after the fault",
        off.t_s - t_fault_s
    );
    assert!(
        off.height_m() < sitting_height_m() + 0.02,
        "torque off at {} m: not seated",
        off.height_m()
    );
    let sink = trace.max_sink_speed_m_s(t_sit_s, off.t_s);
    assert!(sink < 0.15, "sinks at {sink} m/s before torque off");
    if let Some(c) = trace.first_trunk_contact(t_fault_s) {
        assert!(
            c.t_s >= off.t_s,
            "trunk touched at {:.2} s, torque off at {:.2} s",
            c.t_s,
            off.t_s
        );
        let v = -c.base_vel_world_m_s[2];
        assert!(
            v < MAX_TRUNK_TOUCHDOWN_M_S,
            "trunk hits the ground at {v} m/s"
        );
    }
}

#[test]
fn rc_failsafe_while_walking_sits_down_then_cuts_torque() {
    let mut sil = standing(31);
    let mut policy = generated_policy().expect("valid generated policy");
    sil.h.rc.set_sticks(0.6, 0.0, 0.0);
    sil.run(1.0, &mut policy);
    assert_eq!(sil.mode(), Mode::Walking);
    let t_fault = sil.time_s();
    sil.h.rc.set_lost(true);
    // The receiver declares failsafe after its timeout (0.2 s); the robot walks until then.
    let sitting_down = |m: Mode| matches!(m, Mode::SafeSitDown { .. });
    assert!(sil.run_until(0.5, &mut policy, sitting_down));
    let t_sit = sil.time_s();
    assert!(
        t_sit - t_fault >= 0.15,
        "sat down {} s after the loss",
        t_sit - t_fault
    );
    assert!(
        matches!(
            sil.mode(),
            Mode::SafeSitDown {
                fault: Fault::RcLost,
                ..
            }
        ),
        "{:?}",
        sil.mode()
    );
    assert!(sil.run_until(7.0, &mut policy, |m| matches!(m, Mode::Faulted { .. })));
    sil.run(2.0, &mut policy);
    assert_eq!(
        sil.mode(),
        Mode::Faulted {
            fault: Fault::RcLost
        }
    );
    assert_safe_sit_down(&sil.plant().trace, t_fault, t_sit, 5.0);
}

#[test]
fn drive_emcy_lowers_on_the_other_drives_without_dropping_the_trunk() {
    let mut sil = standing(32);
    let t_fault = sil.time_s();
    // Left-middle thigh: overcurrent EMCY; its drive goes to Fault (torque off).
    sil.h.rig.inject_drive_fault(13, 0x2310);
    sil.run(0.1, &mut ZeroPolicy);
    assert!(
        matches!(
            sil.mode(),
            Mode::SafeSitDown {
                fault: Fault::Drive { joint: 13, .. },
                ..
            }
        ),
        "{:?}",
        sil.mode()
    );
    assert_eq!(sil.plant().powered_joints(), 17);
    assert!(sil.run_until(7.0, &mut ZeroPolicy, |m| matches!(m, Mode::Faulted { .. })));
    sil.run(2.0, &mut ZeroPolicy);
    let trace = &sil.plant().trace;
    let off = trace.torque_off(t_fault).expect("torque goes off").t_s;
    let tilt = trace
        .since(t_fault)
        .iter()
        .take_while(|s| s.t_s < off)
        .map(|s| s.tilt_rad)
        .fold(0.0, f32::max);
    assert!(
        tilt < 0.2,
        "the body tips {tilt} rad while lowering on five legs"
    );
    assert_safe_sit_down(trace, t_fault, t_fault, 5.0);
}

#[test]
fn tilt_beyond_the_limit_cuts_torque() {
    let mut sil = standing(33);
    assert_eq!(sil.plant().powered_joints(), 18);
    // Tip the robot over: half a metre up, rolled 75 degrees (beyond the 1 rad limit).
    let half = 75f32.to_radians() / 2.0;
    let q = sil.plant().state().q_rad;
    sil.h
        .plant
        .world
        .reset([0.0, 0.0, 0.5], [half.sin(), 0.0, 0.0, half.cos()], &q);
    let t_tip = sil.time_s();
    // The teleport gives the gyro nothing to see and the fall gives the accelerometer no
    // gravity: the estimate needs a few hundred ms. What is checked is the reaction: torque
    // off in the cycle the estimated tilt passes the limit.
    let limit_rad = sil.config.supervisor.tilt_limit_rad;
    let mut crossed = None;
    while sil.time_s() < t_tip + 1.0 && crossed.is_none() {
        sil.run(POLICY_DT_S, &mut ZeroPolicy);
        if sil.h.controller.attitude().tilt_rad() > limit_rad {
            crossed = Some(sil.time_s());
        }
    }
    let crossed = crossed.expect("the attitude filter sees the tilt within 1 s");
    // The estimate was read at the end of the cycle; the next cycle's supervisor acts on it.
    sil.run(POLICY_DT_S, &mut ZeroPolicy);
    assert_eq!(sil.mode(), Mode::Faulted { fault: Fault::Tilt });
    sil.run(0.2, &mut ZeroPolicy);
    let off = *sil.plant().trace.torque_off(t_tip).expect("torque off");
    assert!(
        off.t_s <= crossed + 2.0 * POLICY_DT_S,
        "torque off at {:.3} s, tilt seen at {crossed:.3} s",
        off.t_s
    );
    assert_eq!(sil.mode(), Mode::Faulted { fault: Fault::Tilt });
    for d in &sil.h.rig.drives {
        assert_eq!(d.power_state(), PowerState::SwitchOnDisabled);
    }
}

/// Walks 10 s on a forward command with `loss` of the frames lost on both buses.
fn walk_with_frame_loss(seed: u64, loss: f32) {
    let mut sil = standing(seed);
    let frames_before: u64 = sil.h.rig.buses.iter().map(|b| b.stats.frames).sum();
    for bus in &mut sil.h.rig.buses {
        bus.faults.loss_probability = loss;
    }
    let mut policy = generated_policy().expect("valid generated policy");
    sil.h.rc.set_sticks(0.6, 0.0, 0.0);
    let t0 = sil.time_s();
    for _ in 0..10 {
        sil.run(1.0, &mut policy);
        assert_eq!(sil.mode(), Mode::Walking, "at {:.1} s", sil.time_s());
    }
    let lost: u64 = sil.h.rig.buses.iter().map(|b| b.stats.lost).sum();
    let frames: u64 = sil.h.rig.buses.iter().map(|b| b.stats.frames).sum::<u64>() - frames_before;
    let rate = lost as f32 / frames as f32;
    assert!((rate - loss).abs() < 0.2 * loss, "lost {lost} of {frames}");
    assert!(
        sil.h.controller.stats.incomplete_feedback > 0,
        "loss reached the feedback"
    );
    let trace = &sil.plant().trace;
    assert!(trace.first_trunk_contact(t0).is_none());
    assert!(
        trace.min_height_m(t0) > 0.2,
        "sagged to {}",
        trace.min_height_m(t0)
    );
}

#[test]
fn half_a_percent_frame_loss_keeps_walking() {
    walk_with_frame_loss(34, 0.005);
}

#[test]
fn five_percent_frame_loss_keeps_walking() {
    walk_with_frame_loss(35, 0.05);
}
