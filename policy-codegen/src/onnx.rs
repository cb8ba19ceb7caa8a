//! ONNX for MLP policies, both ways.
//!
//! Import ([`import`]): a plain MLP actor as rsl_rl and Isaac Lab export actors, or the
//! whole deployed policy as [`export`] writes it. Supported graph per network: optional
//! input normalization (`Sub` mean, `Div` std, constants), then dense layers (`Gemm`, or
//! `MatMul` + `Add`) with `Elu` (alpha 1) or `Relu` between them and a linear output. With
//! one input (the actor observation, 63) the result is an actor-only policy (no estimator,
//! no memory) for the same runtime; with two (`actor_obs` and `history`, 210) the history
//! is normalized once and feeds the estimator and the memory encoder, and a `Concat` of the
//! normalized actor observation, the estimate and the latent feeds the actor.
//!
//! Export ([`export`]): the deployed networks of a checkpoint as one graph of that form,
//! normalization explicit as `Sub`/`Div`, layers as `Gemm` (`transB`) with the checkpoint's
//! tensor names, a batch dimension on every input and output. Outputs: `actions` (the
//! action mean, before the runtime's clip to `+-ACTION_CLIP`), and, when the policy has
//! them, `base_velocity_estimate` and `memory_latent`.
//!
//! The protobuf messages are the subset of `onnx.proto` this needs, declared with prost
//! (field numbers from onnx.proto3).

use crate::checkpoint::{DenseF32, MlpF32, Normalizer, PolicyF32};
use hexapod_core::nn::Activation;
use hexapod_core::obs::{ACTOR_OBS_DIM, HISTORY_DIM};
use prost::Message;
use std::collections::HashMap;

/// `onnx.ModelProto` (subset).
#[derive(Clone, PartialEq, Message)]
pub struct ModelProto {
    /// IR version.
    #[prost(int64, tag = "1")]
    pub ir_version: i64,
    /// Producer.
    #[prost(string, tag = "2")]
    pub producer_name: String,
    /// The graph.
    #[prost(message, optional, tag = "7")]
    pub graph: Option<GraphProto>,
    /// Free text (the export names its checkpoint here).
    #[prost(string, tag = "6")]
    pub doc_string: String,
    /// Operator sets.
    #[prost(message, repeated, tag = "8")]
    pub opset_import: Vec<OperatorSetIdProto>,
}

/// `onnx.OperatorSetIdProto`.
#[derive(Clone, PartialEq, Message)]
pub struct OperatorSetIdProto {
    /// Domain ("" = default).
    #[prost(string, tag = "1")]
    pub domain: String,
    /// Version.
    #[prost(int64, tag = "2")]
    pub version: i64,
}

/// `onnx.GraphProto` (subset).
#[derive(Clone, PartialEq, Message)]
pub struct GraphProto {
    /// Nodes in topological order.
    #[prost(message, repeated, tag = "1")]
    pub node: Vec<NodeProto>,
    /// Name.
    #[prost(string, tag = "2")]
    pub name: String,
    /// Constant tensors.
    #[prost(message, repeated, tag = "5")]
    pub initializer: Vec<TensorProto>,
    /// Inputs.
    #[prost(message, repeated, tag = "11")]
    pub input: Vec<ValueInfoProto>,
    /// Outputs.
    #[prost(message, repeated, tag = "12")]
    pub output: Vec<ValueInfoProto>,
}

/// `onnx.NodeProto` (subset).
#[derive(Clone, PartialEq, Message)]
pub struct NodeProto {
    /// Input names.
    #[prost(string, repeated, tag = "1")]
    pub input: Vec<String>,
    /// Output names.
    #[prost(string, repeated, tag = "2")]
    pub output: Vec<String>,
    /// Node name.
    #[prost(string, tag = "3")]
    pub name: String,
    /// Operator.
    #[prost(string, tag = "4")]
    pub op_type: String,
    /// Attributes.
    #[prost(message, repeated, tag = "5")]
    pub attribute: Vec<AttributeProto>,
}

