//! `policy-codegen`: trained checkpoint -> fixed-point Rust (`hexapod-policy`).
//!
//! Reads a checkpoint ([`checkpoint`]) or an ONNX MLP ([`onnx`]), calibrates and
//! quantizes it ([`quantize`]) for `hexapod_core::nn`, writes the generated crate
//! ([`emit`]), reports fixed-point vs f32 accuracy ([`accuracy`]), exports the deployed
//! networks as ONNX ([`onnx::export`]) and checks a firmware ELF against the STM32H743's
//! memory map ([`size`]).

pub mod accuracy;
pub mod bench;
pub mod checkpoint;
pub mod emit;
pub mod forward;
pub mod onnx;
pub mod quantize;
pub mod random;
pub mod records;
pub mod sim;
pub mod size;

/// The checkpoint `firmware/policy` is generated from: the shipped terrain policy (the paper's
/// recipe on the tile curriculum, stairs and slopes, its last 1,000 iterations' weights
/// averaged; `assets/policies/terrain-averaged/README.md`).
pub const SHIPPED_CHECKPOINT: &str = "assets/policies/terrain-averaged";

/// Synthetic observations in the calibration set ([`records::synthetic`]). 20,000: with 2,000
/// (and the closed loop) `terrain-descend`'s fixed point left f32 by 4.7e-3 on other
/// synthetic observations (1.8e-3 with 20,000; BENCHMARKS.md, fixed point).
pub const CALIBRATION_COUNT: usize = 20_000;
/// Seed of the synthetic calibration observations.
pub const CALIBRATION_SEED: u64 = 1;
/// Robots of each calibration rollout in host-sim.
pub const CALIBRATION_ROBOTS: usize = 16;
/// Policy steps (50 per second) of each calibration rollout.
pub const CALIBRATION_STEPS: usize = 500;
/// Seeds of the calibration rollouts, flat ground then terrain: apart from the seeds
/// `sim-compare` measures with (1..=N), so the accuracy it reports is on observations the
/// calibration did not see.
pub const CALIBRATION_ROLLOUT_SEEDS: [u64; 2] = [101, 102];

/// The calibration set: the synthetic observations, then the observations the f32 policy
/// itself visits in host-sim ([`CALIBRATION_ROBOTS`] robots for [`CALIBRATION_STEPS`]
/// steps on flat ground and on the terrain tiles). The synthetic set alone misses the
/// memory network's largest activations: its histories lack a real gait's structure, and a
/// trained policy's fixed point then saturates in closed loop (BENCHMARKS.md, fixed point).
/// Deterministic: the simulator and the f32 forward pass are.
pub fn calibration_set(
    policy: &checkpoint::PolicyF32,
    robots: usize,
    steps: usize,
) -> anyhow::Result<Vec<records::ObsRecord>> {
    let mut set = records::synthetic(CALIBRATION_COUNT, CALIBRATION_SEED);
    let [flat_seed, terrain_seed] = CALIBRATION_ROLLOUT_SEEDS;
    for config in [
        sim::flat_config(robots, flat_seed),
        sim::terrain_config(robots, terrain_seed),
    ] {
        sim::closed_loop(|o, h| policy.act(o, h), config, steps, Some(&mut set))?;
    }
    Ok(set)
}

/// Calibrates on [`calibration_set`] and quantizes: what `generate` ships.
pub fn quantize_default(policy: &checkpoint::PolicyF32) -> anyhow::Result<quantize::OwnedPolicy> {
    let records = calibration_set(policy, CALIBRATION_ROBOTS, CALIBRATION_STEPS)?;
    let cal = quantize::calibrate(policy, &records)?;
    Ok(quantize::quantize_policy(policy, &cal)?)
}

/// Calibrates on the synthetic observations only (no simulator): for networks that do not
/// drive the robot (random initializations in tests).
pub fn quantize_synthetic(
    policy: &checkpoint::PolicyF32,
) -> Result<quantize::OwnedPolicy, quantize::QuantError> {
    let records = records::synthetic(CALIBRATION_COUNT, CALIBRATION_SEED);
    let cal = quantize::calibrate(policy, &records)?;
    quantize::quantize_policy(policy, &cal)
}
