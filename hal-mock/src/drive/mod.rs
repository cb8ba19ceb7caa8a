//! A CiA 402 servo drive emulator speaking CANopen frames: NMT, an SDO server over
//! [`objects::Objects`], SYNC-driven TPDOs and RPDOs by their configured mapping, the
//! power state machine, producer and consumer heartbeat, EMCY, and CSP tracking through a
//! [`crate::plant::JointPlant`].
//!
//! The object dictionary comes from the drive's EDS ([`objects`], `hal-mock/eds`), and the
//! drive converts its units the way the profile defines them from its own objects
//! ([`DriveScale`]: encoder resolution 0x608F, gear ratio 0x6091, 0x6080 in motor rpm),
//! not with the master's `units.rs`: a unit error in the master shows as a wrong limit or
//! position here.
//!
//! Fault injection: [`Drive::inject_fault`] (fault state + EMCY), [`Drive::set_mute`]
//! (the node falls silent: lost heartbeat), [`Drive::set_tx_mute`] (it still receives but
//! nothing it sends arrives), [`Drive::set_heartbeat_mute`] (heartbeat stops, PDOs go on).

pub mod objects;

use hexapod_core::can_frame::CanFrame;
use hexapod_core::canopen::cia402::{PowerState, SW_REMOTE, SW_TARGET_REACHED, SW_VOLTAGE_ENABLED};
use hexapod_core::canopen::cob::{self, Cob};
use hexapod_core::canopen::emcy::{self, Emcy};
use hexapod_core::canopen::nmt::{NmtCommand, NmtState};
use hexapod_core::canopen::od;
use hexapod_core::canopen::sdo::{abort, SdoRequest, SdoResponse};
use hexapod_core::robot::{can_node_id, TORQUE_LIMIT_NM};
use std::f64::consts::TAU;

use crate::plant::{CspSetpoint, JointState};
use objects::Objects;

/// Counters of what the drive rejected.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct DriveCounters {
    /// SDO requests answered with an abort.
    pub sdo_aborts: u32,
    /// Frames with a wrong length for their PDO or service.
    pub malformed: u32,
}

/// The drive's units, from its own object dictionary (CiA 402 factor group).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DriveScale {
    /// Position units (encoder increments) per radian of the output shaft.
    pub increments_per_rad: f64,
    /// Motor revolutions per output shaft revolution (0x6091).
    pub gear_ratio: f64,
}

impl DriveScale {
    /// Output angle, rad -> position units.
    pub fn to_increments(&self, rad: f32) -> i32 {
        (rad as f64 * self.increments_per_rad).round() as i32
    }
    /// Position units -> output angle, rad.
    pub fn to_rad(&self, increments: i32) -> f32 {
        (increments as f64 / self.increments_per_rad) as f32
    }
    /// Output speed, rad/s -> velocity units (position units per second).
    pub fn to_velocity_units(&self, rad_s: f32) -> i32 {
        (rad_s as f64 * self.increments_per_rad).round() as i32
    }
    /// Velocity units -> output speed, rad/s.
    pub fn velocity_units_to_rad_s(&self, units: u32) -> f32 {
        (units as f64 / self.increments_per_rad) as f32
    }
    /// Motor speed in rpm (0x6080) -> output speed, rad/s.
    pub fn motor_rpm_to_rad_s(&self, rpm: u32) -> f32 {
        (rpm as f64 * TAU / 60.0 / self.gear_ratio) as f32
    }
}

/// One emulated drive.
#[derive(Clone, Debug)]
pub struct Drive {
    joint: usize,
    node_id: u8,
    nmt: NmtState,
    power: PowerState,
    /// The object dictionary.
    pub objects: Objects,
    previous_controlword: u16,
    hold_position: i32,
    feedback: JointState,
    next_heartbeat_us: Option<u64>,
    master_heartbeat_us: Option<u64>,
    consumer_tripped: bool,
    sync_counter: [u8; 4],
    muted: bool,
    tx_muted: bool,
    heartbeat_muted: bool,
    /// Rejected-input counters.
    pub counters: DriveCounters,
}

