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
/// recipe on the tile curriculum, stairs and slopes; `assets/policies/terrain-reach/README.md`).
pub const SHIPPED_CHECKPOINT: &str = "assets/policies/terrain-reach";

/// Observations used for calibration (synthetic, seed 1).
pub const CALIBRATION_COUNT: usize = 2000;
/// Seed of the calibration set.
pub const CALIBRATION_SEED: u64 = 1;

/// Calibrates on the synthetic set and quantizes.
pub fn quantize_default(
    policy: &checkpoint::PolicyF32,
) -> Result<quantize::OwnedPolicy, quantize::QuantError> {
    let records = records::synthetic(CALIBRATION_COUNT, CALIBRATION_SEED);
    let cal = quantize::calibrate(policy, &records)?;
    quantize::quantize_policy(policy, &cal)
}
