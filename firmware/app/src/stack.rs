//! Stack high-water mark. cortex-m-rt paints the whole stack region with a pattern at reset
//! (`paint-stack` feature); the deepest word no longer holding it tells how much stack the
//! firmware has used so far.

/// cortex-m-rt's paint pattern.
const PAINT: u32 = 0xCCCC_CCCC;

extern "C" {
    /// Top of the stack (initial stack pointer), from cortex-m-rt's linker script.
    static _stack_start: u32;
    /// Lowest address the stack may grow to (end of the static data).
    static _stack_end: u32;
}

/// Bytes of stack used since reset (the scan reads the unused part once, about 0.5 MB on
/// this board: call it rarely).
pub fn high_water_bytes() -> usize {
    let top = core::ptr::addr_of!(_stack_start) as usize;
    let bottom = core::ptr::addr_of!(_stack_end) as usize;
    let mut addr = bottom;
    // SAFETY: [bottom, top) is the stack region, word-aligned (cortex-m-rt asserts it), RAM
    // that stays mapped; words below the stack pointer are only read, never referenced.
    while addr < top && unsafe { core::ptr::read_volatile(addr as *const u32) } == PAINT {
        addr += 4;
    }
    top - addr
}
