//! One simulated robot in its own rapier world: the URDF multibody on the ground, the
//! joint drives (CSP law at the physics rate), state read-out, contacts and collisions.
//!
//! Solver contacts are made by the feet and the trunk (which rests on the ground when the
//! drives are off). The thigh and shank collision shapes of the URDF are taken out of the
//! rapier world and kept as probes: once per policy step they, and the trunk, are tested
//! against the ground shape for the collision flags (penalties, trunk termination), so they
//! cost nothing in the physics steps in between.

use crate::foot_contact::FootGroundContacts;
use crate::urdf_model::UrdfModel;
use hexapod_core::robot::{
    JOINT_NAMES, NUM_JOINTS, NUM_LEGS, Q_MAX_RAD, Q_MIN_RAD, TORQUE_LIMIT_NM, VELOCITY_LIMIT_RAD_S,
};
use hexapod_core::timing::{csp_torque_nm, CSP_KP1_PER_S, CSP_KP2_NMS_PER_RAD, PHYSICS_DT_S};
use rapier3d::prelude::*;
use rapier3d_urdf::{UrdfLoaderOptions, UrdfMultibodyOptions, UrdfRobot, UrdfRobotHandles};

/// Per-robot physical parameters that domain randomization changes.
#[derive(Clone, Debug)]
pub struct DriveParams {
    /// Position loop gain per joint, 1/s.
    pub kp1_per_s: [f32; NUM_JOINTS],
    /// Velocity loop gain per joint, N m s/rad.
    pub kp2_nms_per_rad: [f32; NUM_JOINTS],
    /// Motor strength factor per joint.
    pub motor_strength: [f32; NUM_JOINTS],
}

impl Default for DriveParams {
    fn default() -> Self {
        Self {
            kp1_per_s: [CSP_KP1_PER_S; NUM_JOINTS],
            kp2_nms_per_rad: [CSP_KP2_NMS_PER_RAD; NUM_JOINTS],
            motor_strength: [1.0; NUM_JOINTS],
        }
    }
}

/// The kinematic state of the robot.
#[derive(Clone, Copy, Debug, Default)]
pub struct RobotState {
    /// Base position, world, m.
    pub base_pos_world_m: [f32; 3],
    /// Base orientation, world, quaternion (x, y, z, w).
    pub base_quat_xyzw: [f32; 4],
    /// Base linear velocity, world, m/s.
    pub base_lin_vel_world_m_s: [f32; 3],
    /// Base angular velocity, world, rad/s.
    pub base_ang_vel_world_rad_s: [f32; 3],
    /// Joint angles, rad.
    pub q_rad: [f32; NUM_JOINTS],
    /// Joint velocities, rad/s.
    pub qdot_rad_s: [f32; NUM_JOINTS],
}

/// Contacts and collisions after a physics step.
#[derive(Clone, Copy, Debug, Default)]
pub struct ContactState {
    /// Ground reaction force on each foot, world, N: the normal (non-friction) part, so on
    /// sloped ground its vertical component is below the foot's share of the weight.
    pub foot_force_world_n: [[f32; 3]; NUM_LEGS],
    /// Trunk touches the ground.
    pub trunk: bool,
    /// Each thigh touches the ground.
    pub thighs: [bool; NUM_LEGS],
    /// Each shank (above the foot) touches the ground.
    pub shanks: [bool; NUM_LEGS],
}

/// Stiffness of a joint's mechanical stop beyond its limit, N m/rad.
pub const JOINT_STOP_STIFFNESS_NM_PER_RAD: f32 = 500.0;
/// Damping of a joint's mechanical stop while beyond its limit, N m s/rad.
pub const JOINT_STOP_DAMPING_NMS_PER_RAD: f32 = 5.0;

/// Torque of the mechanical stop of joint `j`: zero inside the URDF limits, a stiff damped
/// spring beyond them (explicit; stable at the 5 ms step with the drives' armature).
pub fn joint_stop_torque_nm(j: usize, q_rad: f32, qdot_rad_s: f32) -> f32 {
    let over = if q_rad > Q_MAX_RAD[j] {
        q_rad - Q_MAX_RAD[j]
    } else if q_rad < Q_MIN_RAD[j] {
        q_rad - Q_MIN_RAD[j]
    } else {
        return 0.0;
    };
    -JOINT_STOP_STIFFNESS_NM_PER_RAD * over - JOINT_STOP_DAMPING_NMS_PER_RAD * qdot_rad_s
}

/// The world pose of one link of the robot.
#[derive(Clone, Copy, Debug)]
pub struct LinkPose<'a> {
    /// The URDF link name (`base`, `rf_coxa`, `rf_thigh`, `rf_shank`, ...).
    pub name: &'a str,
    /// Position of the link frame, world, m.
    pub pos_world_m: [f32; 3],
    /// Orientation of the link frame, world, quaternion (x, y, z, w).
    pub quat_world_xyzw: [f32; 4],
}

/// The geometry of a collision shape, in its own frame (parry's conventions).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LinkShapeKind {
    /// A box centred on its frame's origin.
    Cuboid {
        /// Half the side lengths along x, y, z, m.
        half_extents_m: [f32; 3],
    },
    /// A cylinder centred on its frame's origin, its axis along y.
    Cylinder {
        /// Half the length along y, m.
        half_height_m: f32,
        /// Radius, m.
        radius_m: f32,
    },
    /// A capsule around the segment from `a_m` to `b_m`.
    Capsule {
        /// One end of the axis, m.
        a_m: [f32; 3],
        /// The other end of the axis, m.
        b_m: [f32; 3],
        /// Radius, m.
        radius_m: f32,
    },
    /// A sphere centred on its frame's origin.
    Ball {
        /// Radius, m.
        radius_m: f32,
    },
}

