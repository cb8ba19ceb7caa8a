//! The training configuration: one `Default` struct per concern, read from TOML presets
//! (`configs/*.toml`, `deny_unknown_fields`) and saved, resolved, beside every checkpoint.

use serde::{Deserialize, Serialize};
use std::path::Path;

/// Why a configuration could not be used.
#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    /// The file could not be read.
    #[error("cannot read config {path}: {source}")]
    Io {
        /// File that failed.
        path: String,
        /// Underlying error.
        source: std::io::Error,
    },
    /// The TOML is malformed or has unknown or mistyped keys.
    #[error("malformed config {path}: {message}")]
    Parse {
        /// File that failed.
        path: String,
        /// The parser's message (names the key and line).
        message: String,
    },
    /// A value is out of its meaningful range.
    #[error("invalid config: {0}")]
    Invalid(String),
}

/// Which environment the trainer drives.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum EnvKind {
    /// The rapier3d hexapod of `host-sim`.
    Sim,
    /// A deterministic point-mass stand-in with the robot's observation sizes (tests, smoke runs).
    Fake,
}

/// Environment section.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct EnvConfig {
    /// Environment implementation.
    pub kind: EnvKind,
    /// Number of parallel robots.
    pub num_envs: usize,
    /// Seed of the environment (terrain, randomization, commands).
    pub seed: u64,
    /// Episode length in policy steps for the fake environment (the simulator uses 20 s).
    pub fake_episode_steps: usize,
}

impl Default for EnvConfig {
    fn default() -> Self {
        Self {
            kind: EnvKind::Sim,
            num_envs: 128,
            seed: 1,
            fake_episode_steps: 200,
        }
    }
}

/// Reward terms (paper Table I): r = r_g + r_s + r_l; the ablations switch terms off.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RewardConfig {
    /// Task (velocity tracking) reward r_g.
    pub task: bool,
    /// Style reward r_s from the discriminator.
    pub style: bool,
    /// Penalties r_l.
    pub penalties: bool,
    /// Scale of the style reward (paper: 1).
    pub style_weight: f32,
    /// Clip the environment's reward (task + penalties) at zero before the style reward is
    /// added (legged_gym's `only_positive_rewards`): with penalties larger than the task
    /// reward early in training, a negative per-step reward pays the policy to end episodes
    /// early by falling.
    pub only_positive_env_reward: bool,
}

impl Default for RewardConfig {
    fn default() -> Self {
        Self {
            task: true,
            style: true,
            penalties: true,
            style_weight: 1.0,
            only_positive_env_reward: true,
        }
    }
}

/// Network shapes and the asymmetric actor-critic's structure.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct PolicyConfig {
    /// Estimator hidden sizes (history -> scaled base velocity).
    pub estimator_hidden: Vec<usize>,
    /// Memory encoder hidden sizes (history -> latent).
    pub memory_hidden: Vec<usize>,
    /// Memory latent size.
    pub memory_latent: usize,
    /// Low-level actor hidden sizes.
    pub actor_hidden: Vec<usize>,
    /// Critic hidden sizes.
    pub critic_hidden: Vec<usize>,
    /// Privileged encoder g_p hidden sizes.
    pub privileged_encoder_hidden: Vec<usize>,
    /// Privileged latent l^p size.
    pub privileged_latent: usize,
    /// Terrain encoder g_e hidden sizes.
    pub terrain_encoder_hidden: Vec<usize>,
    /// Terrain latent l^e size.
    pub terrain_latent: usize,
    /// Initial action standard deviation.
    pub init_noise_std: f32,
    /// Floor on every action dimension's standard deviation, enforced after each optimizer
    /// step (AMP_for_hardware's `min_normalized_std` clamp, in action units); 0 = no floor,
    /// the paper's setting. An option for fine-tuning stages whose exploration PPO would
    /// otherwise shrink away. One action unit is `hexapod_core::timing::ACTION_SCALE_RAD`
    /// (0.25 rad) at the joint; `assets/reports/terrain-stages` (stage 8) measured a 0.35
    /// floor against none: the mean policy walked shorter and stepped down worse.
    pub min_noise_std: f32,
    /// The actor reads the velocity estimate (false: "Baseline").
    pub use_estimator: bool,
    /// The critic reads the privileged state and terrain through g_p and g_e
    /// (false: "Baseline" and "Concurrent", whose critic sees the actor's observations).
    pub privileged_critic: bool,
}

