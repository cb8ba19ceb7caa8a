//! Safety properties of the supervisor under random operator input, sensor faults, drive
//! faults and policy failures: targets are always finite, and torque never goes off while
//! the robot is up unless it sits or tilts beyond the limit ("never drop the robot").

use hexapod_core::canopen::cia402::DriveRequest;
use hexapod_core::canopen::master::NodeFault;
use hexapod_core::rc::receiver::RcState;
use hexapod_core::robot::{Q0_RAD, Q_SIT_RAD};
use hexapod_core::supervisor::{Inputs, Mode, Supervisor, SupervisorConfig};
use proptest::prelude::*;

#[derive(Clone, Debug)]
struct Event {
    arm: bool,
    link_ok: bool,
    imu_fresh: bool,
    tilt: bool,
    drive_fault: Option<u8>,
    overrun: bool,
    policy_fails: bool,
    hold_cycles: u8,
}

fn event() -> impl Strategy<Value = Event> {
    (
        prop::bool::weighted(0.8),
        prop::bool::weighted(0.97),
        prop::bool::weighted(0.98),
        prop::bool::weighted(0.01),
        prop::option::weighted(0.02, 0u8..5),
        prop::bool::weighted(0.01),
        prop::bool::weighted(0.01),
        1u8..120,
    )
        .prop_map(
            |(arm, link_ok, imu_fresh, tilt, drive_fault, overrun, policy_fails, hold_cycles)| {
                Event {
                    arm,
                    link_ok,
                    imu_fresh,
                    tilt,
                    drive_fault,
                    overrun,
                    policy_fails,
                    hold_cycles,
                }
            },
        )
}

fn node_fault(k: u8) -> NodeFault {
    match k {
        0 => NodeFault::Emergency { error_code: 0x2310 },
        1 => NodeFault::DriveFault,
        2 => NodeFault::LostHeartbeat,
        3 => NodeFault::BusOff,
        _ => NodeFault::FeedbackLost,
    }
}

fn is_up(mode: Mode) -> bool {
    matches!(
        mode,
        Mode::StandingUp { .. }
            | Mode::Walking
            | Mode::SittingDown { .. }
            | Mode::SafeSitDown { .. }
            | Mode::SafeHold { .. }
    )
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, failure_persistence: None, ..ProptestConfig::default() })]

    #[test]
    fn never_drops_the_robot(events in prop::collection::vec(event(), 1..40)) {
        let mut s = Supervisor::new(SupervisorConfig::default());
        s.start();
        let mut q = Q_SIT_RAD;
        let mut now_us = 0u64;
        let mut enabled = false;
        let mut latched_fault: Option<(usize, NodeFault)> = None;
        for e in &events {
            if let Some(k) = e.drive_fault {
                latched_fault.get_or_insert((k as usize * 4, node_fault(k)));
            }
            for _ in 0..e.hold_cycles {
                now_us += 20_000;
                let before = s.mode();
                let tilt_rad = if e.tilt { 1.3 } else { 0.1 };
                let inputs = Inputs {
                    now_us,
                    configuring: now_us < 100_000,
                    drives_enabled: enabled,
                    drives_adopted: false,
                    adopted_rad: &q,
                    drive_fault: latched_fault,
                    q_rad: &q,
                    imu_fresh: e.imu_fresh,
                    tilt_rad,
                    rc: RcState { command: [0.0; 3], arm: e.arm && e.link_ok, link_ok: e.link_ok },
                    overrun: e.overrun,
                };
                let mut walk = Q0_RAD;
                walk[0] += 0.1;
                let cmd = s.step(&inputs, || if e.policy_fails { Err(()) } else { Ok(walk) });
                prop_assert!(cmd.targets_rad.iter().all(|t| t.is_finite()));
                let torque_on = cmd.requests.iter().all(|r| *r == DriveRequest::Enable);
                if is_up(before) && !torque_on {
                    let sat = q.iter().zip(&Q_SIT_RAD).all(|(a, b)| (a - b).abs() < 1e-4);
                    prop_assert!(
                        sat || e.tilt,
                        "torque off while up: {:?} -> {:?}", before, s.mode()
                    );
                }
                // Drives follow: enabled after one cycle of Enable, joints track targets.
                if torque_on {
                    if enabled {
                        q = cmd.targets_rad;
                    }
                    enabled = true;
                } else {
                    enabled = false;
                }
                if cmd.clear_faults {
                    latched_fault = latched_fault.filter(|(_, f)| !f.link_alive());
                }
            }
        }
    }
}