/// A collision shape of the robot as the simulator has it (solid or probe), placed on its
/// link: what a 3D replay draws.
#[derive(Clone, Copy, Debug)]
pub struct LinkShape {
    /// Index of the link in [`RobotWorld::link_poses`].
    pub link: usize,
    /// Position of the shape's frame in the link frame, m.
    pub pos_link_m: [f32; 3],
    /// Orientation of the shape's frame in the link frame, quaternion (x, y, z, w).
    pub quat_link_xyzw: [f32; 4],
    /// The shape.
    pub kind: LinkShapeKind,
}

/// A link shape kept out of the physics and tested against the ground on demand.
struct Probe {
    body: RigidBodyHandle,
    local_pose: Pose,
    shape: SharedShape,
}

/// A robot in its own physics world.
pub struct RobotWorld {
    world: PhysicsWorld,
    base: RigidBodyHandle,
    link_of_joint: [usize; NUM_JOINTS],
    dof_of_joint: [usize; NUM_JOINTS],
    child_body: [RigidBodyHandle; NUM_JOINTS],
    parent_body: [RigidBodyHandle; NUM_JOINTS],
    axis_local: [Vector; NUM_JOINTS],
    feet: [ColliderHandle; NUM_LEGS],
    /// Trunk, thighs (6), shanks (6): shapes tested against the ground on demand.
    probes: Vec<Probe>,
    ground: ColliderHandle,
    /// Keeps one contact per foot on a heightfield.
    foot_contacts: FootGroundContacts,
    link_bodies: Vec<RigidBodyHandle>,
    /// URDF link names, in the order of `link_bodies`.
    link_names: Vec<String>,
    nominal_mass: Vec<MassProperties>,
    /// Drive parameters (randomized per episode in training).
    pub drives: DriveParams,
    /// Last applied joint torques, N m.
    pub torque_nm: [f32; NUM_JOINTS],
}

/// Why a robot world could not be built.
#[derive(Debug, thiserror::Error)]
pub enum BuildError {
    /// The URDF does not have the structure the simulator expects.
    #[error("{path}: {message}")]
    Structure {
        /// The URDF file.
        path: String,
        /// What is missing.
        message: String,
    },
}

/// The URDF's colliders the simulator treats apart: trunk, feet, thighs, shanks.
struct LinkColliders {
    base: RigidBodyHandle,
    trunk: ColliderHandle,
    feet: [ColliderHandle; NUM_LEGS],
    thighs: [ColliderHandle; NUM_LEGS],
    shanks: [ColliderHandle; NUM_LEGS],
}

/// Each joint's bodies and axis, in joint order.
struct JointBodies {
    child_body: [RigidBodyHandle; NUM_JOINTS],
    parent_body: [RigidBodyHandle; NUM_JOINTS],
    axis_local: [Vector; NUM_JOINTS],
}

fn structure_error(model: &UrdfModel, message: String) -> BuildError {
    BuildError::Structure {
        path: model.path.display().to_string(),
        message,
    }
}

/// An empty world: gravity, the physics time step and the solver settings.
fn physics_world(solver_iterations: usize) -> PhysicsWorld {
    let mut world = PhysicsWorld::new();
    world.gravity = Vector::new(0.0, 0.0, -9.81);
    world.integration_parameters.dt = PHYSICS_DT_S;
    world.integration_parameters.num_solver_iterations = solver_iterations;
    // Speculative contacts within 1 cm (default 2 cm): a foot moves at most a few mm per
    // 5 ms step, and the heightfield then yields fewer contact points (about 16 instead of 27).
    world.integration_parameters.normalized_prediction_distance = 0.01;
    // Friction in both passes of each substep (`RobotWorld::set_friction_in_bias_pass`).
    world.integration_parameters.friction_in_bias_pass = true;
    // No continuous collision detection. rapier sweeps every body that moves more than half
    // its thinnest extent in a step against the fixed colliders; for a robot whose solve
    // blew up that sweep covers the whole terrain heightfield, millions of triangles per
    // step (a training stalled in it for minutes). The feet move millimetres per 5 ms step
    // and the speculative margin above finds their contacts; MuJoCo has no CCD either.
    world.integration_parameters.max_ccd_substeps = 0;
    world
}

/// Inserts the URDF's links and joints as one multibody without self-contacts.
fn insert_urdf(
    world: &mut PhysicsWorld,
    model: &UrdfModel,
) -> UrdfRobotHandles<Option<MultibodyJointHandle>> {
    let options = UrdfLoaderOptions {
        enable_joint_collisions: false,
        ..Default::default()
    };
    let urdf = UrdfRobot::from_robot(&model.robot, options, std::path::Path::new("."));
    urdf.insert_using_multibody_joints(
        &mut world.bodies,
        &mut world.colliders,
        &mut world.multibody_joints,
        UrdfMultibodyOptions::DISABLE_SELF_CONTACTS,
    )
}

/// Finds the base with its trunk shape and each leg's thigh, shank and foot shapes.
fn find_link_colliders(
    model: &UrdfModel,
    world: &PhysicsWorld,
    handles: &UrdfRobotHandles<Option<MultibodyJointHandle>>,
) -> Result<LinkColliders, BuildError> {
    let structure = |message: String| structure_error(model, message);
    let link_index = |name: &str| model.robot.links.iter().position(|l| l.name == name);
    let base_link = link_index("base").ok_or_else(|| structure("no link `base`".into()))?;
    let base = handles.links[base_link].body;
    let trunk = *handles.links[base_link]
        .colliders
        .first()
        .map(|c| &c.handle)
        .ok_or_else(|| structure("link `base` has no collision shape".into()))?;
    let mut feet = [trunk; NUM_LEGS];
    let mut thighs = [trunk; NUM_LEGS];
    let mut shanks = [trunk; NUM_LEGS];
    for leg in 0..NUM_LEGS {
        let thigh_link =
            &handles.links[link_index(&format!("{}_thigh", hexapod_core::robot::LEG_NAMES[leg]))
                .ok_or_else(|| structure(format!("no thigh link for leg {leg}")))?];
        let shank_link =
            &handles.links[link_index(&format!("{}_shank", hexapod_core::robot::LEG_NAMES[leg]))
                .ok_or_else(|| structure(format!("no shank link for leg {leg}")))?];
        thighs[leg] = thigh_link
            .colliders
            .first()
            .map(|c| c.handle)
            .ok_or_else(|| structure(format!("leg {leg}: thigh has no collision shape")))?;
        let mut foot = None;
        let mut shank = None;
        for c in &shank_link.colliders {
            if world.colliders[c.handle].shape().as_ball().is_some() {
                foot = Some(c.handle);
            } else {
                shank = Some(c.handle);
            }
        }
        feet[leg] =
            foot.ok_or_else(|| structure(format!("leg {leg}: shank has no foot sphere")))?;
        shanks[leg] =
            shank.ok_or_else(|| structure(format!("leg {leg}: shank has no cylinder")))?;
    }
    Ok(LinkColliders {
        base,
        trunk,
        feet,
        thighs,
        shanks,
    })
}

