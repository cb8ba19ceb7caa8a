//! The evaluation course: straight lanes side by side, one feature each (a flight of stairs
//! up or down, a ramp up or down, a single step), with exact riser heights and slope angles,
//! and a start pose per lane before its feature, facing it.
//!
//! Lane `j` runs along +x and covers y in [j, j + 1) x [`LANE_WIDTH_M`]. From its start a
//! level run-up of [`RUN_UP_M`] leads to the feature's first edge; the feature runs for
//! [`FEATURE_LENGTH_M`] and ends on a level landing. Every robot lives in its own physics
//! world, so all trials of a lane start at the same pose.

use crate::env::SpawnPose;
use crate::terrain::Terrain;
use serde::{Deserialize, Serialize};

/// Lane width, m: the robot (about 1.2 m across its feet) starts on the centre line, so it
/// may drift 1.4 m sideways before it reaches the next lane.
pub const LANE_WIDTH_M: f32 = 4.0;
/// From the start pose (the base) to the feature's first edge, m: the front feet stand
/// about 0.5 m ahead of the base, so they start 0.5 m before the edge.
pub const RUN_UP_M: f32 = 1.0;
/// Length of a flight of stairs or a ramp along the lane, m; a level landing follows.
pub const FEATURE_LENGTH_M: f32 = 5.0;
/// Stair tread depth, m (the tile grid's default).
pub const TREAD_M: f32 = 0.35;
/// Height grid spacing, m (the tile grid's default). Treads and the run-up are whole cells.
/// The grid draws each riser as a ramp one cell wide: a 20 cm riser leans at 76 deg on 5 cm
/// cells, 83 deg on 2.5 cm ([`Course::with_cell`]).
pub const CELL_M: f32 = 0.05;
/// Level ground behind the start, m.
const BACK_MARGIN_M: f32 = 2.0;
/// Level landing after the feature, m.
const LANDING_M: f32 = 3.0;

/// One lane's feature.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Feature {
    /// Level ground.
    Flat,
    /// A flight of stairs climbing away from the start, risers of `step_height_m`.
    StairsUp {
        /// Riser height, m.
        step_height_m: f32,
    },
    /// A flight of stairs descending away from the start.
    StairsDown {
        /// Riser height, m.
        step_height_m: f32,
    },
    /// A ramp climbing away from the start.
    SlopeUp {
        /// Angle to the horizontal, degrees.
        slope_deg: f32,
    },
    /// A ramp descending away from the start.
    SlopeDown {
        /// Angle to the horizontal, degrees.
        slope_deg: f32,
    },
    /// One step up onto a level top (a kerb, a flower bed).
    Step {
        /// Height of the step, m.
        height_m: f32,
    },
}

impl Feature {
    /// Height of the ground `along_m` past the feature's first edge, m (0 before it). Risers
    /// stand at whole multiples of [`TREAD_M`]; the grid draws each one as a ramp one cell wide.
    pub fn height_m(&self, along_m: f32) -> f32 {
        let cells = (along_m / CELL_M).round() as i64;
        self.height_at_cell(cells, CELL_M)
    }

    /// Height at a whole number of cells of `cell_m` past the edge, m (exact integer stair
    /// arithmetic).
    fn height_at_cell(&self, cells: i64, cell_m: f32) -> f32 {
        if cells <= 0 {
            return 0.0;
        }
        let tread = (TREAD_M / cell_m).round() as i64;
        let feature_cells = (FEATURE_LENGTH_M / cell_m).round() as i64;
        let steps = |h: f32| {
            let k = ((cells.min(feature_cells) + tread - 1) / tread).min(feature_cells / tread);
            h * k as f32
        };
        let ramp = |deg: f32| deg.to_radians().tan() * cells.min(feature_cells) as f32 * cell_m;
        match *self {
            Feature::Flat => 0.0,
            Feature::StairsUp { step_height_m } => steps(step_height_m),
            Feature::StairsDown { step_height_m } => -steps(step_height_m),
            Feature::SlopeUp { slope_deg } => ramp(slope_deg),
            Feature::SlopeDown { slope_deg } => -ramp(slope_deg),
            Feature::Step { height_m } => height_m,
        }
    }

    /// The feature in words: "stairs up 0.13 m", "slope down 25 deg", "step 0.15 m".
    pub fn describe(&self) -> String {
        match *self {
            Feature::Flat => "flat".into(),
            Feature::StairsUp { step_height_m } => format!("stairs up {step_height_m:.2} m"),
            Feature::StairsDown { step_height_m } => format!("stairs down {step_height_m:.2} m"),
            Feature::SlopeUp { slope_deg } => format!("slope up {slope_deg:.0} deg"),
            Feature::SlopeDown { slope_deg } => format!("slope down {slope_deg:.0} deg"),
            Feature::Step { height_m } => format!("step {height_m:.2} m"),
        }
    }
}

/// Finest height grid a course may have, m (a grid of 2 cm cells over 30 lanes holds about
/// 8 million heights).
pub const MIN_CELL_M: f32 = 0.01;

