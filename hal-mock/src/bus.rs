//! An in-memory CAN bus between the controller and the emulated drives, with the timing
//! of a real 1 Mbit/s bus and fault injection, and a candump-format traffic record.
//!
//! The wire: every transmitter (the controller, each drive) queues frames in order; when
//! the bus is idle the pending frame with the lowest identifier wins arbitration and
//! occupies the bus for its exact length in bits (CAN 2.0A base frame with its CRC-15 and
//! the bit stuffing of that content, plus ACK, EOF and intermission: 47 + 8 n bits before
//! stuffing). It reaches the receivers at its end of frame. Faults: bit errors in bursts
//! (the frame is destroyed by an error frame and retransmitted automatically), frames lost
//! for the receivers in bursts (Gilbert-Elliott), a fixed extra latency, and bus-off of the
//! controller's peripheral with the ISO 11898-1 recovery.
//!
//! Per SYNC period the bus records its load and the feedback latency (SYNC to the end of
//! the last TPDO) in [`BusStats::cycles`].
//!
//! The controller side implements [`hexapod_core::hal::CanBus`]; the drive side is driven
//! by [`crate::rig::DriveRig`]. Time is set by the owner with [`VirtualBus::set_time`].

use std::collections::VecDeque;

use hexapod_core::can_frame::CanFrame;
use hexapod_core::canopen::cob;
use hexapod_core::hal::{CanBus, CanTxError};

use crate::candump::LogEntry;
use crate::rng::SplitMix64;

/// Bit rate of both buses, bit/s.
pub const BIT_RATE: u64 = 1_000_000;
/// One bit time, nanoseconds.
pub const BIT_NS: u64 = 1_000_000_000 / BIT_RATE;
/// Bus-off recovery (ISO 11898-1): 128 x 11 recessive bits at [`BIT_RATE`], microseconds.
pub const BUS_OFF_RECOVERY_US: u64 = 128 * 11 * 1_000_000 / BIT_RATE;
/// An error frame after a bit error: error flag (6, superposed up to 12), delimiter (8),
/// intermission (3).
pub const ERROR_FRAME_BITS: u64 = 12 + 8 + 3;
/// Frames the controller's transmit FIFO holds (the firmware's queue is 32).
pub const CONTROLLER_TX_QUEUE: usize = 32;

/// Faults injected on one bus.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BusFaults {
    /// Probability that a frame is lost for its receivers (after a correct transmission:
    /// an overrun or a local receive error), in [0, 1].
    pub loss_probability: f32,
    /// Mean length of a loss burst, frames (1: independent losses).
    pub loss_burst_frames: f32,
    /// Probability that a transmission is destroyed by a bit error (error frame, then the
    /// transmitter retries), in [0, 1].
    pub error_probability: f32,
    /// Mean length of an error burst, transmissions (1: independent).
    pub error_burst_frames: f32,
    /// Extra delay between the end of a frame and its reception, microseconds.
    pub latency_us: u64,
    /// A disturbance (shorted or stuck bus, a broken transceiver) that drives the
    /// controller's CAN peripheral bus-off: while it lasts the peripheral can neither send
    /// nor receive. Once it ends, the peripheral recovers as ISO 11898-1 says: after 128
    /// occurrences of 11 consecutive recessive bits ([`BUS_OFF_RECOVERY_US`]).
    pub bus_off: bool,
}

impl Default for BusFaults {
    fn default() -> Self {
        Self {
            loss_probability: 0.0,
            loss_burst_frames: 1.0,
            error_probability: 0.0,
            error_burst_frames: 1.0,
            latency_us: 0,
            bus_off: false,
        }
    }
}

/// One SYNC period of a bus.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CycleStats {
    /// Start of the SYNC frame, microseconds.
    pub sync_us: f64,
    /// From the end of the SYNC to the end of the last TPDO of the period, microseconds
    /// (0 when no TPDO came).
    pub feedback_latency_us: f64,
    /// TPDOs in the period.
    pub tpdos: u32,
    /// Bus busy time over the period (frames and error frames), fraction.
    pub load: f64,
}

