//! What the trained discriminator thinks of a policy's gait at one command, from the AMP
//! transitions `hexapod eval` recorded there: the mean output `d` and style reward, and
//! the style reward the same transitions would earn had the robot moved faster or slower
//! along the command with everything else unchanged (the base velocity of both states
//! shifted by an offset). The offset where that reward peaks is the speed the
//! discriminator associates with this gait: a peak at a positive offset means the style
//! term pays for walking faster than the robot does with these strides, a peak at zero
//! that the style term does not pull the speed either way.

use crate::amp::discriminator::Discriminator;
use hexapod_core::amp::{AMP_BASE_ANG_VEL, AMP_BASE_LIN_VEL, AMP_STATE_DIM};
use serde::Serialize;

/// Offsets probed, in units of the command's axis (m/s along a linear command, rad/s for a
/// pure turn): -0.15 to +0.15 in steps of 0.025.
pub fn probe_offsets() -> Vec<f32> {
    (-6..=6).map(|k| k as f32 * 0.025).collect()
}

/// The least gain in mean style reward (of its maximum 1) that counts as the
/// discriminator preferring a shifted speed.
pub const PREFERENCE_MIN_STYLE: f64 = 0.005;

/// The discriminator's verdict on a command's transitions.
#[derive(Debug, Clone, Serialize)]
pub struct StyleProbe {
    /// Transitions probed.
    pub transitions: usize,
    /// Mean discriminator output on them as recorded.
    pub mean_d: f64,
    /// Mean style reward `max(0, 1 - 0.25 (d - 1)^2)` as recorded.
    pub mean_style_reward: f64,
    /// Axis the offsets shift: `linear` (base velocity along the command, m/s) or `yaw`
    /// (yaw rate, rad/s, for a pure turn).
    pub axis: &'static str,
    /// Offsets probed ([`probe_offsets`]).
    pub offsets: Vec<f32>,
    /// Mean style reward with the base velocity of both states shifted by each offset.
    pub style_reward_by_offset: Vec<f64>,
    /// The offset of the highest mean style reward, or 0 where no offset earns at least
    /// [`PREFERENCE_MIN_STYLE`] more than the gait as recorded (a flat verdict).
    pub preferred_offset: f32,
}

/// Probes `states`/`next_states` (flat `[n, 61]`) recorded at `command`; `None` for a zero
/// command (no axis to shift along) or no transitions.
pub fn probe(
    disc: &Discriminator,
    command: [f32; 3],
    states: &[f32],
    next_states: &[f32],
) -> anyhow::Result<Option<StyleProbe>> {
    let n = states.len() / AMP_STATE_DIM;
    let speed = command[0].hypot(command[1]);
    let (axis, shift): (&'static str, Vec<(usize, f32)>) = if speed > 1e-6 {
        (
            "linear",
            vec![
                (AMP_BASE_LIN_VEL.start, command[0] / speed),
                (AMP_BASE_LIN_VEL.start + 1, command[1] / speed),
            ],
        )
    } else if command[2].abs() > 1e-6 {
        (
            "yaw",
            vec![(AMP_BASE_ANG_VEL.start + 2, command[2].signum())],
        )
    } else {
        return Ok(None);
    };
    if n == 0 {
        return Ok(None);
    }
    let mean = |v: &[f32]| v.iter().map(|&x| x as f64).sum::<f64>() / v.len() as f64;
    let (rewards, d) = disc.style_reward(states, next_states)?;
    let offsets = probe_offsets();
    let mut style_reward_by_offset = Vec::with_capacity(offsets.len());
    for &offset in &offsets {
        let shifted = |buffer: &[f32]| {
            let mut out = buffer.to_vec();
            for row in out.chunks_exact_mut(AMP_STATE_DIM) {
                for &(index, weight) in &shift {
                    row[index] += offset * weight;
                }
            }
            out
        };
        let (rewards_shifted, _) = disc.style_reward(&shifted(states), &shifted(next_states))?;
        style_reward_by_offset.push(mean(&rewards_shifted));
    }
    let recorded = mean(&rewards);
    let best = style_reward_by_offset
        .iter()
        .enumerate()
        .max_by(|a, b| a.1.total_cmp(b.1))
        .filter(|(_, &r)| r >= recorded + PREFERENCE_MIN_STYLE)
        .map(|(k, _)| offsets[k])
        .unwrap_or(0.0);
    Ok(Some(StyleProbe {
        transitions: n,
        mean_d: mean(&d),
        mean_style_reward: recorded,
        axis,
        preferred_offset: best,
        offsets,
        style_reward_by_offset,
    }))
}

