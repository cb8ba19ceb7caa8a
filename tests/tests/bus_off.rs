//! Bus-off and its recovery with physics: bus 0's CAN peripheral goes bus-off for 200 ms
//! while the robot stands. The robot holds on bus 1 (bus 0's drives hold by themselves);
//! when the disturbance ends the peripheral recovers after 128 x 11 recessive bits
//! (ISO 11898-1), the master re-synchronizes bus 0 (probe, reset, configuration) and adopts
//! its drives at their positions, and the robot sits down on all six legs.

use hexapod_core::controller::ZeroPolicy;
use hexapod_core::robot::NUM_JOINTS;
use hexapod_core::supervisor::{Fault, Mode};
use sil_tests::sil::Sil;
use sil_tests::sim_plant::sitting_height_m;

#[test]
fn bus_off_recovers_resyncs_and_sits_down_on_all_legs() {
    let mut sil = Sil::new(111).unwrap();
    sil.stand_up().expect("stands up");
    sil.run(0.5, &mut ZeroPolicy);
    let t_fault = sil.time_s();
    sil.h.rig.buses[0].faults.bus_off = true;
    sil.run(0.2, &mut ZeroPolicy);
    assert_eq!(
        sil.mode(),
        Mode::SafeHold {
            fault: Fault::BusOff { bus: 0 }
        }
    );
    sil.h.rig.buses[0].faults.bus_off = false;
    let t_back = sil.time_s();
    assert!(
        sil.run_until(1.0, &mut ZeroPolicy, |m| matches!(
            m,
            Mode::SafeSitDown { .. }
        )),
        "{:?}",
        sil.mode()
    );
    let resync_s = sil.time_s() - t_back;
    println!("bus 0 back and its drives adopted {resync_s:.3} s after the disturbance ended");
    let master = &sil.h.controller.master;
    assert_eq!(master.counters.bus_off_events, 1);
    assert_eq!(master.counters.bus_off_recoveries, 1);
    assert_eq!(sil.h.rig.buses[0].stats.bus_off_recoveries, 1);
    assert!((0..NUM_JOINTS).all(|j| master.node(j).is_healthy()));
    assert!((0..NUM_JOINTS).filter(|&j| master.node(j).adopted).count() >= 9);
    assert_eq!(sil.plant().powered_joints(), 18);
    assert!(sil.run_until(7.0, &mut ZeroPolicy, |m| matches!(m, Mode::Faulted { .. })));
    sil.run(0.5, &mut ZeroPolicy);
    let trace = &sil.plant().trace;
    let off = *trace.torque_off(t_fault).expect("torque off once seated");
    assert!(off.height_m() < sitting_height_m() + 0.02);
    assert!(trace
        .since(t_fault)
        .iter()
        .take_while(|s| s.t_s < off.t_s)
        .all(|s| s.powered_joints == 18));
    if let Some(c) = trace.first_trunk_contact(t_fault) {
        assert!(c.t_s >= off.t_s);
    }
    // On all six legs: level, unlike the sit-down on one bus (0.23 rad).
    let tilt = trace
        .since(t_fault)
        .iter()
        .take_while(|s| s.t_s < off.t_s)
        .map(|s| s.tilt_rad)
        .fold(0.0, f32::max);
    assert!(tilt < 0.1, "tilts {tilt} rad");
    // The bus is back: the fault clears with the arm switch off.
    sil.h.rc.set_arm(false);
    assert!(sil.run_until(0.5, &mut ZeroPolicy, |m| m == Mode::Disabled));
}
