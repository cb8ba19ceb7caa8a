//! A ring buffer of policy AMP transitions `(s_t, s_t+1)`, sampled uniformly for the
//! discriminator (AMP_for_hardware's `ReplayBuffer`).

use hexapod_core::amp::AMP_STATE_DIM;
use rand::{Rng, RngCore};

/// Fixed-capacity ring buffer of AMP transitions.
pub struct TransitionBuffer {
    capacity: usize,
    len: usize,
    next: usize,
    states: Vec<f32>,
    next_states: Vec<f32>,
}

impl TransitionBuffer {
    /// An empty buffer for `capacity` transitions (allocated once).
    pub fn new(capacity: usize) -> Self {
        Self {
            capacity,
            len: 0,
            next: 0,
            states: vec![0.0; capacity * AMP_STATE_DIM],
            next_states: vec![0.0; capacity * AMP_STATE_DIM],
        }
    }

    /// Number of transitions held.
    pub fn len(&self) -> usize {
        self.len
    }

    /// True when empty.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Appends transitions (`[n, 61]` each), overwriting the oldest when full.
    pub fn insert(&mut self, states: &[f32], next_states: &[f32]) {
        assert_eq!(states.len(), next_states.len());
        for (s, sn) in states
            .chunks_exact(AMP_STATE_DIM)
            .zip(next_states.chunks_exact(AMP_STATE_DIM))
        {
            let at = self.next * AMP_STATE_DIM;
            self.states[at..at + AMP_STATE_DIM].copy_from_slice(s);
            self.next_states[at..at + AMP_STATE_DIM].copy_from_slice(sn);
            self.next = (self.next + 1) % self.capacity;
            self.len = (self.len + 1).min(self.capacity);
        }
    }

    /// `n` transitions drawn uniformly with replacement: (`[n, 61]`, `[n, 61]`).
    /// Panics when empty (the runner fills the buffer before the first update).
    pub fn sample(&self, n: usize, rng: &mut dyn RngCore) -> (Vec<f32>, Vec<f32>) {
        assert!(!self.is_empty(), "sampling an empty replay buffer");
        let mut s = Vec::with_capacity(n * AMP_STATE_DIM);
        let mut sn = Vec::with_capacity(n * AMP_STATE_DIM);
        for _ in 0..n {
            let i = rng.gen_range(0..self.len) * AMP_STATE_DIM;
            s.extend_from_slice(&self.states[i..i + AMP_STATE_DIM]);
            sn.extend_from_slice(&self.next_states[i..i + AMP_STATE_DIM]);
        }
        (s, sn)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    fn rows(values: &[f32]) -> Vec<f32> {
        values.iter().flat_map(|&v| [v; AMP_STATE_DIM]).collect()
    }

    #[test]
    fn keeps_the_newest_and_samples_only_stored_pairs() {
        let mut buf = TransitionBuffer::new(3);
        buf.insert(&rows(&[1.0, 2.0]), &rows(&[11.0, 12.0]));
        assert_eq!(buf.len(), 2);
        buf.insert(&rows(&[3.0, 4.0]), &rows(&[13.0, 14.0]));
        assert_eq!(buf.len(), 3);
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(0);
        let (s, sn) = buf.sample(200, &mut rng);
        let mut seen = std::collections::BTreeSet::new();
        for (a, b) in s
            .chunks_exact(AMP_STATE_DIM)
            .zip(sn.chunks_exact(AMP_STATE_DIM))
        {
            assert!(a.iter().all(|&x| x == a[0]));
            assert_eq!(b[0], a[0] + 10.0, "pairs stay together");
            seen.insert(a[0] as i32);
        }
        // 1.0 was overwritten by 4.0.
        assert_eq!(seen.into_iter().collect::<Vec<_>>(), vec![2, 3, 4]);
    }
}