/// One line for the eval's printout.
pub fn describe(command: [f32; 3], p: &StyleProbe) -> String {
    let unit = if p.axis == "yaw" { "rad/s" } else { "m/s" };
    let at = |offset: f32| {
        p.offsets
            .iter()
            .position(|&o| (o - offset).abs() < 1e-6)
            .map_or(f64::NAN, |k| p.style_reward_by_offset[k])
    };
    format!(
        "style at ({:.2},{:.2},{:.2}): d {:+.2}, reward {:.2}; with the speed shifted along the command by -0.05 / +0.05 {unit}: {:.2} / {:.2}; preferred shift {:+.3} {unit} ({:.2})",
        command[0],
        command[1],
        command[2],
        p.mean_d,
        p.mean_style_reward,
        at(-0.05),
        at(0.05),
        p.preferred_offset,
        at(p.preferred_offset),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::amp::discriminator::DISC_IN;
    use candle_core::{DType, Device, Tensor};
    use candle_nn::VarMap;

    /// A linear discriminator `d = slope * vx(s_t) + bias` and transitions walking at 0.3 m/s.
    fn probed(slope: f32, bias: f32, command: [f32; 3]) -> Option<StyleProbe> {
        let dev = Device::Cpu;
        let (mut params, stats) = (VarMap::new(), VarMap::new());
        let disc = Discriminator::new(&[], &params, &stats, 1, DType::F32, &dev).unwrap();
        let mut w = vec![0.0f32; DISC_IN];
        w[AMP_BASE_LIN_VEL.start] = slope;
        params
            .set_one(
                "discriminator.layers.0.weight",
                Tensor::from_vec(w, (1, DISC_IN), &dev).unwrap(),
            )
            .unwrap();
        params
            .set_one(
                "discriminator.layers.0.bias",
                Tensor::from_vec(vec![bias], 1, &dev).unwrap(),
            )
            .unwrap();
        let mut state = vec![0.0f32; 4 * AMP_STATE_DIM];
        for row in state.chunks_exact_mut(AMP_STATE_DIM) {
            row[AMP_BASE_LIN_VEL.start] = 0.3;
        }
        probe(&disc, command, &state, &state).unwrap()
    }

    #[test]
    fn the_probe_finds_the_speed_the_discriminator_pays_for() {
        let faster = probed(2.0, -1.0, [0.3, 0.0, 0.0]).unwrap();
        assert!((faster.mean_d - -0.4).abs() < 1e-5, "{faster:?}");
        assert_eq!(faster.preferred_offset, 0.15);
        assert_eq!(
            probed(-2.0, 0.5, [0.3, 0.0, 0.0]).unwrap().preferred_offset,
            -0.15
        );
        // Commanded backwards, a higher forward velocity is a negative shift.
        assert_eq!(
            probed(2.0, -1.0, [-0.3, 0.0, 0.0])
                .unwrap()
                .preferred_offset,
            -0.15
        );
        // A discriminator blind to velocity, or sure it is fake at every shift (style 0
        // throughout), has no preference, not the grid's last offset.
        assert_eq!(
            probed(0.0, -1.0, [0.3, 0.0, 0.0]).unwrap().preferred_offset,
            0.0
        );
        assert_eq!(
            probed(-2.0, -1.0, [0.3, 0.0, 0.0])
                .unwrap()
                .preferred_offset,
            0.0
        );
        // Sideways commands shift vy, which this discriminator does not see.
        assert_eq!(
            probed(2.0, -1.0, [0.0, 0.3, 0.0]).unwrap().preferred_offset,
            0.0
        );
        assert!(probed(2.0, -1.0, [0.0, 0.0, 0.0]).is_none());
    }
}
