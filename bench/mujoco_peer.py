#!/usr/bin/env python3
"""MuJoCo peer for host-sim: the same URDF, dt, drive law and scripted gait.

Reads a JSON job written by `hexapod-sim bench` or host-sim's fidelity test (nominal pose,
one period of gait joint targets at the physics rate, drive gains and limits, an optional
heightfield) and prints one JSON object: physics steps/s on flat ground and on the
heightfield, mean contact counts, and the fidelity figures (standing base height and joint
torques with noslip on; base displacement and the loaded feet's sliding speed under the
scripted gait, and the yaw turned by a turning gait in place).
"""
import json
import sys
import time
import xml.etree.ElementTree as ET

import mujoco
import numpy as np


def urdf_armature(job):
    """The drives' armature: `hexapod:armature` on the URDF's <robot>. MuJoCo's URDF import
    reads no armature, so build() sets it on every hinge; it must equal what host-sim read."""
    root = ET.parse(job["urdf"]).getroot()
    armature = float(root.attrib["{hexapod}armature"])
    if abs(armature - job["armature_kg_m2"]) > 1e-9:
        raise SystemExit(f"hexapod:armature {armature} differs from the job's {job['armature_kg_m2']}")
    return armature


def build(job, with_hfield):
    spec = mujoco.MjSpec.from_file(job["urdf"])
    spec.option.timestep = job["dt_s"]
    spec.option.gravity = [0.0, 0.0, -9.81]
    root = spec.worldbody.first_body()
    root.add_freejoint()
    armature = urdf_armature(job)
    for j in spec.joints:
        if j.type == mujoco.mjtJoint.mjJNT_HINGE:
            j.armature = armature
    if with_hfield:
        hf = job["hfield"]
        heights = np.array(hf["heights_m"], dtype=np.float64).reshape(hf["nrow"], hf["ncol"])
        lo, hi = float(heights.min()), float(heights.max())
        span = max(hi - lo, 1e-3)
        spec.add_hfield(name="terrain", size=[hf["half_x_m"], hf["half_y_m"], span, 0.1],
                        nrow=hf["nrow"], ncol=hf["ncol"],
                        userdata=((heights - lo) / span).flatten().tolist())
        spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_HFIELD, hfieldname="terrain",
                                pos=[0.0, 0.0, lo])
    else:
        spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_PLANE, size=[0.0, 0.0, 1.0])
    model = spec.compile()
    data = mujoco.MjData(model)
    names = job["joint_names"]
    qadr = np.array([model.jnt_qposadr[model.joint(n).id] for n in names])
    vadr = np.array([model.jnt_dofadr[model.joint(n).id] for n in names])
    if not np.allclose(model.dof_armature[vadr], armature):
        raise SystemExit(f"compiled joint armature {model.dof_armature[vadr]} is not {armature}")
    return model, data, qadr, vadr


def reset(model, data, qadr, job, z0):
    mujoco.mj_resetData(model, data)
    data.qpos[0:3] = [0.0, 0.0, z0]
    data.qpos[3:7] = [1.0, 0.0, 0.0, 0.0]
    data.qpos[qadr] = job["q0_rad"]
    mujoco.mj_forward(model, data)


def csp(job, qd, q, qdot):
    vel = np.clip(job["kp1_per_s"] * (qd - q), -np.array(job["velocity_limit_rad_s"]), job["velocity_limit_rad_s"])
    tau = job["kp2_nms_per_rad"] * (vel - qdot)
    lim = np.array(job["torque_limit_nm"])
    return np.clip(tau, -lim, lim)


def step(model, data, qadr, vadr, job, qd):
    tau = csp(job, qd, data.qpos[qadr], data.qvel[vadr])
    data.qfrc_applied[:] = 0.0
    data.qfrc_applied[vadr] = tau
    mujoco.mj_step(model, data)
    return tau


def foot_geoms(model):
    """The six foot spheres (the URDF's only sphere geoms)."""
    feet = [g for g in range(model.ngeom) if model.geom_type[g] == mujoco.mjtGeom.mjGEOM_SPHERE]
    if len(feet) != 6:
        raise SystemExit(f"expected 6 foot spheres, found {len(feet)}")
    return feet


def loaded_feet(model, data, feet):
    """Whether each foot carries more than 20 N (normal contact force)."""
    normal_n = np.zeros(len(feet))
    wrench = np.zeros(6)
    for c in range(data.ncon):
        con = data.contact[c]
        for i, g in enumerate(feet):
            if g in (con.geom[0], con.geom[1]):
                mujoco.mj_contactForce(model, data, c, wrench)
                normal_n[i] += abs(wrench[0])
    return normal_n > 20.0


def heading_rad(quat_wxyz):
    """Yaw about the world's vertical of a base orientation (MuJoCo's w, x, y, z order)."""
    w, x, y, z = quat_wxyz
    return float(np.arctan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z)))


