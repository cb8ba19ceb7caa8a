//! Reading a policy checkpoint: `policy.safetensors` (f32) and the resolved `config.toml`.
//!
//! Keys follow candle's `VarBuilder` names: `{net}.layers.{k}.weight` (`[out, in]`) and
//! `.bias` (`[out]`) for `estimator`, `memory` and `actor`; `normalizer.actor_obs.mean|std`
//! and `normalizer.history.mean|std`. Layer counts and sizes come from the tensors and are
//! checked to chain; other keys (critic, discriminator, encoders) are ignored.

use hexapod_core::nets::ESTIMATOR_OUT;
use hexapod_core::nn::Activation;
use hexapod_core::obs::{ACTOR_OBS_DIM, HISTORY_DIM};
use hexapod_core::NUM_JOINTS;
use safetensors::{Dtype, SafeTensors};
use std::collections::HashMap;
use std::path::Path;

/// Why a checkpoint cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum CheckpointError {
    /// A file could not be read.
    #[error("cannot read {path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// Underlying error.
        source: std::io::Error,
    },
    /// The safetensors file is malformed.
    #[error("malformed safetensors {path}: {message}")]
    Safetensors {
        /// The file.
        path: String,
        /// The parser's message.
        message: String,
    },
    /// The config is not valid TOML or contradicts the tensors.
    #[error("malformed config {path}: {message}")]
    Config {
        /// The file.
        path: String,
        /// What is wrong.
        message: String,
    },
    /// A tensor is missing.
    #[error("missing tensor {key}")]
    Missing {
        /// The key.
        key: String,
    },
    /// A tensor has the wrong dtype or shape.
    #[error("tensor {key} has shape {shape:?} ({dtype}), expected {expected}")]
    Shape {
        /// The key.
        key: String,
        /// Its shape.
        shape: Vec<usize>,
        /// Its dtype.
        dtype: String,
        /// What was expected.
        expected: String,
    },
    /// A tensor holds NaN or infinity.
    #[error("tensor {key} holds non-finite values")]
    NonFinite {
        /// The key.
        key: String,
    },
}

/// One f32 dense layer, `y = W x + b`, `W` row-major `[out, in]`.
#[derive(Clone, Debug, PartialEq)]
pub struct DenseF32 {
    /// Input size.
    pub in_dim: usize,
    /// Output size.
    pub out_dim: usize,
    /// Row-major weights.
    pub weight: Vec<f32>,
    /// Bias.
    pub bias: Vec<f32>,
}

/// An MLP with one activation between layers (ELU for our checkpoints) and a linear output.
#[derive(Clone, Debug, PartialEq)]
pub struct MlpF32 {
    /// Layers, input first.
    pub layers: Vec<DenseF32>,
    /// Activation after every layer but the last.
    pub hidden: Activation,
}

impl Default for MlpF32 {
    fn default() -> Self {
        Self {
            layers: Vec::new(),
            hidden: Activation::Elu,
        }
    }
}

impl MlpF32 {
    /// Input size.
    pub fn in_dim(&self) -> usize {
        self.layers.first().map_or(0, |l| l.in_dim)
    }
    /// Output size.
    pub fn out_dim(&self) -> usize {
        self.layers.last().map_or(0, |l| l.out_dim)
    }
    /// Multiply-accumulates of one evaluation.
    pub fn macs(&self) -> usize {
        self.layers.iter().map(|l| l.in_dim * l.out_dim).sum()
    }
}

/// Empirical normalization `(x - mean) / std` (std includes epsilon).
#[derive(Clone, Debug, PartialEq)]
pub struct Normalizer {
    /// Mean per entry.
    pub mean: Vec<f32>,
    /// Standard deviation per entry.
    pub std: Vec<f32>,
}

impl Normalizer {
    /// Mean 0, std 1.
    pub fn identity(dim: usize) -> Self {
        Self {
            mean: vec![0.0; dim],
            std: vec![1.0; dim],
        }
    }
}