/// Finds each joint of [`JOINT_NAMES`] in the URDF: its child and parent bodies and its axis.
fn find_joint_bodies(
    model: &UrdfModel,
    handles: &UrdfRobotHandles<Option<MultibodyJointHandle>>,
    base: RigidBodyHandle,
) -> Result<JointBodies, BuildError> {
    let mut bodies = JointBodies {
        child_body: [base; NUM_JOINTS],
        parent_body: [base; NUM_JOINTS],
        axis_local: [Vector::X; NUM_JOINTS],
    };
    for (j, name) in JOINT_NAMES.iter().enumerate() {
        let ji = model
            .robot
            .joints
            .iter()
            .position(|jt| jt.name == *name)
            .ok_or_else(|| structure_error(model, format!("no joint `{name}`")))?;
        let h = &handles.joints[ji];
        bodies.child_body[j] = h.link2;
        bodies.parent_body[j] = h.link1;
        let axis = &model.robot.joints[ji].axis.xyz;
        bodies.axis_local[j] = Vector::new(axis[0] as f32, axis[1] as f32, axis[2] as f32);
    }
    Ok(bodies)
}

/// Feet and trunk stay solid; thigh and shank shapes leave the physics and become probes
/// (trunk first, then thighs, then shanks). The trunk costs the solver nothing while it is
/// clear of the ground, and it lets an unpowered robot rest on its belly.
fn make_probes(
    model: &UrdfModel,
    world: &mut PhysicsWorld,
    links: &LinkColliders,
) -> Result<Vec<Probe>, BuildError> {
    let structure = |message: String| structure_error(model, message);
    let mut probes = Vec::with_capacity(1 + 2 * NUM_LEGS);
    let trunk_collider = &world.colliders[links.trunk];
    probes.push(Probe {
        body: links.base,
        local_pose: trunk_collider
            .position_wrt_parent()
            .copied()
            .unwrap_or(Pose::IDENTITY),
        shape: trunk_collider.shared_shape().clone(),
    });
    for handle in links.thighs.into_iter().chain(links.shanks) {
        let collider = world
            .colliders
            .remove(
                handle,
                &mut world.islands,
                &mut world.bodies,
                &mut world.soft_bodies,
                false,
            )
            .ok_or_else(|| structure("collision shape vanished".into()))?;
        probes.push(Probe {
            body: collider
                .parent()
                .ok_or_else(|| structure("collision shape without a link".into()))?,
            local_pose: collider
                .position_wrt_parent()
                .copied()
                .unwrap_or(Pose::IDENTITY),
            shape: collider.shared_shape().clone(),
        });
    }
    Ok(probes)
}

/// Friction and restitution of the solid shapes: trunk 0.8; feet 1.0, multiplied with the
/// ground's, without bounce.
fn set_contact_materials(world: &mut PhysicsWorld, links: &LinkColliders) {
    world.colliders[links.trunk].set_friction(0.8);
    for handle in links.feet {
        let c = &mut world.colliders[handle];
        c.set_friction(1.0);
        c.set_friction_combine_rule(CoefficientCombineRule::Multiply);
        c.set_restitution(0.0);
    }
}

/// Maps joints to multibody links and generalized coordinates (returned in that order) and
/// sets each joint's armature, no damping and no limit constraint.
fn configure_joints(
    model: &UrdfModel,
    world: &mut PhysicsWorld,
    base: RigidBodyHandle,
    child_body: &[RigidBodyHandle; NUM_JOINTS],
) -> Result<([usize; NUM_JOINTS], [usize; NUM_JOINTS]), BuildError> {
    let structure = |message: String| structure_error(model, message);
    let link_id = world
        .multibody_joints
        .rigid_body_link(base)
        .ok_or_else(|| structure("base is not in a multibody".into()))?;
    let mb_index = link_id.multibody;
    let mut link_of_joint = [0; NUM_JOINTS];
    let mut dof_of_joint = [0; NUM_JOINTS];
    let mb = world
        .multibody_joints
        .get_multibody_mut(mb_index)
        .ok_or_else(|| structure("no multibody".into()))?;
    for j in 0..NUM_JOINTS {
        let link = mb
            .links()
            .position(|l| l.rigid_body_handle() == child_body[j])
            .ok_or_else(|| structure(format!("joint {} not in multibody", JOINT_NAMES[j])))?;
        link_of_joint[j] = link;
        dof_of_joint[j] = mb.link(link).map(|l| l.assembly_id()).unwrap_or(0);
    }
    for j in 0..NUM_JOINTS {
        mb.armature_mut()[dof_of_joint[j]] = model.armature_kg_m2;
        mb.damping_mut()[dof_of_joint[j]] = 0.0;
        // Joint stops are modelled in `joint_stop_torque_nm` (explicit, only when
        // beyond a limit): rapier's limit constraint would cost a mass-matrix solve per
        // joint per step even far from the limit.
        if let Some(link) = mb.link_mut(link_of_joint[j]) {
            link.joint.data.limit_axes = JointAxesMask::empty();
        }
    }
    Ok((link_of_joint, dof_of_joint))
}