impl Default for PolicyConfig {
    fn default() -> Self {
        use hexapod_core::nets;
        Self {
            estimator_hidden: nets::ESTIMATOR_HIDDEN.to_vec(),
            memory_hidden: nets::MEMORY_HIDDEN.to_vec(),
            memory_latent: nets::MEMORY_LATENT,
            actor_hidden: nets::ACTOR_HIDDEN.to_vec(),
            critic_hidden: vec![512, 256, 128],
            privileged_encoder_hidden: vec![64, 32],
            privileged_latent: 8,
            terrain_encoder_hidden: vec![256, 128],
            terrain_latent: 16,
            init_noise_std: 1.0,
            min_noise_std: 0.0,
            use_estimator: true,
            privileged_critic: true,
        }
    }
}

/// Which phase of RMA (Kumar et al. 2021) a policy is in.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum RmaPhase {
    /// Phase 1: the actor's latent comes from the environment-factor encoder mu
    /// (privileged state and height scan); trained by PPO (`hexapod train`).
    Teacher,
    /// Phase 2 done: the memory encoder was regressed onto mu's latent with the actor,
    /// estimator and mu frozen (`hexapod rma-adapt`); the actor reads the memory latent as
    /// deployed. Not trained further by PPO.
    Adapted,
}

/// RMA's teacher-student structure (`[rma]`; absent: the paper's controller). The teacher's
/// actor reads, in the slot of the memory latent, `mu(normalized privileged state,
/// normalized height scan)` (`policy.memory_latent` numbers); adaptation then trains the
/// memory encoder to regress it from the history, so the deployed topology stays the same.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RmaConfig {
    /// Phase of the policy.
    pub phase: RmaPhase,
    /// Hidden sizes of the environment-factor encoder mu (privileged 42 + heights 187 ->
    /// `policy.memory_latent`).
    pub encoder_hidden: Vec<usize>,
}

impl Default for RmaConfig {
    fn default() -> Self {
        Self {
            phase: RmaPhase::Teacher,
            // RMA's environment-factor encoder.
            encoder_hidden: vec![256, 128],
        }
    }
}

/// Learning-rate schedule.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum LrSchedule {
    /// rsl_rl's adaptive schedule on the KL divergence.
    Adaptive,
    /// Constant learning rate.
    Fixed,
}

/// PPO hyperparameters (rsl_rl's names).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct PpoConfig {
    /// Rollout length per environment and iteration.
    pub num_steps_per_env: usize,
    /// Passes over each rollout.
    pub num_learning_epochs: usize,
    /// Minibatches per pass.
    pub num_mini_batches: usize,
    /// Ratio and value clip.
    pub clip_param: f32,
    /// Discount.
    pub gamma: f32,
    /// GAE lambda.
    pub lam: f32,
    /// Value loss weight.
    pub value_loss_coef: f32,
    /// Entropy bonus weight.
    pub entropy_coef: f32,
    /// Estimator (supervised) loss weight.
    pub estimator_loss_coef: f32,
    /// Initial learning rate of the actor-critic.
    pub learning_rate: f64,
    /// Global gradient-norm clip.
    pub max_grad_norm: f32,
    /// Clip the value loss around the old values.
    pub use_clipped_value_loss: bool,
    /// Learning-rate schedule.
    pub schedule: LrSchedule,
    /// Target KL of the adaptive schedule.
    pub desired_kl: f32,
}

impl Default for PpoConfig {
    fn default() -> Self {
        Self {
            num_steps_per_env: 24,
            num_learning_epochs: 5,
            num_mini_batches: 4,
            clip_param: 0.2,
            gamma: 0.99,
            lam: 0.95,
            value_loss_coef: 1.0,
            entropy_coef: 0.01,
            estimator_loss_coef: 1.0,
            learning_rate: 1e-3,
            max_grad_norm: 1.0,
            use_clipped_value_loss: true,
            schedule: LrSchedule::Adaptive,
            desired_kl: 0.01,
        }
    }
}