/// The deployed part of a checkpoint: what runs on the robot.
#[derive(Clone, Debug, PartialEq)]
pub struct PolicyF32 {
    /// History -> scaled base velocity (no layers when the policy has no estimator).
    pub estimator: MlpF32,
    /// History -> latent.
    pub memory: MlpF32,
    /// Normalized actor observation, estimate, latent -> action mean.
    pub actor: MlpF32,
    /// Actor observation normalizer (63).
    pub actor_obs_norm: Normalizer,
    /// History normalizer (210).
    pub history_norm: Normalizer,
}

impl PolicyF32 {
    /// Multiply-accumulates of one policy step.
    pub fn macs(&self) -> usize {
        self.estimator.macs() + self.memory.macs() + self.actor.macs()
    }

    /// Checks that the networks chain and fit the observation layout.
    pub fn validate(&self) -> Result<(), CheckpointError> {
        let bad = |key: &str, shape: Vec<usize>, expected: String| CheckpointError::Shape {
            key: key.into(),
            shape,
            dtype: "F32".into(),
            expected,
        };
        if !self.estimator.layers.is_empty() {
            if self.estimator.in_dim() != HISTORY_DIM {
                let l = &self.estimator.layers[0];
                return Err(bad(
                    "estimator.layers.0.weight",
                    vec![l.out_dim, l.in_dim],
                    format!("[_, {HISTORY_DIM}]"),
                ));
            }
            if self.estimator.out_dim() != ESTIMATOR_OUT {
                let k = self.estimator.layers.len() - 1;
                let l = &self.estimator.layers[k];
                return Err(bad(
                    &format!("estimator.layers.{k}.weight"),
                    vec![l.out_dim, l.in_dim],
                    format!("[{ESTIMATOR_OUT}, _]"),
                ));
            }
        }
        if !self.memory.layers.is_empty() && self.memory.in_dim() != HISTORY_DIM {
            let l = &self.memory.layers[0];
            return Err(bad(
                "memory.layers.0.weight",
                vec![l.out_dim, l.in_dim],
                format!("[_, {HISTORY_DIM}]"),
            ));
        }
        let actor_in = ACTOR_OBS_DIM + self.estimator.out_dim() + self.memory.out_dim();
        if self.actor.in_dim() != actor_in {
            let l = &self.actor.layers[0];
            return Err(bad(
                "actor.layers.0.weight",
                vec![l.out_dim, l.in_dim],
                format!("[_, {actor_in}] (63 + estimate + latent)"),
            ));
        }
        if self.actor.out_dim() != NUM_JOINTS {
            let k = self.actor.layers.len() - 1;
            let l = &self.actor.layers[k];
            return Err(bad(
                &format!("actor.layers.{k}.weight"),
                vec![l.out_dim, l.in_dim],
                format!("[{NUM_JOINTS}, _]"),
            ));
        }
        Ok(())
    }
}

/// Tensors by name, f32, with shapes.
pub struct TensorMap {
    tensors: HashMap<String, (Vec<usize>, Vec<f32>)>,
}

impl TensorMap {
    /// Parses a safetensors buffer (f32 tensors are kept; other dtypes are reported when
    /// requested).
    pub fn parse(bytes: &[u8], path: &str) -> Result<Self, CheckpointError> {
        let st = SafeTensors::deserialize(bytes).map_err(|e| CheckpointError::Safetensors {
            path: path.into(),
            message: e.to_string(),
        })?;
        let mut tensors = HashMap::new();
        for (name, view) in st.tensors() {
            let values = if view.dtype() == Dtype::F32 {
                view.data()
                    .chunks_exact(4)
                    .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
                    .collect()
            } else {
                Vec::new()
            };
            let mut shape = view.shape().to_vec();
            if view.dtype() != Dtype::F32 {
                shape.push(usize::MAX); // marks a non-f32 tensor
            }
            tensors.insert(name, (shape, values));
        }
        Ok(Self { tensors })
    }

