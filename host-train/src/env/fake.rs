//! A deterministic stand-in environment with the robot's observation layout: a planar
//! "robot" whose body velocity follows the mean joint offsets of three joint groups.
//!
//! Joints track `q0 + ACTION_SCALE_RAD * a` through a first-order lag; the body's
//! `(vx, vy, wz)` relaxes toward `VEL_GAIN x` the mean offset of joints 0..6, 6..12 and
//! 12..18. The task reward is the paper's velocity tracking on a random command, the
//! penalty an action-rate term; an episode terminates when a joint leaves +-1 rad of its
//! nominal angle. Learnable in a few dozen PPO iterations, and the velocity estimator can
//! read the velocity from the joint history, so it exercises every part of the trainer.

use hexapod_core::amp::{amp_state, AMP_STATE_DIM};
use hexapod_core::nets::ACTOR_OUT;
use hexapod_core::obs::{
    actor_obs, proprio_noise_scale, proprio_obs, PrivilegedState, ProprioHistory, ACTOR_OBS_DIM,
    HEIGHT_SCAN_DIM, HISTORY_DIM, PRIVILEGED_DIM, PROPRIO_DIM,
};
use hexapod_core::robot::{NUM_JOINTS, Q0_RAD};
use hexapod_core::timing::{ACTION_SCALE_RAD, POLICY_DT_S};
use host_sim::vec_env::{Observations, StepResult, VecEnv};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Body velocity per rad of mean joint offset.
const VEL_GAIN: f32 = 4.0;
/// Standing height reported in the privileged and AMP states, m.
const HEIGHT_M: f32 = hexapod_core::robot::NOMINAL_BASE_HEIGHT_M;

struct Robot {
    q_off: [f32; NUM_JOINTS],
    qdot: [f32; NUM_JOINTS],
    vel: [f32; 3],
    command: [f32; 3],
    prev_action: [f32; NUM_JOINTS],
    history: ProprioHistory,
    steps: usize,
    sum_task: f32,
    sum_penalty: f32,
}

/// The point-mass environment.
pub struct PointMassEnv {
    robots: Vec<Robot>,
    episode_steps: usize,
    task_reward: bool,
    penalties: bool,
    rng: ChaCha8Rng,
    /// Commands set by [`VecEnv::set_command`], kept instead of the random ones.
    fixed_commands: Vec<Option<[f32; 3]>>,
}

impl PointMassEnv {
    /// `num_envs` robots, episodes of `episode_steps` policy steps, reward terms on or off.
    pub fn new(
        num_envs: usize,
        episode_steps: usize,
        task_reward: bool,
        penalties: bool,
        seed: u64,
    ) -> Self {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let robots = (0..num_envs).map(|_| Self::fresh(&mut rng)).collect();
        Self {
            robots,
            episode_steps,
            task_reward,
            penalties,
            rng,
            fixed_commands: vec![None; num_envs],
        }
    }

    fn fresh(rng: &mut ChaCha8Rng) -> Robot {
        let command = [
            rng.gen_range(-1.0..1.0),
            rng.gen_range(-0.5..0.5),
            rng.gen_range(-1.0..1.0),
        ];
        Robot {
            q_off: [0.0; NUM_JOINTS],
            qdot: [0.0; NUM_JOINTS],
            vel: [0.0; 3],
            command,
            prev_action: [0.0; NUM_JOINTS],
            history: ProprioHistory::filled_with(&[0.0; PROPRIO_DIM]),
            steps: 0,
            sum_task: 0.0,
            sum_penalty: 0.0,
        }
    }

    fn q(r: &Robot) -> [f32; NUM_JOINTS] {
        let mut q = Q0_RAD;
        for (qj, off) in q.iter_mut().zip(&r.q_off) {
            *qj += off;
        }
        q
    }

    fn amp(r: &Robot) -> [f32; AMP_STATE_DIM] {
        amp_state(
            &Self::q(r),
            &r.qdot,
            [r.vel[0], r.vel[1], 0.0],
            [0.0, 0.0, r.vel[2]],
            [0.0, 0.0, 1.0],
        )
    }

