//! Adam with named state (saved with checkpoints for resume) and global gradient-norm
//! clipping, as `torch.optim.Adam` + `clip_grad_norm_` in rsl_rl.

use crate::nn::simd;
use candle_core::backprop::GradStore;
use candle_core::{CpuStorage, DType, Error, InplaceOp1, Layout, Result, Tensor, Var};
use candle_nn::VarMap;
use std::cell::RefCell;
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
        self.step_with(grads, max_norm, true)
    }

    /// [`Adam::step`], one pass per f32 tensor when `fused`, else candle op by op.
    fn step_with(&mut self, grads: &GradStore, max_norm: Option<f64>, fused: bool) -> Result<f64> {
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
        let constants = Constants {
            scale,
            decay: 0.0,
            beta1: self.beta1,
            beta2: self.beta2,
            bias2,
            eps: self.eps,
            step_size,
        };
        for s in &self.slots {
            let Some(g) = grads.get(s.var.as_tensor()) else {
                continue;
            };
            let constants = Constants {
                decay: s.weight_decay,
                ..constants
            };
            if !(fused && fused_step(s, g, &constants)?) {
                op_by_op_step(s, g, &constants)?;
            }
        }
        Ok(norm)
    }
}

/// The scalars of one Adam step.
#[derive(Clone, Copy)]
struct Constants {
    /// Gradient scale from the norm clipping (1 when not clipped).
    scale: f64,
    /// L2 weight decay.
    decay: f64,
    beta1: f64,
    beta2: f64,
    /// `1 - beta2^t`.
    bias2: f64,
    eps: f64,
    /// `lr / (1 - beta1^t)`.
    step_size: f64,
}

/// The step as candle tensor operations, one allocating pass each (any dtype or layout).
fn op_by_op_step(s: &Slot, g: &Tensor, c: &Constants) -> Result<()> {
    let g = if c.scale != 1.0 {
        (g * c.scale)?
    } else {
        g.clone()
    };
    let g = if c.decay != 0.0 {
        (g + (s.var.as_tensor() * c.decay)?)?
    } else {
        g
    };
    let m = ((s.m.as_tensor() * c.beta1)? + (&g * (1.0 - c.beta1))?)?;
    let v = ((s.v.as_tensor() * c.beta2)? + (g.sqr()? * (1.0 - c.beta2))?)?;
    let denom = ((&v / c.bias2)?.sqrt()? + c.eps)?;
    let update = ((&m / &denom)? * c.step_size)?;
    s.var.set(&s.var.as_tensor().sub(&update)?)?;
    s.m.set(&m)?;
    s.v.set(&v)?;
    Ok(())
}

/// The step in one pass over the f32 variable, gradient and moments, in place, bit for bit
/// what [`op_by_op_step`] computes: each scalar enters as candle's `Tensor * f64` does (an
/// affine map `x * (c as f32) + 0`, `x / c` as `x * (1 / c)`, `x + c` as `x * 1 + c`), in the
/// same order. Returns false (nothing done) for other dtypes, layouts or shapes.
fn fused_step(s: &Slot, g: &Tensor, c: &Constants) -> Result<bool> {
    let (w, m, v) = (s.var.as_tensor(), s.m.as_tensor(), s.v.as_tensor());
    let n = w.elem_count();
    let fits =
        |t: &Tensor| t.elem_count() == n && t.dtype() == DType::F32 && t.layout().is_contiguous();
    if !([w, g, m, v].into_iter().all(fits) && w.device().is_cpu()) {
        return Ok(false);
    }
    let c = ElementConstants::new(c);
    with_f32_mut(w, |w| {
        with_f32_mut(m, |m| {
            with_f32_mut(v, |v| {
                let g = f32_slice(g).ok_or_else(|| Error::Msg("adam: gradient layout".into()))?;
                simd::widest(AdamLoop { w, g: &g, m, v, c });
                Ok(())
            })
        })
    })?;
    Ok(true)
}

/// Runs `f` on a contiguous f32 CPU tensor's elements under its storage's write lock (the
/// tensor is written in place; candle's in-place op, no copy).
fn with_f32_mut(t: &Tensor, f: impl FnOnce(&mut [f32]) -> Result<()>) -> Result<()> {
    t.inplace_op1(&WithF32Mut(RefCell::new(Some(f))))
}

/// [`with_f32_mut`]'s in-place op: the closure, taken once.
struct WithF32Mut<F>(RefCell<Option<F>>);

impl<F: FnOnce(&mut [f32]) -> Result<()>> InplaceOp1 for WithF32Mut<F> {
    fn name(&self) -> &'static str {
        "with-f32-mut"
    }

    fn cpu_fwd(&self, storage: &mut CpuStorage, layout: &Layout) -> Result<()> {
        let f = self.0.borrow_mut().take();
        match (storage, layout.contiguous_offsets(), f) {
            (CpuStorage::F32(data), Some((start, end)), Some(f)) => f(&mut data[start..end]),
            _ => Err(Error::Msg(
                "with-f32-mut: a contiguous f32 tensor, once".into(),
            )),
        }
    }
}

/// A read guard on a contiguous f32 tensor's elements, `None` for anything else.
fn f32_slice(
    t: &Tensor,
) -> Option<F32Slice<impl std::ops::Deref<Target = candle_core::Storage> + '_>> {
    let (storage, layout) = t.storage_and_layout();
    let (start, end) = layout.contiguous_offsets()?;
    match &*storage {
        candle_core::Storage::Cpu(candle_core::CpuStorage::F32(_)) => {}
        _ => return None,
    }
    Some(F32Slice {
        storage,
        start,
        end,
    })
}

