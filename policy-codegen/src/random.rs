//! A randomly initialized checkpoint of the right shapes (until a trained one exists).
//!
//! Hidden layers: Kaiming-normal weights for ELU (`std = sqrt(2 / in)`), zero bias; output
//! layers: the same scaled by `output_gain` (small, as policy heads are initialized).
//! Normalizers: mean 0, std 1. Deterministic for a seed.

use crate::checkpoint::{sha256_hex, CheckpointError, DenseF32, MlpF32, Normalizer, PolicyF32};
use hexapod_core::nets::{
    ACTOR_HIDDEN, ACTOR_OUT, ESTIMATOR_HIDDEN, ESTIMATOR_OUT, MEMORY_HIDDEN, MEMORY_LATENT,
};
use hexapod_core::obs::{ACTOR_OBS_DIM, HISTORY_DIM};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use safetensors::tensor::TensorView;
use safetensors::Dtype;
use std::path::Path;

/// Shapes and init of a random policy.
#[derive(Clone, Debug)]
pub struct RandomSpec {
    /// Seed.
    pub seed: u64,
    /// Estimator hidden sizes (`None`: no estimator).
    pub estimator_hidden: Option<Vec<usize>>,
    /// Memory hidden sizes.
    pub memory_hidden: Vec<usize>,
    /// Memory latent size.
    pub memory_latent: usize,
    /// Actor hidden sizes.
    pub actor_hidden: Vec<usize>,
    /// Scale of the output layers' init.
    pub output_gain: f32,
}

impl Default for RandomSpec {
    fn default() -> Self {
        Self {
            seed: 0,
            estimator_hidden: Some(ESTIMATOR_HIDDEN.to_vec()),
            memory_hidden: MEMORY_HIDDEN.to_vec(),
            memory_latent: MEMORY_LATENT,
            actor_hidden: ACTOR_HIDDEN.to_vec(),
            output_gain: 0.1,
        }
    }
}

fn random_mlp(
    rng: &mut ChaCha8Rng,
    input: usize,
    hidden: &[usize],
    output: usize,
    gain: f32,
) -> MlpF32 {
    let mut sizes = vec![input];
    sizes.extend_from_slice(hidden);
    sizes.push(output);
    let n = sizes.len() - 1;
    let layers = (0..n)
        .map(|k| {
            let (in_dim, out_dim) = (sizes[k], sizes[k + 1]);
            let std = (2.0 / in_dim as f32).sqrt() * if k + 1 == n { gain } else { 1.0 };
            let dist = Normal::new(0.0, std)
                .unwrap_or_else(|_| Normal::new(0.0, 1.0).expect("unit normal"));
            DenseF32 {
                in_dim,
                out_dim,
                weight: (0..in_dim * out_dim).map(|_| dist.sample(rng)).collect(),
                bias: vec![0.0; out_dim],
            }
        })
        .collect();
    MlpF32 {
        layers,
        ..Default::default()
    }
}

/// Draws the networks of `spec`.
pub fn random_policy(spec: &RandomSpec) -> PolicyF32 {
    let mut rng = ChaCha8Rng::seed_from_u64(spec.seed);
    let estimator = match &spec.estimator_hidden {
        Some(h) => random_mlp(&mut rng, HISTORY_DIM, h, ESTIMATOR_OUT, spec.output_gain),
        None => MlpF32::default(),
    };
    let memory = random_mlp(
        &mut rng,
        HISTORY_DIM,
        &spec.memory_hidden,
        spec.memory_latent,
        spec.output_gain,
    );
    let actor_in = ACTOR_OBS_DIM + estimator.out_dim() + spec.memory_latent;
    let actor = random_mlp(
        &mut rng,
        actor_in,
        &spec.actor_hidden,
        ACTOR_OUT,
        spec.output_gain,
    );
    PolicyF32 {
        estimator,
        memory,
        actor,
        actor_obs_norm: Normalizer::identity(ACTOR_OBS_DIM),
        history_norm: Normalizer::identity(HISTORY_DIM),
    }
}

