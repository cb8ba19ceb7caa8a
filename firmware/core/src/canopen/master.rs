//! The CANopen master of the 18 joint drives on two buses.
//!
//! One synchronous state machine, time passed in (microseconds):
//! - [`Master::start`] first learns each node's state without touching it: SDO uploads of
//!   the statusword (0x6041) and the position (0x6064). A drive found in Operation enabled
//!   or Quick stop active is holding the body (the controller was reset, the drives were
//!   not): it is *adopted* ([`NodeState::adopted`]); for one in Operation enabled its
//!   target (0x607A) is read as well. Then each node's communication is reset (NMT 0x82)
//!   and the master waits for its boot-up, except for a drive in Operation enabled: it is
//!   sent to pre-operational (NMT 0x80) and configured at once, so that it keeps following
//!   its target (a reset of communication would make it quick-stop on its actual position);
//! - each booted node runs the [`drive_config`](super::drive_config) SDO script, then gets NMT start;
//! - [`Master::sync`] begins a control cycle (SYNC on both buses), the drives answer with
//!   TPDO1/TPDO2, [`Master::feedback_complete`] tells when all arrived, and
//!   [`Master::send_commands`] sends one RPDO per drive (controlword from the CiA 402 state
//!   machine toward the requested state, target position in increments);
//! - [`Master::poll`] runs SDO timeouts, boot retries, the master's own heartbeat and the
//!   supervision of the drives' heartbeats.
//!
//! Faults are latched per node ([`NodeFault`]); malformed frames and frames from unknown
//! nodes or the wrong bus are dropped and counted in [`MasterCounters`], never a panic.
//! Outgoing frames wait in one bounded queue per bus ([`Master::pop_tx`]).

use heapless::Deque;

use super::cia402::{
    next_controlword, DriveRequest, PowerState, CW_DISABLE_VOLTAGE, CW_ENABLE_OPERATION,
    CW_QUICK_STOP,
};
use super::cob::{self, Cob};
use super::drive_config::{
    check_read, config_step, ConfigStep, IdentifyError, HEARTBEAT_PRODUCER_MS,
};
use super::emcy::Emcy;
use super::nmt::{NmtCommand, NmtState};
use super::od::{self, ObjectAddress};
use super::pdo::{Rpdo1, Tpdo1, Tpdo2};
use super::sdo::SdoRequest;
use super::sdo_client::{SdoClient, SdoOutcome};
use super::units;
use super::MASTER_NODE_ID;
use crate::can_frame::CanFrame;
use crate::robot::{can_bus, can_node_id, joint_of_node, NUM_JOINTS, Q_MAX_RAD, Q_MIN_RAD};

/// Number of CAN buses.
pub const NUM_BUSES: usize = 2;
/// Capacity of each bus's transmit queue.
pub const TX_QUEUE_LEN: usize = 64;
/// A drive is lost when no heartbeat arrives for this long (5 producer periods: losing four
/// in a row at 5 % frame loss is a 6e-6 event; a dead drive's feedback PDOs are missed within
/// `FEEDBACK_MISS_LIMIT` cycles anyway).
pub const HEARTBEAT_TIMEOUT_US: u64 = 5 * HEARTBEAT_PRODUCER_MS as u64 * 1000;
/// Period of the master's own heartbeat, microseconds.
pub const MASTER_HEARTBEAT_PERIOD_US: u64 = 100_000;
/// How long the master waits for a boot-up message before resending the reset.
pub const BOOT_TIMEOUT_US: u64 = 500_000;
/// Resets sent before a silent node is given up.
pub const BOOT_ATTEMPTS: u8 = 3;
/// Retries of one SDO step after a timeout.
pub const SDO_RETRIES: u8 = 2;
/// Tries of each probe upload (statusword, position) before the node is booted unprobed.
pub const PROBE_ATTEMPTS: u8 = 2;
/// Consecutive SYNC cycles without complete feedback before a drive is lost: 10 cycles
/// (200 ms at 50 Hz). With 5 % frame loss a drive misses a cycle with p ~ 0.14, so 10 in a
/// row happens about once in 5e8 cycles, while a dead drive is still caught within 0.2 s
/// (its heartbeat, 0x1016, is supervised as well).
pub const FEEDBACK_MISS_LIMIT: u8 = 10;

/// Why a node is out of service (latched).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum NodeFault {
    /// No boot-up message after [`BOOT_ATTEMPTS`] resets.
    NoBootUp,
    /// The drive refused a configuration step.
    ConfigAborted {
        /// Object written or read.
        address: ObjectAddress,
        /// SDO abort code.
        code: u32,
    },
    /// A configuration step timed out [`SDO_RETRIES`] + 1 times.
    ConfigTimeout {
        /// Object concerned.
        address: ObjectAddress,
    },
    /// The device is not what we drive.
    Identify(IdentifyError),
    /// The drive sent an emergency message.
    Emergency {
        /// CiA error code.
        error_code: u16,
    },
    /// The statusword reports Fault.
    DriveFault,
    /// No heartbeat for [`HEARTBEAT_TIMEOUT_US`].
    LostHeartbeat,
    /// The drive rebooted or left operational on its own.
    UnexpectedNmtState,
    /// TPDOs missing for [`FEEDBACK_MISS_LIMIT`] cycles.
    FeedbackLost,
    /// Its bus went bus-off.
    BusOff,
}