/// `onnx.AttributeProto` (subset).
#[derive(Clone, PartialEq, Message)]
pub struct AttributeProto {
    /// Name.
    #[prost(string, tag = "1")]
    pub name: String,
    /// Float value.
    #[prost(float, tag = "2")]
    pub f: f32,
    /// Integer value.
    #[prost(int64, tag = "3")]
    pub i: i64,
    /// Type (1 float, 2 int).
    #[prost(int32, tag = "20")]
    pub r#type: i32,
}

/// `onnx.TensorProto` (subset: float tensors).
#[derive(Clone, PartialEq, Message)]
pub struct TensorProto {
    /// Shape.
    #[prost(int64, repeated, tag = "1")]
    pub dims: Vec<i64>,
    /// Element type (1 = FLOAT).
    #[prost(int32, tag = "2")]
    pub data_type: i32,
    /// Values, when not in `raw_data`.
    #[prost(float, repeated, tag = "4")]
    pub float_data: Vec<f32>,
    /// Name.
    #[prost(string, tag = "8")]
    pub name: String,
    /// Little-endian values.
    #[prost(bytes = "vec", tag = "9")]
    pub raw_data: Vec<u8>,
}

/// `onnx.ValueInfoProto` (name and tensor type).
#[derive(Clone, PartialEq, Message)]
pub struct ValueInfoProto {
    /// Name.
    #[prost(string, tag = "1")]
    pub name: String,
    /// Type (runtimes need it on graph inputs and outputs; the import ignores it).
    #[prost(message, optional, tag = "2")]
    pub r#type: Option<TypeProto>,
}

impl ValueInfoProto {
    /// A value with its name only.
    pub fn named(name: &str) -> Self {
        Self {
            name: name.into(),
            r#type: None,
        }
    }

    /// A `[batch, width]` FLOAT tensor (`batch` symbolic).
    pub fn batch_of(name: &str, width: usize) -> Self {
        let dim = |dim_value: Option<i64>, dim_param: Option<String>| Dimension {
            dim_value,
            dim_param,
        };
        Self {
            name: name.into(),
            r#type: Some(TypeProto {
                tensor_type: Some(TensorTypeProto {
                    elem_type: 1,
                    shape: Some(TensorShapeProto {
                        dim: vec![
                            dim(None, Some("batch".into())),
                            dim(Some(width as i64), None),
                        ],
                    }),
                }),
            }),
        }
    }
}

/// `onnx.TypeProto` (tensor types only).
#[derive(Clone, PartialEq, Message)]
pub struct TypeProto {
    /// A tensor type.
    #[prost(message, optional, tag = "1")]
    pub tensor_type: Option<TensorTypeProto>,
}

/// `onnx.TypeProto.Tensor`.
#[derive(Clone, PartialEq, Message)]
pub struct TensorTypeProto {
    /// Element type (1 = FLOAT).
    #[prost(int32, tag = "1")]
    pub elem_type: i32,
    /// Shape.
    #[prost(message, optional, tag = "2")]
    pub shape: Option<TensorShapeProto>,
}

/// `onnx.TensorShapeProto`.
#[derive(Clone, PartialEq, Message)]
pub struct TensorShapeProto {
    /// Dimensions.
    #[prost(message, repeated, tag = "1")]
    pub dim: Vec<Dimension>,
}

/// `onnx.TensorShapeProto.Dimension` (the `value` oneof as two optional fields: the same
/// bytes on the wire).
#[derive(Clone, PartialEq, Message)]
pub struct Dimension {
    /// A fixed size.
    #[prost(int64, optional, tag = "1")]
    pub dim_value: Option<i64>,
    /// A symbolic size.
    #[prost(string, optional, tag = "2")]
    pub dim_param: Option<String>,
}

/// A float tensor from its values and shape.
pub fn float_tensor(name: &str, dims: &[usize], values: &[f32]) -> TensorProto {
    TensorProto {
        dims: dims.iter().map(|&d| d as i64).collect(),
        data_type: 1,
        float_data: Vec::new(),
        name: name.into(),
        raw_data: values.iter().flat_map(|v| v.to_le_bytes()).collect(),
    }
}

