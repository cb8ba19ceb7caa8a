//! Unit tests of the master against hand-written drive answers.

use super::*;
use crate::canopen::sdo::{abort, SdoResponse};

fn boot_up(node: u8) -> CanFrame {
    NmtState::BootUp.heartbeat_frame(node)
}

/// The SDO request the master queued for `node` on its bus, if any.
fn pending_request(m: &mut Master, node: u8) -> Option<SdoRequest> {
    let bus = can_bus(node as usize - 1);
    let mut found = None;
    while let Some(f) = m.pop_tx(bus) {
        if f.cob_id() == 0x600 + node as u16 {
            found = SdoRequest::parse(f.payload()).ok();
        }
    }
    found
}

fn upload(node: u8, address: od::ObjectAddress, value: u32, len: u8) -> CanFrame {
    SdoResponse::Upload {
        address,
        data: value.to_le_bytes(),
        len,
    }
    .frame(node)
}

/// Answers node `node`'s probe (statusword, then position).
fn answer_probe(m: &mut Master, node: u8, statusword: u16, position: i32, now_us: u64) {
    let bus = can_bus(node as usize - 1);
    m.on_frame(
        bus,
        &upload(node, od::STATUSWORD, statusword as u32, 2),
        now_us,
    );
    m.on_frame(
        bus,
        &upload(node, od::POSITION_ACTUAL, position as u32, 4),
        now_us,
    );
}

#[test]
fn start_probes_each_node_before_resetting_it() {
    let mut m = Master::new();
    m.start(0);
    // First an upload of the statusword: nothing that changes the drive's state.
    assert_eq!(
        pending_request(&mut m, 1),
        Some(SdoRequest::Upload {
            address: od::STATUSWORD
        })
    );
    assert!(m.configuring());
    m.on_frame(0, &upload(1, od::STATUSWORD, 0x0250, 2), 1_000);
    assert_eq!(
        pending_request(&mut m, 1),
        Some(SdoRequest::Upload {
            address: od::POSITION_ACTUAL
        })
    );
    m.on_frame(0, &upload(1, od::POSITION_ACTUAL, 1234, 4), 2_000);
    assert!(!m.node(0).adopted, "switch on disabled: nothing to adopt");
    let mut reset = false;
    while let Some(f) = m.pop_tx(0) {
        reset |= f == NmtCommand::ResetCommunication.frame(1);
    }
    assert!(reset, "reset communication of node 1 after its probe");
    m.on_frame(0, &boot_up(1), 10_000);
    assert_eq!(
        m.node(0).phase,
        NodePhase::Configuring {
            step: 0,
            retries: 0
        }
    );
    assert_eq!(
        pending_request(&mut m, 1),
        Some(SdoRequest::Upload {
            address: od::DEVICE_TYPE
        })
    );
}

#[test]
fn drives_holding_the_body_are_adopted_and_never_disabled() {
    let mut m = Master::new();
    m.start(0);
    // Node 1 in Operation enabled, node 2 in Quick stop active, node 3 disabled.
    answer_probe(&mut m, 1, 0x1637, 50_000, 1_000);
    answer_probe(&mut m, 2, 0x0217, -20_000, 1_000);
    answer_probe(&mut m, 3, 0x0250, 0, 1_000);
    assert!(m.node(0).adopted && m.node(1).adopted && !m.node(2).adopted);
    assert!(m.any_adopted());
    assert!((m.node(0).q_rad - units::increments_to_rad(50_000)).abs() < 1e-6);
    // After configuration the drive is operational; in Quick stop active (the reset of
    // communication made it stop) it is left only deliberately: one cycle holding at its
    // position with quick stop, then enable operation with the target where it is.
    m.nodes[1].phase = NodePhase::Operational;
    let tpdo1 = |sw: u16, pos: i32| {
        let t = Tpdo1 {
            statusword: sw,
            position: pos,
        };
        CanFrame::new_truncating(0x182, &t.encode())
    };
    let rpdo = |m: &mut Master| {
        let mut last = None;
        while let Some(f) = m.pop_tx(0) {
            if f.cob_id() == 0x202 {
                last = Rpdo1::decode(f.payload());
            }
        }
        last
    };
    // No controlword before the drive's state is known.
    m.sync();
    m.send_commands(&[DriveRequest::Enable; NUM_JOINTS], &[0.3; NUM_JOINTS]);
    assert_eq!(rpdo(&mut m), None);
    for cycle in 0..3 {
        m.sync();
        m.on_frame(0, &tpdo1(0x0217, -20_100), 0);
        m.on_frame(0, &CanFrame::new_truncating(0x282, &[0; 6]), 0);
        m.send_commands(&[DriveRequest::Enable; NUM_JOINTS], &[0.3; NUM_JOINTS]);
        let r = rpdo(&mut m).expect("RPDO");
        assert_eq!(
            r.target_position, -20_100,
            "cycle {cycle}: held where it is"
        );
        let expected = if cycle == 0 { 0x0002 } else { 0x000F };
        assert_eq!(r.controlword, expected, "cycle {cycle}");
    }
}