    /// Builds a map from owned tensors.
    pub fn from_tensors(tensors: HashMap<String, (Vec<usize>, Vec<f32>)>) -> Self {
        Self { tensors }
    }

    fn get(&self, key: &str, rank: usize) -> Result<(&[usize], &[f32]), CheckpointError> {
        let (shape, values) = self
            .tensors
            .get(key)
            .ok_or_else(|| CheckpointError::Missing { key: key.into() })?;
        if shape.len() != rank || shape.contains(&usize::MAX) {
            return Err(CheckpointError::Shape {
                key: key.into(),
                shape: shape.iter().copied().filter(|&d| d != usize::MAX).collect(),
                dtype: if shape.contains(&usize::MAX) {
                    "not F32".into()
                } else {
                    "F32".into()
                },
                expected: format!("an F32 tensor of rank {rank}"),
            });
        }
        if values.iter().any(|v| !v.is_finite()) {
            return Err(CheckpointError::NonFinite { key: key.into() });
        }
        Ok((shape, values))
    }

    fn has(&self, key: &str) -> bool {
        self.tensors.contains_key(key)
    }

    /// Reads `{net}.layers.{k}.weight|bias` for k = 0.. until absent; checks the chain.
    pub fn mlp(&self, net: &str) -> Result<MlpF32, CheckpointError> {
        let mut layers: Vec<DenseF32> = Vec::new();
        for k in 0.. {
            let wkey = format!("{net}.layers.{k}.weight");
            if !self.has(&wkey) {
                break;
            }
            let (wshape, w) = self.get(&wkey, 2)?;
            let (out_dim, in_dim) = (wshape[0], wshape[1]);
            if let Some(prev) = layers.last() {
                if prev.out_dim != in_dim {
                    return Err(CheckpointError::Shape {
                        key: wkey,
                        shape: wshape.to_vec(),
                        dtype: "F32".into(),
                        expected: format!(
                            "[_, {}] (output of {net}.layers.{})",
                            prev.out_dim,
                            k - 1
                        ),
                    });
                }
            }
            let bkey = format!("{net}.layers.{k}.bias");
            let (bshape, b) = self.get(&bkey, 1)?;
            if bshape[0] != out_dim {
                return Err(CheckpointError::Shape {
                    key: bkey,
                    shape: bshape.to_vec(),
                    dtype: "F32".into(),
                    expected: format!("[{out_dim}]"),
                });
            }
            layers.push(DenseF32 {
                in_dim,
                out_dim,
                weight: w.to_vec(),
                bias: b.to_vec(),
            });
        }
        Ok(MlpF32 {
            layers,
            hidden: Activation::Elu,
        })
    }

    /// Reads `normalizer.{name}.mean|std` of size `dim`; std must be positive.
    pub fn normalizer(&self, name: &str, dim: usize) -> Result<Normalizer, CheckpointError> {
        let mut parts = Vec::new();
        for part in ["mean", "std"] {
            let key = format!("normalizer.{name}.{part}");
            let (shape, v) = self.get(&key, 1)?;
            if shape[0] != dim || (part == "std" && v.iter().any(|&s| s <= 0.0)) {
                return Err(CheckpointError::Shape {
                    key,
                    shape: shape.to_vec(),
                    dtype: "F32".into(),
                    expected: format!("[{dim}]{}", if part == "std" { ", all > 0" } else { "" }),
                });
            }
            parts.push(v.to_vec());
        }
        let std = parts.pop().unwrap_or_default();
        let mean = parts.pop().unwrap_or_default();
        Ok(Normalizer { mean, std })
    }

    /// The deployed policy (estimator optional, memory and actor required).
    pub fn policy(&self) -> Result<PolicyF32, CheckpointError> {
        let memory = self.mlp("memory")?;
        if memory.layers.is_empty() {
            return Err(CheckpointError::Missing {
                key: "memory.layers.0.weight".into(),
            });
        }
        let actor = self.mlp("actor")?;
        if actor.layers.is_empty() {
            return Err(CheckpointError::Missing {
                key: "actor.layers.0.weight".into(),
            });
        }
        let policy = PolicyF32 {
            estimator: self.mlp("estimator")?,
            memory,
            actor,
            actor_obs_norm: self.normalizer("actor_obs", ACTOR_OBS_DIM)?,
            history_norm: self.normalizer("history", HISTORY_DIM)?,
        };
        policy.validate()?;
        Ok(policy)
    }
}

