//! The IMU: an ICM-42688-P on SPI1 read through the `icm426xx` driver (FIFO mode, 1 kHz,
//! 20-bit samples, INT1 on every new sample), rotated into the base frame, time-stamped
//! and queued for the control loop as hexapod-core [`ImuSample`]s.
//!
//! Time stamps: a burst read after INT1 (several samples when the control step kept the
//! CPU) gets the read time on its newest sample and the IMU's own ODR deltas backwards
//! from there ([`crate::imu_stamp`]), so the attitude filter integrates with the true
//! sample spacing.

use core::sync::atomic::{AtomicU32, Ordering::Relaxed};

use defmt::{info, warn};
use embassy_stm32::exti::ExtiInput;
use embassy_stm32::gpio::Output;
use embassy_stm32::mode::Async;
use embassy_stm32::spi::{mode::Master, Spi};
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::channel::Channel;
use embassy_time::{with_timeout, Delay, Duration, Instant, Timer};
use embedded_hal_bus::spi::ExclusiveDevice;
use hexapod_core::hal::{Imu, ImuSample};
use icm426xx::{OutputDataRate, Sample, Timestamp, ICM42688};

use crate::board::IMU_TO_BASE;
use crate::imu_stamp::{odr_delta_us, stamp_burst};

/// The IMU's SPI device: SPI1 with DMA and its chip select.
pub type ImuSpi = ExclusiveDevice<Spi<'static, Async, Master>, Output<'static>, Delay>;

/// Output data rate of gyro and accelerometer.
const RATE: OutputDataRate = OutputDataRate::Hz1000;
/// Sample period at [`RATE`], microseconds.
const PERIOD_US: u64 = 1_000;
/// FIFO time stamp resolution as the driver configures it (TMST_RES = 1), microseconds.
const TIMESTAMP_LSB_US: u64 = 16;
/// Poll the FIFO anyway when INT1 stays quiet this long.
const INT_TIMEOUT: Duration = Duration::from_millis(10);
/// Consecutive SPI errors before the IMU is reset and initialized again.
const MAX_CONSECUTIVE_ERRORS: u32 = 10;
/// Samples read in one burst at most (the rest waits for the next burst).
const MAX_BURST: usize = 32;
/// Samples waiting for the control loop (32 ms at 1 kHz).
pub const SAMPLE_QUEUE_LEN: usize = 32;

static SAMPLES: Channel<CriticalSectionRawMutex, ImuSample, SAMPLE_QUEUE_LEN> = Channel::new();

/// IMU counters.
pub struct ImuStats {
    /// Samples queued.
    pub samples: AtomicU32,
    /// Samples dropped because the queue was full.
    pub dropped: AtomicU32,
    /// FIFO packets without gyro or accelerometer data.
    pub incomplete: AtomicU32,
    /// SPI transfer errors.
    pub bus_errors: AtomicU32,
    /// FIFO overflows (the IMU was not read in time; the FIFO is flushed).
    pub fifo_overflows: AtomicU32,
    /// INT1 timeouts (the FIFO was polled instead).
    pub int_timeouts: AtomicU32,
    /// Initializations (the first one included).
    pub inits: AtomicU32,
}

/// The IMU's counters.
pub static STATS: ImuStats = ImuStats {
    samples: AtomicU32::new(0),
    dropped: AtomicU32::new(0),
    incomplete: AtomicU32::new(0),
    bus_errors: AtomicU32::new(0),
    fifo_overflows: AtomicU32::new(0),
    int_timeouts: AtomicU32::new(0),
    inits: AtomicU32::new(0),
};

/// A copy of [`ImuStats`] for the log.
#[derive(Clone, Copy, Debug, defmt::Format)]
pub struct ImuSnapshot {
    /// See [`ImuStats::samples`].
    pub samples: u32,
    /// See [`ImuStats::dropped`].
    pub dropped: u32,
    /// See [`ImuStats::incomplete`].
    pub incomplete: u32,
    /// See [`ImuStats::bus_errors`].
    pub bus_errors: u32,
    /// See [`ImuStats::fifo_overflows`].
    pub fifo_overflows: u32,
    /// See [`ImuStats::int_timeouts`].
    pub int_timeouts: u32,
    /// See [`ImuStats::inits`].
    pub inits: u32,
}

impl ImuStats {
    /// The counters now.
    pub fn snapshot(&self) -> ImuSnapshot {
        ImuSnapshot {
            samples: self.samples.load(Relaxed),
            dropped: self.dropped.load(Relaxed),
            incomplete: self.incomplete.load(Relaxed),
            bus_errors: self.bus_errors.load(Relaxed),
            fifo_overflows: self.fifo_overflows.load(Relaxed),
            int_timeouts: self.int_timeouts.load(Relaxed),
            inits: self.inits.load(Relaxed),
        }
    }
}