impl NodeFault {
    /// True when the drive may still produce torque on command (its link works).
    pub fn link_alive(self) -> bool {
        matches!(self, Self::Emergency { .. } | Self::DriveFault)
    }

    /// True when the master cannot see the drive (or its state) any more, while the drive
    /// may still hear the master: it gets the lost-drive reaction ([`LostReaction`]).
    pub fn drive_lost(self) -> bool {
        matches!(
            self,
            Self::LostHeartbeat | Self::FeedbackLost | Self::UnexpectedNmtState
        )
    }
}

/// Consecutive cycles without a drive's feedback from which its target is frozen: the
/// third (a lost drive gets at most two targets computed blind, 40 ms). One or two missing
/// cycles are what frame loss does: at 5 % loss in bursts some drive misses one in about
/// every tenth cycle, and freezing a leg from the second miss made the walking gait stumble
/// (trunk touch in `burst_loss_while_walking.toml`); from the third it does not.
pub const FREEZE_AFTER_MISSED: u8 = 3;

/// How many cycles a lost drive gets "disable voltage" before its NMT stop.
pub const LOST_DISABLE_CYCLES: u8 = 3;

/// What the master sends a drive it has lost (it cannot tell whether the drive hears it,
/// so each step is sent blind, per cycle):
/// 1. from the third cycle in a row without its feedback ([`FREEZE_AFTER_MISSED`]): its
///    last target, frozen;
/// 2. once lost: controlword quick stop (0x0002) with the frozen target: the drive holds
///    its joint in Quick stop active (0x605A = 6) while the others sit down;
/// 3. once the supervisor turns torque off (seated): "disable voltage" (0x0000) for
///    [`LOST_DISABLE_CYCLES`] cycles, then NMT stop of the node: PDOs off, and with
///    0x6007 = quick stop a drive that missed the controlword stops by itself.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum LostReaction {
    /// Not lost.
    None,
    /// Quick stop sent each cycle.
    QuickStop,
    /// Disable voltage sent, this many cycles so far.
    Disabling(u8),
    /// NMT stop sent: nothing more.
    Stopped,
}

/// Configuration progress of a node.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum NodePhase {
    /// Not started.
    Idle,
    /// Reading the node's state before anything is sent to it: step 0 the statusword,
    /// step 1 the position.
    Probing {
        /// Upload in flight.
        step: u8,
        /// Tries of that upload so far.
        attempts: u8,
    },
    /// Reset sent, waiting for the boot-up message.
    Booting {
        /// When the reset was sent.
        since_us: u64,
        /// Resets sent so far.
        attempts: u8,
    },
    /// Running the configuration script.
    Configuring {
        /// Current step.
        step: u8,
        /// Timeouts of the current step so far.
        retries: u8,
    },
    /// NMT operational: PDOs run.
    Operational,
    /// Given up during boot or configuration.
    Failed,
}

/// What the master knows about one drive.
#[derive(Clone, Copy, Debug)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct NodeState {
    /// Configuration progress.
    pub phase: NodePhase,
    /// Latched fault, if any.
    pub fault: Option<NodeFault>,
    /// Power state from the last statusword.
    pub power: PowerState,
    /// Last statusword.
    pub statusword: u16,
    /// Joint position, rad.
    pub q_rad: f32,
    /// Joint velocity, rad/s.
    pub qdot_rad_s: f32,
    /// Joint torque, N m.
    pub torque_nm: f32,
    /// Rated torque read from 0x6076, mN m.
    pub rated_torque_mnm: u32,
    /// Last heartbeat (or boot-up) time.
    pub last_heartbeat_us: u64,
    /// Last controlword sent.
    pub controlword: u16,
    /// Last target position sent, increments.
    pub target_increments: i32,
    /// Cycles in which the drive's target was frozen because its feedback was missing.
    pub frozen_cycles: u32,
    /// The reaction to a lost drive.
    pub lost: LostReaction,
    /// The drive had torque on (Operation enabled or Quick stop active) when the master
    /// started: it holds the body and is taken over at its position, never disabled first.
    pub adopted: bool,
    /// Statusword found by the probe before the boot, if the node answered.
    pub probed_statusword: Option<u16>,
    /// Where an adopted drive holds its joint (its target, or its position), rad.
    pub adopted_target_rad: f32,
    /// A TPDO1 arrived since the node became operational: its state is known.
    pub state_known: bool,
    commanded: bool,
    quick_stop_hold_sent: bool,
    sdo: SdoClient,
    got_tpdo1: bool,
    got_tpdo2: bool,
    awaiting_feedback: bool,
    missed_cycles: u8,
}

