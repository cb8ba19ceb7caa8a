//! One robot whose physics runs in MuJoCo while everything else is this crate's and
//! hexapod-core's: `bench/mujoco_sim2sim.py` (a child process speaking line-delimited JSON)
//! integrates the shared URDF with the same CSP drives at the same physics step, and this
//! side builds the observations ([`crate::observe`]), keeps the history, turns actions into
//! joint targets with `hexapod_core::control::action_to_targets` and applies the
//! environment's termination rule ([`crate::env::terminated`]). The sim-to-sim check of
//! `hexapod sim2sim`.
//!
//! The model is nominal: no domain randomization, no pushes, no observation noise, foot
//! friction 1, on a flat plane; the robot spawns at the world origin facing +x in the nominal
//! pose, at host-sim's spawn height. Rewards are not computed (zeros).

use crate::env::{spawn_height_m, terminated, SPAWN_HEIGHT_M};
use crate::observe;
use crate::robot::{ContactState, RobotState};
use crate::terrain::{Terrain, TerrainConfig};
use crate::urdf_model::{default_urdf_path, UrdfModel};
use crate::vec_env::{Observations, StepResult};
use anyhow::Context;
use hexapod_core::control::action_to_targets;
use hexapod_core::obs::{
    actor_obs, ProprioHistory, ACTOR_OBS_DIM, HEIGHT_SCALE, HEIGHT_SCAN_DIM, HEIGHT_SCAN_OFFSET_M,
    PROPRIO_DIM,
};
use hexapod_core::robot::{
    JOINT_NAMES, LEG_NAMES, NUM_JOINTS, NUM_LEGS, Q0_RAD, TORQUE_LIMIT_NM, VELOCITY_LIMIT_RAD_S,
};
use hexapod_core::timing::{
    CSP_KP1_PER_S, CSP_KP2_NMS_PER_RAD, DECIMATION, PHYSICS_DT_S, POLICY_DT_S,
};
use serde::Deserialize;
use std::io::{BufRead, BufReader, Read, Write};
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdin, ChildStdout, Command, Stdio};
use std::thread::JoinHandle;

/// Lines of the child's stderr quoted when it dies.
const STDERR_TAIL_LINES: usize = 8;

/// The MuJoCo side of `hexapod sim2sim`.
pub fn sim2sim_script() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../bench/mujoco_sim2sim.py")
}

/// A robot state as the child reports it (see the script's docs for frames and units).
#[derive(Debug, Deserialize)]
struct Reply {
    pos_world_m: [f32; 3],
    quat_xyzw: [f32; 4],
    lin_vel_world_m_s: [f32; 3],
    ang_vel_world_rad_s: [f32; 3],
    q_rad: [f32; NUM_JOINTS],
    qdot_rad_s: [f32; NUM_JOINTS],
    foot_force_world_n: [[f32; 3]; NUM_LEGS],
    trunk_contact: bool,
}

/// What `init` answers.
#[derive(Debug, Deserialize)]
struct Hello {
    mujoco_version: String,
}

/// One robot simulated in MuJoCo, driven like one robot of [`crate::env::HexapodEnv`]:
/// `reset` and `step` return the same observation buffers, with episodes that end by
/// termination (trunk contact, tilt, non-finite state) or time-out and reset the robot.
/// Both can fail (the child process died); the error quotes its stderr.
pub struct MujocoEnv {
    child: Child,
    stdin: Option<ChildStdin>,
    stdout: BufReader<ChildStdout>,
    stderr: Option<JoinHandle<String>>,
    python: String,
    mujoco_version: String,
    max_tilt_deg: f32,
    max_episode_steps: usize,
    spawn_pos_world_m: [f32; 3],
    command: [f32; 3],
    step: usize,
    prev_action: [f32; NUM_JOINTS],
    prev_targets: [f32; NUM_JOINTS],
    history: ProprioHistory,
    state: RobotState,
    contacts: ContactState,
}

