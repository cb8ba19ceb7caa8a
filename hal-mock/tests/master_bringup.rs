//! The CiA 402 master brings the 18 emulated drives to Operation enabled purely through
//! frames on the virtual buses, runs the cyclic exchange, and detects lost heartbeats,
//! EMCY and bus-off.
#![allow(clippy::needless_range_loop)]

use hal_mock::plant::JointModel;
use hal_mock::rig::DriveRig;
use hexapod_core::canopen::cia402::{DriveRequest, PowerState};
use hexapod_core::canopen::master::{Master, NodeFault, NodePhase};
use hexapod_core::canopen::units::rad_to_increments;
use hexapod_core::hal::CanBus;
use hexapod_core::robot::{
    NUM_JOINTS, Q0_RAD, Q_MAX_RAD, Q_MIN_RAD, Q_SIT_RAD, TORQUE_LIMIT_NM, VELOCITY_LIMIT_RAD_S,
};
use hexapod_core::timing::PHYSICS_DT_S;

const STEP_US: u64 = 1_000;

struct Bench {
    master: Master,
    rig: DriveRig,
    plant: JointModel,
    now_us: u64,
}

impl Bench {
    fn new() -> Self {
        let mut rig = DriveRig::new(1);
        rig.record();
        rig.power_on(0);
        Self {
            master: Master::new(),
            rig,
            plant: JointModel::at(&Q_SIT_RAD),
            now_us: 0,
        }
    }

    /// Moves frames both ways and advances time by 1 ms.
    fn pump(&mut self) {
        self.master.poll(self.now_us);
        for bus in 0..2 {
            while let Some(f) = self.master.pop_tx(bus) {
                let _ = self.rig.buses[bus].try_send(&f);
            }
        }
        self.rig.step(self.now_us, &mut self.plant);
        for bus in 0..2 {
            let off = self.rig.buses[bus].is_bus_off();
            self.master.set_bus_off(bus, off, self.now_us);
            while let Some(f) = self.rig.buses[bus].try_receive() {
                self.master.on_frame(bus, &f, self.now_us);
            }
        }
        self.now_us += STEP_US;
        if self.now_us.is_multiple_of(5_000) {
            self.plant.step(PHYSICS_DT_S);
        }
    }

    fn configure(&mut self) {
        // The drives' power-on boot-up messages pass before the controller starts.
        for _ in 0..5 {
            self.pump();
        }
        self.master.start(self.now_us);
        while self.master.configuring() && self.now_us < 3_000_000 {
            self.pump();
        }
    }

    /// One 20 ms control cycle with the given request and targets.
    fn cycle(&mut self, request: DriveRequest, targets: &[f32; NUM_JOINTS]) {
        self.master.sync();
        let t0 = self.now_us;
        while !self.master.feedback_complete() && self.now_us < t0 + 5_000 {
            self.pump();
        }
        self.master.send_commands(&[request; NUM_JOINTS], targets);
        while self.now_us < t0 + 20_000 {
            self.pump();
        }
    }
}

