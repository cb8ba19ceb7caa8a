//! Conversions at the edges of the integer pipeline and between layers.
//!
//! Input: `round(x * scale)` saturated to `i16`, with `scale` a power of two (exact multiply)
//! and `libm::roundf` (integer bit manipulation: the same bits on every target).
//! Between layers: `round(acc * multiplier / 2^shift)` in `i64`; `policy-codegen` chooses
//! the multiplier's width per channel so the product cannot overflow.

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

/// `round(acc * multiplier / 2^shift)` (ties towards +inf), `shift` in `1..=62`.
#[inline(always)]
pub fn requantize(acc: i64, multiplier: i32, shift: u8) -> i64 {
    let shift = (shift as u32).clamp(1, 62);
    let product = acc.wrapping_mul(multiplier as i64);
    product.wrapping_add(1i64 << (shift - 1)) >> shift
}

/// Saturates to `i16`.
#[inline(always)]
pub fn saturate_i16(v: i64) -> i16 {
    v.clamp(i16::MIN as i64, i16::MAX as i64) as i16
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
        assert_eq!(requantize(3, 3, 2), 2);
        assert_eq!(requantize(3, 7, 3), 3);
        assert_eq!(requantize(-5, 1, 1), -2);
        assert_eq!(pow2(-3), 0.125);
    }
}