def timed_walk(model, data, qadr, vadr, job, steps):
    targets = np.array(job["gait_targets_rad"])
    q0 = np.array(job["q0_rad"])
    for _ in range(job["settle_steps"]):
        step(model, data, qadr, vadr, job, q0)
    contacts = 0
    start = time.thread_time()  # CPU time of this thread, as host-sim's benchmark measures
    for k in range(steps):
        step(model, data, qadr, vadr, job, targets[k % len(targets)])
        contacts += data.ncon
    elapsed = time.thread_time() - start
    return steps / elapsed, contacts / steps


def main():
    job = json.load(open(sys.argv[1]))
    out = {"mujoco_version": mujoco.__version__, "armature_kg_m2": urdf_armature(job)}
    # Fidelity: stand with noslip on (MuJoCo's soft friction otherwise lets loaded feet creep).
    model, data, qadr, vadr = build(job, False)
    model.opt.noslip_iterations = 10
    reset(model, data, qadr, job, job["spawn_height_m"])
    q0 = np.array(job["q0_rad"])
    tau = None
    for _ in range(job["stand_steps"]):
        tau = step(model, data, qadr, vadr, job, q0)
    out["stand_height_m"] = float(data.qpos[2])
    out["stand_torque_nm"] = [float(t) for t in tau]
    targets = np.array(job["gait_targets_rad"])
    x0 = data.qpos[0:2].copy()
    # After mj_step, geom_xpos and the contact forces are those of the step's start: the
    # motion from one call to the next is paired with the loads measured at its start.
    feet = foot_geoms(model)
    feet_before, loaded_before = data.geom_xpos[feet].copy(), None
    slide_m_s = []
    for k in range(job["walk_steps"]):
        step(model, data, qadr, vadr, job, targets[k % len(targets)])
        loaded = loaded_feet(model, data, feet)
        if loaded_before is not None:
            moved = data.geom_xpos[feet][:, 0:2] - feet_before[:, 0:2]
            slide_m_s += [float(np.linalg.norm(moved[i]) / job["dt_s"])
                          for i in range(len(feet)) if loaded_before[i]]
        feet_before, loaded_before = data.geom_xpos[feet].copy(), loaded
    if not slide_m_s:
        raise SystemExit("no loaded foot in the scripted walk")
    out["walk_displacement_m"] = [float(v) for v in data.qpos[0:2] - x0]
    out["walk_loaded_foot_speed_m_s"] = [float(np.median(slide_m_s)), float(np.percentile(slide_m_s, 90))]
    out["walk_height_m"] = float(data.qpos[2])
    # Fidelity of a turn: stand again, then the turning gait in place; the yaw turned.
    reset(model, data, qadr, job, job["spawn_height_m"])
    for _ in range(job["stand_steps"]):
        step(model, data, qadr, vadr, job, q0)
    turn_targets = np.array(job["turn_targets_rad"])
    last, turned = heading_rad(data.qpos[3:7]), 0.0
    for k in range(job["walk_steps"]):
        step(model, data, qadr, vadr, job, turn_targets[k % len(turn_targets)])
        h = heading_rad(data.qpos[3:7])
        turned += (h - last + np.pi) % (2.0 * np.pi) - np.pi
        last = h
    out["turn_yaw_rad"] = float(turned)
    # Fidelity on the heightfield: the same stand and walk from the tile's centre.
    if "hfield" in job:
        model, data, qadr, vadr = build(job, True)
        model.opt.noslip_iterations = 10
        z0 = job["hfield"]["center_height_m"]
        reset(model, data, qadr, job, job["spawn_height_m"] + z0)
        for _ in range(job["stand_steps"]):
            step(model, data, qadr, vadr, job, q0)
        x0 = data.qpos[0:2].copy()
        heights, contacts = [], 0
        for k in range(job["walk_steps"]):
            step(model, data, qadr, vadr, job, targets[k % len(targets)])
            heights.append(data.qpos[2] - z0)
            contacts += data.ncon
        out["terrain_walk_displacement_m"] = [float(v) for v in data.qpos[0:2] - x0]
        out["terrain_walk_mean_height_m"] = float(np.mean(heights))
        out["terrain_walk_contacts"] = contacts / job["walk_steps"]
    # Speed: default solver settings.
    if job.get("speed_steps", 0) > 0:
        model, data, qadr, vadr = build(job, False)
        reset(model, data, qadr, job, job["spawn_height_m"])
        out["flat_steps_per_s"], out["flat_contacts"] = timed_walk(model, data, qadr, vadr, job, job["speed_steps"])
        if "hfield" in job:
            model, data, qadr, vadr = build(job, True)
            reset(model, data, qadr, job, job["spawn_height_m"] + job["hfield"]["center_height_m"])
            out["terrain_steps_per_s"], out["terrain_contacts"] = timed_walk(model, data, qadr, vadr, job, job["speed_steps"])
    print(json.dumps(out))


if __name__ == "__main__":
    main()