#[test]
fn configures_and_enables_all_drives_through_frames() {
    let mut b = Bench::new();
    b.configure();
    assert_eq!(b.master.first_fault(), None);
    for j in 0..NUM_JOINTS {
        assert_eq!(b.master.node(j).phase, NodePhase::Operational, "joint {j}");
        let d = &b.rig.drives[j];
        assert_eq!(d.objects.mode(), 8);
        assert_eq!(d.objects.rpdo_map(0).active(), &[0x6040_0010, 0x607A_0020]);
        assert_eq!(d.objects.producer_heartbeat_ms(), 100);
        // The speed limit in the profile's units, as the drive reads them from its own
        // dictionary: 0x6080 in motor rpm, 0x607F in increments/s.
        let sp_limit = d.setpoint_limits();
        assert!(
            (sp_limit.0 - VELOCITY_LIMIT_RAD_S[j]).abs() < 0.01 * VELOCITY_LIMIT_RAD_S[j],
            "joint {j}: velocity limit {} rad/s",
            sp_limit.0
        );
        assert_eq!(
            d.objects.position_limits(),
            [
                rad_to_increments(Q_MIN_RAD[j]),
                rad_to_increments(Q_MAX_RAD[j])
            ]
        );
    }
    // Configuration ran over SDO: 47 transfers x 2 frames x 18 drives at least.
    assert!(b.rig.buses.iter().map(|x| x.stats.frames).sum::<u64>() > 47 * 2 * 18);

    let mut cycles = 0;
    while !b.master.all_enabled() && cycles < 10 {
        b.cycle(DriveRequest::Enable, &Q_SIT_RAD);
        cycles += 1;
    }
    assert!(b.master.all_enabled(), "not enabled after {cycles} cycles");
    assert!(cycles <= 5, "{cycles}");
    for (j, d) in b.rig.drives.iter().enumerate() {
        assert_eq!(d.power_state(), PowerState::OperationEnabled);
        // The drive enforces the same limits the simulator's CSP law uses.
        // 0x6080 is whole motor rpm, rounded down: within 1 rpm (0.012 rad/s at 9:1) below.
        let sp = d.setpoint().unwrap();
        let below = VELOCITY_LIMIT_RAD_S[j] - sp.vel_limit_rad_s;
        assert!((0.0..0.012).contains(&below), "{sp:?}");
        assert!(
            (sp.torque_limit_nm - TORQUE_LIMIT_NM[j]).abs() < 1e-3,
            "{sp:?}"
        );
    }
    // Enabling did not move the joints.
    for j in 0..NUM_JOINTS {
        assert!((b.plant.states[j].q_rad - Q_SIT_RAD[j]).abs() < 1e-3);
    }
    assert_eq!(b.master.counters.malformed, 0);
    assert_eq!(b.master.counters.unexpected_sdo, 0);
}

#[test]
fn cyclic_exchange_tracks_targets_and_reports_feedback() {
    let mut b = Bench::new();
    b.configure();
    for _ in 0..5 {
        b.cycle(DriveRequest::Enable, &Q_SIT_RAD);
    }
    assert!(b.master.all_enabled());
    // Ramp to the nominal pose over 1 s.
    for k in 1..=50 {
        let a = k as f32 / 50.0;
        let mut t = [0.0; NUM_JOINTS];
        for j in 0..NUM_JOINTS {
            t[j] = Q_SIT_RAD[j] + a * (Q0_RAD[j] - Q_SIT_RAD[j]);
        }
        b.cycle(DriveRequest::Enable, &t);
    }
    for _ in 0..10 {
        b.cycle(DriveRequest::Enable, &Q0_RAD);
    }
    let fb = b.master.feedback();
    for j in 0..NUM_JOINTS {
        assert!(
            (fb.q_rad[j] - Q0_RAD[j]).abs() < 0.01,
            "joint {j}: {}",
            fb.q_rad[j]
        );
        assert!((fb.q_rad[j] - b.plant.states[j].q_rad).abs() < 1e-4);
    }
    // Torque feedback: block the joints and ask for 0.1 rad more; the CSP law answers
    // 2 N m s/rad * 50 1/s * 0.1 rad = 10 N m, reported in per mille of the rated torque
    // read over SDO and converted back to N m by the master.
    b.plant.inertia_kg_m2 = 1e9;
    let mut t = [0.0; NUM_JOINTS];
    for j in 0..NUM_JOINTS {
        t[j] = b.plant.states[j].q_rad + 0.1;
    }
    b.cycle(DriveRequest::Enable, &t);
    b.cycle(DriveRequest::Enable, &t);
    let fb = b.master.feedback();
    for j in 0..NUM_JOINTS {
        let quantum_nm = b.master.node(j).rated_torque_mnm as f32 * 1e-6;
        let tau = b.plant.states[j].torque_nm;
        assert!((tau - 10.0).abs() < 0.05, "{tau}");
        assert!(
            (fb.torque_nm[j] - tau).abs() <= quantum_nm,
            "joint {j}: {} vs {tau}",
            fb.torque_nm[j]
        );
    }
    assert_eq!(b.master.first_fault(), None);
    // The log is candump text with both buses.
    let log = b.rig.candump();
    assert!(log.lines().any(|l| l.contains(" can0 080#")));
    assert!(log.lines().any(|l| l.contains(" can1 20A#")));
}

#[test]
fn lost_heartbeat_is_detected() {
    let mut b = Bench::new();
    b.configure();
    for _ in 0..5 {
        b.cycle(DriveRequest::Enable, &Q_SIT_RAD);
    }
    b.rig.drives[7].set_mute(true);
    for _ in 0..20 {
        b.cycle(DriveRequest::Enable, &Q_SIT_RAD);
    }
    let fault = b.master.node(7).fault;
    assert!(
        matches!(
            fault,
            Some(NodeFault::LostHeartbeat | NodeFault::FeedbackLost)
        ),
        "{fault:?}"
    );
    assert_eq!(b.master.node(6).fault, None);
}

