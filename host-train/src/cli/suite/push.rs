//! Velocity-disturbance tolerance (the paper's Table III): per axis (X forward, Y left,
//! Z up, in the robot's heading frame), walking at 0.3 m/s and standing, a velocity change
//! of magnitude m is added to the base every 1 s, alternating in sign, 10 times. A policy
//! tolerates m when at least 9 of 10 robots survive, under two rules:
//!
//! - **current**: the simulator's termination (trunk contact or tilt beyond 60 deg);
//! - **strict**: no contact of the trunk, a thigh or a shank with the ground (their
//!   collision shapes placed by the kinematics against the ground, [`BodyShapes`]), no tilt
//!   beyond 30 deg, and back within 0.1 m/s of the command before the next push (1 s
//!   after it; 2 s after the last), measured as the base velocity averaged over the
//!   0.3 s before that instant.
//!
//! The largest tolerated m is bisected per rule: every round tests a few magnitudes inside
//! each open bracket, all conditions and magnitudes in one batch of robots.

use super::batch::{drive, heading_velocity_m_s, seed_trials, steps, tilt_rad, Conditions};
use super::controller::SuiteController;
use crate::config::TrainConfig;
use host_sim::clearance::BodyShapes;
use host_sim::env::HexapodEnv;
use host_sim::frames::{quat_from_yaw, rotate, yaw_rad};
use host_sim::urdf_model::{default_urdf_path, UrdfModel};
use serde::Serialize;

/// Standing, then walking at the command, before the first push, s.
pub const SETTLE_S: f32 = 2.0;
/// Pushes per test.
pub const PUSHES: usize = 10;
/// Time between pushes, s.
pub const INTERVAL_S: f32 = 1.0;
/// Time after the last push before the test ends (and its return is checked), s.
pub const AFTER_LAST_S: f32 = 2.0;
/// Walking command (vx, vy, wz).
pub const WALK_COMMAND: [f32; 3] = [0.3, 0.0, 0.0];
/// Strict rule: largest tilt, deg.
pub const STRICT_TILT_DEG: f32 = 30.0;
/// Strict rule: largest velocity error when the robot must be back, m/s.
pub const STRICT_RETURN_M_S: f32 = 0.1;
/// Strict rule: the velocity is averaged over this window (one stance phase of the tripod
/// gait, so the stride's own oscillation averages out), s.
pub const STRICT_WINDOW_S: f32 = 0.3;
/// Upper end of the search, m/s, per rule: a robot surviving it is reported as ">= max".
pub const MAX_CURRENT_M_S: f32 = 6.0;
/// Upper end of the strict rule's search, m/s.
pub const MAX_STRICT_M_S: f32 = 3.0;

/// Push axis in the heading frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub enum Axis {
    /// Forward.
    X,
    /// Left.
    Y,
    /// Up.
    Z,
}

/// What the robot is doing while pushed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Gait {
    /// Walking at [`WALK_COMMAND`].
    Walk,
    /// Standing (zero command).
    Stand,
}

/// Survival rule.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Rule {
    /// The simulator's termination.
    Current,
    /// The strict rule of the module docs.
    Strict,
}

/// Why a robot failed the strict rule (the first reason seen).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum StrictFailure {
    /// The simulator terminated the episode.
    Fell,
    /// Trunk, thigh or shank touched the ground.
    Contact,
    /// Tilt beyond [`STRICT_TILT_DEG`].
    Tilt,
    /// Not back within [`STRICT_RETURN_M_S`] of the command in time.
    NoReturn,
}

/// Outcome of one magnitude in one condition.
#[derive(Clone, Debug, Serialize)]
pub struct PointResult {
    /// Push magnitude, m/s.
    pub magnitude_m_s: f32,
    /// Robots tested.
    pub robots: usize,
    /// Survivors under the current rule.
    pub survived_current: usize,
    /// Survivors under the strict rule.
    pub survived_strict: usize,
    /// Strict failures by reason: fell, contact, tilt, no return.
    pub strict_failures: [usize; 4],
}

/// The tolerance of one condition under one rule.
#[derive(Clone, Debug, Serialize)]
pub struct Tolerance {
    /// Largest magnitude tolerated among those tested, m/s (0 when even the smallest failed).
    pub tolerated_m_s: f32,
    /// Smallest magnitude not tolerated, m/s (`None`: the search's maximum was tolerated).
    pub failed_m_s: Option<f32>,
}