/// Every link's body with its mass properties as the URDF's shapes give them (the nominal
/// masses that domain randomization scales).
fn nominal_masses(
    world: &mut PhysicsWorld,
    handles: &UrdfRobotHandles<Option<MultibodyJointHandle>>,
) -> (Vec<RigidBodyHandle>, Vec<MassProperties>) {
    let link_bodies: Vec<RigidBodyHandle> = handles.links.iter().map(|l| l.body).collect();
    let mut nominal_mass = Vec::with_capacity(link_bodies.len());
    for h in &link_bodies {
        let rb = &mut world.bodies[*h];
        rb.recompute_mass_properties_from_colliders(&world.colliders);
        nominal_mass.push(rb.mass_properties().local_mprops);
    }
    (link_bodies, nominal_mass)
}

impl RobotWorld {
    /// Builds a world with `ground` and the robot of `model`, standing at the nominal pose.
    pub fn new(
        model: &UrdfModel,
        ground: Collider,
        solver_iterations: usize,
    ) -> Result<Self, BuildError> {
        let mut world = physics_world(solver_iterations);
        let ground = world.colliders.insert(ground);
        let handles = insert_urdf(&mut world, model);
        let links = find_link_colliders(model, &world, &handles)?;
        let joints = find_joint_bodies(model, &handles, links.base)?;
        let probes = make_probes(model, &mut world, &links)?;
        set_contact_materials(&mut world, &links);
        let foot_contacts = FootGroundContacts::new(ground, links.feet, false);
        let (link_of_joint, dof_of_joint) =
            configure_joints(model, &mut world, links.base, &joints.child_body)?;
        let (link_bodies, nominal_mass) = nominal_masses(&mut world, &handles);
        let mut robot = Self {
            world,
            base: links.base,
            link_of_joint,
            dof_of_joint,
            child_body: joints.child_body,
            parent_body: joints.parent_body,
            axis_local: joints.axis_local,
            feet: links.feet,
            probes,
            ground,
            foot_contacts,
            link_bodies,
            link_names: model.robot.links.iter().map(|l| l.name.clone()).collect(),
            nominal_mass,
            drives: DriveParams::default(),
            torque_nm: [0.0; NUM_JOINTS],
        };
        robot.set_one_contact_per_foot(true);
        robot.reset(
            [0.0, 0.0, 0.35],
            [0.0, 0.0, 0.0, 1.0],
            &hexapod_core::robot::Q0_RAD,
        );
        Ok(robot)
    }

    fn multibody(&self) -> &Multibody {
        let link = self
            .world
            .multibody_joints
            .rigid_body_link(self.base)
            .expect("base is a multibody root");
        self.world
            .multibody_joints
            .get_multibody(link.multibody)
            .expect("multibody exists")
    }

    fn multibody_mut(&mut self) -> &mut Multibody {
        let link = *self
            .world
            .multibody_joints
            .rigid_body_link(self.base)
            .expect("base is a multibody root");
        self.world
            .multibody_joints
            .get_multibody_mut(link.multibody)
            .expect("multibody exists")
    }

    /// Places the robot: base pose (world) and joint angles, all velocities zero.
    pub fn reset(
        &mut self,
        base_pos_world_m: [f32; 3],
        base_quat_xyzw: [f32; 4],
        q_rad: &[f32; NUM_JOINTS],
    ) {
        let target_rot = Rotation::from_xyzw(
            base_quat_xyzw[0],
            base_quat_xyzw[1],
            base_quat_xyzw[2],
            base_quat_xyzw[3],
        )
        .normalize();
        let link_of_joint = self.link_of_joint;
        let dof_of_joint = self.dof_of_joint;
        let mb = self.multibody_mut();
        let ndofs = mb.ndofs();
        let mut disp = vec![0.0; ndofs];
        let root = mb.root().joint();
        let coords = root.coords();
        let cur_rot = root.joint_rot();
        for k in 0..3 {
            disp[k] = base_pos_world_m[k] - coords[k];
        }
        let delta = (target_rot * cur_rot.inverse()).to_scaled_axis();
        disp[3] = delta.x;
        disp[4] = delta.y;
        disp[5] = delta.z;
        for j in 0..NUM_JOINTS {
            let angle = mb
                .link(link_of_joint[j])
                .map(|l| l.joint().coords()[3])
                .unwrap_or(0.0);
            disp[dof_of_joint[j]] = q_rad[j] - angle;
        }
        mb.apply_displacements(&disp);
        mb.generalized_velocity_mut().fill(0.0);
        let world = &mut self.world;
        let link = *world
            .multibody_joints
            .rigid_body_link(self.base)
            .expect("root");
        let mb = world
            .multibody_joints
            .get_multibody_mut(link.multibody)
            .expect("multibody");
        mb.forward_kinematics(&world.bodies, false);
        mb.update_rigid_bodies(&mut world.bodies, true);
        let handles: Vec<RigidBodyHandle> = mb.links().map(|l| l.rigid_body_handle()).collect();
        for h in handles {
            let rb = &mut world.bodies[h];
            rb.set_linvel(Vector::ZERO, true);
            rb.set_angvel(Vector::ZERO, true);
            rb.reset_forces(false);
            rb.reset_torques(false);
        }
        self.torque_nm = [0.0; NUM_JOINTS];
    }