impl NodeState {
    const fn new() -> Self {
        Self {
            phase: NodePhase::Idle,
            fault: None,
            power: PowerState::NotReadyToSwitchOn,
            statusword: 0,
            q_rad: 0.0,
            qdot_rad_s: 0.0,
            torque_nm: 0.0,
            rated_torque_mnm: 0,
            last_heartbeat_us: 0,
            controlword: 0,
            target_increments: 0,
            frozen_cycles: 0,
            lost: LostReaction::None,
            adopted: false,
            probed_statusword: None,
            adopted_target_rad: f32::NAN,
            state_known: false,
            commanded: false,
            quick_stop_hold_sent: false,
            sdo: SdoClient::idle(),
            got_tpdo1: false,
            got_tpdo2: false,
            awaiting_feedback: false,
            missed_cycles: 0,
        }
    }

    /// True when configured, operational and free of faults.
    pub fn is_healthy(&self) -> bool {
        self.phase == NodePhase::Operational && self.fault.is_none()
    }

    /// True when the drive is usable for commands: operational and its link alive.
    pub fn is_reachable(&self) -> bool {
        self.phase == NodePhase::Operational && self.fault.is_none_or(|f| f.link_alive())
    }
}

/// Frames dropped, by reason (saturating counters).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct MasterCounters {
    /// Payload of the wrong length or with an invalid value.
    pub malformed: u32,
    /// COB-ID outside the connection set, or a node id that is not one of our drives.
    pub unknown_node: u32,
    /// A drive's frame on the other bus.
    pub wrong_bus: u32,
    /// An SDO response nobody asked for.
    pub unexpected_sdo: u32,
    /// Frames not queued because the transmit queue was full.
    pub tx_overflow: u32,
    /// Emergency messages received.
    pub emergencies: u32,
    /// Remote frames, NMT, SYNC or RPDOs seen from another master.
    pub ignored: u32,
    /// Bus-off events (either bus).
    pub bus_off_events: u32,
    /// Recoveries from bus-off, each followed by a re-synchronization of the bus's drives.
    pub bus_off_recoveries: u32,
}

fn bump(counter: &mut u32) {
    *counter = counter.saturating_add(1);
}

/// Joint feedback in joint order.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct JointFeedback {
    /// Positions, rad.
    pub q_rad: [f32; NUM_JOINTS],
    /// Velocities, rad/s.
    pub qdot_rad_s: [f32; NUM_JOINTS],
    /// Torques, N m.
    pub torque_nm: [f32; NUM_JOINTS],
}

/// The master.
pub struct Master {
    nodes: [NodeState; NUM_JOINTS],
    tx: [Deque<CanFrame, TX_QUEUE_LEN>; NUM_BUSES],
    bus_off: [bool; NUM_BUSES],
    next_heartbeat_us: u64,
    started: bool,
    /// Dropped-frame counters.
    pub counters: MasterCounters,
}

impl Default for Master {
    fn default() -> Self {
        Self::new()
    }
}

impl Master {
    /// A master that has not started.
    pub const fn new() -> Self {
        Self {
            nodes: [NodeState::new(); NUM_JOINTS],
            tx: [Deque::new(), Deque::new()],
            bus_off: [false; NUM_BUSES],
            next_heartbeat_us: 0,
            started: false,
            counters: MasterCounters {
                malformed: 0,
                unknown_node: 0,
                wrong_bus: 0,
                unexpected_sdo: 0,
                tx_overflow: 0,
                emergencies: 0,
                ignored: 0,
                bus_off_events: 0,
                bus_off_recoveries: 0,
            },
        }
    }

    /// Starts the master: probes every node's state (statusword, position) by SDO, then
    /// resets its communication and configures it as it boots.
    pub fn start(&mut self, now_us: u64) {
        self.started = true;
        self.next_heartbeat_us = now_us;
        for j in 0..NUM_JOINTS {
            self.nodes[j] = NodeState::new();
            self.nodes[j].fault = self.bus_off[can_bus(j)].then_some(NodeFault::BusOff);
            self.begin_probe(j, now_us);
        }
    }

    /// Probes node `joint` again (after its bus came back), keeping what it knew.
    fn begin_probe(&mut self, joint: usize, now_us: u64) {
        let node = &mut self.nodes[joint];
        node.phase = NodePhase::Probing {
            step: 0,
            attempts: 1,
        };
        node.sdo.cancel();
        self.probe_request(joint, now_us);
    }

    fn probe_request(&mut self, joint: usize, now_us: u64) {
        let node = &mut self.nodes[joint];
        let NodePhase::Probing { step, .. } = node.phase else {
            return;
        };
        let address = match step {
            0 => od::STATUSWORD,
            1 => od::POSITION_ACTUAL,
            _ => od::TARGET_POSITION,
        };
        if let Some(frame) =
            node.sdo
                .start(SdoRequest::Upload { address }, can_node_id(joint), now_us)
        {
            self.push(can_bus(joint), frame);
        }
    }

