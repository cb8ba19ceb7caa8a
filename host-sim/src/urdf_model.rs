//! Loading `assets/hexapod.urdf` and checking it against hexapod-core's robot definition.
//!
//! The URDF is the simulator's source of masses, inertias, joint frames, axes and limits;
//! hexapod-core is the firmware's. [`UrdfModel::load`] refuses a file whose joints, limits
//! or masses disagree with hexapod-core, naming the file and the field.

use hexapod_core::robot::{
    JOINT_NAMES, NUM_JOINTS, Q_MAX_RAD, Q_MIN_RAD, TORQUE_LIMIT_NM, TOTAL_MASS_KG,
    VELOCITY_LIMIT_RAD_S,
};
use rapier3d_urdf::urdf_rs;
use std::path::{Path, PathBuf};

/// Why a URDF was refused.
#[derive(Debug, thiserror::Error)]
pub enum UrdfError {
    /// The file could not be read.
    #[error("{path}: cannot read: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// The XML is not a URDF robot.
    #[error("{path}: not a valid URDF: {message}")]
    Parse {
        /// The file.
        path: PathBuf,
        /// The parser's message.
        message: String,
    },
    /// A field is missing or disagrees with hexapod-core.
    #[error("{path}: {field}: {message}")]
    Field {
        /// The file.
        path: PathBuf,
        /// The offending element and attribute, e.g. `joint rf_hip / limit.effort`.
        field: String,
        /// What is wrong.
        message: String,
    },
}

/// A parsed and checked robot description.
#[derive(Clone, Debug)]
pub struct UrdfModel {
    /// Where it came from.
    pub path: PathBuf,
    /// The raw XML (the loader re-parses it into rapier bodies).
    pub xml: String,
    /// The parsed robot.
    pub robot: urdf_rs::Robot,
    /// Reflected rotor inertia of every drive, kg m^2 (`hexapod:armature` on `<robot>`).
    pub armature_kg_m2: f32,
}

/// The URDF shipped with the project.
pub fn default_urdf_path() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets/hexapod.urdf")
}

impl UrdfModel {
    /// Reads, parses and checks a URDF file.
    pub fn load(path: &Path) -> Result<Self, UrdfError> {
        let xml = std::fs::read_to_string(path).map_err(|source| UrdfError::Io {
            path: path.to_owned(),
            source,
        })?;
        Self::from_xml(path, xml)
    }

    /// Parses and checks URDF text; `path` is used in error messages.
    pub fn from_xml(path: &Path, xml: String) -> Result<Self, UrdfError> {
        let robot = urdf_rs::read_from_string(&xml).map_err(|e| UrdfError::Parse {
            path: path.to_owned(),
            message: e.to_string(),
        })?;
        let field_err = |field: String, message: String| UrdfError::Field {
            path: path.to_owned(),
            field,
            message,
        };
        let armature_kg_m2 = read_attribute(&xml, "hexapod:armature")
            .ok_or_else(|| field_err("robot / hexapod:armature".into(), "missing".into()))?
            .parse::<f32>()
            .ok()
            .filter(|a| a.is_finite() && *a >= 0.0)
            .ok_or_else(|| {
                field_err(
                    "robot / hexapod:armature".into(),
                    "not a non-negative number".into(),
                )
            })?;

        for (i, name) in JOINT_NAMES.iter().enumerate() {
            let joint = robot
                .joints
                .iter()
                .find(|j| j.name == *name)
                .ok_or_else(|| {
                    field_err(
                        format!("joint {name}"),
                        "missing (hexapod-core expects it)".into(),
                    )
                })?;
            if !matches!(joint.joint_type, urdf_rs::JointType::Revolute) {
                return Err(field_err(
                    format!("joint {name} / type"),
                    "must be revolute".into(),
                ));
            }
            let checks = [
                ("limit.lower", joint.limit.lower, Q_MIN_RAD[i]),
                ("limit.upper", joint.limit.upper, Q_MAX_RAD[i]),
                ("limit.effort", joint.limit.effort, TORQUE_LIMIT_NM[i]),
                (
                    "limit.velocity",
                    joint.limit.velocity,
                    VELOCITY_LIMIT_RAD_S[i],
                ),
            ];
            for (field, urdf_value, core_value) in checks {
                if (urdf_value as f32 - core_value).abs() > 1e-3 {
                    return Err(field_err(
                        format!("joint {name} / {field}"),
                        format!("{urdf_value} differs from hexapod-core's {core_value}"),
                    ));
                }
            }
        }
        let mass_kg: f64 = robot.links.iter().map(|l| l.inertial.mass.value).sum();
        if (mass_kg as f32 - TOTAL_MASS_KG).abs() > 1e-3 {
            return Err(field_err(
                "link / inertial.mass".into(),
                format!("total {mass_kg} kg differs from hexapod-core's {TOTAL_MASS_KG} kg"),
            ));
        }
        for link in &robot.links {
            let m = link.inertial.mass.value;
            let ok = m.is_finite() && m > 0.0;
            if !ok {
                return Err(field_err(
                    format!("link {} / inertial.mass", link.name),
                    format!("{m} is not a positive mass"),
                ));
            }
        }
        check_tree(&robot).map_err(|(field, message)| field_err(field, message))?;
        if robot.joints.len() != NUM_JOINTS {
            return Err(field_err(
                "joint".into(),
                format!(
                    "{} joints, hexapod-core has {NUM_JOINTS}",
                    robot.joints.len()
                ),
            ));
        }
        Ok(Self {
            path: path.to_owned(),
            xml,
            robot,
            armature_kg_m2,
        })
    }
}

