//! Terrain success (the paper's Fig. 5) and the outdoor step: robots start on the evaluation
//! course ([`host_sim::course`]) 1 m before a feature, facing it, and walk at a fixed
//! forward command for 10 s. Success: no fall (the simulator's termination) and at least
//! 2 m along the command, measured from the start to where the base is at the end.

use super::batch::{drive, seed_trials, steps, Conditions};
use super::controller::SuiteController;
use crate::config::TrainConfig;
use host_sim::course::{Course, Feature};
use host_sim::env::HexapodEnv;
use serde::Serialize;

/// Stair risers tested, m (the paper: 3 to 20 cm).
pub const STEP_HEIGHTS_M: [f32; 8] = [0.03, 0.05, 0.08, 0.10, 0.13, 0.15, 0.17, 0.20];
/// Slopes tested, deg (the paper: 5 to 30 deg).
pub const SLOPES_DEG: [f32; 6] = [5.0, 10.0, 15.0, 20.0, 25.0, 30.0];
/// The quick variant's features: one per kind, mid-range.
pub const QUICK_STEP_M: f32 = 0.10;
/// The quick variant's slope, deg.
pub const QUICK_SLOPE_DEG: f32 = 15.0;
/// Command of the terrain test (vx, vy, wz).
pub const TERRAIN_COMMAND: [f32; 3] = [0.3, 0.0, 0.0];
/// Length of each trial, s (`Conditions::terrain_duration_s` may change it).
pub const DURATION_S: f32 = 10.0;
/// Distance along the command a successful trial covers, m.
pub const SUCCESS_DISTANCE_M: f32 = 2.0;
/// Beyond the paper: stair risers, m.
pub const BEYOND_STEP_HEIGHTS_M: [f32; 1] = [0.25];
/// Beyond the paper: slopes, deg.
pub const BEYOND_SLOPES_DEG: [f32; 1] = [35.0];
/// The outdoor step (the paper's flower bed): height, m.
pub const OUTDOOR_STEP_M: f32 = 0.15;
/// The outdoor step's command (vx, vy, wz).
pub const OUTDOOR_COMMAND: [f32; 3] = [0.5, 0.0, 0.0];

/// One feature's trials.
#[derive(Clone, Debug, Serialize)]
pub struct FeatureResult {
    /// The feature.
    pub feature: Feature,
    /// In words.
    pub name: String,
    /// Command (vx, vy, wz).
    pub command: [f32; 3],
    /// Trials.
    pub trials: usize,
    /// Successful trials.
    pub successes: usize,
    /// Trials that fell.
    pub falls: usize,
    /// Mean distance along the command at the end (at the fall for those that fell), m.
    pub mean_distance_m: f64,
    /// Each trial, in trial order.
    pub trial_outcomes: Vec<TrialOutcome>,
}

/// One trial of a feature: its robot's contact friction (the draw most of the steep ramps'
/// outcomes follow) and what it did.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct TrialOutcome {
    /// Friction coefficient of the trial's robot's contacts with the ground (its foot
    /// friction's draw, combined with the ground's).
    pub contact_friction: f32,
    /// Distance along the command at the end (at the fall if it fell), m.
    pub distance_m: f32,
    /// The trial fell.
    pub fell: bool,
    /// No fall and at least [`SUCCESS_DISTANCE_M`] along the command.
    pub success: bool,
}

impl FeatureResult {
    /// Successes / trials.
    pub fn success_rate(&self) -> f64 {
        self.successes as f64 / self.trials.max(1) as f64
    }
}

/// The protocol's results.
#[derive(Clone, Debug, Serialize)]
pub struct TerrainResult {
    /// Length of each trial, s.
    pub duration_s: f32,
    /// Distance needed for a success, m.
    pub success_distance_m: f32,
    /// From the start pose to the feature's first edge, m.
    pub run_up_m: f32,
    /// Stairs and slopes, up and down.
    pub features: Vec<FeatureResult>,
    /// The outdoor step (`None` when the protocol was not selected).
    pub outdoor_step: Option<FeatureResult>,
}

/// The features of the terrain protocol, in report order.
pub fn features(quick: bool) -> Vec<Feature> {
    if quick {
        features_of(&[QUICK_STEP_M], &[QUICK_SLOPE_DEG])
    } else {
        features_of(&STEP_HEIGHTS_M, &SLOPES_DEG)
    }
}

/// The features beyond the paper's range (the same in the quick variant), in report order.
pub fn beyond_features() -> Vec<Feature> {
    features_of(&BEYOND_STEP_HEIGHTS_M, &BEYOND_SLOPES_DEG)
}

