//! End-to-end checks of the code generator: freshness of the committed crate, accuracy
//! against f32, checkpoint validation, ONNX import.

use hexapod_core::nn::{Activation, Kernel};
use hexapod_core::obs::{ACTOR_OBS_DIM, HISTORY_DIM};
use policy_codegen::accuracy::{compare, HostScratch};
use policy_codegen::checkpoint::{self, Normalizer, TensorMap};
use policy_codegen::random::{random_policy, write_checkpoint, RandomSpec};
use policy_codegen::{emit, onnx, quantize_default, quantize_synthetic, records};
use std::path::{Path, PathBuf};

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn temp_dir(name: &str) -> PathBuf {
    let dir =
        std::env::temp_dir().join(format!("policy-codegen-test-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

/// Normalizer statistics of a synthetic observation set (a trained normalizer's kind).
fn empirical_normalizers(n: usize) -> (Normalizer, Normalizer) {
    let recs = records::synthetic(n, 99);
    let stats = |get: &dyn Fn(&records::ObsRecord) -> Vec<f32>, dim: usize| {
        let mut mean = vec![0.0f64; dim];
        let mut sq = vec![0.0f64; dim];
        for r in &recs {
            for (i, v) in get(r).into_iter().enumerate() {
                mean[i] += v as f64 / n as f64;
                sq[i] += (v as f64).powi(2) / n as f64;
            }
        }
        let std = mean
            .iter()
            .zip(&sq)
            .map(|(m, s)| ((s - m * m).max(0.0).sqrt() + 1e-2) as f32)
            .collect();
        Normalizer {
            mean: mean.iter().map(|&m| m as f32).collect(),
            std,
        }
    };
    (
        stats(&|r| r.actor_obs.to_vec(), ACTOR_OBS_DIM),
        stats(&|r| r.history.to_vec(), HISTORY_DIM),
    )
}

#[test]
fn committed_policy_crate_is_fresh() {
    let dir = repo().join(policy_codegen::SHIPPED_CHECKPOINT);
    let ck = checkpoint::load(&dir).unwrap();
    let q = quantize_default(&ck.policy).unwrap();
    let prov = emit::Provenance {
        checkpoint: policy_codegen::SHIPPED_CHECKPOINT.into(),
        sha256: ck.sha256.clone(),
        macs: ck.policy.macs(),
    };
    let files = emit::generate(&prov, &q).unwrap();
    let stale = emit::stale(&repo().join("firmware/policy"), &files);
    assert!(stale.is_empty(), "regenerate firmware/policy: {stale:?}");
    assert_eq!(hexapod_policy::SOURCE_SHA256, ck.sha256);
    assert_eq!(hexapod_policy::MACS, 352_096);
}

#[test]
fn calibration_set_adds_the_policys_own_closed_loop_deterministically() {
    let policy = random_policy(&RandomSpec {
        seed: 5,
        output_gain: 0.5,
        ..Default::default()
    });
    let a = policy_codegen::calibration_set(&policy, 2, 20).unwrap();
    let b = policy_codegen::calibration_set(&policy, 2, 20).unwrap();
    let synthetic = policy_codegen::CALIBRATION_COUNT;
    // Two rollouts (flat, terrain) of 2 robots x 20 steps after the synthetic set.
    assert_eq!(a.len(), synthetic + 2 * 2 * 20);
    assert_eq!(a, b);
    assert_eq!(
        a[..synthetic],
        records::synthetic(synthetic, policy_codegen::CALIBRATION_SEED)[..]
    );
    assert!(a[synthetic..].iter().all(|r| r
        .actor_obs
        .iter()
        .chain(&r.history)
        .all(|v| v.is_finite())));
    // The flat and the terrain rollouts differ (other seed, other ground).
    assert_ne!(a[synthetic + 40..], a[synthetic..synthetic + 40]);
}

#[test]
fn random_checkpoint_is_deterministic_and_loads() {
    let dir = temp_dir("random");
    let spec = RandomSpec::default();
    let sha_a = write_checkpoint(&dir, &random_policy(&spec), &spec).unwrap();
    let sha_b = write_checkpoint(&dir, &random_policy(&spec), &spec).unwrap();
    assert_eq!(sha_a, sha_b);
    let committed = checkpoint::load(&repo().join("assets/policies/random-init")).unwrap();
    assert_eq!(
        committed.sha256, sha_a,
        "assets/policies/random-init is not `random-checkpoint --seed 0`"
    );
    let ck = checkpoint::load(&dir).unwrap();
    assert_eq!(ck.policy, random_policy(&spec));
}

#[test]
fn fixed_point_follows_f32_with_large_actions_and_real_normalizers() {
    // Output gain 0.5 gives actions up to a few units (a trained policy's range); the
    // normalizers have the spread of real statistics, so folding them is exercised.
    let spec = RandomSpec {
        seed: 5,
        output_gain: 0.5,
        ..Default::default()
    };
    let mut policy = random_policy(&spec);
    let (actor_norm, history_norm) = empirical_normalizers(2000);
    policy.actor_obs_norm = actor_norm;
    policy.history_norm = history_norm;
    let q = quantize_synthetic(&policy).unwrap();
    let report = compare(&policy, &q, &records::synthetic(1500, 3)).unwrap();
    eprintln!("{report:?}");
    assert!(report.max_abs_action > 2.0, "{report:?}");
    assert!(report.max_abs_diff <= 2e-3, "{report:?}");
}

#[test]
fn runner_step_matches_the_observation_step() {
    let q = quantize_synthetic(&random_policy(&RandomSpec::default())).unwrap();
    let recs = records::synthetic(1, 11);
    q.with_view(|view| {
        let mut runner = hexapod_core::nn::PolicyRunner::<'_, 1024>::new(view).unwrap();
        let newest: [f32; 42] = recs[0].history[HISTORY_DIM - 42..].try_into().unwrap();
        let out = runner.step([0.3, 0.0, 0.1], &newest).unwrap();
        // After a reset the history is the current frame repeated, the previous action 0.
        let obs = hexapod_core::obs::actor_obs([0.3, 0.0, 0.1], &[0.0; 18], &newest);
        let history = hexapod_core::obs::ProprioHistory::filled_with(&newest).flatten();
        let mut scratch = Box::new(HostScratch::default());
        let want = view
            .step_obs(&mut scratch, &obs, &history, Kernel::Portable)
            .unwrap();
        assert_eq!(out, want);
        assert!(out.q_target_rad.iter().all(|q| q.is_finite()));
    });
}

#[test]
fn malformed_checkpoints_are_refused_with_the_key() {
    let spec = RandomSpec {
        memory_hidden: vec![32],
        actor_hidden: vec![16],
        estimator_hidden: Some(vec![8]),
        ..Default::default()
    };
    let policy = random_policy(&spec);
    let dir = temp_dir("malformed");
    write_checkpoint(&dir, &policy, &spec).unwrap();
    checkpoint::load(&dir).unwrap();

    // Config that contradicts the tensors, then config that is not TOML.
    std::fs::write(dir.join("config.toml"), "[policy]\nmemory_latent = 8\n").unwrap();
    let err = checkpoint::load(&dir).err().unwrap().to_string();
    assert!(err.contains("memory_latent"), "{err}");
    std::fs::write(dir.join("config.toml"), "[policy\nmemory_latent = 16\n").unwrap();
    assert!(matches!(
        checkpoint::load(&dir),
        Err(checkpoint::CheckpointError::Config { .. })
    ));

    // A broken chain names the key and the shapes.
    let mut tensors = std::collections::HashMap::new();
    for (k, s, v) in policy_codegen::random::policy_tensors(&policy) {
        tensors.insert(k, (s, v));
    }
    tensors.insert(
        "memory.layers.1.weight".into(),
        (vec![16, 31], vec![0.0; 16 * 31]),
    );
    let err = TensorMap::from_tensors(tensors)
        .policy()
        .err()
        .unwrap()
        .to_string();
    assert!(
        err.contains("memory.layers.1.weight") && err.contains("[16, 31]"),
        "{err}"
    );
}

#[test]
fn onnx_mlp_imports_and_quantizes() {
    // A plain ReLU actor as rsl_rl exports it: Sub/Div normalization, Gemm layers.
    let spec = RandomSpec {
        seed: 3,
        output_gain: 1.0,
        ..Default::default()
    };
    let mut policy = random_policy(&spec);
    policy.estimator = Default::default();
    policy.memory = Default::default();
    let mut actor = random_policy(&RandomSpec {
        seed: 4,
        ..spec.clone()
    })
    .actor;
    actor.layers[0] = policy_codegen::checkpoint::DenseF32 {
        in_dim: ACTOR_OBS_DIM,
        out_dim: actor.layers[0].out_dim,
        weight: actor.layers[0].weight[..actor.layers[0].out_dim * ACTOR_OBS_DIM].to_vec(),
        bias: vec![0.05; actor.layers[0].out_dim],
    };
    actor.hidden = Activation::Relu;
    policy.actor = actor;
    policy.actor_obs_norm = empirical_normalizers(500).0;
    let bytes = onnx::export(&policy);
    let imported = onnx::import(&bytes).unwrap();
    assert_eq!(imported, policy);

    let q = quantize_synthetic(&imported).unwrap();
    let report = compare(&imported, &q, &records::synthetic(500, 8)).unwrap();
    assert!(report.max_abs_diff <= 2e-3, "{report:?}");

    // An unsupported operator is named.
    let mut model = <onnx::ModelProto as prost::Message>::decode(&bytes[..]).unwrap();
    model.graph.as_mut().unwrap().node[3].op_type = "Tanh".into();
    let err = onnx::import(&prost::Message::encode_to_vec(&model))
        .err()
        .unwrap()
        .to_string();
    assert!(err.contains("Tanh"), "{err}");
}

#[test]
fn closed_loop_in_the_simulator_matches_f32() {
    let spec = RandomSpec {
        seed: 5,
        output_gain: 0.5,
        ..Default::default()
    };
    let policy = random_policy(&spec);
    let q = quantize_synthetic(&policy).unwrap();
    let (f, x, recorded) = policy_codegen::sim::compare_closed_loop(&policy, &q, 2, 40, 3).unwrap();
    assert_eq!(recorded.len(), 80);
    let report = compare(&policy, &q, &recorded).unwrap();
    assert!(report.max_abs_diff <= 2e-3, "{report:?}");
    assert!(f.mean_abs_action > 0.05, "{f:?}");
    assert!(
        (f.mean_abs_action - x.mean_abs_action).abs() < 0.02 * f.mean_abs_action,
        "{f:?} {x:?}"
    );
    // Rewards of an untrained policy nearly cancel (task terms vs penalties): compare the
    // motion instead.
    assert!((f.mean_vx_m_s - x.mean_vx_m_s).abs() < 0.01, "{f:?} {x:?}");
    assert_eq!(f.falls_per_robot, x.falls_per_robot, "{f:?} {x:?}");
}

#[test]
fn onnx_matmul_add_graphs_import_like_gemm() {
    use policy_codegen::onnx::{float_tensor, GraphProto, ModelProto, NodeProto, ValueInfoProto};
    // A PyTorch-style export without Gemm: MatMul with W^T ([in, out]) then Add, Elu between.
    let spec = RandomSpec {
        seed: 9,
        actor_hidden: vec![24],
        output_gain: 1.0,
        ..Default::default()
    };
    let mut policy = random_policy(&spec);
    policy.estimator = Default::default();
    policy.memory = Default::default();
    policy.actor = random_policy(&RandomSpec {
        estimator_hidden: None,
        memory_latent: 0,
        ..spec.clone()
    })
    .actor;
    assert_eq!(policy.actor.in_dim(), ACTOR_OBS_DIM);
    let node = |op: &str, inputs: &[&str], output: &str| NodeProto {
        input: inputs.iter().map(|s| s.to_string()).collect(),
        output: vec![output.into()],
        name: output.into(),
        op_type: op.into(),
        attribute: vec![],
    };
    let mut initializer = Vec::new();
    let mut nodes = Vec::new();
    let mut current = "obs".to_string();
    for (k, l) in policy.actor.layers.iter().enumerate() {
        let mut wt = vec![0.0; l.weight.len()];
        for r in 0..l.out_dim {
            for c in 0..l.in_dim {
                wt[c * l.out_dim + r] = l.weight[r * l.in_dim + c];
            }
        }
        initializer.push(float_tensor(&format!("w{k}"), &[l.in_dim, l.out_dim], &wt));
        initializer.push(float_tensor(&format!("b{k}"), &[l.out_dim], &l.bias));
        nodes.push(node(
            "MatMul",
            &[&current, &format!("w{k}")],
            &format!("m{k}"),
        ));
        nodes.push(node(
            "Add",
            &[&format!("m{k}"), &format!("b{k}")],
            &format!("y{k}"),
        ));
        current = format!("y{k}");
        if k + 1 < policy.actor.layers.len() {
            nodes.push(node("Elu", &[&current], &format!("e{k}")));
            current = format!("e{k}");
        }
    }
    let model = ModelProto {
        ir_version: 8,
        producer_name: "test".into(),
        doc_string: String::new(),
        graph: Some(GraphProto {
            node: nodes,
            name: "actor".into(),
            initializer,
            input: vec![ValueInfoProto::named("obs")],
            output: vec![ValueInfoProto::named(&current)],
        }),
        opset_import: vec![],
    };
    let imported = onnx::import(&prost::Message::encode_to_vec(&model)).unwrap();
    assert_eq!(imported, policy);
    let q = quantize_synthetic(&imported).unwrap();
    let report = compare(&imported, &q, &records::synthetic(300, 4)).unwrap();
    assert!(report.max_abs_diff <= 2e-3, "{report:?}");
}

#[test]
fn exported_policies_import_as_the_same_networks() {
    // The shipped checkpoint (estimator, memory, actor, trained normalizers).
    let shipped = checkpoint::load(&repo().join(policy_codegen::SHIPPED_CHECKPOINT))
        .unwrap()
        .policy;
    let model = onnx::export_model(&shipped);
    let graph = model.graph.as_ref().unwrap();
    let names = |v: &[onnx::ValueInfoProto]| v.iter().map(|v| v.name.clone()).collect::<Vec<_>>();
    assert_eq!(
        names(&graph.input),
        [onnx::ACTOR_OBS_INPUT, onnx::HISTORY_INPUT]
    );
    assert_eq!(
        names(&graph.output),
        [
            onnx::ACTIONS_OUTPUT,
            onnx::ESTIMATE_OUTPUT,
            onnx::LATENT_OUTPUT
        ]
    );
    assert!(graph
        .input
        .iter()
        .chain(&graph.output)
        .all(|v| v.r#type.is_some()));
    let bytes = onnx::export(&shipped);
    assert_eq!(onnx::import(&bytes).unwrap(), shipped);

    // Without an estimator ("Baseline"), and actor-only.
    let mut baseline = random_policy(&RandomSpec {
        seed: 12,
        estimator_hidden: None,
        ..Default::default()
    });
    baseline.history_norm = empirical_normalizers(200).1;
    assert!(baseline.estimator.layers.is_empty());
    assert_eq!(onnx::import(&onnx::export(&baseline)).unwrap(), baseline);
    let mut actor_only = random_policy(&RandomSpec {
        seed: 13,
        estimator_hidden: None,
        memory_latent: 0,
        actor_hidden: vec![32],
        ..Default::default()
    });
    actor_only.estimator = Default::default();
    actor_only.memory = Default::default();
    let model = onnx::export_model(&actor_only);
    assert_eq!(model.graph.as_ref().unwrap().input.len(), 1);
    assert_eq!(
        onnx::import(&onnx::export(&actor_only)).unwrap(),
        actor_only
    );

    // The reference outputs are the f32 forward pass.
    let recs = records::synthetic(3, 11);
    let json = onnx::reference_json(&shipped, &recs, "x", "y");
    let a0 = shipped
        .trace(&recs[0].actor_obs, &recs[0].history)
        .actor
        .pop()
        .unwrap();
    assert!(json.contains(&format!("[{}", a0[0])), "{json:.200}");

    // A graph whose Concat drops the latent is refused, naming the node.
    let mut model = onnx::export_model(&shipped);
    let concat = model
        .graph
        .as_mut()
        .unwrap()
        .node
        .iter_mut()
        .find(|n| n.op_type == "Concat")
        .unwrap();
    concat.input.pop();
    let err = onnx::import(&prost::Message::encode_to_vec(&model))
        .err()
        .unwrap()
        .to_string();
    assert!(err.contains("actor_input"), "{err}");
}