    /// Reads the robot's state.
    pub fn state(&self) -> RobotState {
        let mb = self.multibody();
        let vel = mb.generalized_velocity();
        let mut s = RobotState::default();
        for j in 0..NUM_JOINTS {
            s.q_rad[j] = mb
                .link(self.link_of_joint[j])
                .map(|l| l.joint().coords()[3])
                .unwrap_or(0.0);
            s.qdot_rad_s[j] = vel[self.dof_of_joint[j]];
        }
        let rb = &self.world.bodies[self.base];
        let p = rb.translation();
        let r = rb.rotation();
        let v = rb.linvel();
        let w = rb.angvel();
        // linvel is the centre of mass velocity: move it to the base origin.
        let com_offset_world = rb.center_of_mass() - p;
        let v_origin = v - w.cross(com_offset_world);
        s.base_pos_world_m = [p.x, p.y, p.z];
        s.base_quat_xyzw = [r.x, r.y, r.z, r.w];
        s.base_lin_vel_world_m_s = [v_origin.x, v_origin.y, v_origin.z];
        s.base_ang_vel_world_rad_s = [w.x, w.y, w.z];
        s
    }

    /// Runs one physics step with the drives tracking `q_target_rad` by the CSP law.
    pub fn step(&mut self, q_target_rad: &[f32; NUM_JOINTS]) {
        let state = self.state();
        for j in 0..NUM_JOINTS {
            self.torque_nm[j] = csp_torque_nm(
                q_target_rad[j],
                state.q_rad[j],
                state.qdot_rad_s[j],
                self.drives.kp1_per_s[j],
                self.drives.kp2_nms_per_rad[j],
                VELOCITY_LIMIT_RAD_S[j],
                TORQUE_LIMIT_NM[j],
                self.drives.motor_strength[j],
            );
        }
        let mut applied = self.torque_nm;
        for j in 0..NUM_JOINTS {
            applied[j] += joint_stop_torque_nm(j, state.q_rad[j], state.qdot_rad_s[j]);
        }
        self.apply_joint_torques(&applied);
        let margin_m = self.world.integration_parameters.prediction_distance();
        self.foot_contacts
            .measure(&self.world.colliders, &self.world.narrow_phase, margin_m);
        self.world.step_with_events(&self.foot_contacts, &());
    }

    fn apply_joint_torques(&mut self, torque_nm: &[f32; NUM_JOINTS]) {
        for j in 0..NUM_JOINTS {
            let h = self.child_body[j];
            let rb = &mut self.world.bodies[h];
            rb.reset_torques(false);
        }
        let base = &mut self.world.bodies[self.base];
        base.reset_torques(false);
        for j in 0..NUM_JOINTS {
            let child = &self.world.bodies[self.child_body[j]];
            let axis_world = child.rotation() * self.axis_local[j];
            let torque = axis_world * torque_nm[j];
            self.world.bodies[self.child_body[j]].add_torque(torque, true);
            self.world.bodies[self.parent_body[j]].add_torque(-torque, true);
        }
    }

    /// Ground reaction force on each foot in the last physics step, world, N (normal part).
    pub fn foot_forces_world_n(&self) -> [[f32; 3]; NUM_LEGS] {
        let np = &self.world.narrow_phase;
        let mut forces = [[0.0; 3]; NUM_LEGS];
        for leg in 0..NUM_LEGS {
            let Some(pair) = np.contact_pair(self.feet[leg], self.ground) else {
                continue;
            };
            if !pair.has_any_active_contact() {
                continue;
            }
            let mut f = pair.total_impulse() / PHYSICS_DT_S;
            // The ground pushes the foot up, whichever collider the pair lists first.
            if f.z < 0.0 {
                f = -f;
            }
            forces[leg] = [f.x, f.y, f.z];
        }
        forces
    }

    /// Foot forces and collision flags of the last step.
    pub fn contacts(&self) -> ContactState {
        let mut c = ContactState {
            foot_force_world_n: self.foot_forces_world_n(),
            ..Default::default()
        };
        let ground = &self.world.colliders[self.ground];
        let ground_aabb = ground.compute_aabb();
        let touches = |probe: &Probe| {
            let pose = *self.world.bodies[probe.body].position() * probe.local_pose;
            // Bounding boxes apart: no contact (GJK/EPA below has reported a trunk 0.27 m
            // above flat ground as touching it, for one step).
            if !probe.shape.compute_aabb(&pose).intersects(&ground_aabb) {
                return false;
            }
            // parry's contact query (GJK/EPA); its boolean intersection test misreports an
            // upright cylinder just above a cuboid as touching.
            rapier3d::parry::query::contact(
                &pose,
                &*probe.shape,
                ground.position(),
                ground.shape(),
                0.0,
            )
            .map(|hit| hit.is_some_and(|c| c.dist <= 0.0))
            .unwrap_or(false)
        };
        c.trunk = touches(&self.probes[0]);
        for leg in 0..NUM_LEGS {
            c.thighs[leg] = touches(&self.probes[1 + leg]);
            c.shanks[leg] = touches(&self.probes[1 + NUM_LEGS + leg]);
        }
        c
    }

    /// The rapier integration parameters (solver settings) of this world.
    pub fn integration_parameters_mut(&mut self) -> &mut IntegrationParameters {
        &mut self.world.integration_parameters
    }

    /// Solves contact friction in both passes of each solver substep (`true`, the default
    /// from [`RobotWorld::new`]) or only in the unbiased pass (`false`, rapier's default).
    /// With one substep per 5 ms step, friction solved once lets a loaded foot slide at up to
    /// 0.5 m/s in a tenth of its stance steps; solved in both passes, the scripted gait's
    /// loaded feet move like MuJoCo's (BENCHMARKS.md, foot slip).
    pub fn set_friction_in_bias_pass(&mut self, on: bool) {
        self.world.integration_parameters.friction_in_bias_pass = on;
    }

