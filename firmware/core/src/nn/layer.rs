//! One quantized dense layer: `y = act(requant(W x + b))`, weights `i16` per output channel.

use super::elu::{elu_negative, ELU_MAX_FRAC_BITS, ELU_MIN_FRAC_BITS};
use super::kernel::{dot_row_pair, dot_row_pair_portable};
use super::quant::{requantize, saturate_i16, MAX_SHIFT, MIN_SHIFT};
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

/// Per-output-channel constants: bias and requantization.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ChannelQuant {
    /// Bias in accumulator units.
    pub bias: i64,
    /// Requantization multiplier.
    pub multiplier: i32,
    /// Requantization right shift, `MIN_SHIFT..=MAX_SHIFT` (33..=62).
    pub shift: u8,
    /// Fractional bits of the channel's output.
    pub frac_bits: u8,
}

impl ChannelQuant {
    /// A channel (short constructor for generated tables).
    pub const fn new(bias: i64, multiplier: i32, shift: u8, frac_bits: u8) -> Self {
        Self {
            bias,
            multiplier,
            shift,
            frac_bits,
        }
    }

    /// A padding channel (always 0; a format valid for every activation).
    pub const PAD: Self = Self::new(0, 0, MIN_SHIFT, ELU_MIN_FRAC_BITS);
}

/// A dense layer in the packed, row-pair-interleaved layout of [`crate::nn`].
///
/// Output channel `c` is `q_c = round((acc_c + bias_c) * multiplier_c / 2^shift_c)`, where
/// `acc_c` is the exact sum of `w_q[c][i] * x_q[i]`; `q_c` is in Q`frac_bits_c` (real
/// value `q_c / 2^frac_bits_c`): every channel has its own power-of-two format, which the
/// next layer folds into its weight columns. ELU is applied before saturation to `i16`,
/// so very negative inputs still give -1.
#[derive(Clone, Copy, Debug)]
pub struct QuantizedLayer<'a> {
    /// Logical input size.
    pub in_dim: usize,
    /// Logical output size.
    pub out_dim: usize,
    /// `words(out_dim)` row pairs x `words(in_dim)` input words x 2 (interleaved rows).
    pub weights: &'a [u32],
    /// Per channel, `2 * words(out_dim)` entries (padding channels last).
    pub channels: &'a [ChannelQuant],
    /// Nonlinearity.
    pub activation: Activation,
}

impl QuantizedLayer<'_> {
    /// Checks the table lengths and ranges; `index` names the layer in errors.
    pub fn validate(&self, index: usize) -> Result<(), NnError> {
        let rows = 2 * words(self.out_dim);
        let shape_ok = self.weights.len() == rows * words(self.in_dim)
            && self.channels.len() == rows
            && self.in_dim > 0
            && self.out_dim > 0;
        if !shape_ok {
            return Err(NnError::LayerShape { layer: index });
        }
        let frac = match self.activation {
            Activation::Elu => ELU_MIN_FRAC_BITS..=ELU_MAX_FRAC_BITS,
            Activation::Linear | Activation::Relu => 0..=15,
        };
        let ok = |c: &ChannelQuant| {
            (MIN_SHIFT..=MAX_SHIFT).contains(&c.shift) && frac.contains(&c.frac_bits)
        };
        if !self.channels.iter().all(ok) {
            return Err(NnError::Requant { layer: index });
        }
        Ok(())
    }

    /// Multiply-accumulates of one evaluation.
    pub const fn macs(&self) -> usize {
        self.in_dim * self.out_dim
    }

    /// Runs the layer on packed `input` (at least `words(in_dim)` words) into packed
    /// `output` (at least `words(out_dim)` words). Call [`Self::validate`] once first:
    /// with short tables the missing rows are skipped, never read out of bounds.
    #[inline]
    pub fn run(&self, input: &[u32], output: &mut [u32]) {
        match self.activation {
            Activation::Linear => self.run_with(input, output, dot_row_pair, linear),
            Activation::Elu => self.run_with(input, output, dot_row_pair, elu),
            Activation::Relu => self.run_with(input, output, dot_row_pair, relu),
        }
    }

    /// [`Self::run`] with the portable kernel on every target (benchmark baseline).
    pub fn run_portable(&self, input: &[u32], output: &mut [u32]) {
        let k = dot_row_pair_portable;
        match self.activation {
            Activation::Linear => self.run_with(input, output, k, linear),
            Activation::Elu => self.run_with(input, output, k, elu),
            Activation::Relu => self.run_with(input, output, k, relu),
        }
    }

    /// The loop over row pairs, specialized for one kernel and one activation.
    #[inline(always)]
    fn run_with(
        &self,
        input: &[u32],
        output: &mut [u32],
        kernel: impl Fn(&[u32], &[u32], (i64, i64)) -> (i64, i64),
        activation: impl Fn(i32, u8) -> i16,
    ) {
        let in_words = words(self.in_dim);
        let x = input.get(..in_words).unwrap_or(input);
        let rows = self
            .weights
            .chunks_exact(2 * in_words)
            .zip(self.channels.chunks_exact(2))
            .zip(output.iter_mut().take(words(self.out_dim)));
        let finish = |acc: i64, c: &ChannelQuant| {
            activation(requantize(acc, c.multiplier, c.shift), c.frac_bits)
        };
        for ((w, c), out) in rows {
            if let [c0, c1] = c {
                let (acc0, acc1) = kernel(w, x, (c0.bias, c1.bias));
                *out = pack(finish(acc0, c0), finish(acc1, c1));
            }
        }
    }
}

