//! The whole policy step: history and actor observation in, action and joint targets out.
//!
//! Estimator and memory read the quantized 5-step history (normalization folded into
//! their first layers); the actor reads the quantized actor observation, the velocity
//! estimate and the memory latent, packed side by side (each segment padded to whole
//! words, see [`actor_input_words`]). The action is clipped to `+-ACTION_CLIP` and becomes
//! `q_d = q0 + ACTION_SCALE_RAD * a`.

use super::layer::QuantizedLayer;
use super::quant::{pow2, quantize_packed};
use super::{unpack, words, NnError};
use crate::obs::{actor_obs, ProprioHistory, ACTION_CLIP, ACTOR_OBS_DIM, HISTORY_DIM, PROPRIO_DIM};
use crate::robot::{NUM_JOINTS, Q0_RAD};
use crate::timing::ACTION_SCALE_RAD;

/// A chain of quantized layers.
#[derive(Clone, Copy, Debug)]
pub struct Mlp<'a> {
    /// Layers, input first.
    pub layers: &'a [QuantizedLayer<'a>],
}

impl Mlp<'_> {
    /// Input size (0 without layers).
    pub fn in_dim(&self) -> usize {
        self.layers.first().map_or(0, |l| l.in_dim)
    }

    /// Output size (0 without layers).
    pub fn out_dim(&self) -> usize {
        self.layers.last().map_or(0, |l| l.out_dim)
    }

    /// Fractional bits of output channel `i`.
    pub fn out_frac_bits(&self, i: usize) -> u8 {
        self.layers
            .last()
            .and_then(|l| l.channels.get(i))
            .map_or(0, |c| c.frac_bits)
    }

    /// Multiply-accumulates of one evaluation.
    pub fn macs(&self) -> usize {
        self.layers.iter().map(QuantizedLayer::macs).sum()
    }

    /// Widest layer output, in words.
    pub fn max_out_words(&self) -> usize {
        self.layers
            .iter()
            .map(|l| words(l.out_dim))
            .max()
            .unwrap_or(0)
    }

    /// Checks every layer and that each layer's input is the previous one's output.
    pub fn validate(&self) -> Result<(), NnError> {
        if self.layers.is_empty() {
            return Err(NnError::Chain { layer: 0 });
        }
        for (i, layer) in self.layers.iter().enumerate() {
            layer.validate(i)?;
            if i > 0 && self.layers[i - 1].out_dim != layer.in_dim {
                return Err(NnError::Chain { layer: i });
            }
        }
        Ok(())
    }

    /// Runs the chain on `input`, ping-ponging between `a` and `b`; returns the output.
    fn run<'s>(
        &self,
        input: &[u32],
        a: &'s mut [u32],
        b: &'s mut [u32],
        kernel: Kernel,
    ) -> &'s [u32] {
        let mut in_a = false;
        for (i, layer) in self.layers.iter().enumerate() {
            let (src, dst): (&[u32], &mut [u32]) = match (i, in_a) {
                (0, _) => (input, &mut *a),
                (_, true) => (&*a, &mut *b),
                (_, false) => (&*b, &mut *a),
            };
            match kernel {
                Kernel::Native => layer.run(src, dst),
                Kernel::Portable => layer.run_portable(src, dst),
            }
            in_a = i == 0 || !in_a;
        }
        if in_a {
            a
        } else {
            b
        }
    }
}

/// Which inner loop to use.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kernel {
    /// The target's best: SMLALD on Cortex-M DSP cores, portable elsewhere.
    Native,
    /// Portable Rust everywhere (benchmark baseline).
    Portable,
}

/// The three quantized networks and the input quantization (what `hexapod-policy` holds).
#[derive(Clone, Copy, Debug)]
pub struct QuantizedPolicy<'a> {
    /// Power-of-two scale of each flattened history entry (oldest first).
    pub history_scale: &'a [f32],
    /// Power-of-two scale of each actor observation entry.
    pub actor_obs_scale: &'a [f32],
    /// History -> scaled base linear velocity estimate (no layers: the policy has no
    /// estimator, as the paper's "Baseline").
    pub estimator: Mlp<'a>,
    /// History -> memory latent (no layers: a plain actor MLP, e.g. imported from ONNX).
    pub memory: Mlp<'a>,
    /// Actor observation, estimate and latent -> action.
    pub actor: Mlp<'a>,
}

