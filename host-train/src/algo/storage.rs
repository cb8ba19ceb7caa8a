//! Rollout storage (rsl_rl's `RolloutStorage`): one iteration's transitions, laid out
//! `[T, N, dim]` row-major, with generalized advantage estimation and shuffled minibatches.

use hexapod_core::nets::ACTOR_OUT;
use hexapod_core::obs::{ACTOR_OBS_DIM, HEIGHT_SCAN_DIM, HISTORY_DIM, PRIVILEGED_DIM};
use rand::seq::SliceRandom;
use rand::Rng;

/// One policy step of all robots.
pub struct Transition<'a> {
    /// `[N, 63]`.
    pub actor_obs: &'a [f32],
    /// `[N, 210]`.
    pub history: &'a [f32],
    /// `[N, 42]`.
    pub privileged: &'a [f32],
    /// `[N, 187]`.
    pub heights: &'a [f32],
    /// Sampled actions `[N, 18]`.
    pub actions: &'a [f32],
    /// Action means `[N, 18]`.
    pub action_mean: &'a [f32],
    /// Total rewards `[N]` (time-out bootstrap included).
    pub rewards: &'a [f32],
    /// Episode ended `[N]`.
    pub dones: &'a [bool],
    /// Values `[N]`.
    pub values: &'a [f32],
    /// Log-probabilities of the actions `[N]`.
    pub log_probs: &'a [f32],
}

/// All transitions of one iteration.
pub struct RolloutStorage {
    /// Robots.
    pub num_envs: usize,
    /// Steps per robot.
    pub num_steps: usize,
    step: usize,
    /// `[T, N, 63]`.
    pub actor_obs: Vec<f32>,
    /// `[T, N, 210]`.
    pub history: Vec<f32>,
    /// `[T, N, 42]`.
    pub privileged: Vec<f32>,
    /// `[T, N, 187]`.
    pub heights: Vec<f32>,
    /// `[T, N, 18]`.
    pub actions: Vec<f32>,
    /// `[T, N, 18]`.
    pub action_mean: Vec<f32>,
    /// `[T, N]`.
    pub rewards: Vec<f32>,
    /// `[T, N]`.
    pub dones: Vec<bool>,
    /// `[T, N]`.
    pub values: Vec<f32>,
    /// `[T, N]`.
    pub log_probs: Vec<f32>,
    /// `[T, N]`, after [`RolloutStorage::compute_returns`].
    pub returns: Vec<f32>,
    /// `[T, N]`, after [`RolloutStorage::compute_returns`].
    pub advantages: Vec<f32>,
}

impl RolloutStorage {
    /// Empty storage for `num_steps` steps of `num_envs` robots.
    pub fn new(num_envs: usize, num_steps: usize) -> Self {
        let n = num_envs * num_steps;
        Self {
            num_envs,
            num_steps,
            step: 0,
            actor_obs: Vec::with_capacity(n * ACTOR_OBS_DIM),
            history: Vec::with_capacity(n * HISTORY_DIM),
            privileged: Vec::with_capacity(n * PRIVILEGED_DIM),
            heights: Vec::with_capacity(n * HEIGHT_SCAN_DIM),
            actions: Vec::with_capacity(n * ACTOR_OUT),
            action_mean: Vec::with_capacity(n * ACTOR_OUT),
            rewards: Vec::with_capacity(n),
            dones: Vec::with_capacity(n),
            values: Vec::with_capacity(n),
            log_probs: Vec::with_capacity(n),
            returns: vec![0.0; n],
            advantages: vec![0.0; n],
        }
    }

    /// Number of transitions held.
    pub fn len(&self) -> usize {
        self.step * self.num_envs
    }

    /// True when no transition is held.
    pub fn is_empty(&self) -> bool {
        self.step == 0
    }

    /// True when all `num_steps` steps are stored.
    pub fn is_full(&self) -> bool {
        self.step == self.num_steps
    }

    /// Appends one step. Panics if full (a runner bug, not a data error).
    pub fn add(&mut self, t: &Transition) {
        assert!(!self.is_full(), "rollout storage overflow");
        self.actor_obs.extend_from_slice(t.actor_obs);
        self.history.extend_from_slice(t.history);
        self.privileged.extend_from_slice(t.privileged);
        self.heights.extend_from_slice(t.heights);
        self.actions.extend_from_slice(t.actions);
        self.action_mean.extend_from_slice(t.action_mean);
        self.rewards.extend_from_slice(t.rewards);
        self.dones.extend_from_slice(t.dones);
        self.values.extend_from_slice(t.values);
        self.log_probs.extend_from_slice(t.log_probs);
        self.step += 1;
    }

    /// Empties the storage for the next iteration (keeps the allocations).
    pub fn clear(&mut self) {
        self.step = 0;
        self.actor_obs.clear();
        self.history.clear();
        self.privileged.clear();
        self.heights.clear();
        self.actions.clear();
        self.action_mean.clear();
        self.rewards.clear();
        self.dones.clear();
        self.values.clear();
        self.log_probs.clear();
    }

    /// Computes advantages and returns by GAE from the values of the observations after the
    /// last step, then normalizes the advantages over the whole rollout.
    pub fn compute_returns(&mut self, last_values: &[f32], gamma: f32, lam: f32) {
        let (adv, ret) = gae(
            &self.rewards,
            &self.values,
            &self.dones,
            last_values,
            self.num_envs,
            gamma,
            lam,
        );
        self.advantages = adv;
        self.returns = ret;
        normalize_in_place(&mut self.advantages);
    }

