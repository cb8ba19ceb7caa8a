//! The 50 Hz control loop around hexapod-core's [`Controller`]: each cycle SYNC, the
//! drives' feedback, supervisor and policy, RPDOs; between cycles the buses, the IMU and
//! the RC link are serviced every millisecond (SDO configuration and the master's
//! heartbeat run there). The watchdog is fed only after a cycle that started on time and
//! met its deadline. Cycle and policy-step times are measured (embassy `Instant`, DWT
//! cycle counter) and logged every few seconds.

use core::mem::discriminant;

use cortex_m::peripheral::DWT;
use defmt::{info, warn};
use embassy_futures::select::{select, Either};
use embassy_stm32::gpio::Output;
use embassy_stm32::peripherals::IWDG1;
use embassy_stm32::wdg::IndependentWatchdog;
use embassy_time::{Duration, Instant, Ticker, Timer};
use hexapod_core::canopen::master::NUM_BUSES;
use hexapod_core::control::NnPolicy;
use hexapod_core::controller::{Controller, ControllerConfig};
use hexapod_core::hal::{BootInfo, Clock};
use hexapod_core::supervisor::Mode;
use hexapod_core::timing::POLICY_RATE_HZ;

use crate::board::SYSCLK_HZ;
use crate::can_task::{FdcanBus, HEALTH};
use crate::imu_task::{self, ImuQueue};
use crate::rc_task::{self, RcBytes};
use crate::stack;

/// The generated fixed-point policy.
pub type Policy = NnPolicy<'static, { hexapod_policy::SCRATCH_WORDS }>;

/// Control period.
const CYCLE: Duration = Duration::from_hz(POLICY_RATE_HZ as u64);
/// Service period between cycles.
const SERVICE_PERIOD: Duration = Duration::from_millis(1);
/// Poll period while waiting for the feedback after SYNC.
const FEEDBACK_POLL: Duration = Duration::from_micros(250);
/// Cycles between two status logs (5 s).
const LOG_EVERY_CYCLES: u32 = 5 * POLICY_RATE_HZ;
/// Cycles between two toggles of the alive LED (0.5 s).
const BLINK_EVERY_CYCLES: u32 = POLICY_RATE_HZ / 2;
/// IWDG timeout: five missed cycles reset the board.
pub const WATCHDOG_TIMEOUT_US: u32 = 5 * 1_000_000 / POLICY_RATE_HZ;

/// The controller's clock: embassy's uptime in microseconds.
pub struct UptimeClock;

impl Clock for UptimeClock {
    fn now_us(&self) -> u64 {
        Instant::now().as_micros()
    }
}

/// What the control loop reads and writes.
pub struct ControlIo {
    /// Bus 0 (right legs) and bus 1 (left legs).
    pub buses: [FdcanBus; NUM_BUSES],
    /// IMU samples.
    pub imu: ImuQueue,
    /// CRSF bytes.
    pub rc: RcBytes,
    /// LD1: toggles while the loop runs.
    pub alive_led: Output<'static>,
    /// LD3: on in the fault modes.
    pub fault_led: Output<'static>,
}

/// Moves frames, samples and bytes between the hardware and the controller.
fn service(controller: &mut Controller, io: &mut ControlIo, now_us: u64) {
    controller.service_imu(&mut io.imu);
    controller.service_rc(&mut io.rc, now_us);
    for (index, bus) in io.buses.iter_mut().enumerate() {
        controller.service_bus(index, bus, now_us);
    }
}

/// Cycle-time figures over one log window.
#[derive(Clone, Copy, Debug, Default, defmt::Format)]
struct Window {
    /// Worst SYNC-to-RPDO time, microseconds.
    worst_cycle_us: u32,
    /// Worst `finish_cycle` (supervisor, observation, policy) time, microseconds.
    worst_step_us: u32,
    /// Sum of `finish_cycle` times, for the mean, microseconds.
    step_sum_us: u32,
    /// Cycles in the window.
    cycles: u32,
    /// Cycles after which the watchdog was not fed.
    late: u32,
}

fn is_fault(mode: Mode) -> bool {
    matches!(
        mode,
        Mode::SafeSitDown { .. } | Mode::SafeHold { .. } | Mode::Faulted { .. }
    )
}