/// Word offsets of the actor input segments: observation, estimate, latent, and the total.
pub const fn actor_input_words(estimate_dim: usize, latent_dim: usize) -> [usize; 4] {
    let obs = words(ACTOR_OBS_DIM);
    let est = words(estimate_dim);
    let lat = words(latent_dim);
    [0, obs, obs + est, obs + est + lat]
}

impl QuantizedPolicy<'_> {
    /// Checks shapes: history in, 18 out, and the actor's first layer reads the packed
    /// observation, estimate and latent segments (its `in_dim` counts their padding).
    pub fn validate(&self) -> Result<(), NnError> {
        if !self.estimator.layers.is_empty() {
            self.estimator.validate()?;
        }
        if !self.memory.layers.is_empty() {
            self.memory.validate()?;
        }
        self.actor.validate()?;
        let inputs_ok = self.history_scale.len() == HISTORY_DIM
            && self.actor_obs_scale.len() == ACTOR_OBS_DIM
            && (self.estimator.layers.is_empty() || self.estimator.in_dim() == HISTORY_DIM)
            && (self.memory.layers.is_empty() || self.memory.in_dim() == HISTORY_DIM)
            && self.actor.in_dim()
                == 2 * actor_input_words(self.estimator.out_dim(), self.memory.out_dim())[3]
            && self.actor.out_dim() == NUM_JOINTS;
        if inputs_ok {
            Ok(())
        } else {
            Err(NnError::Chain { layer: 0 })
        }
    }

    /// Multiply-accumulates of one policy step.
    pub fn macs(&self) -> usize {
        self.estimator.macs() + self.memory.macs() + self.actor.macs()
    }

    /// Scratch words needed (one buffer).
    pub fn scratch_words(&self) -> usize {
        let [.., actor_in] = actor_input_words(self.estimator.out_dim(), self.memory.out_dim());
        let nets = [self.estimator, self.memory, self.actor];
        let widest = nets.iter().map(Mlp::max_out_words).max().unwrap_or(0);
        widest.max(actor_in).max(words(HISTORY_DIM))
    }

    /// One policy step from the command (vx, vy, wz, unscaled), the previous action and
    /// the history whose newest frame is the current o^p.
    pub fn step<const W: usize>(
        &self,
        scratch: &mut Scratch<W>,
        command: [f32; 3],
        prev_action: &[f32; NUM_JOINTS],
        history: &ProprioHistory,
        kernel: Kernel,
    ) -> Result<PolicyOutput, NnError> {
        let obs = actor_obs(command, prev_action, history.newest());
        self.step_obs(scratch, &obs, &history.flatten(), kernel)
    }

    /// One policy step from the actor observation (as [`crate::obs::actor_obs`] builds it)
    /// and the flattened history (oldest first): the simulator's observation buffers.
    pub fn step_obs<const W: usize>(
        &self,
        scratch: &mut Scratch<W>,
        actor_obs: &[f32; ACTOR_OBS_DIM],
        history: &[f32; HISTORY_DIM],
        kernel: Kernel,
    ) -> Result<PolicyOutput, NnError> {
        if self.scratch_words() > W {
            return Err(NnError::ScratchTooSmall);
        }
        if !actor_obs.iter().chain(history).all(|x| x.is_finite()) {
            return Err(NnError::NonFiniteInput);
        }
        let Scratch {
            hist,
            actor_in,
            a,
            b,
        } = scratch;
        quantize_packed(history, self.history_scale, &mut hist[..words(HISTORY_DIM)]);
        let [obs_w, est_w, lat_w, end_w] =
            actor_input_words(self.estimator.out_dim(), self.memory.out_dim());
        quantize_packed(actor_obs, self.actor_obs_scale, &mut actor_in[obs_w..est_w]);

        if !self.estimator.layers.is_empty() {
            let estimate = self.estimator.run(hist, a, b, kernel);
            actor_in[est_w..lat_w].copy_from_slice(&estimate[..lat_w - est_w]);
        }
        if !self.memory.layers.is_empty() {
            let latent = self.memory.run(hist, a, b, kernel);
            actor_in[lat_w..end_w].copy_from_slice(&latent[..end_w - lat_w]);
        }
        let out = self.actor.run(actor_in, a, b, kernel);

        let mut result = PolicyOutput {
            action_q: [0; NUM_JOINTS],
            action: [0.0; NUM_JOINTS],
            q_target_rad: Q0_RAD,
        };
        let joints = result
            .action_q
            .iter_mut()
            .zip(&mut result.action)
            .zip(&mut result.q_target_rad);
        for (j, ((raw, action), target)) in joints.enumerate() {
            *raw = unpack(out, j);
            let lsb = pow2(-(self.actor.out_frac_bits(j) as i32));
            *action = (*raw as f32 * lsb).clamp(-ACTION_CLIP, ACTION_CLIP);
            // `target` starts at q0.
            *target += ACTION_SCALE_RAD * *action;
        }
        Ok(result)
    }
}

