//! What every protocol of the suite shares: the simulator settings it runs under (recorded
//! in the report), the seeds that give trial k the same robot in every test, and the loop
//! that drives a batch of robots with a controller at per-robot commands.

use super::controller::SuiteController;
use crate::config::TrainConfig;
use hexapod_core::timing::POLICY_DT_S;
use host_sim::config::{EnvConfig, FrictionCombine, RandomizationConfig};
use host_sim::env::HexapodEnv;
use host_sim::frames::{rotate_inverse, yaw_rad};
use host_sim::robot::RobotState;
use host_sim::vec_env::{StepResult, VecEnv};
use serde::Serialize;

/// Friction of the feet's contacts with the ground the suite draws from (each robot's foot
/// friction is the one its checkpoint's combine rule turns into a draw from this range),
/// instead of the training range's [0.1, 2.5]: below tan 30 deg = 0.58 no legged robot stands
/// on the 30 deg ramp, so the slope test would measure the friction draw, not the policy. Both
/// ends are the training range's inner part.
pub const SUITE_FRICTION: [f32; 2] = [0.6, 1.2];

/// The foot friction range that gives contacts `contact` on the ground under `combine`:
/// trial k's draw from it is the same fraction of the way as from `contact`, so trial k's
/// robot meets the ground with the same friction under either rule.
pub fn foot_friction_range(
    combine: FrictionCombine,
    contact: [f32; 2],
) -> anyhow::Result<[f32; 2]> {
    let foot = |mu: f32| {
        combine.foot_friction_for(mu).ok_or_else(|| {
            anyhow::anyhow!(
                "no foot friction gives contacts of friction {mu} under the checkpoint's \
                 {combine:?} rule (averaged with the ground's {}, contacts are at least half of it)",
                host_sim::terrain::GROUND_FRICTION
            )
        })
    };
    Ok([foot(contact[0])?, foot(contact[1])?])
}

/// The conditions every protocol runs under, as the report records them.
#[derive(Clone, Debug, Serialize)]
pub struct Conditions {
    /// Seed of the suite; trial k of every test uses robot seed `trial_seed(seed, k)`.
    pub seed: u64,
    /// Trials (robots) per test point.
    pub trials: usize,
    /// The reduced variant (CI).
    pub quick: bool,
    /// Domain randomization per robot (the checkpoint's ranges, friction narrowed).
    pub randomization: RandomizationConfig,
    /// How a foot's friction and the ground's combine (the checkpoint's rule).
    pub foot_friction_combine: FrictionCombine,
    /// Friction of the contacts with the ground, the range the foot friction is drawn to give.
    pub contact_friction: [f32; 2],
    /// Observation noise on the actor's inputs (the checkpoint's setting).
    pub observation_noise: bool,
    /// Termination of the simulator ("current" rule): trunk contact or tilt beyond this, deg.
    pub max_tilt_deg: f32,
    /// Random pushes of the training environment (off: the push protocol applies its own).
    pub random_pushes: bool,
    /// Actions: the policy's mean (deterministic), not samples.
    pub deterministic_policy: bool,
    /// Length of each trial of the terrain, step, beyond and friction tests, s.
    pub terrain_duration_s: f32,
    /// Cell of the course's height grid, m: each riser is a ramp one cell wide
    /// (`host_sim::course::CELL_M` by default).
    pub course_cell_m: f32,
}

impl Conditions {
    /// The suite's conditions for a checkpoint's config.
    pub fn new(cfg: &TrainConfig, seed: u64, trials: usize, quick: bool) -> anyhow::Result<Self> {
        let sim = cfg.resolved_sim();
        let mut c = Self {
            seed,
            trials,
            quick,
            randomization: sim.randomization.clone(),
            foot_friction_combine: sim.foot_friction_combine,
            contact_friction: SUITE_FRICTION,
            observation_noise: sim.observation_noise,
            max_tilt_deg: sim.max_tilt_deg,
            random_pushes: false,
            deterministic_policy: true,
            terrain_duration_s: super::terrain::DURATION_S,
            course_cell_m: host_sim::course::CELL_M,
        };
        c.set_contact_friction(SUITE_FRICTION)?;
        Ok(c)
    }

