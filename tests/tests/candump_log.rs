//! A SIL run recorded in the candump log format: boot, stand-up, walking with the generated
//! policy (with bit errors on the buses: error frames in the log), a drive EMCY and the safe
//! sit-down. The log is written to
//! `target/tmp/sil/physics.log` (CI reads it with python-can's candump reader) and must
//! parse back frame by frame.

use hal_mock::candump::{parse_line, LogEntry};
use hexapod_core::canopen::cob::SYNC;
use hexapod_core::controller::ZeroPolicy;
use hexapod_core::robot::can_node_id;
use hexapod_core::supervisor::Mode;
use sil_tests::sil::{generated_policy, Sil};

const FAULTY_JOINT: usize = 13;
const EMCY_CODE: u16 = 0x2310;

#[test]
fn records_a_physics_run_as_a_candump_log() {
    let mut sil = Sil::new(51).unwrap();
    sil.h.rig.record();
    sil.stand_up().expect("stands up");
    let mut policy = generated_policy().expect("valid generated policy");
    sil.h.rc.set_sticks(0.6, 0.0, 0.0);
    for bus in &mut sil.h.rig.buses {
        bus.faults.error_probability = 0.005;
    }
    sil.run(2.0, &mut policy);
    sil.h.rig.inject_drive_fault(FAULTY_JOINT, EMCY_CODE);
    assert!(sil.run_until(7.0, &mut policy, |m| matches!(m, Mode::Faulted { .. })));
    sil.run(0.5, &mut ZeroPolicy);

    let log = sil.h.rig.candump();
    let entries: Vec<LogEntry> = log
        .lines()
        .map(|l| parse_line(l).unwrap_or_else(|e| panic!("{e}")))
        .collect();
    assert!(
        entries.windows(2).all(|w| w[0].time_us <= w[1].time_us),
        "time goes back"
    );
    let error_frames = entries.iter().filter(|e| e.error_frame).count() as u64;
    assert!(error_frames > 0);
    assert_eq!(
        error_frames,
        sil.h
            .rig
            .buses
            .iter()
            .map(|b| b.stats.error_frames)
            .sum::<u64>()
    );
    let syncs = entries
        .iter()
        .filter(|e| !e.error_frame && e.frame.cob_id() == SYNC)
        .count() as u32;
    assert_eq!(
        syncs,
        2 * sil.h.controller.stats.cycles,
        "one SYNC per bus and cycle"
    );
    // The EMCY of the faulty drive: 0x080 + node id, error code first (little endian).
    let node = u16::from(can_node_id(FAULTY_JOINT));
    let emcy = entries
        .iter()
        .find(|e| e.frame.cob_id() == SYNC + node)
        .expect("EMCY in the log");
    assert_eq!(emcy.frame.payload()[..2], EMCY_CODE.to_le_bytes());

    let dir = concat!(env!("CARGO_TARGET_TMPDIR"), "/sil");
    std::fs::create_dir_all(dir).unwrap();
    std::fs::write(format!("{dir}/physics.log"), &log).unwrap();
}
