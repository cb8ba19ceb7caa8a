//! Import of a plain MLP policy exported as ONNX (as rsl_rl and Isaac Lab export actors).
//!
//! Supported graph: optional input normalization (`Sub` mean, `Div` std, constants), then
//! dense layers (`Gemm`, or `MatMul` + `Add`) with `Elu` (alpha 1) or `Relu` between them
//! and a linear output. Input: the actor observation (63); output: the action (18). The
//! result is an actor-only policy (no estimator, no memory) for the same runtime.
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

/// `onnx.ValueInfoProto` (name only).
#[derive(Clone, PartialEq, Message)]
pub struct ValueInfoProto {
    /// Name.
    #[prost(string, tag = "1")]
    pub name: String,
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

/// Reads an ONNX MLP actor into an actor-only policy.
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
    let input = graph
        .input
        .iter()
        .map(|v| v.name.as_str())
        .find(|n| !consts.contains_key(n))
        .ok_or_else(|| anyhow::anyhow!("graph has no input"))?;
    let mut current = input.to_string();
    let mut norm = Normalizer::identity(ACTOR_OBS_DIM);
    let mut layers: Vec<DenseF32> = Vec::new();
    let mut hidden: Option<Activation> = None;
    let mut pending_matmul: Option<(usize, usize, Vec<f32>)> = None; // (in, out, W row-major [out, in])
    for node in &graph.node {
        let data_in: Vec<&str> = node
            .input
            .iter()
            .map(String::as_str)
            .filter(|n| !consts.contains_key(n))
            .collect();
        anyhow::ensure!(
            data_in == [current.as_str()],
            "node {} ({}) does not continue the chain from {current}",
            node.name,
            node.op_type
        );
        let konst = |i: usize| node.input.get(i).and_then(|n| consts.get(n.as_str()));
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
                    c.values.len() == ACTOR_OBS_DIM,
                    "{}: {} constant has {} values, expected {ACTOR_OBS_DIM}",
                    node.name,
                    node.op_type,
                    c.values.len()
                );
                if node.op_type == "Sub" {
                    norm.mean = c.values.clone();
                } else {
                    norm.std = c.values.clone();
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
                let w = konst(1)
                    .ok_or_else(|| anyhow::anyhow!("{}: MatMul B must be constant", node.name))?;
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
                let b = konst(1)
                    .ok_or_else(|| anyhow::anyhow!("{}: Add needs a constant bias", node.name))?;
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
    let actor = MlpF32 {
        layers,
        hidden: hidden.unwrap_or(Activation::Elu),
    };
    let policy = PolicyF32 {
        estimator: MlpF32::default(),
        memory: MlpF32::default(),
        actor,
        actor_obs_norm: norm,
        history_norm: Normalizer::identity(HISTORY_DIM),
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

/// Encodes an actor-only policy as an ONNX graph (Gemm with transB, hidden activation,
/// input normalization as Sub/Div): used to make the repository's test model.
pub fn export(policy: &PolicyF32) -> Vec<u8> {
    let mut nodes = Vec::new();
    let mut inits = vec![
        float_tensor("obs_mean", &[ACTOR_OBS_DIM], &policy.actor_obs_norm.mean),
        float_tensor("obs_std", &[ACTOR_OBS_DIM], &policy.actor_obs_norm.std),
    ];
    let node =
        |op: &str, inputs: &[&str], output: &str, attribute: Vec<AttributeProto>| NodeProto {
            input: inputs.iter().map(|s| s.to_string()).collect(),
            output: vec![output.into()],
            name: format!("{op}_{output}"),
            op_type: op.into(),
            attribute,
        };
    nodes.push(node("Sub", &["obs", "obs_mean"], "centered", vec![]));
    nodes.push(node("Div", &["centered", "obs_std"], "x0", vec![]));
    let n = policy.actor.layers.len();
    let act = if policy.actor.hidden == Activation::Relu {
        "Relu"
    } else {
        "Elu"
    };
    let mut current = "x0".to_string();
    for (k, l) in policy.actor.layers.iter().enumerate() {
        inits.push(float_tensor(
            &format!("w{k}"),
            &[l.out_dim, l.in_dim],
            &l.weight,
        ));
        inits.push(float_tensor(&format!("b{k}"), &[l.out_dim], &l.bias));
        let trans_b = AttributeProto {
            name: "transB".into(),
            f: 0.0,
            i: 1,
            r#type: 2,
        };
        let out = if k + 1 == n {
            "actions".to_string()
        } else {
            format!("h{k}")
        };
        nodes.push(node(
            "Gemm",
            &[&current, &format!("w{k}"), &format!("b{k}")],
            &out,
            vec![trans_b],
        ));
        current = out;
        if k + 1 < n {
            let out = format!("a{k}");
            nodes.push(node(act, &[&current], &out, vec![]));
            current = out;
        }
    }
    let model = ModelProto {
        ir_version: 8,
        producer_name: "policy-codegen".into(),
        graph: Some(GraphProto {
            node: nodes,
            name: "actor".into(),
            initializer: inits,
            input: vec![ValueInfoProto { name: "obs".into() }],
            output: vec![ValueInfoProto {
                name: "actions".into(),
            }],
        }),
        opset_import: vec![OperatorSetIdProto {
            domain: String::new(),
            version: 17,
        }],
    };
    model.encode_to_vec()
}