#[inline(always)]
fn linear(y: i32, _frac_bits: u8) -> i16 {
    saturate_i16(y)
}

#[inline(always)]
fn elu(y: i32, frac_bits: u8) -> i16 {
    if y < 0 {
        elu_negative(y, frac_bits)
    } else {
        saturate_i16(y)
    }
}

#[inline(always)]
fn relu(y: i32, _frac_bits: u8) -> i16 {
    saturate_i16(y.max(0))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::nn::unpack;

    /// 3 inputs (Q12), 3 outputs (Q12); weights in Q14, so `multiplier / 2^shift = 2^-14`.
    fn tables() -> ([u32; 8], [ChannelQuant; 4]) {
        let w = |r: [i16; 3]| [pack(r[0], r[1]), pack(r[2], 0)];
        let (r0, r1, r2) = (w([16384, 0, 0]), w([-16384, 8192, 0]), w([0, 0, -16384]));
        // Row pairs (0, 1) and (2, padding), each input word interleaved.
        let weights = [r0[0], r1[0], r0[1], r1[1], r2[0], 0, r2[1], 0];
        let q = |bias: i64| ChannelQuant::new(bias, 1 << 20, 34, 12);
        (weights, [q(0), q(4096 << 14), q(0), ChannelQuant::PAD])
    }

    fn layer<'a>(
        weights: &'a [u32],
        channels: &'a [ChannelQuant],
        activation: Activation,
    ) -> QuantizedLayer<'a> {
        QuantizedLayer {
            in_dim: 3,
            out_dim: 3,
            weights,
            channels,
            activation,
        }
    }

    #[test]
    fn computes_requantizes_and_activates() {
        let (weights, channels) = tables();
        // x = (1.0, 0.5, 2.0) in Q12.
        let x = [pack(4096, 2048), pack(8192, 0)];
        let mut y = [0u32; 2];
        let linear = layer(&weights, &channels, Activation::Linear);
        linear.validate(0).unwrap();
        linear.run(&x, &mut y);
        // y0 = 1.0; y1 = -1.0 + 0.25 + 1.0 (bias) = 0.25; y2 = -2.0 (Q12).
        assert_eq!(
            [unpack(&y, 0), unpack(&y, 1), unpack(&y, 2)],
            [4096, 1024, -8192]
        );
        assert_eq!(unpack(&y, 3), 0, "padding stays zero");
        layer(&weights, &channels, Activation::Elu).run(&x, &mut y);
        // ELU(-2) = exp(-2) - 1 = -0.8647 -> -3542 in Q12 (within the table's accuracy).
        assert!(
            (unpack(&y, 2) as i32 + 3542).abs() <= 1,
            "{}",
            unpack(&y, 2)
        );
        assert_eq!(unpack(&y, 0), 4096);
        let relu = layer(&weights, &channels, Activation::Relu);
        relu.run(&x, &mut y);
        assert_eq!(unpack(&y, 2), 0);
        let mut y_portable = [0u32; 2];
        relu.run_portable(&x, &mut y_portable);
        assert_eq!(y, y_portable);
    }

    #[test]
    fn validation_names_the_problem() {
        let (weights, channels) = tables();
        let short = layer(&weights[..6], &channels, Activation::Linear);
        assert_eq!(short.validate(2), Err(NnError::LayerShape { layer: 2 }));
        let mut bad_shift = channels;
        bad_shift[1].shift = 20;
        assert_eq!(
            layer(&weights, &bad_shift, Activation::Linear).validate(1),
            Err(NnError::Requant { layer: 1 })
        );
        let mut fine_format = channels;
        fine_format[1].frac_bits = 15;
        assert!(layer(&weights, &fine_format, Activation::Linear)
            .validate(1)
            .is_ok());
        assert_eq!(
            layer(&weights, &fine_format, Activation::Elu).validate(1),
            Err(NnError::Requant { layer: 1 })
        );
    }
}
