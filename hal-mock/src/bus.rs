//! An in-memory CAN bus between the controller and the emulated drives, with fault
//! injection (frame loss, latency, bus-off) and a candump-format traffic record.
//!
//! The controller side implements [`hexapod_core::hal::CanBus`]; the drive side is driven
//! by [`crate::rig::DriveRig`]. Time is set by the owner with [`VirtualBus::set_time`].

use std::collections::VecDeque;

use hexapod_core::can_frame::CanFrame;
use hexapod_core::hal::{CanBus, CanTxError};

use crate::candump::LogEntry;
use crate::rng::SplitMix64;

/// Faults injected on one bus.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct BusFaults {
    /// Probability that a frame is lost (not received by anyone), in [0, 1].
    pub loss_probability: f32,
    /// Delay between transmission and reception, microseconds.
    pub latency_us: u64,
    /// A disturbance (shorted or stuck bus, a broken transceiver) that drives the
    /// controller's CAN peripheral bus-off: while it lasts the peripheral can neither send
    /// nor receive. Once it ends, the peripheral recovers as ISO 11898-1 says: after 128
    /// occurrences of 11 consecutive recessive bits ([`BUS_OFF_RECOVERY_US`]).
    pub bus_off: bool,
}

/// Bit rate of both buses, bit/s.
pub const BIT_RATE: u64 = 1_000_000;
/// Bus-off recovery (ISO 11898-1): 128 x 11 recessive bits at [`BIT_RATE`], microseconds.
pub const BUS_OFF_RECOVERY_US: u64 = 128 * 11 * 1_000_000 / BIT_RATE;

/// Traffic counters of one bus.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct BusStats {
    /// Frames put on the bus.
    pub frames: u64,
    /// Frames lost by injection.
    pub lost: u64,
    /// Times the controller's peripheral went bus-off.
    pub bus_off_events: u64,
    /// Times it recovered (error active again).
    pub bus_off_recoveries: u64,
}

/// One virtual bus.
#[derive(Clone, Debug)]
pub struct VirtualBus {
    index: usize,
    now_us: u64,
    to_controller: VecDeque<(u64, CanFrame)>,
    to_drives: VecDeque<(u64, CanFrame)>,
    rng: SplitMix64,
    /// The peripheral is bus-off; `Some(t)`: the disturbance ended at `t` and recovery runs.
    bus_off_state: Option<Option<u64>>,
    /// Injected faults.
    pub faults: BusFaults,
    /// Counters.
    pub stats: BusStats,
    /// Recorded traffic, when recording is on.
    pub log: Option<Vec<LogEntry>>,
}

impl VirtualBus {
    /// Bus `index` (logged as `can<index>`), loss dice seeded with `seed`.
    pub fn new(index: usize, seed: u64) -> Self {
        Self {
            index,
            now_us: 0,
            to_controller: VecDeque::new(),
            to_drives: VecDeque::new(),
            rng: SplitMix64::new(seed),
            bus_off_state: None,
            faults: BusFaults::default(),
            stats: BusStats::default(),
            log: None,
        }
    }

    /// Sets the bus clock (and runs the peripheral's bus-off state).
    pub fn set_time(&mut self, now_us: u64) {
        self.now_us = now_us;
        self.update_bus_off();
    }

    fn update_bus_off(&mut self) {
        match (self.faults.bus_off, self.bus_off_state) {
            (true, None) => {
                self.bus_off_state = Some(None);
                self.stats.bus_off_events += 1;
                self.to_controller.clear();
            }
            (true, Some(Some(_))) => self.bus_off_state = Some(None),
            (false, Some(None)) => self.bus_off_state = Some(Some(self.now_us)),
            (false, Some(Some(since))) if self.now_us >= since + BUS_OFF_RECOVERY_US => {
                self.bus_off_state = None;
                self.stats.bus_off_recoveries += 1;
            }
            _ => {}
        }
    }

    /// True while the controller's peripheral is bus-off (disturbed or recovering).
    pub fn peripheral_bus_off(&self) -> bool {
        self.faults.bus_off || self.bus_off_state.is_some()
    }

