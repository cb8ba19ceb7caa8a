//! The QEMU benchmark's output and the host's reference for it.
//!
//! `firmware/qemu-bench` runs `hexapod_policy::POLICY` on [`hexapod_core::nn::bench`]'s
//! input with seed [`BENCH_INPUT_SEED`] and prints the raw actions; the host quantizes the
//! same checkpoint (what `generate --check` proves the crate holds) and runs the same step
//! with its portable kernel, and the two must agree bit for bit.

use crate::accuracy::HostScratch;
use hexapod_core::nn::bench::bench_input;
use hexapod_core::nn::{Kernel, NnError, QuantizedPolicy};
use hexapod_core::NUM_JOINTS;

/// Seed of the benchmark input (the same constant is in `firmware/qemu-bench`).
pub const BENCH_INPUT_SEED: u32 = 7;

/// What the benchmark printed.
#[derive(Clone, Debug, PartialEq)]
pub struct BenchOutput {
    /// Raw fixed-point actions.
    pub action_q: [i16; NUM_JOINTS],
    /// Instructions of one step with the SMLALD kernel.
    pub smlald_insns: f32,
    /// Instructions per MAC, SMLALD kernel.
    pub smlald_per_mac: f32,
    /// Instructions per MAC, portable kernel.
    pub portable_per_mac: f32,
}

/// Parses the benchmark's stdout.
pub fn parse(text: &str) -> anyhow::Result<BenchOutput> {
    let line = |prefix: &str| {
        text.lines()
            .find_map(|l| l.trim().strip_prefix(prefix))
            .ok_or_else(|| anyhow::anyhow!("no `{prefix}` line in the benchmark output"))
    };
    let values: Vec<i16> = line("action_q:")?
        .split_whitespace()
        .map(str::parse)
        .collect::<Result<_, _>>()?;
    let action_q: [i16; NUM_JOINTS] = values
        .try_into()
        .map_err(|v: Vec<i16>| anyhow::anyhow!("{} actions, expected {NUM_JOINTS}", v.len()))?;
    let numbers = |prefix: &str| -> anyhow::Result<(f32, f32)> {
        let rest = line(prefix)?;
        let nums: Vec<f32> = rest
            .split_whitespace()
            .filter_map(|t| t.parse().ok())
            .collect();
        match nums[..] {
            [per_step, per_mac] => Ok((per_step, per_mac)),
            _ => anyhow::bail!("cannot read `{prefix}{rest}`"),
        }
    };
    let (smlald_insns, smlald_per_mac) = numbers("smlald:")?;
    let (_, portable_per_mac) = numbers("portable:")?;
    Ok(BenchOutput {
        action_q,
        smlald_insns,
        smlald_per_mac,
        portable_per_mac,
    })
}

/// The host's raw actions for the benchmark input.
pub fn host_action_q(policy: &QuantizedPolicy<'_>) -> Result<[i16; NUM_JOINTS], NnError> {
    let (obs, history) = bench_input(BENCH_INPUT_SEED);
    let mut scratch = Box::new(HostScratch::default());
    Ok(policy
        .step_obs(&mut scratch, &obs, &history, Kernel::Native)?
        .action_q)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_the_benchmark_output() {
        let text = "action_q: 1 -2 3 4 5 6 7 8 9 10 11 12 13 14 15 16 17 -18\nmacs: 352096\n\
                    smlald: instructions/step 518200 instructions/MAC 1.472\n\
                    portable: instructions/step 947920 instructions/MAC 2.692\n";
        let b = parse(text).unwrap();
        assert_eq!(b.action_q[1], -2);
        assert_eq!(b.action_q[17], -18);
        assert_eq!(b.smlald_insns, 518200.0);
        assert_eq!(b.portable_per_mac, 2.692);
        assert!(parse("action_q: 1 2\n").is_err());
    }
}
