//! An MLP with ELU between layers and a linear output; weights live under
//! `<prefix>.layers.{k}.weight|bias` (shape `[out, in]`), the keys the code generator reads.

use candle_core::{Result, Tensor};
use candle_nn::{Linear, VarBuilder};

/// A linear layer initialized as PyTorch's `nn.Linear` (what rsl_rl uses): weights and
/// biases uniform in `+-1/sqrt(fan_in)`. (candle's `linear` draws Kaiming-normal weights for
/// ReLU, about 2.4x larger per layer, which makes a fresh policy's actions explode through
/// the previous-action feedback.)
pub fn torch_linear(input: usize, output: usize, vb: VarBuilder) -> Result<Linear> {
    let bound = 1.0 / (input as f64).sqrt();
    let init = candle_nn::Init::Uniform {
        lo: -bound,
        up: bound,
    };
    let w = vb.get_with_hints((output, input), "weight", init)?;
    let b = vb.get_with_hints(output, "bias", init)?;
    Ok(Linear::new(w, Some(b)))
}

/// `x W^T + b` as `candle_nn::Linear` computes it for a `[B, in]` batch, with the bias
/// added by [`crate::nn::bias::add_bias`] (its gradient one pass over the rows).
fn linear(layer: &Linear, x: &Tensor) -> Result<Tensor> {
    let y = x.matmul(&layer.weight().t()?)?;
    match layer.bias() {
        Some(b) => crate::nn::bias::add_bias(&y, b),
        None => Ok(y),
    }
}

/// `elu(x W^T + b)`, the bias and the ELU in one pass
/// ([`crate::nn::bias::add_bias_elu`]; the same bits as [`linear`] then ELU).
fn linear_elu(layer: &Linear, x: &Tensor) -> Result<Tensor> {
    let y = x.matmul(&layer.weight().t()?)?;
    match layer.bias() {
        Some(b) => crate::nn::bias::add_bias_elu(&y, b),
        None => crate::nn::elu::elu(&y),
    }
}

/// A multilayer perceptron: `Linear -> ELU -> ... -> Linear`.
#[derive(Clone, Debug)]
pub struct Mlp {
    layers: Vec<Linear>,
}

impl Mlp {
    /// Creates (or loads) an MLP `input -> hidden... -> output` under `vb`'s prefix.
    pub fn new(input: usize, hidden: &[usize], output: usize, vb: VarBuilder) -> Result<Self> {
        let mut sizes = Vec::with_capacity(hidden.len() + 2);
        sizes.push(input);
        sizes.extend_from_slice(hidden);
        sizes.push(output);
        let layers = sizes
            .windows(2)
            .enumerate()
            .map(|(k, w)| torch_linear(w[0], w[1], vb.pp(format!("layers.{k}"))))
            .collect::<Result<Vec<_>>>()?;
        Ok(Self { layers })
    }

    /// The linear layers in order.
    pub fn layers(&self) -> &[Linear] {
        &self.layers
    }

    /// Input size.
    pub fn input_dim(&self) -> usize {
        self.layers[0].weight().dims()[1]
    }

    /// Output size.
    pub fn output_dim(&self) -> usize {
        self.layers[self.layers.len() - 1].weight().dims()[0]
    }

    /// Forward pass `[B, in] -> [B, out]` (each hidden layer's bias and ELU in one pass).
    pub fn forward(&self, x: &Tensor) -> Result<Tensor> {
        let mut h = x.clone();
        let last = self.layers.len() - 1;
        for (k, layer) in self.layers.iter().enumerate() {
            h = if k < last {
                linear_elu(layer, &h)?
            } else {
                linear(layer, &h)?
            };
        }
        Ok(h)
    }

    /// Forward pass that also returns every hidden pre-activation `z_k` (before ELU), as the
    /// explicit input gradient needs them.
    pub fn forward_with_preactivations(&self, x: &Tensor) -> Result<(Tensor, Vec<Tensor>)> {
        let mut h = x.clone();
        let last = self.layers.len() - 1;
        let mut pre = Vec::with_capacity(last);
        for (k, layer) in self.layers.iter().enumerate() {
            h = linear(layer, &h)?;
            if k < last {
                pre.push(h.clone());
                h = crate::nn::elu::elu(&h)?;
            }
        }
        Ok((h, pre))
    }