/// One axis and gait.
#[derive(Clone, Debug, Serialize)]
pub struct ConditionResult {
    /// Axis.
    pub axis: Axis,
    /// Gait.
    pub gait: Gait,
    /// Under the simulator's termination.
    pub current: Tolerance,
    /// Under the strict rule.
    pub strict: Tolerance,
    /// Every magnitude tested, ascending.
    pub points: Vec<PointResult>,
}

/// The protocol's results.
#[derive(Clone, Debug, Serialize)]
pub struct PushResult {
    /// Pushes per test.
    pub pushes: usize,
    /// Time between pushes, s.
    pub interval_s: f32,
    /// Robots tested per magnitude.
    pub trials: usize,
    /// Survivors needed to tolerate a magnitude.
    pub survivors_needed: usize,
    /// Bisection rounds.
    pub rounds: usize,
    /// Magnitudes per bracket per round.
    pub points_per_round: usize,
    /// Per axis and gait.
    pub conditions: Vec<ConditionResult>,
}

/// The search per condition and rule: `lo` tolerated, `hi` not (or the maximum, untested).
#[derive(Clone, Copy, Debug)]
struct Bracket {
    lo: f32,
    hi: f32,
    hi_tested: bool,
    /// The maximum was tested and tolerated.
    saturated: bool,
}

impl Bracket {
    fn new(max: f32) -> Self {
        Self {
            lo: 0.0,
            hi: max,
            hi_tested: false,
            saturated: false,
        }
    }

    /// Magnitudes to test next: `k` inside the bracket, and its top until it is tested.
    fn next_points(&self, k: usize) -> Vec<f32> {
        if self.saturated {
            return Vec::new();
        }
        let mut p: Vec<f32> = (1..=k)
            .map(|j| self.lo + (self.hi - self.lo) * j as f32 / (k + 1) as f32)
            .collect();
        if !self.hi_tested {
            p.push(self.hi);
        }
        p
    }

    /// Narrows the bracket with tested magnitudes (`tolerated` per magnitude).
    fn update(&mut self, results: &[(f32, bool)]) {
        let mut inside: Vec<(f32, bool)> = results
            .iter()
            .copied()
            .filter(|(m, _)| *m > self.lo && *m <= self.hi)
            .collect();
        inside.sort_by(|a, b| a.0.total_cmp(&b.0));
        if let Some(&(m, ok)) = inside.iter().find(|(m, _)| *m == self.hi) {
            self.hi_tested = true;
            if ok && m == self.hi && !inside.iter().any(|(_, ok)| !ok) {
                self.lo = self.hi;
                self.saturated = true;
                return;
            }
        }
        if let Some(&(first_fail, _)) = inside.iter().find(|(_, ok)| !ok) {
            self.hi = first_fail;
            self.hi_tested = true;
        }
        if let Some(&(m, _)) = inside.iter().rev().find(|(m, ok)| *ok && *m < self.hi) {
            self.lo = m;
        }
    }

    fn tolerance(&self) -> Tolerance {
        Tolerance {
            tolerated_m_s: self.lo,
            failed_m_s: if self.saturated { None } else { Some(self.hi) },
        }
    }
}

/// One robot's test: a condition at a magnitude.
#[derive(Clone, Copy)]
struct Job {
    condition: usize,
    magnitude_m_s: f32,
}

/// How one robot did.
#[derive(Clone, Copy, Default)]
struct Outcome {
    fell: bool,
    strict: Option<StrictFailure>,
}

/// The conditions in report order.
pub const CONDITIONS: [(Axis, Gait); 6] = [
    (Axis::X, Gait::Walk),
    (Axis::Y, Gait::Walk),
    (Axis::Z, Gait::Walk),
    (Axis::X, Gait::Stand),
    (Axis::Y, Gait::Stand),
    (Axis::Z, Gait::Stand),
];

