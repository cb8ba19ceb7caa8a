//! Caches: the instruction cache, and the data cache for flash only.
//!
//! The policy streams 704 KB of weights from flash every step; the data cache turns those
//! reads into line fills. RAM must stay out of it: embassy's DMA (SPI, UART, and the FDCAN
//! message RAM copies) does no cache maintenance, and the debugger reads the defmt RTT
//! buffer behind the core's back. MPU region 0 therefore makes the `RAM` region of
//! `memory.x` (AXI SRAM, which holds all statics, DMA buffers and the stack) normal
//! non-cacheable memory; everything else keeps the default memory map.

use cortex_m::peripheral::{CPUID, MPU, SCB};
use defmt::warn;

use crate::mpu_region::{rasr_non_cacheable, CTRL_ENABLE_PRIVDEFENA};

extern "C" {
    /// Start of `memory.x`'s RAM region, from cortex-m-rt's linker script.
    static _ram_start: u32;
    /// Its end.
    static _ram_end: u32;
}

/// Turns on the instruction cache, and the data cache with RAM non-cacheable. Leaves the
/// data cache off (with a warning) when the RAM region is not an MPU-describable region.
pub fn enable(scb: &mut SCB, cpuid: &mut CPUID, mpu: &mut MPU) {
    scb.enable_icache();
    let base = core::ptr::addr_of!(_ram_start) as u32;
    let len = (core::ptr::addr_of!(_ram_end) as u32).wrapping_sub(base);
    let Some(rasr) = rasr_non_cacheable(base, len) else {
        warn!(
            "cache: RAM {:#x}+{:#x} is not one MPU region; data cache stays off",
            base, len
        );
        return;
    };
    cortex_m::asm::dmb();
    // SAFETY: boot, before any DMA runs: region 0 only changes RAM's cacheability, and the
    // data cache is still off, so nothing cached can go stale.
    unsafe {
        mpu.ctrl.write(0);
        mpu.rnr.write(0);
        mpu.rbar.write(base);
        mpu.rasr.write(rasr);
        mpu.ctrl.write(CTRL_ENABLE_PRIVDEFENA);
    }
    cortex_m::asm::dsb();
    cortex_m::asm::isb();
    scb.enable_dcache(cpuid);
}