/// Where prior (expert) transitions come from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PriorKind {
    /// `assets/priors-sync/*.json`, the trajectory-optimized tripod clips.
    Dataset,
    /// A synthetic tripod oscillation (tests and smoke runs only).
    Synthetic,
}

/// AMP discriminator.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct AmpConfig {
    /// Discriminator hidden sizes.
    pub discriminator_hidden: Vec<usize>,
    /// Discriminator learning rate.
    pub learning_rate: f64,
    /// Gradient-penalty weight alpha_gp (penalty = alpha_gp / 2 * E|grad D|^2).
    pub grad_penalty_weight: f32,
    /// Weight of the discriminator loss in the joint update.
    pub loss_coef: f32,
    /// L2 weight decay on the discriminator's hidden-layer weights.
    pub weight_decay: f64,
    /// L2 weight decay on the output (logit) layer's weights, which keeps the discriminator
    /// from saturating at d = -1 where the style reward has no slope (AMP's logit
    /// regularization).
    pub logit_weight_decay: f64,
    /// Standard deviation of Gaussian instance noise added to the discriminator's normalized
    /// inputs (prior and policy) while it trains, never when it scores the policy. The
    /// priors are a few exact periodic loops; without noise the discriminator fences them
    /// in so tightly that every policy transition scores d = -1 and the style reward is
    /// flat zero.
    pub input_noise_std: f32,
    /// Policy transitions kept in the replay buffer.
    pub replay_buffer_size: usize,
    /// Prior source.
    pub prior_kind: PriorKind,
    /// Directory of the motion-prior clips (relative to the working directory, or else to
    /// the workspace root).
    pub priors_dir: String,
    /// Which states of the clips the discriminator sees and episodes start from: `tracked`
    /// (the simulator performing each clip with its drives: states the robot can reach)
    /// or `optimized` (the trajectory optimization's frames, as the paper's dataset).
    pub prior_states: crate::priors::dataset::PriorStates,
    /// Let the discriminator's Adam follow the policy's learning rate (the adaptive KL
    /// schedule), as AMP_for_hardware does with one optimizer for both, instead of the
    /// fixed `learning_rate`.
    pub follow_policy_learning_rate: bool,
    /// Discriminator gradient steps per iteration: it trains on the first this many of the
    /// update's PPO minibatches (0: on every one, as AMP_for_hardware does). With few robots
    /// per iteration every minibatch gives the discriminator many more steps per environment
    /// sample than the reference implementations take (AMP_for_hardware: 20 steps per
    /// 4,096 x 24 samples; 128 x 24 in 6 minibatches: 6), and it outruns the policy;
    /// `flat-tripod` takes 1.
    pub steps_per_iteration: usize,
}

impl Default for AmpConfig {
    fn default() -> Self {
        Self {
            discriminator_hidden: vec![1024, 512],
            learning_rate: 1e-4,
            grad_penalty_weight: 10.0,
            loss_coef: 1.0,
            weight_decay: 1e-4,
            logit_weight_decay: 1e-2,
            input_noise_std: 0.0,
            replay_buffer_size: 100_000,
            prior_kind: PriorKind::Dataset,
            priors_dir: "assets/priors-sync".into(),
            prior_states: crate::priors::dataset::PriorStates::Tracked,
            follow_policy_learning_rate: false,
            steps_per_iteration: 0,
        }
    }
}

/// The runner: iterations, logging, checkpoints.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RunnerConfig {
    /// Name of the experiment (output directory name).
    pub experiment_name: String,
    /// Number of iterations (rollout + update).
    pub max_iterations: usize,
    /// Checkpoint every this many iterations (and at the end).
    pub save_interval: usize,
    /// Seed of the learner (initialization, sampling, minibatches).
    pub seed: u64,
    /// Learner threads (0: all cores).
    pub num_threads: usize,
}

impl Default for RunnerConfig {
    fn default() -> Self {
        Self {
            experiment_name: "hexapod".into(),
            max_iterations: 1500,
            save_interval: 50,
            seed: 1,
            num_threads: 0,
        }
    }
}

