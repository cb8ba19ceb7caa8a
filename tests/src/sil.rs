//! One software-in-the-loop rig: hal-mock's harness (controller core, CAN buses, 18
//! CiA 402 drive emulators, IMU, RC) over host-sim's physics, with the scenario steps the
//! tests share (boot, stand up, run until a mode).

use hal_mock::harness::Harness;
use hexapod_core::control::{NnPolicy, Policy};
use hexapod_core::controller::{ControllerConfig, ZeroPolicy};
use hexapod_core::nn::Kernel;
use hexapod_core::supervisor::Mode;
use hexapod_core::timing::POLICY_DT_S;

use crate::sim_plant::{PlantError, SimPlant};
use host_sim::course::{Course, Feature};

/// The generated fixed-point policy as the control step runs it.
pub type GeneratedPolicy = NnPolicy<'static, { hexapod_policy::SCRATCH_WORDS }>;

/// The generated policy (`firmware/policy`); `None` if it does not validate.
pub fn generated_policy() -> Option<GeneratedPolicy> {
    GeneratedPolicy::new(&hexapod_policy::POLICY, Kernel::Native)
}

/// The physics closure the harness calls every 5 ms.
pub fn physics(plant: &mut SimPlant, _dt_s: f32) {
    plant.step();
}

/// A SIL rig.
pub struct Sil {
    /// Controller, buses, drives, sensors and the simulated robot.
    pub h: Harness<SimPlant>,
    /// The controller's parameters.
    pub config: ControllerConfig,
    /// When [`Sil::stand_up`] reached `Walking`, s.
    pub stood_up_at_s: Option<f32>,
    /// When the supervisor first left `Walking` after [`Sil::stand_up`] (a fault's hold or
    /// sit-down, a disarm), s.
    pub left_walking_at_s: Option<f32>,
}

impl Sil {
    /// The robot sitting on flat ground, drives powered on, controller not started;
    /// `seed` drives every random source (bus loss dice, IMU noise).
    pub fn new(seed: u64) -> Result<Self, PlantError> {
        Ok(Self::with_plant(SimPlant::sitting()?, seed))
    }

    /// The robot sitting at the start of one lane of host-sim's evaluation course: level
    /// ground, then `feature` (stairs, a ramp) 1 m ahead of the base, as the paper suite
    /// walks it.
    pub fn before(feature: Feature, seed: u64) -> Result<Self, PlantError> {
        let course = Course::new(&[feature]);
        let start = course.start_pose(0);
        let plant = SimPlant::sitting_on(course.terrain().clone(), start.position_m)?;
        Ok(Self::with_plant(plant, seed))
    }

    /// A rig over `plant`, drives powered on, controller not started.
    pub fn with_plant(plant: SimPlant, seed: u64) -> Self {
        let config = ControllerConfig::default();
        let h = Harness::new(plant, config, seed);
        Self {
            h,
            config,
            stood_up_at_s: None,
            left_walking_at_s: None,
        }
    }

    /// The supervisor's mode.
    pub fn mode(&self) -> Mode {
        self.h.controller.mode()
    }

    /// Simulated time, s.
    pub fn time_s(&self) -> f32 {
        self.h.now_us as f32 * 1e-6
    }

    /// The simulated robot.
    pub fn plant(&self) -> &SimPlant {
        &self.h.plant
    }

    /// Runs control cycles with `policy` for `seconds`.
    pub fn run<P: Policy>(&mut self, seconds: f32, policy: &mut P) {
        let cycles = (seconds / POLICY_DT_S).round() as usize;
        for _ in 0..cycles {
            self.cycle(policy);
        }
    }

    /// One control cycle; notes when the robot first stops walking after standing up.
    fn cycle<P: Policy>(&mut self, policy: &mut P) {
        self.h.cycle(policy, &mut physics);
        if self.stood_up_at_s.is_some()
            && self.left_walking_at_s.is_none()
            && self.mode() != Mode::Walking
        {
            self.left_walking_at_s = Some(self.time_s());
        }
    }

    /// Runs control cycles until `done(mode)` or `max_s` passed; true when `done`.
    pub fn run_until<P: Policy>(
        &mut self,
        max_s: f32,
        policy: &mut P,
        done: impl Fn(Mode) -> bool,
    ) -> bool {
        let cycles = (max_s / POLICY_DT_S).round() as usize;
        for _ in 0..cycles {
            if done(self.mode()) {
                return true;
            }
            self.cycle(policy);
        }
        done(self.mode())
    }

    /// A reset of the controller (watchdog, HardFault) with the drives running on: the
    /// controller is gone for `down_s`, then a new one starts with `reset_flags` (RCC_RSR).
    pub fn restart_controller(&mut self, down_s: f32, reset_flags: u32) {
        let down_us = (down_s * 1e6).round() as u64;
        self.h.restart_controller(
            down_us,
            hexapod_core::hal::BootInfo { reset_flags },
            &mut physics,
        );
    }

    /// Starts the controller and waits until the drives are configured (`Disabled`).
    pub fn boot(&mut self) -> Result<(), Mode> {
        self.h.start(&mut physics);
        if self.run_until(2.0, &mut ZeroPolicy, |m| m == Mode::Disabled) {
            Ok(())
        } else {
            Err(self.mode())
        }
    }

    /// A robot that stood up and has walked forward (0.6 of full stick) for 1 s with the
    /// scripted tripod gait, and that gait to go on with.
    pub fn walking_with_gait(seed: u64) -> (Self, crate::gait_policy::GaitPolicy) {
        let mut sil = Self::new(seed).expect("SIL world");
        sil.stand_up().expect("stands up");
        let mut gait = crate::gait_policy::GaitPolicy::default();
        sil.h.rc.set_sticks(0.6, 0.0, 0.0);
        sil.run(1.0, &mut gait);
        assert_eq!(sil.mode(), Mode::Walking);
        (sil, gait)
    }

    /// Boots, arms and stands up with the zero policy until the supervisor hands over to
    /// the policy (`Walking`).
    pub fn stand_up(&mut self) -> Result<(), Mode> {
        self.boot()?;
        self.h.rc.set_arm(true);
        if self.run_until(5.0, &mut ZeroPolicy, |m| m == Mode::Walking) {
            self.stood_up_at_s = Some(self.time_s());
            self.left_walking_at_s = None;
            Ok(())
        } else {
            Err(self.mode())
        }
    }
}
