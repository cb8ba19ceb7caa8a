//! The f32 policy as the trainer runs it: normalization, estimator, memory, actor.

use crate::checkpoint::{MlpF32, Normalizer, PolicyF32};
use hexapod_core::nn::reference::{dense_f32, elu_f32};
use hexapod_core::nn::Activation;
use hexapod_core::obs::{ACTION_CLIP, ACTOR_OBS_DIM, HISTORY_DIM};
use hexapod_core::NUM_JOINTS;

impl MlpF32 {
    /// Outputs of every layer (after ELU for hidden layers, linear for the last).
    pub fn trace(&self, x: &[f32]) -> Vec<Vec<f32>> {
        let mut outs: Vec<Vec<f32>> = Vec::with_capacity(self.layers.len());
        for (k, layer) in self.layers.iter().enumerate() {
            let input = if k == 0 { x } else { &outs[k - 1] };
            let mut y = vec![0.0; layer.out_dim];
            dense_f32(&layer.weight, &layer.bias, input, &mut y);
            if k + 1 < self.layers.len() {
                match self.hidden {
                    Activation::Relu => y.iter_mut().for_each(|v| *v = v.max(0.0)),
                    Activation::Elu => y.iter_mut().for_each(|v| *v = elu_f32(*v)),
                    Activation::Linear => {}
                }
            }
            outs.push(y);
        }
        outs
    }

    /// The network's output.
    pub fn forward(&self, x: &[f32]) -> Vec<f32> {
        self.trace(x).pop().unwrap_or_default()
    }
}

impl Normalizer {
    /// `(x - mean) / std`.
    pub fn apply(&self, x: &[f32]) -> Vec<f32> {
        x.iter()
            .zip(&self.mean)
            .zip(&self.std)
            .map(|((x, m), s)| (x - m) / s)
            .collect()
    }
}

/// Every layer output of one f32 policy step.
pub struct PolicyTrace {
    /// Estimator layer outputs (empty without an estimator).
    pub estimator: Vec<Vec<f32>>,
    /// Memory layer outputs.
    pub memory: Vec<Vec<f32>>,
    /// Actor layer outputs; the last is the action mean (before clipping).
    pub actor: Vec<Vec<f32>>,
}

impl PolicyF32 {
    /// One step with every intermediate output.
    pub fn trace(
        &self,
        actor_obs: &[f32; ACTOR_OBS_DIM],
        history: &[f32; HISTORY_DIM],
    ) -> PolicyTrace {
        let h = self.history_norm.apply(history);
        let estimator = self.estimator.trace(&h);
        let memory = self.memory.trace(&h);
        let mut input = self.actor_obs_norm.apply(actor_obs);
        if let Some(v) = estimator.last() {
            input.extend_from_slice(v);
        }
        input.extend_from_slice(memory.last().map_or(&[][..], |v| v));
        let actor = self.actor.trace(&input);
        PolicyTrace {
            estimator,
            memory,
            actor,
        }
    }

    /// The action (clipped to `+-ACTION_CLIP`).
    pub fn act(
        &self,
        actor_obs: &[f32; ACTOR_OBS_DIM],
        history: &[f32; HISTORY_DIM],
    ) -> [f32; NUM_JOINTS] {
        let trace = self.trace(actor_obs, history);
        let mut a = [0.0; NUM_JOINTS];
        if let Some(out) = trace.actor.last() {
            for (a, &y) in a.iter_mut().zip(out) {
                *a = y.clamp(-ACTION_CLIP, ACTION_CLIP);
            }
        }
        a
    }
}