/// The complete training configuration.
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct TrainConfig {
    /// Environment.
    pub env: EnvConfig,
    /// Reward terms.
    pub rewards: RewardConfig,
    /// Networks.
    pub policy: PolicyConfig,
    /// PPO.
    pub ppo: PpoConfig,
    /// AMP.
    pub amp: AmpConfig,
    /// Runner.
    pub runner: RunnerConfig,
    /// RMA's teacher (or its adapted student); absent (not written) for every other
    /// controller.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub rma: Option<RmaConfig>,
    /// The simulator (terrain, commands, reward scales, randomization, pushes) when
    /// `env.kind = "sim"`. Its `num_envs` and `seed` are taken from `[env]`, and its
    /// `rewards.task` / `rewards.regularization` switches from `[rewards]`.
    pub sim: host_sim::config::EnvConfig,
}

impl PartialEq for TrainConfig {
    fn eq(&self, other: &Self) -> bool {
        self.to_toml_string() == other.to_toml_string()
    }
}

impl TrainConfig {
    /// Parses a TOML string (missing keys take their defaults, unknown keys are errors).
    pub fn from_toml_str(text: &str, origin: &str) -> Result<Self, ConfigError> {
        let cfg: TrainConfig = toml::from_str(text).map_err(|e| ConfigError::Parse {
            path: origin.into(),
            message: e.to_string(),
        })?;
        cfg.validate()?;
        Ok(cfg)
    }

    /// Reads and validates a TOML file. A preset may start from another one with
    /// `base = "other.toml"` (relative to its own directory): the base is read first (it
    /// may have a base of its own) and the preset's keys replace the base's, table by
    /// table.
    pub fn load(path: &Path) -> Result<Self, ConfigError> {
        Self::load_with_overrides(path, &[])
    }

    /// [`TrainConfig::load`], then `overrides` (`section.key=value`, the value in TOML
    /// syntax; a bare word is taken as a string) applied over the layered file.
    pub fn load_with_overrides(path: &Path, overrides: &[String]) -> Result<Self, ConfigError> {
        let mut table = load_layered(path, &mut Vec::new())?;
        let origin = path.display().to_string();
        for o in overrides {
            apply_override(&mut table, o).map_err(|message| ConfigError::Parse {
                path: format!("--set {o}"),
                message,
            })?;
        }
        let cfg: TrainConfig =
            toml::Value::Table(table)
                .try_into()
                .map_err(|e: toml::de::Error| ConfigError::Parse {
                    path: origin,
                    message: e.to_string(),
                })?;
        cfg.validate()?;
        Ok(cfg)
    }

    /// The resolved configuration as TOML (every key written).
    pub fn to_toml_string(&self) -> String {
        toml::to_string_pretty(self).expect("the config is always representable in TOML")
    }

    /// The simulator config with the trainer's overrides applied.
    pub fn resolved_sim(&self) -> host_sim::config::EnvConfig {
        let mut sim = self.sim.clone();
        sim.num_envs = self.env.num_envs;
        sim.seed = self.env.seed;
        sim.rewards.task = self.rewards.task;
        sim.rewards.regularization = self.rewards.penalties;
        sim
    }

    /// Whether the actor reads mu's latent (an RMA teacher) instead of the memory encoder's.
    pub fn rma_teacher(&self) -> bool {
        self.rma
            .as_ref()
            .is_some_and(|r| r.phase == RmaPhase::Teacher)
    }

    /// Whether the discriminator is trained and its reward used.
    pub fn amp_enabled(&self) -> bool {
        self.rewards.style && self.rewards.style_weight != 0.0
    }