/// A checkpoint directory as read.
pub struct Checkpoint {
    /// The deployed networks.
    pub policy: PolicyF32,
    /// SHA-256 of `policy.safetensors`, hex.
    pub sha256: String,
    /// The resolved config.
    pub config: toml::Table,
}

/// Reads `dir/policy.safetensors` and `dir/config.toml`.
pub fn load(dir: &Path) -> Result<Checkpoint, CheckpointError> {
    let st_path = dir.join("policy.safetensors");
    let bytes = std::fs::read(&st_path).map_err(|source| CheckpointError::Io {
        path: st_path.display().to_string(),
        source,
    })?;
    let cfg_path = dir.join("config.toml");
    let cfg_text = std::fs::read_to_string(&cfg_path).map_err(|source| CheckpointError::Io {
        path: cfg_path.display().to_string(),
        source,
    })?;
    let config: toml::Table =
        cfg_text
            .parse()
            .map_err(|e: toml::de::Error| CheckpointError::Config {
                path: cfg_path.display().to_string(),
                message: e.to_string(),
            })?;
    let policy = TensorMap::parse(&bytes, &st_path.display().to_string())?.policy()?;
    check_config(&config, &policy).map_err(|message| CheckpointError::Config {
        path: cfg_path.display().to_string(),
        message,
    })?;
    Ok(Checkpoint {
        policy,
        sha256: sha256_hex(&bytes),
        config,
    })
}

/// The `[policy]` section, when present, must agree with the tensors.
pub fn check_config(config: &toml::Table, policy: &PolicyF32) -> Result<(), String> {
    let Some(section) = config.get("policy") else {
        return Ok(());
    };
    let section = section.as_table().ok_or("[policy] is not a table")?;
    let hidden = |mlp: &MlpF32| -> Vec<i64> {
        mlp.layers
            .iter()
            .take(mlp.layers.len().saturating_sub(1))
            .map(|l| l.out_dim as i64)
            .collect()
    };
    let checks: [(&str, Option<Vec<i64>>); 4] = [
        (
            "estimator_hidden",
            (!policy.estimator.layers.is_empty()).then(|| hidden(&policy.estimator)),
        ),
        ("memory_hidden", Some(hidden(&policy.memory))),
        ("actor_hidden", Some(hidden(&policy.actor))),
        ("memory_latent", Some(vec![policy.memory.out_dim() as i64])),
    ];
    for (key, want) in checks {
        let (Some(value), Some(want)) = (section.get(key), want) else {
            continue;
        };
        let got: Option<Vec<i64>> = match value {
            toml::Value::Integer(i) => Some(vec![*i]),
            toml::Value::Array(a) => a.iter().map(|v| v.as_integer()).collect(),
            _ => None,
        };
        match got {
            Some(got) if got == want => {}
            Some(got) => {
                return Err(format!(
                    "policy.{key} = {got:?} but the tensors say {want:?}"
                ))
            }
            None => {
                return Err(format!(
                    "policy.{key} is not an integer or a list of integers"
                ))
            }
        }
    }
    if let Some(v) = section.get("use_estimator") {
        let uses = v.as_bool().ok_or("policy.use_estimator is not a boolean")?;
        if uses == policy.estimator.layers.is_empty() {
            return Err(format!(
                "policy.use_estimator = {uses} but the checkpoint {} estimator tensors",
                if uses { "has no" } else { "has" }
            ));
        }
    }
    Ok(())
}

/// SHA-256 of `bytes` as lowercase hex.
pub fn sha256_hex(bytes: &[u8]) -> String {
    use sha2::Digest;
    sha2::Sha256::digest(bytes)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}
