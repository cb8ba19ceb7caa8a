//! The vectorized hexapod environment: N robots, each in its own rapier world, stepped in
//! parallel (rayon). Implements [`VecEnv`]: observations, rewards, terminations, time-outs,
//! domain randomization, pushes, command sampling and the terrain curriculum.

use crate::config::{ConfigError, EnvConfig};
use crate::curriculum::{curriculum_step, CommandProgress, LevelChange};
use crate::frames::{quat_from_yaw, quat_mul, rotate, rotate_inverse, yaw_rad};
use crate::observe;
use crate::reference::ReferenceStart;
use crate::rewards::{self, RewardInputs, TERM_NAMES};
use crate::robot::{BuildError, ContactState, DriveParams, RobotState, RobotWorld};
use crate::terrain::Terrain;
use crate::urdf_model::{UrdfError, UrdfModel};
use crate::vec_env::{Observations, StepResult, VecEnv};
use hexapod_core::amp::AMP_STATE_DIM;
use hexapod_core::control::action_to_targets;
use hexapod_core::kinematics::foot_position_base;
use hexapod_core::obs::{
    actor_obs, height_scan_point_m, proprio_noise_scale, ProprioHistory, ACTION_CLIP,
    ACTOR_OBS_DIM, HEIGHT_SCALE, HEIGHT_SCAN_DIM, HEIGHT_SCAN_OFFSET_M, HISTORY_DIM,
    PRIVILEGED_DIM, PROPRIO_DIM,
};
use hexapod_core::robot::{
    Leg, FOOT_RADIUS_M, NUM_JOINTS, NUM_LEGS, Q0_RAD, Q_MAX_RAD, Q_MIN_RAD, TORQUE_LIMIT_NM,
    VELOCITY_LIMIT_RAD_S,
};
use hexapod_core::timing::{
    ACTION_SCALE_RAD, CSP_KP1_PER_S, CSP_KP2_NMS_PER_RAD, DECIMATION, POLICY_DT_S,
};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use std::sync::Arc;

/// Nominal joint stiffness (Kp1 * Kp2), N m/rad.
const NOMINAL_STIFFNESS_NM_PER_RAD: f32 = CSP_KP1_PER_S * CSP_KP2_NMS_PER_RAD;
/// Spawn height above the terrain, m (the robot settles onto its feet).
pub const SPAWN_HEIGHT_M: f32 = 0.33;
/// Least gap between a foot and the ground under it at spawn, m.
const SPAWN_FOOT_GAP_M: f32 = 0.01;

