//! The two CAN buses: FDCAN setup (bit timing, in-order transmission, acceptance filters,
//! buffered reception), the adapter from embassy's buffered driver to hexapod-core's
//! synchronous `CanBus`, and a task per bus that watches its health.
//!
//! Reception runs in the FDCAN interrupt: the handler moves every frame from the 3-deep
//! hardware FIFOs into a 64-deep queue, so the 18 feedback frames after a SYNC survive a
//! control step that keeps the CPU for a few milliseconds. The control loop drains the
//! queue with non-blocking reads; transmission queues frames the interrupt feeds to the
//! controller's TX FIFO in order (SYNC first, then the RPDOs).
//!
//! Lost frames are counted where they can be seen: a drain that finds the software queue
//! full (the handler may have dropped frames), and the controller's "RX FIFO message lost"
//! flags (the handler did not run in time).

use core::num::{NonZeroU16, NonZeroU8};
use core::sync::atomic::{AtomicU32, Ordering::Relaxed};

use defmt::{info, warn};
use embassy_stm32::can::config::{GlobalFilter, NominalBitTiming, TxBufferMode};
use embassy_stm32::can::enums::BusErrorMode;
use embassy_stm32::can::filter::{Action, FilterType, StandardFilter, StandardFilterSlot};
use embassy_stm32::can::{
    self, BufferedCan, BufferedCanReceiver, BufferedCanSender, CanConfigurator, RxBuf, TxBuf,
};
use embassy_stm32::pac;
use embassy_time::{Duration, Ticker};
use embedded_can::StandardId;
use hexapod_core::can_frame::CanFrame;
use hexapod_core::canopen::cob;
use hexapod_core::canopen::master::NUM_BUSES;
use hexapod_core::hal::{CanBus, CanTxError};
use hexapod_core::robot::{can_bus, can_node_id, NUM_JOINTS};
use static_cell::{ConstStaticCell, StaticCell};

use crate::board;

/// Received frames the interrupt handler can hold (more than 3 ms of a fully loaded bus).
pub const RX_QUEUE_LEN: usize = 64;
/// Frames waiting for the controller's transmit FIFO.
pub const TX_QUEUE_LEN: usize = 32;
/// How often the health task samples the error counters.
const MONITOR_PERIOD: Duration = Duration::from_millis(10);

/// A started, buffered FDCAN instance.
pub type Fdcan = BufferedCan<'static, TX_QUEUE_LEN, RX_QUEUE_LEN>;

static TX_QUEUES: [ConstStaticCell<TxBuf<TX_QUEUE_LEN>>; NUM_BUSES] =
    [const { ConstStaticCell::new(TxBuf::new()) }; NUM_BUSES];
static RX_QUEUES: [ConstStaticCell<RxBuf<RX_QUEUE_LEN>>; NUM_BUSES] =
    [const { ConstStaticCell::new(RxBuf::new()) }; NUM_BUSES];
static DRIVERS: [StaticCell<Fdcan>; NUM_BUSES] = [const { StaticCell::new() }; NUM_BUSES];

/// Counters of one bus (wrapping 32-bit), shared by the control loop, which moves the
/// frames, and the health task.
pub struct BusHealth {
    /// Frames handed to the controller core.
    pub rx_frames: AtomicU32,
    /// Frames queued for transmission.
    pub tx_frames: AtomicU32,
    /// Drains that found the receive queue full: frames may have been dropped.
    pub rx_queue_full: AtomicU32,
    /// Hardware receive FIFO overflows: frames lost before the interrupt handler ran.
    pub rx_fifo_lost: AtomicU32,
    /// Transmissions refused because the transmit queue was full (the core retries).
    pub tx_queue_full: AtomicU32,
    /// Protocol errors that raised the controller's error counters (stuff, form, ack,
    /// bit, CRC), from the error logging counter.
    pub protocol_errors: AtomicU32,
    /// Times the controller entered bus-off.
    pub bus_off_events: AtomicU32,
    /// Frames the core cannot use (extended ids) or error reports, dropped.
    pub discarded: AtomicU32,
}

impl BusHealth {
    const fn new() -> Self {
        Self {
            rx_frames: AtomicU32::new(0),
            tx_frames: AtomicU32::new(0),
            rx_queue_full: AtomicU32::new(0),
            rx_fifo_lost: AtomicU32::new(0),
            tx_queue_full: AtomicU32::new(0),
            protocol_errors: AtomicU32::new(0),
            bus_off_events: AtomicU32::new(0),
            discarded: AtomicU32::new(0),
        }
    }