/// A contiguous f32 tensor's elements, held under its storage's read lock.
struct F32Slice<G> {
    storage: G,
    start: usize,
    end: usize,
}

impl<G: std::ops::Deref<Target = candle_core::Storage>> std::ops::Deref for F32Slice<G> {
    type Target = [f32];
    fn deref(&self) -> &[f32] {
        match &*self.storage {
            candle_core::Storage::Cpu(candle_core::CpuStorage::F32(v)) => &v[self.start..self.end],
            _ => unreachable!("checked in f32_slice"),
        }
    }
}

/// [`Constants`] as the f32 factors candle's affine maps use.
#[derive(Clone, Copy)]
struct ElementConstants {
    scale: Option<f32>,
    decay: Option<f32>,
    beta1: f32,
    one_minus_beta1: f32,
    beta2: f32,
    one_minus_beta2: f32,
    inv_bias2: f32,
    eps: f32,
    step_size: f32,
}

impl ElementConstants {
    fn new(c: &Constants) -> Self {
        Self {
            scale: (c.scale != 1.0).then_some(c.scale as f32),
            decay: (c.decay != 0.0).then_some(c.decay as f32),
            beta1: c.beta1 as f32,
            one_minus_beta1: (1.0 - c.beta1) as f32,
            beta2: c.beta2 as f32,
            one_minus_beta2: (1.0 - c.beta2) as f32,
            inv_bias2: (1.0 / c.bias2) as f32,
            eps: c.eps as f32,
            step_size: c.step_size as f32,
        }
    }
}

/// The fused step's loop (compiled for the CPU's vector width, [`simd`]): the weights and
/// moments are updated in place.
struct AdamLoop<'a> {
    w: &'a mut [f32],
    g: &'a [f32],
    m: &'a mut [f32],
    v: &'a mut [f32],
    c: ElementConstants,
}

impl simd::Loop for AdamLoop<'_> {
    type Output = ();
    #[inline(always)]
    fn run(self) {
        let c = self.c;
        let n = self.w.len();
        let (g_all, m_all, v_all) = (&self.g[..n], &mut self.m[..n], &mut self.v[..n]);
        for i in 0..n {
            let (w, g, m, v) = (self.w[i], g_all[i], m_all[i], v_all[i]);
            let g = match c.scale {
                Some(s) => g * s + 0.0,
                None => g,
            };
            let g = match c.decay {
                Some(d) => g + (w * d + 0.0),
                None => g,
            };
            let m = (m * c.beta1 + 0.0) + (g * c.one_minus_beta1 + 0.0);
            let v = (v * c.beta2 + 0.0) + ((g * g) * c.one_minus_beta2 + 0.0);
            let denom = (v * c.inv_bias2 + 0.0).sqrt() * 1.0 + c.eps;
            let update = (m / denom) * c.step_size + 0.0;
            self.w[i] = w - update;
            m_all[i] = m;
            v_all[i] = v;
        }
    }
}

impl Adam {
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

    #[test]
    fn fused_steps_are_the_op_by_op_steps_bit_for_bit() {
        let init = |seed: u64| {
            let map = VarMap::new();
            let vb = VarBuilder::from_varmap(&map, DType::F32, &Device::Cpu);
            let data: Vec<f32> = (0..1_003u64)
                .map(|i| ((i * 2_654_435_761 + seed) % 10_007) as f32 / 5_003.0 - 1.0)
                .collect();
            let init = Tensor::from_vec(data, (17, 59), &Device::Cpu).unwrap();
            let w = vb.get_with_hints((17, 59), "w", Init::Const(0.0)).unwrap();
            let b = vb.get_with_hints(59, "b", Init::Const(0.25)).unwrap();
            map.data().lock().unwrap()["w"].set(&init).unwrap();
            (map, w, b)
        };
        let (map_a, w_a, b_a) = init(7);
        let (map_b, w_b, b_b) = init(7);
        let decay = |name: &str| if name == "w" { 0.01 } else { 0.0 };
        let mut fused = Adam::new(&map_a, 0.003).unwrap().with_weight_decay(decay);
        let mut ops = Adam::new(&map_b, 0.003).unwrap().with_weight_decay(decay);
        use crate::nn::bit_exact::f32_bits as bits;
        let loss = |w: &Tensor, b: &Tensor| -> GradStore {
            let y = w.broadcast_add(b).unwrap();
            (y.sqr().unwrap() - y.sin().unwrap() * 3.0)
                .unwrap()
                .sum_all()
                .unwrap()
                .backward()
                .unwrap()
        };
        for step in 0..5 {
            let max_norm = if step % 2 == 0 { Some(1.0) } else { None };
            let (ga, gb) = (loss(&w_a, &b_a), loss(&w_b, &b_b));
            let na = fused.step_with(&ga, max_norm, true).unwrap();
            let nb = ops.step_with(&gb, max_norm, false).unwrap();
            assert_eq!(na.to_bits(), nb.to_bits(), "step {step}: norm");
            for (a, b) in fused.slots.iter().zip(&ops.slots) {
                assert_eq!(bits(&a.var), bits(&b.var), "step {step}: {}", a.name);
                assert_eq!(bits(&a.m), bits(&b.m), "step {step}: {} m", a.name);
                assert_eq!(bits(&a.v), bits(&b.v), "step {step}: {} v", a.name);
            }
        }
        assert_ne!(bits(&w_a), bits(&init(7).1), "the weights moved");
    }
}
