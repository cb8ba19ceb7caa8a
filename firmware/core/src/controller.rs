//! The controller: one synchronous state machine that the firmware's tasks and the host
//! software-in-the-loop both drive, with time passed in.
//!
//! Per 20 ms control cycle:
//! 1. [`Controller::begin_cycle`]: SYNC on both buses (the drives sample and answer);
//! 2. [`Controller::service_bus`], [`Controller::service_imu`], [`Controller::service_rc`]
//!    move frames and samples between the hardware traits and the core, any number of
//!    times; [`Controller::feedback_ready`] tells when all TPDOs are in (or the feedback
//!    deadline passed);
//! 3. [`Controller::finish_cycle`]: supervisor, observation, policy, clamps, RPDOs.
//!
//! A cycle that finishes late or starts late counts as a deadline overrun (a fault).
//!
//! How a firmware task (or the host harness, `hal_mock::harness`) drives it:
//!
//! ```text
//! controller.start(clock.now_us());
//! loop every 20 ms:
//!     controller.begin_cycle(now);                       // SYNC
//!     until controller.feedback_ready(now):              // TPDOs, <= 6 ms
//!         controller.service_bus(0, &mut fdcan1, now);
//!         controller.service_bus(1, &mut fdcan2, now);
//!         controller.service_imu(&mut imu);
//!         controller.service_rc(&mut crsf_uart, now);
//!     controller.finish_cycle(now, &mut policy);         // supervisor, policy, RPDOs
//!     controller.service_bus(0, ..); controller.service_bus(1, ..);  // send them
//! ```
//!
//! `service_bus` must run at least every few milliseconds between cycles too: it carries
//! the SDO configuration and the master's heartbeat, which the drives supervise.

use crate::attitude::{AttitudeConfig, AttitudeFilter};
use crate::can_frame::CanFrame;
use crate::canopen::master::{Master, NUM_BUSES};
use crate::control::{ControlStep, Policy, Sensors};
use crate::hal::{BootInfo, CanBus, CanTxError, Imu, ImuSample, RcInput};
use crate::rc::receiver::{RcConfig, RcReceiver, RcState};
use crate::robot::NUM_JOINTS;
use crate::supervisor::{Command, Inputs, Mode, Supervisor, SupervisorConfig};
use crate::timing::POLICY_DT_S;

/// Controller parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ControllerConfig {
    /// Supervisor timing and limits.
    pub supervisor: SupervisorConfig,
    /// RC mapping and failsafe.
    pub rc: RcConfig,
    /// Attitude filter gains.
    pub attitude: AttitudeConfig,
    /// The IMU is stale when its newest sample is older than this, microseconds.
    pub imu_timeout_us: u64,
    /// How long after SYNC the control step waits for feedback, microseconds.
    pub feedback_deadline_us: u64,
    /// A cycle must finish within this time after its SYNC, microseconds.
    pub cycle_deadline_us: u64,
}

impl Default for ControllerConfig {
    fn default() -> Self {
        Self {
            supervisor: SupervisorConfig::default(),
            rc: RcConfig::default(),
            attitude: AttitudeConfig::default(),
            imu_timeout_us: 50_000,
            feedback_deadline_us: 6_000,
            cycle_deadline_us: 15_000,
        }
    }
}

/// Counters of the control loop.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct LoopStats {
    /// Cycles run.
    pub cycles: u32,
    /// Cycles that missed their deadline.
    pub overruns: u32,
    /// Cycles that ran without complete feedback.
    pub incomplete_feedback: u32,
    /// Worst time from SYNC to RPDOs, microseconds.
    pub worst_cycle_us: u32,
}

/// The controller core.
pub struct Controller {
    config: ControllerConfig,
    /// The CANopen master.
    pub master: Master,
    supervisor: Supervisor,
    control: ControlStep,
    attitude: AttitudeFilter,
    rc: RcReceiver,
    last_imu: Option<ImuSample>,
    cycle_start_us: Option<u64>,
    overrun: bool,
    was_walking: bool,
    boot: BootInfo,
    /// Loop counters.
    pub stats: LoopStats,
}