impl Drive {
    /// A drive for `joint`, powered off (call [`Drive::power_on`]).
    pub fn new(joint: usize) -> Self {
        let node_id = can_node_id(joint);
        // Rated torque: half the peak torque of the joint (peak = 200 % of rated).
        let rated_torque_mnm = (TORQUE_LIMIT_NM[joint] * 500.0) as u32;
        Self {
            joint,
            node_id,
            nmt: NmtState::BootUp,
            power: PowerState::NotReadyToSwitchOn,
            objects: Objects::defaults(node_id, rated_torque_mnm),
            previous_controlword: 0,
            hold_position: 0,
            feedback: JointState::default(),
            next_heartbeat_us: None,
            master_heartbeat_us: None,
            consumer_tripped: false,
            sync_counter: [0; 4],
            muted: false,
            tx_muted: false,
            heartbeat_muted: false,
            counters: DriveCounters::default(),
        }
    }

    /// The joint this drive moves.
    pub fn joint(&self) -> usize {
        self.joint
    }

    /// The CANopen node id.
    pub fn node_id(&self) -> u8 {
        self.node_id
    }

    /// The NMT state.
    pub fn nmt_state(&self) -> NmtState {
        self.nmt
    }

    /// The CiA 402 power state.
    pub fn power_state(&self) -> PowerState {
        self.power
    }

    /// The drive's units from its encoder resolution (0x608F) and gear ratio (0x6091).
    pub fn scale(&self) -> DriveScale {
        let o = &self.objects;
        let ratio = |index: u16| {
            let num = o.get(od::ObjectAddress::new(index, 1)).max(1) as f64;
            let den = o.get(od::ObjectAddress::new(index, 2)).max(1) as f64;
            num / den
        };
        let increments_per_motor_rev = ratio(0x608F);
        let gear_ratio = ratio(0x6091);
        DriveScale {
            increments_per_rad: increments_per_motor_rev * gear_ratio / TAU,
            gear_ratio,
        }
    }

    /// Initialisation: boot-up message, then pre-operational, power stage Switch on disabled.
    pub fn power_on(&mut self, now_us: u64, out: &mut Vec<CanFrame>) {
        let rated = self.objects.rated_torque_mnm();
        self.objects = Objects::defaults(self.node_id, rated);
        self.power = PowerState::SwitchOnDisabled;
        self.previous_controlword = 0;
        self.reset_communication(now_us, out);
    }

    fn reset_communication(&mut self, now_us: u64, out: &mut Vec<CanFrame>) {
        self.objects.reset_communication();
        self.master_heartbeat_us = None;
        self.consumer_tripped = false;
        self.sync_counter = [0; 4];
        self.next_heartbeat_us = None;
        self.send(out, NmtState::BootUp.heartbeat_frame(self.node_id));
        self.nmt = NmtState::PreOperational;
        let _ = now_us;
    }

    /// Silences the node (no frames out, none processed): a cut cable or dead drive.
    pub fn set_mute(&mut self, muted: bool) {
        self.muted = muted;
    }

    /// Nothing the drive sends arrives, but it still receives and acts on what it hears
    /// (a broken transmit path).
    pub fn set_tx_mute(&mut self, muted: bool) {
        self.tx_muted = muted;
    }

    /// The drive stops producing its heartbeat; PDOs, SDOs and EMCY go on.
    pub fn set_heartbeat_mute(&mut self, muted: bool) {
        self.heartbeat_muted = muted;
    }

    /// A drive fault: torque off, error code 0x603F, EMCY.
    pub fn inject_fault(&mut self, error_code: u16, out: &mut Vec<CanFrame>) {
        self.power = PowerState::Fault;
        self.objects.set_internal(od::ERROR_CODE, error_code as u32);
        self.objects
            .set_internal(od::ObjectAddress::new(0x1001, 0), 0x01);
        let e = Emcy {
            error_code,
            error_register: 0x01,
            vendor: [0; 5],
        };
        self.send(out, e.frame(self.node_id));
    }

    /// The measured joint state, sampled at the next SYNC.
    pub fn set_feedback(&mut self, state: JointState) {
        self.feedback = state;
    }

    /// The setpoint the drive's power stage applies now (`None` = torque off).
    pub fn setpoint(&self) -> Option<CspSetpoint> {
        let o = &self.objects;
        let [min, max] = o.position_limits();
        let target = match self.power {
            PowerState::OperationEnabled if o.mode() == od::MODE_CSP => {
                o.target_position().clamp(min, max)
            }
            PowerState::OperationEnabled | PowerState::QuickStopActive => self.hold_position,
            _ => return None,
        };
        let (vel_limit_rad_s, torque_limit_nm) = self.setpoint_limits();
        Some(CspSetpoint {
            q_target_rad: self.scale().to_rad(target),
            vel_limit_rad_s,
            torque_limit_nm,
        })
    }