impl MujocoEnv {
    /// Starts `python bench/mujoco_sim2sim.py` and builds the model; episodes last
    /// `episode_length_s` and end beyond `max_tilt_deg` of tilt, as in the simulator.
    pub fn new(python: &str, episode_length_s: f32, max_tilt_deg: f32) -> anyhow::Result<Self> {
        let script = sim2sim_script();
        let mut child = Command::new(python)
            .arg(&script)
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .map_err(|e| {
                anyhow::anyhow!(
                    "cannot run `{python}` ({e}): MuJoCo runs in Python 3 (pip install mujoco numpy; --python chooses the interpreter)"
                )
            })?;
        let stdin = child.stdin.take();
        let stdout = BufReader::new(child.stdout.take().expect("piped stdout"));
        let mut stderr_pipe = child.stderr.take().expect("piped stderr");
        let stderr = std::thread::spawn(move || {
            let mut text = String::new();
            let _ = stderr_pipe.read_to_string(&mut text);
            text
        });
        let flat = Terrain::generate(&TerrainConfig::default());
        let z = spawn_height_m(&flat, [0.0, 0.0], 0.0, &Q0_RAD, SPAWN_HEIGHT_M);
        let mut env = Self {
            child,
            stdin,
            stdout,
            stderr: Some(stderr),
            python: python.to_string(),
            mujoco_version: String::new(),
            max_tilt_deg,
            max_episode_steps: (episode_length_s / POLICY_DT_S).round() as usize,
            spawn_pos_world_m: [0.0, 0.0, z],
            command: [0.0; 3],
            step: 0,
            prev_action: [0.0; NUM_JOINTS],
            prev_targets: Q0_RAD,
            history: ProprioHistory::filled_with(&[0.0; PROPRIO_DIM]),
            state: RobotState::default(),
            contacts: ContactState::default(),
        };
        let urdf = default_urdf_path();
        let model = UrdfModel::load(&urdf)?;
        let hello: Hello = env.call(&serde_json::json!({
            "cmd": "init",
            "urdf": urdf.canonicalize().with_context(|| format!("resolving {}", urdf.display()))?,
            "dt_s": PHYSICS_DT_S,
            "decimation": DECIMATION,
            "armature_kg_m2": model.armature_kg_m2,
            "joint_names": JOINT_NAMES,
            "foot_geoms": LEG_NAMES.map(|leg| format!("{leg}_foot")),
            "kp1_per_s": CSP_KP1_PER_S,
            "kp2_nms_per_rad": CSP_KP2_NMS_PER_RAD,
            "velocity_limit_rad_s": VELOCITY_LIMIT_RAD_S,
            "torque_limit_nm": TORQUE_LIMIT_NM,
        }))?;
        env.mujoco_version = hello.mujoco_version;
        Ok(env)
    }

    /// Version of the child's `mujoco` package.
    pub fn mujoco_version(&self) -> &str {
        &self.mujoco_version
    }

    /// The command `(vx m/s, vy m/s, wz rad/s)` the next observations carry.
    pub fn set_command(&mut self, command: [f32; 3]) {
        self.command = command;
    }

    /// Kinematic state after the last reset or step.
    pub fn robot_state(&self) -> RobotState {
        self.state
    }

    /// Spawns the robot and returns its observations.
    pub fn reset(&mut self) -> anyhow::Result<Observations> {
        let reply: Reply = self.call(&serde_json::json!({
            "cmd": "reset",
            "pos_world_m": self.spawn_pos_world_m,
            "quat_xyzw": [0.0, 0.0, 0.0, 1.0],
            "q_rad": Q0_RAD,
        }))?;
        self.step = 0;
        self.prev_action = [0.0; NUM_JOINTS];
        self.prev_targets = Q0_RAD;
        self.absorb(reply);
        self.contacts = ContactState::default();
        self.history = ProprioHistory::filled_with(&observe::proprio(&self.state));
        Ok(self.observations())
    }

    /// Applies one action (`[18]`, the policy's raw output) for one policy step.
    pub fn step(&mut self, actions: &[f32]) -> anyhow::Result<StepResult> {
        let action: &[f32; NUM_JOINTS] = actions.try_into().map_err(|_| {
            anyhow::anyhow!(
                "MuJoCo env: {} actions for one robot of 18 joints",
                actions.len()
            )
        })?;
        let mut result = StepResult {
            rewards: vec![0.0],
            ..Default::default()
        };
        if action.iter().any(|a| !a.is_finite()) {
            result.amp_next = observe::amp(&self.state).to_vec();
            result.obs = self.reset()?;
            result.dones = vec![true];
            result.time_outs = vec![false];
            result.invalid_actions = vec![true];
            return Ok(result);
        }
        let (clipped, targets) = action_to_targets(action, &self.prev_targets);
        self.prev_targets = targets;
        let reply: Reply =
            self.call(&serde_json::json!({ "cmd": "step", "targets_rad": targets }))?;
        self.absorb(reply);
        self.step += 1;
        self.prev_action = clipped;
        let terminated = terminated(&self.state, self.contacts.trunk, self.max_tilt_deg);
        let time_out = self.step >= self.max_episode_steps;
        result.amp_next = observe::amp(&self.state).to_vec();
        result.dones = vec![terminated || time_out];
        result.time_outs = vec![time_out && !terminated];
        result.invalid_actions = vec![false];
        result.obs = if terminated || time_out {
            self.reset()?
        } else {
            self.history.push(&observe::proprio(&self.state));
            self.observations()
        };
        Ok(result)
    }