/// The policy's tensors under the trainer's key names.
pub fn policy_tensors(policy: &PolicyF32) -> Vec<(String, Vec<usize>, Vec<f32>)> {
    let mut out = Vec::new();
    for (net, mlp) in [
        ("estimator", &policy.estimator),
        ("memory", &policy.memory),
        ("actor", &policy.actor),
    ] {
        for (k, l) in mlp.layers.iter().enumerate() {
            out.push((
                format!("{net}.layers.{k}.weight"),
                vec![l.out_dim, l.in_dim],
                l.weight.clone(),
            ));
            out.push((
                format!("{net}.layers.{k}.bias"),
                vec![l.out_dim],
                l.bias.clone(),
            ));
        }
    }
    for (name, norm) in [
        ("actor_obs", &policy.actor_obs_norm),
        ("history", &policy.history_norm),
    ] {
        out.push((
            format!("normalizer.{name}.mean"),
            vec![norm.mean.len()],
            norm.mean.clone(),
        ));
        out.push((
            format!("normalizer.{name}.std"),
            vec![norm.std.len()],
            norm.std.clone(),
        ));
    }
    out
}

/// Serializes tensors to safetensors bytes (f32, little-endian).
pub fn to_safetensors(
    tensors: &[(String, Vec<usize>, Vec<f32>)],
) -> Result<Vec<u8>, CheckpointError> {
    let bytes: Vec<(String, Vec<usize>, Vec<u8>)> = tensors
        .iter()
        .map(|(k, s, v)| {
            (
                k.clone(),
                s.clone(),
                v.iter().flat_map(|x| x.to_le_bytes()).collect(),
            )
        })
        .collect();
    let views = bytes
        .iter()
        .map(|(k, s, b)| TensorView::new(Dtype::F32, s.clone(), b).map(|v| (k.clone(), v)))
        .collect::<Result<Vec<_>, _>>()
        .map_err(|e| CheckpointError::Safetensors {
            path: "<memory>".into(),
            message: e.to_string(),
        })?;
    safetensors::serialize(views, None).map_err(|e| CheckpointError::Safetensors {
        path: "<memory>".into(),
        message: e.to_string(),
    })
}

/// Writes `dir/policy.safetensors` and `dir/config.toml`; returns the safetensors sha256.
pub fn write_checkpoint(
    dir: &Path,
    policy: &PolicyF32,
    spec: &RandomSpec,
) -> Result<String, CheckpointError> {
    let io = |path: &Path| {
        let path = path.display().to_string();
        move |source| CheckpointError::Io { path, source }
    };
    std::fs::create_dir_all(dir).map_err(io(dir))?;
    let bytes = to_safetensors(&policy_tensors(policy))?;
    let st_path = dir.join("policy.safetensors");
    std::fs::write(&st_path, &bytes).map_err(io(&st_path))?;
    let hidden = |mlp: &MlpF32| -> Vec<usize> {
        mlp.layers
            .iter()
            .take(mlp.layers.len() - 1)
            .map(|l| l.out_dim)
            .collect()
    };
    let config = format!(
        "# Randomly initialized policy (`policy-codegen random-checkpoint`, seed {seed}): the shapes of\n\
         # the paper's Table II, no training. Stands in until a trained checkpoint lands.\n\n\
         [policy]\n\
         use_estimator = {use_est}\n\
         estimator_hidden = {est:?}\n\
         memory_hidden = {mem:?}\n\
         memory_latent = {lat}\n\
         actor_hidden = {act:?}\n\n\
         [init]\nseed = {seed}\noutput_gain = {gain:?}\n",
        seed = spec.seed,
        use_est = !policy.estimator.layers.is_empty(),
        est = spec.estimator_hidden.clone().unwrap_or_default(),
        mem = hidden(&policy.memory),
        lat = policy.memory.out_dim(),
        act = hidden(&policy.actor),
        gain = spec.output_gain,
    );
    let cfg_path = dir.join("config.toml");
    std::fs::write(&cfg_path, config).map_err(io(&cfg_path))?;
    Ok(sha256_hex(&bytes))
}
