//! The RC link: CRSF bytes from the receiver on USART2 (420 kbaud, DMA into a ring buffer)
//! into a byte pipe that the control loop drains into hexapod-core's CRSF receiver, which
//! parses, checks CRCs and applies the failsafe.

use core::sync::atomic::{AtomicU32, Ordering::Relaxed};

use defmt::debug;
use embassy_stm32::usart::{self, RingBufferedUartRx};
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::pipe::Pipe;
use hexapod_core::hal::RcInput;
use static_cell::ConstStaticCell;

use crate::board::CRSF_BAUD;

/// DMA ring buffer: 12 ms of bytes at 420 kbaud, more than a control step keeps the CPU.
const DMA_RING_LEN: usize = 512;
/// Bytes waiting for the control loop.
const PIPE_LEN: usize = 512;

/// In `.bss`, which `memory.x` puts in AXI SRAM: reachable by DMA1 (DTCM is not).
static DMA_RING: ConstStaticCell<[u8; DMA_RING_LEN]> = ConstStaticCell::new([0; DMA_RING_LEN]);
static BYTES: Pipe<CriticalSectionRawMutex, PIPE_LEN> = Pipe::new();

/// RC link counters.
pub struct RcStats {
    /// Bytes received.
    pub bytes: AtomicU32,
    /// Bytes dropped because the pipe was full.
    pub dropped: AtomicU32,
    /// UART errors (overrun, framing, noise, parity); reception restarts after each.
    pub uart_errors: AtomicU32,
}

/// The link's counters.
pub static STATS: RcStats = RcStats {
    bytes: AtomicU32::new(0),
    dropped: AtomicU32::new(0),
    uart_errors: AtomicU32::new(0),
};

/// A copy of [`RcStats`] for the log.
#[derive(Clone, Copy, Debug, defmt::Format)]
pub struct RcSnapshot {
    /// See [`RcStats::bytes`].
    pub bytes: u32,
    /// See [`RcStats::dropped`].
    pub dropped: u32,
    /// See [`RcStats::uart_errors`].
    pub uart_errors: u32,
}

impl RcStats {
    /// The counters now.
    pub fn snapshot(&self) -> RcSnapshot {
        RcSnapshot {
            bytes: self.bytes.load(Relaxed),
            dropped: self.dropped.load(Relaxed),
            uart_errors: self.uart_errors.load(Relaxed),
        }
    }
}

/// The CRSF UART settings: 420 kbaud, 8N1.
pub fn uart_config() -> usart::Config {
    let mut config = usart::Config::default();
    config.baudrate = CRSF_BAUD;
    config.data_bits = usart::DataBits::DataBits8;
    config.stop_bits = usart::StopBits::STOP1;
    config.parity = usart::Parity::ParityNone;
    config
}

/// The DMA ring buffer (call once, at boot).
pub fn dma_ring() -> &'static mut [u8] {
    DMA_RING.take()
}

/// The control loop's end of the pipe, as hexapod-core's [`RcInput`].
pub struct RcBytes;

impl RcInput for RcBytes {
    fn read(&mut self, buf: &mut [u8]) -> usize {
        BYTES.try_read(buf).unwrap_or(0)
    }
}

/// Moves received bytes into the pipe.
#[embassy_executor::task]
pub async fn rc_task(mut uart: RingBufferedUartRx<'static>) {
    let mut buf = [0u8; 64];
    loop {
        match uart.read(&mut buf).await {
            Ok(n) => {
                STATS.bytes.fetch_add(n as u32, Relaxed);
                let written = BYTES.try_write(&buf[..n]).unwrap_or(0);
                STATS.dropped.fetch_add((n - written) as u32, Relaxed);
            }
            Err(e) => {
                STATS.uart_errors.fetch_add(1, Relaxed);
                debug!("CRSF UART: {}", e);
            }
        }
    }
}