/// Checks that `cell_m` can draw the course: at least [`MIN_CELL_M`], at most the default
/// [`CELL_M`], and the treads, the run-up, the feature, the margins and the lanes whole
/// numbers of cells.
pub fn check_cell(cell_m: f32) -> Result<(), String> {
    if !(MIN_CELL_M..=CELL_M).contains(&cell_m) {
        return Err(format!(
            "a course cell of {cell_m} m is outside [{MIN_CELL_M}, {CELL_M}] m"
        ));
    }
    let lengths = [
        ("tread", TREAD_M),
        ("run-up", RUN_UP_M),
        ("feature", FEATURE_LENGTH_M),
        ("back margin", BACK_MARGIN_M),
        ("landing", LANDING_M),
        ("lane width", LANE_WIDTH_M),
    ];
    for (name, length_m) in lengths {
        let cells = length_m / cell_m;
        if (cells - cells.round()).abs() > 1e-3 {
            return Err(format!(
                "a course cell of {cell_m} m does not divide the {name} ({length_m} m) into whole cells"
            ));
        }
    }
    Ok(())
}

/// The course: its ground and, per lane, the feature and the start pose.
pub struct Course {
    features: Vec<Feature>,
    terrain: Terrain,
}

impl Course {
    /// Builds one lane per feature, in order, on a grid of [`CELL_M`].
    pub fn new(features: &[Feature]) -> Self {
        Self::with_cell(features, CELL_M)
    }

    /// Builds one lane per feature, in order, on a height grid of `cell_m` (see
    /// [`check_cell`]; panics on a cell it refuses).
    pub fn with_cell(features: &[Feature], cell_m: f32) -> Self {
        assert!(!features.is_empty(), "a course needs at least one lane");
        if let Err(e) = check_cell(cell_m) {
            panic!("{e}");
        }
        let length_m = BACK_MARGIN_M + RUN_UP_M + FEATURE_LENGTH_M + LANDING_M;
        let nx = (length_m / cell_m).round() as usize + 1;
        let lane_cells = (LANE_WIDTH_M / cell_m).round() as usize;
        let ny = features.len() * lane_cells + 1;
        let edge_cell = ((BACK_MARGIN_M + RUN_UP_M) / cell_m).round() as i64;
        let mut heights_m = vec![0.0f32; nx * ny];
        for ix in 0..nx {
            for iy in 0..ny {
                let lane = (iy / lane_cells).min(features.len() - 1);
                heights_m[ix * ny + iy] =
                    features[lane].height_at_cell(ix as i64 - edge_cell, cell_m);
            }
        }
        Self {
            features: features.to_vec(),
            terrain: Terrain::from_heights(cell_m, nx, ny, heights_m),
        }
    }

    /// The ground of all lanes.
    pub fn terrain(&self) -> &Terrain {
        &self.terrain
    }

    /// The features, one per lane.
    pub fn features(&self) -> &[Feature] {
        &self.features
    }

    /// Start pose of lane `lane`: on its centre line, [`RUN_UP_M`] before the feature,
    /// facing it (+x).
    pub fn start_pose(&self, lane: usize) -> SpawnPose {
        SpawnPose {
            position_m: [BACK_MARGIN_M, self.lane_center_y_m(lane)],
            yaw_rad: 0.0,
        }
    }

    /// World x of every feature's first edge (a riser's foot, a ramp's start), m.
    pub fn feature_edge_x_m(&self) -> f32 {
        BACK_MARGIN_M + RUN_UP_M
    }

    /// World y of lane `lane`'s centre line, m.
    pub fn lane_center_y_m(&self, lane: usize) -> f32 {
        (lane as f32 + 0.5) * LANE_WIDTH_M
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stair_arithmetic_is_exact() {
        let f = Feature::StairsUp {
            step_height_m: 0.08,
        };
        assert_eq!(f.height_m(-0.5), 0.0);
        assert_eq!(f.height_m(0.0), 0.0);
        assert_eq!(f.height_m(0.05), 0.08);
        assert_eq!(f.height_m(0.35), 0.08);
        assert_eq!(f.height_m(0.40), 0.16);
        let last = 0.08 * (FEATURE_LENGTH_M / TREAD_M).floor();
        assert!((f.height_m(FEATURE_LENGTH_M + 1.0) - last).abs() < 1e-6);
        assert_eq!(Feature::Step { height_m: 0.15 }.height_m(2.0), 0.15);
        assert_eq!(
            Feature::StairsDown { step_height_m: 0.2 }.height_m(0.1),
            -0.2
        );
    }

    #[test]
    fn a_cell_must_divide_the_course() {
        assert!(check_cell(CELL_M).is_ok());
        assert!(check_cell(0.025).is_ok());
        assert!(check_cell(0.0125).is_ok());
        let e = check_cell(0.04).unwrap_err();
        assert!(e.contains("tread"), "{e}");
        assert!(check_cell(0.1).unwrap_err().contains("outside"));
        assert!(check_cell(0.005).unwrap_err().contains("outside"));
        assert!(check_cell(f32::NAN).is_err());
    }
}