/// Runs the controller until reset.
#[embassy_executor::task]
pub async fn control_task(
    mut io: ControlIo,
    mut policy: Policy,
    mut watchdog: IndependentWatchdog<'static, IWDG1>,
    boot: BootInfo,
) {
    let config = ControllerConfig::default();
    let clock = UptimeClock;
    let mut controller = Controller::new(config);
    controller.start_after_reset(clock.now_us(), boot);
    let mut mode = controller.mode();
    if boot.warm() {
        warn!(
            "control: started after a reset ({}, RCC_RSR {:#010x}): drives holding the body are adopted",
            boot.cause(),
            boot.reset_flags
        );
    }
    info!("control: started, {} Hz, mode {}", POLICY_RATE_HZ, mode);

    watchdog.unleash();
    let mut ticker = Ticker::every(CYCLE);
    let mut window = Window::default();
    let mut expected_sync: Option<Instant> = None;
    loop {
        if let Either::Second(()) = select(ticker.next(), Timer::after(SERVICE_PERIOD)).await {
            service(&mut controller, &mut io, clock.now_us());
            continue;
        }

        // SYNC, then the drives' feedback (or its deadline).
        let sync = Instant::now();
        controller.begin_cycle(sync.as_micros());
        service(&mut controller, &mut io, sync.as_micros());
        while !controller.feedback_ready(clock.now_us()) {
            Timer::after(FEEDBACK_POLL).await;
            service(&mut controller, &mut io, clock.now_us());
        }

        // Supervisor, observation and policy; then the RPDOs go out.
        let step_start = DWT::cycle_count();
        controller.finish_cycle(clock.now_us(), &mut policy);
        let step_cycles = DWT::cycle_count().wrapping_sub(step_start);
        service(&mut controller, &mut io, clock.now_us());
        let done = Instant::now();

        let cycle_us = (done - sync).as_micros();
        let step_us = step_cycles / (SYSCLK_HZ / 1_000_000);
        let late_start = expected_sync.is_some_and(|t| sync > t + CYCLE / 2);
        if cycle_us <= config.cycle_deadline_us && !late_start {
            watchdog.pet();
        } else {
            window.late += 1;
        }
        expected_sync = Some(sync + CYCLE);
        if done - sync >= CYCLE {
            // Do not fire the missed ticks back to back: start the schedule anew.
            ticker.reset();
            expected_sync = None;
        }

        window.cycles += 1;
        window.worst_cycle_us = window.worst_cycle_us.max(cycle_us as u32);
        window.worst_step_us = window.worst_step_us.max(step_us);
        window.step_sum_us = window.step_sum_us.saturating_add(step_us);

        let now_mode = controller.mode();
        if discriminant(&now_mode) != discriminant(&mode) {
            if is_fault(now_mode) {
                warn!("control: mode {} -> {}", mode, now_mode);
            } else {
                info!("control: mode {} -> {}", mode, now_mode);
            }
            mode = now_mode;
        }
        io.fault_led.set_level(is_fault(now_mode).into());
        let cycles = controller.stats.cycles;
        if cycles.is_multiple_of(BLINK_EVERY_CYCLES) {
            io.alive_led.toggle();
        }
        if cycles.is_multiple_of(LOG_EVERY_CYCLES) {
            log_status(&controller, &window);
            window = Window::default();
        }
    }
}

/// The periodic status log.
fn log_status(controller: &Controller, window: &Window) {
    let mean_step_us = window.step_sum_us / window.cycles.max(1);
    info!(
        "control: mode {}, {} | window: worst cycle {} us, policy step mean {} us worst {} us, {} late of {}",
        controller.mode(),
        controller.stats,
        window.worst_cycle_us,
        mean_step_us,
        window.worst_step_us,
        window.late,
        window.cycles
    );
    info!(
        "CAN0 {} | CAN1 {} | master {}",
        HEALTH[0].snapshot(),
        HEALTH[1].snapshot(),
        controller.master.counters
    );
    info!(
        "IMU {} | RC {} CRSF {} | stack high water {} bytes",
        imu_task::STATS.snapshot(),
        rc_task::STATS.snapshot(),
        controller.rc_receiver().parser.counters,
        stack::high_water_bytes()
    );
}