    /// Probe done (or given up): reset the node's communication and wait for its boot-up.
    fn begin_boot(&mut self, joint: usize, now_us: u64) {
        let node = &mut self.nodes[joint];
        node.sdo.cancel();
        if node.adopted && node.power == PowerState::OperationEnabled {
            // Holding the body and following its last target: no reset of communication
            // (CiA 402 makes that a communication abort, a quick stop that holds the actual
            // position and lets the loaded joint give way by its following error). Back to
            // pre-operational (PDOs stop, the drive keeps its target) and configure again.
            node.phase = NodePhase::Configuring {
                step: 0,
                retries: 0,
            };
            self.push(
                can_bus(joint),
                NmtCommand::EnterPreOperational.frame(can_node_id(joint)),
            );
            self.next_sdo(joint, now_us);
            return;
        }
        node.phase = NodePhase::Booting {
            since_us: now_us,
            attempts: 1,
        };
        self.push(
            can_bus(joint),
            NmtCommand::ResetCommunication.frame(can_node_id(joint)),
        );
    }

    /// Where the adopted drives hold the body: their target for a drive found following
    /// one (Operation enabled), their position otherwise; the measured position for drives
    /// not adopted.
    pub fn adopted_targets_rad(&self) -> [f32; NUM_JOINTS] {
        let mut out = [0.0; NUM_JOINTS];
        for (o, n) in out.iter_mut().zip(&self.nodes) {
            *o = if n.adopted && n.adopted_target_rad.is_finite() {
                n.adopted_target_rad
            } else {
                n.q_rad
            };
        }
        out
    }

    /// True when some drive was holding the body when the master started (adopted).
    pub fn any_adopted(&self) -> bool {
        self.nodes.iter().any(|n| n.adopted)
    }

    /// The state of joint `j`'s drive.
    pub fn node(&self, joint: usize) -> &NodeState {
        &self.nodes[joint.min(NUM_JOINTS - 1)]
    }

    /// True when every drive is operational and fault-free.
    pub fn all_healthy(&self) -> bool {
        self.nodes.iter().all(NodeState::is_healthy)
    }

    /// True while some drive is still being probed, booting or being configured, or is
    /// operational but has not reported its state (TPDO1) yet.
    pub fn configuring(&self) -> bool {
        self.nodes.iter().any(|n| {
            n.fault.is_none()
                && match n.phase {
                    NodePhase::Probing { .. }
                    | NodePhase::Booting { .. }
                    | NodePhase::Configuring { .. } => true,
                    NodePhase::Operational => !n.state_known,
                    NodePhase::Idle | NodePhase::Failed => false,
                }
        })
    }

    /// The first latched fault, with its joint.
    pub fn first_fault(&self) -> Option<(usize, NodeFault)> {
        self.nodes
            .iter()
            .enumerate()
            .find_map(|(j, n)| n.fault.map(|f| (j, f)))
    }

    /// True when every drive is in Operation enabled.
    pub fn all_enabled(&self) -> bool {
        self.nodes
            .iter()
            .all(|n| n.is_healthy() && n.power == PowerState::OperationEnabled)
    }

    /// Joint positions, velocities and torques from the last TPDOs.
    pub fn feedback(&self) -> JointFeedback {
        let mut fb = JointFeedback {
            q_rad: [0.0; NUM_JOINTS],
            qdot_rad_s: [0.0; NUM_JOINTS],
            torque_nm: [0.0; NUM_JOINTS],
        };
        for (j, n) in self.nodes.iter().enumerate() {
            fb.q_rad[j] = n.q_rad;
            fb.qdot_rad_s[j] = n.qdot_rad_s;
            fb.torque_nm[j] = n.torque_nm;
        }
        fb
    }

    /// The next frame to transmit on `bus`.
    pub fn pop_tx(&mut self, bus: usize) -> Option<CanFrame> {
        self.tx.get_mut(bus)?.pop_front()
    }

    /// Puts a frame back at the head of `bus`'s queue (the driver's queue was full).
    pub fn unpop_tx(&mut self, bus: usize, frame: CanFrame) {
        if let Some(q) = self.tx.get_mut(bus) {
            if q.push_front(frame).is_err() {
                bump(&mut self.counters.tx_overflow);
            }
        }
    }

    fn push(&mut self, bus: usize, frame: CanFrame) {
        if self.bus_off[bus] {
            return;
        }
        if self.tx[bus].push_back(frame).is_err() {
            bump(&mut self.counters.tx_overflow);
        }
    }

    fn fail(&mut self, joint: usize, fault: NodeFault) {
        let node = &mut self.nodes[joint];
        if node.fault.is_none() {
            node.fault = Some(fault);
        }
    }