    /// Keeps one contact per foot on a heightfield (the default, [`crate::foot_contact`]) or,
    /// with `false`, every triangle's contact as rapier makes them. No effect on flat ground.
    pub fn set_one_contact_per_foot(&mut self, on: bool) {
        let ground = self.ground;
        let uneven = self.world.colliders[ground]
            .shape()
            .as_heightfield()
            .is_some();
        let hooks = if on && uneven {
            ActiveHooks::MODIFY_SOLVER_CONTACTS
        } else {
            ActiveHooks::empty()
        };
        for handle in self.feet {
            self.world.colliders[handle].set_active_hooks(hooks);
        }
        self.foot_contacts = FootGroundContacts::new(ground, self.feet, on && uneven);
    }

    /// Number of solver contact points (feet on the ground) in the last step.
    pub fn num_contact_points(&self) -> usize {
        self.feet
            .iter()
            .filter_map(|f| self.world.narrow_phase.contact_pair(*f, self.ground))
            .map(|p| {
                p.solver_manifolds()
                    .iter()
                    .map(|m| m.data.solver_contacts.len())
                    .sum::<usize>()
            })
            .sum()
    }

    /// Total mass of the robot, kg.
    pub fn total_mass_kg(&self) -> f32 {
        self.multibody()
            .links()
            .map(|l| self.world.bodies[l.rigid_body_handle()].mass())
            .sum()
    }

    /// Sets how the feet's friction combines with the ground's (of a pair's two rules rapier
    /// takes the stronger, Average being the weakest; the ground keeps rapier's default Average).
    pub fn set_foot_friction_combine(&mut self, combine: crate::config::FrictionCombine) {
        let rule = match combine {
            crate::config::FrictionCombine::Multiply => CoefficientCombineRule::Multiply,
            crate::config::FrictionCombine::Average => CoefficientCombineRule::Average,
        };
        for h in self.feet {
            self.world.colliders[h].set_friction_combine_rule(rule);
        }
    }

    /// Sets the friction coefficient of all feet.
    pub fn set_foot_friction(&mut self, friction: f32) {
        for h in self.feet {
            self.world.colliders[h].set_friction(friction);
        }
    }

    /// Scales the mass of every link and adds `payload_kg` to the trunk at `payload_offset_m`
    /// (base frame). Factors apply to the URDF's nominal values each call.
    /// `link_mass_scale` has one factor per URDF link (in URDF order); missing ones are 1.
    pub fn set_mass_properties(
        &mut self,
        link_mass_scale: &[f32],
        payload_kg: f32,
        payload_offset_base_m: [f32; 3],
    ) {
        for (i, h) in self.link_bodies.iter().enumerate() {
            let mut props = self.nominal_mass[i];
            let scale = link_mass_scale.get(i).copied().unwrap_or(1.0);
            props.set_mass(props.mass() * scale, true);
            if *h == self.base && payload_kg > 0.0 {
                props += MassProperties::new(
                    Vector::from(payload_offset_base_m),
                    payload_kg,
                    Vector::ZERO,
                );
            }
            let rb = &mut self.world.bodies[*h];
            rb.set_additional_mass_properties(props, true);
            rb.recompute_mass_properties_from_colliders(&self.world.colliders);
        }
    }