/// Runs the protocol: `rounds` of bisection with `k` magnitudes per bracket.
pub fn run(
    cfg: &TrainConfig,
    controller: &mut dyn SuiteController,
    c: &Conditions,
    rounds: usize,
    k: usize,
) -> anyhow::Result<PushResult> {
    let mut brackets: Vec<[Bracket; 2]> = CONDITIONS
        .iter()
        .map(|_| [Bracket::new(MAX_CURRENT_M_S), Bracket::new(MAX_STRICT_M_S)])
        .collect();
    let mut tested: Vec<Vec<PointResult>> = vec![Vec::new(); CONDITIONS.len()];
    for round in 0..rounds {
        let mut jobs: Vec<Job> = Vec::new();
        for (condition, pair) in brackets.iter().enumerate() {
            let mut ms: Vec<f32> = pair.iter().flat_map(|b| b.next_points(k)).collect();
            if round == 0 {
                ms.push(0.0); // the strict rule's own check: without pushes every robot passes
            }
            ms.retain(|m| !tested[condition].iter().any(|p| p.magnitude_m_s == *m));
            ms.sort_by(f32::total_cmp);
            ms.dedup();
            jobs.extend(ms.into_iter().map(|magnitude_m_s| Job {
                condition,
                magnitude_m_s,
            }));
        }
        if jobs.is_empty() {
            break;
        }
        let outcomes = run_jobs(cfg, controller, c, &jobs)?;
        for (j, job) in jobs.iter().enumerate() {
            let robots = &outcomes[j * c.trials..(j + 1) * c.trials];
            let mut strict_failures = [0usize; 4];
            for o in robots.iter().filter_map(|o| o.strict) {
                strict_failures[o as usize] += 1;
            }
            tested[job.condition].push(PointResult {
                magnitude_m_s: job.magnitude_m_s,
                robots: c.trials,
                survived_current: robots.iter().filter(|o| !o.fell).count(),
                survived_strict: robots.iter().filter(|o| o.strict.is_none()).count(),
                strict_failures,
            });
        }
        for (condition, pair) in brackets.iter_mut().enumerate() {
            let need = c.survivors_needed();
            let current: Vec<(f32, bool)> = tested[condition]
                .iter()
                .map(|p| (p.magnitude_m_s, p.survived_current >= need))
                .collect();
            let strict: Vec<(f32, bool)> = tested[condition]
                .iter()
                .map(|p| (p.magnitude_m_s, p.survived_strict >= need))
                .collect();
            pair[0].update(&current);
            pair[1].update(&strict);
        }
    }
    let conditions = CONDITIONS
        .iter()
        .enumerate()
        .map(|(i, &(axis, gait))| {
            let mut points = tested[i].clone();
            points.sort_by(|a, b| a.magnitude_m_s.total_cmp(&b.magnitude_m_s));
            ConditionResult {
                axis,
                gait,
                current: brackets[i][0].tolerance(),
                strict: brackets[i][1].tolerance(),
                points,
            }
        })
        .collect();
    Ok(PushResult {
        pushes: PUSHES,
        interval_s: INTERVAL_S,
        trials: c.trials,
        survivors_needed: c.survivors_needed(),
        rounds,
        points_per_round: k,
        conditions,
    })
}