/// Stairs up, stairs down, slopes up, slopes down: one feature per riser and per slope.
fn features_of(steps_m: &[f32], slopes: &[f32]) -> Vec<Feature> {
    let mut f: Vec<Feature> = Vec::new();
    f.extend(
        steps_m
            .iter()
            .map(|&h| Feature::StairsUp { step_height_m: h }),
    );
    f.extend(
        steps_m
            .iter()
            .map(|&h| Feature::StairsDown { step_height_m: h }),
    );
    f.extend(slopes.iter().map(|&d| Feature::SlopeUp { slope_deg: d }));
    f.extend(slopes.iter().map(|&d| Feature::SlopeDown { slope_deg: d }));
    f
}

/// A lane robots walk in: its place in the [`course`], its feature and its command.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lane {
    /// Index of the lane in the course.
    pub course_lane: usize,
    /// The lane's feature.
    pub feature: Feature,
    /// Command (vx, vy, wz).
    pub command: [f32; 3],
}

/// Every lane of the course, in course order: the terrain features, then the outdoor step.
fn all_lanes(quick: bool) -> Vec<Lane> {
    let step = Feature::Step {
        height_m: OUTDOOR_STEP_M,
    };
    lanes_in_order(
        features(quick)
            .into_iter()
            .map(|f| (f, TERRAIN_COMMAND))
            .chain(std::iter::once((step, OUTDOOR_COMMAND))),
    )
}

/// One lane per (feature, command), numbered in course order.
fn lanes_in_order(features: impl IntoIterator<Item = (Feature, [f32; 3])>) -> Vec<Lane> {
    features
        .into_iter()
        .enumerate()
        .map(|(course_lane, (feature, command))| Lane {
            course_lane,
            feature,
            command,
        })
        .collect()
}

/// The course of both tests: a lane per terrain feature and one for the outdoor step,
/// whichever of the two run. The ground is one heightfield whose size and placement follow
/// from its lanes, and contacts on a heightfield of another size round differently: a course
/// of the selected lanes only gave trial k another ground, at the bit level, when the terrain
/// test ran alone than beside the step, and different outcomes on marginal stairs.
pub fn course(quick: bool, cell_m: f32) -> Course {
    let features: Vec<Feature> = all_lanes(quick).iter().map(|l| l.feature).collect();
    Course::with_cell(&features, cell_m)
}

/// The lanes of the selected tests (`terrain`, `step`), in report order (the step last).
pub fn selected_lanes(quick: bool, terrain: bool, step: bool) -> Vec<Lane> {
    let lanes = all_lanes(quick);
    let step_lane = lanes.len() - 1;
    lanes
        .into_iter()
        .filter(|l| {
            if l.course_lane == step_lane {
                step
            } else {
                terrain
            }
        })
        .collect()
}

/// Runs the terrain features (`terrain`) and the outdoor step (`step`) in one batch, on the
/// same [`course`] either way.
pub fn run(
    cfg: &TrainConfig,
    controller: &mut dyn SuiteController,
    c: &Conditions,
    terrain: bool,
    step: bool,
) -> anyhow::Result<TerrainResult> {
    let lanes = selected_lanes(c.quick, terrain, step);
    let mut results = run_lanes(
        cfg,
        controller,
        c,
        &course(c.quick, c.course_cell_m),
        &lanes,
    )?;
    let outdoor_step = if step { results.pop() } else { None };
    Ok(TerrainResult {
        duration_s: c.terrain_duration_s,
        success_distance_m: SUCCESS_DISTANCE_M,
        run_up_m: host_sim::course::RUN_UP_M,
        features: results,
        outdoor_step,
    })
}

/// Runs the features beyond the paper ([`beyond_features`]) on a course of their own, with
/// the terrain test's command, duration and success rule.
pub fn run_beyond(
    cfg: &TrainConfig,
    controller: &mut dyn SuiteController,
    c: &Conditions,
) -> anyhow::Result<Vec<FeatureResult>> {
    run_on_own_course(cfg, controller, c, &beyond_features())
}

/// Walks `features` on a course of their own, one lane each, with the terrain test's
/// command, duration and success rule; one result per feature.
pub(super) fn run_on_own_course(
    cfg: &TrainConfig,
    controller: &mut dyn SuiteController,
    c: &Conditions,
    features: &[Feature],
) -> anyhow::Result<Vec<FeatureResult>> {
    let lanes = lanes_in_order(features.iter().map(|&f| (f, TERRAIN_COMMAND)));
    let course = Course::with_cell(features, c.course_cell_m);
    run_lanes(cfg, controller, c, &course, &lanes)
}