    /// The counters now.
    pub fn snapshot(&self) -> HealthSnapshot {
        HealthSnapshot {
            rx_frames: self.rx_frames.load(Relaxed),
            tx_frames: self.tx_frames.load(Relaxed),
            rx_queue_full: self.rx_queue_full.load(Relaxed),
            rx_fifo_lost: self.rx_fifo_lost.load(Relaxed),
            tx_queue_full: self.tx_queue_full.load(Relaxed),
            protocol_errors: self.protocol_errors.load(Relaxed),
            bus_off_events: self.bus_off_events.load(Relaxed),
            discarded: self.discarded.load(Relaxed),
        }
    }
}

/// A copy of [`BusHealth`] for the log.
#[derive(Clone, Copy, Debug, defmt::Format)]
pub struct HealthSnapshot {
    /// See [`BusHealth::rx_frames`].
    pub rx_frames: u32,
    /// See [`BusHealth::tx_frames`].
    pub tx_frames: u32,
    /// See [`BusHealth::rx_queue_full`].
    pub rx_queue_full: u32,
    /// See [`BusHealth::rx_fifo_lost`].
    pub rx_fifo_lost: u32,
    /// See [`BusHealth::tx_queue_full`].
    pub tx_queue_full: u32,
    /// See [`BusHealth::protocol_errors`].
    pub protocol_errors: u32,
    /// See [`BusHealth::bus_off_events`].
    pub bus_off_events: u32,
    /// See [`BusHealth::discarded`].
    pub discarded: u32,
}

/// The counters of bus 0 (right legs) and bus 1 (left legs).
pub static HEALTH: [BusHealth; NUM_BUSES] = [const { BusHealth::new() }; NUM_BUSES];

fn bump(counter: &AtomicU32, by: u32) {
    counter.fetch_add(by, Relaxed);
}

/// The first and last node id on `bus`, and how many drives it carries.
const fn node_span(bus: usize) -> (u8, u8, usize) {
    let (mut first, mut last, mut count) = (u8::MAX, 0, 0);
    let mut joint = 0;
    while joint < NUM_JOINTS {
        if can_bus(joint) == bus {
            let id = can_node_id(joint);
            if id < first {
                first = id;
            }
            if id > last {
                last = id;
            }
            count += 1;
        }
        joint += 1;
    }
    (first, last, count)
}

/// True when the drives on `bus` have consecutive node ids, so one id range per function
/// code accepts exactly them.
const fn consecutive_ids(bus: usize) -> bool {
    let (first, last, count) = node_span(bus);
    count > 0 && (last - first) as usize + 1 == count
}
const _: () = assert!(consecutive_ids(0) && consecutive_ids(1));

/// The first and last node id on `bus`.
const fn node_range(bus: usize) -> (u8, u8) {
    let (first, last, _) = node_span(bus);
    (first, last)
}

/// Accepts `base + first ..= base + last` into `action`'s FIFO.
fn range_filter(base: u16, (first, last): (u8, u8), action: Action) -> StandardFilter {
    let id = |node: u8| StandardId::new(base + node as u16).expect("CANopen ids fit 11 bits");
    StandardFilter {
        filter: FilterType::Range {
            from: id(first),
            to: id(last),
        },
        action,
    }
}

/// Bit timing, in-order transmission and acceptance filters for bus `bus`: the drives'
/// TPDO1/TPDO2 feedback into FIFO 0; their EMCY, SDO responses and heartbeats into
/// FIFO 1, so a feedback burst never delays an emergency. Everything else is rejected.
pub fn configure(can: &mut CanConfigurator<'static>, bus: usize) {
    let nonzero8 = |v: u8| NonZeroU8::new(v).expect("nonzero bit timing");
    let timing = NominalBitTiming {
        prescaler: NonZeroU16::new(board::CAN_PRESCALER).expect("nonzero prescaler"),
        seg1: nonzero8(board::CAN_SEG1),
        seg2: nonzero8(board::CAN_SEG2),
        sync_jump_width: nonzero8(board::CAN_SJW),
    };
    let config = can
        .config()
        .set_nominal_bit_timing(timing)
        .set_tx_buffer_mode(TxBufferMode::Fifo)
        .set_automatic_retransmit(true)
        .set_automatic_bus_off_recovery(true)
        .set_global_filter(GlobalFilter::reject_all());
    can.set_config(config);

    let nodes = node_range(bus);
    let filters = [
        (cob::TPDO_BASE[0], Action::StoreInFifo0),
        (cob::TPDO_BASE[1], Action::StoreInFifo0),
        (cob::EMCY_BASE, Action::StoreInFifo1),
        (cob::SDO_TX_BASE, Action::StoreInFifo1),
        (cob::HEARTBEAT_BASE, Action::StoreInFifo1),
    ];
    let slots = [
        StandardFilterSlot::_0,
        StandardFilterSlot::_1,
        StandardFilterSlot::_2,
        StandardFilterSlot::_3,
        StandardFilterSlot::_4,
    ];
    for (slot, (base, action)) in slots.into_iter().zip(filters) {
        can.properties()
            .set_standard_filter(slot, range_filter(base, nodes, action));
    }
}