struct Const {
    dims: Vec<usize>,
    values: Vec<f32>,
}

fn constant(t: &TensorProto) -> anyhow::Result<Const> {
    anyhow::ensure!(
        t.data_type == 1,
        "initializer {} is not FLOAT (type {})",
        t.name,
        t.data_type
    );
    let values = if t.raw_data.is_empty() {
        t.float_data.clone()
    } else {
        t.raw_data
            .chunks_exact(4)
            .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
            .collect()
    };
    let dims: Vec<usize> = t.dims.iter().map(|&d| d.max(0) as usize).collect();
    anyhow::ensure!(
        dims.iter().product::<usize>() == values.len(),
        "initializer {}: {} values for shape {:?}",
        t.name,
        values.len(),
        dims
    );
    Ok(Const { dims, values })
}

fn attr<'a>(node: &'a NodeProto, name: &str) -> Option<&'a AttributeProto> {
    node.attribute.iter().find(|a| a.name == name)
}

/// Name of the actor observation input (63) of an exported policy.
pub const ACTOR_OBS_INPUT: &str = "actor_obs";
/// Name of the history input (210) of an exported policy with an estimator or memory.
pub const HISTORY_INPUT: &str = "history";
/// Name of the action output (the action mean, unclipped).
pub const ACTIONS_OUTPUT: &str = "actions";
/// Name of the estimator's output (scaled base velocity).
pub const ESTIMATE_OUTPUT: &str = "base_velocity_estimate";
/// Name of the memory encoder's output.
pub const LATENT_OUTPUT: &str = "memory_latent";

/// Operators a network's chain is made of.
const CHAIN_OPS: [&str; 7] = ["Sub", "Div", "Gemm", "MatMul", "Add", "Elu", "Relu"];

/// One chain of nodes: optional normalization, then an MLP.
struct Chain {
    mean: Option<Vec<f32>>,
    std: Option<Vec<f32>>,
    mlp: MlpF32,
    /// The tensor the chain ends in.
    end: String,
}

impl Chain {
    fn normalizer(&self, dim: usize) -> Normalizer {
        let identity = Normalizer::identity(dim);
        Normalizer {
            mean: self.mean.clone().unwrap_or(identity.mean),
            std: self.std.clone().unwrap_or(identity.std),
        }
    }

    fn has_norm(&self) -> bool {
        self.mean.is_some() || self.std.is_some()
    }
}

/// The graph being read: its nodes, constants and which nodes are already accounted for.
struct Reader<'a> {
    nodes: &'a [NodeProto],
    consts: HashMap<&'a str, Const>,
    used: Vec<bool>,
}

