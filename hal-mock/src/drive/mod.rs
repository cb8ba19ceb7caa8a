//! A CiA 402 servo drive emulator speaking CANopen frames: NMT, an SDO server over
//! [`objects::Objects`], SYNC-driven TPDOs and RPDOs by their configured mapping, the
//! power state machine, producer and consumer heartbeat, EMCY, and CSP tracking through a
//! [`crate::plant::JointPlant`].
//!
//! Fault injection: [`Drive::inject_fault`] (fault state + EMCY), [`Drive::set_mute`]
//! (the node falls silent: lost heartbeat).

pub mod objects;

use hexapod_core::can_frame::CanFrame;
use hexapod_core::canopen::cia402::{PowerState, SW_REMOTE, SW_TARGET_REACHED, SW_VOLTAGE_ENABLED};
use hexapod_core::canopen::cob::{self, Cob};
use hexapod_core::canopen::emcy::{self, Emcy};
use hexapod_core::canopen::nmt::{NmtCommand, NmtState};
use hexapod_core::canopen::od;
use hexapod_core::canopen::sdo::{abort, SdoRequest, SdoResponse};
use hexapod_core::canopen::units;
use hexapod_core::robot::{can_node_id, TORQUE_LIMIT_NM};

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

    /// Initialisation: boot-up message, then pre-operational, power stage Switch on disabled.
    pub fn power_on(&mut self, now_us: u64, out: &mut Vec<CanFrame>) {
        let rated = self.objects.rated_torque_mnm;
        self.objects = Objects::defaults(self.node_id, rated);
        self.power = PowerState::SwitchOnDisabled;
        self.previous_controlword = 0;
        self.reset_communication(now_us, out);
    }

    fn reset_communication(&mut self, now_us: u64, out: &mut Vec<CanFrame>) {
        let fresh = Objects::defaults(self.node_id, self.objects.rated_torque_mnm);
        let o = &mut self.objects;
        o.sync_cob_id = fresh.sync_cob_id;
        o.comm_cycle_us = fresh.comm_cycle_us;
        o.consumer_heartbeat = fresh.consumer_heartbeat;
        o.producer_heartbeat_ms = fresh.producer_heartbeat_ms;
        o.rpdo_comm = fresh.rpdo_comm;
        o.rpdo_map = fresh.rpdo_map;
        o.tpdo_comm = fresh.tpdo_comm;
        o.tpdo_map = fresh.tpdo_map;
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

    /// A drive fault: torque off, error code 0x603F, EMCY.
    pub fn inject_fault(&mut self, error_code: u16, out: &mut Vec<CanFrame>) {
        self.power = PowerState::Fault;
        self.objects.error_code = error_code;
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
        let target = match self.power {
            PowerState::OperationEnabled if o.mode == od::MODE_CSP => o
                .target_position
                .clamp(o.position_limits[0], o.position_limits[1]),
            PowerState::OperationEnabled | PowerState::QuickStopActive => self.hold_position,
            _ => return None,
        };
        Some(CspSetpoint {
            q_target_rad: units::increments_to_rad(target),
            vel_limit_rad_s: units::velocity_units_to_rad_s(
                o.max_motor_speed.min(i32::MAX as u32) as i32
            ),
            torque_limit_nm: o.max_torque as f32 * o.rated_torque_mnm as f32 * 1e-6,
        })
    }

    fn send(&self, out: &mut Vec<CanFrame>, frame: CanFrame) {
        if !self.muted {
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
            Cob::Heartbeat(n) if n as u32 == (self.objects.consumer_heartbeat >> 16) & 0x7F => {
                self.master_heartbeat_us = Some(now_us);
            }
            Cob::Heartbeat(_) => {}
            _ if frame.cob_id() == (self.objects.sync_cob_id & 0x7FF) as u16 => self.on_sync(out),
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
            NmtCommand::Stop => self.nmt = NmtState::Stopped,
            NmtCommand::EnterPreOperational => self.nmt = NmtState::PreOperational,
            NmtCommand::ResetCommunication => self.reset_communication(now_us, out),
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
            let c = self.objects.rpdo_comm[k];
            c.valid() && (c.cob_id & 0x7FF) as u16 == frame.cob_id()
        }) else {
            return;
        };
        let map = self.objects.rpdo_map[k];
        let bytes: usize = map.active().iter().map(|&e| (e & 0xFF) as usize / 8).sum();
        let p = frame.payload();
        if p.len() != bytes {
            self.counters.malformed += 1;
            return;
        }
        let mut at = 0;
        for &entry in map.active() {
            let (address, bits) = od::ObjectAddress::from_mapping(entry);
            let n = bits as usize / 8;
            let mut le = [0u8; 4];
            le[..n].copy_from_slice(&p[at..at + n]);
            at += n;
            let _ = self.objects.write(address, u32::from_le_bytes(le), n as u8);
        }
        self.apply_controlword(out);
    }

    /// The CiA 402 state machine reacting to the controlword (CiA 402 table 29).
    fn apply_controlword(&mut self, out: &mut Vec<CanFrame>) {
        use PowerState as S;
        let cw = self.objects.controlword;
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
                    self.objects.error_code = 0;
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
            self.hold_position = units::rad_to_increments(self.feedback.q_rad);
        }
        self.power = next;
    }

    /// Where a quick stop ends (0x605A): options 5..=8 stay in Quick stop active, holding
    /// position with torque on; 0..=4 end in Switch on disabled (torque off).
    fn quick_stop_state(&self) -> PowerState {
        if (5..=8).contains(&self.objects.quick_stop_option) {
            PowerState::QuickStopActive
        } else {
            PowerState::SwitchOnDisabled
        }
    }

    fn refresh_objects(&mut self) {
        let o = &mut self.objects;
        let mut sw = self.power.statusword_bits() | SW_REMOTE;
        if self.power.torque_on() || matches!(self.power, PowerState::SwitchedOn) {
            sw |= SW_VOLTAGE_ENABLED;
        }
        let target_error =
            (o.target_position - units::rad_to_increments(self.feedback.q_rad)).abs();
        if target_error < units::rad_to_increments(0.01) {
            sw |= SW_TARGET_REACHED;
        }
        if self.power == PowerState::OperationEnabled && o.mode == od::MODE_CSP {
            sw |= hexapod_core::canopen::cia402::SW_CSP_FOLLOWING;
        }
        o.statusword = sw;
        o.position = units::rad_to_increments(self.feedback.q_rad);
        o.velocity = units::rad_s_to_velocity_units(self.feedback.qdot_rad_s);
        o.torque = units::torque_nm_to_permille(self.feedback.torque_nm, o.rated_torque_mnm)
            .clamp(i16::MIN as i32, i16::MAX as i32) as i16;
    }

    fn on_sync(&mut self, out: &mut Vec<CanFrame>) {
        if self.nmt != NmtState::Operational {
            return;
        }
        self.refresh_objects();
        for k in 0..4 {
            let c = self.objects.tpdo_comm[k];
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
            for &entry in self.objects.tpdo_map[k].active() {
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
        let period_us = self.objects.producer_heartbeat_ms as u64 * 1000;
        if period_us > 0 {
            let due = *self.next_heartbeat_us.get_or_insert(now_us);
            if now_us >= due {
                self.next_heartbeat_us = Some(now_us + period_us);
                self.send(out, self.nmt.heartbeat_frame(self.node_id));
            }
        } else {
            self.next_heartbeat_us = None;
        }
        let consumer_ms = (self.objects.consumer_heartbeat & 0xFFFF) as u64;
        if let Some(last) = self.master_heartbeat_us {
            if consumer_ms > 0 && !self.consumer_tripped && now_us > last + consumer_ms * 1000 {
                self.consumer_tripped = true;
                self.on_master_lost(out);
            }
        }
    }

    /// Communication loss: EMCY, then the reaction configured in 0x6007.
    fn on_master_lost(&mut self, out: &mut Vec<CanFrame>) {
        let e = Emcy {
            error_code: emcy::HEARTBEAT_ERROR,
            error_register: 0x11,
            vendor: [0; 5],
        };
        self.send(out, e.frame(self.node_id));
        match self.objects.abort_connection_option {
            od::ABORT_CONNECTION_QUICK_STOP if self.power == PowerState::OperationEnabled => {
                self.hold_position = units::rad_to_increments(self.feedback.q_rad);
                self.power = self.quick_stop_state();
            }
            2 => self.power = PowerState::SwitchOnDisabled,
            1 => {
                self.power = PowerState::Fault;
                self.objects.error_code = emcy::HEARTBEAT_ERROR;
            }
            _ => {}
        }
    }
}
