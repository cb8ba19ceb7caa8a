//! A drive the master loses while the robot walks, with physics: one whose transmit path
//! fails (it still hears the master) and one whose heartbeat stops while its PDOs go on.
//! The lost drive's target is frozen from the third cycle in a row without its feedback, it
//! gets a quick stop (it holds its joint while the other 17 sit down), and once the robot is seated
//! "disable voltage" and an NMT stop.

use hexapod_core::canopen::cia402::PowerState;
use hexapod_core::canopen::master::{LostReaction, NodeFault};
use hexapod_core::canopen::nmt::NmtState;
use hexapod_core::supervisor::{Fault, Mode};
use hexapod_core::timing::POLICY_DT_S;
use sil_tests::gait_policy::GaitPolicy;
use sil_tests::sil::Sil;

const JOINT: usize = 7;

fn walking(seed: u64) -> (Sil, GaitPolicy) {
    Sil::walking_with_gait(seed)
}

/// Runs until the robot is seated with torque off, then checks the lost drive's end state
/// and that the trunk stayed clear while lowering.
fn assert_seated_and_lost_drive_stopped(sil: &mut Sil, gait: &mut GaitPolicy, t_fault: f32) {
    assert!(sil.run_until(8.0, gait, |m| matches!(m, Mode::Faulted { .. })));
    sil.run(0.5, gait);
    let d = &sil.h.rig.drives[JOINT];
    assert_eq!(d.power_state(), PowerState::SwitchOnDisabled, "torque off");
    assert_eq!(d.nmt_state(), NmtState::Stopped, "NMT stopped");
    assert_eq!(
        sil.h.controller.master.node(JOINT).lost,
        LostReaction::Stopped
    );
    assert_eq!(sil.plant().powered_joints(), 0);
    let trace = &sil.plant().trace;
    let off = trace.torque_off(t_fault).expect("torque off").t_s;
    // The trunk stays clear of the ground until the robot is seated and torque is off.
    if let Some(c) = trace.first_trunk_contact(t_fault) {
        assert!(
            c.t_s >= off,
            "trunk touches the ground at {:.2} s at {:.2} m/s, before torque off at {off:.2} s",
            c.t_s,
            -c.base_vel_world_m_s[2]
        );
    }
    assert!(trace.max_sink_speed_m_s(t_fault, off) < 0.15);
}

#[test]
fn a_drive_that_stops_transmitting_gets_a_frozen_target_then_quick_stop_then_nmt_stop() {
    let (mut sil, mut gait) = walking(91);
    // The drive still receives and acts on RPDOs, but nothing it sends arrives.
    sil.h.rig.drives[JOINT].set_tx_mute(true);
    let t_fault = sil.time_s();
    // The first two cycles without its feedback may be frame loss: it still gets the
    // gait's targets; from the third cycle in a row its target is frozen.
    sil.run(2.0 * POLICY_DT_S, &mut gait);
    let target_at_loss = sil.h.rig.drives[JOINT].objects.target_position();
    let mut saw_quick_stop_at = None;
    for _ in 0..25 {
        sil.run(POLICY_DT_S, &mut gait);
        let d = &sil.h.rig.drives[JOINT];
        // Frozen: the gait's targets no longer reach it.
        assert_eq!(
            d.objects.target_position(),
            target_at_loss,
            "target moved at {:.2} s",
            sil.time_s()
        );
        if d.power_state() == PowerState::QuickStopActive && saw_quick_stop_at.is_none() {
            saw_quick_stop_at = Some(sil.time_s());
        }
    }
    let qs = saw_quick_stop_at.expect("quick stop within 0.5 s");
    assert!(
        qs - t_fault < 0.3,
        "quick stop {:.2} s after the loss",
        qs - t_fault
    );
    assert!(
        matches!(
            sil.mode(),
            Mode::SafeSitDown {
                fault: Fault::Drive {
                    joint: 7,
                    fault: NodeFault::FeedbackLost
                },
                ..
            }
        ),
        "{:?}",
        sil.mode()
    );
    assert!(sil.h.controller.master.node(JOINT).frozen_cycles >= 7);
    // Holding its joint (torque on) while the others sit down.
    assert_eq!(sil.plant().powered_joints(), 18);
    assert_seated_and_lost_drive_stopped(&mut sil, &mut gait, t_fault);
}

#[test]
fn heartbeat_loss_with_live_pdos_is_a_lost_drive() {
    let (mut sil, mut gait) = walking(92);
    sil.h.rig.drives[JOINT].set_heartbeat_mute(true);
    let t_fault = sil.time_s();
    // The PDOs go on: nothing is seen before the heartbeat timeout (5 x 100 ms).
    sil.run(0.4, &mut gait);
    assert_eq!(sil.mode(), Mode::Walking);
    assert!(sil.run_until(0.3, &mut gait, |m| matches!(m, Mode::SafeSitDown { .. })));
    assert!(
        matches!(
            sil.mode(),
            Mode::SafeSitDown {
                fault: Fault::Drive {
                    joint: 7,
                    fault: NodeFault::LostHeartbeat
                },
                ..
            }
        ),
        "{:?}",
        sil.mode()
    );
    sil.run(0.1, &mut gait);
    // Its TPDOs still arrive: the master sees the quick stop it commanded.
    assert_eq!(
        sil.h.controller.master.node(JOINT).power,
        PowerState::QuickStopActive
    );
    assert_eq!(
        sil.h.rig.drives[JOINT].power_state(),
        PowerState::QuickStopActive
    );
    assert_seated_and_lost_drive_stopped(&mut sil, &mut gait, t_fault);
}
