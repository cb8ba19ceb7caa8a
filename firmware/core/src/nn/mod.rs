//! Fixed-point runtime of the controller's networks (estimator, memory, actor).
//!
//! Integer pipeline end to end: observations are quantized once to `i16` (a power-of-two
//! scale per entry, so the multiply is exact), every layer multiplies `i16` weights
//! (quantized per output channel) with `i16` activations into exact `i64` accumulators,
//! requantizes with a per-channel integer multiplier and shift, and applies ELU through a
//! table. The only float steps are the input quantization and the output dequantization,
//! done identically on host and target, so the host's portable path and the Cortex-M DSP
//! path (SMLALD, see [`kernel`]) give bit-identical actions.
//!
//! Observation normalization (`(x - mean) / std`) is folded into the first layers by
//! `policy-codegen`; the generated crate `hexapod-policy` holds [`QuantizedPolicy`] statics.
//!
//! Data layout: activations are packed two per `u32` word (element `2k` in the low half),
//! every vector padded to an even length with zeros. Weights are stored by row pairs: for
//! rows `2p, 2p + 1` and input pair `k`, word `2k` holds row `2p`'s pair and word `2k + 1`
//! row `2p + 1`'s, so one input word feeds two dual multiply-accumulates.

pub mod bench;
pub mod elu;
pub mod kernel;
pub mod layer;
pub mod policy;
pub mod quant;
pub mod reference;

pub use layer::{Activation, ChannelQuant, QuantizedLayer};
pub use policy::{
    actor_input_words, Kernel, Mlp, PolicyOutput, PolicyRunner, QuantizedPolicy, Scratch,
};

/// Why a quantized network cannot run.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum NnError {
    /// A layer's weight, bias or requantization table has the wrong length.
    LayerShape {
        /// Index of the layer in its network.
        layer: usize,
    },
    /// Consecutive layers (or a network and its input or output) do not chain.
    Chain {
        /// Index of the layer whose input does not match.
        layer: usize,
    },
    /// A requantization shift or fractional bit count is out of range.
    Requant {
        /// Index of the layer.
        layer: usize,
    },
    /// The scratch buffers are smaller than the widest layer.
    ScratchTooSmall,
    /// An input was NaN or infinite.
    NonFiniteInput,
}

/// Number of packed `u32` words that hold `n` `i16` elements.
pub const fn words(n: usize) -> usize {
    n.div_ceil(2)
}

/// Element `i` of a packed vector.
#[inline(always)]
pub fn unpack(packed: &[u32], i: usize) -> i16 {
    match packed.get(i / 2) {
        Some(&w) => (w >> (16 * (i % 2))) as u16 as i16,
        None => 0,
    }
}

/// Packs two elements into one word (`lo` is the even element).
#[inline(always)]
pub const fn pack(lo: i16, hi: i16) -> u32 {
    (lo as u16 as u32) | ((hi as u16 as u32) << 16)
}