/// Runs every job with `c.trials` robots each, in one batch.
fn run_jobs(
    cfg: &TrainConfig,
    controller: &mut dyn SuiteController,
    c: &Conditions,
    jobs: &[Job],
) -> anyhow::Result<Vec<Outcome>> {
    let n = c.robots(jobs.len());
    let duration_s = SETTLE_S + (PUSHES - 1) as f32 * INTERVAL_S + AFTER_LAST_S;
    let mut env = HexapodEnv::new(c.sim_config(cfg, n, duration_s))?;
    seed_trials(&mut env, c);
    for i in 0..n {
        env.set_spawn_pose(
            i,
            Some(host_sim::env::SpawnPose {
                position_m: [0.0, 0.0],
                yaw_rad: 0.0,
            }),
        );
    }
    let job_of = |i: usize| jobs[i / c.trials];
    let first = steps(SETTLE_S);
    let every = steps(INTERVAL_S);
    let push_steps: Vec<usize> = (0..PUSHES).map(|p| first + p * every).collect();
    // Check instants: just before each next push, and AFTER_LAST_S after the last.
    let mut checks: Vec<usize> = push_steps[1..].iter().map(|s| s - 1).collect();
    checks.push(push_steps[PUSHES - 1] + steps(AFTER_LAST_S) - 1);
    let total = checks[checks.len() - 1] + 1;
    let window = steps(STRICT_WINDOW_S);
    let tilt_limit_rad = STRICT_TILT_DEG.to_radians();
    let shapes = BodyShapes::from_model(&UrdfModel::load(&default_urdf_path())?)?;
    let mut out = vec![Outcome::default(); n];
    let mut history: Vec<Vec<[f32; 3]>> = vec![Vec::with_capacity(total); n];
    drive(
        &mut env,
        controller,
        total,
        |step, env, commands| {
            for i in 0..n {
                let job = job_of(i);
                let (axis, gait) = CONDITIONS[job.condition];
                commands[i] = if gait == Gait::Walk {
                    WALK_COMMAND
                } else {
                    [0.0; 3]
                };
                if let Some(p) = push_steps.iter().position(|s| *s == step) {
                    let sign = if p % 2 == 0 { 1.0 } else { -1.0 };
                    let m = sign * job.magnitude_m_s;
                    let dv_heading = match axis {
                        Axis::X => [m, 0.0, 0.0],
                        Axis::Y => [0.0, m, 0.0],
                        Axis::Z => [0.0, 0.0, m],
                    };
                    let yaw = yaw_rad(env.robot_state(i).base_quat_xyzw);
                    env.push(i, rotate(quat_from_yaw(yaw), dv_heading));
                }
            }
        },
        |step, env, res| {
            for i in 0..n {
                let o = &mut out[i];
                if o.fell {
                    continue;
                }
                if res.dones[i] {
                    o.fell = true;
                    o.strict.get_or_insert(StrictFailure::Fell);
                    continue;
                }
                let s = env.robot_state(i);
                let v = heading_velocity_m_s(&s);
                history[i].push(v);
                if step < first || o.strict.is_some() {
                    continue;
                }
                if shapes.clearance(&s, env.terrain()).lowest_m() < 0.0 {
                    o.strict = Some(StrictFailure::Contact);
                } else if tilt_rad(&s) > tilt_limit_rad {
                    o.strict = Some(StrictFailure::Tilt);
                } else if checks.contains(&step) {
                    let job = job_of(i);
                    let command = if CONDITIONS[job.condition].1 == Gait::Walk {
                        WALK_COMMAND
                    } else {
                        [0.0; 3]
                    };
                    let h = &history[i];
                    let recent = &h[h.len().saturating_sub(window)..];
                    let mut mean = [0.0f32; 3];
                    for v in recent {
                        for k in 0..3 {
                            mean[k] += v[k] / recent.len() as f32;
                        }
                    }
                    let err = ((mean[0] - command[0]).powi(2)
                        + (mean[1] - command[1]).powi(2)
                        + mean[2].powi(2))
                    .sqrt();
                    if err > STRICT_RETURN_M_S {
                        o.strict = Some(StrictFailure::NoReturn);
                    }
                }
            }
        },
    )?;
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bracket_narrows_to_the_last_tolerated_magnitude() {
        // Tolerated up to 1.3 m/s.
        let ok = |m: f32| m <= 1.3;
        let mut b = Bracket::new(3.0);
        let mut tested: Vec<(f32, bool)> = Vec::new();
        for _ in 0..4 {
            for m in b.next_points(3) {
                tested.push((m, ok(m)));
            }
            b.update(&tested);
        }
        let t = b.tolerance();
        assert!(
            t.tolerated_m_s <= 1.3 && t.failed_m_s.unwrap() > 1.3,
            "{t:?}"
        );
        assert!(
            t.failed_m_s.unwrap() - t.tolerated_m_s < 3.0 / 64.0 + 1e-4,
            "{t:?}"
        );
    }

    #[test]
    fn bracket_saturates_when_the_maximum_is_tolerated() {
        let mut b = Bracket::new(2.0);
        let tested: Vec<(f32, bool)> = b.next_points(3).into_iter().map(|m| (m, true)).collect();
        b.update(&tested);
        assert!(b.next_points(3).is_empty());
        let t = b.tolerance();
        assert_eq!((t.tolerated_m_s, t.failed_m_s), (2.0, None));
    }

    #[test]
    fn bracket_reports_zero_when_the_smallest_fails() {
        let mut b = Bracket::new(2.0);
        let tested: Vec<(f32, bool)> = b.next_points(1).into_iter().map(|m| (m, false)).collect();
        b.update(&tested);
        assert_eq!(b.tolerance().tolerated_m_s, 0.0);
        assert_eq!(b.tolerance().failed_m_s, Some(1.0));
    }
}
