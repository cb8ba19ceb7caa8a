//! Conversions at the edges of the integer pipeline and between layers.
//!
//! Input: `round(x * scale)` saturated to `i16`, with `scale` a power of two (exact multiply)
//! and `libm::roundf` (integer bit manipulation: the same bits on every target).
//! Between layers: `round(acc * multiplier / 2^shift)`; `policy-codegen` chooses the
//! multiplier's width per channel so the `i64` product cannot overflow.

/// Quantizes one value: `round(x * scale)`, saturated to `i16` (NaN gives 0).
#[inline]
pub fn quantize(x: f32, scale: f32) -> i16 {
    let r = libm::roundf(x * scale);
    // `as` saturates (and maps NaN to 0).
    (r as i32).clamp(i16::MIN as i32, i16::MAX as i32) as i16
}

/// Quantizes `values` with per-entry `scales` into packed words (zero padding at the end).
/// Uses `min(values.len(), scales.len())` entries and fills `out` completely.
pub fn quantize_packed(values: &[f32], scales: &[f32], out: &mut [u32]) {
    let mut it = values.iter().zip(scales).map(|(&x, &s)| quantize(x, s));
    for word in out.iter_mut() {
        let lo = it.next().unwrap_or(0);
        let hi = it.next().unwrap_or(0);
        *word = super::pack(lo, hi);
    }
}

/// Smallest requantization shift: the result is then the high word of the product, shifted.
pub const MIN_SHIFT: u8 = 33;
/// Largest requantization shift.
pub const MAX_SHIFT: u8 = 62;

/// `round(acc * multiplier / 2^shift)` (ties towards +inf), for `shift` in
/// [`MIN_SHIFT`]`..=`[`MAX_SHIFT`] and `|acc * multiplier| < 2^62`.
///
/// With `shift >= 33` the rounding constant `2^(shift - 1)` has a zero low word, so
/// `(p + 2^(shift-1)) >> shift == (hi(p) + 2^(shift-33)) >> (shift - 32)` exactly: after
/// one 32 x 64 multiply everything is 32-bit arithmetic.
#[inline(always)]
pub fn requantize(acc: i64, multiplier: i32, shift: u8) -> i32 {
    // Masks instead of a clamp: the layer validated the range, and out-of-range shifts
    // still cannot panic.
    let down = (shift as u32).wrapping_sub(32) & 31;
    let hi = (acc.wrapping_mul(multiplier as i64) >> 32) as i32;
    hi.wrapping_add(1 << (down.wrapping_sub(1) & 31)) >> down
}

/// Saturates to `i16` (one `SSAT` on Arm).
#[inline(always)]
pub fn saturate_i16(v: i32) -> i16 {
    v.clamp(i16::MIN as i32, i16::MAX as i32) as i16
}

/// `2^bits` as `f32` (exact), for `bits` in -126..=127.
pub fn pow2(bits: i32) -> f32 {
    f32::from_bits(((bits.clamp(-126, 127) + 127) as u32) << 23)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantize_rounds_and_saturates() {
        assert_eq!(quantize(0.49, 1.0), 0);
        assert_eq!(quantize(0.5, 1.0), 1);
        assert_eq!(quantize(-0.5, 1.0), -1);
        assert_eq!(quantize(1.0, pow2(12)), 4096);
        assert_eq!(quantize(1e9, 1.0), i16::MAX);
        assert_eq!(quantize(-1e9, 1.0), i16::MIN);
        assert_eq!(quantize(f32::NAN, 1.0), 0);
    }

    #[test]
    fn requantize_rounds_to_nearest() {
        // 3 * 0.75 = 2.25 -> 2; 3 * 0.875 = 2.625 -> 3; -2.5 -> -2 (ties up).
        assert_eq!(requantize(3 << 31, 3, 33), 2);
        assert_eq!(requantize(3 << 30, 7, 33), 3);
        assert_eq!(requantize(-5 << 30, 1, 32 + 1), -1);
        assert_eq!(requantize(-5 << 33, 1, 34), -2);
        assert_eq!(pow2(-3), 0.125);
    }

    #[test]
    fn requantize_is_exact_rounding() {
        let mut state = 0x1234_5678_9abc_def0u64;
        for _ in 0..20_000 {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            let shift = 33 + (state >> 59) as u8 % 30;
            let multiplier = (state >> 33) as i32 & 0x3fff_ffff;
            let acc = (state as i64) >> 34; // |acc| < 2^30: |acc * m| < 2^60
            let exact = ((acc as i128 * multiplier as i128) + (1i128 << (shift - 1))) >> shift;
            assert_eq!(
                requantize(acc, multiplier, shift) as i128,
                exact,
                "{acc} {multiplier} {shift}"
            );
        }
    }
}
