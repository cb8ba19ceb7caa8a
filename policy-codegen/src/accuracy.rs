//! Fixed-point vs f32 actions over a set of observations.

use crate::checkpoint::PolicyF32;
use crate::quantize::OwnedPolicy;
use crate::records::ObsRecord;
use hexapod_core::nn::{Kernel, NnError, Scratch};

/// Scratch large enough for any policy this crate generates (hidden sizes up to 2048).
pub type HostScratch = Scratch<1024>;

/// How closely the fixed-point policy follows the f32 one.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AccuracyReport {
    /// Observations compared.
    pub count: usize,
    /// Largest `|a_fixed - a_f32|` over all observations and joints.
    pub max_abs_diff: f32,
    /// Mean `|a_fixed - a_f32|`.
    pub mean_abs_diff: f32,
    /// Largest `|a_f32|` (for scale).
    pub max_abs_action: f32,
}

/// Compares the two policies on `records`.
pub fn compare(
    f32_policy: &PolicyF32,
    fixed: &OwnedPolicy,
    records: &[ObsRecord],
) -> Result<AccuracyReport, NnError> {
    fixed.with_view(|q| {
        q.validate()?;
        let mut scratch = Box::new(HostScratch::default());
        let (mut max, mut sum, mut amax) = (0.0f32, 0.0f64, 0.0f32);
        for r in records {
            let want = f32_policy.act(&r.actor_obs, &r.history);
            let got = q.step_obs(&mut scratch, &r.actor_obs, &r.history, Kernel::Native)?;
            for (a, b) in got.action.iter().zip(&want) {
                let d = (a - b).abs();
                max = max.max(d);
                sum += d as f64;
                amax = amax.max(b.abs());
            }
        }
        let n = records.len().max(1) * want_len();
        Ok(AccuracyReport {
            count: records.len(),
            max_abs_diff: max,
            mean_abs_diff: (sum / n as f64) as f32,
            max_abs_action: amax,
        })
    })
}

fn want_len() -> usize {
    hexapod_core::NUM_JOINTS
}