    /// Reports the bus state from the CAN driver (`now_us` for the re-synchronization).
    ///
    /// Bus-off faults every drive on the bus. The CAN controller recovers by itself
    /// (ISO 11898-1: after 128 x 11 recessive bits; the firmware enables automatic
    /// recovery): when the bus is back, its drives' faults are cleared and each drive is
    /// probed, reset, configured and adopted again as at start, so a drive that still
    /// holds the body is never disabled.
    pub fn set_bus_off(&mut self, bus: usize, bus_off: bool, now_us: u64) {
        let Some(flag) = self.bus_off.get_mut(bus) else {
            return;
        };
        let was = *flag;
        *flag = bus_off;
        if bus_off && !was {
            self.tx[bus].clear();
            bump(&mut self.counters.bus_off_events);
            for j in (0..NUM_JOINTS).filter(|&j| can_bus(j) == bus) {
                self.nodes[j].fault = Some(NodeFault::BusOff);
            }
        } else if was && !bus_off && self.started {
            bump(&mut self.counters.bus_off_recoveries);
            for j in (0..NUM_JOINTS).filter(|&j| can_bus(j) == bus) {
                let node = &mut self.nodes[j];
                if node.fault == Some(NodeFault::BusOff) || node.fault.is_none() {
                    let q_rad = node.q_rad;
                    *node = NodeState::new();
                    node.q_rad = q_rad;
                    self.begin_probe(j, now_us);
                }
            }
        }
    }

    /// Clears faults whose cause is gone (a drive fault that the drive has reset).
    /// Lost links stay latched until [`Master::start`].
    pub fn clear_recoverable_faults(&mut self) {
        for n in self.nodes.iter_mut() {
            let recoverable = n.fault.is_some_and(NodeFault::link_alive);
            if recoverable && n.power != PowerState::Fault && n.phase == NodePhase::Operational {
                n.fault = None;
            }
        }
    }

    /// Handles one received frame from `bus`.
    pub fn on_frame(&mut self, bus: usize, frame: &CanFrame, now_us: u64) {
        if bus >= NUM_BUSES {
            return;
        }
        if frame.is_rtr() {
            bump(&mut self.counters.ignored);
            return;
        }
        let Some(c) = cob::classify(frame.cob_id()) else {
            bump(&mut self.counters.unknown_node);
            return;
        };
        let node_id = match c {
            Cob::Emcy(n) | Cob::Tpdo(_, n) | Cob::SdoTx(n) | Cob::Heartbeat(n) => n,
            Cob::Nmt | Cob::Sync | Cob::Rpdo(..) | Cob::SdoRx(_) => {
                bump(&mut self.counters.ignored);
                return;
            }
        };
        let Some(joint) = joint_of_node(node_id) else {
            bump(&mut self.counters.unknown_node);
            return;
        };
        if can_bus(joint) != bus {
            bump(&mut self.counters.wrong_bus);
            return;
        }
        let p = frame.payload();
        match c {
            Cob::Heartbeat(_) => self.on_heartbeat(joint, p, now_us),
            Cob::SdoTx(_) => self.on_sdo(joint, p, now_us),
            Cob::Emcy(_) => self.on_emcy(joint, p),
            Cob::Tpdo(0, _) => self.on_tpdo1(joint, p),
            Cob::Tpdo(1, _) => self.on_tpdo2(joint, p),
            _ => bump(&mut self.counters.ignored),
        }
    }

    fn on_heartbeat(&mut self, joint: usize, p: &[u8], now_us: u64) {
        let Some(state) = NmtState::parse(p) else {
            bump(&mut self.counters.malformed);
            return;
        };
        let node = &mut self.nodes[joint];
        node.last_heartbeat_us = now_us;
        match (node.phase, state) {
            // A node that boots while being probed has just powered up: configure it.
            (NodePhase::Booting { .. } | NodePhase::Probing { .. }, NmtState::BootUp) => {
                node.phase = NodePhase::Configuring {
                    step: 0,
                    retries: 0,
                };
                node.sdo.cancel();
                self.next_sdo(joint, now_us);
            }
            (NodePhase::Operational, NmtState::Operational) => {}
            // A heartbeat sent before the drive processed our NMT start (it was on the bus
            // behind it): not a state change until the drive has shown it runs (TPDO1).
            (NodePhase::Operational, NmtState::PreOperational) if !node.state_known => {}
            (NodePhase::Operational, _) => self.fail(joint, NodeFault::UnexpectedNmtState),
            (NodePhase::Configuring { .. }, NmtState::BootUp) => {
                // Rebooted mid-configuration: start over.
                node.phase = NodePhase::Configuring {
                    step: 0,
                    retries: 0,
                };
                node.sdo.cancel();
                self.next_sdo(joint, now_us);
            }
            _ => {}
        }
    }