/// Traffic counters of one bus.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct BusStats {
    /// Frames put on the bus (successful transmissions).
    pub frames: u64,
    /// Frames lost for their receivers by injection.
    pub lost: u64,
    /// Error frames (destroyed transmissions, each retried).
    pub error_frames: u64,
    /// Bits on the wire, stuff bits and error frames included.
    pub bits: u64,
    /// Stuff bits among them.
    pub stuff_bits: u64,
    /// Times the controller's peripheral went bus-off.
    pub bus_off_events: u64,
    /// Times it recovered (error active again).
    pub bus_off_recoveries: u64,
    /// Per SYNC period: load and feedback latency.
    pub cycles: Vec<CycleStats>,
}

impl BusStats {
    /// Mean and worst feedback latency over the periods with feedback, microseconds.
    pub fn feedback_latency_us(&self) -> Option<(f64, f64)> {
        let with: Vec<f64> = self
            .cycles
            .iter()
            .filter(|c| c.tpdos > 0)
            .map(|c| c.feedback_latency_us)
            .collect();
        if with.is_empty() {
            return None;
        }
        let mean = with.iter().sum::<f64>() / with.len() as f64;
        Some((mean, with.iter().copied().fold(0.0, f64::max)))
    }

    /// Mean and worst bus load per SYNC period over the last `n` periods.
    pub fn load(&self, n: usize) -> Option<(f64, f64)> {
        let last = &self.cycles[self.cycles.len().saturating_sub(n)..];
        if last.is_empty() {
            return None;
        }
        let mean = last.iter().map(|c| c.load).sum::<f64>() / last.len() as f64;
        Some((mean, last.iter().map(|c| c.load).fold(0.0, f64::max)))
    }
}

/// Who sends a frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Source {
    Controller,
    Drive(u8),
}

#[derive(Clone, Copy, Debug)]
struct Pending {
    frame: CanFrame,
    ready_ns: u64,
}

/// The CRC-15 of CAN over `bits` (MSB first).
fn crc15(bits: &[bool]) -> u16 {
    let mut crc: u16 = 0;
    for &b in bits {
        let next = b ^ (crc >> 14 & 1 == 1);
        crc = (crc << 1) & 0x7FFF;
        if next {
            crc ^= 0x4599;
        }
    }
    crc
}

/// Bits of a base-format frame on the wire (SOF to intermission) and its stuff bits.
pub fn frame_bits(frame: &CanFrame) -> (u64, u64) {
    let mut bits: Vec<bool> = Vec::with_capacity(110);
    let push = |bits: &mut Vec<bool>, value: u32, n: u32| {
        for k in (0..n).rev() {
            bits.push(value >> k & 1 == 1);
        }
    };
    bits.push(false); // SOF
    push(&mut bits, frame.cob_id() as u32, 11);
    bits.push(frame.is_rtr()); // RTR
    bits.push(false); // IDE
    bits.push(false); // r0
    let dlc = if frame.is_rtr() {
        0
    } else {
        frame.payload().len() as u32
    };
    push(&mut bits, dlc, 4);
    if !frame.is_rtr() {
        for &b in frame.payload() {
            push(&mut bits, b as u32, 8);
        }
    }
    let crc = crc15(&bits);
    push(&mut bits, crc as u32, 15);
    // Stuffing: after five equal bits a complementary bit (which starts the next run).
    let mut stuff = 0u64;
    let mut run = 0;
    let mut last = None;
    for &b in &bits {
        if Some(b) == last {
            run += 1;
        } else {
            run = 1;
            last = Some(b);
        }
        if run == 5 {
            stuff += 1;
            last = Some(!b);
            run = 1;
        }
    }
    // CRC delimiter, ACK slot and delimiter, EOF (7), intermission (3).
    (bits.len() as u64 + stuff + 13, stuff)
}

/// A two-state (Gilbert-Elliott) burst process: `rate` of the events in bursts of mean
/// length `burst`; with `burst` <= 1 each event is independent.
#[derive(Clone, Copy, Debug, Default)]
struct Bursts {
    bad: bool,
}

impl Bursts {
    fn hit(&mut self, rng: &mut SplitMix64, rate: f32, burst: f32) -> bool {
        if rate <= 0.0 {
            self.bad = false;
            return false;
        }
        if burst <= 1.0 {
            return rng.uniform() < rate;
        }
        let rate = rate.min(0.5);
        let leave = 1.0 / burst;
        let enter = rate / (1.0 - rate) * leave;
        let u = rng.uniform();
        self.bad = if self.bad { u >= leave } else { u < enter };
        self.bad
    }
}

