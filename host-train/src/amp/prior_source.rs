//! Where prior (expert) AMP transitions come from: the motion-prior dataset, or a synthetic
//! tripod oscillation for tests and smoke runs.

use crate::priors::dataset::MotionDataset;
use hexapod_core::amp::{amp_state, AMP_STATE_DIM};
use hexapod_core::robot::{Leg, NUM_JOINTS, Q0_RAD};
use hexapod_core::timing::POLICY_DT_S;
use host_sim::reference::ReferenceStart;
use rand::{Rng, RngCore};

/// A source of prior transitions.
pub trait MotionPriorSource {
    /// `n` transitions (`s_t` `[n, 61]`, `s_t+1` `[n, 61]`), one policy step apart.
    fn sample(&mut self, n: usize, rng: &mut dyn RngCore) -> (Vec<f32>, Vec<f32>);
    /// States episodes may start from (reference state initialization), each with its
    /// motion's command; none by default.
    fn reference_states(&self) -> Vec<ReferenceStart> {
        Vec::new()
    }
}

/// An idealized tripod gait: the two tripods swing in antiphase at a fixed frequency while
/// the base moves forward. Not a physically optimized motion: only for tests and smoke runs.
pub struct SyntheticTripod {
    /// Stride frequency, Hz.
    pub frequency_hz: f32,
    /// Forward speed, m/s.
    pub speed_m_s: f32,
}

impl Default for SyntheticTripod {
    fn default() -> Self {
        Self {
            frequency_hz: 1.5,
            speed_m_s: 0.3,
        }
    }
}

impl SyntheticTripod {
    /// The AMP state at gait phase `phase_rad`.
    pub fn state(&self, phase_rad: f32) -> [f32; AMP_STATE_DIM] {
        let omega = 2.0 * std::f32::consts::PI * self.frequency_hz;
        let mut q = Q0_RAD;
        let mut qd = [0.0f32; NUM_JOINTS];
        for leg in Leg::ALL {
            let offset = if leg.tripod() == hexapod_core::robot::Tripod::A {
                0.0
            } else {
                std::f32::consts::PI
            };
            let p = phase_rad + offset;
            let j = 3 * leg.index();
            // Hip sweeps, thigh lifts during the half period the hip swings forward.
            q[j] += 0.2 * p.sin();
            qd[j] = 0.2 * omega * p.cos();
            let lift = (-p.cos()).max(0.0);
            q[j + 1] -= 0.3 * lift;
            qd[j + 1] = if lift > 0.0 {
                -0.3 * omega * p.sin()
            } else {
                0.0
            };
        }
        amp_state(
            &q,
            &qd,
            [self.speed_m_s, 0.0, 0.0],
            [0.0; 3],
            [0.0, 0.0, 1.0],
        )
    }
}

impl MotionPriorSource for SyntheticTripod {
    fn sample(&mut self, n: usize, rng: &mut dyn RngCore) -> (Vec<f32>, Vec<f32>) {
        let dphase = 2.0 * std::f32::consts::PI * self.frequency_hz * POLICY_DT_S;
        let mut s = Vec::with_capacity(n * AMP_STATE_DIM);
        let mut sn = Vec::with_capacity(n * AMP_STATE_DIM);
        for _ in 0..n {
            let phase = rng.gen_range(0.0..2.0 * std::f32::consts::PI);
            s.extend_from_slice(&self.state(phase));
            sn.extend_from_slice(&self.state(phase + dphase));
        }
        (s, sn)
    }
}

/// Why the motion priors are missing or malformed.
#[derive(Debug, thiserror::Error)]
#[error("motion priors: {0}")]
pub struct PriorSourceError(pub String);