    /// The controller's CAN peripheral is reset: frames waiting for it are gone (frames it
    /// already put on the wire still reach the drives).
    pub fn reset_controller_side(&mut self) {
        self.to_controller.clear();
    }

    /// Starts recording all traffic.
    pub fn record(&mut self) {
        self.log.get_or_insert_with(Vec::new);
    }

    /// Puts a frame on the wire: logs it, rolls the loss dice, returns its delivery time.
    fn transmit(&mut self, frame: &CanFrame) -> Option<u64> {
        self.stats.frames += 1;
        if let Some(log) = &mut self.log {
            log.push(LogEntry {
                time_us: self.now_us,
                bus: self.index,
                frame: *frame,
            });
        }
        if self.faults.loss_probability > 0.0 && self.rng.uniform() < self.faults.loss_probability {
            self.stats.lost += 1;
            return None;
        }
        Some(self.now_us + self.faults.latency_us)
    }

    /// A drive transmits.
    pub fn send_from_drive(&mut self, frame: &CanFrame) {
        self.update_bus_off();
        if let Some(at) = self.transmit(frame) {
            if !self.peripheral_bus_off() {
                self.to_controller.push_back((at, *frame));
            }
        }
    }

    /// Frames due at the drives by now.
    pub fn take_for_drives(&mut self) -> Vec<CanFrame> {
        let mut due = Vec::new();
        while let Some(&(at, f)) = self.to_drives.front() {
            if at > self.now_us {
                break;
            }
            self.to_drives.pop_front();
            due.push(f);
        }
        due
    }
}

impl CanBus for VirtualBus {
    fn try_send(&mut self, frame: &CanFrame) -> Result<(), CanTxError> {
        self.update_bus_off();
        if self.peripheral_bus_off() {
            return Err(CanTxError::BusOff);
        }
        if let Some(at) = self.transmit(frame) {
            self.to_drives.push_back((at, *frame));
        }
        Ok(())
    }

    fn try_receive(&mut self) -> Option<CanFrame> {
        self.update_bus_off();
        if self.peripheral_bus_off() {
            self.to_controller.clear();
            return None;
        }
        match self.to_controller.front() {
            Some(&(at, f)) if at <= self.now_us => {
                self.to_controller.pop_front();
                Some(f)
            }
            _ => None,
        }
    }

    fn is_bus_off(&self) -> bool {
        self.peripheral_bus_off()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn latency_loss_and_bus_off() {
        let mut bus = VirtualBus::new(0, 7);
        bus.faults.latency_us = 100;
        let f = CanFrame::data_frame(0x181, &[1]).unwrap();
        bus.send_from_drive(&f);
        assert_eq!(bus.try_receive(), None);
        bus.set_time(100);
        assert_eq!(bus.try_receive(), Some(f));

        bus.faults.loss_probability = 0.5;
        for _ in 0..1000 {
            bus.try_send(&f).unwrap();
        }
        assert!((400..600).contains(&bus.stats.lost), "{}", bus.stats.lost);

        bus.faults.bus_off = true;
        assert_eq!(bus.try_send(&f), Err(CanTxError::BusOff));
    }

    #[test]
    fn bus_off_recovers_after_128_times_11_recessive_bits() {
        let mut bus = VirtualBus::new(0, 7);
        bus.faults.bus_off = true;
        bus.set_time(1_000);
        assert!(bus.is_bus_off());
        bus.faults.bus_off = false;
        bus.set_time(50_000);
        assert!(bus.is_bus_off(), "recovery starts when the disturbance ends");
        bus.set_time(50_000 + BUS_OFF_RECOVERY_US - 1);
        assert!(bus.is_bus_off());
        bus.set_time(50_000 + BUS_OFF_RECOVERY_US);
        assert!(!bus.is_bus_off());
        assert_eq!(BUS_OFF_RECOVERY_US, 1_408);
        assert_eq!((bus.stats.bus_off_events, bus.stats.bus_off_recoveries), (1, 1));
        let f = CanFrame::data_frame(0x181, &[1]).unwrap();
        assert_eq!(bus.try_send(&f), Ok(()));
    }
}