    /// Checks ranges that serde cannot.
    pub fn validate(&self) -> Result<(), ConfigError> {
        let bad = |m: &str| Err(ConfigError::Invalid(m.into()));
        let p = &self.ppo;
        if self.env.num_envs == 0 {
            return bad("env.num_envs must be positive");
        }
        if p.num_steps_per_env == 0 || p.num_learning_epochs == 0 || p.num_mini_batches == 0 {
            return bad(
                "ppo.num_steps_per_env, num_learning_epochs, num_mini_batches must be positive",
            );
        }
        if !(self.env.num_envs * p.num_steps_per_env).is_multiple_of(p.num_mini_batches) {
            return bad(
                "env.num_envs * ppo.num_steps_per_env must be divisible by ppo.num_mini_batches",
            );
        }
        if !(0.0..=1.0).contains(&p.gamma) || !(0.0..=1.0).contains(&p.lam) {
            return bad("ppo.gamma and ppo.lam must lie in [0, 1]");
        }
        if p.clip_param <= 0.0 || p.learning_rate <= 0.0 || p.max_grad_norm <= 0.0 {
            return bad("ppo.clip_param, learning_rate and max_grad_norm must be positive");
        }
        if self.policy.init_noise_std <= 0.0 {
            return bad("policy.init_noise_std must be positive");
        }
        if !(self.policy.min_noise_std.is_finite() && self.policy.min_noise_std >= 0.0) {
            return bad("policy.min_noise_std must be zero (no floor) or positive");
        }
        let sizes = [
            &self.policy.estimator_hidden,
            &self.policy.memory_hidden,
            &self.policy.actor_hidden,
            &self.policy.critic_hidden,
            &self.policy.privileged_encoder_hidden,
            &self.policy.terrain_encoder_hidden,
            &self.amp.discriminator_hidden,
            self.rma
                .as_ref()
                .map_or(&self.amp.discriminator_hidden, |r| &r.encoder_hidden),
        ];
        if sizes.iter().any(|h| h.contains(&0)) {
            return bad("hidden sizes must be positive");
        }
        if self.policy.memory_latent == 0
            || self.policy.privileged_latent == 0
            || self.policy.terrain_latent == 0
        {
            return bad("latent sizes must be positive");
        }
        if self.amp_enabled() && self.amp.replay_buffer_size == 0 {
            return bad("amp.replay_buffer_size must be positive");
        }
        if !self.rewards.task && !self.rewards.style && !self.rewards.penalties {
            return bad("at least one reward term must be on");
        }
        if self.env.kind == EnvKind::Sim {
            self.resolved_sim()
                .validate("[sim]")
                .map_err(|e| ConfigError::Invalid(e.to_string()))?;
        }
        if self.runner.save_interval == 0 {
            return bad("runner.save_interval must be positive");
        }
        Ok(())
    }
}

/// A path from a config or the command line: as given when it exists (relative to the
/// working directory) or is absolute, else relative to the workspace root, so the CLI works
/// from any directory of the checkout.
pub fn resolve_path(path: &str) -> std::path::PathBuf {
    let given = Path::new(path);
    if given.is_absolute() || given.exists() {
        return given.to_path_buf();
    }
    let from_root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..").join(given);
    if from_root.exists() {
        from_root
    } else {
        given.to_path_buf()
    }
}

/// The TOML table of `path` with its `base` chain merged under it. `chain` holds the
/// presets that led here (each canonicalized), so a preset met twice is refused as a loop.
fn load_layered(
    path: &Path,
    chain: &mut Vec<std::path::PathBuf>,
) -> Result<toml::Table, ConfigError> {
    let origin = path.display().to_string();
    let canonical = std::fs::canonicalize(path).map_err(|source| ConfigError::Io {
        path: origin.clone(),
        source,
    })?;
    if chain.contains(&canonical) {
        let names: Vec<String> = chain
            .iter()
            .chain(std::iter::once(&canonical))
            .map(|p| {
                p.file_name()
                    .unwrap_or_default()
                    .to_string_lossy()
                    .into_owned()
            })
            .collect();
        return Err(ConfigError::Parse {
            path: origin,
            message: format!("a loop of `base` presets: {}", names.join(" -> ")),
        });
    }
    chain.push(canonical);
    let text = std::fs::read_to_string(path).map_err(|source| ConfigError::Io {
        path: origin.clone(),
        source,
    })?;
    let mut table: toml::Table = text
        .parse()
        .map_err(|e: toml::de::Error| ConfigError::Parse {
            path: origin.clone(),
            message: e.to_string(),
        })?;
    let Some(base) = table.remove("base") else {
        return Ok(table);
    };
    let Some(base) = base.as_str() else {
        return Err(ConfigError::Parse {
            path: origin,
            message: "`base` must be a file name (a string)".into(),
        });
    };
    let base_path = path.parent().unwrap_or(Path::new(".")).join(base);
    let mut merged = load_layered(&base_path, chain)?;
    merge_into(&mut merged, table);
    Ok(merged)
}