    /// The speed (rad/s) and torque (N m) limits the power stage applies, from the
    /// configured objects in the profile's units.
    pub fn setpoint_limits(&self) -> (f32, f32) {
        let o = &self.objects;
        let scale = self.scale();
        // CSP: the speed is limited by the max motor speed (0x6080, motor rpm) and the max
        // profile velocity (0x607F, velocity units), whichever is lower.
        let vel_limit_rad_s = scale
            .motor_rpm_to_rad_s(o.get(od::MAX_MOTOR_SPEED))
            .min(scale.velocity_units_to_rad_s(o.get(od::MAX_PROFILE_VELOCITY)));
        let torque_limit_nm = o.max_torque() as f32 * o.rated_torque_mnm() as f32 * 1e-6;
        (vel_limit_rad_s, torque_limit_nm)
    }

    fn send(&self, out: &mut Vec<CanFrame>, frame: CanFrame) {
        if !self.muted && !self.tx_muted {
            out.push(frame);
        }
    }

    /// Handles one frame from the bus; responses go to `out`.
    pub fn on_frame(&mut self, frame: &CanFrame, now_us: u64, out: &mut Vec<CanFrame>) {
        if self.muted || frame.is_rtr() {
            return;
        }
        let Some(c) = cob::classify(frame.cob_id()) else {
            return;
        };
        let p = frame.payload();
        match c {
            Cob::Nmt => self.on_nmt(p, now_us, out),
            Cob::Heartbeat(n) if n as u32 == (self.objects.consumer_heartbeat() >> 16) & 0x7F => {
                self.master_heartbeat_us = Some(now_us);
            }
            Cob::Heartbeat(_) => {}
            _ if frame.cob_id() == (self.objects.sync_cob_id() & 0x7FF) as u16 => self.on_sync(out),
            Cob::SdoRx(n) if n == self.node_id => self.on_sdo(p, out),
            Cob::Rpdo(..) if self.nmt == NmtState::Operational => self.on_rpdo(frame, out),
            _ => {}
        }
    }

    fn on_nmt(&mut self, p: &[u8], now_us: u64, out: &mut Vec<CanFrame>) {
        let Some((command, node)) = NmtCommand::parse(p) else {
            self.counters.malformed += 1;
            return;
        };
        if node != 0 && node != self.node_id {
            return;
        }
        match command {
            NmtCommand::Start => self.nmt = NmtState::Operational,
            NmtCommand::Stop => {
                // CiA 402 0x6007: entering NMT stopped is a communication abort.
                self.nmt = NmtState::Stopped;
                self.abort_connection();
            }
            NmtCommand::EnterPreOperational => self.nmt = NmtState::PreOperational,
            NmtCommand::ResetCommunication => {
                // So is a reset of communication; the power stage keeps its state.
                self.abort_connection();
                self.reset_communication(now_us, out);
            }
            NmtCommand::ResetNode => self.power_on(now_us, out),
        }
    }

    fn on_sdo(&mut self, p: &[u8], out: &mut Vec<CanFrame>) {
        if self.nmt == NmtState::Stopped {
            return;
        }
        let response = match SdoRequest::parse(p) {
            Ok(SdoRequest::Download { address, data, len }) => {
                match self.objects.write(address, u32::from_le_bytes(data), len) {
                    Ok(()) => SdoResponse::DownloadAck { address },
                    Err(code) => SdoResponse::Abort { address, code },
                }
            }
            Ok(SdoRequest::Upload { address }) => {
                self.refresh_objects();
                match self.objects.read(address) {
                    Ok((value, len)) => SdoResponse::Upload {
                        address,
                        data: value.to_le_bytes(),
                        len,
                    },
                    Err(code) => SdoResponse::Abort { address, code },
                }
            }
            Ok(SdoRequest::Abort { .. }) => return,
            Err(_) if p.len() >= 4 => {
                let address = od::ObjectAddress::new(u16::from_le_bytes([p[1], p[2]]), p[3]);
                SdoResponse::Abort {
                    address,
                    code: abort::INVALID_COMMAND,
                }
            }
            Err(_) => {
                self.counters.malformed += 1;
                return;
            }
        };
        if matches!(response, SdoResponse::Abort { .. }) {
            self.counters.sdo_aborts += 1;
        }
        if let SdoResponse::DownloadAck { address } = response {
            if address == od::CONTROLWORD {
                self.apply_controlword(out);
            }
        }
        self.send(out, response.frame(self.node_id));
    }