    /// Draws the robots' contacts from `contact_friction`: the foot friction range that
    /// gives it under the checkpoint's combine rule.
    pub fn set_contact_friction(&mut self, contact_friction: [f32; 2]) -> anyhow::Result<()> {
        self.randomization.friction =
            foot_friction_range(self.foot_friction_combine, contact_friction)?;
        self.contact_friction = contact_friction;
        Ok(())
    }

    /// These conditions with every robot's contacts at friction `contact_friction`.
    pub fn at_contact_friction(&self, contact_friction: f32) -> anyhow::Result<Self> {
        let mut at = self.clone();
        at.set_contact_friction([contact_friction; 2])?;
        Ok(at)
    }

    /// Simulator config for `num_envs` robots running `duration_s` without a time-out, on
    /// flat ground, without the curriculum or the environment's own pushes.
    pub fn sim_config(&self, cfg: &TrainConfig, num_envs: usize, duration_s: f32) -> EnvConfig {
        let mut sim = cfg.resolved_sim();
        sim.num_envs = num_envs;
        sim.seed = self.seed;
        sim.curriculum = false;
        sim.push.enabled = self.random_pushes;
        sim.episode_length_s = duration_s + 1.0;
        sim.randomization = self.randomization.clone();
        sim.observation_noise = self.observation_noise;
        sim.terrain = host_sim::terrain::TerrainConfig::default();
        sim
    }

    /// Robots needed by `points` test points of `trials` each.
    pub fn robots(&self, points: usize) -> usize {
        points * self.trials
    }

    /// At least this many of `trials` robots must survive: 9 of 10 (90 %, rounded up).
    pub fn survivors_needed(&self) -> usize {
        (self.trials * 9).div_ceil(10)
    }
}

/// Seed of trial `k`'s robot: the same dynamics in every test and at every magnitude.
pub fn trial_seed(seed: u64, k: usize) -> u64 {
    seed.wrapping_mul(0x2545_F491_4F6C_DD1D)
        .wrapping_add(0x9E37 + k as u64)
}

/// Policy steps in `s` seconds.
pub fn steps(s: f32) -> usize {
    (s / POLICY_DT_S).round() as usize
}

/// Runs `steps` policy steps of `controller`. Before each step `before(step, env, commands)` may push
/// robots and set each robot's command; after it `after(step, env, result)` reads the
/// outcome (a robot whose episode ended is already reset in `env`).
pub fn drive(
    env: &mut HexapodEnv,
    controller: &mut dyn SuiteController,
    steps: usize,
    mut before: impl FnMut(usize, &mut HexapodEnv, &mut [[f32; 3]]),
    mut after: impl FnMut(usize, &HexapodEnv, &StepResult),
) -> anyhow::Result<()> {
    let n = env.num_envs();
    let mut commands = vec![[0.0f32; 3]; n];
    let mut obs = env.reset();
    controller.start(env);
    for step in 0..steps {
        before(step, env, &mut commands);
        for (i, c) in commands.iter().enumerate() {
            env.set_command(i, *c);
            obs.set_command(i, *c);
        }
        let actions = controller.act(&obs, env)?;
        let res = env.step(&actions);
        for (i, _) in res.dones.iter().enumerate().filter(|(_, d)| **d) {
            controller.episode_ended(i);
        }
        after(step, env, &res);
        obs = res.obs;
    }
    Ok(())
}

/// Reseeds robot `i` as trial `i % trials` and resets nothing else (call before `drive`).
pub fn seed_trials(env: &mut HexapodEnv, c: &Conditions) {
    for i in 0..env.num_envs() {
        env.reseed(i, trial_seed(c.seed, i % c.trials));
    }
}

