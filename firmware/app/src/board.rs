//! The Nucleo-H743ZI2 and the robot's wiring: clocks, which peripheral and pin does what,
//! bus parameters, and how the IMU is mounted. The only file that knows the board.
//!
//! | function | peripheral | pins (Nucleo-144 connectors) |
//! |---|---|---|
//! | CAN bus of the right legs (node ids 1-9) | FDCAN1 | PD0 RX, PD1 TX (CN9) |
//! | CAN bus of the left legs (node ids 10-18) | FDCAN2 | PB5 RX, PB6 TX (CN7, CN10) |
//! | IMU, ICM-42688-P | SPI1, DMA1 streams 0 (TX) and 1 (RX) | PA5 SCK, PA6 MISO, PD7 MOSI, PD14 CS, PD15 INT1 (EXTI15) |
//! | RC receiver, CRSF | USART2 RX, DMA1 stream 2 (ring buffer) | PD6 RX |
//! | status LEDs | GPIO | PB0 LD1 green (loop alive), PB14 LD3 red (fault) |
//! | watchdog | IWDG1 | |
//!
//! Each CAN bus needs a 3.3 V transceiver (e.g. TJA1051T/3, SN65HVD230) between the pins
//! and the bus, and 120 ohm termination at both bus ends. USART3 (PD8/PD9) stays free for
//! the ST-LINK virtual COM port; Ethernet's RMII pins (PA7, PB13, PC1, PC4, PC5, PG11,
//! PG13) are avoided because the on-board PHY drives some of them.
//!
//! Which joint sits on which bus, and its node id, comes from `hexapod_core::robot`
//! (`can_bus`, `can_node_id`); this file only says which FDCAN instance is bus 0 and 1.

use embassy_stm32::peripherals::{
    DMA1_CH0, DMA1_CH1, DMA1_CH2, EXTI15, FDCAN1, FDCAN2, IWDG1, PA5, PA6, PB0, PB14, PB5, PB6,
    PD0, PD1, PD14, PD15, PD6, PD7, SPI1, USART2,
};
use embassy_stm32::time::Hertz;
use embassy_stm32::{rcc, Config, Peri, PeripheralType, Peripherals};

/// CPU clock: PLL1_P.
pub const SYSCLK_HZ: u32 = 480_000_000;
/// HSE: the ST-LINK's 8 MHz MCO output (bypass mode), accurate enough for CAN.
pub const HSE_HZ: u32 = 8_000_000;
/// PLL1 feedback multiplier: 8 MHz * 120 = 960 MHz VCO.
const PLL1_MUL: u32 = 120;
/// PLL1_P divider: 960 / 2 = 480 MHz.
const PLL1_DIVP: u32 = 2;
/// PLL1_Q divider: 960 / 12 = 80 MHz, the FDCAN and SPI1 kernel clock.
const PLL1_DIVQ: u32 = 12;
/// FDCAN and SPI1/2/3 kernel clock (PLL1_Q).
pub const PLL1_Q_HZ: u32 = HSE_HZ * PLL1_MUL / PLL1_DIVQ;

/// CAN bit rate of both buses.
pub const CAN_BITRATE: u32 = 1_000_000;
/// Nominal bit timing at 80 MHz: 5 clocks per time quantum, 1 + 13 + 2 = 16 quanta per bit
/// (1 Mbit/s), sample point at 14/16 = 87.5 % (CiA 301's recommendation).
pub const CAN_PRESCALER: u16 = 5;
/// Time quanta between the sync segment and the sample point.
pub const CAN_SEG1: u8 = 13;
/// Time quanta after the sample point.
pub const CAN_SEG2: u8 = 2;
/// Resynchronization jump width, time quanta.
pub const CAN_SJW: u8 = 2;
const CAN_QUANTA: u32 = 1 + CAN_SEG1 as u32 + CAN_SEG2 as u32;
const _: () = assert!(PLL1_Q_HZ == 80_000_000);
const _: () = assert!(HSE_HZ * PLL1_MUL / PLL1_DIVP == SYSCLK_HZ);
const _: () = assert!(PLL1_Q_HZ == CAN_BITRATE * CAN_PRESCALER as u32 * CAN_QUANTA);
const _: () = assert!((1 + CAN_SEG1 as u32) * 1000 / CAN_QUANTA == 875);

/// IMU SPI clock: 80 MHz / 8 (the ICM-42688-P allows 24 MHz).
pub const IMU_SPI_HZ: u32 = 10_000_000;
/// CRSF: 420 kbaud, 8N1, not inverted.
pub const CRSF_BAUD: u32 = 420_000;

/// Rotation from the IMU's axes to the base frame (x forward, y left, z up): row `i` gives
/// base axis `i` as a combination of IMU axes. The ICM-42688-P sits flat with its x axis
/// forward and its z axis up.
pub const IMU_TO_BASE: [[f32; 3]; 3] = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];

