//! The inner loop: two weight rows against one packed `i16` input vector, exact `i64` sums.
//!
//! Each input word (two elements) meets one weight word of each row: a dual 16 x 16
//! multiply with a 64-bit accumulate. On Cortex-M cores with the DSP extension
//! (`cfg(arm_dsp)`, set by the build script for thumbv7em / thumbv8m.main) that is one
//! `SMLALD` per word through stable inline assembly; elsewhere the same arithmetic in
//! portable Rust. Both are exact (no wrap-around), so they agree bit for bit.
//!
//! `i64` accumulators cost nothing extra on the Cortex-M7 (SMLALD issues like SMLAD) and
//! remove any overflow question: a 512-input row sums at most 2^40 in magnitude.

/// `acc + lo(x) * lo(w) + hi(x) * hi(w)`, exact, portable.
#[inline(always)]
pub fn mac2_portable(acc: i64, x: u32, w: u32) -> i64 {
    let p_lo = (x as u16 as i16 as i32) * (w as u16 as i16 as i32);
    let p_hi = ((x >> 16) as u16 as i16 as i32) * ((w >> 16) as u16 as i16 as i32);
    acc + p_lo as i64 + p_hi as i64
}

/// `acc + lo(x) * lo(w) + hi(x) * hi(w)`, exact, one `SMLALD`.
#[cfg(all(target_arch = "arm", arm_dsp))]
#[inline(always)]
pub fn mac2_dsp(acc: i64, x: u32, w: u32) -> i64 {
    let mut lo = acc as u32;
    let mut hi = (acc >> 32) as u32;
    // SAFETY: SMLALD only reads and writes the named registers.
    unsafe {
        core::arch::asm!(
            "smlald {lo}, {hi}, {x}, {w}",
            lo = inout(reg) lo,
            hi = inout(reg) hi,
            x = in(reg) x,
            w = in(reg) w,
            options(pure, nomem, nostack, preserves_flags),
        );
    }
    (((hi as u64) << 32) | lo as u64) as i64
}

/// The dual multiply-accumulate of this build: SMLALD on DSP cores, portable elsewhere.
#[inline(always)]
pub fn mac2(acc: i64, x: u32, w: u32) -> i64 {
    #[cfg(all(target_arch = "arm", arm_dsp))]
    {
        mac2_dsp(acc, x, w)
    }
    #[cfg(not(all(target_arch = "arm", arm_dsp)))]
    {
        mac2_portable(acc, x, w)
    }
}

/// Dot products of the row pair `w` (interleaved: word `2k` row 0, `2k + 1` row 1) with the
/// packed input `x`, added to `acc`. Uses `min(x.len(), w.len() / 2)` input words.
#[inline(always)]
pub fn dot_row_pair(w: &[u32], x: &[u32], acc: (i64, i64)) -> (i64, i64) {
    #[cfg(all(target_arch = "arm", arm_dsp))]
    {
        dot_row_pair_dsp(w, x, acc)
    }
    #[cfg(not(all(target_arch = "arm", arm_dsp)))]
    {
        dot_row_pair_portable(w, x, acc)
    }
}

