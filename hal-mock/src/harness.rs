//! A software-in-the-loop harness: the controller core, the drive rig, the IMU and RC
//! models and a joint plant, advanced together in 1 ms steps with the real frame flow.
//!
//! The physics is a closure the caller passes (`host-sim` steps its world there; tests use
//! [`crate::plant::JointModel::step`]); it runs every [`PHYSICS_DT_S`]. The base state the
//! IMU sees is [`Harness::base`], set by the caller, or by the plant at every tick when it
//! simulates the base ([`JointPlant::base_state`], as `sil-tests` does with host-sim).

use hexapod_core::control::Policy;
use hexapod_core::controller::{Controller, ControllerConfig};
use hexapod_core::hal::BootInfo;
use hexapod_core::supervisor::Command;
use hexapod_core::timing::{PHYSICS_DT_S, POLICY_DT_S};

use crate::base::BaseState;
use crate::imu::{ImuModel, ImuNoise};
use crate::plant::JointPlant;
use crate::rc::RcSource;
use crate::rig::DriveRig;

/// Harness time step, microseconds.
pub const TICK_US: u64 = 1_000;
const PHYSICS_US: u64 = (PHYSICS_DT_S * 1e6) as u64;
const CYCLE_US: u64 = (POLICY_DT_S * 1e6) as u64;

/// Everything of one SIL run.
pub struct Harness<P: JointPlant> {
    /// The controller core under test.
    pub controller: Controller,
    /// Buses and drives.
    pub rig: DriveRig,
    /// The IMU model.
    pub imu: ImuModel,
    /// The RC transmitter and receiver.
    pub rc: RcSource,
    /// The joints.
    pub plant: P,
    /// The base state the IMU senses.
    pub base: BaseState,
    /// Simulation time, microseconds.
    pub now_us: u64,
    /// Extra delay before the next cycle's control step, microseconds (overrun injection).
    pub delay_next_finish_us: u64,
    /// The last command of the controller.
    pub last_command: Option<Command>,
    /// The controller's parameters (a restarted controller gets the same).
    pub config: ControllerConfig,
    /// The controller is held in reset: the drives, sensors and physics run on.
    pub controller_down: bool,
}

impl<P: JointPlant> Harness<P> {
    /// Powers the drives on; the controller starts after the drives' boot-up messages.
    pub fn new(plant: P, config: ControllerConfig, seed: u64) -> Self {
        let mut rig = DriveRig::new(seed);
        rig.power_on(0);
        Self {
            controller: Controller::new(config),
            rig,
            imu: ImuModel::new(ImuNoise::default(), seed ^ 0x1A0),
            rc: RcSource::new(),
            plant,
            base: BaseState::default(),
            now_us: 0,
            delay_next_finish_us: 0,
            last_command: None,
            config,
            controller_down: false,
        }
    }

    /// A reset of the microcontroller (IWDG, HardFault): the controller is gone for
    /// `down_us` while the drives keep running on their last commands, then a new
    /// controller starts with `boot` (its reset flags) and no memory of the old one. The
    /// CAN peripherals' queues are lost with the reset.
    pub fn restart_controller(
        &mut self,
        down_us: u64,
        boot: BootInfo,
        physics: &mut impl FnMut(&mut P, f32),
    ) {
        self.controller_down = true;
        for bus in &mut self.rig.buses {
            bus.reset_controller_side();
        }
        let until = self.now_us + down_us;
        self.idle_until(until, physics);
        self.controller_down = false;
        self.controller = Controller::new(self.config);
        self.last_command = None;
        self.controller.start_after_reset(self.now_us, boot);
    }

    /// One 1 ms tick: sensors, frames both ways, drives, physics.
    fn tick(&mut self, physics: &mut impl FnMut(&mut P, f32)) {
        let now = self.now_us;
        for bus in &mut self.rig.buses {
            bus.set_time(now);
        }
        if let Some(base) = self.plant.base_state() {
            self.base = base;
        }
        let b = self.base;
        self.imu.sample(
            now,
            b.orientation,
            b.ang_vel_base_rad_s,
            b.lin_acc_world_m_s2,
        );
        self.rc.tick(now);
        if self.controller_down {
            for bus in &mut self.rig.buses {
                bus.reset_controller_side();
            }
            self.rig.step(now, &mut self.plant);
        } else {
            self.controller.service_imu(&mut self.imu);
            self.controller.service_rc(&mut self.rc, now);
            for bus in 0..2 {
                self.controller
                    .service_bus(bus, &mut self.rig.buses[bus], now);
            }
            self.rig.step(now, &mut self.plant);
            for bus in 0..2 {
                self.controller
                    .service_bus(bus, &mut self.rig.buses[bus], now);
            }
        }
        self.now_us += TICK_US;
        if self.now_us.is_multiple_of(PHYSICS_US) {
            physics(&mut self.plant, PHYSICS_DT_S);
        }
    }

    /// Runs without control cycles (boot) until `until_us`.
    pub fn idle_until(&mut self, until_us: u64, physics: &mut impl FnMut(&mut P, f32)) {
        while self.now_us < until_us {
            self.tick(physics);
        }
    }

    /// Starts the controller after a 10 ms boot delay.
    pub fn start(&mut self, physics: &mut impl FnMut(&mut P, f32)) {
        self.idle_until(self.now_us + 10_000, physics);
        self.controller.start(self.now_us);
    }

    /// One 20 ms control cycle with `policy`.
    pub fn cycle<Q: Policy>(&mut self, policy: &mut Q, physics: &mut impl FnMut(&mut P, f32)) {
        let t0 = self.now_us;
        self.controller.begin_cycle(t0);
        let delay = core::mem::take(&mut self.delay_next_finish_us);
        let mut finished = false;
        while self.now_us < t0 + CYCLE_US.max(delay + TICK_US) {
            self.tick(physics);
            let ready = self.controller.feedback_ready(self.now_us);
            if !finished && ready && self.now_us >= t0 + delay {
                self.last_command = Some(self.controller.finish_cycle(self.now_us, policy));
                finished = true;
                for bus in 0..2 {
                    self.rig.buses[bus].set_time(self.now_us);
                    self.controller
                        .service_bus(bus, &mut self.rig.buses[bus], self.now_us);
                }
            }
        }
    }

    /// Runs control cycles for `seconds`.
    pub fn run<Q: Policy>(
        &mut self,
        seconds: f32,
        policy: &mut Q,
        physics: &mut impl FnMut(&mut P, f32),
    ) {
        let cycles = (seconds / POLICY_DT_S).round() as usize;
        for _ in 0..cycles {
            self.cycle(policy, physics);
        }
    }
}
