//! f32 policy -> fixed-point policy: calibration, normalization folding, per-channel
//! quantization, requantization multipliers.
//!
//! Inputs: each history and actor-observation entry is quantized with its own power-of-two
//! scale, chosen to cover both the calibration data (with 2x headroom) and the
//! normalizer's `|mean| + 8 std`. The normalizer is folded into the first layer: column
//! `i` gets `W[:, i] / std_i` (and `/ scale_i` for the input quantization), the bias
//! `b - W mean / std`. Hidden activations use a power-of-two format per layer from the
//! calibration (2x headroom) per channel. Weights: `i16` per output channel (largest magnitude ->
//! 32767). The requantization multiplier of each channel is as wide as the worst-case
//! accumulator allows (`|acc| * multiplier < 2^62`, from the channel's own weights), so
//! the `i64` pipeline can never overflow.

use crate::checkpoint::{DenseF32, MlpF32, PolicyF32};
use crate::records::ObsRecord;
use hexapod_core::nn::elu::{ELU_MAX_FRAC_BITS, ELU_MIN_FRAC_BITS};
use hexapod_core::nn::quant::{MAX_SHIFT, MIN_SHIFT};
use hexapod_core::nn::{
    actor_input_words, words, Activation, ChannelQuant, Mlp, QuantizedLayer, QuantizedPolicy,
};
use hexapod_core::obs::{ACTOR_OBS_DIM, HISTORY_DIM, OBS_CLIP};

/// Why a policy cannot be quantized.
#[derive(Debug, thiserror::Error)]
pub enum QuantError {
    /// A channel's scale does not fit the requantization range.
    #[error(
        "{net}.layers.{layer}: channel {channel} scale {scale:e} out of the requantization range"
    )]
    Scale {
        /// Network.
        net: &'static str,
        /// Layer.
        layer: usize,
        /// Output channel.
        channel: usize,
        /// The real requantization factor.
        scale: f64,
    },
    /// A hidden activation is too large for the ELU table's input format.
    #[error("{net}.layers.{layer}: channel {channel} reaches {magnitude:.1}, beyond the ELU range +-256")]
    Range {
        /// Network.
        net: &'static str,
        /// Layer.
        layer: usize,
        /// Output channel.
        channel: usize,
        /// Largest calibrated magnitude.
        magnitude: f64,
    },
    /// No calibration observations were given.
    #[error("calibration needs at least one observation")]
    NoCalibration,
}

/// Headroom over the calibrated magnitudes.
pub const HEADROOM: f64 = 2.0;
/// Normalizer coverage of the input quantization, in standard deviations.
pub const INPUT_COVERAGE_STD: f64 = 8.0;

/// An owned quantized layer (the generated crate holds the same as statics).
#[derive(Clone, Debug, PartialEq)]
pub struct OwnedLayer {
    /// Logical input size (padded for the actor's first layer).
    pub in_dim: usize,
    /// Output size.
    pub out_dim: usize,
    /// Packed, interleaved weights.
    pub weights: Vec<u32>,
    /// Bias, requantization and output format per channel (padded to whole row pairs).
    pub channels: Vec<ChannelQuant>,
    /// Nonlinearity.
    pub activation: Activation,
}

impl OwnedLayer {
    /// Borrowed view for the runtime.
    pub fn view(&self) -> QuantizedLayer<'_> {
        QuantizedLayer {
            in_dim: self.in_dim,
            out_dim: self.out_dim,
            weights: &self.weights,
            channels: &self.channels,
            activation: self.activation,
        }
    }
}

/// An owned quantized policy.
#[derive(Clone, Debug, PartialEq)]
pub struct OwnedPolicy {
    /// History input scales (powers of two).
    pub history_scale: Vec<f32>,
    /// Actor observation input scales (powers of two).
    pub actor_obs_scale: Vec<f32>,
    /// Estimator layers (empty without an estimator).
    pub estimator: Vec<OwnedLayer>,
    /// Memory layers.
    pub memory: Vec<OwnedLayer>,
    /// Actor layers.
    pub actor: Vec<OwnedLayer>,
}