fn bump(counter: &AtomicU32) {
    counter.fetch_add(1, Relaxed);
}

/// The control loop's end of the sample queue, as hexapod-core's [`Imu`].
pub struct ImuQueue;

impl Imu for ImuQueue {
    fn read(&mut self) -> Option<ImuSample> {
        SAMPLES.try_receive().ok()
    }
}

/// `IMU_TO_BASE * v`.
fn to_base((x, y, z): (f32, f32, f32)) -> [f32; 3] {
    IMU_TO_BASE.map(|row| row[0] * x + row[1] * y + row[2] * z)
}

/// The packet's time since the previous sample, microseconds.
fn delta_us(sample: &Sample) -> u64 {
    let ticks = match sample.timestamp {
        Timestamp::OdrTimestamp(ticks) => Some(ticks),
        _ => None,
    };
    odr_delta_us(ticks, TIMESTAMP_LSB_US, PERIOD_US)
}

/// Stamps a burst (oldest first) whose newest sample was read at `read_us` and queues it.
fn queue_burst(burst: &[Sample], read_us: u64, last_us: &mut u64) {
    let mut deltas_us = [0; MAX_BURST];
    for (delta, sample) in deltas_us.iter_mut().zip(burst) {
        *delta = delta_us(sample);
    }
    let mut stamps_us = [0; MAX_BURST];
    let n = burst.len().min(MAX_BURST);
    stamp_burst(&deltas_us[..n], read_us, last_us, &mut stamps_us);
    for (sample, &timestamp_us) in burst.iter().zip(&stamps_us[..n]) {
        let (Some(gyro), Some(accel)) = (sample.gyro, sample.accel) else {
            bump(&STATS.incomplete);
            continue;
        };
        let out = ImuSample {
            gyro_rad_s: to_base(gyro),
            accel_m_s2: to_base(accel),
            timestamp_us,
        };
        match SAMPLES.try_send(out) {
            Ok(()) => bump(&STATS.samples),
            Err(_) => bump(&STATS.dropped),
        }
    }
}

/// Why a burst read stopped.
enum ReadError {
    /// SPI transfer failed.
    Bus,
    /// The IMU's FIFO overflowed.
    Overflow,
}

/// Reads samples until the FIFO is empty or `burst` is full.
async fn read_burst(
    icm: &mut ICM42688<&mut ImuSpi, icm426xx::Ready>,
    burst: &mut heapless::Vec<Sample, MAX_BURST>,
) -> Result<(), ReadError> {
    while !burst.is_full() {
        match icm.read_sample().await {
            Ok(Some((sample, more))) => {
                // Cannot fail: the loop checks for room.
                let _ = burst.push(sample);
                if !more {
                    break;
                }
            }
            Ok(None) => break,
            Err(icm426xx::Error::FifoOverflow) => return Err(ReadError::Overflow),
            Err(_) => return Err(ReadError::Bus),
        }
    }
    Ok(())
}

/// Initializes the IMU (again after repeated errors) and queues its samples.
#[embassy_executor::task]
pub async fn imu_task(mut spi: ImuSpi, mut int1: ExtiInput<'static, Async>) {
    let mut last_us = 0;
    loop {
        bump(&STATS.inits);
        let config = icm426xx::Config {
            rate: RATE,
            ..Default::default()
        };
        let mut icm = match ICM42688::new(&mut spi).initialize(Delay, config).await {
            Ok(icm) => icm,
            Err(icm426xx::Error::WhoAmIMismatch(id)) => {
                warn!("IMU: WHO_AM_I {:#x}, expected 0x47 (ICM-42688-P)", id);
                Timer::after_millis(100).await;
                continue;
            }
            Err(_) => {
                warn!("IMU: SPI error during initialization");
                Timer::after_millis(100).await;
                continue;
            }
        };
        info!("IMU: ICM-42688-P ready, 1 kHz");
        let mut errors = 0;
        while errors < MAX_CONSECUTIVE_ERRORS {
            if with_timeout(INT_TIMEOUT, int1.wait_for_high())
                .await
                .is_err()
            {
                bump(&STATS.int_timeouts);
            }
            let mut burst = heapless::Vec::new();
            let result = read_burst(&mut icm, &mut burst).await;
            queue_burst(&burst, Instant::now().as_micros(), &mut last_us);
            match result {
                Ok(()) => errors = 0,
                Err(ReadError::Overflow) => {
                    bump(&STATS.fifo_overflows);
                    if icm.reset_fifo().await.is_err() {
                        bump(&STATS.bus_errors);
                        errors += 1;
                    }
                }
                Err(ReadError::Bus) => {
                    bump(&STATS.bus_errors);
                    errors += 1;
                }
            }
        }
        warn!("IMU: {} consecutive SPI errors, initializing again", errors);
    }
}