/// Clocks: HSE bypass -> PLL1 (480 MHz CPU, 80 MHz PLL1_Q), AHB 240 MHz, APBs 120 MHz,
/// voltage scale 0 (needed above 400 MHz; revision V silicon, as on the Nucleo-H743ZI2).
pub fn clock_config() -> Config {
    let mut config = Config::default();
    config.rcc.hsi = None;
    config.rcc.hse = Some(rcc::Hse {
        freq: Hertz(HSE_HZ),
        mode: rcc::HseMode::Bypass,
    });
    config.rcc.pll1 = Some(rcc::Pll {
        source: rcc::PllSource::HSE,
        prediv: rcc::PllPreDiv::DIV1,
        mul: rcc::PllMul::MUL120,
        fracn: None,
        divp: Some(rcc::PllDiv::DIV2),
        divq: Some(rcc::PllDiv::DIV12),
        divr: None,
    });
    config.rcc.sys = rcc::Sysclk::PLL1_P;
    config.rcc.d1c_pre = rcc::AHBPrescaler::DIV1;
    config.rcc.ahb_pre = rcc::AHBPrescaler::DIV2;
    config.rcc.apb1_pre = rcc::APBPrescaler::DIV2;
    config.rcc.apb2_pre = rcc::APBPrescaler::DIV2;
    config.rcc.apb3_pre = rcc::APBPrescaler::DIV2;
    config.rcc.apb4_pre = rcc::APBPrescaler::DIV2;
    config.rcc.voltage_scale = rcc::VoltageScale::Scale0;
    // The default FDCAN kernel clock is HSE; 1 Mbit/s with an 87.5 % sample point needs
    // a multiple of 16 MHz.
    config.rcc.mux.fdcansel = rcc::mux::Fdcansel::PLL1_Q;
    config.rcc.mux.spi123sel = rcc::mux::Saisel::PLL1_Q;
    config
}

/// One CAN bus's peripheral and pins.
pub struct CanPins<
    T: PeripheralType + 'static,
    Rx: PeripheralType + 'static,
    Tx: PeripheralType + 'static,
> {
    /// The FDCAN instance.
    pub fdcan: Peri<'static, T>,
    /// Receive pin (to the transceiver's RXD).
    pub rx: Peri<'static, Rx>,
    /// Transmit pin (to the transceiver's TXD).
    pub tx: Peri<'static, Tx>,
}

/// The IMU's SPI bus, chip select and interrupt line.
pub struct ImuPins {
    /// SPI instance.
    pub spi: Peri<'static, SPI1>,
    /// Clock.
    pub sck: Peri<'static, PA5>,
    /// Controller in, peripheral out.
    pub miso: Peri<'static, PA6>,
    /// Controller out, peripheral in.
    pub mosi: Peri<'static, PD7>,
    /// Chip select (active low).
    pub cs: Peri<'static, PD14>,
    /// INT1 (FIFO watermark, latched, active high).
    pub int1: Peri<'static, PD15>,
    /// Its EXTI line.
    pub int1_exti: Peri<'static, EXTI15>,
    /// Transmit DMA stream.
    pub tx_dma: Peri<'static, DMA1_CH0>,
    /// Receive DMA stream.
    pub rx_dma: Peri<'static, DMA1_CH1>,
}

/// The RC receiver's UART.
pub struct RcPins {
    /// UART instance.
    pub uart: Peri<'static, USART2>,
    /// Receive pin (the receiver's TX).
    pub rx: Peri<'static, PD6>,
    /// Receive DMA stream (circular).
    pub rx_dma: Peri<'static, DMA1_CH2>,
}

/// Status LEDs.
pub struct LedPins {
    /// LD1, green: toggles while the control loop runs.
    pub alive: Peri<'static, PB0>,
    /// LD3, red: on while the supervisor is in a fault mode.
    pub fault: Peri<'static, PB14>,
}

/// Everything the firmware uses, by function.
pub struct Board {
    /// Bus 0: the right legs.
    pub can_right: CanPins<FDCAN1, PD0, PD1>,
    /// Bus 1: the left legs.
    pub can_left: CanPins<FDCAN2, PB5, PB6>,
    /// The IMU.
    pub imu: ImuPins,
    /// The RC receiver.
    pub rc: RcPins,
    /// The LEDs.
    pub leds: LedPins,
    /// The independent watchdog.
    pub iwdg: Peri<'static, IWDG1>,
}

impl Board {
    /// Splits the chip's peripherals by function.
    pub fn new(p: Peripherals) -> Self {
        Self {
            can_right: CanPins {
                fdcan: p.FDCAN1,
                rx: p.PD0,
                tx: p.PD1,
            },
            can_left: CanPins {
                fdcan: p.FDCAN2,
                rx: p.PB5,
                tx: p.PB6,
            },
            imu: ImuPins {
                spi: p.SPI1,
                sck: p.PA5,
                miso: p.PA6,
                mosi: p.PD7,
                cs: p.PD14,
                int1: p.PD15,
                int1_exti: p.EXTI15,
                tx_dma: p.DMA1_CH0,
                rx_dma: p.DMA1_CH1,
            },
            rc: RcPins {
                uart: p.USART2,
                rx: p.PD6,
                rx_dma: p.DMA1_CH2,
            },
            leds: LedPins {
                alive: p.PB0,
                fault: p.PB14,
            },
            iwdg: p.IWDG1,
        }
    }
}