    /// Gradient of a scalar-output MLP with respect to its input, `[B, in]`, as an explicit
    /// forward expression: `dy/dx = W_L diag(elu'(z_{L-1})) ... W_2 diag(elu'(z_1)) W_1`,
    /// with `elu'(z) = exp(min(z, 0))`. It stays differentiable with respect to the weights,
    /// so a gradient penalty built on it backpropagates exactly (no double backward needed).
    pub fn input_gradient(&self, preactivations: &[Tensor]) -> Result<Tensor> {
        let n = self.layers.len();
        assert_eq!(
            preactivations.len(),
            n - 1,
            "one pre-activation per hidden layer"
        );
        assert_eq!(self.output_dim(), 1, "input_gradient needs a scalar output");
        if n == 1 {
            return self.layers[0]
                .weight()
                .broadcast_as((preactivations.len().max(1), self.input_dim()))?
                .contiguous();
        }
        // dy/dz_{n-2} (*) W_{n-2} = elu'(z_{n-2}) @ (diag(w_{n-1}) W_{n-2}): folding the last
        // weight row into the previous matrix saves a batch-sized product and its backward.
        let w_last = self.layers[n - 1].weight().t()?; // [H, 1]
        let folded = self.layers[n - 2].weight().broadcast_mul(&w_last)?; // [H, in]
        let mut g = crate::nn::elu::elu_derivative(&preactivations[n - 2])?.matmul(&folded)?;
        for k in (0..n - 2).rev() {
            g = crate::nn::elu::times_elu_derivative(&g, &preactivations[k])?
                .matmul(self.layers[k].weight())?; // [B, in_k]
        }
        Ok(g)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use candle_core::{DType, Device};
    use candle_nn::VarMap;

    #[test]
    fn keys_follow_the_checkpoint_contract() {
        let map = VarMap::new();
        let vb = VarBuilder::from_varmap(&map, DType::F32, &Device::Cpu);
        let mlp = Mlp::new(210, &[64, 32], 3, vb.pp("estimator")).unwrap();
        let data = map.data().lock().unwrap();
        let w = data.get("estimator.layers.0.weight").unwrap();
        assert_eq!(w.dims(), &[64, 210]);
        assert!(data.contains_key("estimator.layers.2.bias"));
        assert_eq!(data.len(), 6);
        assert_eq!((mlp.input_dim(), mlp.output_dim()), (210, 3));
    }

    #[test]
    fn input_gradient_matches_finite_differences() {
        let map = VarMap::new();
        let vb = VarBuilder::from_varmap(&map, DType::F64, &Device::Cpu);
        let mlp = Mlp::new(5, &[7, 6], 1, vb).unwrap();
        let x0: Vec<f64> = (0..10)
            .map(|i| ((i * 37 % 11) as f64 - 5.0) * 0.3)
            .collect();
        let x = Tensor::from_vec(x0.clone(), (2, 5), &Device::Cpu).unwrap();
        let (_, pre) = mlp.forward_with_preactivations(&x).unwrap();
        let g = mlp.input_gradient(&pre).unwrap().to_vec2::<f64>().unwrap();
        let eps = 1e-6;
        for b in 0..2 {
            for i in 0..5 {
                let eval = |d: f64| {
                    let mut xs = x0.clone();
                    xs[b * 5 + i] += d;
                    let t = Tensor::from_vec(xs, (2, 5), &Device::Cpu).unwrap();
                    mlp.forward(&t).unwrap().to_vec2::<f64>().unwrap()[b][0]
                };
                let fd = (eval(eps) - eval(-eps)) / (2.0 * eps);
                assert!(
                    (fd - g[b][i]).abs() < 1e-6,
                    "b {b} i {i}: fd {fd} explicit {}",
                    g[b][i]
                );
            }
        }
    }
}
