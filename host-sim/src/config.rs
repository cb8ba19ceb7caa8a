//! Environment settings: one `Default` struct, read from TOML with unknown fields refused.

use crate::rewards::RewardScales;
use crate::terrain::TerrainConfig;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// Ranges of the velocity commands.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CommandConfig {
    /// Forward velocity range, m/s.
    pub lin_vel_x_m_s: [f32; 2],
    /// Lateral velocity range, m/s.
    pub lin_vel_y_m_s: [f32; 2],
    /// Yaw rate range, rad/s.
    pub ang_vel_z_rad_s: [f32; 2],
    /// Commands are resampled this often, s.
    pub resampling_time_s: f32,
    /// Probability that a sampled command is zero (standing still).
    pub zero_probability: f32,
}

impl Default for CommandConfig {
    fn default() -> Self {
        Self {
            lin_vel_x_m_s: [-0.5, 0.5],
            lin_vel_y_m_s: [-0.3, 0.3],
            ang_vel_z_rad_s: [-0.5, 0.5],
            resampling_time_s: 10.0,
            zero_probability: 0.1,
        }
    }
}

/// Domain randomization ranges (the paper's table), as [low, high] factors or values.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RandomizationConfig {
    /// Switch for everything below.
    pub enabled: bool,
    /// Joint stiffness factor (nominal 100 N m/rad).
    pub stiffness_factor: [f32; 2],
    /// Joint damping factor (nominal 2 N m s/rad).
    pub damping_factor: [f32; 2],
    /// Initial joint position factor on the nominal pose.
    pub initial_joint_pos_factor: [f32; 2],
    /// Link mass factor.
    pub link_mass_factor: [f32; 2],
    /// Payload on the trunk, kg.
    pub payload_kg: [f32; 2],
    /// Payload offset from the base origin in x and y, m (symmetric).
    pub payload_offset_m: f32,
    /// Foot friction coefficient.
    pub friction: [f32; 2],
    /// Motor strength factor.
    pub motor_strength: [f32; 2],
}

impl Default for RandomizationConfig {
    fn default() -> Self {
        Self {
            enabled: true,
            stiffness_factor: [0.8, 1.2],
            damping_factor: [0.8, 1.2],
            initial_joint_pos_factor: [0.6, 1.4],
            link_mass_factor: [0.9, 1.1],
            payload_kg: [0.0, 5.0],
            payload_offset_m: 0.15,
            friction: [0.1, 2.5],
            motor_strength: [0.8, 1.2],
        }
    }
}

/// How the friction coefficients of a foot and of the ground combine into the contact's.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FrictionCombine {
    /// foot x ground: on the ground's 1.0 a contact has the foot's coefficient, so the
    /// randomized range is the contacts' range (the simulator's default).
    #[default]
    Multiply,
    /// (foot + ground) / 2: PhysX's default combine mode, which Isaac Gym (where the paper
    /// trained, on legged_gym's terrain of friction 1.0) does not change. The paper's foot
    /// friction [0.1, 2.5] then meets the ground at [0.55, 1.75].
    Average,
}

impl FrictionCombine {
    /// The contact's friction coefficient for a foot's on the ground.
    pub fn contact_friction(self, foot_friction: f32) -> f32 {
        let ground = crate::terrain::GROUND_FRICTION;
        match self {
            Self::Multiply => foot_friction * ground,
            Self::Average => 0.5 * (foot_friction + ground),
        }
    }

    /// The foot's friction coefficient that gives a contact `contact_friction` on the
    /// ground, `None` where no non-negative foot coefficient does (below 0.5 averaged).
    pub fn foot_friction_for(self, contact_friction: f32) -> Option<f32> {
        let ground = crate::terrain::GROUND_FRICTION;
        let foot = match self {
            Self::Multiply => contact_friction / ground,
            Self::Average => 2.0 * contact_friction - ground,
        };
        (foot >= 0.0 && foot.is_finite()).then_some(foot)
    }
}