/// Base velocity in the heading frame (x forward, y left, z up; not tilted with the base), m/s.
pub fn heading_velocity_m_s(s: &RobotState) -> [f32; 3] {
    let yaw = yaw_rad(s.base_quat_xyzw);
    rotate_inverse(
        host_sim::frames::quat_from_yaw(yaw),
        s.base_lin_vel_world_m_s,
    )
}

/// Roll and pitch of the base, rad (z-y-x Euler angles).
pub fn roll_pitch_rad(s: &RobotState) -> (f32, f32) {
    let [x, y, z, w] = s.base_quat_xyzw;
    let roll = (2.0 * (w * x + y * z)).atan2(1.0 - 2.0 * (x * x + y * y));
    let pitch = (2.0 * (w * y - z * x)).clamp(-1.0, 1.0).asin();
    (roll, pitch)
}

/// Angle between the base's z axis and the vertical, rad.
pub fn tilt_rad(s: &RobotState) -> f32 {
    let [x, y, _, _] = s.base_quat_xyzw;
    (1.0 - 2.0 * (x * x + y * y)).clamp(-1.0, 1.0).acos()
}

#[cfg(test)]
mod tests {
    use super::*;
    use host_sim::frames::quat_from_yaw;

    /// Under either combine rule the suite's robots meet the ground with the same friction:
    /// the foot range maps onto the contact range end to end, and every friction the suite
    /// asks for has a foot friction that gives it.
    #[test]
    fn both_combine_rules_give_the_suites_contact_friction() {
        for combine in [FrictionCombine::Multiply, FrictionCombine::Average] {
            let foot = foot_friction_range(combine, SUITE_FRICTION).unwrap();
            for k in 0..2 {
                assert!((combine.contact_friction(foot[k]) - SUITE_FRICTION[k]).abs() < 1e-6);
            }
            let mut cfg = TrainConfig::default();
            cfg.sim.foot_friction_combine = combine;
            let c = Conditions::new(&cfg, 1, 10, false).unwrap();
            for &mu in super::super::friction::FRICTION_SWEEP.iter() {
                let at = c.at_contact_friction(mu).unwrap();
                assert_eq!(at.contact_friction, [mu, mu]);
                assert!((combine.contact_friction(at.randomization.friction[0]) - mu).abs() < 1e-6);
            }
        }
        let c = Conditions::new(&TrainConfig::default(), 1, 10, false).unwrap();
        assert_eq!(c.foot_friction_combine, FrictionCombine::Multiply);
        let averaged = foot_friction_range(FrictionCombine::Average, SUITE_FRICTION).unwrap();
        assert!((averaged[0] - 0.2).abs() < 1e-6 && (averaged[1] - 1.4).abs() < 1e-6);
        assert!(foot_friction_range(FrictionCombine::Average, [0.4, 1.0]).is_err());
    }

    #[test]
    fn nine_of_ten() {
        let mut c = Conditions::new(&TrainConfig::default(), 1, 10, false).unwrap();
        assert_eq!(c.survivors_needed(), 9);
        c.trials = 2;
        assert_eq!(c.survivors_needed(), 2);
        c.trials = 1;
        assert_eq!(c.survivors_needed(), 1);
    }

    #[test]
    fn frames() {
        let mut s = RobotState {
            base_quat_xyzw: quat_from_yaw(1.0),
            ..Default::default()
        };
        s.base_lin_vel_world_m_s = [1.0f32.cos(), 1.0f32.sin(), 0.2];
        let v = heading_velocity_m_s(&s);
        assert!((v[0] - 1.0).abs() < 1e-5 && v[1].abs() < 1e-5 && (v[2] - 0.2).abs() < 1e-6);
        assert!(tilt_rad(&s) < 1e-3);
        // 20 deg roll about x.
        let h = 10f32.to_radians();
        s.base_quat_xyzw = [h.sin(), 0.0, 0.0, h.cos()];
        let (roll, pitch) = roll_pitch_rad(&s);
        assert!((roll.to_degrees() - 20.0).abs() < 1e-3 && pitch.abs() < 1e-5);
        assert!((tilt_rad(&s).to_degrees() - 20.0).abs() < 1e-2);
    }
}
