//! Parameters of the model-based controller, settable from a TOML file (`configs/mpc/default.toml`;
//! every key optional, unknown keys refused). Body height, lift height and gait period are the
//! three the paper tuned on its MPC; the defaults come from a short measured tuning on flat
//! ground (ARCHITECTURE.md, "Model-based MPC").

use serde::{Deserialize, Serialize};
use std::path::Path;

/// Parameters of the MPC.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MpcParams {
    /// Base height above the (assumed flat) ground the controller holds, m.
    pub body_height_m: f64,
    /// Swing apex above the ground, m.
    pub lift_height_m: f64,
    /// Tripod gait cycle, s.
    pub gait_period_s: f64,
    /// Share of the cycle a leg swings (at most 0.5: a tripod is always on the ground).
    pub swing_fraction: f64,
    /// Steps of the prediction horizon.
    pub horizon_steps: usize,
    /// Step of the prediction horizon, s.
    pub horizon_dt_s: f64,
    /// Friction coefficient of the cones (conservative against the ground's).
    pub friction_mu: f64,
    /// Upper bound on each foot's normal force, N.
    pub max_normal_force_n: f64,
    /// Raibert feedback: foothold shift per m/s of velocity error, s.
    pub raibert_gain_s: f64,
    /// Stance legs: share of the joint error to the kinematic stance pose the drives see on top
    /// of the force feed-forward (0: pure force control, 1: the drives' full stiffness).
    pub stance_position_gain: f64,
    /// Swing legs aim this far ahead on their trajectory (the drives' lag), s.
    pub swing_lead_s: f64,
    /// Cost weights per state: roll, pitch, yaw, rad^-2.
    pub w_attitude: [f64; 3],
    /// Cost weights: x, y, z position, m^-2.
    pub w_position: [f64; 3],
    /// Cost weights: angular velocity about x, y, z, (rad/s)^-2.
    pub w_angular_velocity: [f64; 3],
    /// Cost weights: linear velocity along x, y, z, (m/s)^-2.
    pub w_linear_velocity: [f64; 3],
    /// Cost weight of the forces, N^-2.
    pub w_force: f64,
}

impl Default for MpcParams {
    fn default() -> Self {
        Self {
            body_height_m: 0.30,
            lift_height_m: 0.08,
            gait_period_s: 0.6,
            swing_fraction: 0.43,
            horizon_steps: 8,
            horizon_dt_s: 0.04,
            friction_mu: 0.5,
            max_normal_force_n: 200.0,
            raibert_gain_s: 0.1,
            stance_position_gain: 0.5,
            swing_lead_s: 0.02,
            w_attitude: [50.0, 50.0, 10.0],
            w_position: [2.0, 2.0, 100.0],
            w_angular_velocity: [0.1, 0.1, 0.5],
            w_linear_velocity: [5.0, 5.0, 1.0],
            w_force: 1e-6,
        }
    }
}

impl MpcParams {
    /// Reads a TOML file; errors are one line and name the file.
    pub fn load(path: &Path) -> anyhow::Result<Self> {
        let text = std::fs::read_to_string(path)
            .map_err(|e| anyhow::anyhow!("MPC parameters {}: {e}", path.display()))?;
        Self::parse(&text).map_err(|e| anyhow::anyhow!("MPC parameters {}: {e}", path.display()))
    }

    /// Parses and checks TOML text.
    pub fn parse(text: &str) -> Result<Self, String> {
        let p: Self = toml::from_str(text).map_err(|e| {
            let line = e
                .span()
                .map(|s| text[..s.start.min(text.len())].matches('\n').count() + 1);
            let msg = e.message().replace('\n', " ");
            match line {
                Some(l) => format!("line {l}: {}", msg.trim()),
                None => msg.trim().to_string(),
            }
        })?;
        p.validate()?;
        Ok(p)
    }

    /// Checks ranges; the message names the key.
    pub fn validate(&self) -> Result<(), String> {
        let range = |name: &str, v: f64, lo: f64, hi: f64| {
            if v.is_finite() && v >= lo && v <= hi {
                Ok(())
            } else {
                Err(format!("{name} must be in [{lo}, {hi}], got {v}"))
            }
        };
        range("body_height_m", self.body_height_m, 0.15, 0.40)?;
        range("lift_height_m", self.lift_height_m, 0.0, 0.20)?;
        range("gait_period_s", self.gait_period_s, 0.2, 3.0)?;
        range("swing_fraction", self.swing_fraction, 0.1, 0.5)?;
        range("horizon_steps", self.horizon_steps as f64, 1.0, 50.0)?;
        range("horizon_dt_s", self.horizon_dt_s, 0.005, 0.2)?;
        range("friction_mu", self.friction_mu, 0.05, 2.0)?;
        range("max_normal_force_n", self.max_normal_force_n, 50.0, 2000.0)?;
        range("raibert_gain_s", self.raibert_gain_s, 0.0, 1.0)?;
        range("stance_position_gain", self.stance_position_gain, 0.0, 1.0)?;
        range("swing_lead_s", self.swing_lead_s, 0.0, 0.2)?;
        let weights = [
            ("w_attitude", self.w_attitude),
            ("w_position", self.w_position),
            ("w_angular_velocity", self.w_angular_velocity),
            ("w_linear_velocity", self.w_linear_velocity),
        ];
        for (name, w) in weights {
            for v in w {
                range(name, v, 0.0, 1e6)?;
            }
        }
        range("w_force", self.w_force, 1e-9, 1.0)
    }

    /// Stance time of one leg per cycle, s.
    pub fn stance_s(&self) -> f64 {
        self.gait_period_s * (1.0 - self.swing_fraction)
    }

    /// Swing time of one leg per cycle, s.
    pub fn swing_s(&self) -> f64 {
        self.gait_period_s * self.swing_fraction
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_are_valid_and_keys_are_optional() {
        assert_eq!(MpcParams::parse("").unwrap(), MpcParams::default());
        let p = MpcParams::parse("body_height_m = 0.28\ngait_period_s = 0.5\n").unwrap();
        assert_eq!((p.body_height_m, p.gait_period_s), (0.28, 0.5));
    }

    #[test]
    fn bad_files_get_one_line_errors() {
        let e = MpcParams::parse("body_height_m = 0.9").unwrap_err();
        assert_eq!(e, "body_height_m must be in [0.15, 0.4], got 0.9");
        let e = MpcParams::parse("\nbody_hieght_m = 0.3").unwrap_err();
        assert!(
            e.starts_with("line 2:") && e.contains("body_hieght_m"),
            "{e}"
        );
        assert!(!e.contains('\n'));
        let e = MpcParams::parse("lift_height_m = \"high\"").unwrap_err();
        assert!(e.starts_with("line 1:") && !e.contains('\n'), "{e}");
        let missing = MpcParams::load(Path::new("no/such/mpc.toml")).unwrap_err();
        let m = missing.to_string();
        assert!(m.contains("no/such/mpc.toml") && !m.contains('\n'), "{m}");
    }
}
