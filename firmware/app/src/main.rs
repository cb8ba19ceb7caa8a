//! Hexapod firmware for the STM32H743ZI (Nucleo-H743ZI2): clocks, pins, interrupt
//! bindings and the tasks around hexapod-core's controller and the generated policy.
//!
//! Tasks (one thread-mode executor; the FDCAN, DMA and UART interrupts buffer the data):
//! - `control_task`: the 50 Hz loop (SYNC, feedback, supervisor, policy, RPDOs), watchdog;
//! - `can_task::monitor` (one per bus): error counters, FIFO overflows, error states;
//! - `imu_task`: the ICM-42688-P's FIFO at 1 kHz;
//! - `rc_task`: CRSF bytes from the receiver.
#![no_std]
#![no_main]

mod board;
mod cache;
mod can_task;
mod control_task;
mod imu_stamp;
mod imu_task;
mod mpu_region;
mod rc_task;
mod stack;

use defmt::info;
use embassy_executor::Spawner;
use embassy_stm32::can::{self, CanConfigurator};
use embassy_stm32::exti::{self, ExtiInput};
use embassy_stm32::gpio::{Level, Output, Pull, Speed};
use embassy_stm32::peripherals::{DMA1_CH0, DMA1_CH1, DMA1_CH2, FDCAN1, FDCAN2, USART2};
use embassy_stm32::spi::{self, Spi};
use embassy_stm32::time::Hertz;
use embassy_stm32::usart::{self, UartRx};
use embassy_stm32::wdg::IndependentWatchdog;
use embassy_stm32::{bind_interrupts, dma, interrupt, pac};
use embassy_time::Delay;
use embedded_hal_bus::spi::ExclusiveDevice;
use hexapod_core::control::NnPolicy;
use hexapod_core::hal::BootInfo;
use hexapod_core::nn::Kernel;
use {defmt_rtt as _, panic_probe as _};

use crate::board::Board;
use crate::can_task::FdcanBus;
use crate::control_task::ControlIo;

bind_interrupts!(struct Irqs {
    FDCAN1_IT0 => can::IT0InterruptHandler<FDCAN1>;
    FDCAN1_IT1 => can::IT1InterruptHandler<FDCAN1>;
    FDCAN2_IT0 => can::IT0InterruptHandler<FDCAN2>;
    FDCAN2_IT1 => can::IT1InterruptHandler<FDCAN2>;
    DMA1_STREAM0 => dma::InterruptHandler<DMA1_CH0>;
    DMA1_STREAM1 => dma::InterruptHandler<DMA1_CH1>;
    DMA1_STREAM2 => dma::InterruptHandler<DMA1_CH2>;
    USART2 => usart::InterruptHandler<USART2>;
    EXTI15_10 => exti::InterruptHandler<interrupt::typelevel::EXTI15_10>;
});

#[embassy_executor::main]
async fn main(spawner: Spawner) {
    let mut core = cortex_m::Peripherals::take().expect("core peripherals taken once");
    // Why we (re)started: the reset flags, read before anything else and then cleared, so
    // that the next reset reports only its own cause. The controller adopts drives that
    // hold the body whatever the cause; the flags go to the log.
    let boot = BootInfo {
        reset_flags: pac::RCC.rsr().read().0,
    };
    pac::RCC.rsr().modify(|w| w.set_rmvf(true));
    let board = Board::new(embassy_stm32::init(board::clock_config()));
    cache::enable(&mut core.SCB, &mut core.CPUID, &mut core.MPU);
    core.DCB.enable_trace();
    core.DWT.enable_cycle_counter();
    info!(
        "hexapod firmware {}: STM32H743ZI at {} MHz, policy from {} ({} MACs per step)",
        env!("CARGO_PKG_VERSION"),
        board::SYSCLK_HZ / 1_000_000,
        hexapod_policy::SOURCE_CHECKPOINT,
        hexapod_policy::MACS
    );

    // CAN: bus 0 = FDCAN1 (right legs), bus 1 = FDCAN2 (left legs).
    let right = board.can_right;
    let mut fdcan1 = CanConfigurator::new(right.fdcan, right.rx, right.tx, Irqs);
    can_task::configure(&mut fdcan1, 0);
    let fdcan1 = can_task::start(fdcan1, 0);
    let left = board.can_left;
    let mut fdcan2 = CanConfigurator::new(left.fdcan, left.rx, left.tx, Irqs);
    can_task::configure(&mut fdcan2, 1);
    let fdcan2 = can_task::start(fdcan2, 1);
    spawner.spawn(can_task::monitor(0, pac::FDCAN1).expect("CAN0 monitor spawns"));
    spawner.spawn(can_task::monitor(1, pac::FDCAN2).expect("CAN1 monitor spawns"));

    // IMU on SPI1 with DMA.
    let imu = board.imu;
    let mut spi_config = spi::Config::default();
    spi_config.frequency = Hertz(board::IMU_SPI_HZ);
    spi_config.mode = spi::MODE_0;
    let spi = Spi::new(
        imu.spi, imu.sck, imu.mosi, imu.miso, imu.tx_dma, imu.rx_dma, Irqs, spi_config,
    );
    let cs = Output::new(imu.cs, Level::High, Speed::VeryHigh);
    let imu_spi = ExclusiveDevice::new(spi, cs, Delay).expect("chip select is infallible");
    let int1 = ExtiInput::new(imu.int1, imu.int1_exti, Pull::Down, Irqs);
    spawner.spawn(imu_task::imu_task(imu_spi, int1).expect("IMU task spawns"));

    // CRSF receiver on USART2, DMA ring buffer.
    let rc = board.rc;
    let uart = UartRx::new(rc.uart, rc.rx, rc.rx_dma, Irqs, rc_task::uart_config())
        .expect("USART2 accepts 420 kbaud 8N1");
    let uart = uart.into_ring_buffered(rc_task::dma_ring());
    spawner.spawn(rc_task::rc_task(uart).expect("RC task spawns"));

    // Watchdog: frozen while a debugger halts the core.
    pac::DBGMCU.apb4fzr1().modify(|w| w.set_iwdg1(true));
    let watchdog = IndependentWatchdog::new(board.iwdg, control_task::WATCHDOG_TIMEOUT_US);

    let policy = NnPolicy::new(&hexapod_policy::POLICY, Kernel::Native)
        .expect("the generated policy is valid and fits its scratch");
    let io = ControlIo {
        buses: [FdcanBus::new(fdcan1, 0), FdcanBus::new(fdcan2, 1)],
        imu: imu_task::ImuQueue,
        rc: rc_task::RcBytes,
        alive_led: Output::new(board.leds.alive, Level::Low, Speed::Low),
        fault_led: Output::new(board.leds.fault, Level::Low, Speed::Low),
    };
    spawner.spawn(
        control_task::control_task(io, policy, watchdog, boot).expect("control task spawns"),
    );
}