    fn on_rpdo(&mut self, frame: &CanFrame, out: &mut Vec<CanFrame>) {
        let Some(k) = (0..4).find(|&k| {
            let c = self.objects.rpdo_comm(k);
            c.valid() && (c.cob_id & 0x7FF) as u16 == frame.cob_id()
        }) else {
            return;
        };
        let map = self.objects.rpdo_map(k);
        let bytes: usize = map.active().iter().map(|&e| (e & 0xFF) as usize / 8).sum();
        let p = frame.payload();
        if p.len() != bytes {
            self.counters.malformed += 1;
            return;
        }
        let mut at = 0;
        for &entry in map.active() {
            let n = (entry & 0xFF) as usize / 8;
            let mut le = [0u8; 4];
            le[..n.min(4)].copy_from_slice(&p[at..at + n.min(4)]);
            at += n;
            self.objects.write_mapped(entry, u32::from_le_bytes(le));
        }
        self.apply_controlword(out);
    }

    /// The CiA 402 state machine reacting to the controlword (CiA 402 table 29).
    fn apply_controlword(&mut self, out: &mut Vec<CanFrame>) {
        use PowerState as S;
        let cw = self.objects.controlword();
        let rising_reset = cw & 0x80 != 0 && self.previous_controlword & 0x80 == 0;
        self.previous_controlword = cw;
        let shutdown = cw & 0x87 == 0x06;
        let switch_on = cw & 0x8F == 0x07;
        let enable = cw & 0x8F == 0x0F;
        let disable_voltage = cw & 0x82 == 0x00;
        let quick_stop = cw & 0x86 == 0x02;
        let next = match self.power {
            S::Fault | S::FaultReactionActive => {
                if rising_reset {
                    self.objects.set_internal(od::ERROR_CODE, 0);
                    self.objects
                        .set_internal(od::ObjectAddress::new(0x1001, 0), 0);
                    let e = Emcy {
                        error_code: emcy::ERROR_RESET,
                        error_register: 0,
                        vendor: [0; 5],
                    };
                    self.send(out, e.frame(self.node_id));
                    S::SwitchOnDisabled
                } else {
                    self.power
                }
            }
            _ if disable_voltage => S::SwitchOnDisabled,
            S::SwitchOnDisabled | S::NotReadyToSwitchOn if shutdown => S::ReadyToSwitchOn,
            S::ReadyToSwitchOn if switch_on => S::SwitchedOn,
            S::ReadyToSwitchOn if quick_stop => S::SwitchOnDisabled,
            S::SwitchedOn if enable => S::OperationEnabled,
            S::SwitchedOn if shutdown => S::ReadyToSwitchOn,
            S::SwitchedOn if quick_stop => S::SwitchOnDisabled,
            S::OperationEnabled if switch_on => S::SwitchedOn,
            S::OperationEnabled if shutdown => S::ReadyToSwitchOn,
            S::OperationEnabled if quick_stop => self.quick_stop_state(),
            S::QuickStopActive if enable => S::OperationEnabled,
            s => s,
        };
        if next != self.power && next.torque_on() {
            self.hold_position = self.scale().to_increments(self.feedback.q_rad);
        }
        self.power = next;
    }

    /// Where a quick stop ends (0x605A): options 5..=8 stay in Quick stop active, holding
    /// position with torque on; 0..=4 end in Switch on disabled (torque off).
    fn quick_stop_state(&self) -> PowerState {
        if (5..=8).contains(&self.objects.quick_stop_option()) {
            PowerState::QuickStopActive
        } else {
            PowerState::SwitchOnDisabled
        }
    }