/// Starts bus `bus` in normal mode with its queues. Call once per bus at boot.
pub fn start(can: CanConfigurator<'static>, bus: usize) -> &'static Fdcan {
    let tx = TX_QUEUES[bus].take();
    let rx = RX_QUEUES[bus].take();
    DRIVERS[bus].init(can.into_normal_mode().buffered(tx, rx))
}

/// One bus as hexapod-core's [`CanBus`].
pub struct FdcanBus {
    driver: &'static Fdcan,
    rx: BufferedCanReceiver,
    tx: BufferedCanSender,
    health: &'static BusHealth,
    drained: usize,
}

impl FdcanBus {
    /// The adapter of bus `bus` over its started driver.
    pub fn new(driver: &'static Fdcan, bus: usize) -> Self {
        Self {
            driver,
            rx: driver.reader(),
            tx: driver.writer(),
            health: &HEALTH[bus],
            drained: 0,
        }
    }
}

impl CanBus for FdcanBus {
    fn try_send(&mut self, frame: &CanFrame) -> Result<(), CanTxError> {
        if self.is_bus_off() {
            return Err(CanTxError::BusOff);
        }
        let id = StandardId::new(frame.cob_id()).unwrap_or(StandardId::ZERO);
        let out = if frame.is_rtr() {
            <can::Frame as embedded_can::Frame>::new_remote(id, embedded_can::Frame::dlc(frame))
        } else {
            <can::Frame as embedded_can::Frame>::new(id, frame.payload())
        };
        let Some(out) = out else {
            // Unreachable: a CanFrame always has an 11-bit id and at most 8 bytes.
            bump(&self.health.discarded, 1);
            return Ok(());
        };
        match self.tx.try_write(out) {
            Ok(()) => {
                bump(&self.health.tx_frames, 1);
                Ok(())
            }
            Err(_) => {
                bump(&self.health.tx_queue_full, 1);
                Err(CanTxError::QueueFull)
            }
        }
    }

    fn try_receive(&mut self) -> Option<CanFrame> {
        loop {
            let Ok(received) = self.rx.try_receive() else {
                self.drained = 0;
                return None;
            };
            self.drained += 1;
            if self.drained == RX_QUEUE_LEN {
                bump(&self.health.rx_queue_full, 1);
            }
            match received.ok().and_then(|e| CanFrame::from_frame(&e.frame)) {
                Some(frame) => {
                    bump(&self.health.rx_frames, 1);
                    return Some(frame);
                }
                None => bump(&self.health.discarded, 1),
            }
        }
    }

    fn is_bus_off(&self) -> bool {
        matches!(
            self.driver.properties().bus_error_mode(),
            BusErrorMode::BusOff
        )
    }
}

/// Error state from the error counters, for the log (0 active, 1 passive, 2 bus-off).
fn error_state(regs: pac::can::Fdcan) -> u8 {
    let psr = regs.psr().read();
    match (psr.bo(), psr.ep()) {
        (true, _) => 2,
        (false, true) => 1,
        (false, false) => 0,
    }
}

/// Watches bus `bus`: counts protocol errors (the controller's error logging counter,
/// cleared on read) and hardware FIFO overflows, and logs error-state changes.
#[embassy_executor::task(pool_size = 2)]
pub async fn monitor(bus: usize, regs: pac::can::Fdcan) {
    let health = &HEALTH[bus];
    let mut state = 0;
    let mut ticker = Ticker::every(MONITOR_PERIOD);
    info!(
        "CAN{}: nodes {}..={}",
        bus,
        node_range(bus).0,
        node_range(bus).1
    );
    loop {
        ticker.next().await;
        let ecr = regs.ecr().read();
        bump(&health.protocol_errors, ecr.cel() as u32);
        let ir = regs.ir().read();
        for fifo in 0..2 {
            if ir.rfl(fifo) {
                bump(&health.rx_fifo_lost, 1);
            }
        }
        regs.ir().write(|w| {
            w.set_rfl(0, ir.rfl(0));
            w.set_rfl(1, ir.rfl(1));
        });
        let now = error_state(regs);
        if now != state {
            if now == 2 {
                bump(&health.bus_off_events, 1);
            }
            warn!(
                "CAN{}: error state {} -> {} (0 active, 1 passive, 2 bus-off), TEC {} REC {}",
                bus,
                state,
                now,
                ecr.tec(),
                ecr.rec()
            );
            state = now;
        }
    }
}
