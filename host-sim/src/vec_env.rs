//! The narrow seam between simulator and learner, in the manner of rsl_rl's `VecEnv`.
//!
//! Every buffer is row-major `[num_envs, dim]` in one flat `Vec<f32>`; the dimensions come
//! from `hexapod_core::obs` and `hexapod_core::amp`. Actions are `[num_envs, 18]` in joint
//! order, unscaled policy outputs (`q_d = q0 + ACTION_SCALE_RAD * a`).

use hexapod_core::obs::{ACTOR_COMMAND, ACTOR_OBS_DIM, COMMAND_SCALE};

/// Observations of all robots after a reset or a step.
#[derive(Clone, Debug, Default)]
pub struct Observations {
    /// Actor observation `[N, 63]`: command, previous action, o^p (with noise).
    pub actor: Vec<f32>,
    /// Proprioceptive history `[N, 210]`, oldest first (with noise).
    pub history: Vec<f32>,
    /// Privileged state s^p `[N, 42]` (critic only, noise free).
    pub privileged: Vec<f32>,
    /// Terrain heights i^e `[N, 187]` (critic only).
    pub heights: Vec<f32>,
    /// AMP state `[N, 61]` of the current instant (noise free).
    pub amp: Vec<f32>,
}

impl Observations {
    /// Writes `command` (vx m/s, vy m/s, wz rad/s) into robot `i`'s actor observation: for
    /// observations already returned when [`VecEnv::set_command`] changes a command.
    pub fn set_command(&mut self, i: usize, command: [f32; 3]) {
        let row = &mut self.actor[i * ACTOR_OBS_DIM..(i + 1) * ACTOR_OBS_DIM];
        for k in 0..3 {
            row[ACTOR_COMMAND.start + k] = command[k] * COMMAND_SCALE[k];
        }
    }
}

/// What one policy step returns.
#[derive(Clone, Debug, Default)]
pub struct StepResult {
    /// Observations after the step (after the reset, for robots that were reset).
    pub obs: Observations,
    /// Task and regularization reward `[N]`, each term already multiplied by the policy
    /// period (legged_gym's convention). The style reward is the learner's (it owns the
    /// discriminator) and should be weighted by the policy period the same way.
    pub rewards: Vec<f32>,
    /// `[N]` true where the episode ended (termination or time-out) and the robot was reset.
    pub dones: Vec<bool>,
    /// `[N]` true where the episode ended by time-out only (bootstrap the value).
    pub time_outs: Vec<bool>,
    /// AMP state `[N, 61]` reached by this step, taken before any reset: with the previous
    /// step's `obs.amp` it forms the policy transition (s_t, s_t+1) the discriminator sees.
    pub amp_next: Vec<f32>,
    /// `[N]` true where the actions contained NaN or infinity (those robots were reset).
    pub invalid_actions: Vec<bool>,
    /// Means over the robots that finished an episode in this step: `rew_<term>` (sum over
    /// the episode / episode length in s), `episode_length_s`, `terrain_level`.
    pub episode_log: Vec<(String, f32)>,
}

/// A batch of simulated robots.
pub trait VecEnv {
    /// Number of robots.
    fn num_envs(&self) -> usize;
    /// Resets all robots and returns their observations.
    fn reset(&mut self) -> Observations;
    /// Applies `actions` (`[N, 18]`) for one policy step (decimation physics steps).
    fn step(&mut self, actions: &[f32]) -> StepResult;
    /// Fixes robot `i`'s command (vx m/s, vy m/s, wz rad/s) from now on (play, evaluation):
    /// it is no longer resampled, on resets neither, and the robot's rewards and the
    /// observations of the next `step` or `reset` carry it. Observations already returned
    /// keep the old command ([`Observations::set_command`] rewrites them).
    fn set_command(&mut self, i: usize, command: [f32; 3]);
    /// Moves each robot's episode clock to a random step of its episode (rsl_rl's
    /// `init_at_random_ep_len`), so that the running episodes time out, get pushed and
    /// resample their commands at different moments instead of all at once; later episodes
    /// start at 0 as usual. The default ignores it (the trainer's point-mass stand-in).
    fn randomize_episode_clocks(&mut self) {}
    /// Each robot's terrain tile (curriculum row, column) when the robots walk on terrain
    /// tiles, for a checkpoint to carry the curriculum; `None` otherwise (the default).
    fn terrain_tiles(&self) -> Option<Vec<[usize; 2]>> {
        None
    }
    /// Puts each robot on its tile of `tiles` from its next reset on (a resumed run's
    /// curriculum). The default ignores it.
    fn set_terrain_tiles(&mut self, _tiles: &[[usize; 2]]) {}
    /// Reference states that episodes may start from (reference state initialization);
    /// environments without it ignore them.
    fn set_reference_states(
        &mut self,
        _states: std::sync::Arc<[crate::reference::ReferenceStart]>,
    ) {
    }
}