    fn on_sdo(&mut self, joint: usize, p: &[u8], now_us: u64) {
        if matches!(self.nodes[joint].phase, NodePhase::Probing { .. }) {
            self.on_probe_sdo(joint, p, now_us);
            return;
        }
        let node = &mut self.nodes[joint];
        let NodePhase::Configuring { step, .. } = node.phase else {
            bump(&mut self.counters.unexpected_sdo);
            return;
        };
        let outcome = match node.sdo.on_response(p) {
            Ok(o) => o,
            Err(super::sdo_client::SdoClientError::Malformed(_)) => {
                bump(&mut self.counters.malformed);
                return;
            }
            Err(super::sdo_client::SdoClientError::Unexpected) => {
                bump(&mut self.counters.unexpected_sdo);
                return;
            }
        };
        match outcome {
            SdoOutcome::Written(_) => {}
            SdoOutcome::Read(address, value, _) => {
                if let Err(e) = check_read(address, value) {
                    node.phase = NodePhase::Failed;
                    self.fail(joint, NodeFault::Identify(e));
                    return;
                }
                if address == od::MOTOR_RATED_TORQUE {
                    node.rated_torque_mnm = value;
                }
            }
            SdoOutcome::Aborted(address, code) => {
                node.phase = NodePhase::Failed;
                self.fail(joint, NodeFault::ConfigAborted { address, code });
                return;
            }
            SdoOutcome::TimedOut(_) => return,
        }
        node.phase = NodePhase::Configuring {
            step: step.saturating_add(1),
            retries: 0,
        };
        self.next_sdo(joint, now_us);
    }

    fn on_probe_sdo(&mut self, joint: usize, p: &[u8], now_us: u64) {
        let node = &mut self.nodes[joint];
        let NodePhase::Probing { step, .. } = node.phase else {
            return;
        };
        let outcome = match node.sdo.on_response(p) {
            Ok(o) => o,
            Err(super::sdo_client::SdoClientError::Malformed(_)) => {
                bump(&mut self.counters.malformed);
                return;
            }
            Err(super::sdo_client::SdoClientError::Unexpected) => {
                bump(&mut self.counters.unexpected_sdo);
                return;
            }
        };
        match outcome {
            SdoOutcome::Read(address, value, _) if address == od::STATUSWORD && step == 0 => {
                let sw = value as u16;
                node.probed_statusword = Some(sw);
                node.statusword = sw;
                node.power = PowerState::from_statusword(sw);
                node.adopted = matches!(
                    node.power,
                    PowerState::OperationEnabled | PowerState::QuickStopActive
                );
                node.phase = NodePhase::Probing {
                    step: 1,
                    attempts: 1,
                };
                self.probe_request(joint, now_us);
            }
            SdoOutcome::Read(address, value, _) if address == od::POSITION_ACTUAL => {
                node.q_rad = units::increments_to_rad(value as i32);
                node.adopted_target_rad = node.q_rad;
                if node.power == PowerState::OperationEnabled {
                    // Following a target: read it, to keep it.
                    node.phase = NodePhase::Probing {
                        step: 2,
                        attempts: 1,
                    };
                    self.probe_request(joint, now_us);
                } else {
                    self.begin_boot(joint, now_us);
                }
            }
            SdoOutcome::Read(address, value, _) if address == od::TARGET_POSITION => {
                let target = units::increments_to_rad(value as i32);
                // The target it follows, if plausible (within 0.2 rad of where it is).
                if (target - node.q_rad).abs() < 0.2 {
                    node.adopted_target_rad = target;
                }
                self.begin_boot(joint, now_us);
            }
            // Aborted (no such object) or anything else: boot without knowing.
            SdoOutcome::TimedOut(_) => {}
            _ => self.begin_boot(joint, now_us),
        }
    }

    /// Sends the current configuration step, or NMT start after the last one.
    fn next_sdo(&mut self, joint: usize, now_us: u64) {
        let node = &mut self.nodes[joint];
        let NodePhase::Configuring { step, .. } = node.phase else {
            return;
        };
        let node_id = can_node_id(joint);
        let request = match config_step(step as usize, joint, node.rated_torque_mnm) {
            Some(ConfigStep::Read(address)) => SdoRequest::Upload { address },
            Some(ConfigStep::Write(address, value, len)) => {
                SdoRequest::download(address, value, len)
            }
            None => {
                node.phase = NodePhase::Operational;
                node.last_heartbeat_us = now_us;
                node.awaiting_feedback = false;
                node.missed_cycles = 0;
                node.state_known = false;
                node.commanded = false;
                node.quick_stop_hold_sent = false;
                self.push(can_bus(joint), NmtCommand::Start.frame(node_id));
                return;
            }
        };
        if let Some(frame) = node.sdo.start(request, node_id, now_us) {
            self.push(can_bus(joint), frame);
        }
    }

    fn on_emcy(&mut self, joint: usize, p: &[u8]) {
        let Some(e) = Emcy::parse(p) else {
            bump(&mut self.counters.malformed);
            return;
        };
        bump(&mut self.counters.emergencies);
        if !e.is_reset() {
            self.fail(
                joint,
                NodeFault::Emergency {
                    error_code: e.error_code,
                },
            );
        }
    }