    fn observe_proprio(r: &mut Robot, rng: &mut ChaCha8Rng) -> [f32; PROPRIO_DIM] {
        let mut o = proprio_obs([0.0, 0.0, r.vel[2]], [0.0, 0.0, -1.0], &Self::q(r), &r.qdot);
        for (x, n) in o.iter_mut().zip(proprio_noise_scale()) {
            *x += rng.gen_range(-1.0..=1.0) * n;
        }
        o
    }

    fn observations(&mut self) -> Observations {
        let n = self.robots.len();
        let mut obs = Observations {
            actor: Vec::with_capacity(n * ACTOR_OBS_DIM),
            history: Vec::with_capacity(n * HISTORY_DIM),
            privileged: Vec::with_capacity(n * PRIVILEGED_DIM),
            heights: vec![0.05; n * HEIGHT_SCAN_DIM],
            amp: Vec::with_capacity(n * AMP_STATE_DIM),
        };
        for r in &self.robots {
            obs.actor
                .extend_from_slice(&actor_obs(r.command, &r.prev_action, r.history.newest()));
            obs.history.extend_from_slice(&r.history.flatten());
            let p = PrivilegedState {
                lin_vel_base_m_s: [r.vel[0], r.vel[1], 0.0],
                base_height_m: HEIGHT_M,
                friction: 1.0,
                ..Default::default()
            };
            obs.privileged.extend_from_slice(&p.to_obs());
            obs.amp.extend_from_slice(&Self::amp(r));
        }
        obs
    }
}

impl VecEnv for PointMassEnv {
    fn num_envs(&self) -> usize {
        self.robots.len()
    }

    fn set_command(&mut self, i: usize, command: [f32; 3]) {
        self.fixed_commands[i] = Some(command);
        self.robots[i].command = command;
    }

    fn reset(&mut self) -> Observations {
        for i in 0..self.robots.len() {
            self.robots[i] = Self::fresh(&mut self.rng);
            if let Some(c) = self.fixed_commands[i] {
                self.robots[i].command = c;
            }
            let o = Self::observe_proprio(&mut self.robots[i], &mut self.rng);
            self.robots[i].history = ProprioHistory::filled_with(&o);
        }
        self.observations()
    }