/// One virtual bus.
#[derive(Clone, Debug)]
pub struct VirtualBus {
    index: usize,
    now_us: u64,
    /// Per transmitter, in order.
    pending: Vec<(Source, VecDeque<Pending>)>,
    /// The bus is busy until then, nanoseconds.
    busy_until_ns: u64,
    to_controller: VecDeque<(u64, CanFrame)>,
    to_drives: VecDeque<(u64, CanFrame)>,
    rng: SplitMix64,
    loss: Bursts,
    errors: Bursts,
    /// The peripheral is bus-off; `Some(t)`: the disturbance ended at `t` and recovery runs.
    bus_off_state: Option<Option<u64>>,
    /// The controller's transmit and receive error counters (ISO 11898-1 fault confinement).
    tec: u16,
    rec: u16,
    cycle: Option<CycleStats>,
    cycle_sync_end_ns: u64,
    cycle_busy_ns: u64,
    /// Injected faults.
    pub faults: BusFaults,
    /// Counters.
    pub stats: BusStats,
    /// Recorded traffic, when recording is on.
    pub log: Option<Vec<LogEntry>>,
}

impl VirtualBus {
    /// Bus `index` (logged as `can<index>`), fault dice seeded with `seed`.
    pub fn new(index: usize, seed: u64) -> Self {
        Self {
            index,
            now_us: 0,
            pending: Vec::new(),
            busy_until_ns: 0,
            to_controller: VecDeque::new(),
            to_drives: VecDeque::new(),
            rng: SplitMix64::new(seed),
            loss: Bursts::default(),
            errors: Bursts::default(),
            bus_off_state: None,
            tec: 0,
            rec: 0,
            cycle: None,
            cycle_sync_end_ns: 0,
            cycle_busy_ns: 0,
            faults: BusFaults::default(),
            stats: BusStats::default(),
            log: None,
        }
    }

    /// Sets the bus clock: transmits what the wire carries until then.
    pub fn set_time(&mut self, now_us: u64) {
        self.now_us = now_us.max(self.now_us);
        self.update_bus_off();
        self.run_wire(self.now_us * 1000);
    }

    fn update_bus_off(&mut self) {
        match (self.faults.bus_off, self.bus_off_state) {
            (true, None) => {
                self.bus_off_state = Some(None);
                self.stats.bus_off_events += 1;
                self.to_controller.clear();
                self.queue_of(Source::Controller).clear();
            }
            (true, Some(Some(_))) => self.bus_off_state = Some(None),
            (false, Some(None)) => self.bus_off_state = Some(Some(self.now_us)),
            (false, Some(Some(since))) if self.now_us >= since + BUS_OFF_RECOVERY_US => {
                self.bus_off_state = None;
                self.stats.bus_off_recoveries += 1;
                self.tec = 0;
                self.rec = 0;
            }
            _ => {}
        }
    }

    /// The controller's transmit and receive error counters.
    pub fn error_counters(&self) -> (u16, u16) {
        (self.tec, self.rec)
    }

    /// The controller's peripheral is error passive (an error counter above 127).
    pub fn error_passive(&self) -> bool {
        self.tec > 127 || self.rec > 127
    }

    /// True while the controller's peripheral is bus-off (disturbed or recovering).
    pub fn peripheral_bus_off(&self) -> bool {
        self.faults.bus_off || self.bus_off_state.is_some()
    }

    /// The controller's CAN peripheral is reset: frames waiting for it, and its own
    /// frames not yet on the wire, are gone.
    pub fn reset_controller_side(&mut self) {
        self.to_controller.clear();
        self.queue_of(Source::Controller).clear();
    }

    /// Starts recording all traffic.
    pub fn record(&mut self) {
        self.log.get_or_insert_with(Vec::new);
    }

    fn queue_of(&mut self, source: Source) -> &mut VecDeque<Pending> {
        let k = match self.pending.iter().position(|(s, _)| *s == source) {
            Some(k) => k,
            None => {
                self.pending.push((source, VecDeque::new()));
                self.pending.len() - 1
            }
        };
        &mut self.pending[k].1
    }

    fn enqueue(&mut self, source: Source, frame: &CanFrame) {
        let ready_ns = self.now_us * 1000;
        self.enqueue_at(source, frame, ready_ns);
    }

    fn enqueue_at(&mut self, source: Source, frame: &CanFrame, ready_ns: u64) {
        self.queue_of(source).push_back(Pending {
            frame: *frame,
            ready_ns,
        });
    }