impl Controller {
    /// A controller in `Boot`.
    pub fn new(config: ControllerConfig) -> Self {
        Self {
            config,
            master: Master::new(),
            supervisor: Supervisor::new(config.supervisor),
            control: ControlStep::new(),
            attitude: AttitudeFilter::new(config.attitude),
            rc: RcReceiver::new(config.rc),
            last_imu: None,
            cycle_start_us: None,
            overrun: false,
            was_walking: false,
            boot: BootInfo { reset_flags: 0 },
            stats: LoopStats::default(),
        }
    }

    /// Starts the drives (state probe, NMT reset, configuration) and leaves `Boot`.
    pub fn start(&mut self, now_us: u64) {
        self.master.start(now_us);
        self.supervisor.start();
    }

    /// [`Controller::start`] after a reset of the microcontroller, with what it reports
    /// about the reset (kept for the logs: [`Controller::boot_info`]). The drives' state is
    /// learnt before anything is commanded either way: a drive holding the body is adopted
    /// whatever the flags say.
    pub fn start_after_reset(&mut self, now_us: u64, boot: BootInfo) {
        self.boot = boot;
        self.start(now_us);
    }

    /// What the microcontroller reported about its last reset.
    pub fn boot_info(&self) -> BootInfo {
        self.boot
    }

    /// The supervisor's mode.
    pub fn mode(&self) -> Mode {
        self.supervisor.mode()
    }

    /// The operator's request as the receiver sees it now.
    pub fn rc_state(&self, now_us: u64) -> RcState {
        self.rc.state(now_us)
    }

    /// The attitude filter.
    pub fn attitude(&self) -> &AttitudeFilter {
        &self.attitude
    }

    /// The RC receiver (its parser carries the CRSF error counters).
    pub fn rc_receiver(&self) -> &RcReceiver {
        &self.rc
    }

    /// Handles one received CAN frame.
    pub fn on_can_frame(&mut self, bus: usize, frame: &CanFrame, now_us: u64) {
        self.master.on_frame(bus, frame, now_us);
    }

    /// Handles one IMU sample.
    pub fn on_imu(&mut self, sample: ImuSample) {
        let dt_s = match self.last_imu {
            Some(prev) if sample.timestamp_us > prev.timestamp_us => {
                (sample.timestamp_us - prev.timestamp_us) as f32 * 1e-6
            }
            Some(_) => return,
            None => 0.0,
        };
        self.attitude
            .update(sample.gyro_rad_s, sample.accel_m_s2, dt_s.min(0.1));
        self.last_imu = Some(sample);
    }

    /// Handles received RC bytes.
    pub fn on_rc_bytes(&mut self, bytes: &[u8], now_us: u64) {
        self.rc.feed(bytes, now_us);
    }

    /// Moves frames between bus `bus` and the master; runs the master's timers.
    pub fn service_bus<B: CanBus>(&mut self, bus_index: usize, bus: &mut B, now_us: u64) {
        if bus_index >= NUM_BUSES {
            return;
        }
        self.master.set_bus_off(bus_index, bus.is_bus_off(), now_us);
        while let Some(frame) = bus.try_receive() {
            self.master.on_frame(bus_index, &frame, now_us);
        }
        self.master.poll(now_us);
        while let Some(frame) = self.master.pop_tx(bus_index) {
            match bus.try_send(&frame) {
                Ok(()) => {}
                Err(CanTxError::QueueFull) => {
                    self.master.unpop_tx(bus_index, frame);
                    break;
                }
                Err(CanTxError::BusOff) => break,
            }
        }
    }

    /// Reads all pending IMU samples.
    pub fn service_imu<I: Imu>(&mut self, imu: &mut I) {
        while let Some(sample) = imu.read() {
            self.on_imu(sample);
        }
    }

    /// Reads all pending RC bytes.
    pub fn service_rc<R: RcInput>(&mut self, rc: &mut R, now_us: u64) {
        let mut buf = [0u8; 64];
        loop {
            let n = rc.read(&mut buf).min(buf.len());
            if n == 0 {
                break;
            }
            self.rc.feed(&buf[..n], now_us);
        }
    }

    /// Begins a control cycle: SYNC.
    pub fn begin_cycle(&mut self, now_us: u64) {
        if let Some(prev) = self.cycle_start_us {
            let period_us = (POLICY_DT_S * 1e6) as u64;
            if now_us.saturating_sub(prev) > period_us + period_us / 2 {
                self.overrun = true;
            }
        }
        self.cycle_start_us = Some(now_us);
        self.master.sync();
    }

