//! Time stamps for a burst of IMU FIFO samples read together.
//!
//! The newest sample of a burst gets the read time; each older one the time of the next
//! minus the next one's ODR delta (the IMU's own sample spacing). Stamps always increase,
//! so the attitude filter, which skips a sample that is not newer than the previous one,
//! sees every sample. Plain `core` code: CI runs its tests on the host with `rustc --test`.

/// The time since the previous sample: the packet's ODR delta in `lsb_us` units, or the
/// nominal `period_us` when the packet has none or it is implausible (outside a quarter
/// to four periods, e.g. the first packet after a FIFO flush).
pub fn odr_delta_us(ticks: Option<u16>, lsb_us: u64, period_us: u64) -> u64 {
    match ticks {
        Some(ticks) => {
            let us = ticks as u64 * lsb_us;
            if (period_us / 4..=period_us * 4).contains(&us) {
                us
            } else {
                period_us
            }
        }
        None => period_us,
    }
}

/// Stamps a burst: `deltas_us[i]` is sample `i`'s time since sample `i - 1` (oldest first),
/// the newest sample was read at `read_us`, `last_us` is the previous burst's newest stamp
/// (updated). Writes `min(deltas_us.len(), out.len())` stamps into `out`.
pub fn stamp_burst(deltas_us: &[u64], read_us: u64, last_us: &mut u64, out: &mut [u64]) {
    let n = deltas_us.len().min(out.len());
    let span_us: u64 = deltas_us.iter().take(n).skip(1).sum();
    let mut t_us = read_us.saturating_sub(span_us);
    for (i, (delta_us, slot)) in deltas_us.iter().zip(out.iter_mut()).enumerate() {
        if i > 0 {
            t_us += delta_us;
        }
        let stamp = t_us.max(*last_us + 1);
        *slot = stamp;
        *last_us = stamp;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn newest_sample_gets_the_read_time_older_ones_their_deltas() {
        let mut last = 0;
        let mut out = [0; 3];
        stamp_burst(&[1000, 990, 1010], 50_000, &mut last, &mut out);
        assert_eq!(out, [48_000, 48_990, 50_000]);
        assert_eq!(last, 50_000);
    }

    #[test]
    fn stamps_increase_across_bursts() {
        let mut last = 49_800;
        let mut out = [0; 2];
        // The first sample would land before the previous burst's newest stamp.
        stamp_burst(&[1000, 1000], 50_500, &mut last, &mut out);
        assert_eq!(out, [49_801, 50_500]);
        // A burst read at the same microsecond as the previous one still moves forward.
        let mut one = [0; 1];
        stamp_burst(&[1000], 50_500, &mut last, &mut one);
        assert_eq!(one, [50_501]);
    }

    #[test]
    fn empty_burst_changes_nothing_and_output_limits_the_burst() {
        let mut last = 7;
        stamp_burst(&[], 100, &mut last, &mut []);
        assert_eq!(last, 7);
        let mut out = [0; 2];
        stamp_burst(&[1000, 1000, 1000], 10_000, &mut last, &mut out);
        assert_eq!(out, [9_000, 10_000]);
    }

    #[test]
    fn delta_falls_back_to_the_period_when_missing_or_implausible() {
        assert_eq!(odr_delta_us(Some(62), 16, 1000), 992);
        assert_eq!(odr_delta_us(None, 16, 1000), 1000);
        assert_eq!(odr_delta_us(Some(0), 16, 1000), 1000);
        assert_eq!(odr_delta_us(Some(1000), 16, 1000), 1000);
        assert_eq!(odr_delta_us(Some(250), 16, 1000), 4000);
    }
}