/// Walks `c.trials` robots per lane of `course` for `c.terrain_duration_s`; one result per lane.
fn run_lanes(
    cfg: &TrainConfig,
    controller: &mut dyn SuiteController,
    c: &Conditions,
    course: &Course,
    lanes: &[Lane],
) -> anyhow::Result<Vec<FeatureResult>> {
    let n = c.robots(lanes.len());
    let mut env = HexapodEnv::with_terrain(
        c.sim_config(cfg, n, c.terrain_duration_s),
        course.terrain().clone(),
    )?;
    seed_trials(&mut env, c);
    let lane_of = |i: usize| i / c.trials;
    let starts: Vec<_> = (0..n)
        .map(|i| course.start_pose(lanes[lane_of(i)].course_lane))
        .collect();
    for (i, start) in starts.iter().enumerate() {
        env.set_spawn_pose(i, Some(*start));
    }
    let mut fell = vec![false; n];
    let mut distance_m = vec![0.0f32; n];
    let mut contact_friction = vec![0.0f32; n];
    drive(
        &mut env,
        controller,
        steps(c.terrain_duration_s),
        |step, env, commands| {
            if step == 0 {
                // The draw of the trial's robot (a robot that falls is reset with another).
                for (i, f) in contact_friction.iter_mut().enumerate() {
                    *f = env.contact_friction(i);
                }
            }
            for (i, cmd) in commands.iter_mut().enumerate() {
                *cmd = lanes[lane_of(i)].command;
            }
        },
        |_, env, res| {
            for i in 0..n {
                if fell[i] {
                    continue;
                }
                if res.dones[i] {
                    fell[i] = true;
                    continue;
                }
                // Heading +x: the distance along the command is the x advance.
                distance_m[i] = env.robot_state(i).base_pos_world_m[0] - starts[i].position_m[0];
            }
        },
    )?;
    let results: Vec<FeatureResult> = lanes
        .iter()
        .enumerate()
        .map(|(lane, l)| {
            let robots: Vec<usize> = (0..n).filter(|&i| lane_of(i) == lane).collect();
            let trial_outcomes: Vec<TrialOutcome> = robots
                .iter()
                .map(|&i| TrialOutcome {
                    contact_friction: contact_friction[i],
                    distance_m: distance_m[i],
                    fell: fell[i],
                    success: !fell[i] && distance_m[i] >= SUCCESS_DISTANCE_M,
                })
                .collect();
            let count =
                |keep: fn(&TrialOutcome) -> bool| trial_outcomes.iter().filter(|t| keep(t)).count();
            FeatureResult {
                feature: l.feature,
                name: l.feature.describe(),
                command: l.command,
                trials: trial_outcomes.len(),
                successes: count(|t| t.success),
                falls: count(|t| t.fell),
                mean_distance_m: trial_outcomes
                    .iter()
                    .map(|t| t.distance_m as f64)
                    .sum::<f64>()
                    / trial_outcomes.len().max(1) as f64,
                trial_outcomes,
            }
        })
        .collect();
    Ok(results)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Trial k meets the same ground whether the terrain test runs alone, beside the step, or
    /// the step alone: one course for all, and each test's lanes keep their place in it.
    #[test]
    fn the_ground_does_not_depend_on_the_tests_selected() {
        for quick in [false, true] {
            let both = selected_lanes(quick, true, true);
            let terrain = selected_lanes(quick, true, false);
            let step = selected_lanes(quick, false, true);
            assert_eq!(terrain.len(), features(quick).len());
            assert_eq!(step.len(), 1);
            assert_eq!(terrain[..], both[..terrain.len()]);
            assert_eq!(step[..], both[terrain.len()..]);
            let course = course(quick, host_sim::course::CELL_M);
            assert_eq!(course.features().len(), both.len());
            for l in &both {
                assert_eq!(course.features()[l.course_lane], l.feature);
            }
            assert_eq!(step[0].course_lane, terrain.len());
            assert_eq!(step[0].command, OUTDOOR_COMMAND);
            assert!(selected_lanes(quick, false, false).is_empty());
        }
    }

    /// The features beyond the paper go past its hardest of each kind, one of each.
    #[test]
    fn beyond_the_paper_is_past_the_paper_s_range() {
        let kind_and_size = |f: &Feature| match *f {
            Feature::StairsUp { step_height_m } => ("stairs up", step_height_m),
            Feature::StairsDown { step_height_m } => ("stairs down", step_height_m),
            Feature::SlopeUp { slope_deg } => ("slope up", slope_deg),
            Feature::SlopeDown { slope_deg } => ("slope down", slope_deg),
            _ => ("other", 0.0),
        };
        let beyond = beyond_features();
        assert_eq!(beyond.len(), 4);
        for b in &beyond {
            let (kind, size) = kind_and_size(b);
            let paper_max = features(false)
                .iter()
                .map(kind_and_size)
                .filter(|(k, _)| *k == kind)
                .fold(0.0f32, |m, (_, v)| m.max(v));
            assert!(paper_max > 0.0 && size > paper_max, "{}", b.describe());
        }
    }
}