    fn on_tpdo1(&mut self, joint: usize, p: &[u8]) {
        let Some(t) = Tpdo1::decode(p) else {
            bump(&mut self.counters.malformed);
            return;
        };
        let node = &mut self.nodes[joint];
        node.statusword = t.statusword;
        node.power = PowerState::from_statusword(t.statusword);
        node.q_rad = units::increments_to_rad(t.position);
        node.got_tpdo1 = true;
        if !node.state_known && node.phase == NodePhase::Operational {
            node.state_known = true;
            // Torque on in its first report: holding the body, adopt it (the probe may
            // not have reached it).
            if matches!(
                node.power,
                PowerState::OperationEnabled | PowerState::QuickStopActive
            ) && !node.adopted
            {
                node.adopted = true;
                node.adopted_target_rad = node.q_rad;
            }
        }
        self.check_feedback(joint);
        if matches!(
            self.nodes[joint].power,
            PowerState::Fault | PowerState::FaultReactionActive
        ) {
            self.fail(joint, NodeFault::DriveFault);
        }
    }

    fn on_tpdo2(&mut self, joint: usize, p: &[u8]) {
        let Some(t) = Tpdo2::decode(p) else {
            bump(&mut self.counters.malformed);
            return;
        };
        let node = &mut self.nodes[joint];
        node.qdot_rad_s = units::velocity_units_to_rad_s(t.velocity);
        node.torque_nm = units::permille_to_torque_nm(t.torque, node.rated_torque_mnm);
        node.got_tpdo2 = true;
        self.check_feedback(joint);
    }

    fn check_feedback(&mut self, joint: usize) {
        let node = &mut self.nodes[joint];
        if node.got_tpdo1 && node.got_tpdo2 {
            node.awaiting_feedback = false;
            node.missed_cycles = 0;
        }
    }

    /// Timers: boot retries, SDO timeouts, heartbeat supervision, the master's heartbeat.
    pub fn poll(&mut self, now_us: u64) {
        if !self.started {
            return;
        }
        if now_us >= self.next_heartbeat_us {
            self.next_heartbeat_us = now_us.saturating_add(MASTER_HEARTBEAT_PERIOD_US);
            for bus in 0..NUM_BUSES {
                self.push(bus, NmtState::Operational.heartbeat_frame(MASTER_NODE_ID));
            }
        }
        for j in 0..NUM_JOINTS {
            if self.nodes[j].fault.is_some_and(|f| !f.link_alive()) {
                continue;
            }
            let node_id = can_node_id(j);
            match self.nodes[j].phase {
                NodePhase::Probing { step, attempts } => {
                    if let Some((SdoOutcome::TimedOut(_), abort)) =
                        self.nodes[j].sdo.poll_timeout(node_id, now_us)
                    {
                        self.push(can_bus(j), abort);
                        if attempts >= PROBE_ATTEMPTS {
                            self.begin_boot(j, now_us);
                        } else {
                            self.nodes[j].phase = NodePhase::Probing {
                                step,
                                attempts: attempts + 1,
                            };
                            self.probe_request(j, now_us);
                        }
                    }
                }
                NodePhase::Booting { since_us, attempts }
                    if now_us.saturating_sub(since_us) >= BOOT_TIMEOUT_US =>
                {
                    if attempts >= BOOT_ATTEMPTS {
                        self.nodes[j].phase = NodePhase::Failed;
                        self.fail(j, NodeFault::NoBootUp);
                    } else {
                        self.nodes[j].phase = NodePhase::Booting {
                            since_us: now_us,
                            attempts: attempts + 1,
                        };
                        self.push(can_bus(j), NmtCommand::ResetCommunication.frame(node_id));
                    }
                }
                NodePhase::Configuring { step, retries } => {
                    if let Some((SdoOutcome::TimedOut(address), abort)) =
                        self.nodes[j].sdo.poll_timeout(node_id, now_us)
                    {
                        self.push(can_bus(j), abort);
                        if retries >= SDO_RETRIES {
                            self.nodes[j].phase = NodePhase::Failed;
                            self.fail(j, NodeFault::ConfigTimeout { address });
                        } else {
                            self.nodes[j].phase = NodePhase::Configuring {
                                step,
                                retries: retries + 1,
                            };
                            self.next_sdo(j, now_us);
                        }
                    }
                }
                NodePhase::Operational
                    if now_us.saturating_sub(self.nodes[j].last_heartbeat_us)
                        > HEARTBEAT_TIMEOUT_US =>
                {
                    self.fail(j, NodeFault::LostHeartbeat);
                }
                _ => {}
            }
        }
    }

    /// Begins a control cycle: counts drives whose feedback of the last cycle is missing
    /// and sends SYNC on both buses.
    pub fn sync(&mut self) {
        for j in 0..NUM_JOINTS {
            let node = &mut self.nodes[j];
            if node.phase != NodePhase::Operational {
                continue;
            }
            if node.awaiting_feedback {
                node.missed_cycles = node.missed_cycles.saturating_add(1);
                if node.missed_cycles >= FEEDBACK_MISS_LIMIT {
                    self.fail(j, NodeFault::FeedbackLost);
                }
            }
            let node = &mut self.nodes[j];
            node.awaiting_feedback = true;
            node.got_tpdo1 = false;
            node.got_tpdo2 = false;
        }
        for bus in 0..NUM_BUSES {
            self.push(bus, CanFrame::new_truncating(cob::SYNC, &[]));
        }
    }

