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
    /// The controller's CAN peripheral is bus-off: it can neither send nor receive.
    pub bus_off: bool,
}

/// Traffic counters of one bus.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct BusStats {
    /// Frames put on the bus.
    pub frames: u64,
    /// Frames lost by injection.
    pub lost: u64,
}

/// One virtual bus.
#[derive(Clone, Debug)]
pub struct VirtualBus {
    index: usize,
    now_us: u64,
    to_controller: VecDeque<(u64, CanFrame)>,
    to_drives: VecDeque<(u64, CanFrame)>,
    rng: SplitMix64,
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
            faults: BusFaults::default(),
            stats: BusStats::default(),
            log: None,
        }
    }

    /// Sets the bus clock.
    pub fn set_time(&mut self, now_us: u64) {
        self.now_us = now_us;
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
        if let Some(at) = self.transmit(frame) {
            if !self.faults.bus_off {
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
        if self.faults.bus_off {
            return Err(CanTxError::BusOff);
        }
        if let Some(at) = self.transmit(frame) {
            self.to_drives.push_back((at, *frame));
        }
        Ok(())
    }

    fn try_receive(&mut self) -> Option<CanFrame> {
        if self.faults.bus_off {
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
        self.faults.bus_off
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
}
