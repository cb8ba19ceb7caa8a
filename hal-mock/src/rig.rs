//! The drive side of the software-in-the-loop setup: two virtual buses and 18 emulated
//! drives (node ids 1-9 on bus 0, 10-18 on bus 1) acting on one [`JointPlant`].
//!
//! Call [`DriveRig::step`] whenever time advances (at least at the physics rate): it hands
//! each drive its joint's state, delivers due frames, runs the drives' timers and applies
//! their setpoints to the plant.

use hexapod_core::can_frame::CanFrame;
use hexapod_core::robot::{can_bus, NUM_JOINTS};

use crate::bus::VirtualBus;
use crate::candump::{format_log, LogEntry};
use crate::drive::Drive;
use crate::plant::JointPlant;

/// How long a drive takes from receiving a frame to queueing its answer (a SYNC to its
/// TPDOs), nanoseconds.
pub const DRIVE_RESPONSE_NS: u64 = 50_000;

/// Two buses and 18 drives.
#[derive(Clone, Debug)]
pub struct DriveRig {
    /// Bus 0 (right legs) and bus 1 (left legs).
    pub buses: [VirtualBus; 2],
    /// Drives in joint order.
    pub drives: Vec<Drive>,
    out: Vec<CanFrame>,
}

impl DriveRig {
    /// A rig with powered-off drives; `seed` drives the buses' loss dice.
    pub fn new(seed: u64) -> Self {
        Self {
            buses: [VirtualBus::new(0, seed), VirtualBus::new(1, seed ^ 0x5EED)],
            drives: (0..NUM_JOINTS).map(Drive::new).collect(),
            out: Vec::new(),
        }
    }

    /// Starts recording traffic on both buses.
    pub fn record(&mut self) {
        self.buses.iter_mut().for_each(VirtualBus::record);
    }

    /// The recorded traffic of both buses in candump log format.
    pub fn candump(&self) -> String {
        let entries: Vec<LogEntry> = self
            .buses
            .iter()
            .filter_map(|b| b.log.as_ref())
            .flatten()
            .copied()
            .collect();
        format_log(&entries)
    }

    /// Powers all drives on (each sends its boot-up message).
    pub fn power_on(&mut self, now_us: u64) {
        for b in &mut self.buses {
            b.set_time(now_us);
        }
        for j in 0..NUM_JOINTS {
            self.drives[j].power_on(now_us, &mut self.out);
            self.flush(j);
        }
    }

    fn flush(&mut self, joint: usize) {
        let bus = &mut self.buses[can_bus(joint)];
        for f in self.out.drain(..) {
            bus.send_from_drive(&f);
        }
    }

    /// Sends what drive `joint` answered to a frame it received at `received_ns`.
    fn flush_reply(&mut self, joint: usize, received_ns: u64) {
        let bus = &mut self.buses[can_bus(joint)];
        for f in self.out.drain(..) {
            bus.send_from_drive_at(&f, received_ns + DRIVE_RESPONSE_NS);
        }
    }

    /// Injects a drive fault: the drive goes to Fault (torque off) and sends its EMCY.
    pub fn inject_drive_fault(&mut self, joint: usize, error_code: u16) {
        self.drives[joint].inject_fault(error_code, &mut self.out);
        self.flush(joint);
    }

    /// Silences (or revives) a drive: no heartbeat, no PDOs, no SDO answers.
    pub fn set_drive_mute(&mut self, joint: usize, muted: bool) {
        self.drives[joint].set_mute(muted);
    }

    /// Advances the drive side to `now_us`.
    pub fn step<P: JointPlant>(&mut self, now_us: u64, plant: &mut P) {
        for b in &mut self.buses {
            b.set_time(now_us);
        }
        for j in 0..NUM_JOINTS {
            self.drives[j].set_feedback(plant.joint_state(j));
        }
        for bus in 0..2 {
            for (received_ns, frame) in self.buses[bus].take_for_drives_timed() {
                for j in (0..NUM_JOINTS).filter(|&j| can_bus(j) == bus) {
                    self.drives[j].on_frame(&frame, now_us, &mut self.out);
                    self.flush_reply(j, received_ns);
                }
            }
        }
        for j in 0..NUM_JOINTS {
            self.drives[j].tick(now_us, &mut self.out);
            self.flush(j);
            plant.set_setpoint(j, self.drives[j].setpoint());
        }
    }
}
