//! The controller core in the loop with the emulated drives, IMU and RC: boot, stand up,
//! walk, sit down, and every fault reaction, all through CAN frames and CRSF bytes.
#![allow(clippy::needless_range_loop)]

use hal_mock::candump::parse_line;
use hal_mock::harness::Harness;
use hal_mock::plant::JointModel;
use hexapod_core::canopen::cia402::PowerState;
use hexapod_core::canopen::master::NodeFault;
use hexapod_core::control::Policy;
use hexapod_core::controller::{ControllerConfig, ZeroPolicy};
use hexapod_core::obs::ProprioHistory;
use hexapod_core::robot::{NUM_JOINTS, Q0_RAD, Q_SIT_RAD};
use hexapod_core::supervisor::{Fault, Mode};

fn physics(p: &mut JointModel, dt_s: f32) {
    p.step(dt_s);
}

fn bench() -> Harness<JointModel> {
    let mut h = Harness::new(JointModel::at(&Q_SIT_RAD), ControllerConfig::default(), 3);
    h.start(&mut physics);
    h
}

/// Boots, arms, stands up and walks with the zero policy.
fn walking() -> Harness<JointModel> {
    let mut h = bench();
    h.run(1.0, &mut ZeroPolicy, &mut physics);
    assert_eq!(h.controller.mode(), Mode::Disabled, "configured within 1 s");
    h.rc.set_arm(true);
    h.run(4.0, &mut ZeroPolicy, &mut physics);
    assert_eq!(h.controller.mode(), Mode::Walking);
    h
}

fn assert_pose(h: &Harness<JointModel>, pose: &[f32; NUM_JOINTS], tol: f32) {
    for j in 0..NUM_JOINTS {
        let q = h.plant.states[j].q_rad;
        assert!((q - pose[j]).abs() < tol, "joint {j}: {q} vs {}", pose[j]);
    }
}

#[test]
fn boots_stands_walks_and_sits_down() {
    let mut h = walking();
    h.run(1.0, &mut ZeroPolicy, &mut physics);
    assert_pose(&h, &Q0_RAD, 0.01);
    for d in &h.rig.drives {
        assert_eq!(d.power_state(), PowerState::OperationEnabled);
    }
    h.rc.set_arm(false);
    h.run(4.0, &mut ZeroPolicy, &mut physics);
    assert_eq!(h.controller.mode(), Mode::Disabled);
    assert_pose(&h, &Q_SIT_RAD, 0.01);
    for d in &h.rig.drives {
        assert_eq!(
            d.power_state(),
            PowerState::SwitchOnDisabled,
            "torque off when sitting"
        );
    }
    let stats = h.controller.stats;
    assert_eq!(stats.overruns, 0);
    assert!(stats.worst_cycle_us <= 6_000, "{stats:?}");
    assert_eq!(h.controller.master.counters, Default::default());
}

/// A policy that follows the command with the hips: proves the command and the
/// observation reach the policy.
struct TurnWithHips {
    calls: u32,
}

impl Policy for TurnWithHips {
    fn act(
        &mut self,
        command: [f32; 3],
        _prev: &[f32; NUM_JOINTS],
        history: &ProprioHistory,
    ) -> Option<[f32; NUM_JOINTS]> {
        self.calls += 1;
        assert!(
            (history.newest()[5] + 1.0).abs() < 0.05,
            "projected gravity points down"
        );
        let mut a = [0.0; NUM_JOINTS];
        for leg in 0..6 {
            a[3 * leg] = command[2];
        }
        Some(a)
    }
}

#[test]
fn the_rc_command_reaches_the_policy() {
    let mut h = walking();
    let mut policy = TurnWithHips { calls: 0 };
    h.rc.set_sticks(0.0, 0.0, 1.0);
    h.run(1.0, &mut policy, &mut physics);
    assert!(policy.calls >= 49, "{}", policy.calls);
    // Full left turn stick: wz = 0.5 rad/s, hip action 0.5 -> 0.125 rad.
    assert!(
        (h.plant.states[0].q_rad - 0.125).abs() < 0.01,
        "{}",
        h.plant.states[0].q_rad
    );
}