#[test]
fn emcy_faults_the_node_and_fault_reset_recovers() {
    let mut b = Bench::new();
    b.configure();
    for _ in 0..5 {
        b.cycle(DriveRequest::Enable, &Q_SIT_RAD);
    }
    let mut out = Vec::new();
    b.rig.drives[12].inject_fault(0x2310, &mut out);
    for f in &out {
        b.rig.buses[1].send_from_drive(f);
    }
    b.cycle(DriveRequest::Enable, &Q_SIT_RAD);
    assert_eq!(
        b.master.node(12).fault,
        Some(NodeFault::Emergency { error_code: 0x2310 })
    );
    assert_eq!(b.master.node(12).power, PowerState::Fault);
    assert_eq!(b.master.counters.emergencies, 1);
    for _ in 0..3 {
        b.cycle(DriveRequest::FaultReset, &Q_SIT_RAD);
    }
    assert_eq!(b.rig.drives[12].power_state(), PowerState::SwitchOnDisabled);
    b.master.clear_recoverable_faults();
    assert_eq!(b.master.first_fault(), None);
    for _ in 0..5 {
        b.cycle(DriveRequest::Enable, &Q_SIT_RAD);
    }
    assert!(b.master.all_enabled());
}

#[test]
fn bus_off_loses_that_bus_only() {
    let mut b = Bench::new();
    b.configure();
    for _ in 0..5 {
        b.cycle(DriveRequest::Enable, &Q_SIT_RAD);
    }
    b.rig.buses[0].faults.bus_off = true;
    b.cycle(DriveRequest::Enable, &Q_SIT_RAD);
    for j in 0..NUM_JOINTS {
        let expect = if j < 9 { Some(NodeFault::BusOff) } else { None };
        assert_eq!(b.master.node(j).fault, expect, "joint {j}");
    }
    // The drives of the silent bus lose the master's heartbeat and hold by quick stop.
    for _ in 0..25 {
        b.cycle(DriveRequest::Enable, &Q_SIT_RAD);
    }
    assert_eq!(b.rig.drives[0].power_state(), PowerState::QuickStopActive);
    assert!(
        b.rig.drives[0].setpoint().is_some(),
        "a held joint keeps torque"
    );
    assert_eq!(b.rig.drives[10].power_state(), PowerState::OperationEnabled);
}

#[test]
fn configuration_survives_frame_loss_by_retrying() {
    let mut b = Bench::new();
    for bus in &mut b.rig.buses {
        bus.faults.loss_probability = 0.02;
    }
    b.configure();
    let configured = (0..NUM_JOINTS)
        .filter(|&j| b.master.node(j).phase == NodePhase::Operational)
        .count();
    // With 2 % loss and 2 retries per step, essentially every drive completes.
    assert!(configured >= NUM_JOINTS - 1, "{configured}");
}

/// Every step of the master's SDO script addresses an object of the drive's EDS with the
/// right access, size and range (the EDS is written from the profile, not from the master).
#[test]
fn the_sdo_script_matches_the_drive_eds() {
    use hal_mock::eds::Eds;
    use hexapod_core::canopen::drive_config::{config_step, ConfigStep};
    let eds = Eds::cia402_servo();
    for j in 0..NUM_JOINTS {
        let rated = (TORQUE_LIMIT_NM[j] * 500.0) as u32;
        for step in (0..).map_while(|k| config_step(k, j, rated)) {
            match step {
                ConfigStep::Read(a) => {
                    let e = eds
                        .entry(a.index, a.sub)
                        .unwrap_or_else(|| panic!("{a:?} not in the EDS"));
                    assert!(e.access.readable(), "{a:?} {e:?}");
                }
                ConfigStep::Write(a, value, len) => {
                    let e = eds
                        .entry(a.index, a.sub)
                        .unwrap_or_else(|| panic!("{a:?} not in the EDS"));
                    assert!(e.access.writable(), "{a:?} {e:?}");
                    assert_eq!(e.data_type.size(), len, "{a:?} {e:?}");
                    assert!(e.in_range(value), "{a:?} = {value} {e:?}");
                }
            }
        }
    }
}