    /// Runs arbitration and transmissions up to `until_ns`.
    fn run_wire(&mut self, until_ns: u64) {
        loop {
            // The bus is idle from `start`; every head ready by then competes.
            let earliest = self
                .pending
                .iter()
                .filter_map(|(_, q)| q.front().map(|p| p.ready_ns))
                .min();
            let Some(earliest) = earliest else {
                return;
            };
            let start = earliest.max(self.busy_until_ns);
            if start >= until_ns {
                return;
            }
            let Some(k) = self
                .pending
                .iter()
                .enumerate()
                .filter_map(|(k, (_, q))| q.front().filter(|p| p.ready_ns <= start).map(|p| (k, p)))
                .min_by_key(|(_, p)| p.frame.cob_id())
                .map(|(k, _)| k)
            else {
                return;
            };
            let frame = self.pending[k].1.front().map(|p| p.frame);
            let Some(frame) = frame else {
                return;
            };
            let source = self.pending[k].0;
            let (bits, stuff) = frame_bits(&frame);
            if self.errors.hit(
                &mut self.rng,
                self.faults.error_probability,
                self.faults.error_burst_frames,
            ) {
                // A bit error somewhere in the frame, then the error frame; retried.
                let at_bit = 1 + (self.rng.next_u64() % bits.max(1));
                let busy = (at_bit + ERROR_FRAME_BITS) * BIT_NS;
                self.busy_until_ns = start + busy;
                self.stats.error_frames += 1;
                self.stats.bits += at_bit + ERROR_FRAME_BITS;
                self.cycle_busy_ns += busy;
                // Fault confinement: the transmitter's TEC + 8, a receiver's REC + 1; a
                // controller whose TEC passes 255 goes bus-off (and recovers by itself).
                match source {
                    Source::Controller => {
                        self.tec = self.tec.saturating_add(8);
                        if self.tec > 255 && self.bus_off_state.is_none() {
                            self.stats.bus_off_events += 1;
                            self.bus_off_state = Some(Some(self.now_us.max(start / 1000)));
                            self.to_controller.clear();
                            self.queue_of(Source::Controller).clear();
                        }
                    }
                    Source::Drive(_) => self.rec = self.rec.saturating_add(1).min(255),
                }
                if let Some(log) = &mut self.log {
                    log.push(LogEntry::error(start / 1000, self.index));
                }
                continue;
            }
            self.pending[k].1.pop_front();
            match source {
                Source::Controller => self.tec = self.tec.saturating_sub(1),
                Source::Drive(_) => self.rec = self.rec.saturating_sub(1),
            }
            let busy = bits * BIT_NS;
            let end = start + busy;
            self.busy_until_ns = end;
            self.stats.frames += 1;
            self.stats.bits += bits;
            self.stats.stuff_bits += stuff;
            if let Some(log) = &mut self.log {
                log.push(LogEntry::frame(start / 1000, self.index, frame));
            }
            self.on_wire_frame(&frame, start, end, busy);
            let lost = self.loss.hit(
                &mut self.rng,
                self.faults.loss_probability,
                self.faults.loss_burst_frames,
            );
            if lost {
                self.stats.lost += 1;
                continue;
            }
            let at = end.div_ceil(1000) + self.faults.latency_us;
            match source {
                Source::Controller => self.to_drives.push_back((at, frame)),
                Source::Drive(_) => {
                    if !self.peripheral_bus_off() {
                        self.to_controller.push_back((at, frame));
                    }
                }
            }
        }
    }

    /// Per-period statistics: a SYNC closes the last period and opens the next.
    fn on_wire_frame(&mut self, frame: &CanFrame, start: u64, end: u64, busy: u64) {
        if frame.cob_id() == cob::SYNC {
            if let Some(mut c) = self.cycle.take() {
                let period = start as f64 - c.sync_us * 1000.0;
                c.load = self.cycle_busy_ns as f64 / period.max(1.0);
                self.stats.cycles.push(c);
            }
            self.cycle = Some(CycleStats {
                sync_us: start as f64 / 1000.0,
                ..CycleStats::default()
            });
            self.cycle_sync_end_ns = end;
            self.cycle_busy_ns = busy;
            return;
        }
        self.cycle_busy_ns += busy;
        let tpdo = matches!(cob::classify(frame.cob_id()), Some(cob::Cob::Tpdo(..)));
        if let (Some(c), true) = (&mut self.cycle, tpdo) {
            c.tpdos += 1;
            c.feedback_latency_us = (end - self.cycle_sync_end_ns) as f64 / 1000.0;
        }
    }