    /// True when the cycle can be finished: all feedback in, or its deadline passed.
    pub fn feedback_ready(&self, now_us: u64) -> bool {
        self.master.feedback_complete()
            || self
                .cycle_start_us
                .is_none_or(|t| now_us >= t.saturating_add(self.config.feedback_deadline_us))
    }

    /// Finishes the cycle: supervisor, control step, RPDOs. Returns what was commanded.
    pub fn finish_cycle<P: Policy + ?Sized>(&mut self, now_us: u64, policy: &mut P) -> Command {
        let start = self.cycle_start_us.unwrap_or(now_us);
        let cycle_us = now_us.saturating_sub(start);
        if cycle_us > self.config.cycle_deadline_us {
            self.overrun = true;
        }
        self.stats.cycles = self.stats.cycles.saturating_add(1);
        self.stats.worst_cycle_us = self.stats.worst_cycle_us.max(cycle_us as u32);
        if !self.master.feedback_complete() {
            self.stats.incomplete_feedback = self.stats.incomplete_feedback.saturating_add(1);
        }
        if self.overrun {
            self.stats.overruns = self.stats.overruns.saturating_add(1);
        }

        let feedback = self.master.feedback();
        let adopted_rad = self.master.adopted_targets_rad();
        let imu_fresh = self
            .last_imu
            .is_some_and(|s| now_us.saturating_sub(s.timestamp_us) <= self.config.imu_timeout_us)
            && self.attitude.is_initialized();
        let rc = self.rc.state(now_us);
        let inputs = Inputs {
            now_us,
            configuring: self.master.configuring(),
            drives_enabled: self.master.all_enabled(),
            drives_adopted: self.master.any_adopted(),
            adopted_rad: &adopted_rad,
            drive_fault: self.master.first_fault(),
            q_rad: &feedback.q_rad,
            imu_fresh,
            tilt_rad: if self.attitude.is_initialized() {
                self.attitude.tilt_rad()
            } else {
                0.0
            },
            rc,
            overrun: self.overrun,
        };
        self.overrun = false;

        let walking = self.supervisor.mode() == Mode::Walking;
        if walking && !self.was_walking {
            self.control.reset(self.supervisor.targets_rad());
        }
        let sensors = Sensors {
            ang_vel_base_rad_s: self.last_imu.map_or([0.0; 3], |s| s.gyro_rad_s),
            gravity_base: self.attitude.projected_gravity(),
            q_rad: feedback.q_rad,
            qdot_rad_s: feedback.qdot_rad_s,
        };
        let control = &mut self.control;
        let command = self.supervisor.step(&inputs, || {
            control.step(policy, &sensors, rc.command).map_err(|_| ())
        });
        self.was_walking = walking && self.supervisor.mode() == Mode::Walking;
        if command.clear_faults {
            self.master.clear_recoverable_faults();
        }
        self.master
            .send_commands(&command.requests, &command.targets_rad);
        command
    }
}

/// A policy that always returns the zero action (stand still at the nominal pose).
#[derive(Clone, Copy, Debug, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ZeroPolicy;

impl Policy for ZeroPolicy {
    fn act(
        &mut self,
        _command: [f32; 3],
        _prev_action: &[f32; NUM_JOINTS],
        _history: &crate::obs::ProprioHistory,
    ) -> Option<[f32; NUM_JOINTS]> {
        Some([0.0; NUM_JOINTS])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fits_in_a_few_kilobytes_of_static_ram() {
        let bytes = core::mem::size_of::<Controller>();
        println!("Controller: {bytes} bytes");
        assert!(bytes < 8 * 1024, "Controller is {bytes} bytes");
    }

    #[test]
    fn a_late_cycle_is_an_overrun() {
        let mut c = Controller::new(ControllerConfig::default());
        c.start(0);
        c.begin_cycle(0);
        c.finish_cycle(16_000, &mut ZeroPolicy);
        assert_eq!(c.stats.overruns, 1);
        c.begin_cycle(20_000);
        c.finish_cycle(22_000, &mut ZeroPolicy);
        assert_eq!(c.stats.overruns, 1);
        // The next SYNC comes 35 ms later instead of 20 ms.
        c.begin_cycle(55_000);
        c.finish_cycle(57_000, &mut ZeroPolicy);
        assert_eq!(c.stats.overruns, 2);
    }
}