impl OwnedPolicy {
    /// Runs `f` with the runtime's view of the policy.
    pub fn with_view<R>(&self, f: impl FnOnce(&QuantizedPolicy<'_>) -> R) -> R {
        let est: Vec<_> = self.estimator.iter().map(OwnedLayer::view).collect();
        let mem: Vec<_> = self.memory.iter().map(OwnedLayer::view).collect();
        let act: Vec<_> = self.actor.iter().map(OwnedLayer::view).collect();
        let policy = QuantizedPolicy {
            history_scale: &self.history_scale,
            actor_obs_scale: &self.actor_obs_scale,
            estimator: Mlp { layers: &est },
            memory: Mlp { layers: &mem },
            actor: Mlp { layers: &act },
        };
        f(&policy)
    }
}

/// Magnitudes seen on the calibration observations.
#[derive(Clone, Debug)]
pub struct Calibration {
    /// Per history entry.
    pub history_absmax: Vec<f64>,
    /// Per actor observation entry.
    pub actor_obs_absmax: Vec<f64>,
    /// Per estimator layer, per output channel.
    pub estimator: Vec<Vec<f64>>,
    /// Per memory layer, per output channel.
    pub memory: Vec<Vec<f64>>,
    /// Per actor layer, per output channel.
    pub actor: Vec<Vec<f64>>,
}

/// Runs the f32 policy on `records` and records magnitudes.
pub fn calibrate(policy: &PolicyF32, records: &[ObsRecord]) -> Result<Calibration, QuantError> {
    if records.is_empty() {
        return Err(QuantError::NoCalibration);
    }
    let mut cal = Calibration {
        history_absmax: vec![0.0; HISTORY_DIM],
        actor_obs_absmax: vec![0.0; ACTOR_OBS_DIM],
        estimator: policy
            .estimator
            .layers
            .iter()
            .map(|l| vec![0.0; l.out_dim])
            .collect(),
        memory: policy
            .memory
            .layers
            .iter()
            .map(|l| vec![0.0; l.out_dim])
            .collect(),
        actor: policy
            .actor
            .layers
            .iter()
            .map(|l| vec![0.0; l.out_dim])
            .collect(),
    };
    let absmax = |acc: &mut [f64], x: &[f32]| {
        for (a, &v) in acc.iter_mut().zip(x) {
            *a = a.max(v.abs() as f64);
        }
    };
    let layer_max = |acc: &mut [Vec<f64>], outs: &[Vec<f32>]| {
        for (a, o) in acc.iter_mut().zip(outs) {
            absmax(a, o);
        }
    };
    for r in records {
        absmax(&mut cal.history_absmax, &r.history);
        absmax(&mut cal.actor_obs_absmax, &r.actor_obs);
        let t = policy.trace(&r.actor_obs, &r.history);
        layer_max(&mut cal.estimator, &t.estimator);
        layer_max(&mut cal.memory, &t.memory);
        layer_max(&mut cal.actor, &t.actor);
    }
    Ok(cal)
}

/// Largest fractional bit count whose `i16` range covers `range`, within `0..=max`.
pub fn frac_bits_for(range: f64, max: u8) -> u8 {
    let range = range.max(1e-6);
    let bits = (32767.0 / range).log2().floor();
    bits.clamp(0.0, max as f64) as u8
}

fn pow2(bits: i32) -> f64 {
    (bits as f64).exp2()
}

/// How the first layer's columns map to quantized inputs.
struct Column {
    /// Index into the f32 layer's input (`None`: padding).
    source: Option<usize>,
    mean: f64,
    std: f64,
    /// Input quantization scale (x_q = x * scale).
    scale: f64,
}

/// Quantizes one layer: `columns` describe the (padded) input, `out_frac_bits` the output
/// format of each channel.
fn quantize_layer(
    net: &'static str,
    index: usize,
    layer: &DenseF32,
    columns: &[Column],
    out_frac_bits: &[u8],
    activation: Activation,
) -> Result<OwnedLayer, QuantError> {
    let in_dim = columns.len();
    let in_words = words(in_dim);
    let rows = 2 * words(layer.out_dim);
    let mut weights = vec![0u32; rows * in_words];
    let mut channels = vec![ChannelQuant::PAD; rows];
    for r in 0..layer.out_dim {
        let w_row = &layer.weight[r * layer.in_dim..(r + 1) * layer.in_dim];
        // Fold normalization and input scale.
        let mut b = layer.bias[r] as f64;
        let eff: Vec<f64> = columns
            .iter()
            .map(|c| match c.source {
                Some(i) => {
                    let w = w_row[i] as f64 / c.std;
                    b -= w * c.mean;
                    w / c.scale
                }
                None => 0.0,
            })
            .collect();
        let wmax = eff.iter().fold(0.0f64, |m, w| m.max(w.abs()));
        let w_scale = if wmax > 0.0 { wmax / 32767.0 } else { 1.0 };
        let q: Vec<i16> = eff
            .iter()
            .map(|w| (w / w_scale).round().clamp(-32767.0, 32767.0) as i16)
            .collect();
        let bias_q = (b / w_scale).round() as i64;
        let bound: u128 = q
            .iter()
            .map(|&w| w.unsigned_abs() as u128 * 32768)
            .sum::<u128>()
            + bias_q.unsigned_abs() as u128;
        let bound_bits = 128 - bound.leading_zeros() as i32;
        let m_bits = (62 - bound_bits).min(31);
        let real = w_scale * pow2(out_frac_bits[r] as i32);
        let exponent = real.log2().floor() as i32;
        let sh = (m_bits - 1 - exponent).min(MAX_SHIFT as i32);
        let m = (real * pow2(sh)).round();
        if sh < MIN_SHIFT as i32 || m_bits < 8 || m >= pow2(31) {
            return Err(QuantError::Scale {
                net,
                layer: index,
                channel: r,
                scale: real,
            });
        }
        for (k, pair) in q.chunks(2).enumerate() {
            let lo = pair[0];
            let hi = pair.get(1).copied().unwrap_or(0);
            weights[(r / 2) * 2 * in_words + 2 * k + (r % 2)] = hexapod_core::nn::pack(lo, hi);
        }
        channels[r] = ChannelQuant::new(bias_q, m as i32, sh as u8, out_frac_bits[r]);
    }
    Ok(OwnedLayer {
        in_dim,
        out_dim: layer.out_dim,
        weights,
        channels,
        activation,
    })
}

/// Quantizes a network whose first layer reads `columns`; returns the layers.
fn quantize_mlp(
    net: &'static str,
    mlp: &MlpF32,
    first: Vec<Column>,
    cal: &[Vec<f64>],
) -> Result<Vec<OwnedLayer>, QuantError> {
    let n = mlp.layers.len();
    let mut out: Vec<OwnedLayer> = Vec::with_capacity(n);
    let mut columns = first;
    for (k, layer) in mlp.layers.iter().enumerate() {
        let last = k + 1 == n;
        let (activation, max_bits, floor) = if last {
            (Activation::Linear, 15, 1e-3)
        } else {
            (mlp.hidden, ELU_MAX_FRAC_BITS, 1.0)
        };
        let f: Vec<u8> = cal[k]
            .iter()
            .map(|&m| frac_bits_for((m * HEADROOM).max(floor), max_bits))
            .collect();
        let min_bits = if activation == Activation::Elu {
            ELU_MIN_FRAC_BITS
        } else {
            0
        };
        if let Some(channel) = f.iter().position(|&b| b < min_bits) {
            return Err(QuantError::Range {
                net,
                layer: k,
                channel,
                magnitude: cal[k][channel],
            });
        }
        out.push(quantize_layer(net, k, layer, &columns, &f, activation)?);
        columns = f
            .iter()
            .enumerate()
            .map(|(i, &f)| Column {
                source: Some(i),
                mean: 0.0,
                std: 1.0,
                scale: pow2(f as i32),
            })
            .collect();
    }
    Ok(out)
}

fn input_scales(absmax: &[f64], mean: &[f32], std: &[f32]) -> Vec<f64> {
    absmax
        .iter()
        .zip(mean.iter().zip(std))
        .map(|(&a, (&m, &s))| {
            let range = (a * HEADROOM)
                .max(m.abs() as f64 + INPUT_COVERAGE_STD * s as f64)
                .min(OBS_CLIP as f64);
            pow2(frac_bits_for(range, 15) as i32)
        })
        .collect()
}

/// Quantizes the whole policy with calibration `cal`.
pub fn quantize_policy(policy: &PolicyF32, cal: &Calibration) -> Result<OwnedPolicy, QuantError> {
    let hn = &policy.history_norm;
    let an = &policy.actor_obs_norm;
    let history_scale = input_scales(&cal.history_absmax, &hn.mean, &hn.std);
    let actor_obs_scale = input_scales(&cal.actor_obs_absmax, &an.mean, &an.std);
    let history_columns = || -> Vec<Column> {
        (0..HISTORY_DIM)
            .map(|i| Column {
                source: Some(i),
                mean: hn.mean[i] as f64,
                std: hn.std[i] as f64,
                scale: history_scale[i],
            })
            .collect()
    };
    let estimator = if policy.estimator.layers.is_empty() {
        Vec::new()
    } else {
        quantize_mlp(
            "estimator",
            &policy.estimator,
            history_columns(),
            &cal.estimator,
        )?
    };
    let memory = quantize_mlp("memory", &policy.memory, history_columns(), &cal.memory)?;

    // Actor input: observation, estimate, latent, each padded to whole words.
    let est_dim = policy.estimator.out_dim();
    let lat_dim = policy.memory.out_dim();
    let [_, est_w, lat_w, end_w] = actor_input_words(est_dim, lat_dim);
    let mut columns: Vec<Column> = (0..2 * end_w)
        .map(|_| Column {
            source: None,
            mean: 0.0,
            std: 1.0,
            scale: 1.0,
        })
        .collect();
    for i in 0..ACTOR_OBS_DIM {
        columns[i] = Column {
            source: Some(i),
            mean: an.mean[i] as f64,
            std: an.std[i] as f64,
            scale: actor_obs_scale[i],
        };
    }
    let segment_scale = |layers: &[OwnedLayer], i: usize| {
        layers
            .last()
            .and_then(|l| l.channels.get(i))
            .map_or(1.0, |c| pow2(c.frac_bits as i32))
    };
    for i in 0..est_dim {
        columns[2 * est_w + i] = Column {
            source: Some(ACTOR_OBS_DIM + i),
            mean: 0.0,
            std: 1.0,
            scale: segment_scale(&estimator, i),
        };
    }
    for i in 0..lat_dim {
        columns[2 * lat_w + i] = Column {
            source: Some(ACTOR_OBS_DIM + est_dim + i),
            mean: 0.0,
            std: 1.0,
            scale: segment_scale(&memory, i),
        };
    }
    let actor = quantize_mlp("actor", &policy.actor, columns, &cal.actor)?;
    Ok(OwnedPolicy {
        history_scale: history_scale.iter().map(|&s| s as f32).collect(),
        actor_obs_scale: actor_obs_scale.iter().map(|&s| s as f32).collect(),
        estimator,
        memory,
        actor,
    })
}