    /// A drive transmits (it queues the frame; the wire takes it when it wins).
    pub fn send_from_drive(&mut self, frame: &CanFrame) {
        // Queued only: the wire runs when the bus is read, so that all frames queued at
        // the same instant compete in one arbitration.
        let node = (frame.cob_id() & 0x7F) as u8;
        self.enqueue(Source::Drive(node), frame);
    }

    /// A drive transmits a frame it made `ready_ns` (its answer to a frame it received
    /// then, e.g. the TPDOs after a SYNC), even if the caller runs in coarser steps.
    pub fn send_from_drive_at(&mut self, frame: &CanFrame, ready_ns: u64) {
        let node = (frame.cob_id() & 0x7F) as u8;
        let ready_ns = ready_ns.max(self.busy_until_ns.min(self.now_us * 1000));
        self.enqueue_at(Source::Drive(node), frame, ready_ns);
    }

    /// Frames due at the drives by now.
    pub fn take_for_drives(&mut self) -> Vec<CanFrame> {
        self.take_for_drives_timed()
            .into_iter()
            .map(|(_, f)| f)
            .collect()
    }

    /// Frames due at the drives by now, with their end of frame (nanoseconds).
    pub fn take_for_drives_timed(&mut self) -> Vec<(u64, CanFrame)> {
        self.run_wire(self.now_us * 1000 + 1);
        let mut due = Vec::new();
        while let Some(&(at, f)) = self.to_drives.front() {
            if at > self.now_us {
                break;
            }
            self.to_drives.pop_front();
            due.push((at.saturating_sub(self.faults.latency_us) * 1000, f));
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
        if self.queue_of(Source::Controller).len() >= CONTROLLER_TX_QUEUE {
            return Err(CanTxError::QueueFull);
        }
        self.enqueue(Source::Controller, frame);
        Ok(())
    }

    fn try_receive(&mut self) -> Option<CanFrame> {
        self.update_bus_off();
        if self.peripheral_bus_off() {
            self.to_controller.clear();
            return None;
        }
        self.run_wire(self.now_us * 1000 + 1);
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
    fn frame_length_with_stuffing() {
        // SYNC: 47 bits without stuffing; its 19 leading dominant bits (SOF, 0x080's
        // high zeros ...) need stuff bits.
        let sync = CanFrame::data_frame(0x080, &[]).unwrap();
        let (bits, stuff) = frame_bits(&sync);
        assert_eq!(bits, 47 + stuff);
        assert!(stuff >= 3, "{stuff}");
        // A TPDO with 6 bytes: 95 bits before stuffing, at most 24 stuff bits.
        let t = CanFrame::data_frame(0x181, &[0x37, 0x16, 0, 0, 0, 0]).unwrap();
        let (bits, stuff) = frame_bits(&t);
        assert_eq!(bits, 95 + stuff);
        assert!(stuff > 0 && stuff <= 24, "{stuff}");
        // CRC-15 of CAN: the check value of "123456789" is 0x059E.
        let mut msg = Vec::new();
        for b in b"123456789" {
            for k in (0..8).rev() {
                msg.push(b >> k & 1 == 1);
            }
        }
        assert_eq!(crc15(&msg), 0x059E);
    }

    #[test]
    fn arbitration_by_identifier_and_bit_timing() {
        let mut bus = VirtualBus::new(0, 7);
        bus.record();
        // Three drives answer at once; the lowest id goes first, each after the other.
        for id in [0x283u16, 0x181, 0x182] {
            bus.send_from_drive(&CanFrame::data_frame(id, &[0; 6]).unwrap());
        }
        let order: Vec<u16> = (0..3)
            .flat_map(|_| {
                bus.set_time(bus.now_us + 1_000);
                let mut ids = Vec::new();
                while let Some(f) = bus.try_receive() {
                    ids.push(f.cob_id());
                }
                ids
            })
            .collect();
        assert_eq!(order, vec![0x181, 0x182, 0x283]);
        assert_eq!(bus.stats.frames, 3);
        // About 3 x 105 bits: the last ends 0.3 ms after the first started.
        let bits = bus.stats.bits;
        assert!((3 * 95..3 * 120).contains(&bits), "{bits}");
    }

    #[test]
    fn latency_loss_and_bus_off() {
        let mut bus = VirtualBus::new(0, 7);
        bus.faults.latency_us = 100;
        let f = CanFrame::data_frame(0x181, &[1]).unwrap();
        bus.send_from_drive(&f);
        bus.set_time(100);
        assert_eq!(bus.try_receive(), None, "67 bits + 100 us");
        bus.set_time(200);
        assert_eq!(bus.try_receive(), Some(f));

        bus.faults.loss_probability = 0.5;
        for k in 0..1000 {
            bus.set_time(1_000 + 100 * k);
            bus.try_send(&f).unwrap();
        }
        bus.set_time(200_000);
        assert!((400..600).contains(&bus.stats.lost), "{}", bus.stats.lost);

        bus.faults.bus_off = true;
        assert_eq!(bus.try_send(&f), Err(CanTxError::BusOff));
    }

    #[test]
    fn burst_loss_keeps_its_rate_in_longer_runs() {
        let mut bus = VirtualBus::new(0, 9);
        bus.faults.loss_probability = 0.05;
        bus.faults.loss_burst_frames = 4.0;
        let f = CanFrame::data_frame(0x181, &[1; 8]).unwrap();
        let mut longest = 0;
        let mut run = 0;
        for k in 0..20_000u64 {
            bus.set_time(k * 1_000);
            let before = bus.stats.lost;
            bus.try_send(&f).unwrap();
            bus.set_time(k * 1_000 + 500);
            if bus.stats.lost > before {
                run += 1;
                longest = longest.max(run);
            } else {
                run = 0;
            }
        }
        let rate = bus.stats.lost as f64 / bus.stats.frames as f64;
        assert!((0.04..0.06).contains(&rate), "{rate}");
        assert!(longest >= 6, "bursts: longest {longest}");
    }

    #[test]
    fn error_frames_delay_and_retry() {
        let mut bus = VirtualBus::new(0, 3);
        bus.record();
        bus.faults.error_probability = 0.5;
        let f = CanFrame::data_frame(0x181, &[1; 8]).unwrap();
        for k in 0..100u64 {
            bus.set_time(k * 1_000);
            bus.send_from_drive(&f);
        }
        bus.set_time(200_000);
        let mut got = 0;
        while bus.try_receive().is_some() {
            got += 1;
        }
        assert_eq!(got, 100, "every frame arrives, retried");
        assert!(bus.stats.error_frames > 50, "{}", bus.stats.error_frames);
        let log = bus.log.as_ref().unwrap();
        assert_eq!(
            log.iter().filter(|e| e.error_frame).count() as u64,
            bus.stats.error_frames
        );
    }

    #[test]
    fn sustained_transmit_errors_drive_the_controller_bus_off_and_it_recovers() {
        let mut bus = VirtualBus::new(0, 3);
        bus.faults.error_probability = 1.0;
        let f = CanFrame::data_frame(0x080, &[]).unwrap();
        bus.try_send(&f).unwrap();
        bus.set_time(2_000);
        // 32 destroyed attempts: TEC 256 > 255, bus-off; the recovery runs by itself.
        assert_eq!(bus.stats.error_frames, 32);
        assert!(bus.is_bus_off());
        assert_eq!(bus.stats.bus_off_events, 1);
        bus.faults.error_probability = 0.0;
        bus.set_time(4_000);
        assert!(!bus.is_bus_off());
        assert_eq!(bus.error_counters(), (0, 0));
        assert_eq!(bus.stats.bus_off_recoveries, 1);
    }

    #[test]
    fn bus_off_recovers_after_128_times_11_recessive_bits() {
        let mut bus = VirtualBus::new(0, 7);
        bus.faults.bus_off = true;
        bus.set_time(1_000);
        assert!(bus.is_bus_off());
        bus.faults.bus_off = false;
        bus.set_time(50_000);
        assert!(
            bus.is_bus_off(),
            "recovery starts when the disturbance ends"
        );
        bus.set_time(50_000 + BUS_OFF_RECOVERY_US - 1);
        assert!(bus.is_bus_off());
        bus.set_time(50_000 + BUS_OFF_RECOVERY_US);
        assert!(!bus.is_bus_off());
        assert_eq!(BUS_OFF_RECOVERY_US, 1_408);
        assert_eq!(
            (bus.stats.bus_off_events, bus.stats.bus_off_recoveries),
            (1, 1)
        );
        let f = CanFrame::data_frame(0x181, &[1]).unwrap();
        assert_eq!(bus.try_send(&f), Ok(()));
    }
}