#[test]
fn a_drive_in_quick_stop_that_was_not_adopted_stays_in_quick_stop() {
    let mut m = Master::new();
    m.nodes[0].phase = NodePhase::Operational;
    m.nodes[0].state_known = true;
    m.nodes[0].power = PowerState::QuickStopActive;
    for _ in 0..3 {
        m.send_commands(&[DriveRequest::Enable; NUM_JOINTS], &[0.3; NUM_JOINTS]);
        assert_eq!(m.node(0).controlword, 0x0002);
    }
}

#[test]
fn silent_nodes_are_reset_again_then_given_up() {
    let mut m = Master::new();
    m.start(0);
    // The probe times out (twice), then the resets.
    let mut t = 0;
    for _ in 0..PROBE_ATTEMPTS {
        t += super::super::sdo_client::SDO_TIMEOUT_US;
        m.poll(t);
    }
    assert!(matches!(m.node(5).phase, NodePhase::Booting { .. }));
    for _ in 0..BOOT_ATTEMPTS {
        t += BOOT_TIMEOUT_US;
        m.poll(t);
    }
    assert_eq!(m.node(5).fault, Some(NodeFault::NoBootUp));
    assert_eq!(m.node(5).phase, NodePhase::Failed);
    assert!(!m.configuring());
}

#[test]
fn an_sdo_abort_fails_the_node() {
    let mut m = Master::new();
    m.start(0);
    m.on_frame(0, &boot_up(2), 0);
    let Some(SdoRequest::Upload { address }) = pending_request(&mut m, 2) else {
        panic!()
    };
    let abort = SdoResponse::Abort {
        address,
        code: abort::NO_OBJECT,
    };
    m.on_frame(0, &abort.frame(2), 100);
    assert_eq!(
        m.node(1).fault,
        Some(NodeFault::ConfigAborted {
            address,
            code: abort::NO_OBJECT
        })
    );
}

#[test]
fn a_foreign_device_is_refused() {
    let mut m = Master::new();
    m.start(0);
    m.on_frame(0, &boot_up(2), 0);
    let r = SdoResponse::Upload {
        address: od::DEVICE_TYPE,
        data: 0x0001_0191u32.to_le_bytes(),
        len: 4,
    };
    m.on_frame(0, &r.frame(2), 100);
    assert_eq!(
        m.node(1).fault,
        Some(NodeFault::Identify(IdentifyError::NotAServoDrive(
            0x0001_0191
        )))
    );
}

#[test]
fn sdo_timeouts_are_retried_then_fail_the_node() {
    let mut m = Master::new();
    m.start(0);
    m.on_frame(1, &boot_up(12), 0);
    let mut t = 0;
    let mut requests = 0;
    for _ in 0..=SDO_RETRIES {
        if pending_request(&mut m, 12).is_some() {
            requests += 1;
        }
        t += super::super::sdo_client::SDO_TIMEOUT_US;
        m.poll(t);
    }
    assert_eq!(requests, 1 + SDO_RETRIES as usize);
    assert_eq!(
        m.node(11).fault,
        Some(NodeFault::ConfigTimeout {
            address: od::DEVICE_TYPE
        })
    );
}

#[test]
fn a_reboot_while_operational_is_a_fault() {
    let mut m = Master::new();
    m.start(0);
    m.nodes[3].phase = NodePhase::Operational;
    m.on_frame(0, &NmtState::Operational.heartbeat_frame(4), 10);
    assert_eq!(m.node(3).fault, None);
    m.on_frame(0, &boot_up(4), 20);
    assert_eq!(m.node(3).fault, Some(NodeFault::UnexpectedNmtState));
}

#[test]
fn missing_feedback_for_three_cycles_is_a_fault() {
    let mut m = Master::new();
    m.start(0);
    m.nodes[0].phase = NodePhase::Operational;
    for _ in 0..FEEDBACK_MISS_LIMIT {
        assert_eq!(m.node(0).fault, None);
        m.sync();
    }
    m.sync();
    assert_eq!(m.node(0).fault, Some(NodeFault::FeedbackLost));
}

