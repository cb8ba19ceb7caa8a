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

/// Why the microcontroller started, as the firmware reads it at boot (the STM32H7's
/// RCC_RSR reset flags, before clearing them with RMVF) and hands it to
/// [`crate::controller::Controller::start_after_reset`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct BootInfo {
    /// RCC_RSR as read at boot (0 when unknown, e.g. on the host).
    pub reset_flags: u32,
}

/// The cause of the last reset, decoded from [`BootInfo::reset_flags`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ResetCause {
    /// The independent watchdog (IWDG1) expired: the control loop stalled.
    IndependentWatchdog,
    /// The window watchdog (WWDG1).
    WindowWatchdog,
    /// A software reset (SYSRESETREQ: the firmware's panic and HardFault handlers).
    Software,
    /// Low-power management.
    LowPower,
    /// Power on (or power dropping below the brown-out threshold).
    PowerOn,
    /// Brown-out.
    BrownOut,
    /// The NRST pin (reset button, debugger).
    Pin,
    /// No flag set (or not known).
    Unknown,
}

impl BootInfo {
    /// RCC_RSR bit: CPU reset.
    pub const CPURSTF: u32 = 1 << 17;
    /// RCC_RSR bit: brown-out reset.
    pub const BORRSTF: u32 = 1 << 21;
    /// RCC_RSR bit: NRST pin reset (set with every reset that drives the pin).
    pub const PINRSTF: u32 = 1 << 22;
    /// RCC_RSR bit: power-on reset.
    pub const PORRSTF: u32 = 1 << 23;
    /// RCC_RSR bit: system reset from the CPU (SYSRESETREQ).
    pub const SFTRSTF: u32 = 1 << 24;
    /// RCC_RSR bit: independent watchdog 1.
    pub const IWDG1RSTF: u32 = 1 << 26;
    /// RCC_RSR bit: window watchdog 1.
    pub const WWDG1RSTF: u32 = 1 << 28;
    /// RCC_RSR bit: low-power reset.
    pub const LPWRRSTF: u32 = 1 << 30;

    /// The most specific cause among the flags (a watchdog or software reset also sets
    /// the pin flag, a power-on reset also the brown-out and pin flags).
    pub fn cause(&self) -> ResetCause {
        let f = self.reset_flags;
        if f & Self::IWDG1RSTF != 0 {
            ResetCause::IndependentWatchdog
        } else if f & Self::WWDG1RSTF != 0 {
            ResetCause::WindowWatchdog
        } else if f & Self::SFTRSTF != 0 {
            ResetCause::Software
        } else if f & Self::LPWRRSTF != 0 {
            ResetCause::LowPower
        } else if f & Self::PORRSTF != 0 {
            ResetCause::PowerOn
        } else if f & Self::BORRSTF != 0 {
            ResetCause::BrownOut
        } else if f & Self::PINRSTF != 0 {
            ResetCause::Pin
        } else {
            ResetCause::Unknown
        }
    }

    /// True for a reset while the drives may have been running (not a power-up).
    pub fn warm(&self) -> bool {
        !matches!(
            self.cause(),
            ResetCause::PowerOn | ResetCause::BrownOut | ResetCause::Unknown
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reset_cause_picks_the_most_specific_flag() {
        let info = |f| BootInfo { reset_flags: f };
        // IWDG reset as the H743 reports it: IWDG1RSTF with PINRSTF and CPURSTF.
        let iwdg = BootInfo::IWDG1RSTF | BootInfo::PINRSTF | BootInfo::CPURSTF;
        assert_eq!(info(iwdg).cause(), ResetCause::IndependentWatchdog);
        assert!(info(iwdg).warm());
        let por = BootInfo::PORRSTF | BootInfo::BORRSTF | BootInfo::PINRSTF;
        assert_eq!(info(por).cause(), ResetCause::PowerOn);
        assert!(!info(por).warm());
        assert_eq!(
            info(BootInfo::SFTRSTF | BootInfo::PINRSTF).cause(),
            ResetCause::Software
        );
        assert_eq!(info(BootInfo::PINRSTF).cause(), ResetCause::Pin);
        assert_eq!(info(0).cause(), ResetCause::Unknown);
    }
}