    /// Shuffled minibatch index sets covering the rollout once.
    pub fn minibatch_indices<R: Rng>(
        &self,
        num_mini_batches: usize,
        rng: &mut R,
    ) -> Vec<Vec<usize>> {
        let mut idx: Vec<usize> = (0..self.len()).collect();
        idx.shuffle(rng);
        let size = self.len() / num_mini_batches;
        idx.chunks_exact(size).map(|c| c.to_vec()).collect()
    }
}

/// Generalized advantage estimation over `[T, N]` buffers.
///
/// `delta_t = r_t + gamma (1 - done_t) V_{t+1} - V_t`,
/// `A_t = delta_t + gamma lambda (1 - done_t) A_{t+1}`, `R_t = A_t + V_t`, where `V_T` is
/// `last_values`. Returns (advantages, returns), not normalized.
pub fn gae(
    rewards: &[f32],
    values: &[f32],
    dones: &[bool],
    last_values: &[f32],
    num_envs: usize,
    gamma: f32,
    lam: f32,
) -> (Vec<f32>, Vec<f32>) {
    let steps = rewards.len() / num_envs;
    let mut adv = vec![0.0f32; rewards.len()];
    let mut ret = vec![0.0f32; rewards.len()];
    for e in 0..num_envs {
        let mut next_adv = 0.0f32;
        let mut next_value = last_values[e];
        for t in (0..steps).rev() {
            let i = t * num_envs + e;
            let not_done = if dones[i] { 0.0 } else { 1.0 };
            let delta = rewards[i] + gamma * not_done * next_value - values[i];
            next_adv = delta + gamma * lam * not_done * next_adv;
            adv[i] = next_adv;
            ret[i] = next_adv + values[i];
            next_value = values[i];
        }
    }
    (adv, ret)
}

/// Shifts and scales to zero mean and unit standard deviation (std + 1e-8).
pub fn normalize_in_place(x: &mut [f32]) {
    if x.is_empty() {
        return;
    }
    let n = x.len() as f64;
    let mean = x.iter().map(|&v| v as f64).sum::<f64>() / n;
    let var = x.iter().map(|&v| (v as f64 - mean).powi(2)).sum::<f64>() / (n - 1.0).max(1.0);
    let std = var.sqrt() + 1e-8;
    for v in x {
        *v = ((*v as f64 - mean) / std) as f32;
    }
}

/// Gathers rows `idx` of a `[_, dim]` buffer.
pub fn gather_rows(src: &[f32], dim: usize, idx: &[usize]) -> Vec<f32> {
    let mut out = Vec::with_capacity(idx.len() * dim);
    for &i in idx {
        out.extend_from_slice(&src[i * dim..(i + 1) * dim]);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    #[test]
    fn gae_matches_a_hand_computed_example() {
        // One robot, 3 steps, done after step 1 (index 1).
        let r = [1.0, 2.0, 3.0];
        let v = [0.5, 1.0, 1.5];
        let d = [false, true, false];
        let (g, l) = (0.9f32, 0.8f32);
        let (adv, ret) = gae(&r, &v, &d, &[2.0], 1, g, l);
        let d2 = 3.0 + g * 2.0 - 1.5; // bootstraps from last value
        let d1 = 2.0 - 1.0; // episode ended: no bootstrap
        let d0 = 1.0 + g * 1.0 - 0.5;
        let a2 = d2;
        let a1 = d1;
        let a0 = d0 + g * l * a1;
        for (got, want) in adv.iter().zip([a0, a1, a2]) {
            assert!((got - want).abs() < 1e-6, "{adv:?}");
        }
        for k in 0..3 {
            assert!((ret[k] - adv[k] - v[k]).abs() < 1e-6);
        }
    }

    #[test]
    fn lambda_one_gives_discounted_returns() {
        // With lambda = 1 and no dones, returns are the discounted sums bootstrapped at the end.
        let n = 2;
        let r = [1.0, -1.0, 1.0, -1.0, 1.0, -1.0];
        let v = [0.3, 0.1, -0.2, 0.4, 0.0, 0.7];
        let d = [false; 6];
        let last = [5.0, -5.0];
        let g = 0.5;
        let (_, ret) = gae(&r, &v, &d, &last, n, g, 1.0);
        for e in 0..n {
            let want0 = r[e] + g * r[n + e] + g * g * r[2 * n + e] + g * g * g * last[e];
            assert!((ret[e] - want0).abs() < 1e-5, "{ret:?}");
        }
    }

    #[test]
    fn minibatches_partition_the_rollout() {
        let mut s = RolloutStorage::new(4, 3);
        for _ in 0..3 {
            s.add(&Transition {
                actor_obs: &[0.0; 4 * ACTOR_OBS_DIM],
                history: &[0.0; 4 * HISTORY_DIM],
                privileged: &[0.0; 4 * PRIVILEGED_DIM],
                heights: &[0.0; 4 * HEIGHT_SCAN_DIM],
                actions: &[0.0; 4 * ACTOR_OUT],
                action_mean: &[0.0; 4 * ACTOR_OUT],
                rewards: &[0.0; 4],
                dones: &[false; 4],
                values: &[0.0; 4],
                log_probs: &[0.0; 4],
            });
        }
        assert!(s.is_full());
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let mut all: Vec<usize> = s.minibatch_indices(3, &mut rng).concat();
        all.sort();
        assert_eq!(all, (0..12).collect::<Vec<_>>());
    }

    #[test]
    fn normalized_advantages_have_zero_mean_unit_std() {
        let mut x = vec![1.0, 2.0, 3.0, 10.0];
        normalize_in_place(&mut x);
        let mean: f32 = x.iter().sum::<f32>() / 4.0;
        let var: f32 = x.iter().map(|v| (v - mean).powi(2)).sum::<f32>() / 3.0;
        assert!(mean.abs() < 1e-6 && (var - 1.0).abs() < 1e-4);
    }
}
