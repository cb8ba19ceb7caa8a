//! Ground clearance of the robot's non-foot parts: the trunk box and the thigh and shank
//! cylinders of the URDF, placed by the base pose and hexapod-core's leg kinematics, against
//! the terrain's height lookup. Exact on level ground; on stairs and slopes the ground is
//! read under each shape's lowest point's end.
//!
//! This is the geometric test behind the evaluation suite's strict push rule. The
//! simulator's own collision flags ([`crate::robot::ContactState`], parry's contact query on
//! the thigh and shank probes) also report upright shanks 3-4 cm above level ground as
//! touching while their foot stands on it, so the rule does not use them.

use crate::frames::rotate;
use crate::robot::RobotState;
use crate::terrain::Terrain;
use crate::urdf_model::{UrdfError, UrdfModel};
use hexapod_core::robot::{
    COXA_LENGTH_M, HIP_POS_BASE_M, LEG_NAMES, MOUNT_YAW_RAD, NUM_LEGS, THIGH_LENGTH_M,
};
use rapier3d_urdf::urdf_rs::Geometry;

/// A cylinder along a link's x axis.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LinkCylinder {
    /// Start of the axis along the link's x, m.
    pub from_m: f32,
    /// End of the axis along the link's x, m.
    pub to_m: f32,
    /// Radius, m.
    pub radius_m: f32,
}

/// The non-foot collision shapes of the robot.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BodyShapes {
    /// Half extents of the trunk box (centred on the base), m.
    pub trunk_half_m: [f32; 3],
    /// Thigh cylinder (the same on every leg).
    pub thigh: LinkCylinder,
    /// Shank cylinder (the same on every leg).
    pub shank: LinkCylinder,
}

/// Height of each part's lowest point above the ground under it, m (negative: inside it).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Clearance {
    /// Trunk.
    pub trunk_m: f32,
    /// Thighs, in leg order.
    pub thighs_m: [f32; NUM_LEGS],
    /// Shanks, in leg order.
    pub shanks_m: [f32; NUM_LEGS],
}

impl Clearance {
    /// The lowest clearance of all parts, m.
    pub fn lowest_m(&self) -> f32 {
        self.thighs_m
            .iter()
            .chain(self.shanks_m.iter())
            .fold(self.trunk_m, |a, b| a.min(*b))
    }
}

fn field(model: &UrdfModel, field: String, message: &str) -> UrdfError {
    UrdfError::Field {
        path: model.path.clone(),
        field,
        message: message.into(),
    }
}

fn cylinder(model: &UrdfModel, link: &str) -> Result<LinkCylinder, UrdfError> {
    let l = model
        .robot
        .links
        .iter()
        .find(|l| l.name == link)
        .ok_or_else(|| field(model, format!("link {link}"), "missing"))?;
    for c in &l.collision {
        if let Geometry::Cylinder { radius, length } = c.geometry {
            let rpy = &c.origin.rpy;
            if (rpy[1] - std::f64::consts::FRAC_PI_2).abs() > 1e-3
                || rpy[0].abs() > 1e-6
                || rpy[2].abs() > 1e-6
            {
                return Err(field(
                    model,
                    format!("link {link} / collision.origin.rpy"),
                    "the cylinder must lie along the link's x axis (rpy 0 pi/2 0)",
                ));
            }
            let x = c.origin.xyz[0] as f32;
            let half = length as f32 / 2.0;
            return Ok(LinkCylinder {
                from_m: x - half,
                to_m: x + half,
                radius_m: radius as f32,
            });
        }
    }
    Err(field(
        model,
        format!("link {link} / collision"),
        "no cylinder",
    ))
}

impl BodyShapes {
    /// Reads the shapes from the robot model; every leg must have the same thigh and shank.
    pub fn from_model(model: &UrdfModel) -> Result<Self, UrdfError> {
        let base = model
            .robot
            .links
            .iter()
            .find(|l| l.name == "base")
            .ok_or_else(|| field(model, "link base".into(), "missing"))?;
        let size = base
            .collision
            .iter()
            .find_map(|c| match &c.geometry {
                Geometry::Box { size } => Some([
                    size[0] as f32 / 2.0,
                    size[1] as f32 / 2.0,
                    size[2] as f32 / 2.0,
                ]),
                _ => None,
            })
            .ok_or_else(|| field(model, "link base / collision".into(), "no box"))?;
        let thigh = cylinder(model, &format!("{}_thigh", LEG_NAMES[0]))?;
        let shank = cylinder(model, &format!("{}_shank", LEG_NAMES[0]))?;
        for leg in LEG_NAMES {
            if cylinder(model, &format!("{leg}_thigh"))? != thigh
                || cylinder(model, &format!("{leg}_shank"))? != shank
            {
                return Err(field(
                    model,
                    format!("links {leg}_thigh, {leg}_shank"),
                    "differ from the rf leg's",
                ));
            }
        }
        Ok(Self {
            trunk_half_m: size,
            thigh,
            shank,
        })
    }