/// Replaces `base`'s keys by `top`'s, descending into tables present in both.
fn merge_into(base: &mut toml::Table, top: toml::Table) {
    for (key, value) in top {
        match (base.get_mut(&key), value) {
            (Some(toml::Value::Table(b)), toml::Value::Table(t)) => merge_into(b, t),
            (_, value) => {
                base.insert(key, value);
            }
        }
    }
}

/// Sets `section.key=value` in `table`.
fn apply_override(table: &mut toml::Table, assignment: &str) -> Result<(), String> {
    let (key, value) = assignment
        .split_once('=')
        .ok_or_else(|| "expected `section.key=value`".to_string())?;
    let value = value.trim();
    let parsed: toml::Value = match format!("v = {value}").parse::<toml::Table>() {
        Ok(mut t) => t.remove("v").expect("the key was written"),
        Err(_) => toml::Value::String(value.to_string()),
    };
    let mut parts: Vec<&str> = key.trim().split('.').collect();
    let last = parts
        .pop()
        .filter(|k| !k.is_empty())
        .ok_or_else(|| "empty key".to_string())?;
    let mut at = table;
    for part in parts {
        at = at
            .entry(part.to_string())
            .or_insert_with(|| toml::Value::Table(toml::Table::new()))
            .as_table_mut()
            .ok_or_else(|| format!("`{part}` is not a table"))?;
    }
    at.insert(last.to_string(), parsed);
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_round_trip_through_toml() {
        let cfg = TrainConfig::default();
        let back = TrainConfig::from_toml_str(&cfg.to_toml_string(), "test").unwrap();
        assert_eq!(cfg, back);
    }

    #[test]
    fn every_preset_parses_and_validates() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../configs");
        let mut names = Vec::new();
        for entry in std::fs::read_dir(&dir).unwrap() {
            let path = entry.unwrap().path();
            if path.extension().is_some_and(|e| e == "toml") {
                let cfg = TrainConfig::load(&path).unwrap_or_else(|e| panic!("{e}"));
                names.push((path.file_stem().unwrap().to_string_lossy().to_string(), cfg));
            }
        }
        let get = |n: &str| {
            &names
                .iter()
                .find(|(k, _)| k == n)
                .unwrap_or_else(|| panic!("preset {n}"))
                .1
        };
        assert!(!get("ablation-gl").amp_enabled());
        assert!(!get("ablation-gs").rewards.penalties);
        assert!(!get("baseline").policy.use_estimator && !get("baseline").policy.privileged_critic);
        assert!(
            get("concurrent").policy.use_estimator && !get("concurrent").policy.privileged_critic
        );
        assert_eq!(get("paper").env.num_envs, 4096);
        assert_eq!(get("paper").amp.discriminator_hidden, vec![1024, 512]);
        // The flat recipe's second stage differs from its first in the tracking kernel only.
        use host_sim::rewards::TrackingKernel;
        let (first, second) = (get("flat-tripod"), get("flat-tripod-track"));
        assert_eq!(first.sim.rewards.tracking_kernel, TrackingKernel::Squared);
        assert_eq!(second.sim.rewards.tracking_kernel, TrackingKernel::Norm);
        assert_eq!(
            second.runner.max_iterations,
            first.runner.max_iterations + 1000
        );
        // So does the terrain recipe's, which also runs on the shipped simulator.
        let (first, second) = (get("ablation-gsl"), get("terrain-track"));
        assert_eq!(first.sim.rewards.tracking_kernel, TrackingKernel::Squared);
        assert_eq!(second.sim.rewards.tracking_kernel, TrackingKernel::Norm);
        assert_eq!(
            format!("{:?}", first.sim.terrain),
            format!("{:?}", second.sim.terrain)
        );
        assert!(second.sim.friction_in_bias_pass && !first.sim.friction_in_bias_pass);
    }

    #[test]
    fn unknown_keys_are_rejected_with_their_name() {
        let err = TrainConfig::from_toml_str("[ppo]\nlearnig_rate = 1e-3\n", "x.toml").unwrap_err();
        assert!(err.to_string().contains("learnig_rate"), "{err}");
    }

    #[test]
    fn wrong_types_and_ranges_are_rejected() {
        assert!(TrainConfig::from_toml_str("[env]\nnum_envs = \"many\"\n", "x").is_err());
        assert!(TrainConfig::from_toml_str("[ppo]\ngamma = 1.5\n", "x").is_err());
        let err = TrainConfig::from_toml_str(
            "[env]\nnum_envs = 3\n[ppo]\nnum_mini_batches = 4\nnum_steps_per_env = 3\n",
            "x",
        )
        .unwrap_err();
        assert!(err.to_string().contains("divisible"), "{err}");
        for floor in ["-0.1", "nan"] {
            let err =
                TrainConfig::from_toml_str(&format!("[policy]\nmin_noise_std = {floor}\n"), "x")
                    .unwrap_err();
            assert!(err.to_string().contains("min_noise_std"), "{err}");
        }
    }

    fn temp_dir(name: &str) -> std::path::PathBuf {
        let d = std::env::temp_dir().join(format!("hexapod-config-{name}-{}", std::process::id()));
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    #[test]
    fn presets_layer_on_a_base_and_the_command_line_overrides_both() {
        let d = temp_dir("layers");
        std::fs::write(
            d.join("base.toml"),
            "[ppo]\nlearning_rate = 1e-3\ngamma = 0.98\n[runner]\nexperiment_name = \"base\"\n",
        )
        .unwrap();
        std::fs::write(
            d.join("mid.toml"),
            "base = \"base.toml\"\n[ppo]\ngamma = 0.97\n",
        )
        .unwrap();
        std::fs::write(
            d.join("top.toml"),
            "base = \"mid.toml\"\n[runner]\nexperiment_name = \"top\"\n",
        )
        .unwrap();
        let cfg = TrainConfig::load(&d.join("top.toml")).unwrap();
        assert_eq!((cfg.ppo.learning_rate, cfg.ppo.gamma), (1e-3, 0.97));
        assert_eq!(cfg.runner.experiment_name, "top");
        let set = |s: &[&str]| s.iter().map(|x| x.to_string()).collect::<Vec<_>>();
        let cfg = TrainConfig::load_with_overrides(
            &d.join("top.toml"),
            &set(&[
                "ppo.learning_rate=3e-4",
                "runner.experiment_name=x",
                "sim.curriculum=false",
            ]),
        )
        .unwrap();
        assert_eq!(
            (
                cfg.ppo.learning_rate,
                cfg.runner.experiment_name.as_str(),
                cfg.sim.curriculum
            ),
            (3e-4, "x", false)
        );
        // Unknown keys and bad values name what is wrong.
        let err =
            TrainConfig::load_with_overrides(&d.join("top.toml"), &set(&["ppo.learnig_rate=1"]))
                .unwrap_err()
                .to_string();
        assert!(err.contains("learnig_rate"), "{err}");
        let err = TrainConfig::load_with_overrides(&d.join("top.toml"), &set(&["ppo.gamma"]))
            .unwrap_err()
            .to_string();
        assert!(err.contains("section.key=value"), "{err}");
        // A loop of bases and a missing base are refused.
        std::fs::write(d.join("loop.toml"), "base = \"loop.toml\"\n").unwrap();
        assert!(TrainConfig::load(&d.join("loop.toml"))
            .unwrap_err()
            .to_string()
            .contains("loop"));
        std::fs::write(d.join("ping.toml"), "base = \"pong.toml\"\n").unwrap();
        std::fs::write(d.join("pong.toml"), "base = \"ping.toml\"\n").unwrap();
        let err = TrainConfig::load(&d.join("ping.toml"))
            .unwrap_err()
            .to_string();
        assert!(err.contains("ping.toml -> pong.toml -> ping.toml"), "{err}");
        // A long chain without a loop is followed to its end.
        for k in 0..12 {
            let text = match k {
                0 => "[ppo]\ngamma = 0.96\n".to_string(),
                _ => format!("base = \"chain{}.toml\"\n", k - 1),
            };
            std::fs::write(d.join(format!("chain{k}.toml")), text).unwrap();
        }
        assert_eq!(
            TrainConfig::load(&d.join("chain11.toml"))
                .unwrap()
                .ppo
                .gamma,
            0.96
        );
        std::fs::write(d.join("orphan.toml"), "base = \"nowhere.toml\"\n").unwrap();
        assert!(TrainConfig::load(&d.join("orphan.toml"))
            .unwrap_err()
            .to_string()
            .contains("nowhere.toml"));
        std::fs::remove_dir_all(&d).ok();
    }
}
