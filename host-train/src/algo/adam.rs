//! Adam with named state (saved with checkpoints for resume) and global gradient-norm
//! clipping, as `torch.optim.Adam` + `clip_grad_norm_` in rsl_rl.

use candle_core::backprop::GradStore;
use candle_core::{Result, Tensor, Var};
use candle_nn::VarMap;
use std::collections::HashMap;

struct Slot {
    name: String,
    /// L2 weight decay added to the gradient (torch.optim.Adam's `weight_decay`).
    weight_decay: f64,
    var: Var,
    m: Var,
    v: Var,
}

/// Adam over a named set of variables.
pub struct Adam {
    slots: Vec<Slot>,
    step_count: usize,
    /// Learning rate.
    pub lr: f64,
    beta1: f64,
    beta2: f64,
    eps: f64,
}

impl Adam {
    /// Adam over every variable of `map` (sorted by name, so the order is reproducible).
    pub fn new(map: &VarMap, lr: f64) -> Result<Self> {
        let data = map.data().lock().expect("var map lock");
        let mut names: Vec<&String> = data.keys().collect();
        names.sort();
        let slots = names
            .into_iter()
            .map(|name| {
                let var = data[name].clone();
                Ok(Slot {
                    name: name.clone(),
                    weight_decay: 0.0,
                    m: Var::zeros(var.shape(), var.dtype(), var.device())?,
                    v: Var::zeros(var.shape(), var.dtype(), var.device())?,
                    var,
                })
            })
            .collect::<Result<Vec<_>>>()?;
        Ok(Self {
            slots,
            step_count: 0,
            lr,
            beta1: 0.9,
            beta2: 0.999,
            eps: 1e-8,
        })
    }

    /// Sets each variable's L2 weight decay from its name (torch's `weight_decay`, coupled:
    /// `g += decay * w` before the moments).
    pub fn with_weight_decay(mut self, decay_of: impl Fn(&str) -> f64) -> Self {
        for s in &mut self.slots {
            s.weight_decay = decay_of(&s.name);
        }
        self
    }

    /// L2 norm of all gradients of this optimizer's variables.
    pub fn grad_norm(&self, grads: &GradStore) -> Result<f64> {
        let mut sq = 0.0f64;
        for s in &self.slots {
            if let Some(g) = grads.get(s.var.as_tensor()) {
                sq += g
                    .sqr()?
                    .sum_all()?
                    .to_dtype(candle_core::DType::F64)?
                    .to_scalar::<f64>()?;
            }
        }
        Ok(sq.sqrt())
    }

    /// One Adam step; gradients are scaled so that their global norm is at most `max_norm`
    /// (no clipping when `None`). Returns the norm before clipping.
    pub fn step(&mut self, grads: &GradStore, max_norm: Option<f64>) -> Result<f64> {
        let norm = self.grad_norm(grads)?;
        let scale = match max_norm {
            Some(max) if norm > max => max / (norm + 1e-6),
            _ => 1.0,
        };
        self.step_count += 1;
        let t = self.step_count as i32;
        let bias1 = 1.0 - self.beta1.powi(t);
        let bias2 = 1.0 - self.beta2.powi(t);
        let step_size = self.lr / bias1;
        for s in &self.slots {
            let Some(g) = grads.get(s.var.as_tensor()) else {
                continue;
            };
            let g = if scale != 1.0 {
                (g * scale)?
            } else {
                g.clone()
            };
            let g = if s.weight_decay != 0.0 {
                (g + (s.var.as_tensor() * s.weight_decay)?)?
            } else {
                g
            };
            let m = ((s.m.as_tensor() * self.beta1)? + (&g * (1.0 - self.beta1))?)?;
            let v = ((s.v.as_tensor() * self.beta2)? + (g.sqr()? * (1.0 - self.beta2))?)?;
            let denom = ((&v / bias2)?.sqrt()? + self.eps)?;
            let update = ((&m / &denom)? * step_size)?;
            s.var.set(&s.var.as_tensor().sub(&update)?)?;
            s.m.set(&m)?;
            s.v.set(&v)?;
        }
        Ok(norm)
    }

    /// Optimizer state as named tensors, `<prefix>.<var>.m|v` and `<prefix>.step`.
    pub fn state(&self, prefix: &str) -> Result<Vec<(String, Tensor)>> {
        let mut out = Vec::with_capacity(2 * self.slots.len() + 2);
        for s in &self.slots {
            out.push((format!("{prefix}.{}.m", s.name), s.m.as_tensor().clone()));
            out.push((format!("{prefix}.{}.v", s.name), s.v.as_tensor().clone()));
        }
        let dev = self
            .slots
            .first()
            .map(|s| s.var.device().clone())
            .unwrap_or(candle_core::Device::Cpu);
        out.push((
            format!("{prefix}.step"),
            Tensor::new(&[self.step_count as f32], &dev)?,
        ));
        out.push((
            format!("{prefix}.lr"),
            Tensor::new(&[self.lr as f32], &dev)?,
        ));
        Ok(out)
    }