#[test]
fn commands_follow_the_state_machine_and_never_jump() {
    let mut m = Master::new();
    m.start(0);
    for bus in 0..NUM_BUSES {
        while m.pop_tx(bus).is_some() {}
    }
    m.nodes[0].phase = NodePhase::Operational;
    let tpdo = Tpdo1 {
        statusword: 0x0250,
        position: 10_000,
    };
    m.on_frame(0, &CanFrame::new_truncating(0x181, &tpdo.encode()), 0);
    let targets = [1.0; NUM_JOINTS];
    m.send_commands(&[DriveRequest::Enable; NUM_JOINTS], &targets);
    let f = m.pop_tx(0).unwrap();
    assert_eq!(f.cob_id(), 0x201);
    let r = Rpdo1::decode(f.payload()).unwrap();
    assert_eq!(r.controlword, 0x0006, "shutdown first");
    assert_eq!(r.target_position, 10_000, "target = actual until enabled");
    assert_eq!(m.pop_tx(0), None, "only operational drives get RPDOs");
    let tpdo = Tpdo1 {
        statusword: 0x1637,
        position: 10_000,
    };
    m.on_frame(0, &CanFrame::new_truncating(0x181, &tpdo.encode()), 0);
    m.send_commands(&[DriveRequest::Enable; NUM_JOINTS], &[f32::NAN; NUM_JOINTS]);
    let r = Rpdo1::decode(m.pop_tx(0).unwrap().payload()).unwrap();
    assert_eq!(
        (r.controlword, r.target_position),
        (0x000F, 10_000),
        "NaN target holds"
    );
    m.send_commands(&[DriveRequest::Enable; NUM_JOINTS], &[9.0; NUM_JOINTS]);
    let r = Rpdo1::decode(m.pop_tx(0).unwrap().payload()).unwrap();
    assert_eq!(
        r.target_position,
        units::rad_to_increments(Q_MAX_RAD[0]),
        "clamped to the limit"
    );
}

/// The lost-drive reaction frame by frame: target frozen from the third cycle without
/// feedback, quick stop once lost, then (torque off requested) disable voltage three
/// times and NMT stop, then silence.
#[test]
fn a_lost_drive_gets_frozen_target_quick_stop_disable_then_nmt_stop() {
    let mut m = Master::new();
    m.started = true;
    m.nodes[0].phase = NodePhase::Operational;
    m.nodes[0].state_known = true;
    m.nodes[0].power = PowerState::OperationEnabled;
    let frames = |m: &mut Master| {
        let mut out = heapless::Vec::<CanFrame, 16>::new();
        while let Some(f) = m.pop_tx(0) {
            if f.cob_id() == 0x201 || f.cob_id() == 0x000 {
                let _ = out.push(f);
            }
        }
        out
    };
    let enable = [DriveRequest::Enable; NUM_JOINTS];
    // One answered cycle at 0.1 rad.
    m.sync();
    m.on_frame(
        0,
        &CanFrame::new_truncating(
            0x181,
            &Tpdo1 {
                statusword: 0x1637,
                position: 0,
            }
            .encode(),
        ),
        0,
    );
    m.on_frame(0, &CanFrame::new_truncating(0x281, &[0; 6]), 0);
    m.send_commands(&enable, &[0.1; NUM_JOINTS]);
    let sent = Rpdo1::decode(frames(&mut m)[0].payload()).unwrap();
    assert_eq!(sent.target_position, units::rad_to_increments(0.1));
    // Then silence: two blind cycles still follow, from the third the target is frozen.
    let mut targets = heapless::Vec::<i32, 16>::new();
    for k in 0..4 {
        m.sync();
        m.send_commands(&enable, &[0.2 + 0.1 * k as f32; NUM_JOINTS]);
        let _ = targets.push(
            Rpdo1::decode(frames(&mut m)[0].payload())
                .unwrap()
                .target_position,
        );
    }
    let inc = units::rad_to_increments;
    assert_eq!(
        targets.as_slice(),
        &[inc(0.2), inc(0.3), inc(0.3), inc(0.3)]
    );
    // Lost (latched): quick stop with the frozen target.
    m.fail(0, NodeFault::FeedbackLost);
    m.send_commands(&enable, &[0.9; NUM_JOINTS]);
    let r = Rpdo1::decode(frames(&mut m)[0].payload()).unwrap();
    assert_eq!((r.controlword, r.target_position), (0x0002, inc(0.3)));
    assert_eq!(m.node(0).lost, LostReaction::QuickStop);
    // Seated, torque off requested: disable voltage x3, NMT stop, then nothing.
    let disable = [DriveRequest::Disable; NUM_JOINTS];
    for _ in 0..LOST_DISABLE_CYCLES {
        m.send_commands(&disable, &[0.0; NUM_JOINTS]);
        let r = Rpdo1::decode(frames(&mut m)[0].payload()).unwrap();
        assert_eq!(r.controlword, 0x0000);
    }
    m.send_commands(&disable, &[0.0; NUM_JOINTS]);
    assert_eq!(frames(&mut m).as_slice(), &[NmtCommand::Stop.frame(1)]);
    assert_eq!(m.node(0).lost, LostReaction::Stopped);
    m.send_commands(&disable, &[0.0; NUM_JOINTS]);
    assert!(frames(&mut m).is_empty());
}