/// Why an environment could not be built.
#[derive(Debug, thiserror::Error)]
pub enum EnvError {
    /// Bad config.
    #[error(transparent)]
    Config(#[from] ConfigError),
    /// Bad URDF.
    #[error(transparent)]
    Urdf(#[from] UrdfError),
    /// URDF without the expected structure.
    #[error(transparent)]
    Build(#[from] BuildError),
}

/// Where a robot starts and which way it faces (evaluation: before a feature, facing it).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SpawnPose {
    /// Base position (x, y) in the world, m; the height follows from the ground under the
    /// base and the feet, as for every spawn.
    pub position_m: [f32; 2],
    /// Heading (yaw about z, from the world x axis), rad.
    pub yaw_rad: f32,
}

/// One robot with its episode bookkeeping.
struct Slot {
    robot: RobotWorld,
    rng: ChaCha8Rng,
    terrain: Arc<Terrain>,
    level: usize,
    column: usize,
    origin_m: [f32; 2],
    spawn_pose: Option<SpawnPose>,
    references: Arc<[ReferenceStart]>,
    command_progress: CommandProgress,
    command: [f32; 3],
    /// The command set by [`VecEnv::set_command`], kept instead of resampling.
    fixed_command: Option<[f32; 3]>,
    action: [f32; NUM_JOINTS],
    prev_action: [f32; NUM_JOINTS],
    prev_targets: [f32; NUM_JOINTS],
    last_qdot: [f32; NUM_JOINTS],
    history: ProprioHistory,
    /// Policy steps since the episode started.
    step: usize,
    /// Steps added to `step` for the episode clock (time-out, pushes, command resampling):
    /// 0, but for the episode running when [`VecEnv::randomize_episode_clocks`] was called.
    clock_offset: usize,
    friction: f32,
    last_push_m_s: [f32; 3],
    term_sums: [f32; TERM_NAMES.len()],
    actor: [f32; ACTOR_OBS_DIM],
    privileged: [f32; PRIVILEGED_DIM],
    heights: [f32; HEIGHT_SCAN_DIM],
    amp: [f32; AMP_STATE_DIM],
    state: RobotState,
    contacts: ContactState,
}

/// What one robot's step produced.
struct SlotStep {
    reward: f32,
    done: bool,
    time_out: bool,
    invalid: bool,
    amp_next: [f32; AMP_STATE_DIM],
    episode: Option<Vec<(String, f32)>>,
}

/// N simulated hexapods.
pub struct HexapodEnv {
    config: EnvConfig,
    terrain: Arc<Terrain>,
    slots: Vec<Slot>,
    max_episode_steps: usize,
}

impl HexapodEnv {
    /// Builds the environment from a config and the shipped URDF.
    pub fn new(config: EnvConfig) -> Result<Self, EnvError> {
        let model = UrdfModel::load(&crate::urdf_model::default_urdf_path())?;
        Self::with_model(config, &model)
    }

    /// Builds the environment from a config and a robot model.
    pub fn with_model(config: EnvConfig, model: &UrdfModel) -> Result<Self, EnvError> {
        config.validate("env config")?;
        let terrain = Terrain::generate(&config.terrain);
        Self::build(config, model, terrain)
    }

    /// Builds the environment on a given ground (the evaluation course) instead of the one
    /// `config.terrain` describes; robots spawn at the world origin unless given a
    /// [`SpawnPose`]. Keep `config.curriculum` off: there are no tile rows to move between.
    pub fn with_terrain(config: EnvConfig, terrain: Terrain) -> Result<Self, EnvError> {
        config.validate("env config")?;
        let model = UrdfModel::load(&crate::urdf_model::default_urdf_path())?;
        Self::build(config, &model, terrain)
    }

    fn build(config: EnvConfig, model: &UrdfModel, terrain: Terrain) -> Result<Self, EnvError> {
        let terrain = Arc::new(terrain);
        let ground = terrain.collider();
        let max_episode_steps = (config.episode_length_s / POLICY_DT_S).round() as usize;
        let slots: Result<Vec<Slot>, EnvError> = (0..config.num_envs)
            .map(|i| {
                let mut robot = RobotWorld::new(model, ground.clone(), config.solver_iterations)?;
                robot.set_friction_in_bias_pass(config.friction_in_bias_pass);
                robot.set_foot_friction_combine(config.foot_friction_combine);
                let mut rng = ChaCha8Rng::seed_from_u64(
                    config.seed.wrapping_mul(0x9E37_79B9).wrapping_add(i as u64),
                );
                let columns = config.terrain.columns.len().max(1);
                let level = if config.terrain.tiles {
                    rng.gen_range(0..=config.max_initial_level.min(config.terrain.rows - 1))
                } else {
                    0
                };
                Ok(Slot {
                    robot,
                    rng,
                    terrain: terrain.clone(),
                    level,
                    column: i % columns,
                    origin_m: [0.0; 2],
                    spawn_pose: None,
                    references: Arc::from(Vec::new()),
                    command_progress: CommandProgress::default(),
                    command: [0.0; 3],
                    fixed_command: None,
                    action: [0.0; NUM_JOINTS],
                    prev_action: [0.0; NUM_JOINTS],
                    prev_targets: Q0_RAD,
                    last_qdot: [0.0; NUM_JOINTS],
                    history: ProprioHistory::filled_with(&[0.0; PROPRIO_DIM]),
                    step: 0,
                    clock_offset: 0,
                    friction: 1.0,
                    last_push_m_s: [0.0; 3],
                    term_sums: [0.0; TERM_NAMES.len()],
                    actor: [0.0; ACTOR_OBS_DIM],
                    privileged: [0.0; PRIVILEGED_DIM],
                    heights: [0.0; HEIGHT_SCAN_DIM],
                    amp: [0.0; AMP_STATE_DIM],
                    state: RobotState::default(),
                    contacts: ContactState::default(),
                })
            })
            .collect();
        Ok(Self {
            config,
            terrain,
            slots: slots?,
            max_episode_steps,
        })
    }

    /// The config in force.
    pub fn config(&self) -> &EnvConfig {
        &self.config
    }

    /// The ground all robots walk on.
    pub fn terrain(&self) -> &Terrain {
        &self.terrain
    }

    /// Kinematic state of robot `i`.
    pub fn robot_state(&self, i: usize) -> RobotState {
        self.slots[i].state
    }

    /// Foot friction coefficient robot `i` drew at its last reset (1.0 without randomization).
    pub fn foot_friction(&self, i: usize) -> f32 {
        self.slots[i].friction
    }

    /// Friction coefficient of robot `i`'s foot contacts with the ground: its foot's
    /// combined with the ground's by the configured rule.
    pub fn contact_friction(&self, i: usize) -> f32 {
        self.config
            .foot_friction_combine
            .contact_friction(self.slots[i].friction)
    }

    /// The simulated robot `i` (link poses and shapes for a 3D replay).
    pub fn robot_world(&self, i: usize) -> &RobotWorld {
        &self.slots[i].robot
    }

    /// Contacts of robot `i` after the last step.
    pub fn contacts(&self, i: usize) -> ContactState {
        self.slots[i].contacts
    }

    /// Feet on the ground (bit i = leg i) of robot `i`: the rewards' stance rule
    /// (`rewards::stance_mask`, contact force above `STANCE_FORCE_N`).
    pub fn foot_contact_mask(&self, i: usize) -> u8 {
        rewards::stance_mask(&self.slots[i].contacts.foot_force_world_n)
    }

    /// Command of robot `i`.
    pub fn command(&self, i: usize) -> [f32; 3] {
        self.slots[i].command
    }

    /// Terrain level (row) of robot `i`.
    pub fn terrain_level(&self, i: usize) -> usize {
        self.slots[i].level
    }

    /// Places robot `i` on tile (`level`, `column`) from its next reset on (evaluation; the
    /// curriculum, when on, moves it again after each episode).
    pub fn set_terrain_tile(&mut self, i: usize, level: usize, column: usize) {
        let rows = self.config.terrain.rows.max(1);
        let columns = self.config.terrain.columns.len().max(1);
        self.slots[i].level = level.min(rows - 1);
        self.slots[i].column = column % columns;
    }

    /// Spawns robot `i` at `pose` from its next reset on (`None`: back to its tile, at a
    /// random offset and heading). The random draws of a reset are the same either way, so
    /// a pose changes where a robot starts, not its randomized dynamics.
    pub fn set_spawn_pose(&mut self, i: usize, pose: Option<SpawnPose>) {
        self.slots[i].spawn_pose = pose;
    }

    /// The reference states episodes may start from (reference state initialization, with
    /// probability `reference_init_probability` per reset), shared by all robots.
    pub fn set_reference_states(&mut self, states: Arc<[ReferenceStart]>) {
        for slot in &mut self.slots {
            slot.references = states.clone();
        }
    }

    /// Reseeds robot `i`'s random generator (randomization, noise, commands, pushes), so
    /// that robots in different slots can draw the same dynamics (evaluation: trial k of
    /// every test gets the same robot).
    pub fn reseed(&mut self, i: usize, seed: u64) {
        self.slots[i].rng = ChaCha8Rng::seed_from_u64(seed);
    }

    /// Where robot `i` started its current episode (x, y), m.
    pub fn spawn_position_m(&self, i: usize) -> [f32; 2] {
        self.slots[i].origin_m
    }

    /// Joint targets of robot `i` in the last policy step (after the action path's clamps),
    /// rad.
    pub fn targets_rad(&self, i: usize) -> [f32; NUM_JOINTS] {
        self.slots[i].prev_targets
    }

    /// Joint torques of robot `i` in the last physics step, N m.
    pub fn torque_nm(&self, i: usize) -> [f32; NUM_JOINTS] {
        self.slots[i].robot.torque_nm
    }

    /// Drive parameters of robot `i` (randomized per episode).
    pub fn drive_params(&self, i: usize) -> DriveParams {
        self.slots[i].robot.drives.clone()
    }

    /// Total mass of robot `i` including its payload, kg (randomized per episode).
    pub fn total_mass_kg(&self, i: usize) -> f32 {
        self.slots[i].robot.total_mass_kg()
    }

    /// Pushes robot `i`: adds `dv_world_m_s` to its base velocity.
    pub fn push(&mut self, i: usize, dv_world_m_s: [f32; 3]) {
        let slot = &mut self.slots[i];
        slot.robot.push(dv_world_m_s);
        slot.last_push_m_s = dv_world_m_s;
    }

    fn gather(&self) -> Observations {
        let n = self.slots.len();
        let mut obs = Observations {
            actor: Vec::with_capacity(n * ACTOR_OBS_DIM),
            history: Vec::with_capacity(n * HISTORY_DIM),
            privileged: Vec::with_capacity(n * PRIVILEGED_DIM),
            heights: Vec::with_capacity(n * HEIGHT_SCAN_DIM),
            amp: Vec::with_capacity(n * AMP_STATE_DIM),
        };
        for s in &self.slots {
            obs.actor.extend_from_slice(&s.actor);
            obs.history.extend_from_slice(&s.history.flatten());
            obs.privileged.extend_from_slice(&s.privileged);
            obs.heights.extend_from_slice(&s.heights);
            obs.amp.extend_from_slice(&s.amp);
        }
        obs
    }
}

impl VecEnv for HexapodEnv {
    fn num_envs(&self) -> usize {
        self.slots.len()
    }

    fn set_reference_states(&mut self, states: Arc<[ReferenceStart]>) {
        HexapodEnv::set_reference_states(self, states);
    }

    fn randomize_episode_clocks(&mut self) {
        let max_steps = self.max_episode_steps;
        for s in &mut self.slots {
            s.clock_offset = s.rng.gen_range(0..max_steps.max(1));
        }
    }

    fn terrain_tiles(&self) -> Option<Vec<[usize; 2]>> {
        self.config
            .terrain
            .tiles
            .then(|| self.slots.iter().map(|s| [s.level, s.column]).collect())
    }

    fn set_terrain_tiles(&mut self, tiles: &[[usize; 2]]) {
        for (i, [level, column]) in tiles.iter().copied().enumerate().take(self.slots.len()) {
            self.set_terrain_tile(i, level, column);
        }
    }

    fn set_command(&mut self, i: usize, command: [f32; 3]) {
        let s = &mut self.slots[i];
        s.fixed_command = Some(command);
        s.command = command;
    }

    fn reset(&mut self) -> Observations {
        let config = &self.config;
        self.slots.par_iter_mut().for_each(|s| {
            s.reset(config);
        });
        self.gather()
    }

    fn step(&mut self, actions: &[f32]) -> StepResult {
        let n = self.slots.len();
        assert_eq!(
            actions.len(),
            n * NUM_JOINTS,
            "actions must be [num_envs, 18]"
        );
        let config = &self.config;
        let max_steps = self.max_episode_steps;
        let outs: Vec<SlotStep> = self
            .slots
            .par_iter_mut()
            .zip(actions.par_chunks(NUM_JOINTS))
            .map(|(slot, a)| slot.step(config, a, max_steps))
            .collect();
        let mut result = StepResult {
            obs: self.gather(),
            rewards: Vec::with_capacity(n),
            dones: Vec::with_capacity(n),
            time_outs: Vec::with_capacity(n),
            amp_next: Vec::with_capacity(n * AMP_STATE_DIM),
            invalid_actions: Vec::with_capacity(n),
            episode_log: Vec::new(),
        };
        let mut finished = 0usize;
        let mut sums: Vec<(String, f32)> = Vec::new();
        for o in outs {
            result.rewards.push(o.reward);
            result.dones.push(o.done);
            result.time_outs.push(o.time_out);
            result.invalid_actions.push(o.invalid);
            result.amp_next.extend_from_slice(&o.amp_next);
            if let Some(log) = o.episode {
                finished += 1;
                if sums.is_empty() {
                    sums = log;
                } else {
                    for (acc, (_, v)) in sums.iter_mut().zip(log) {
                        acc.1 += v;
                    }
                }
            }
        }
        if finished > 0 {
            result.episode_log = sums
                .into_iter()
                .map(|(k, v)| (k, v / finished as f32))
                .collect();
            let mean_level = self.slots.iter().map(|s| s.level as f32).sum::<f32>() / n as f32;
            result
                .episode_log
                .push(("terrain_level".into(), mean_level));
            if self.config.terrain.tiles {
                // Per tile kind: a stalled column (stairs) hides in the mean over all robots.
                for (column, kind) in self.config.terrain.columns.iter().enumerate() {
                    let (sum, count) = self
                        .slots
                        .iter()
                        .filter(|s| s.column == column)
                        .fold((0usize, 0usize), |(sum, count), s| {
                            (sum + s.level, count + 1)
                        });
                    if count > 0 {
                        result
                            .episode_log
                            .push((format!("terrain_level_{kind:?}"), sum as f32 / count as f32));
                    }
                }
            }
        }
        result
    }
}

/// Base height at which a robot spawns at `xy` with heading `yaw_rad` and joints `q`:
/// [`SPAWN_HEIGHT_M`] above the ground under the base, or higher where a foot would
/// otherwise start inside the ground under it (a foot over the first step of a stair tile,
/// or over a block). A foot spawned inside a heightfield falls through it.
pub fn spawn_height_m(
    terrain: &Terrain,
    xy: [f32; 2],
    yaw_rad: f32,
    q: &[f32; NUM_JOINTS],
    min_height_m: f32,
) -> f32 {
    let (sin, cos) = yaw_rad.sin_cos();
    let mut z = terrain.height_at_m(xy[0], xy[1]) + min_height_m;
    for leg in Leg::ALL {
        let j = 3 * leg.index();
        let p = foot_position_base(leg, [q[j], q[j + 1], q[j + 2]]);
        let (fx, fy) = (
            xy[0] + cos * p[0] - sin * p[1],
            xy[1] + sin * p[0] + cos * p[1],
        );
        z = z.max(terrain.height_at_m(fx, fy) - p[2] + FOOT_RADIUS_M + SPAWN_FOOT_GAP_M);
    }
    z
}

/// The termination rule: the trunk touches the ground, the base tilts more than
/// `max_tilt_deg` from upright, or the state is not physical: not finite, or the base moving
/// faster than [`BLOWN_UP_SPEED_M_S`] (a solve that blew up; no push or fall comes near it).
pub fn terminated(s: &RobotState, trunk_contact: bool, max_tilt_deg: f32) -> bool {
    let gravity = rotate_inverse(s.base_quat_xyzw, [0.0, 0.0, -1.0]);
    let finite = s
        .base_pos_world_m
        .iter()
        .chain(s.q_rad.iter())
        .chain(s.qdot_rad_s.iter())
        .chain(s.base_lin_vel_world_m_s.iter())
        .chain(s.base_ang_vel_world_rad_s.iter())
        .all(|x| x.is_finite());
    let speed_m_s = s
        .base_lin_vel_world_m_s
        .iter()
        .map(|v| v * v)
        .sum::<f32>()
        .sqrt();
    trunk_contact
        || gravity[2] > -max_tilt_deg.to_radians().cos()
        || !finite
        || speed_m_s > BLOWN_UP_SPEED_M_S
}

/// Base speed beyond which a robot's state counts as a blown-up solve, m/s: the paper
/// suite's strongest push is 6 m/s, a fall from standing height reaches about 2.5 m/s.
pub const BLOWN_UP_SPEED_M_S: f32 = 20.0;

fn uniform(rng: &mut ChaCha8Rng, [lo, hi]: [f32; 2]) -> f32 {
    if hi > lo {
        rng.gen_range(lo..hi)
    } else {
        lo
    }
}

impl Slot {
    /// Draws a new command, or keeps the fixed one; the draw is made either way, so the
    /// robot's other random draws do not depend on whether its command is fixed.
    fn sample_command(&mut self, config: &EnvConfig) {
        let c = &config.commands;
        let drawn = if self.rng.gen::<f32>() < c.zero_probability {
            [0.0; 3]
        } else {
            [
                uniform(&mut self.rng, c.lin_vel_x_m_s),
                uniform(&mut self.rng, c.lin_vel_y_m_s),
                uniform(&mut self.rng, c.ang_vel_z_rad_s),
            ]
        };
        self.command = self.fixed_command.unwrap_or(drawn);
    }

    /// The episode clock: time-outs, pushes and command resampling follow it.
    fn clock(&self) -> usize {
        self.step + self.clock_offset
    }

    fn update_curriculum(&mut self, config: &EnvConfig) {
        if !(config.curriculum && config.terrain.tiles) {
            return;
        }
        let walked_m = self.command_progress.progress_m();
        // What a fall cut short; none after a time-out, also one the episode clock brought
        // forward ([`VecEnv::randomize_episode_clocks`]).
        let remaining_s = config.episode_length_s - self.clock() as f32 * POLICY_DT_S;
        let commanded_m = self.command_progress.commanded_m(self.command, remaining_s);
        let rows = config.terrain.rows;
        self.level = match curriculum_step(walked_m, commanded_m, config.terrain.tile_size_m) {
            LevelChange::Up if self.level + 1 >= rows => self.rng.gen_range(0..rows),
            LevelChange::Up => self.level + 1,
            LevelChange::Down => self.level.saturating_sub(1),
            LevelChange::Stay => self.level,
        };
    }

    fn randomize(&mut self, config: &EnvConfig) {
        let r = &config.randomization;
        if !r.enabled {
            self.robot.drives = DriveParams::default();
            self.friction = 1.0;
            self.robot.set_foot_friction(1.0);
            self.robot.set_mass_properties(&[], 0.0, [0.0; 3]);
            return;
        }
        let mut drives = DriveParams::default();
        for j in 0..NUM_JOINTS {
            let stiffness =
                NOMINAL_STIFFNESS_NM_PER_RAD * uniform(&mut self.rng, r.stiffness_factor);
            let damping = CSP_KP2_NMS_PER_RAD * uniform(&mut self.rng, r.damping_factor);
            drives.kp2_nms_per_rad[j] = damping;
            drives.kp1_per_s[j] = stiffness / damping;
            drives.motor_strength[j] = uniform(&mut self.rng, r.motor_strength);
        }
        self.robot.drives = drives;
        self.friction = uniform(&mut self.rng, r.friction);
        self.robot.set_foot_friction(self.friction);
        let scales: Vec<f32> = (0..self.robot.num_links())
            .map(|_| uniform(&mut self.rng, r.link_mass_factor))
            .collect();
        let payload = uniform(&mut self.rng, r.payload_kg);
        let off = r.payload_offset_m;
        let offset = [
            uniform(&mut self.rng, [-off, off]),
            uniform(&mut self.rng, [-off, off]),
            0.0,
        ];
        self.robot.set_mass_properties(&scales, payload, offset);
    }

    fn reset(&mut self, config: &EnvConfig) {
        self.randomize(config);
        let [cx, cy] = self.terrain.tile_center_m(self.level, self.column);
        let spread = if config.terrain.tiles { 1.0 } else { 0.0 };
        let mut x = cx + uniform(&mut self.rng, [-spread, spread]);
        let mut y = cy + uniform(&mut self.rng, [-spread, spread]);
        let mut yaw = uniform(&mut self.rng, [-std::f32::consts::PI, std::f32::consts::PI]);
        if let Some(pose) = self.spawn_pose {
            [x, y] = pose.position_m;
            yaw = pose.yaw_rad;
        }
        self.origin_m = [x, y];
        let mut q = Q0_RAD;
        if config.randomization.enabled {
            for j in 0..NUM_JOINTS {
                q[j] = (Q0_RAD[j]
                    * uniform(&mut self.rng, config.randomization.initial_joint_pos_factor))
                .clamp(Q_MIN_RAD[j], Q_MAX_RAD[j]);
            }
        }
        let start = self.draw_reference(config);
        let reference = start.map(|s| s.state);
        self.action = [0.0; NUM_JOINTS];
        if let Some(r) = reference {
            // Reference state initialization: the prior's pose and velocities, tilted as in
            // the prior, at this spawn's position and heading, feet just above the ground.
            q = r.q_rad;
            let quat = quat_mul(quat_from_yaw(yaw), r.tilt_quat_xyzw());
            let z = spawn_height_m(&self.terrain, [x, y], yaw, &q, r.base_height_m);
            self.robot.reset([x, y, z], quat, &q);
            self.robot.set_velocities(
                rotate(quat, r.lin_vel_base_m_s),
                rotate(quat, r.ang_vel_base_rad_s),
                &r.qdot_rad_s,
            );
            for j in 0..NUM_JOINTS {
                self.action[j] =
                    ((q[j] - Q0_RAD[j]) / ACTION_SCALE_RAD).clamp(-ACTION_CLIP, ACTION_CLIP);
            }
        } else {
            let z = spawn_height_m(&self.terrain, [x, y], yaw, &q, SPAWN_HEIGHT_M);
            self.robot.reset([x, y, z], quat_from_yaw(yaw), &q);
        }
        self.command_progress = CommandProgress::default();
        self.sample_command(config);
        if let (Some(start), true, None) =
            (start, config.reference_init_command, self.fixed_command)
        {
            // Until the first resample, the robot is asked for what its motion was doing.
            self.command = start.command;
        }
        self.prev_action = self.action;
        self.prev_targets = q;
        self.last_qdot = reference.map_or([0.0; NUM_JOINTS], |r| r.qdot_rad_s);
        self.step = 0;
        self.clock_offset = 0;
        self.last_push_m_s = [0.0; 3];
        self.term_sums = [0.0; TERM_NAMES.len()];
        self.state = self.robot.state();
        self.contacts = ContactState::default();
        let proprio = self.proprio(config);
        self.history = ProprioHistory::filled_with(&proprio);
        self.observe(proprio);
    }

    /// A reference state to start from, with probability `reference_init_probability`.
    fn draw_reference(&mut self, config: &EnvConfig) -> Option<ReferenceStart> {
        if config.reference_init_probability <= 0.0 || self.references.is_empty() {
            return None;
        }
        let pick = self.rng.gen_range(0..self.references.len());
        (self.rng.gen::<f32>() < config.reference_init_probability).then(|| self.references[pick])
    }

    /// o^p of the current state, with noise when configured.
    fn proprio(&mut self, config: &EnvConfig) -> [f32; PROPRIO_DIM] {
        let mut o = observe::proprio(&self.state);
        if config.observation_noise {
            let scale = proprio_noise_scale();
            for (x, n) in o.iter_mut().zip(scale) {
                *x += n * self.rng.gen_range(-1.0f32..1.0);
            }
        }
        o
    }

    fn base_height_m(&self) -> f32 {
        let p = self.state.base_pos_world_m;
        p[2] - self.terrain.height_at_m(p[0], p[1])
    }

    /// Fills the observation buffers from the current state (history already updated).
    fn observe(&mut self, proprio: [f32; PROPRIO_DIM]) {
        let s = self.state;
        let height = self.base_height_m();
        self.actor = actor_obs(self.command, &self.prev_action, &proprio);
        self.privileged = observe::privileged(
            &s,
            height,
            self.friction,
            &self.contacts,
            self.last_push_m_s,
        );
        // Height scan in the yaw-aligned frame.
        let yaw = yaw_rad(s.base_quat_xyzw);
        let (sin, cos) = yaw.sin_cos();
        let [bx, by, bz] = s.base_pos_world_m;
        for k in 0..HEIGHT_SCAN_DIM {
            let [px, py] = height_scan_point_m(k);
            let h = self
                .terrain
                .height_at_m(bx + cos * px - sin * py, by + sin * px + cos * py);
            self.heights[k] = (bz - HEIGHT_SCAN_OFFSET_M - h).clamp(-1.0, 1.0) * HEIGHT_SCALE;
        }
        self.amp = observe::amp(&s);
    }

    fn step(&mut self, config: &EnvConfig, action: &[f32], max_steps: usize) -> SlotStep {
        let invalid = action.iter().any(|a| !a.is_finite());
        if invalid {
            let amp_next = self.amp;
            let episode = Some(self.episode_log());
            self.reset(config);
            return SlotStep {
                reward: 0.0,
                done: true,
                time_out: false,
                invalid,
                amp_next,
                episode,
            };
        }
        // The firmware's action path (`hexapod_core::control::action_to_targets`): clip,
        // offset from the nominal pose, clamp to the joint limits and the rate limit.
        let action: &[f32; NUM_JOINTS] = action.try_into().expect("one action per joint");
        let q_target;
        (self.action, q_target) = action_to_targets(action, &self.prev_targets);
        self.prev_targets = q_target;
        // Foot forces are averaged over the policy step: single 5 ms samples carry impact
        // spikes that would dominate the contact-force penalty and the privileged state.
        let mut force_sum = [[0.0f32; 3]; NUM_LEGS];
        for _ in 0..DECIMATION {
            self.robot.step(&q_target);
            for (sum, f) in force_sum.iter_mut().zip(self.robot.foot_forces_world_n()) {
                for k in 0..3 {
                    sum[k] += f[k] / DECIMATION as f32;
                }
            }
        }
        self.step += 1;
        self.state = self.robot.state();
        self.contacts = self.robot.contacts();
        self.contacts.foot_force_world_n = force_sum;
        let s = self.state;
        let lin_vel = rotate_inverse(s.base_quat_xyzw, s.base_lin_vel_world_m_s);
        let ang_vel = rotate_inverse(s.base_quat_xyzw, s.base_ang_vel_world_rad_s);
        self.command_progress
            .advance(self.command, [lin_vel[0], lin_vel[1]], POLICY_DT_S);
        let mut qddot = [0.0; NUM_JOINTS];
        for j in 0..NUM_JOINTS {
            qddot[j] = (s.qdot_rad_s[j] - self.last_qdot[j]) / POLICY_DT_S;
        }
        let collisions = self
            .contacts
            .thighs
            .iter()
            .chain(self.contacts.shanks.iter())
            .filter(|c| **c)
            .count() as u32;
        let terms = rewards::compute(
            &config.rewards,
            &RewardInputs {
                command: self.command,
                lin_vel_base_m_s: lin_vel,
                ang_vel_base_rad_s: ang_vel,
                torque_nm: &self.robot.torque_nm,
                torque_limit_nm: &TORQUE_LIMIT_NM,
                qdot_rad_s: &s.qdot_rad_s,
                velocity_limit_rad_s: &VELOCITY_LIMIT_RAD_S,
                qddot_rad_s2: &qddot,
                action: &self.action,
                prev_action: &self.prev_action,
                collisions,
                foot_force_n: &self.contacts.foot_force_world_n,
            },
            POLICY_DT_S,
        );
        for (acc, v) in self.term_sums.iter_mut().zip(terms.values) {
            *acc += v;
        }
        let terminated = terminated(&s, self.contacts.trunk, config.max_tilt_deg);
        let clock = self.clock();
        let time_out = clock >= max_steps;
        let done = terminated || time_out;
        let amp_next = observe::amp(&s);
        self.last_qdot = s.qdot_rad_s;
        self.prev_action = self.action;

        if done {
            let episode = Some(self.episode_log());
            self.update_curriculum(config);
            self.reset(config);
            return SlotStep {
                reward: terms.total(),
                done,
                time_out: time_out && !terminated,
                invalid,
                amp_next,
                episode,
            };
        }
        // Pushes and command resampling.
        let push_every = (config.push.interval_s / POLICY_DT_S).round().max(1.0) as usize;
        if config.push.enabled && clock.is_multiple_of(push_every) {
            let m = config.push.max_vel_xy_m_s;
            let dv = [
                uniform(&mut self.rng, [-m, m]),
                uniform(&mut self.rng, [-m, m]),
                0.0,
            ];
            self.robot.push(dv);
            self.last_push_m_s = dv;
        }
        let resample_every = (config.commands.resampling_time_s / POLICY_DT_S)
            .round()
            .max(1.0) as usize;
        if clock.is_multiple_of(resample_every) {
            self.sample_command(config);
        }
        let proprio = self.proprio(config);
        self.history.push(&proprio);
        self.observe(proprio);
        SlotStep {
            reward: terms.total(),
            done,
            time_out: false,
            invalid,
            amp_next,
            episode: None,
        }
    }

    fn episode_log(&self) -> Vec<(String, f32)> {
        let length_s = (self.step.max(1)) as f32 * POLICY_DT_S;
        let mut log: Vec<(String, f32)> = TERM_NAMES
            .iter()
            .zip(self.term_sums)
            .map(|(name, sum)| (format!("rew_{name}"), sum / length_s))
            .collect();
        log.push(("episode_length_s".into(), length_s));
        log
    }
}
