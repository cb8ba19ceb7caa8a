//! Hardware traits of the controller core: CAN buses, IMU, RC receiver, clock.
//!
//! The firmware implements them on the STM32H743 peripherals (FDCAN, SPI IMU, UART) and
//! `hal-mock` on the host. All calls are non-blocking: the core polls them from one
//! synchronous loop and never waits.

use crate::can_frame::CanFrame;

/// Why a CAN transmission was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum CanTxError {
    /// The transmit queue is full; the frame was not sent.
    QueueFull,
    /// The controller is bus-off (too many errors); nothing is sent until it recovers.
    BusOff,
}

/// One CAN bus as seen by the controller.
pub trait CanBus {
    /// Queues a frame for transmission.
    fn try_send(&mut self, frame: &CanFrame) -> Result<(), CanTxError>;
    /// The next received frame, if any.
    fn try_receive(&mut self) -> Option<CanFrame>;
    /// True while the controller is bus-off.
    fn is_bus_off(&self) -> bool;
}

/// One IMU sample in the IMU's (= the base's) frame.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ImuSample {
    /// Angular velocity, rad/s.
    pub gyro_rad_s: [f32; 3],
    /// Specific force (what an accelerometer reads: +g upward at rest), m/s^2.
    pub accel_m_s2: [f32; 3],
    /// When the sample was taken, microseconds on the controller clock.
    pub timestamp_us: u64,
}

/// An inertial measurement unit.
pub trait Imu {
    /// The newest sample since the last call, if a new one is available.
    fn read(&mut self) -> Option<ImuSample>;
}

/// The RC receiver's serial link (CRSF bytes).
pub trait RcInput {
    /// Copies received bytes into `buf`; returns how many were written (0 when idle).
    fn read(&mut self, buf: &mut [u8]) -> usize;
}

/// A monotonic microsecond clock.
pub trait Clock {
    /// Microseconds since an arbitrary start; never decreases.
    fn now_us(&self) -> u64;
}