    /// Clearance of every part for a robot state over `terrain`.
    pub fn clearance(&self, s: &RobotState, terrain: &Terrain) -> Clearance {
        let world = |p: [f32; 3]| {
            let r = rotate(s.base_quat_xyzw, p);
            [
                r[0] + s.base_pos_world_m[0],
                r[1] + s.base_pos_world_m[1],
                r[2] + s.base_pos_world_m[2],
            ]
        };
        let above = |p: [f32; 3], drop_m: f32| p[2] - drop_m - terrain.height_at_m(p[0], p[1]);
        let mut c = Clearance {
            trunk_m: f32::MAX,
            ..Default::default()
        };
        let h = self.trunk_half_m;
        for corner in 0..8 {
            let sign = |bit: usize| if corner & (1 << bit) != 0 { 1.0 } else { -1.0 };
            c.trunk_m = c.trunk_m.min(above(
                world([sign(0) * h[0], sign(1) * h[1], sign(2) * h[2]]),
                0.0,
            ));
        }
        // A cylinder's lowest point lies on one of its end rims, r sqrt(1 - d_z^2) below the
        // end's centre for a world axis direction d.
        let cyl = |origin: [f32; 3], dir: [f32; 3], shape: &LinkCylinder| {
            let d = rotate(s.base_quat_xyzw, dir);
            let drop = shape.radius_m * (1.0 - d[2] * d[2]).max(0.0).sqrt();
            let end = |t: f32| {
                world([
                    origin[0] + dir[0] * t,
                    origin[1] + dir[1] * t,
                    origin[2] + dir[2] * t,
                ])
            };
            above(end(shape.from_m), drop).min(above(end(shape.to_m), drop))
        };
        for leg in 0..NUM_LEGS {
            let q = &s.q_rad[3 * leg..3 * leg + 3];
            let yaw = MOUNT_YAW_RAD[leg] + q[0];
            let (sy, cy) = yaw.sin_cos();
            let hip = HIP_POS_BASE_M[leg];
            let thigh_origin = [
                hip[0] + COXA_LENGTH_M[leg] * cy,
                hip[1] + COXA_LENGTH_M[leg] * sy,
                hip[2],
            ];
            // Thigh and shank angles are positive downward, in the leg's vertical plane.
            let along = |a: f32| [a.cos() * cy, a.cos() * sy, -a.sin()];
            let thigh_dir = along(q[1]);
            c.thighs_m[leg] = cyl(thigh_origin, thigh_dir, &self.thigh);
            let knee = [
                thigh_origin[0] + thigh_dir[0] * THIGH_LENGTH_M,
                thigh_origin[1] + thigh_dir[1] * THIGH_LENGTH_M,
                thigh_origin[2] + thigh_dir[2] * THIGH_LENGTH_M,
            ];
            c.shanks_m[leg] = cyl(knee, along(q[1] + q[2]), &self.shank);
        }
        c
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::terrain::TerrainConfig;
    use crate::urdf_model::default_urdf_path;
    use hexapod_core::kinematics::foot_positions_base;
    use hexapod_core::robot::{FOOT_RADIUS_M, Q0_RAD};

    fn shapes() -> BodyShapes {
        BodyShapes::from_model(&UrdfModel::load(&default_urdf_path()).unwrap()).unwrap()
    }

    #[test]
    fn shapes_come_from_the_urdf() {
        let b = shapes();
        assert_eq!(b.trunk_half_m, [0.3, 0.15, 0.06]);
        assert!(
            (b.shank.from_m - 0.018).abs() < 1e-6
                && (b.shank.to_m - 0.2).abs() < 1e-6
                && b.shank.radius_m == 0.018
        );
        assert!(
            (b.thigh.from_m - 0.03).abs() < 1e-6
                && (b.thigh.to_m - 0.17).abs() < 1e-6
                && b.thigh.radius_m == 0.03
        );
    }

    #[test]
    fn standing_at_the_nominal_pose_clears_the_ground_and_lying_does_not() {
        let flat = Terrain::generate(&TerrainConfig::default());
        let b = shapes();
        // Base height that puts the nominal feet on the ground.
        let foot_z = foot_positions_base(&Q0_RAD)[0][2];
        let mut s = RobotState {
            q_rad: Q0_RAD,
            base_quat_xyzw: [0.0, 0.0, 0.0, 1.0],
            ..Default::default()
        };
        s.base_pos_world_m = [0.0, 0.0, FOOT_RADIUS_M - foot_z];
        let c = b.clearance(&s, &flat);
        // The nominal shank is vertical: its end is 2 cm above the foot's centre.
        for leg in 0..NUM_LEGS {
            assert!(
                (c.shanks_m[leg] - (FOOT_RADIUS_M + 0.02)).abs() < 2e-3,
                "shank {leg}: {}",
                c.shanks_m[leg]
            );
            assert!(c.thighs_m[leg] > 0.1, "thigh {leg}: {}", c.thighs_m[leg]);
        }
        assert!((c.trunk_m - (s.base_pos_world_m[2] - 0.06)).abs() < 1e-5);
        // Lowered onto its belly, with the legs through the ground.
        s.base_pos_world_m[2] = 0.05;
        let c = b.clearance(&s, &flat);
        assert!(c.trunk_m < 0.0 && c.lowest_m() < -0.1);
    }
}