    /// Restores the state written by [`Adam::state`]; missing entries leave the state fresh.
    pub fn load_state(&mut self, prefix: &str, tensors: &HashMap<String, Tensor>) -> Result<()> {
        for s in &self.slots {
            if let (Some(m), Some(v)) = (
                tensors.get(&format!("{prefix}.{}.m", s.name)),
                tensors.get(&format!("{prefix}.{}.v", s.name)),
            ) {
                s.m.set(m)?;
                s.v.set(v)?;
            }
        }
        if let Some(step) = tensors.get(&format!("{prefix}.step")) {
            self.step_count = step.to_vec1::<f32>()?[0] as usize;
        }
        if let Some(lr) = tensors.get(&format!("{prefix}.lr")) {
            self.lr = lr.to_vec1::<f32>()?[0] as f64;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use candle_core::{DType, Device};
    use candle_nn::{Init, VarBuilder};

    #[test]
    fn first_step_moves_each_weight_by_lr_against_its_gradient_sign() {
        let map = VarMap::new();
        let vb = VarBuilder::from_varmap(&map, DType::F32, &Device::Cpu);
        let w = vb.get_with_hints(3, "w", Init::Const(1.0)).unwrap();
        let target = Tensor::new(&[0.0f32, 2.0, 1.0], &Device::Cpu).unwrap();
        let loss = w.sub(&target).unwrap().sqr().unwrap().sum_all().unwrap();
        let grads = loss.backward().unwrap();
        let mut opt = Adam::new(&map, 0.1).unwrap();
        let norm = opt.step(&grads, None).unwrap();
        assert!((norm - (4.0f64 + 4.0).sqrt()).abs() < 1e-5);
        let after = w.to_vec1::<f32>().unwrap();
        assert!((after[0] - 0.9).abs() < 1e-5 && (after[1] - 1.1).abs() < 1e-5);
        assert!((after[2] - 1.0).abs() < 1e-6, "zero gradient, no move");
    }

    #[test]
    fn weight_decay_pulls_a_weight_without_gradient_towards_zero() {
        let map = VarMap::new();
        let vb = VarBuilder::from_varmap(&map, DType::F32, &Device::Cpu);
        let w = vb.get_with_hints(2, "w", Init::Const(1.0)).unwrap();
        let loss = w.narrow(0, 0, 1).unwrap().sum_all().unwrap();
        let grads = loss.backward().unwrap();
        let mut opt = Adam::new(&map, 0.1).unwrap().with_weight_decay(|_| 0.5);
        opt.step(&grads, None).unwrap();
        let after = w.to_vec1::<f32>().unwrap();
        assert!((after[0] - 0.9).abs() < 1e-5, "{after:?}");
        // The loss does not depend on w[1]: its gradient is zero, and decay alone moves it.
        assert!(
            (after[1] - 0.9).abs() < 1e-5,
            "decay alone moves it by lr: {after:?}"
        );
    }

    #[test]
    fn state_round_trips() {
        let map = VarMap::new();
        let vb = VarBuilder::from_varmap(&map, DType::F32, &Device::Cpu);
        let w = vb.get_with_hints(2, "w", Init::Const(1.0)).unwrap();
        let grads = w.sqr().unwrap().sum_all().unwrap().backward().unwrap();
        let mut a = Adam::new(&map, 0.01).unwrap();
        a.step(&grads, Some(0.5)).unwrap();
        a.lr = 0.003;
        let state: HashMap<String, Tensor> = a.state("opt").unwrap().into_iter().collect();
        let mut b = Adam::new(&map, 0.01).unwrap();
        b.load_state("opt", &state).unwrap();
        assert_eq!(b.step_count, 1);
        assert!((b.lr - 0.003).abs() < 1e-9);
        assert_eq!(
            b.slots[0].m.to_vec1::<f32>().unwrap(),
            a.slots[0].m.to_vec1::<f32>().unwrap()
        );
    }

    #[test]
    fn three_clipped_decayed_steps_match_torch_adams_formula() {
        let map = VarMap::new();
        let vb = VarBuilder::from_varmap(&map, DType::F32, &Device::Cpu);
        let w = vb
            .get_with_hints(
                (2, 3),
                "w",
                Init::Randn {
                    mean: 0.0,
                    stdev: 1.0,
                },
            )
            .unwrap();
        let x = Tensor::new(&[[0.5f32, -1.0, 2.0], [1.5, 0.25, -0.75]], &Device::Cpu).unwrap();
        let mut opt = Adam::new(&map, 0.01).unwrap().with_weight_decay(|_| 0.1);
        let (lr, b1, b2, eps, decay, max_norm) =
            (0.01f64, 0.9f64, 0.999f64, 1e-8f64, 0.1f64, 0.5f64);
        let f64s = |t: &Tensor| -> Vec<f64> {
            let v = t.flatten_all().unwrap().to_vec1::<f32>().unwrap();
            v.into_iter().map(f64::from).collect()
        };
        let mut wr = f64s(&w);
        let (mut m, mut v) = (vec![0.0f64; 6], vec![0.0f64; 6]);
        for t in 1..=3 {
            let loss = w.mul(&x).unwrap().sqr().unwrap().sum_all().unwrap();
            let grads = loss.backward().unwrap();
            let g = f64s(grads.get(&w).unwrap());
            let norm = g.iter().map(|v| v * v).sum::<f64>().sqrt();
            let scale = if norm > max_norm {
                max_norm / (norm + 1e-6)
            } else {
                1.0
            };
            assert!((opt.step(&grads, Some(max_norm)).unwrap() - norm).abs() < 1e-5 * norm);
            for i in 0..6 {
                let gi = g[i] * scale + decay * wr[i];
                m[i] = b1 * m[i] + (1.0 - b1) * gi;
                v[i] = b2 * v[i] + (1.0 - b2) * gi * gi;
                let denom = (v[i] / (1.0 - b2.powi(t))).sqrt() + eps;
                wr[i] -= lr / (1.0 - b1.powi(t)) * m[i] / denom;
            }
            let got = w.flatten_all().unwrap().to_vec1::<f32>().unwrap();
            for i in 0..6 {
                assert!(
                    (got[i] as f64 - wr[i]).abs() < 1e-5,
                    "step {t}, {i}: {} against {}",
                    got[i],
                    wr[i]
                );
            }
        }
    }
}