    fn step(&mut self, actions: &[f32]) -> StepResult {
        let n = self.robots.len();
        let mut res = StepResult {
            rewards: vec![0.0; n],
            dones: vec![false; n],
            time_outs: vec![false; n],
            amp_next: Vec::with_capacity(n * AMP_STATE_DIM),
            invalid_actions: vec![false; n],
            ..Default::default()
        };
        let mut finished = 0usize;
        let (mut sum_len, mut sum_task, mut sum_pen) = (0.0f32, 0.0f32, 0.0f32);
        for i in 0..n {
            let a = &actions[i * ACTOR_OUT..(i + 1) * ACTOR_OUT];
            let invalid = a.iter().any(|x| !x.is_finite());
            let r = &mut self.robots[i];
            let mut rate = 0.0f32;
            for j in 0..NUM_JOINTS {
                let aj = if invalid {
                    0.0
                } else {
                    a[j].clamp(-100.0, 100.0)
                };
                let target = ACTION_SCALE_RAD * aj;
                let new_off = r.q_off[j] + 0.5 * (target - r.q_off[j]);
                r.qdot[j] = (new_off - r.q_off[j]) / POLICY_DT_S;
                r.q_off[j] = new_off;
                rate += (aj - r.prev_action[j]).powi(2);
                r.prev_action[j] = aj;
            }
            for (k, v) in r.vel.iter_mut().enumerate() {
                let mean_off = r.q_off[6 * k..6 * k + 6].iter().sum::<f32>() / 6.0;
                *v += 0.3 * (VEL_GAIN * mean_off - *v);
            }
            let lin_err = (r.vel[0] - r.command[0]).powi(2) + (r.vel[1] - r.command[1]).powi(2);
            // Per-step terms are scaled by the policy period, as the simulator's are.
            let task = POLICY_DT_S
                * ((-lin_err / 0.15).exp()
                    + 0.5 * (-(r.vel[2] - r.command[2]).powi(2) / 0.15).exp());
            let penalty = -0.01 * rate * POLICY_DT_S;
            res.rewards[i] = if self.task_reward { task } else { 0.0 }
                + if self.penalties { penalty } else { 0.0 };
            r.sum_task += task;
            r.sum_penalty += penalty;
            r.steps += 1;
            res.amp_next.extend_from_slice(&Self::amp(r));
            let fell = r.q_off.iter().any(|x| x.abs() > 1.0);
            let timed_out = r.steps >= self.episode_steps;
            res.invalid_actions[i] = invalid;
            if fell || timed_out || invalid {
                res.dones[i] = true;
                res.time_outs[i] = timed_out && !fell && !invalid;
                finished += 1;
                sum_len += r.steps as f32;
                sum_task += r.sum_task / r.steps as f32;
                sum_pen += r.sum_penalty / r.steps as f32;
                *r = Self::fresh(&mut self.rng);
                if let Some(c) = self.fixed_commands[i] {
                    r.command = c;
                }
                let o = Self::observe_proprio(r, &mut self.rng);
                r.history = ProprioHistory::filled_with(&o);
            } else {
                let o = Self::observe_proprio(r, &mut self.rng);
                r.history.push(&o);
            }
        }
        if finished > 0 {
            let f = finished as f32;
            res.episode_log.push(("rew_task".into(), sum_task / f));
            res.episode_log.push(("rew_penalties".into(), sum_pen / f));
            res.episode_log.push(("length_steps".into(), sum_len / f));
        }
        res.obs = self.observations();
        res
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shapes_and_determinism() {
        let run = || {
            let mut env = PointMassEnv::new(3, 5, true, true, 7);
            let o = env.reset();
            assert_eq!(o.actor.len(), 3 * ACTOR_OBS_DIM);
            assert_eq!(o.history.len(), 3 * HISTORY_DIM);
            assert_eq!(o.heights.len(), 3 * HEIGHT_SCAN_DIM);
            let mut last = StepResult::default();
            for _ in 0..6 {
                last = env.step(&[0.3; 3 * ACTOR_OUT]);
            }
            assert_eq!(last.amp_next.len(), 3 * AMP_STATE_DIM);
            (last.rewards, last.obs.actor)
        };
        assert_eq!(run(), run());
    }

    #[test]
    fn time_outs_and_terminations_are_reported() {
        let mut env = PointMassEnv::new(2, 3, true, true, 1);
        env.reset();
        for _ in 0..2 {
            assert!(!env.step(&[0.0; 2 * ACTOR_OUT]).dones[0]);
        }
        let r = env.step(&[0.0; 2 * ACTOR_OUT]);
        assert!(r.dones[0] && r.time_outs[0]);
        let mut big = [0.0f32; 2 * ACTOR_OUT];
        big[0] = 20.0;
        let r = env.step(&big);
        assert!(r.dones[0] && !r.time_outs[0] && !r.dones[1]);
        let mut nan = [0.0f32; 2 * ACTOR_OUT];
        nan[ACTOR_OUT] = f32::NAN;
        let r = env.step(&nan);
        assert!(r.invalid_actions[1] && r.dones[1]);
    }
}

#[cfg(test)]
mod probe {
    use super::*;
    use rand_distr::{Distribution, Normal};

    #[test]
    fn random_actions_survive_long_episodes() {
        let mut env = PointMassEnv::new(8, 100, true, true, 3);
        env.reset();
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        let normal = Normal::new(0.0f32, 0.5).unwrap();
        let mut terminations = 0;
        for _ in 0..100 {
            let a: Vec<f32> = (0..8 * ACTOR_OUT)
                .map(|_| normal.sample(&mut rng))
                .collect();
            let r = env.step(&a);
            terminations += r
                .dones
                .iter()
                .zip(&r.time_outs)
                .filter(|(d, t)| **d && !**t)
                .count();
        }
        assert_eq!(terminations, 0);
    }
}
