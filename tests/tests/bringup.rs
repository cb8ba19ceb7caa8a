//! Boot: the controller configures and enables all 18 drives through CAN frames alone, and
//! the recorded candump log shows the CANopen bring-up of every node in order.

use hal_mock::candump::{parse_line, LogEntry};
use hexapod_core::canopen::cia402::PowerState;
use hexapod_core::canopen::cob::{NMT, RPDO_BASE};
use hexapod_core::robot::{
    can_bus, can_node_id, NUM_JOINTS, TORQUE_LIMIT_NM, VELOCITY_LIMIT_RAD_S,
};
use sil_tests::sil::Sil;

/// Index of the first entry at or after `from` that matches `pred`.
fn first_from(log: &[LogEntry], from: usize, pred: impl Fn(&LogEntry) -> bool) -> Option<usize> {
    log.iter().skip(from).position(pred).map(|i| i + from)
}

#[test]
fn boots_and_enables_18_drives_only_through_frames() {
    let mut sil = Sil::new(11).unwrap();
    sil.h.rig.record();
    sil.stand_up().expect("stands up");
    for d in &sil.h.rig.drives {
        assert_eq!(
            d.power_state(),
            PowerState::OperationEnabled,
            "node {}",
            d.node_id()
        );
    }
    assert_eq!(sil.plant().powered_joints(), NUM_JOINTS);
    // The limits the master configured by SDO are the core's, which the simulated drive law
    // applies.
    for (j, d) in sil.h.rig.drives.iter().enumerate() {
        let sp = d.setpoint().expect("torque on");
        assert!(
            (sp.vel_limit_rad_s - VELOCITY_LIMIT_RAD_S[j]).abs() < 0.01 * VELOCITY_LIMIT_RAD_S[j],
            "{sp:?}"
        );
        assert!(
            (sp.torque_limit_nm - TORQUE_LIMIT_NM[j]).abs() < 0.01 * TORQUE_LIMIT_NM[j],
            "{sp:?}"
        );
    }

    let log: Vec<LogEntry> = sil
        .h
        .rig
        .candump()
        .lines()
        .map(|l| parse_line(l).unwrap_or_else(|e| panic!("{e}")))
        .collect();
    for j in 0..NUM_JOINTS {
        let node = can_node_id(j);
        let node16 = u16::from(node);
        let on_bus = |e: &LogEntry| e.bus == can_bus(j);
        // SDO expedited download of 1 byte: 0x6060 (modes of operation) = 8 (CSP) ...
        let mode_write = first_from(&log, 0, |e| {
            on_bus(e)
                && e.frame.cob_id() == 0x600 + node16
                && e.frame.payload() == [0x2F, 0x60, 0x60, 0x00, 0x08, 0, 0, 0]
        })
        .unwrap_or_else(|| panic!("node {node}: no SDO write 0x6060 = 8"));
        // ... confirmed by the drive.
        first_from(&log, mode_write, |e| {
            on_bus(e)
                && e.frame.cob_id() == 0x580 + node16
                && e.frame.payload()[..4] == [0x60, 0x60, 0x60, 0x00]
        })
        .unwrap_or_else(|| panic!("node {node}: 0x6060 write not confirmed"));
        // NMT start (of this node or all nodes) after the configuration.
        let start = first_from(&log, mode_write, |e| {
            on_bus(e)
                && e.frame.cob_id() == NMT
                && e.frame.payload().len() == 2
                && e.frame.payload()[0] == 0x01
                && (e.frame.payload()[1] == node || e.frame.payload()[1] == 0)
        })
        .unwrap_or_else(|| panic!("node {node}: no NMT start after its configuration"));
        // The CiA 402 power state machine: shutdown (6), switch on (7), enable operation (15),
        // in that order, carried by RPDO1.
        let mut at = start;
        for cw in [0x0006u16, 0x0007, 0x000F] {
            at = first_from(&log, at, |e| {
                on_bus(e)
                    && e.frame.cob_id() == RPDO_BASE[0] + node16
                    && e.frame.payload().len() == 6
                    && u16::from_le_bytes([e.frame.payload()[0], e.frame.payload()[1]]) & 0x8F == cw
            })
            .unwrap_or_else(|| panic!("node {node}: no controlword {cw:#06x} after NMT start"));
        }
        // The drive reports Operation enabled (statusword xxxx xxxx x01x 0111) in TPDO1.
        first_from(&log, at, |e| {
            on_bus(e)
                && e.frame.cob_id() == 0x180 + node16
                && u16::from_le_bytes([e.frame.payload()[0], e.frame.payload()[1]]) & 0x6F == 0x27
        })
        .unwrap_or_else(|| panic!("node {node}: no TPDO1 with Operation enabled"));
    }
}
