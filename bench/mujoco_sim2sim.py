#!/usr/bin/env python3
"""MuJoCo physics for `hexapod sim2sim`: one robot on a flat plane, stepped by joint targets.

The policy, its observations and the action path stay in Rust; this process only
integrates. It reads one JSON object per line on stdin and answers each with one JSON
object per line on stdout:

  {"cmd": "init", <the peer's job fields: urdf, dt_s, armature_kg_m2, joint_names,
   kp1_per_s, kp2_nms_per_rad, velocity_limit_rad_s, torque_limit_nm>, "decimation": 4,
   "foot_geoms": ["rf_foot", ...]}
      -> {"mujoco_version": ..., "armature_kg_m2": ...}
  {"cmd": "reset", "pos_world_m": [3], "quat_xyzw": [4], "q_rad": [18]}   -> state
  {"cmd": "step", "targets_rad": [18]}                                    -> state

The model is bench/mujoco_peer.py's (the URDF with hexapod:armature on every hinge, the
same CSP drive law at every physics step) with host-sim's contact set: feet and trunk
collide with the ground only; thighs and shanks, which are probes in host-sim, and
robot-robot pairs do not collide. A step runs `decimation` physics steps holding the
targets. A state is {"pos_world_m", "quat_xyzw", "lin_vel_world_m_s" (base origin),
"ang_vel_world_rad_s", "q_rad", "qdot_rad_s", "foot_force_world_n" (per leg, the normal
contact force on the foot, world frame, averaged over the step's physics steps, as
host-sim averages it), "trunk_contact" (the trunk touches the ground after the step)}.
End of input ends the process.
"""
import json
import sys

import mujoco
import numpy as np

from mujoco_peer import build, csp, urdf_armature


class Robot:
    """The compiled model, its data and the indices the protocol needs."""

    def __init__(self, job):
        self.job = job
        self.model, self.data, self.qadr, self.vadr = build(job, False)
        m = self.model
        free = [j for j in range(m.njnt) if m.jnt_type[j] == mujoco.mjtJoint.mjJNT_FREE]
        if len(free) != 1:
            raise SystemExit(f"expected one free joint, found {len(free)}")
        self.base_body = int(m.jnt_bodyid[free[0]])
        self.free_qadr = int(m.jnt_qposadr[free[0]])
        self.free_vadr = int(m.jnt_dofadr[free[0]])
        self.foot_geoms = [m.geom(name).id for name in job["foot_geoms"]]
        self.trunk_geoms = {g for g in range(m.ngeom) if m.geom_bodyid[g] == self.base_body}
        ground = {g for g in range(m.ngeom) if m.geom_bodyid[g] == 0}
        for g in range(m.ngeom):
            if g in ground:
                continue
            solid = g in self.trunk_geoms or g in self.foot_geoms
            # Robot geoms reach only the ground (contype & the ground's conaffinity).
            m.geom_contype[g] = 1 if solid else 0
            m.geom_conaffinity[g] = 0
        self.ground = ground
        self.decimation = int(job["decimation"])

    def reset(self, pos, quat_xyzw, q):
        d = self.data
        mujoco.mj_resetData(self.model, d)
        a = self.free_qadr
        d.qpos[a:a + 3] = pos
        d.qpos[a + 3:a + 7] = [quat_xyzw[3], quat_xyzw[0], quat_xyzw[1], quat_xyzw[2]]
        d.qpos[self.qadr] = q
        mujoco.mj_forward(self.model, d)
        return self.state(np.zeros((len(self.foot_geoms), 3)))

    def foot_forces(self):
        """Normal contact force on each foot from the ground, world frame, N."""
        forces = np.zeros((len(self.foot_geoms), 3))
        f6 = np.zeros(6)
        for i in range(self.data.ncon):
            c = self.data.contact[i]
            for leg, g in enumerate(self.foot_geoms):
                if g not in (c.geom1, c.geom2):
                    continue
                mujoco.mj_contactForce(self.model, self.data, i, f6)
                # The contact frame's normal points from geom1 to geom2; the force acts on
                # geom2 along it.
                sign = 1.0 if c.geom2 == g else -1.0
                forces[leg] += sign * f6[0] * np.asarray(c.frame[0:3])
        return forces

    def trunk_contact(self):
        for i in range(self.data.ncon):
            c = self.data.contact[i]
            if c.dist <= 0.0 and (c.geom1 in self.trunk_geoms or c.geom2 in self.trunk_geoms):
                return True
        return False

    def step(self, targets):
        qd = np.asarray(targets, dtype=np.float64)
        forces = np.zeros((len(self.foot_geoms), 3))
        d = self.data
        for _ in range(self.decimation):
            tau = csp(self.job, qd, d.qpos[self.qadr], d.qvel[self.vadr])
            d.qfrc_applied[:] = 0.0
            d.qfrc_applied[self.vadr] = tau
            mujoco.mj_step(self.model, d)
            forces += self.foot_forces() / self.decimation
        return self.state(forces)

    def state(self, forces):
        d = self.data
        a, v = self.free_qadr, self.free_vadr
        w, x, y, z = d.qpos[a + 3:a + 7]
        # A free joint's qvel: linear velocity of the body origin in the world frame, then
        # angular velocity in the body frame.
        rot = d.xmat[self.base_body].reshape(3, 3)
        ang_world = rot @ d.qvel[v + 3:v + 6]
        return {
            "pos_world_m": d.qpos[a:a + 3].tolist(),
            "quat_xyzw": [x, y, z, w],
            "lin_vel_world_m_s": d.qvel[v:v + 3].tolist(),
            "ang_vel_world_rad_s": ang_world.tolist(),
            "q_rad": d.qpos[self.qadr].tolist(),
            "qdot_rad_s": d.qvel[self.vadr].tolist(),
            "foot_force_world_n": forces.tolist(),
            "trunk_contact": self.trunk_contact(),
        }


def main():
    robot = None
    for line in sys.stdin:
        if not line.strip():
            continue
        msg = json.loads(line)
        cmd = msg.get("cmd")
        if cmd == "init":
            robot = Robot(msg)
            out = {"mujoco_version": mujoco.__version__, "armature_kg_m2": urdf_armature(msg)}
        elif robot is None:
            raise SystemExit(f"'{cmd}' before 'init'")
        elif cmd == "reset":
            out = robot.reset(msg["pos_world_m"], msg["quat_xyzw"], msg["q_rad"])
        elif cmd == "step":
            out = robot.step(msg["targets_rad"])
        else:
            raise SystemExit(f"unknown command {cmd!r}")
        sys.stdout.write(json.dumps(out) + "\n")
        sys.stdout.flush()


if __name__ == "__main__":
    main()