/// The prior source a config asks for: for the style reward, or for episodes started from
/// reference states (`sim.reference_init_probability` above 0, which then holds without the
/// style reward too); `None` when neither is on. Dataset priors must cover the configured
/// command range ([`MotionDataset::check_command_coverage`]).
pub fn load_prior_source(
    cfg: &crate::config::TrainConfig,
) -> Result<Option<Box<dyn MotionPriorSource>>, PriorSourceError> {
    use crate::config::PriorKind;
    if !cfg.amp_enabled() && cfg.sim.reference_init_probability <= 0.0 {
        return Ok(None);
    }
    match cfg.amp.prior_kind {
        PriorKind::Synthetic => Ok(Some(Box::new(SyntheticTripod::default()))),
        PriorKind::Dataset => {
            let dir = crate::config::resolve_path(&cfg.amp.priors_dir);
            let sim = cfg.resolved_sim();
            let dataset =
                MotionDataset::load(&dir, cfg.amp.prior_states, sim.friction_in_bias_pass)
                    .map_err(|e| {
                        PriorSourceError(format!(
                            "{e} (generate the clips with `hexapod priors`, or set amp.priors_dir)"
                        ))
                    })?;
            let c = &sim.commands;
            dataset
                .check_command_coverage(
                    [c.lin_vel_x_m_s, c.lin_vel_y_m_s, c.ang_vel_z_rad_s],
                    c.zero_probability,
                )
                .map_err(|e| PriorSourceError(e.to_string()))?;
            Ok(Some(Box::new(dataset)))
        }
    }
}

impl MotionPriorSource for MotionDataset {
    fn sample(&mut self, n: usize, rng: &mut dyn RngCore) -> (Vec<f32>, Vec<f32>) {
        let mut s = Vec::with_capacity(n * AMP_STATE_DIM);
        let mut sn = Vec::with_capacity(n * AMP_STATE_DIM);
        for (a, b) in self.sample_transitions(rng, n) {
            s.extend_from_slice(&a);
            sn.extend_from_slice(&b);
        }
        (s, sn)
    }

    fn reference_states(&self) -> Vec<ReferenceStart> {
        MotionDataset::reference_states(self)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::{PriorKind, TrainConfig};
    use rand::SeedableRng;

    #[test]
    fn shipped_dataset_loads_and_samples_consecutive_frames() {
        let mut cfg = TrainConfig::default();
        cfg.amp.prior_kind = PriorKind::Dataset;
        cfg.amp.priors_dir = concat!(env!("CARGO_MANIFEST_DIR"), "/../assets/priors").into();
        let mut src = load_prior_source(&cfg).unwrap().unwrap();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(0);
        let (s, sn) = src.sample(32, &mut rng);
        assert_eq!(
            (s.len(), sn.len()),
            (32 * AMP_STATE_DIM, 32 * AMP_STATE_DIM)
        );
        // Consecutive frames: joint angles move by little (< 0.3 rad in 20 ms).
        for (a, b) in s
            .chunks_exact(AMP_STATE_DIM)
            .zip(sn.chunks_exact(AMP_STATE_DIM))
        {
            assert!(a[..18]
                .iter()
                .zip(&b[..18])
                .all(|(x, y)| (x - y).abs() < 0.3));
        }
    }

    #[test]
    fn missing_priors_are_a_clear_error() {
        let mut cfg = TrainConfig::default();
        cfg.amp.prior_kind = PriorKind::Dataset;
        cfg.amp.priors_dir = "no/such/dir".into();
        let err = load_prior_source(&cfg)
            .err()
            .expect("must fail")
            .to_string();
        assert!(
            err.contains("no/such/dir") && err.contains("hexapod priors"),
            "{err}"
        );
        cfg.rewards.style = false;
        assert!(
            load_prior_source(&cfg).unwrap().is_none(),
            "no priors needed without style reward"
        );
    }

    /// Reference-state starts need the priors with the style reward off too: a config
    /// that asks for them gets them rather than silently none.
    #[test]
    fn reference_starts_load_the_priors_without_the_style_reward() {
        let mut cfg = TrainConfig::default();
        cfg.amp.prior_kind = PriorKind::Dataset;
        cfg.amp.priors_dir = concat!(env!("CARGO_MANIFEST_DIR"), "/../assets/priors").into();
        cfg.rewards.style = false;
        cfg.sim.reference_init_probability = 0.85;
        let src = load_prior_source(&cfg)
            .unwrap()
            .expect("priors for the starts");
        assert!(!src.reference_states().is_empty());
    }
}
