//! Writes a [`Recording`] as a rerun `.rrd` file (the `rerun` feature).
//!
//! Timeline `sim_time` (s). Entities, world frame z up:
//! - `world/terrain`: the ground around the robot's path (static mesh);
//! - `world/robot/<link>`: one transform per link and policy step (the simulator's link
//!   poses); under it, static, the link's collision shapes as the simulator has them (trunk
//!   box, thigh and shank cylinders, foot spheres) and the coxa as a capsule of hexapod-core's
//!   length and radius (the simulator gives it no collision shape); legs red (tripod A) or
//!   blue (tripod B);
//! - `world/contacts`: the stance feet (force above `STANCE_FORCE_N`) as points at the sole
//!   and their ground reaction forces as arrows (1 mm per N);
//! - `vx_m_s`, `vy_m_s`, `wz_rad_s` (`command` and `measured`), `base_height_m`: scalars;
//! - `events`: one text entry per segment (eval: each command).

use crate::cli::recording::Recording;
use crate::cli::terrain_mesh::terrain_mesh;
use anyhow::Context;
use hexapod_core::robot::{Leg, Tripod, COXA_LENGTH_M, COXA_RADIUS_M, FOOT_RADIUS_M, LEG_NAMES};
use host_sim::frames::{quat_mul, rotate};
use host_sim::rewards::STANCE_FORCE_N;
use host_sim::robot::LinkShapeKind;
use host_sim::terrain::Terrain;
use rerun::{
    Arrows3D, Boxes3D, Capsules3D, Color, Cylinders3D, Ellipsoids3D, FillMode, Mesh3D, Points3D,
    RecordingStream, Scalars, SeriesLines, TextLog, Transform3D, ViewCoordinates,
};
use std::path::Path;

/// Ground drawn beyond the base's path on every side, m.
const TERRAIN_MARGIN_M: f32 = 1.5;
/// Length of a foot-force arrow per newton, m.
const FORCE_ARROW_M_PER_N: f32 = 0.001;
/// Quaternion (x, y, z, w) turning a rerun cylinder's or capsule's z axis onto y (parry's
/// cylinder axis): -90 deg about x.
const Z_TO_Y: [f32; 4] = [
    -std::f32::consts::FRAC_1_SQRT_2,
    0.0,
    0.0,
    std::f32::consts::FRAC_1_SQRT_2,
];
/// Quaternion turning z onto x (the coxa's axis in its link frame): +90 deg about y.
const Z_TO_X: [f32; 4] = [
    0.0,
    std::f32::consts::FRAC_1_SQRT_2,
    0.0,
    std::f32::consts::FRAC_1_SQRT_2,
];

/// Writes `recording` to `path` (`.rrd`), with `terrain` around the robot's path.
pub fn write_rrd(recording: &Recording, terrain: &Terrain, path: &Path) -> anyhow::Result<()> {
    let rec = rerun::RecordingStreamBuilder::new("hexapod")
        .save(path)
        .with_context(|| format!("creating the rerun recording {}", path.display()))?;
    log_static(&rec, recording, terrain)?;
    let mut segments = recording.segments.iter().peekable();
    for step in &recording.steps {
        rec.set_duration_secs("sim_time", step.t_s);
        while let Some((_, label)) = segments.next_if(|(t_s, _)| *t_s <= step.t_s) {
            rec.log("events", &TextLog::new(label.as_str()))?;
        }
        for (k, name) in recording.link_names.iter().enumerate() {
            let transform = Transform3D::from_translation_rotation(
                step.link_pos_world_m[k],
                rerun::Quaternion::from_xyzw(step.link_quat_world_xyzw[k]),
            );
            rec.log(format!("world/robot/{name}"), &transform)?;
        }
        let (mut soles, mut forces) = (Vec::new(), Vec::new());
        for (p, f) in step.foot_pos_world_m.iter().zip(&step.foot_force_world_n) {
            if (f[0] * f[0] + f[1] * f[1] + f[2] * f[2]).sqrt() > STANCE_FORCE_N {
                soles.push([p[0], p[1], p[2] - FOOT_RADIUS_M]);
                forces.push(f.map(|x| x * FORCE_ARROW_M_PER_N));
            }
        }
        rec.log(
            "world/contacts/feet",
            &Points3D::new(soles.iter().copied())
                .with_radii([0.015])
                .with_colors([Color::from_rgb(20, 170, 60)]),
        )?;
        rec.log(
            "world/contacts/forces",
            &Arrows3D::from_vectors(forces)
                .with_origins(soles)
                .with_colors([Color::from_rgb(20, 170, 60)]),
        )?;
        for (k, name) in ["vx_m_s", "vy_m_s", "wz_rad_s"].iter().enumerate() {
            rec.log(
                format!("{name}/command"),
                &Scalars::single(step.command[k] as f64),
            )?;
            rec.log(
                format!("{name}/measured"),
                &Scalars::single(step.measured[k] as f64),
            )?;
        }
        rec.log("base_height_m", &Scalars::single(step.base_height_m as f64))?;
    }
    rec.flush_blocking()
        .with_context(|| format!("writing {}", path.display()))?;
    Ok(())
}

