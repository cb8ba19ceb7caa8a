//! The trainer's candle forward pass and policy-codegen's f32 forward pass agree on a
//! checkpoint: the latter gives the reference outputs `policy-codegen export-onnx` writes
//! beside the ONNX model (which CI runs in onnxruntime), so the ONNX model is checked
//! against the network as trained.

use candle_core::{DType, Tensor};
use hexapod_core::obs::{ACTOR_OBS_DIM, HISTORY_DIM};
use std::path::Path;

#[test]
fn candle_and_the_onnx_reference_forward_pass_agree() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets/policies/flat-tripod");
    let (_cfg, ppo) = host_train::checkpoint::load_for_inference(&dir).unwrap();
    let reference = policy_codegen::checkpoint::load(&dir).unwrap().policy;
    // The inputs export-onnx writes (16 synthetic observations, seed 11).
    let recs = policy_codegen::records::synthetic(16, 11);
    let n = recs.len();
    let obs: Vec<f32> = recs.iter().flat_map(|r| r.actor_obs).collect();
    let hist: Vec<f32> = recs.iter().flat_map(|r| r.history).collect();
    let obs = Tensor::from_vec(obs, (n, ACTOR_OBS_DIM), &ppo.device).unwrap();
    let hist = Tensor::from_vec(hist, (n, HISTORY_DIM), &ppo.device).unwrap();
    let out = ppo.ac.policy(&obs, &hist).unwrap();
    let mean: Vec<Vec<f32>> = out.mean.to_dtype(DType::F32).unwrap().to_vec2().unwrap();
    let estimate: Vec<Vec<f32>> = out
        .estimate
        .unwrap()
        .to_dtype(DType::F32)
        .unwrap()
        .to_vec2()
        .unwrap();
    let (mut worst_action, mut worst_estimate, mut scale) = (0.0f32, 0.0f32, 0.0f32);
    for (i, r) in recs.iter().enumerate() {
        let t = reference.trace(&r.actor_obs, &r.history);
        for (a, b) in mean[i].iter().zip(t.actor.last().unwrap()) {
            worst_action = worst_action.max((a - b).abs());
            scale = scale.max(b.abs());
        }
        for (a, b) in estimate[i].iter().zip(t.estimator.last().unwrap()) {
            worst_estimate = worst_estimate.max((a - b).abs());
        }
    }
    eprintln!("candle vs f32 reference: max |da| = {worst_action:.2e} (max |a| {scale:.3}), max |dv_hat| = {worst_estimate:.2e}");
    assert!(
        worst_action <= 1e-5 * scale.max(1.0),
        "actions differ by {worst_action}"
    );
    assert!(
        worst_estimate <= 1e-5 * 3.0,
        "estimates differ by {worst_estimate}"
    );
}