    /// World pose of every link, in URDF order (the order of [`LinkShape::link`]), with the
    /// link names.
    pub fn link_poses(&self) -> Vec<LinkPose<'_>> {
        self.link_bodies
            .iter()
            .zip(&self.link_names)
            .map(|(h, name)| {
                let pose = self.world.bodies[*h].position();
                let (p, r) = (pose.translation, pose.rotation);
                LinkPose {
                    name,
                    pos_world_m: [p.x, p.y, p.z],
                    quat_world_xyzw: [r.x, r.y, r.z, r.w],
                }
            })
            .collect()
    }

    /// The robot's collision shapes on their links: the trunk box, the thigh and shank
    /// probes, the foot spheres (the coxae have none). Shapes of a kind other than
    /// [`LinkShapeKind`]'s are left out (the URDF has none).
    pub fn link_shapes(&self) -> Vec<LinkShape> {
        let solid = self.feet.iter().map(|h| {
            let c = &self.world.colliders[*h];
            (
                c.parent().unwrap_or(self.base),
                c.position_wrt_parent().copied().unwrap_or(Pose::IDENTITY),
                c.shape(),
            )
        });
        let probes = self
            .probes
            .iter()
            .map(|p| (p.body, p.local_pose, &*p.shape));
        probes
            .chain(solid)
            .filter_map(|(body, pose, shape)| {
                let link = self.link_bodies.iter().position(|h| *h == body)?;
                let v = |v: Vector| [v.x, v.y, v.z];
                let kind = if let Some(b) = shape.as_cuboid() {
                    LinkShapeKind::Cuboid {
                        half_extents_m: v(b.half_extents),
                    }
                } else if let Some(c) = shape.as_cylinder() {
                    LinkShapeKind::Cylinder {
                        half_height_m: c.half_height,
                        radius_m: c.radius,
                    }
                } else if let Some(c) = shape.as_capsule() {
                    LinkShapeKind::Capsule {
                        a_m: v(c.segment.a),
                        b_m: v(c.segment.b),
                        radius_m: c.radius,
                    }
                } else {
                    LinkShapeKind::Ball {
                        radius_m: shape.as_ball()?.radius,
                    }
                };
                let r = pose.rotation;
                Some(LinkShape {
                    link,
                    pos_link_m: v(pose.translation),
                    quat_link_xyzw: [r.x, r.y, r.z, r.w],
                    kind,
                })
            })
            .collect()
    }

    /// Centre of each foot sphere, world, m.
    pub fn foot_positions_world_m(&self) -> [[f32; 3]; NUM_LEGS] {
        self.feet.map(|h| {
            let p = self.world.colliders[h].translation();
            [p.x, p.y, p.z]
        })
    }

    /// Number of links (URDF order), for per-link randomization.
    pub fn num_links(&self) -> usize {
        self.link_bodies.len()
    }

    /// Sets the base's velocity (its origin's linear velocity and the angular velocity,
    /// world frame) and the joint velocities; after [`RobotWorld::reset`], to start from a
    /// moving state (reference state initialization).
    pub fn set_velocities(
        &mut self,
        lin_vel_world_m_s: [f32; 3],
        ang_vel_world_rad_s: [f32; 3],
        qdot_rad_s: &[f32; NUM_JOINTS],
    ) {
        let base = self.base;
        let (p, com) = {
            let rb = &self.world.bodies[base];
            (rb.translation(), rb.center_of_mass())
        };
        let w = Vector::new(
            ang_vel_world_rad_s[0],
            ang_vel_world_rad_s[1],
            ang_vel_world_rad_s[2],
        );
        // The root's generalized velocity is its centre of mass's.
        let v = Vector::new(
            lin_vel_world_m_s[0],
            lin_vel_world_m_s[1],
            lin_vel_world_m_s[2],
        ) + w.cross(com - p);
        let dof_of_joint = self.dof_of_joint;
        {
            let mb = self.multibody_mut();
            let mut gv = mb.generalized_velocity_mut();
            for k in 0..3 {
                gv[k] = v[k];
                gv[3 + k] = w[k];
            }
            for j in 0..NUM_JOINTS {
                gv[dof_of_joint[j]] = qdot_rad_s[j];
            }
        }
        let rb = &mut self.world.bodies[base];
        rb.set_linvel(v, true);
        rb.set_angvel(w, true);
    }

    /// Changes the base velocity by `dv_world_m_s` (a push).
    pub fn push(&mut self, dv_world_m_s: [f32; 3]) {
        let mb = self.multibody_mut();
        let mut v = mb.generalized_velocity_mut();
        for k in 0..3 {
            v[k] += dv_world_m_s[k];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::terrain::{Terrain, TerrainConfig};
    use crate::urdf_model::{default_urdf_path, UrdfModel};
    use hexapod_core::robot::{NOMINAL_BASE_HEIGHT_M, Q0_RAD, TOTAL_MASS_KG};

    fn flat_robot() -> RobotWorld {
        let model = UrdfModel::load(&default_urdf_path()).unwrap();
        let ground = Terrain::generate(&TerrainConfig::default()).collider();
        RobotWorld::new(&model, ground, 1).unwrap()
    }

    #[test]
    fn total_mass_matches_core() {
        let mut r = flat_robot();
        r.step(&Q0_RAD);
        let m = r.total_mass_kg();
        assert!((m - TOTAL_MASS_KG).abs() < 1e-3, "{m}");
    }

    #[test]
    fn foot_positions_match_core_kinematics() {
        let mut r = flat_robot();
        r.step(&Q0_RAD);
        let s = r.state();
        let feet = hexapod_core::kinematics::foot_positions_base(&s.q_rad);
        let rot = Rotation::from_xyzw(
            s.base_quat_xyzw[0],
            s.base_quat_xyzw[1],
            s.base_quat_xyzw[2],
            s.base_quat_xyzw[3],
        );
        let base = Vector::from(s.base_pos_world_m);
        for leg in 0..NUM_LEGS {
            let sim = r.world.colliders[r.feet[leg]].translation();
            let core = base + rot * Vector::from(feet[leg]);
            assert!(
                (sim - core).length() < 1e-4,
                "leg {leg}: {sim:?} vs {core:?}"
            );
        }
    }

    #[test]
    fn link_poses_and_shapes_are_the_simulated_ones() {
        let mut r = flat_robot();
        r.step(&Q0_RAD);
        let poses = r.link_poses();
        assert_eq!(poses.len(), 1 + 3 * NUM_LEGS);
        assert_eq!(poses[0].name, "base");
        let s = r.state();
        assert_eq!(poses[0].pos_world_m, s.base_pos_world_m);
        let shapes = r.link_shapes();
        // Trunk, thigh and shank cylinders, foot spheres.
        assert_eq!(shapes.len(), 1 + 3 * NUM_LEGS);
        let [hx, hy, hz] = hexapod_core::robot::TRUNK_SIZE_M.map(|x| x / 2.0);
        assert!(shapes.iter().any(|s| poses[s.link].name == "base"
            && s.kind
                == LinkShapeKind::Cuboid {
                    half_extents_m: [hx, hy, hz]
                }));
        let feet = r.foot_positions_world_m();
        for (leg, name) in hexapod_core::robot::LEG_NAMES.iter().enumerate() {
            let shank = poses
                .iter()
                .position(|p| p.name == format!("{name}_shank"))
                .unwrap();
            let foot = shapes
                .iter()
                .find(|s| s.link == shank && matches!(s.kind, LinkShapeKind::Ball { .. }))
                .unwrap();
            // The foot sphere placed by its link's world pose lands on the collider's centre.
            let p = &poses[shank];
            let q = p.quat_world_xyzw;
            let world = Vector::from(p.pos_world_m)
                + Rotation::from_xyzw(q[0], q[1], q[2], q[3]) * Vector::from(foot.pos_link_m);
            assert!(
                (world - Vector::from(feet[leg])).length() < 1e-5,
                "leg {leg}"
            );
            assert!(shapes
                .iter()
                .any(|s| s.link == shank && matches!(s.kind, LinkShapeKind::Cylinder { .. })));
        }
    }

    #[test]
    fn payload_and_mass_scale_change_total_mass() {
        let mut r = flat_robot();
        let n = r.num_links();
        r.set_mass_properties(&vec![1.1; n], 5.0, [0.15, -0.15, 0.0]);
        let m = r.total_mass_kg();
        assert!((m - (TOTAL_MASS_KG * 1.1 + 5.0)).abs() < 1e-3, "{m}");
        r.set_mass_properties(&[], 0.0, [0.0; 3]);
        assert!((r.total_mass_kg() - TOTAL_MASS_KG).abs() < 1e-3);
    }

    #[test]
    fn collision_flags_follow_the_link_shapes() {
        let mut r = flat_robot();
        r.reset(
            [0.0, 0.0, NOMINAL_BASE_HEIGHT_M],
            [0.0, 0.0, 0.0, 1.0],
            &Q0_RAD,
        );
        let c = r.contacts();
        assert!(
            !c.trunk && !c.thighs.iter().any(|t| *t) && !c.shanks.iter().any(|s| *s),
            "{c:?}"
        );
        // Legs stretched out flat with the base low: thighs and shanks lie on the ground.
        r.reset([0.0, 0.0, 0.01], [0.0, 0.0, 0.0, 1.0], &[0.0; NUM_JOINTS]);
        let c = r.contacts();
        assert!(c.trunk, "trunk 5 cm into the ground");
        assert!(
            c.thighs.iter().all(|t| *t) && c.shanks.iter().all(|s| *s),
            "{c:?}"
        );
        // Only the trunk low, legs folded up above it.
        let mut q = Q0_RAD;
        for leg in 0..NUM_LEGS {
            q[3 * leg + 1] = -0.8;
            q[3 * leg + 2] = 0.0;
        }
        r.reset([0.0, 0.0, 0.05], [0.0, 0.0, 0.0, 1.0], &q);
        let c = r.contacts();
        assert!(c.trunk && !c.shanks.iter().any(|s| *s), "{c:?}");
    }

    #[test]
    fn joint_stops_hold_a_joint_driven_past_its_limit() {
        // In free fall, so only the drive and the stop act on the hip.
        let mut r = flat_robot();
        r.reset([0.0, 0.0, 3.0], [0.0, 0.0, 0.0, 1.0], &Q0_RAD);
        let mut target = Q0_RAD;
        target[0] = 2.0; // far beyond the hip's 0.785 rad limit
        for _ in 0..100 {
            r.step(&target);
        }
        let q = r.state().q_rad[0];
        let limit = hexapod_core::robot::Q_MAX_RAD[0];
        assert!(
            q > limit && q < limit + 0.1,
            "hip at {q} rad, limit {limit}"
        );
    }

    #[test]
    fn unpowered_robot_collapses_onto_its_folded_legs() {
        let mut r = flat_robot();
        r.drives.motor_strength = [0.0; NUM_JOINTS];
        for _ in 0..1000 {
            r.step(&Q0_RAD);
        }
        // Limp legs fold to their stops and the planted feet hold: the trunk comes to rest
        // a few centimetres above the ground (MuJoCo, the same URDF and no torque: base at
        // 0.088-0.092 m; the trunk's half height is 0.06 m). With rapier's own friction
        // (solved in one pass) the feet slid out and the trunk lay on the ground.
        let s = r.state();
        let z = s.base_pos_world_m[2];
        let half_height = hexapod_core::robot::TRUNK_SIZE_M[2] / 2.0;
        assert!(
            z > half_height - 0.005 && z < half_height + 0.04,
            "base at {z} m"
        );
        let speed: f32 = s
            .base_lin_vel_world_m_s
            .iter()
            .map(|v| v * v)
            .sum::<f32>()
            .sqrt();
        assert!(speed < 0.01, "still moving at {speed} m/s");
    }

    #[test]
    fn reset_places_joints() {
        let mut r = flat_robot();
        let mut q = Q0_RAD;
        q[4] += 0.3;
        r.reset([1.0, 2.0, 0.5], [0.0, 0.0, 0.0, 1.0], &q);
        let s = r.state();
        for j in 0..NUM_JOINTS {
            assert!((s.q_rad[j] - q[j]).abs() < 1e-5, "{j}");
        }
        assert!((s.base_pos_world_m[0] - 1.0).abs() < 1e-5);
    }

    #[test]
    fn stands_10_s_at_about_31_cm() {
        let mut r = flat_robot();
        for _ in 0..2000 {
            r.step(&Q0_RAD);
        }
        let s = r.state();
        let height = s.base_pos_world_m[2];
        assert!(
            (height - NOMINAL_BASE_HEIGHT_M).abs() < 0.02,
            "height {height}"
        );
        for j in 0..NUM_JOINTS {
            assert!(
                (s.q_rad[j] - Q0_RAD[j]).abs() < 0.05,
                "joint {j} drifted: {}",
                s.q_rad[j]
            );
        }
        let c = r.contacts();
        let total_fz: f32 = c.foot_force_world_n.iter().map(|f| f[2]).sum();
        assert!(
            (total_fz - TOTAL_MASS_KG * 9.81).abs() < 0.1 * TOTAL_MASS_KG * 9.81,
            "fz {total_fz}"
        );
        assert!(!c.trunk);
    }
}

#[cfg(test)]
mod gait_tests {
    use super::*;
    use crate::gait::TripodGait;
    use crate::terrain::{Terrain, TerrainConfig};
    use crate::urdf_model::{default_urdf_path, UrdfModel};

    #[test]
    fn scripted_tripod_gait_walks_forward_upright() {
        let model = UrdfModel::load(&default_urdf_path()).unwrap();
        let ground = Terrain::generate(&TerrainConfig::default()).collider();
        let mut r = RobotWorld::new(&model, ground, 1).unwrap();
        let gait = TripodGait::default();
        for k in 0..2000 {
            r.step(&gait.joint_targets(k as f32 * PHYSICS_DT_S));
        }
        let s = r.state();
        let [x, y, z] = s.base_pos_world_m;
        eprintln!("after 10 s: x {x:.3} y {y:.3} z {z:.3}");
        assert!(x > 0.5 * 0.2 * 10.0 && x < 1.5 * 0.2 * 10.0, "x {x}");
        assert!(y.abs() < 0.3, "y {y}");
        assert!((z - 0.3).abs() < 0.05, "z {z}");
        let [qx, qy, _, _] = s.base_quat_xyzw;
        assert!(qx.abs() < 0.05 && qy.abs() < 0.05);
    }
}