impl<'a> Reader<'a> {
    fn data_inputs(&self, node: &'a NodeProto) -> Vec<&'a str> {
        node.input
            .iter()
            .map(String::as_str)
            .filter(|n| !n.is_empty() && !self.consts.contains_key(n))
            .collect()
    }

    /// Nodes not yet read that take `tensor` as a data input.
    fn consumers(&self, tensor: &str) -> Vec<usize> {
        (0..self.nodes.len())
            .filter(|&i| !self.used[i] && self.data_inputs(&self.nodes[i]).contains(&tensor))
            .collect()
    }

    /// Follows `start` through normalization and dense layers while each tensor has exactly
    /// one consumer that is a chain operator; `norm_dim` is the size Sub/Div constants must
    /// have.
    fn walk(&mut self, start: &str, norm_dim: usize) -> anyhow::Result<Chain> {
        self.walk_via(start, None, norm_dim)
    }

    /// [`Reader::walk`], with `first` (a consumer of `start`) as its first node.
    fn walk_via(
        &mut self,
        start: &str,
        mut first: Option<usize>,
        norm_dim: usize,
    ) -> anyhow::Result<Chain> {
        let mut current = start.to_string();
        let mut chain = Chain {
            mean: None,
            std: None,
            mlp: MlpF32::default(),
            end: String::new(),
        };
        let mut layers: Vec<DenseF32> = Vec::new();
        let mut hidden: Option<Activation> = None;
        let mut pending_matmul: Option<(usize, usize, Vec<f32>)> = None; // (in, out, W row-major [out, in])
        loop {
            let i = match first.take() {
                Some(i) => i,
                None => match self.consumers(&current)[..] {
                    [i] => i,
                    _ => break,
                },
            };
            let node = &self.nodes[i];
            if !CHAIN_OPS.contains(&node.op_type.as_str()) {
                break;
            }
            anyhow::ensure!(
                self.data_inputs(node) == [current.as_str()],
                "node {} ({}) does not continue the chain from {current}",
                node.name,
                node.op_type
            );
            let konst = |i: usize| node.input.get(i).and_then(|n| self.consts.get(n.as_str()));
            match node.op_type.as_str() {
                "Sub" | "Div" if layers.is_empty() && pending_matmul.is_none() => {
                    let c = konst(1).ok_or_else(|| {
                        anyhow::anyhow!(
                            "{}: {} needs a constant second input",
                            node.name,
                            node.op_type
                        )
                    })?;
                    anyhow::ensure!(
                        c.values.len() == norm_dim,
                        "{}: {} constant has {} values, expected {norm_dim}",
                        node.name,
                        node.op_type,
                        c.values.len()
                    );
                    if node.op_type == "Sub" {
                        chain.mean = Some(c.values.clone());
                    } else {
                        chain.std = Some(c.values.clone());
                    }
                }
                "Gemm" => {
                    let w = konst(1)
                        .ok_or_else(|| anyhow::anyhow!("{}: Gemm B must be constant", node.name))?;
                    anyhow::ensure!(w.dims.len() == 2, "{}: Gemm B must be 2-D", node.name);
                    for (name, one) in [("alpha", 1.0), ("beta", 1.0)] {
                        if let Some(a) = attr(node, name) {
                            anyhow::ensure!(
                                a.f == one,
                                "{}: Gemm {name} = {} unsupported",
                                node.name,
                                a.f
                            );
                        }
                    }
                    anyhow::ensure!(
                        attr(node, "transA").map_or(0, |a| a.i) == 0,
                        "{}: transA unsupported",
                        node.name
                    );
                    let trans_b = attr(node, "transB").map_or(0, |a| a.i) != 0;
                    let (out_dim, in_dim, weight) = if trans_b {
                        (w.dims[0], w.dims[1], w.values.clone())
                    } else {
                        (
                            w.dims[1],
                            w.dims[0],
                            transpose(&w.values, w.dims[0], w.dims[1]),
                        )
                    };
                    let bias = match konst(2) {
                        Some(b) => b.values.clone(),
                        None => vec![0.0; out_dim],
                    };
                    anyhow::ensure!(
                        bias.len() == out_dim,
                        "{}: bias has {} values, expected {out_dim}",
                        node.name,
                        bias.len()
                    );
                    layers.push(DenseF32 {
                        in_dim,
                        out_dim,
                        weight,
                        bias,
                    });
                }
                "MatMul" => {
                    let w = konst(1).ok_or_else(|| {
                        anyhow::anyhow!("{}: MatMul B must be constant", node.name)
                    })?;
                    anyhow::ensure!(w.dims.len() == 2, "{}: MatMul B must be 2-D", node.name);
                    pending_matmul = Some((
                        w.dims[0],
                        w.dims[1],
                        transpose(&w.values, w.dims[0], w.dims[1]),
                    ));
                }
                "Add" => {
                    let (in_dim, out_dim, weight) = pending_matmul.take().ok_or_else(|| {
                        anyhow::anyhow!("{}: Add without a MatMul before it", node.name)
                    })?;
                    let b = konst(1).ok_or_else(|| {
                        anyhow::anyhow!("{}: Add needs a constant bias", node.name)
                    })?;
                    anyhow::ensure!(
                        b.values.len() == out_dim,
                        "{}: bias has {} values, expected {out_dim}",
                        node.name,
                        b.values.len()
                    );
                    layers.push(DenseF32 {
                        in_dim,
                        out_dim,
                        weight,
                        bias: b.values.clone(),
                    });
                }
                "Elu" | "Relu" => {
                    if let Some((in_dim, out_dim, weight)) = pending_matmul.take() {
                        layers.push(DenseF32 {
                            in_dim,
                            out_dim,
                            weight,
                            bias: vec![0.0; out_dim],
                        });
                    }
                    let act = if node.op_type == "Elu" {
                        let alpha = attr(node, "alpha").map_or(1.0, |a| a.f);
                        anyhow::ensure!(
                            alpha == 1.0,
                            "{}: Elu alpha {alpha} unsupported (1 only)",
                            node.name
                        );
                        Activation::Elu
                    } else {
                        Activation::Relu
                    };
                    anyhow::ensure!(
                        hidden.is_none_or(|h| h == act),
                        "{}: mixed hidden activations unsupported",
                        node.name
                    );
                    hidden = Some(act);
                }
                other => anyhow::bail!("{}: unsupported operator {other}", node.name),
            }
            self.used[i] = true;
            current = node.output.first().cloned().unwrap_or_default();
        }
        if let Some((in_dim, out_dim, weight)) = pending_matmul.take() {
            layers.push(DenseF32 {
                in_dim,
                out_dim,
                weight,
                bias: vec![0.0; out_dim],
            });
        }
        chain.mlp = MlpF32 {
            layers,
            hidden: hidden.unwrap_or(Activation::Elu),
        };
        chain.end = current;
        Ok(chain)
    }

    /// Fails on the first node no chain accounted for.
    fn all_used(&self) -> anyhow::Result<()> {
        if let Some(i) = self.used.iter().position(|u| !u) {
            let node = &self.nodes[i];
            if CHAIN_OPS.contains(&node.op_type.as_str()) || node.op_type == "Concat" {
                anyhow::bail!(
                    "node {} ({}) is not on the policy's chain (inputs {:?})",
                    node.name,
                    node.op_type,
                    node.input
                );
            }
            anyhow::bail!("{}: unsupported operator {}", node.name, node.op_type);
        }
        Ok(())
    }
}

/// Reads an ONNX MLP actor (one input) or a whole policy as [`export`] writes it (inputs
/// `actor_obs` and `history`).
pub fn import(bytes: &[u8]) -> anyhow::Result<PolicyF32> {
    let model = ModelProto::decode(bytes)?;
    let graph = model
        .graph
        .ok_or_else(|| anyhow::anyhow!("model has no graph"))?;
    let consts: HashMap<&str, Const> = graph
        .initializer
        .iter()
        .map(|t| Ok((t.name.as_str(), constant(t)?)))
        .collect::<anyhow::Result<_>>()?;
    let inputs: Vec<&str> = graph
        .input
        .iter()
        .map(|v| v.name.as_str())
        .filter(|n| !consts.contains_key(n))
        .collect();
    let mut reader = Reader {
        nodes: &graph.node,
        consts,
        used: vec![false; graph.node.len()],
    };
    let policy = match inputs[..] {
        [] => anyhow::bail!("graph has no input"),
        [obs] => {
            let actor = reader.walk(obs, ACTOR_OBS_DIM)?;
            reader.all_used()?;
            PolicyF32 {
                estimator: MlpF32::default(),
                memory: MlpF32::default(),
                actor_obs_norm: actor.normalizer(ACTOR_OBS_DIM),
                actor: actor.mlp,
                history_norm: Normalizer::identity(HISTORY_DIM),
            }
        }
        [a, b] => {
            let (obs, history) = match (a, b) {
                (_, HISTORY_INPUT) => (a, b),
                (HISTORY_INPUT, _) => (b, a),
                _ => anyhow::bail!(
                    "graph inputs {a} and {b}: one of two inputs must be `{HISTORY_INPUT}`"
                ),
            };
            let obs_chain = reader.walk(obs, ACTOR_OBS_DIM)?;
            anyhow::ensure!(
                obs_chain.mlp.layers.is_empty(),
                "{obs}: dense layers before the concatenation with the history's networks"
            );
            let history_chain = reader.walk(history, HISTORY_DIM)?;
            let history_norm = history_chain.normalizer(HISTORY_DIM);
            // The history, normalized once, feeds one or two networks.
            let mut branches: Vec<Chain> = if history_chain.mlp.layers.is_empty() {
                let starts = reader.consumers(&history_chain.end);
                let mut branches = Vec::new();
                for start in starts {
                    let chain = reader.walk_via(&history_chain.end, Some(start), HISTORY_DIM)?;
                    anyhow::ensure!(
                        !chain.has_norm(),
                        "{history}: a second normalization after {}",
                        history_chain.end
                    );
                    branches.push(chain);
                }
                branches
            } else {
                vec![history_chain]
            };
            let concat_index = match reader.consumers(&obs_chain.end)[..] {
                [i] if reader.nodes[i].op_type == "Concat" => i,
                _ => anyhow::bail!(
                    "{}: expected one Concat of the actor observation, the estimate and the latent",
                    obs_chain.end
                ),
            };
            let concat = &reader.nodes[concat_index];
            let axis = attr(concat, "axis").map_or(0, |a| a.i);
            anyhow::ensure!(
                axis == 1 || axis == -1,
                "{}: Concat axis {axis}, expected 1 (the feature axis)",
                concat.name
            );
            let parts = reader.data_inputs(concat);
            anyhow::ensure!(
                parts.first() == Some(&obs_chain.end.as_str())
                    && parts.len() == 1 + branches.len()
                    && parts[1..]
                        .iter()
                        .all(|p| branches.iter().any(|b| b.end == *p)),
                "{}: Concat of {parts:?}, expected {} then the history networks' outputs",
                concat.name,
                obs_chain.end
            );
            let mut ordered: Vec<Chain> = Vec::new();
            for p in &parts[1..] {
                let i = branches.iter().position(|b| b.end == *p).unwrap_or(0);
                ordered.push(branches.remove(i));
            }
            // Two networks: estimate then latent, as the actor reads them; one: named by
            // its output.
            let (estimator, memory) = match ordered.len() {
                2 => {
                    let memory = ordered.pop().map(|c| c.mlp).unwrap_or_default();
                    (ordered.pop().map(|c| c.mlp).unwrap_or_default(), memory)
                }
                1 if ordered[0].end == ESTIMATE_OUTPUT => (
                    ordered.pop().map(|c| c.mlp).unwrap_or_default(),
                    MlpF32::default(),
                ),
                1 => (
                    MlpF32::default(),
                    ordered.pop().map(|c| c.mlp).unwrap_or_default(),
                ),
                n => anyhow::bail!("{n} networks read the history; at most 2 are supported"),
            };
            reader.used[concat_index] = true;
            let actor_input = concat.output.first().cloned().unwrap_or_default();
            let actor = reader.walk(&actor_input, ACTOR_OBS_DIM)?;
            anyhow::ensure!(
                !actor.has_norm(),
                "{actor_input}: normalization after the concatenation"
            );
            reader.all_used()?;
            PolicyF32 {
                estimator,
                memory,
                actor: actor.mlp,
                actor_obs_norm: obs_chain.normalizer(ACTOR_OBS_DIM),
                history_norm,
            }
        }
        _ => anyhow::bail!("graph has {} inputs; 1 or 2 are supported", inputs.len()),
    };
    policy.validate()?;
    Ok(policy)
}

fn transpose(values: &[f32], rows: usize, cols: usize) -> Vec<f32> {
    let mut out = vec![0.0; values.len()];
    for r in 0..rows {
        for c in 0..cols {
            out[c * rows + r] = values[r * cols + c];
        }
    }
    out
}

/// Nodes and initializers of one graph under construction.
#[derive(Default)]
struct Builder {
    nodes: Vec<NodeProto>,
    inits: Vec<TensorProto>,
}

impl Builder {
    fn node(
        &mut self,
        op: &str,
        name: &str,
        inputs: &[&str],
        output: &str,
        attribute: Vec<AttributeProto>,
    ) {
        self.nodes.push(NodeProto {
            input: inputs.iter().map(|s| s.to_string()).collect(),
            output: vec![output.into()],
            name: name.into(),
            op_type: op.into(),
            attribute,
        });
    }

