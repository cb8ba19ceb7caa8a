//! One quantized dense layer: `y = act(requant(W x + b))`, weights `i16` per output channel.

use super::elu::{elu_negative, ELU_MAX_FRAC_BITS};
use super::kernel::{dot_row_pair, dot_row_pair_portable};
use super::quant::{requantize, saturate_i16};
use super::{pack, words, NnError};

/// The nonlinearity after a layer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Activation {
    /// None (output layers).
    Linear,
    /// ELU with alpha 1.
    Elu,
    /// ReLU (policies imported from elsewhere).
    Relu,
}

/// A dense layer in the packed, row-pair-interleaved layout of [`crate::nn`].
///
/// Output channel `c` is `q_c = round((acc_c + bias[c]) * multiplier[c] / 2^shift[c])`,
/// where `acc_c` is the exact sum of `w_q[c][i] * x_q[i]`; `q_c` is in
/// Q`out_frac_bits[c]` (real value `q_c / 2^out_frac_bits[c]`): every channel has its own
/// power-of-two format, which the next layer folds into its weight columns. ELU is applied before saturation
/// to `i16`, so very negative inputs still give -1.
#[derive(Clone, Copy, Debug)]
pub struct QuantizedLayer<'a> {
    /// Logical input size.
    pub in_dim: usize,
    /// Logical output size.
    pub out_dim: usize,
    /// `words(out_dim)` row pairs x `words(in_dim)` input words x 2 (interleaved rows).
    pub weights: &'a [u32],
    /// Bias in accumulator units, `2 * words(out_dim)` entries (zero padding).
    pub bias: &'a [i64],
    /// Requantization multiplier per channel (`2 * words(out_dim)` entries).
    pub multiplier: &'a [i32],
    /// Requantization right shift per channel, `1..=62`.
    pub shift: &'a [u8],
    /// Fractional bits of each output channel (`2 * words(out_dim)` entries).
    pub out_frac_bits: &'a [u8],
    /// Nonlinearity.
    pub activation: Activation,
}

impl QuantizedLayer<'_> {
    /// Checks the table lengths and ranges; `index` names the layer in errors.
    pub fn validate(&self, index: usize) -> Result<(), NnError> {
        let rows = 2 * words(self.out_dim);
        let shape_ok = self.weights.len() == rows * words(self.in_dim)
            && self.bias.len() == rows
            && self.multiplier.len() == rows
            && self.shift.len() == rows
            && self.out_frac_bits.len() == rows
            && self.in_dim > 0
            && self.out_dim > 0;
        if !shape_ok {
            return Err(NnError::LayerShape { layer: index });
        }
        let max_frac = match self.activation {
            Activation::Elu => ELU_MAX_FRAC_BITS,
            Activation::Linear | Activation::Relu => 15,
        };
        let frac_ok = self.out_frac_bits.iter().all(|&f| f <= max_frac);
        if !frac_ok || self.shift.iter().any(|&s| !(1..=62).contains(&s)) {
            return Err(NnError::Requant { layer: index });
        }
        Ok(())
    }

    /// Multiply-accumulates of one evaluation (logical sizes).
    pub const fn macs(&self) -> usize {
        self.in_dim * self.out_dim
    }

    /// Runs the layer on packed `input` (at least `words(in_dim)` words) into packed
    /// `output` (at least `words(out_dim)` words). Call [`Self::validate`] once first:
    /// with short tables the missing rows are skipped, never read out of bounds.
    #[inline]
    pub fn run(&self, input: &[u32], output: &mut [u32]) {
        self.run_with(input, output, dot_row_pair);
    }

    /// [`Self::run`] with the portable kernel on every target (benchmark baseline).
    pub fn run_portable(&self, input: &[u32], output: &mut [u32]) {
        self.run_with(input, output, dot_row_pair_portable);
    }

    #[inline(always)]
    fn run_with(
        &self,
        input: &[u32],
        output: &mut [u32],
        kernel: impl Fn(&[u32], &[u32], (i64, i64)) -> (i64, i64),
    ) {
        let in_words = words(self.in_dim);
        let x = input.get(..in_words).unwrap_or(input);
        let rows = self
            .weights
            .chunks_exact(2 * in_words)
            .zip(self.bias.chunks_exact(2))
            .zip(self.multiplier.chunks_exact(2))
            .zip(self.shift.chunks_exact(2))
            .zip(self.out_frac_bits.chunks_exact(2))
            .zip(output.iter_mut().take(words(self.out_dim)));
        for (((((w, b), m), s), f), out) in rows {
            let (acc0, acc1) = kernel(w, x, (b[0], b[1]));
            let y0 = self.finish(requantize(acc0, m[0], s[0]), f[0]);
            let y1 = self.finish(requantize(acc1, m[1], s[1]), f[1]);
            *out = pack(y0, y1);
        }
    }

    #[inline(always)]
    fn finish(&self, y: i64, frac_bits: u8) -> i16 {
        match self.activation {
            Activation::Elu if y < 0 => elu_negative(y, frac_bits),
            Activation::Relu if y < 0 => 0,
            _ => saturate_i16(y),
        }
    }
}
