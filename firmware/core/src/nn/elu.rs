//! ELU in fixed point: `x` for `x >= 0`, `exp(x) - 1` below, by a table with linear
//! interpolation.
//!
//! The table holds `exp(-k / 64) - 1` in Q15 for `k = 0..=1024` (inputs down to -16, where
//! `exp(x) - 1` is within 1.2e-7 of -1). It is computed at compile time with integer
//! arithmetic only (no float, no libm), so host and target hold the same bits. Linear
//! interpolation between entries 1/64 apart errs by at most `h^2 / 8 = 3.1e-5`.

/// Table steps per unit of input.
pub const ELU_STEPS_PER_UNIT_LOG2: u32 = 6;
/// Number of table intervals (inputs in [-16, 0]).
pub const ELU_TABLE_INTERVALS: usize = 1024;
/// Smallest fractional bit count of an ELU layer's output (one table step per input lsb at
/// most; Q6 spans +-512).
pub const ELU_MIN_FRAC_BITS: u8 = 6;
/// Largest fractional bit count of an ELU layer's output (Q15 table -> at least 1 bit shift).
pub const ELU_MAX_FRAC_BITS: u8 = 14;

/// `exp(-k / 64) - 1` in Q15, `k = 0..=1024`.
pub static ELU_TABLE_Q15: [i16; ELU_TABLE_INTERVALS + 1] = elu_table();

const ONE_Q62: i128 = 1 << 62;

/// `exp(-1/64)` in Q62 by its Taylor series (terms shrink by 64 n; 12 terms are exact to
/// well below 2^-62).
const fn exp_step_q62() -> i128 {
    let mut sum = ONE_Q62;
    let mut term = ONE_Q62;
    let mut n = 1;
    while n <= 12 {
        term = -term / (64 * n);
        sum += term;
        n += 1;
    }
    sum
}

const fn elu_table() -> [i16; ELU_TABLE_INTERVALS + 1] {
    let step = exp_step_q62();
    let mut table = [0i16; ELU_TABLE_INTERVALS + 1];
    let mut power = ONE_Q62; // exp(-k/64) in Q62
    let mut k = 0;
    while k <= ELU_TABLE_INTERVALS {
        let value_q62 = power - ONE_Q62; // in (-2^62, 0]
                                         // Round to Q15: divide by 2^47, to nearest (ties away from zero).
        let half = 1i128 << 46;
        let q15 = -((-value_q62 + half) >> 47);
        table[k] = if q15 < i16::MIN as i128 {
            i16::MIN
        } else {
            q15 as i16
        };
        power = (power * step) >> 62;
        k += 1;
    }
    table
}

/// ELU of a negative value `y` given in Q`frac_bits`, result in the same format.
/// `frac_bits` must be in [`ELU_MIN_FRAC_BITS`]`..=`[`ELU_MAX_FRAC_BITS`] (checked by the
/// layer; clamped here).
#[inline(always)]
pub fn elu_negative(y: i32, frac_bits: u8) -> i16 {
    let f = (frac_bits as u32).clamp(ELU_MIN_FRAC_BITS as u32, ELU_MAX_FRAC_BITS as u32);
    // Table position of u = -y: u * 64 / 2^f = u >> frac_len, remainder frac.
    let frac_len = f - ELU_STEPS_PER_UNIT_LOG2;
    let u = y.unsigned_abs();
    let index = (u >> frac_len) as usize;
    let value_q15 = match ELU_TABLE_Q15.get(index..index.saturating_add(2)) {
        Some(&[a, b]) => {
            let (a, b) = (a as i32, b as i32);
            let frac = (u & ((1 << frac_len) - 1)) as i32;
            a + (((b - a) * frac + ((1 << frac_len) >> 1)) >> frac_len)
        }
        // At or beyond -16: exp(x) - 1 is -1 to within the table's last entry.
        _ => ELU_TABLE_Q15[ELU_TABLE_INTERVALS] as i32,
    };
    // Q15 -> Q(f), rounding to nearest.
    let down = 15 - f;
    ((value_q15 + (1 << (down - 1))) >> down) as i16
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn table_matches_exp() {
        for (k, &t) in ELU_TABLE_Q15.iter().enumerate() {
            let exact = ((-(k as f64) / 64.0).exp() - 1.0) * 32768.0;
            assert!(
                (t as f64 - exact).abs() <= 0.5 + 1e-9,
                "{k}: {t} vs {exact}"
            );
        }
        assert_eq!(ELU_TABLE_Q15[0], 0);
    }

    #[test]
    fn negative_branch_is_accurate() {
        for frac_bits in [6u8, 8, 11, 14] {
            let lsb = 1.0 / (1u64 << frac_bits) as f64;
            for step in 1..4000 {
                let x = -(step as f64) * 0.00731;
                let y = (x / lsb).round() as i32;
                let got = elu_negative(y, frac_bits) as f64 * lsb;
                let want = (y as f64 * lsb).exp() - 1.0;
                assert!(
                    (got - want).abs() <= 0.5 * lsb + 5e-5,
                    "f{frac_bits} x {x}: {got} {want}"
                );
            }
            // Far below the table: -1 within a half lsb.
            let got = elu_negative(i32::MIN, frac_bits) as f64 * lsb;
            assert!((got + 1.0).abs() <= 0.5 * lsb + 1e-6);
        }
    }
}