/// Working memory of a policy step: `W` words per buffer (see
/// [`QuantizedPolicy::scratch_words`]).
#[derive(Clone, Debug)]
pub struct Scratch<const W: usize> {
    hist: [u32; W],
    actor_in: [u32; W],
    a: [u32; W],
    b: [u32; W],
}

impl<const W: usize> Scratch<W> {
    /// Zeroed buffers (`const`, so a scratch can be a `static`).
    pub const fn new() -> Self {
        Self {
            hist: [0; W],
            actor_in: [0; W],
            a: [0; W],
            b: [0; W],
        }
    }
}

impl<const W: usize> Default for Scratch<W> {
    fn default() -> Self {
        Self::new()
    }
}

/// What a policy step produces.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PolicyOutput {
    /// The network's raw output (channel `j` in Q`frac_bits` of the actor's last
    /// layer), for bit-exact comparisons.
    pub action_q: [i16; NUM_JOINTS],
    /// The action, clipped to `+-ACTION_CLIP`.
    pub action: [f32; NUM_JOINTS],
    /// Joint position targets `q0 + ACTION_SCALE_RAD * action`.
    pub q_target_rad: [f32; NUM_JOINTS],
}

/// The policy as the firmware runs it: keeps the history and the previous action.
#[derive(Clone, Debug)]
pub struct PolicyRunner<'p, const W: usize> {
    policy: &'p QuantizedPolicy<'p>,
    history: Option<ProprioHistory>,
    prev_action: [f32; NUM_JOINTS],
    scratch: Scratch<W>,
}

impl<'p, const W: usize> PolicyRunner<'p, W> {
    /// Validates `policy` and checks that `W` words of scratch suffice.
    pub fn new(policy: &'p QuantizedPolicy<'p>) -> Result<Self, NnError> {
        policy.validate()?;
        if policy.scratch_words() > W {
            return Err(NnError::ScratchTooSmall);
        }
        Ok(Self {
            policy,
            history: None,
            prev_action: [0.0; NUM_JOINTS],
            scratch: Scratch::default(),
        })
    }

    /// Forgets the history and the previous action (as after a reset in simulation).
    pub fn reset(&mut self) {
        self.history = None;
        self.prev_action = [0.0; NUM_JOINTS];
    }

    /// One control step with the current o^p (from [`crate::obs::proprio_obs`]). After a
    /// reset the history is filled with `proprio`.
    pub fn step(
        &mut self,
        command: [f32; 3],
        proprio: &[f32; PROPRIO_DIM],
    ) -> Result<PolicyOutput, NnError> {
        let history = match &mut self.history {
            Some(h) => {
                h.push(proprio);
                h
            }
            none => none.insert(ProprioHistory::filled_with(proprio)),
        };
        let out = self.policy.step(
            &mut self.scratch,
            command,
            &self.prev_action,
            history,
            Kernel::Native,
        )?;
        self.prev_action = out.action;
        Ok(out)
    }
}