    fn refresh_objects(&mut self) {
        let scale = self.scale();
        let o = &mut self.objects;
        let mut sw = self.power.statusword_bits() | SW_REMOTE;
        if self.power.torque_on() || matches!(self.power, PowerState::SwitchedOn) {
            sw |= SW_VOLTAGE_ENABLED;
        }
        let position = scale.to_increments(self.feedback.q_rad);
        let target_error = (o.target_position() as i64 - position as i64).abs();
        if target_error < scale.to_increments(0.01) as i64 {
            sw |= SW_TARGET_REACHED;
        }
        if self.power == PowerState::OperationEnabled && o.mode() == od::MODE_CSP {
            sw |= hexapod_core::canopen::cia402::SW_CSP_FOLLOWING;
        }
        let rated_nm = o.rated_torque_mnm().max(1) as f32 * 1e-3;
        let torque_permille = (self.feedback.torque_nm / rated_nm * 1000.0)
            .round()
            .clamp(i16::MIN as f32, i16::MAX as f32) as i16;
        o.set_internal(od::STATUSWORD, sw as u32);
        o.set_internal(od::MODES_OF_OPERATION_DISPLAY, o.mode() as u8 as u32);
        o.set_internal(od::POSITION_ACTUAL, position as u32);
        o.set_internal(
            od::VELOCITY_ACTUAL,
            scale.to_velocity_units(self.feedback.qdot_rad_s) as u32,
        );
        o.set_internal(od::TORQUE_ACTUAL, torque_permille as u16 as u32);
    }

    fn on_sync(&mut self, out: &mut Vec<CanFrame>) {
        if self.nmt != NmtState::Operational {
            return;
        }
        self.refresh_objects();
        for k in 0..4 {
            let c = self.objects.tpdo_comm(k);
            if !c.valid() || !(1..=240).contains(&c.transmission) {
                continue;
            }
            self.sync_counter[k] += 1;
            if self.sync_counter[k] < c.transmission {
                continue;
            }
            self.sync_counter[k] = 0;
            let mut payload = [0u8; 8];
            let mut at = 0;
            for &entry in self.objects.tpdo_map(k).active() {
                let Some((value, bits)) = self.objects.mapped_value(entry) else {
                    continue;
                };
                let n = bits as usize / 8;
                if at + n > 8 {
                    break;
                }
                payload[at..at + n].copy_from_slice(&value.to_le_bytes()[..n]);
                at += n;
            }
            self.send(
                out,
                CanFrame::new_truncating((c.cob_id & 0x7FF) as u16, &payload[..at]),
            );
        }
    }

    /// Timers: producer heartbeat and consumer heartbeat supervision of the master.
    pub fn tick(&mut self, now_us: u64, out: &mut Vec<CanFrame>) {
        if self.muted {
            return;
        }
        let period_us = self.objects.producer_heartbeat_ms() as u64 * 1000;
        if period_us > 0 {
            let due = *self.next_heartbeat_us.get_or_insert(now_us);
            if now_us >= due {
                self.next_heartbeat_us = Some(now_us + period_us);
                if !self.heartbeat_muted {
                    self.send(out, self.nmt.heartbeat_frame(self.node_id));
                }
            }
        } else {
            self.next_heartbeat_us = None;
        }
        let consumer_ms = (self.objects.consumer_heartbeat() & 0xFFFF) as u64;
        if let Some(last) = self.master_heartbeat_us {
            if consumer_ms > 0 && !self.consumer_tripped && now_us > last + consumer_ms * 1000 {
                self.consumer_tripped = true;
                self.on_master_lost(out);
            }
        }
    }

    /// Communication loss (the master's heartbeat): EMCY, then the reaction of 0x6007.
    fn on_master_lost(&mut self, out: &mut Vec<CanFrame>) {
        let e = Emcy {
            error_code: emcy::HEARTBEAT_ERROR,
            error_register: 0x11,
            vendor: [0; 5],
        };
        self.send(out, e.frame(self.node_id));
        self.abort_connection();
    }

    /// The abort connection option (0x6007), applied on a communication abort (heartbeat
    /// loss, NMT stopped, reset communication) while the drive is enabled: 1 fault,
    /// 2 disable voltage, 3 quick stop (ending as 0x605A says).
    fn abort_connection(&mut self) {
        if !matches!(
            self.power,
            PowerState::OperationEnabled | PowerState::SwitchedOn | PowerState::ReadyToSwitchOn
        ) {
            return;
        }
        let enabled = self.power == PowerState::OperationEnabled;
        match self.objects.abort_connection_option() {
            od::ABORT_CONNECTION_QUICK_STOP if enabled => {
                self.hold_position = self.scale().to_increments(self.feedback.q_rad);
                self.power = self.quick_stop_state();
            }
            od::ABORT_CONNECTION_QUICK_STOP => self.power = PowerState::SwitchOnDisabled,
            2 => self.power = PowerState::SwitchOnDisabled,
            1 => {
                self.power = PowerState::Fault;
                self.objects
                    .set_internal(od::ERROR_CODE, emcy::HEARTBEAT_ERROR as u32);
            }
            _ => {}
        }
    }
}