/// Random pushes: sudden base velocity changes.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct PushConfig {
    /// Switch.
    pub enabled: bool,
    /// Time between pushes, s.
    pub interval_s: f32,
    /// Largest horizontal velocity change, m/s.
    pub max_vel_xy_m_s: f32,
}

impl Default for PushConfig {
    fn default() -> Self {
        Self {
            enabled: true,
            interval_s: 8.0,
            max_vel_xy_m_s: 0.5,
        }
    }
}

/// Everything that defines a batch of simulated robots.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct EnvConfig {
    /// Number of robots.
    pub num_envs: usize,
    /// Seed of all randomness.
    pub seed: u64,
    /// Episode length, s.
    pub episode_length_s: f32,
    /// Rapier solver iterations per physics step.
    pub solver_iterations: usize,
    /// Solve foot friction in both passes of each solver substep (the simulator's default,
    /// [`crate::robot::RobotWorld::set_friction_in_bias_pass`]); `false` is rapier's own
    /// default, under which loaded feet slide (BENCHMARKS.md, foot slip). Runs trained before
    /// the change set `false` to be reproduced.
    pub friction_in_bias_pass: bool,
    /// How a foot's friction coefficient (the randomized one) and the ground's
    /// ([`crate::terrain::GROUND_FRICTION`]) make the contact's.
    pub foot_friction_combine: FrictionCombine,
    /// Add observation noise to the actor's inputs.
    pub observation_noise: bool,
    /// Terminate when the base tilts beyond this angle, degrees.
    pub max_tilt_deg: f32,
    /// Move robots between terrain rows by how far they walk.
    pub curriculum: bool,
    /// Highest row a robot starts on.
    pub max_initial_level: usize,
    /// Terrain.
    pub terrain: TerrainConfig,
    /// Commands.
    pub commands: CommandConfig,
    /// Reward scales.
    pub rewards: RewardScales,
    /// Domain randomization.
    pub randomization: RandomizationConfig,
    /// Pushes.
    pub push: PushConfig,
    /// Probability that an episode starts from a random reference state (a prior's pose
    /// and velocities) instead of standing at the nominal pose, when the learner has given
    /// reference states (AMP's reference state initialization; AMP_for_hardware uses 0.85).
    /// The trainer loads the motion priors for them whenever this is above 0, with or
    /// without the style reward.
    pub reference_init_probability: f32,
    /// An episode started from a reference state is commanded the velocity of that state's
    /// motion (its clip's command) until the command is first resampled, instead of a
    /// random command: the robot starts mid-stride doing what it is asked. Off in the paper's
    /// setup and in AMP_for_hardware, which draw the two independently.
    pub reference_init_command: bool,
}

impl Default for EnvConfig {
    fn default() -> Self {
        Self {
            num_envs: 64,
            seed: 1,
            episode_length_s: hexapod_core::timing::EPISODE_LENGTH_S,
            solver_iterations: 1,
            friction_in_bias_pass: true,
            foot_friction_combine: FrictionCombine::Multiply,
            observation_noise: true,
            max_tilt_deg: 60.0,
            curriculum: true,
            max_initial_level: 2,
            terrain: TerrainConfig::default(),
            commands: CommandConfig::default(),
            rewards: RewardScales::default(),
            randomization: RandomizationConfig::default(),
            reference_init_probability: 0.0,
            reference_init_command: false,
            push: PushConfig::default(),
        }
    }
}

/// Why a config was refused.
#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    /// The file could not be read.
    #[error("{path}: cannot read: {source}")]
    Io {
        /// The file.
        path: String,
        /// The cause.
        source: std::io::Error,
    },
    /// TOML syntax or an unknown / mistyped field (the message names it).
    #[error("{path}: {message}")]
    Parse {
        /// The file.
        path: String,
        /// The parser's message, naming the field.
        message: String,
    },
    /// A value outside its allowed range.
    #[error("{path}: {field}: {message}")]
    Invalid {
        /// The file.
        path: String,
        /// The field.
        field: String,
        /// What is wrong.
        message: String,
    },
}