    /// True when every reachable operational drive has answered the last SYNC.
    pub fn feedback_complete(&self) -> bool {
        self.nodes
            .iter()
            .all(|n| !n.is_reachable() || !n.awaiting_feedback)
    }

    /// Sends one RPDO per reachable drive: the controlword that moves it toward
    /// `requests[j]` and the target position (clamped to the joint limits). Drives that
    /// are not yet enabled get their own position as target, so enabling never jumps.
    /// A drive whose feedback of this cycle is missing keeps its last target and
    /// controlword (frozen); a lost drive gets the [`LostReaction`].
    pub fn send_commands(
        &mut self,
        requests: &[DriveRequest; NUM_JOINTS],
        targets_rad: &[f32; NUM_JOINTS],
    ) {
        for j in 0..NUM_JOINTS {
            let node = &mut self.nodes[j];
            if node.phase != NodePhase::Operational {
                continue;
            }
            if node.fault.is_some_and(NodeFault::drive_lost) {
                self.react_to_lost(j, requests[j]);
                continue;
            }
            // No controlword before the drive's state is known.
            if !node.is_reachable() || !node.state_known {
                continue;
            }
            if node.awaiting_feedback && node.missed_cycles >= FREEZE_AFTER_MISSED - 1 {
                // No feedback for FREEZE_AFTER_MISSED cycles in a row: whatever we would send
                // is based on stale state. Repeat the last command (nothing if none was sent
                // since configuration).
                node.frozen_cycles = node.frozen_cycles.saturating_add(1);
                if node.commanded {
                    let (cw, target) = (node.controlword, node.target_increments);
                    self.push_rpdo(j, cw, target);
                }
                continue;
            }
            let mut cw = next_controlword(node.power, requests[j], node.controlword);
            if node.power == PowerState::OperationEnabled {
                node.quick_stop_hold_sent = false;
            }
            if node.power == PowerState::QuickStopActive && requests[j] == DriveRequest::Enable {
                // Leaving Quick stop active only deliberately: for a drive adopted at its
                // position, after one cycle that set its target to where it is.
                if node.adopted && node.quick_stop_hold_sent {
                    cw = CW_ENABLE_OPERATION;
                } else {
                    node.quick_stop_hold_sent = true;
                }
            }
            let follow = node.power == PowerState::OperationEnabled
                && requests[j] == DriveRequest::Enable
                && targets_rad[j].is_finite();
            let target_rad = if follow {
                targets_rad[j].clamp(Q_MIN_RAD[j], Q_MAX_RAD[j])
            } else {
                node.q_rad
            };
            let target = units::rad_to_increments(target_rad);
            self.push_rpdo(j, cw, target);
        }
    }

    fn push_rpdo(&mut self, joint: usize, controlword: u16, target_increments: i32) {
        let node = &mut self.nodes[joint];
        node.controlword = controlword;
        node.target_increments = target_increments;
        node.commanded = true;
        let rpdo = Rpdo1 {
            controlword,
            target_position: target_increments,
        };
        let frame = CanFrame::new_truncating(
            cob::RPDO_BASE[0] + can_node_id(joint) as u16,
            &rpdo.encode(),
        );
        self.push(can_bus(joint), frame);
    }

    /// One cycle of the lost-drive reaction ([`LostReaction`]).
    fn react_to_lost(&mut self, joint: usize, request: DriveRequest) {
        let node = &mut self.nodes[joint];
        let torque_off = matches!(request, DriveRequest::Disable | DriveRequest::FaultReset);
        let next = match (node.lost, torque_off) {
            (LostReaction::Stopped, _) => return,
            (LostReaction::None | LostReaction::QuickStop, false) => LostReaction::QuickStop,
            (LostReaction::None | LostReaction::QuickStop, true) => LostReaction::Disabling(0),
            (LostReaction::Disabling(n), _) if n + 1 >= LOST_DISABLE_CYCLES => {
                LostReaction::Stopped
            }
            (LostReaction::Disabling(n), _) => LostReaction::Disabling(n + 1),
        };
        node.lost = next;
        let target = node.target_increments;
        match next {
            LostReaction::QuickStop => self.push_rpdo(joint, CW_QUICK_STOP, target),
            LostReaction::Disabling(_) => self.push_rpdo(joint, CW_DISABLE_VOLTAGE, target),
            LostReaction::Stopped => {
                let frame = NmtCommand::Stop.frame(can_node_id(joint));
                self.push(can_bus(joint), frame);
            }
            LostReaction::None => {}
        }
    }
}

#[cfg(test)]
#[path = "master_tests.rs"]
mod tests;