/// The links and joints form one tree rooted at `base`: every joint joins two existing
/// links, no link has two parent joints, and every link reaches `base` without a cycle (the
/// simulator builds one reduced-coordinate multibody along it).
fn check_tree(robot: &urdf_rs::Robot) -> Result<(), (String, String)> {
    use std::collections::HashMap;
    let links: std::collections::HashSet<&str> =
        robot.links.iter().map(|l| l.name.as_str()).collect();
    let mut parent_of: HashMap<&str, &str> = HashMap::new();
    for joint in &robot.joints {
        for (end, link) in [("parent", &joint.parent.link), ("child", &joint.child.link)] {
            if !links.contains(link.as_str()) {
                return Err((
                    format!("joint {} / {end}", joint.name),
                    format!("no link named `{link}`"),
                ));
            }
        }
        if let Some(previous) =
            parent_of.insert(joint.child.link.as_str(), joint.parent.link.as_str())
        {
            return Err((
                format!("joint {} / child", joint.name),
                format!(
                    "link `{}` already has parent `{previous}`: a kinematic loop (the model must be a tree)",
                    joint.child.link
                ),
            ));
        }
    }
    if parent_of.contains_key("base") {
        return Err((
            "link base".into(),
            "the root link `base` is a joint's child".into(),
        ));
    }
    for link in &robot.links {
        let (mut current, mut steps) = (link.name.as_str(), 0);
        while current != "base" {
            current = match parent_of.get(current) {
                Some(parent) => parent,
                None => {
                    return Err((
                        format!("link {}", link.name),
                        "not connected to `base`".into(),
                    ))
                }
            };
            steps += 1;
            if steps > robot.links.len() {
                return Err((
                    format!("link {}", link.name),
                    "on a kinematic loop (the model must be a tree)".into(),
                ));
            }
        }
    }
    Ok(())
}

/// The value of the first `name="..."` attribute in `xml`.
fn read_attribute<'a>(xml: &'a str, name: &str) -> Option<&'a str> {
    let key = format!("{name}=\"");
    let start = xml.find(&key)? + key.len();
    let len = xml[start..].find('"')?;
    Some(&xml[start..start + len])
}

#[cfg(test)]
mod tests {
    use super::*;

    fn shipped() -> String {
        std::fs::read_to_string(default_urdf_path()).unwrap()
    }

    #[test]
    fn shipped_urdf_matches_core() {
        let model = UrdfModel::load(&default_urdf_path()).unwrap();
        assert_eq!(model.armature_kg_m2, 0.01);
        assert_eq!(model.robot.links.len(), 19);
    }

    #[test]
    fn wrong_limit_is_named() {
        let xml = shipped().replacen("effort=\"30\"", "effort=\"31\"", 1);
        let err = UrdfModel::from_xml(Path::new("bad.urdf"), xml)
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("bad.urdf") && err.contains("rf_hip") && err.contains("effort"),
            "{err}"
        );
    }

    #[test]
    fn missing_joint_is_named() {
        let xml = shipped().replace("name=\"lr_shank\"", "name=\"lr_knee\"");
        let err = UrdfModel::from_xml(Path::new("bad.urdf"), xml)
            .unwrap_err()
            .to_string();
        assert!(err.contains("lr_shank"), "{err}");
    }

    #[test]
    fn malformed_xml_is_refused() {
        let err = UrdfModel::from_xml(Path::new("bad.urdf"), "<robot name=".into()).unwrap_err();
        assert!(matches!(err, UrdfError::Parse { .. }), "{err}");
    }

    #[test]
    fn kinematic_loop_is_refused() {
        // Make the first leg's shank the child of a second joint: a loop, which the
        // reduced-coordinate multibody cannot represent.
        let xml = shipped();
        let marker = "<child link=\"";
        let first = xml.find(marker).expect("a joint child");
        let start = first + marker.len();
        let end = start + xml[start..].find('"').unwrap();
        let first_child = xml[start..end].to_string();
        let second = start + xml[start..].find(marker).expect("a second joint");
        let s2 = second + marker.len();
        let e2 = s2 + xml[s2..].find('"').unwrap();
        let looped = format!("{}{}{}", &xml[..s2], first_child, &xml[e2..]);
        let err = UrdfModel::from_xml(Path::new("looped.urdf"), looped)
            .unwrap_err()
            .to_string();
        assert!(err.contains("looped.urdf") && err.contains("loop"), "{err}");
    }

    #[test]
    fn missing_file_is_named() {
        let err = UrdfModel::load(Path::new("nowhere.urdf"))
            .unwrap_err()
            .to_string();
        assert!(err.contains("nowhere.urdf"), "{err}");
    }
}