impl EnvConfig {
    /// Reads a config from a TOML file and validates it.
    pub fn load(path: &Path) -> Result<Self, ConfigError> {
        let text = std::fs::read_to_string(path).map_err(|source| ConfigError::Io {
            path: path.display().to_string(),
            source,
        })?;
        Self::from_toml(&path.display().to_string(), &text)
    }

    /// Parses and validates TOML text; `origin` names it in errors.
    pub fn from_toml(origin: &str, text: &str) -> Result<Self, ConfigError> {
        let config: Self = toml::from_str(text).map_err(|e| ConfigError::Parse {
            path: origin.into(),
            message: e.to_string(),
        })?;
        config.validate(origin)?;
        Ok(config)
    }

    /// Checks ranges; `origin` names the source in errors.
    pub fn validate(&self, origin: &str) -> Result<(), ConfigError> {
        let bad = |field: &str, message: String| ConfigError::Invalid {
            path: origin.into(),
            field: field.into(),
            message,
        };
        if self.num_envs == 0 {
            return Err(bad("num_envs", "must be at least 1".into()));
        }
        if self.episode_length_s.is_nan() || self.episode_length_s <= 0.0 {
            return Err(bad("episode_length_s", "must be positive".into()));
        }
        if self.solver_iterations == 0 {
            return Err(bad("solver_iterations", "must be at least 1".into()));
        }
        if !(0.0..=1.0).contains(&self.reference_init_probability) {
            return Err(bad(
                "reference_init_probability",
                format!(
                    "{} is not a probability in [0, 1]",
                    self.reference_init_probability
                ),
            ));
        }
        let ranges = [
            ("commands.lin_vel_x_m_s", self.commands.lin_vel_x_m_s),
            ("commands.lin_vel_y_m_s", self.commands.lin_vel_y_m_s),
            ("commands.ang_vel_z_rad_s", self.commands.ang_vel_z_rad_s),
            (
                "randomization.stiffness_factor",
                self.randomization.stiffness_factor,
            ),
            (
                "randomization.damping_factor",
                self.randomization.damping_factor,
            ),
            (
                "randomization.initial_joint_pos_factor",
                self.randomization.initial_joint_pos_factor,
            ),
            (
                "randomization.link_mass_factor",
                self.randomization.link_mass_factor,
            ),
            ("randomization.payload_kg", self.randomization.payload_kg),
            ("randomization.friction", self.randomization.friction),
            (
                "randomization.motor_strength",
                self.randomization.motor_strength,
            ),
        ];
        for (field, [lo, hi]) in ranges {
            if !(lo.is_finite() && hi.is_finite() && lo <= hi) {
                return Err(bad(field, format!("[{lo}, {hi}] is not a range")));
            }
        }
        if self.randomization.damping_factor[0] <= 0.0 || self.randomization.friction[0] < 0.0 {
            return Err(bad(
                "randomization",
                "damping factor must be positive, friction non-negative".into(),
            ));
        }
        if self.terrain.tiles && (self.terrain.rows == 0 || self.terrain.columns.is_empty()) {
            return Err(bad(
                "terrain",
                "tiles need at least one row and one column".into(),
            ));
        }
        if self.terrain.cell_size_m.is_nan() || self.terrain.cell_size_m <= 0.0 {
            return Err(bad("terrain.cell_size_m", "must be positive".into()));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_round_trips_through_toml() {
        let text = toml::to_string(&EnvConfig::default()).unwrap();
        let back = EnvConfig::from_toml("default", &text).unwrap();
        assert_eq!(back.num_envs, EnvConfig::default().num_envs);
    }

    #[test]
    fn unknown_field_is_named() {
        let err = EnvConfig::from_toml("env.toml", "[push]\nmax_vel = 1.0\n")
            .unwrap_err()
            .to_string();
        assert!(err.contains("env.toml") && err.contains("max_vel"), "{err}");
    }

    #[test]
    fn bad_range_is_named() {
        let err = EnvConfig::from_toml("env.toml", "[randomization]\nfriction = [2.0, 1.0]\n")
            .unwrap_err()
            .to_string();
        assert!(err.contains("randomization.friction"), "{err}");
    }
}