#[test]
fn rc_loss_sits_down_then_recovers_after_disarm() {
    let mut h = walking();
    h.rc.set_lost(true);
    h.run(0.5, &mut ZeroPolicy, &mut physics);
    assert!(matches!(
        h.controller.mode(),
        Mode::SafeSitDown {
            fault: Fault::RcLost,
            ..
        }
    ));
    h.run(5.5, &mut ZeroPolicy, &mut physics);
    assert_eq!(
        h.controller.mode(),
        Mode::Faulted {
            fault: Fault::RcLost
        }
    );
    assert_pose(&h, &Q_SIT_RAD, 0.01);
    h.rc.set_lost(false);
    h.rc.set_arm(false);
    h.run(0.2, &mut ZeroPolicy, &mut physics);
    assert_eq!(h.controller.mode(), Mode::Disabled);
}

#[test]
fn drive_emcy_sits_down_on_the_other_drives_and_recovers_by_fault_reset() {
    let mut h = walking();
    h.rig.inject_drive_fault(4, 0x4310);
    h.run(0.1, &mut ZeroPolicy, &mut physics);
    let mode = h.controller.mode();
    assert!(
        matches!(
            mode,
            Mode::SafeSitDown {
                fault: Fault::Drive {
                    joint: 4,
                    fault: NodeFault::Emergency { error_code: 0x4310 }
                },
                ..
            }
        ),
        "{mode:?}"
    );
    assert_eq!(h.rig.drives[5].power_state(), PowerState::OperationEnabled);
    h.run(6.0, &mut ZeroPolicy, &mut physics);
    assert!(matches!(h.controller.mode(), Mode::Faulted { .. }));
    for j in (0..NUM_JOINTS).filter(|&j| j != 4) {
        assert!(
            (h.plant.states[j].q_rad - Q_SIT_RAD[j]).abs() < 0.01,
            "joint {j}"
        );
    }
    h.rc.set_arm(false);
    h.run(0.3, &mut ZeroPolicy, &mut physics);
    assert_eq!(h.controller.mode(), Mode::Disabled);
    assert_eq!(h.rig.drives[4].power_state(), PowerState::SwitchOnDisabled);
    h.rc.set_arm(true);
    h.run(4.0, &mut ZeroPolicy, &mut physics);
    assert_eq!(
        h.controller.mode(),
        Mode::Walking,
        "re-armed after the fault reset"
    );
}

#[test]
fn lost_heartbeat_sits_down() {
    let mut h = walking();
    h.rig.set_drive_mute(14, true);
    h.run(0.5, &mut ZeroPolicy, &mut physics);
    let mode = h.controller.mode();
    assert!(
        matches!(
            mode,
            Mode::SafeSitDown {
                fault: Fault::Drive { joint: 14, .. },
                ..
            }
        ),
        "{mode:?}"
    );
}

#[test]
fn bus_off_holds_with_the_other_bus_and_the_lost_drives_hold_themselves() {
    let mut h = walking();
    h.rig.buses[0].faults.bus_off = true;
    h.run(1.0, &mut ZeroPolicy, &mut physics);
    assert_eq!(
        h.controller.mode(),
        Mode::SafeHold {
            fault: Fault::BusOff { bus: 0 }
        }
    );
    assert_pose(&h, &Q0_RAD, 0.01);
    for j in 0..9 {
        assert_eq!(
            h.rig.drives[j].power_state(),
            PowerState::QuickStopActive,
            "joint {j}"
        );
    }
    for j in 9..NUM_JOINTS {
        assert_eq!(
            h.rig.drives[j].power_state(),
            PowerState::OperationEnabled,
            "joint {j}"
        );
    }
}

#[test]
fn imu_stale_sits_down() {
    let mut h = walking();
    h.imu.set_stale(true);
    h.run(0.2, &mut ZeroPolicy, &mut physics);
    assert!(matches!(
        h.controller.mode(),
        Mode::SafeSitDown {
            fault: Fault::ImuStale,
            ..
        }
    ));
}