    fn absorb(&mut self, r: Reply) {
        self.state = RobotState {
            base_pos_world_m: r.pos_world_m,
            base_quat_xyzw: r.quat_xyzw,
            base_lin_vel_world_m_s: r.lin_vel_world_m_s,
            base_ang_vel_world_rad_s: r.ang_vel_world_rad_s,
            q_rad: r.q_rad,
            qdot_rad_s: r.qdot_rad_s,
        };
        // Thighs and shanks do not collide in the MuJoCo model, as they are probes in
        // host-sim's physics; their flags stay clear.
        self.contacts = ContactState {
            foot_force_world_n: r.foot_force_world_n,
            trunk: r.trunk_contact,
            ..Default::default()
        };
    }

    /// The observation buffers of the current state, laid out as the simulator's.
    fn observations(&self) -> Observations {
        let s = &self.state;
        let proprio = *self.history.newest();
        let actor = actor_obs(self.command, &self.prev_action, &proprio);
        debug_assert_eq!(actor.len(), ACTOR_OBS_DIM);
        let height_m = s.base_pos_world_m[2];
        let scan = (height_m - HEIGHT_SCAN_OFFSET_M).clamp(-1.0, 1.0) * HEIGHT_SCALE;
        Observations {
            actor: actor.to_vec(),
            history: self.history.flatten().to_vec(),
            privileged: observe::privileged(s, height_m, 1.0, &self.contacts, [0.0; 3]).to_vec(),
            heights: vec![scan; HEIGHT_SCAN_DIM],
            amp: observe::amp(s).to_vec(),
        }
    }

    /// Sends one request and reads its reply.
    fn call<T: for<'de> Deserialize<'de>>(
        &mut self,
        request: &serde_json::Value,
    ) -> anyhow::Result<T> {
        let sent = match self.stdin.as_mut() {
            Some(stdin) => writeln!(stdin, "{request}")
                .and_then(|_| stdin.flush())
                .is_ok(),
            None => false,
        };
        let mut line = String::new();
        if !sent || self.stdout.read_line(&mut line).unwrap_or(0) == 0 {
            return Err(self.died());
        }
        serde_json::from_str(&line)
            .with_context(|| format!("MuJoCo process: unreadable reply {:?}", line.trim()))
    }

    /// The error for a child that stopped answering: its exit status and stderr tail.
    fn died(&mut self) -> anyhow::Error {
        self.stdin = None;
        let status = self
            .child
            .wait()
            .map(|s| s.to_string())
            .unwrap_or_else(|e| e.to_string());
        let stderr = self
            .stderr
            .take()
            .and_then(|h| h.join().ok())
            .unwrap_or_default();
        if stderr.contains("No module named 'mujoco'") || stderr.contains("No module named 'numpy'")
        {
            return anyhow::anyhow!(
                "`{}` has no mujoco or numpy module: pip install mujoco numpy",
                self.python
            );
        }
        let lines: Vec<&str> = stderr.lines().filter(|l| !l.trim().is_empty()).collect();
        let tail = lines[lines.len().saturating_sub(STDERR_TAIL_LINES)..].join(" | ");
        let script = sim2sim_script();
        let script = script.canonicalize().unwrap_or(script);
        anyhow::anyhow!(
            "MuJoCo process ({} {}) stopped ({status}): {tail}",
            self.python,
            script.display()
        )
    }
}

impl Drop for MujocoEnv {
    fn drop(&mut self) {
        // End of input ends the script; reap it.
        self.stdin = None;
        let _ = self.child.wait();
        if let Some(h) = self.stderr.take() {
            let _ = h.join();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_missing_interpreter_is_one_clear_error() {
        let err = MujocoEnv::new("/nonexistent/python3", 20.0, 60.0)
            .err()
            .expect("no such interpreter");
        let text = err.to_string();
        assert!(
            text.contains("/nonexistent/python3") && text.contains("pip install mujoco numpy"),
            "{text}"
        );
    }
}
