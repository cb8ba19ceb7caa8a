//! Cortex-M7 cost of the policy step, measured under QEMU (`mps2-an500`, `-icount shift=0`).
//!
//! With `-icount shift=0` QEMU advances its virtual clock by exactly 1 ns per executed
//! instruction, and SysTick (on the core clock) counts that virtual time. The program first
//! calibrates instructions per SysTick tick with a loop of known length, then times one
//! policy step with the SMLALD kernel and one with the portable kernel, and prints the
//! raw fixed-point actions (the host check compares them bit for bit), instructions per
//! step and per multiply-accumulate. Then the control path without the network, with the
//! core's float functions (`libm`) against micromath and against `libm` with the FPU's
//! square root ([`control_path`]): 20 attitude-filter updates (1 kHz IMU in a 20 ms
//! period), the tilt, and the control step (observation, history, input quantization,
//! clamps) with a policy that only quantizes; the filter's state after a 2 s IMU sequence
//! must equal the host's bit for bit (`hexapod_core::math::bench`). It exits through
//! semihosting (status 0 on success).
#![no_std]
#![no_main]

use core::fmt::Write as _;
use cortex_m::peripheral::syst::SystClkSource;
use cortex_m::peripheral::SYST;
use cortex_m_rt::entry;
use cortex_m_semihosting::{debug, hio};
use hexapod_core::nn::bench::bench_input;
use hexapod_core::nn::{Kernel, Scratch};
use hexapod_policy::{MACS, POLICY, SCRATCH_WORDS};

mod control_path;

/// Seed of the benchmark input (the host check uses the same).
const INPUT_SEED: u32 = 7;
/// Iterations of the calibration loop (2 instructions each).
const CALIBRATION_LOOPS: u32 = 50_000;

/// SysTick ticks elapsed since `start` (the counter counts down, 24 bits).
pub(crate) fn ticks_since(start: u32) -> u32 {
    start.wrapping_sub(SYST::get_current()) & 0x00ff_ffff
}

/// A loop of exactly `2 * n` instructions (`subs` + `bne`).
fn known_loop(n: u32) {
    // SAFETY: only the named register and the flags change.
    unsafe {
        core::arch::asm!(
            "2:",
            "subs {n}, {n}, #1",
            "bne 2b",
            n = inout(reg) n => _,
            options(nomem, nostack),
        );
    }
}

static mut SCRATCH: Scratch<SCRATCH_WORDS> = Scratch::new();

#[entry]
fn main() -> ! {
    let code = run();
    debug::exit(if code.is_ok() {
        debug::EXIT_SUCCESS
    } else {
        debug::EXIT_FAILURE
    });
    loop {
        cortex_m::asm::nop();
    }
}

fn run() -> Result<(), ()> {
    let mut out = hio::hstdout()?;
    let mut cp = cortex_m::Peripherals::take().ok_or(())?;
    cp.SYST.set_clock_source(SystClkSource::Core);
    cp.SYST.set_reload(0x00ff_ffff);
    cp.SYST.clear_current();
    cp.SYST.enable_counter();

    // Calibration: instructions per tick from a loop of known length (the timing code's
    // own overhead is measured with an empty region and removed).
    let start = SYST::get_current();
    let empty = ticks_since(start);
    let start = SYST::get_current();
    known_loop(CALIBRATION_LOOPS);
    let loop_ticks = ticks_since(start).saturating_sub(empty).max(1);
    let insns_per_tick = (2 * CALIBRATION_LOOPS) as f32 / loop_ticks as f32;

    POLICY.validate().map_err(|_| ())?;
    let (obs, history) = bench_input(INPUT_SEED);
    // SAFETY: the only reference to SCRATCH, taken once in this single-threaded program.
    let scratch = unsafe { &mut *core::ptr::addr_of_mut!(SCRATCH) };
    let mut results = [
        (Kernel::Native, 0u32, [0i16; 18]),
        (Kernel::Portable, 0u32, [0i16; 18]),
    ];
    for (kernel, ticks, action_q) in results.iter_mut() {
        // Warm-up run, then the timed one (same input: same work).
        POLICY
            .step_obs(scratch, &obs, &history, *kernel)
            .map_err(|_| ())?;
        let start = SYST::get_current();
        let r = POLICY
            .step_obs(scratch, &obs, &history, *kernel)
            .map_err(|_| ())?;
        *ticks = ticks_since(start).saturating_sub(empty);
        *action_q = r.action_q;
    }
    if results[0].2 != results[1].2 {
        writeln!(out, "error: SMLALD and portable kernels disagree").ok();
        return Err(());
    }
    write!(out, "action_q:").ok();
    for q in results[0].2 {
        write!(out, " {q}").ok();
    }
    writeln!(out).ok();
    writeln!(out, "macs: {MACS}").ok();
    writeln!(out, "instructions_per_tick: {insns_per_tick:.3}").ok();
    for (kernel, ticks, _) in results {
        let insns = ticks as f32 * insns_per_tick;
        let name = if kernel == Kernel::Native {
            "smlald"
        } else {
            "portable"
        };
        writeln!(
            out,
            "{name}: instructions/step {:.0} instructions/MAC {:.3}",
            insns,
            insns / MACS as f32
        )
        .ok();
    }

    // One layer alone (memory.layers.1, 512 -> 256): the kernel without the step's
    // input quantization, copies and other layers.
    if let Some(layer) = POLICY.memory.layers.get(1) {
        static mut INPUT: [u32; 256] = [0; 256];
        static mut OUTPUT: [u32; 256] = [0; 256];
        // SAFETY: single-threaded; the only references to these statics.
        let (input, output) = unsafe {
            (
                &mut *core::ptr::addr_of_mut!(INPUT),
                &mut *core::ptr::addr_of_mut!(OUTPUT),
            )
        };
        for (i, w) in input.iter_mut().enumerate() {
            *w = (i as u32).wrapping_mul(0x9e37_79b9);
        }
        for native in [true, false] {
            let start = SYST::get_current();
            if native {
                layer.run(input, output);
            } else {
                layer.run_portable(input, output);
            }
            let insns = ticks_since(start).saturating_sub(empty) as f32 * insns_per_tick;
            let name = if native { "smlald" } else { "portable" };
            writeln!(
                out,
                "layer memory.1 ({} -> {}) {name}: instructions/MAC {:.3}",
                layer.in_dim,
                layer.out_dim,
                insns / layer.macs() as f32
            )
            .ok();
        }
    }

    control_path::run(&mut out, empty, insns_per_tick)
}

#[panic_handler]
fn panic(_: &core::panic::PanicInfo) -> ! {
    debug::exit(debug::EXIT_FAILURE);
    loop {
        cortex_m::asm::nop();
    }
}
