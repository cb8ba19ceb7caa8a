//! Friction on the hardest climbs: the terrain test's 30 deg ramp and 20 cm stairs walked by
//! the same robots at fixed friction coefficients of their contacts with the ground, one value
//! at a time (each robot's foot friction is the one that gives it under the checkpoint's
//! combine rule).
//!
//! The terrain test draws each robot's friction from [`super::batch::SUITE_FRICTION`], so on
//! the steep ramp a row's score mixes the policy with the draw. Here trial k is the same robot
//! (stiffness, masses, payload, motors: the draw of suite seed and trial) at every friction
//! value; only the friction changes. A robot needs at least tan 30 deg = 0.577 to stand on the
//! 30 deg ramp at all (the friction force along the ramp must carry the weight's share along
//! it), so the sweep shows how close to that bound a policy climbs.

use super::batch::Conditions;
use super::controller::SuiteController;
use super::terrain::{run_on_own_course, FeatureResult};
use crate::config::TrainConfig;
use host_sim::course::Feature;
use serde::Serialize;

/// Contact friction coefficients tried.
pub const FRICTION_SWEEP: [f32; 8] = [0.6, 0.7, 0.8, 0.9, 1.0, 1.2, 1.6, 2.0];
/// The quick variant's coefficients.
pub const QUICK_FRICTION_SWEEP: [f32; 2] = [0.6, 1.2];
/// Ramp of the sweep, deg (the paper's steepest).
pub const SWEEP_SLOPE_DEG: f32 = 30.0;
/// Stair riser of the sweep, m (the paper's tallest).
pub const SWEEP_STEP_M: f32 = 0.20;

/// The features walked at every friction value, in report order.
pub fn features() -> Vec<Feature> {
    vec![
        Feature::SlopeUp {
            slope_deg: SWEEP_SLOPE_DEG,
        },
        Feature::StairsUp {
            step_height_m: SWEEP_STEP_M,
        },
    ]
}

/// The least friction coefficient on which a body stands on a ramp of `slope_deg` (tan of
/// the slope).
pub fn least_friction_to_stand(slope_deg: f32) -> f32 {
    slope_deg.to_radians().tan()
}

/// The features' results at one friction coefficient.
#[derive(Clone, Debug, Serialize)]
pub struct FrictionPoint {
    /// Friction coefficient of every robot's contacts with the ground.
    pub contact_friction: f32,
    /// One result per feature of [`features`].
    pub features: Vec<FeatureResult>,
}

/// The friction values of the variant.
pub fn sweep(quick: bool) -> &'static [f32] {
    if quick {
        &QUICK_FRICTION_SWEEP
    } else {
        &FRICTION_SWEEP
    }
}

/// Runs the sweep: for each friction value, `c.trials` robots per feature on a course of the
/// sweep's own, with the terrain test's command, duration and success rule.
pub fn run(
    cfg: &TrainConfig,
    controller: &mut dyn SuiteController,
    c: &Conditions,
) -> anyhow::Result<Vec<FrictionPoint>> {
    let features = features();
    sweep(c.quick)
        .iter()
        .map(|&mu| {
            let at = c.at_contact_friction(mu)?;
            Ok(FrictionPoint {
                contact_friction: mu,
                features: run_on_own_course(cfg, controller, &at, &features)?,
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The sweep starts above the least friction to stand on its ramp and spans the suite's
    /// range, in increasing order.
    #[test]
    fn the_sweep_is_ordered_and_starts_where_standing_is_possible() {
        for quick in [false, true] {
            let s = sweep(quick);
            assert!(s.windows(2).all(|w| w[0] < w[1]));
            assert!(s[0] > least_friction_to_stand(SWEEP_SLOPE_DEG));
            assert!(s[0] <= super::super::batch::SUITE_FRICTION[0]);
            assert!(*s.last().unwrap() >= super::super::batch::SUITE_FRICTION[1]);
        }
        assert!((least_friction_to_stand(30.0) - 0.5774).abs() < 1e-4);
    }
}