/// What does not change: the axes, the ground, the robot's shapes on their links, the
/// series' names and colours.
fn log_static(
    rec: &RecordingStream,
    recording: &Recording,
    terrain: &Terrain,
) -> anyhow::Result<()> {
    rec.log_static("world", &ViewCoordinates::RIGHT_HAND_Z_UP())?;
    if let Some(area) = recording.footprint_m(TERRAIN_MARGIN_M) {
        let mesh = terrain_mesh(terrain, area);
        rec.log_static(
            "world/terrain",
            &Mesh3D::new(mesh.positions_m)
                .with_vertex_normals(mesh.normals)
                .with_triangle_indices(mesh.triangles)
                .with_albedo_factor(rerun::Rgba32::from_rgb(170, 165, 150)),
        )?;
    }
    let trunk = Color::from_rgb(90, 90, 90);
    let colour = |link: &str| match LEG_NAMES
        .iter()
        .position(|leg| link.starts_with(&format!("{leg}_")))
    {
        Some(i) if Leg::ALL[i].tripod() == Tripod::A => Color::from_rgb(210, 60, 50),
        Some(_) => Color::from_rgb(50, 90, 210),
        None => trunk,
    };
    for (k, shape) in recording.shapes.iter().enumerate() {
        let link = &recording.link_names[shape.link];
        let path = format!("world/robot/{link}/shape_{k}");
        let (centre, color) = (shape.pos_link_m, colour(link));
        let q = shape.quat_link_xyzw;
        match shape.kind {
            LinkShapeKind::Cuboid { half_extents_m } => rec.log_static(
                path,
                &Boxes3D::from_centers_and_half_sizes([centre], [half_extents_m])
                    .with_quaternions([rerun::Quaternion::from_xyzw(q)])
                    .with_fill_mode(FillMode::Solid)
                    .with_colors([color]),
            )?,
            LinkShapeKind::Cylinder {
                half_height_m,
                radius_m,
            } => rec.log_static(
                path,
                &Cylinders3D::from_lengths_and_radii([2.0 * half_height_m], [radius_m])
                    .with_centers([centre])
                    .with_quaternions([rerun::Quaternion::from_xyzw(quat_mul(q, Z_TO_Y))])
                    .with_fill_mode(FillMode::Solid)
                    .with_colors([color]),
            )?,
            LinkShapeKind::Capsule { a_m, b_m, radius_m } => {
                // Rerun's capsule runs from its origin along +z: turn z onto a -> b.
                let d = [b_m[0] - a_m[0], b_m[1] - a_m[1], b_m[2] - a_m[2]];
                let length = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
                let start = rotate(q, a_m);
                rec.log_static(
                    path,
                    &Capsules3D::from_lengths_and_radii([length], [radius_m])
                        .with_translations([[
                            centre[0] + start[0],
                            centre[1] + start[1],
                            centre[2] + start[2],
                        ]])
                        .with_quaternions([rerun::Quaternion::from_xyzw(quat_mul(q, quat_z_to(d)))])
                        .with_fill_mode(FillMode::Solid)
                        .with_colors([color]),
                )?
            }
            LinkShapeKind::Ball { radius_m } => rec.log_static(
                path,
                &Ellipsoids3D::from_centers_and_radii([centre], [radius_m])
                    .with_fill_mode(FillMode::Solid)
                    .with_colors([color]),
            )?,
        }
    }
    for (i, leg) in LEG_NAMES.iter().enumerate() {
        let link = format!("{leg}_coxa");
        if recording.link_names.contains(&link) {
            rec.log_static(
                format!("world/robot/{link}/coxa"),
                &Capsules3D::from_lengths_and_radii([COXA_LENGTH_M[i]], [COXA_RADIUS_M])
                    .with_quaternions([rerun::Quaternion::from_xyzw(Z_TO_X)])
                    .with_fill_mode(FillMode::Solid)
                    .with_colors([colour(&link)]),
            )?;
        }
    }
    for name in ["vx_m_s", "vy_m_s", "wz_rad_s"] {
        rec.log_static(
            format!("{name}/command"),
            &SeriesLines::new()
                .with_names(["command"])
                .with_colors([Color::from_rgb(120, 120, 120)]),
        )?;
        rec.log_static(
            format!("{name}/measured"),
            &SeriesLines::new().with_names(["measured"]),
        )?;
    }
    Ok(())
}

/// The shortest rotation (x, y, z, w) taking +z onto the direction of `d`.
fn quat_z_to(d: [f32; 3]) -> [f32; 4] {
    let n = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
    if n < 1e-9 {
        return [0.0, 0.0, 0.0, 1.0];
    }
    let u = d.map(|x| x / n);
    // q = (z x u, 1 + z . u), normalized; opposite directions: half a turn about x.
    let w = 1.0 + u[2];
    if w < 1e-6 {
        return [1.0, 0.0, 0.0, 0.0];
    }
    let q = [-u[1], u[0], 0.0, w];
    let m = (q.iter().map(|x| x * x).sum::<f32>()).sqrt();
    q.map(|x| x / m)
}