#[test]
fn tilt_cuts_torque() {
    let mut h = walking();
    // Rolled 70 degrees.
    let half = 70f32.to_radians() / 2.0;
    h.base.orientation = [half.cos(), half.sin(), 0.0, 0.0];
    h.run(2.0, &mut ZeroPolicy, &mut physics);
    assert_eq!(h.controller.mode(), Mode::Faulted { fault: Fault::Tilt });
    for d in &h.rig.drives {
        assert_eq!(d.power_state(), PowerState::SwitchOnDisabled);
    }
}

struct NanPolicy;

impl Policy for NanPolicy {
    fn act(
        &mut self,
        _: [f32; 3],
        _: &[f32; NUM_JOINTS],
        _: &ProprioHistory,
    ) -> Option<[f32; NUM_JOINTS]> {
        Some([f32::NAN; NUM_JOINTS])
    }
}

#[test]
fn nan_policy_output_sits_down_from_finite_targets() {
    let mut h = walking();
    h.cycle(&mut NanPolicy, &mut physics);
    assert!(matches!(
        h.controller.mode(),
        Mode::SafeSitDown {
            fault: Fault::NonFinite,
            ..
        }
    ));
    let cmd = h.last_command.unwrap();
    assert!(cmd.targets_rad.iter().all(|t| t.is_finite()));
    h.run(6.0, &mut NanPolicy, &mut physics);
    assert_pose(&h, &Q_SIT_RAD, 0.01);
}

#[test]
fn deadline_overrun_sits_down() {
    let mut h = walking();
    h.delay_next_finish_us = 16_000;
    h.cycle(&mut ZeroPolicy, &mut physics);
    h.cycle(&mut ZeroPolicy, &mut physics);
    assert!(matches!(
        h.controller.mode(),
        Mode::SafeSitDown {
            fault: Fault::Overrun,
            ..
        }
    ));
}

#[test]
fn walks_through_frame_loss_latency_and_rc_noise() {
    let mut h = walking();
    for bus in &mut h.rig.buses {
        bus.faults.loss_probability = 0.01;
        bus.faults.latency_us = 300;
    }
    h.rc.inject_bytes(&[0xC8, 0x18, 0x16, 0xFF, 0x00, 0x42]);
    h.run(5.0, &mut ZeroPolicy, &mut physics);
    assert_eq!(h.controller.mode(), Mode::Walking);
    assert_pose(&h, &Q0_RAD, 0.02);
    let parser = h.controller.rc_receiver().parser.counters;
    assert!(parser.crc_errors + parser.bad_length >= 1, "{parser:?}");
}

#[test]
fn records_a_candump_log_that_parses_back() {
    let mut h = Harness::new(JointModel::at(&Q_SIT_RAD), ControllerConfig::default(), 9);
    h.rig.record();
    h.start(&mut physics);
    h.run(1.0, &mut ZeroPolicy, &mut physics);
    h.rc.set_arm(true);
    h.run(1.0, &mut ZeroPolicy, &mut physics);
    let log = h.rig.candump();
    let entries: Vec<_> = log.lines().map(|l| parse_line(l).expect(l)).collect();
    let syncs = entries.iter().filter(|e| e.frame.cob_id() == 0x080).count();
    assert_eq!(syncs, 2 * 100, "one SYNC per bus per cycle");
    assert!(entries.windows(2).all(|w| w[0].time_us <= w[1].time_us));
    // SDO configuration, NMT start and RPDOs are all there.
    assert!(entries.iter().any(|e| e.frame.cob_id() == 0x601));
    assert!(entries
        .iter()
        .any(|e| e.frame.cob_id() == 0x000 && e.frame.payload() == [0x01, 18]));
    assert!(entries.iter().any(|e| e.frame.cob_id() == 0x212));
    std::fs::create_dir_all(concat!(env!("CARGO_TARGET_TMPDIR"), "/sil")).unwrap();
    std::fs::write(
        concat!(env!("CARGO_TARGET_TMPDIR"), "/sil/bringup.log"),
        &log,
    )
    .unwrap();
}