/// [`dot_row_pair`] on DSP cores: a hand-scheduled loop over four input words (16 MACs in
/// 16 instructions: two 64-bit input loads, four 64-bit weight loads, eight SMLALD, the
/// loop counter and branch), then the remaining words one SMLALD pair at a time.
#[cfg(all(target_arch = "arm", arm_dsp))]
#[inline(always)]
pub fn dot_row_pair_dsp(w: &[u32], x: &[u32], acc: (i64, i64)) -> (i64, i64) {
    let n = x.len().min(w.len() / 2);
    let blocks = n / 4;
    let (mut a0, mut a1) = acc;
    if blocks > 0 {
        let (mut lo0, mut hi0) = (a0 as u32, (a0 >> 32) as u32);
        let (mut lo1, mut hi1) = (a1 as u32, (a1 >> 32) as u32);
        // SAFETY: reads `4 * blocks <= n` words of `x` and `8 * blocks <= w.len()` words of
        // `w` (both word-aligned slices); writes only the named registers.
        unsafe {
            core::arch::asm!(
                "2:",
                "ldrd {x0}, {x1}, [{xp}], #8",
                "ldrd {w0}, {w1}, [{wp}], #8",
                "smlald {lo0}, {hi0}, {x0}, {w0}",
                "smlald {lo1}, {hi1}, {x0}, {w1}",
                "ldrd {w0}, {w1}, [{wp}], #8",
                "smlald {lo0}, {hi0}, {x1}, {w0}",
                "smlald {lo1}, {hi1}, {x1}, {w1}",
                "ldrd {x0}, {x1}, [{xp}], #8",
                "ldrd {w0}, {w1}, [{wp}], #8",
                "smlald {lo0}, {hi0}, {x0}, {w0}",
                "smlald {lo1}, {hi1}, {x0}, {w1}",
                "ldrd {w0}, {w1}, [{wp}], #8",
                "smlald {lo0}, {hi0}, {x1}, {w0}",
                "smlald {lo1}, {hi1}, {x1}, {w1}",
                "subs {n}, {n}, #1",
                "bne 2b",
                xp = inout(reg) x.as_ptr() => _,
                wp = inout(reg) w.as_ptr() => _,
                n = inout(reg) blocks => _,
                lo0 = inout(reg) lo0,
                hi0 = inout(reg) hi0,
                lo1 = inout(reg) lo1,
                hi1 = inout(reg) hi1,
                x0 = out(reg) _,
                x1 = out(reg) _,
                w0 = out(reg) _,
                w1 = out(reg) _,
                options(nostack, readonly),
            );
        }
        a0 = (((hi0 as u64) << 32) | lo0 as u64) as i64;
        a1 = (((hi1 as u64) << 32) | lo1 as u64) as i64;
    }
    let done = 4 * blocks;
    let tail_w = w.get(2 * done..2 * n).unwrap_or(&[]);
    let tail_x = x.get(done..n).unwrap_or(&[]);
    for (wc, &xw) in tail_w.chunks_exact(2).zip(tail_x) {
        if let [w0, w1] = wc {
            a0 = mac2_dsp(a0, xw, *w0);
            a1 = mac2_dsp(a1, xw, *w1);
        }
    }
    (a0, a1)
}

/// The same as [`dot_row_pair`], in portable Rust on every target (for benchmarks and tests).
pub fn dot_row_pair_portable(w: &[u32], x: &[u32], acc: (i64, i64)) -> (i64, i64) {
    let (mut a0, mut a1) = acc;
    for (wc, &xw) in w.chunks_exact(2).zip(x) {
        if let [w0, w1] = wc {
            a0 = mac2_portable(a0, xw, *w0);
            a1 = mac2_portable(a1, xw, *w1);
        }
    }
    (a0, a1)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::nn::pack;

    #[test]
    fn extremes_are_exact() {
        let x = pack(i16::MIN, i16::MIN);
        let w = pack(i16::MIN, i16::MIN);
        assert_eq!(mac2_portable(0, x, w), 2 * (1i64 << 30));
        let w = pack(i16::MAX, -1);
        assert_eq!(mac2_portable(5, x, w), 5 - 32768 * 32767 + 32768);
    }

    #[test]
    fn row_pair_matches_scalar_sums() {
        // Odd word count exercises the remainder.
        let n = 7;
        let xs: [i16; 14] = core::array::from_fn(|i| (i as i16).wrapping_mul(4099) ^ 0x5a5a);
        let r0: [i16; 14] = core::array::from_fn(|i| (i as i16).wrapping_mul(-7919));
        let r1: [i16; 14] = core::array::from_fn(|i| 32767 - (i as i16) * 1000);
        let x: [u32; 7] = core::array::from_fn(|k| pack(xs[2 * k], xs[2 * k + 1]));
        let mut w = [0u32; 14];
        for k in 0..n {
            w[2 * k] = pack(r0[2 * k], r0[2 * k + 1]);
            w[2 * k + 1] = pack(r1[2 * k], r1[2 * k + 1]);
        }
        let want0: i64 = (0..14).map(|i| xs[i] as i64 * r0[i] as i64).sum::<i64>() + 3;
        let want1: i64 = (0..14).map(|i| xs[i] as i64 * r1[i] as i64).sum::<i64>() - 3;
        assert_eq!(dot_row_pair(&w, &x, (3, -3)), (want0, want1));
        assert_eq!(dot_row_pair_portable(&w, &x, (3, -3)), (want0, want1));
    }
}