    /// `(input - mean) / std` with the checkpoint's names; returns the output tensor.
    fn normalize(&mut self, group: &str, input: &str, norm: &Normalizer) -> String {
        let (mean, std) = (
            format!("normalizer.{group}.mean"),
            format!("normalizer.{group}.std"),
        );
        self.inits
            .push(float_tensor(&mean, &[norm.mean.len()], &norm.mean));
        self.inits
            .push(float_tensor(&std, &[norm.std.len()], &norm.std));
        let (centered, normalized) = (format!("{group}_centered"), format!("{group}_normalized"));
        self.node(
            "Sub",
            &format!("normalizer.{group}.sub"),
            &[input, &mean],
            &centered,
            vec![],
        );
        self.node(
            "Div",
            &format!("normalizer.{group}.div"),
            &[&centered, &std],
            &normalized,
            vec![],
        );
        normalized
    }

    /// An MLP as Gemm (`transB`) nodes with its hidden activation; the last layer writes
    /// `output`.
    fn mlp(&mut self, net: &str, mlp: &MlpF32, input: &str, output: &str) {
        let act = if mlp.hidden == Activation::Relu {
            "Relu"
        } else {
            "Elu"
        };
        let n = mlp.layers.len();
        let mut current = input.to_string();
        for (k, l) in mlp.layers.iter().enumerate() {
            let (w, b) = (
                format!("{net}.layers.{k}.weight"),
                format!("{net}.layers.{k}.bias"),
            );
            self.inits
                .push(float_tensor(&w, &[l.out_dim, l.in_dim], &l.weight));
            self.inits.push(float_tensor(&b, &[l.out_dim], &l.bias));
            let trans_b = AttributeProto {
                name: "transB".into(),
                f: 0.0,
                i: 1,
                r#type: 2,
            };
            let out = if k + 1 == n {
                output.to_string()
            } else {
                format!("{net}.h{k}")
            };
            self.node(
                "Gemm",
                &format!("{net}.layers.{k}"),
                &[&current, &w, &b],
                &out,
                vec![trans_b],
            );
            current = out;
            if k + 1 < n {
                let out = format!("{net}.a{k}");
                self.node(
                    act,
                    &format!("{net}.{}{k}", act.to_lowercase()),
                    &[&current],
                    &out,
                    vec![],
                );
                current = out;
            }
        }
    }
}

/// The deployed networks as one ONNX graph (see the module documentation): inputs
/// `actor_obs` `[batch, 63]` and, with an estimator or memory, `history` `[batch, 210]`;
/// outputs `actions` and the history networks' outputs. Opset 17, IR version 8.
pub fn export_model(policy: &PolicyF32) -> ModelProto {
    let mut g = Builder::default();
    let mut inputs = vec![ValueInfoProto::batch_of(ACTOR_OBS_INPUT, ACTOR_OBS_DIM)];
    let mut outputs = vec![ValueInfoProto::batch_of(
        ACTIONS_OUTPUT,
        policy.actor.out_dim(),
    )];
    let obs = g.normalize("actor_obs", ACTOR_OBS_INPUT, &policy.actor_obs_norm);
    let branches = [
        ("estimator", &policy.estimator, ESTIMATE_OUTPUT),
        ("memory", &policy.memory, LATENT_OUTPUT),
    ];
    if branches.iter().all(|(_, m, _)| m.layers.is_empty()) {
        g.mlp("actor", &policy.actor, &obs, ACTIONS_OUTPUT);
    } else {
        inputs.push(ValueInfoProto::batch_of(HISTORY_INPUT, HISTORY_DIM));
        let history = g.normalize("history", HISTORY_INPUT, &policy.history_norm);
        let mut parts = vec![obs];
        for (net, mlp, output) in branches {
            if !mlp.layers.is_empty() {
                g.mlp(net, mlp, &history, output);
                outputs.push(ValueInfoProto::batch_of(output, mlp.out_dim()));
                parts.push(output.to_string());
            }
        }
        let axis = AttributeProto {
            name: "axis".into(),
            f: 0.0,
            i: 1,
            r#type: 2,
        };
        let parts: Vec<&str> = parts.iter().map(String::as_str).collect();
        g.node("Concat", "actor_input", &parts, "actor_input", vec![axis]);
        g.mlp("actor", &policy.actor, "actor_input", ACTIONS_OUTPUT);
    }
    ModelProto {
        ir_version: 8,
        producer_name: "policy-codegen".into(),
        doc_string: String::new(),
        graph: Some(GraphProto {
            node: g.nodes,
            name: "hexapod_policy".into(),
            initializer: g.inits,
            input: inputs,
            output: outputs,
        }),
        opset_import: vec![OperatorSetIdProto {
            domain: String::new(),
            version: 17,
        }],
    }
}

/// [`export_model`], encoded.
pub fn export(policy: &PolicyF32) -> Vec<u8> {
    export_model(policy).encode_to_vec()
}

/// Reference inputs and outputs for an exported model: `records` through the f32 forward
/// pass ([`PolicyF32::trace`], the trainer's arithmetic), as JSON keyed by the graph's
/// input and output names, rows per record. A runtime that loads the model should give
/// the same outputs on these inputs.
pub fn reference_json(
    policy: &PolicyF32,
    records: &[crate::records::ObsRecord],
    source: &str,
    sha256: &str,
) -> String {
    let row = |v: &[f32]| {
        let items: Vec<String> = v.iter().map(|x| format!("{x}")).collect();
        format!("[{}]", items.join(", "))
    };
    let rows = |name: &str, rows: Vec<String>| {
        format!("    \"{name}\": [\n      {}\n    ]", rows.join(",\n      "))
    };
    let traces: Vec<_> = records
        .iter()
        .map(|r| policy.trace(&r.actor_obs, &r.history))
        .collect();
    let last = |v: &Vec<Vec<f32>>| v.last().cloned().unwrap_or_default();
    let mut inputs = vec![rows(
        ACTOR_OBS_INPUT,
        records.iter().map(|r| row(&r.actor_obs)).collect(),
    )];
    let mut outputs = vec![rows(
        ACTIONS_OUTPUT,
        traces.iter().map(|t| row(&last(&t.actor))).collect(),
    )];
    if !(policy.estimator.layers.is_empty() && policy.memory.layers.is_empty()) {
        inputs.push(rows(
            HISTORY_INPUT,
            records.iter().map(|r| row(&r.history)).collect(),
        ));
    }
    if !policy.estimator.layers.is_empty() {
        outputs.push(rows(
            ESTIMATE_OUTPUT,
            traces.iter().map(|t| row(&last(&t.estimator))).collect(),
        ));
    }
    if !policy.memory.layers.is_empty() {
        outputs.push(rows(
            LATENT_OUTPUT,
            traces.iter().map(|t| row(&last(&t.memory))).collect(),
        ));
    }
    let escape = |s: &str| s.replace('\\', "\\\\").replace('"', "\\\"");
    format!(
        "{{\n  \"checkpoint\": \"{}\",\n  \"sha256\": \"{}\",\n  \"forward\": \"policy-codegen f32 (PolicyF32::trace)\",\n  \"inputs\": {{\n{}\n  }},\n  \"outputs\": {{\n{}\n  }}\n}}\n",
        escape(source),
        escape(sha256),
        inputs.join(",\n"),
        outputs.join(",\n")
    )
}
