//! The suite's report: the JSON document and its Markdown rendering in the paper's layout
//! (Table III with one row per controller, the success matrix with one column per
//! controller), with the rules stated and the paper's figures beside ours.

use super::batch::Conditions;
use super::curriculum::CurriculumResult;
use super::friction::{self, FrictionPoint};
use super::push::{self, Axis, Gait, PushResult, Tolerance};
use super::sine::SineRun;
use super::terrain::{self, FeatureResult, TerrainResult};
use serde::Serialize;
use std::collections::BTreeMap;
use std::fmt::Write as _;

/// The paper's Table III (Y axis), m/s.
pub const PAPER_TABLE_III_Y_M_S: [(&str, f32); 5] = [
    ("Ours", 0.803),
    ("RMA", 0.738),
    ("Concurrent", 0.463),
    ("Baseline", 0.201),
    ("MPC", 0.112),
];

/// One controller's results.
#[derive(Clone, Debug, Serialize)]
pub struct ControllerReport {
    /// Short name (the checkpoint directory's).
    pub name: String,
    /// Checkpoint directory.
    pub checkpoint: String,
    /// Training iteration of the checkpoint.
    pub iteration: Option<usize>,
    /// Ground it trained on.
    pub trained_on: String,
    /// Conditions of the runs.
    pub conditions: Conditions,
    /// Velocity-disturbance tolerance.
    pub push: Option<PushResult>,
    /// Terrain success and the outdoor step.
    pub terrain: Option<TerrainResult>,
    /// The terrain test beyond the paper's range (25 cm stairs, 35 deg slopes).
    pub beyond_paper: Option<Vec<FeatureResult>>,
    /// The 30 deg ramp and 20 cm stairs at fixed contact friction coefficients.
    pub friction_sweep: Option<Vec<FrictionPoint>>,
    /// Sinusoidal commands.
    pub sine: Option<Vec<SineRun>>,
    /// Curriculum.
    pub curriculum: Option<CurriculumResult>,
    /// Wall-clock time per protocol, s.
    pub wall_clock_s: BTreeMap<String, f64>,
}

/// The whole report.
#[derive(Clone, Debug, Serialize)]
pub struct SuiteReport {
    /// Suite name.
    pub suite: String,
    /// The command line that made it.
    pub command: String,
    /// Protocols run.
    pub protocols: Vec<String>,
    /// All protocols finished for every controller (a report is only written when true).
    pub complete: bool,
    /// Per controller, in command-line order.
    pub controllers: Vec<ControllerReport>,
    /// Plot files, relative to the report.
    pub plots: Vec<String>,
}

fn tol(t: &Tolerance) -> String {
    match t.failed_m_s {
        None => format!(">= {:.2}", t.tolerated_m_s),
        Some(_) => format!("{:.2}", t.tolerated_m_s),
    }
}

fn range(t: &Tolerance) -> String {
    match t.failed_m_s {
        None => format!("[<= -{0:.2}, >= {0:.2}]", t.tolerated_m_s),
        Some(_) => format!("[-{0:.2}, {0:.2}]", t.tolerated_m_s),
    }
}

/// The terrain rows some trials passed and some did not, with each trial's contact friction:
/// on the steep ramps the friction draw, not the policy, may decide a trial.
fn friction_of_split_rows(s: &mut String, runs: &[(&ControllerReport, &TerrainResult)]) {
    let split = |f: &&FeatureResult| f.successes > 0 && f.successes < f.trials;
    if !runs
        .iter()
        .any(|(_, t)| t.features.iter().any(|f| split(&f)))
    {
        return;
    }
    let _ = writeln!(
        s,
        "Rows with successes and failures, each trial's contact friction (`report.json` has every \
         trial's friction, distance and fall):\n\n\
         | controller | terrain | contact friction of the successes | of the failures |\n|---|---|---|---|"
    );
    let list = |f: &FeatureResult, success: bool| {
        let mut mu: Vec<f32> = f
            .trial_outcomes
            .iter()
            .filter(|t| t.success == success)
            .map(|t| t.contact_friction)
            .collect();
        mu.sort_by(f32::total_cmp);
        mu.iter()
            .map(|m| format!("{m:.2}"))
            .collect::<Vec<_>>()
            .join(", ")
    };
    for (c, t) in runs {
        for f in t.features.iter().filter(split) {
            let _ = writeln!(
                s,
                "| {} | {} | {} | {} |",
                c.name,
                f.name,
                list(f, true),
                list(f, false)
            );
        }
    }
    let _ = writeln!(s);
}

fn cell(f: &FeatureResult) -> String {
    format!("{}/{} ({:.2} m)", f.successes, f.trials, f.mean_distance_m)
}

/// A success table's header and rows, one column per controller, one row per feature of the
/// first controller.
fn feature_rows(s: &mut String, columns: &[(&str, &[FeatureResult])]) {
    let _ = writeln!(
        s,
        "| terrain | {} |\n|---|{}",
        columns
            .iter()
            .map(|(name, _)| *name)
            .collect::<Vec<_>>()
            .join(" | "),
        "---|".repeat(columns.len())
    );
    let Some((_, first)) = columns.first() else {
        return;
    };
    for (k, f) in first.iter().enumerate() {
        let cells: Vec<String> = columns
            .iter()
            .map(|(_, fs)| fs.get(k).map(cell).unwrap_or_else(|| "-".into()))
            .collect();
        let _ = writeln!(s, "| {} | {} |", f.name, cells.join(" | "));
    }
}

impl SuiteReport {
    /// The report as Markdown; `plots` are the PNG paths relative to the report.
    pub fn markdown(&self) -> String {
        let mut s = String::new();
        let names: Vec<&str> = self.controllers.iter().map(|c| c.name.as_str()).collect();
        let _ = writeln!(s, "# Paper suite: {}\n", names.join(", "));
        let _ = writeln!(
            s,
            "Made by `{}`; `report.json` holds every number below and more.\n",
            self.command
        );
        let _ = writeln!(
            s,
            "| controller | checkpoint | iteration | trained on |\n|---|---|---|---|"
        );
        for c in &self.controllers {
            let it = c
                .iteration
                .map(|i| i.to_string())
                .unwrap_or_else(|| "-".into());
            let _ = writeln!(
                s,
                "| {} | `{}` | {} | {} |",
                c.name, c.checkpoint, it, c.trained_on
            );
        }
        if let Some(c) = self.controllers.first() {
            let k = &c.conditions;
            let r = &k.randomization;
            let _ = writeln!(
                s,
                "\n**Conditions.** Seed {}, {} trials (robots) per test point{}; trial k is the same robot \
                 (the same randomized dynamics) in every test. Policy: the action mean. Observation noise: {}. \
                 Domain randomization per robot (the training ranges, the paper's Table II, except friction): \
                 joint stiffness x[{}, {}], damping x[{}, {}], motor strength x[{}, {}], link masses x[{}, {}], \
                 payload [{}, {}] kg within +-{} m, initial joints x[{}, {}], friction of the foot contacts with the ground [{}, {}] (foot \
                 friction [{:.2}, {:.2}] combined with the ground's by {:?}; training: foot friction [0.1, 2.5]; below \
                 tan 30 deg = 0.58 no robot stands on the 30 deg ramp). The environment's own \
                 random pushes are off. Fall (the simulator's termination): trunk contact with the ground or tilt \
                 beyond {} deg. Each trial of the terrain, step, beyond and friction tests lasts {} s (the \
                 protocol's: {} s). The course's height grid has {} cm cells: each riser is a ramp one cell \
                 wide, {:.0} deg for a 20 cm riser (real risers are vertical).\n",
                k.seed,
                k.trials,
                if k.quick { ", the quick variant (fewer trials and test points)" } else { "" },
                if k.observation_noise { "on, as in training" } else { "off" },
                r.stiffness_factor[0], r.stiffness_factor[1], r.damping_factor[0], r.damping_factor[1],
                r.motor_strength[0], r.motor_strength[1], r.link_mass_factor[0], r.link_mass_factor[1],
                r.payload_kg[0], r.payload_kg[1], r.payload_offset_m,
                r.initial_joint_pos_factor[0], r.initial_joint_pos_factor[1], k.contact_friction[0], k.contact_friction[1],
                r.friction[0], r.friction[1], k.foot_friction_combine,
                k.max_tilt_deg,
                k.terrain_duration_s,
                terrain::DURATION_S,
                k.course_cell_m * 100.0,
                (0.2 / k.course_cell_m).atan().to_degrees(),
            );
        }
        self.push_section(&mut s);
        self.terrain_section(&mut s);
        self.beyond_section(&mut s);
        self.friction_section(&mut s);
        self.sine_section(&mut s);
        self.curriculum_section(&mut s);
        let _ = writeln!(
            s,
            "## Run time\n\n| controller | protocol | wall clock, s |\n|---|---|---|"
        );
        for c in &self.controllers {
            for (p, t) in &c.wall_clock_s {
                let _ = writeln!(s, "| {} | {} | {:.0} |", c.name, p, t);
            }
        }
        s
    }

    fn plot_link(&self, s: &mut String, file: &str) {
        if self.plots.iter().any(|p| p.ends_with(file)) {
            let _ = writeln!(s, "![{file}](plots/{file})\n");
        }
    }

    fn push_section(&self, s: &mut String) {
        let pushed: Vec<(&ControllerReport, &PushResult)> = self
            .controllers
            .iter()
            .filter_map(|c| Some((c, c.push.as_ref()?)))
            .collect();
        let Some((_, p0)) = pushed.first() else {
            return;
        };
        let _ = writeln!(
            s,
            "## Velocity-disturbance tolerance (Table III)\n\n\
             A velocity change of magnitude m is added to the base every {:.0} s, {} times, alternating in \
             sign, along one axis of the robot's heading frame (X forward, Y left, Z up), while it walks at \
             {:.1} m/s or stands; the first push comes after {:.0} s. The robot tolerates m when at least {} of \
             {} survive. The largest m is bisected ({} rounds, {} magnitudes per bracket per round; search \
             up to {:.0} m/s for the current rule, {:.0} m/s for the strict one), so each figure is the largest \
             tolerated magnitude tested; the smallest failing one is in the full table.\n",
            p0.interval_s,
            p0.pushes,
            push::WALK_COMMAND[0],
            push::SETTLE_S,
            p0.survivors_needed,
            p0.trials,
            p0.rounds,
            p0.points_per_round,
            push::MAX_CURRENT_M_S,
            push::MAX_STRICT_M_S,
        );
        let _ = writeln!(
            s,
            "Two rules:\n\n\
             - **current**: the simulator's termination (trunk contact or tilt beyond 60 deg);\n\
             - **strict**: the trunk, thighs and shanks never touch the ground, the tilt stays within {:.0} deg, and \
             the robot is back within {:.1} m/s of its command before the next push arrives (1 s after each push, \
             {:.0} s after the last), the base velocity (x, y and z, heading frame) averaged over the {:.1} s \
             before that instant.\n\n\
             Why the strict rule: under the current rule this robot survives pushes of metres per second. It is \
             wide (about 1.2 m across its feet) and low (0.30 m): a shove makes it slide on its feet rather than \
             tip, and its trunk seldom reaches the ground, so the rule counts robots that are still sliding or \
             bouncing when the next push comes as survivors. The strict rule asks what the paper's \"regain \
             stability\" means: the parts of the legs that are not feet and the trunk stay off the ground \
             (training penalizes those collisions; on the real robot they are the damage), the body stays within \
             half the termination angle of upright, and the robot walks at its command again before it is \
             pushed again. The return is checked before the next push rather than 2 s after each push: with a \
             push every second, 2 s after a push the robot is answering the next push, of the opposite sign, \
             and crosses its command on the way. The 0.3 s window is one stance phase of the tripod gait, so \
             the gait's own speed ripple is not counted as an error. Contact is tested geometrically: the URDF's \
             trunk box and thigh and shank cylinders, placed by the joint angles and the base pose, against the \
             ground height (`host_sim::clearance`). The simulator's own thigh and shank collision flags are not \
             used: they also report upright shanks 3-4 cm above level ground as touching, which failed robots \
             standing still. The m = 0 rows of the full table (no pushes) check the rule itself. Survival is not \
             always monotone in m with 10 robots; the search reports the largest tolerated magnitude below the \
             smallest failing one it found, and every magnitude tested is listed.\n",
            push::STRICT_TILT_DEG,
            push::STRICT_RETURN_M_S,
            push::AFTER_LAST_S,
            push::STRICT_WINDOW_S,
        );
        let _ = writeln!(s, "### Table III layout (Y axis, walking at 0.3 m/s)\n");
        let _ = writeln!(s, "| Controllers | Disturbances [Min, Max] (m/s), strict rule | current rule |\n|---|---|---|");
        for (c, p) in &pushed {
            if let Some(cond) = p
                .conditions
                .iter()
                .find(|x| x.axis == Axis::Y && x.gait == Gait::Walk)
            {
                let _ = writeln!(
                    s,
                    "| {} | {} | {} |",
                    c.name,
                    range(&cond.strict),
                    range(&cond.current)
                );
            }
        }
        for (name, v) in PAPER_TABLE_III_Y_M_S {
            let _ = writeln!(s, "| *paper: {name}* | *[-{v:.3}, {v:.3}]* | |");
        }
        let _ = writeln!(
            s,
            "\nThe paper does not state its fall rule, its push timing beyond \"one-second intervals\", or whether \
             it walked; its figures are printed for reference, not as the same measurement.\n"
        );
        let _ = writeln!(s, "### All axes: largest tolerated push, m/s\n");
        let _ = writeln!(s, "| controller | rule | X walk | Y walk | Z walk | X stand | Y stand | Z stand |\n|---|---|---|---|---|---|---|---|");
        for (c, p) in &pushed {
            for (rule, pick) in [("strict", 1usize), ("current", 0usize)] {
                let cells: Vec<String> = push::CONDITIONS
                    .iter()
                    .map(|(a, g)| {
                        p.conditions
                            .iter()
                            .find(|x| x.axis == *a && x.gait == *g)
                            .map(|x| tol(if pick == 1 { &x.strict } else { &x.current }))
                            .unwrap_or_else(|| "-".into())
                    })
                    .collect();
                let _ = writeln!(s, "| {} | {} | {} |", c.name, rule, cells.join(" | "));
            }
        }
        let _ = writeln!(
            s,
            "\n### Every magnitude tested\n\nSurvivors of {} under the current / strict rule; strict failures by \
             first reason (fell, non-foot contact, tilt, no return).\n",
            p0.trials
        );
        let _ = writeln!(s, "| controller | axis, gait | m, m/s | current | strict | fell / contact / tilt / no return |\n|---|---|---|---|---|---|");
        for (c, p) in &pushed {
            for cond in &p.conditions {
                for q in &cond.points {
                    let f = q.strict_failures;
                    let _ = writeln!(
                        s,
                        "| {} | {:?} {:?} | {:.3} | {} | {} | {} / {} / {} / {} |",
                        c.name,
                        cond.axis,
                        cond.gait,
                        q.magnitude_m_s,
                        q.survived_current,
                        q.survived_strict,
                        f[0],
                        f[1],
                        f[2],
                        f[3]
                    );
                }
            }
        }
        let _ = writeln!(s);
        for a in ["X", "Y", "Z"] {
            self.plot_link(s, &format!("push_{a}_walk.png"));
        }
    }

    fn terrain_section(&self, s: &mut String) {
        let runs: Vec<(&ControllerReport, &TerrainResult)> = self
            .controllers
            .iter()
            .filter_map(|c| Some((c, c.terrain.as_ref()?)))
            .collect();
        let Some((_, t0)) = runs.first() else { return };
        if !t0.features.is_empty() {
            let _ = writeln!(
                s,
                "## Terrain success (Fig. 5)\n\n\
                 Each robot starts on a straight lane of the evaluation course, its base {:.1} m before the \
                 feature's first edge, facing it, and walks at {:.1} m/s for {:.0} s. Stairs have 0.35 m treads \
                 and 14 risers; ramps run 5 m; a level landing follows. **Success: no fall and at least {:.0} m \
                 along the command** (the base's advance from its start at the end of the run, which puts it about \
                 1 m into the feature). Cells: successes of trials (mean distance along the command, m; the command \
                 asks for {:.0} m, and more means the robot ran or slid ahead of it, as on the steep ramps down).\n",
                t0.run_up_m,
                terrain::TERRAIN_COMMAND[0],
                t0.duration_s,
                t0.success_distance_m,
                terrain::TERRAIN_COMMAND[0] * t0.duration_s
            );
            let columns: Vec<(&str, &[FeatureResult])> = runs
                .iter()
                .map(|(c, t)| (c.name.as_str(), t.features.as_slice()))
                .collect();
            feature_rows(s, &columns);
            let totals: Vec<String> = runs
                .iter()
                .map(|(_, t)| {
                    let (ok, n) = t
                        .features
                        .iter()
                        .fold((0, 0), |(a, b), f| (a + f.successes, b + f.trials));
                    format!("{ok}/{n}")
                })
                .collect();
            let _ = writeln!(s, "| **all** | {} |\n", totals.join(" | "));
            friction_of_split_rows(s, &runs);
            for f in [
                "success_stairs_up.png",
                "success_stairs_down.png",
                "success_slopes_up.png",
                "success_slopes_down.png",
            ] {
                self.plot_link(s, f);
            }
        }
        if let Some(step) = &t0.outdoor_step {
            let _ = writeln!(
                s,
                "## The outdoor step (the paper's flower bed)\n\n\
                 A single {:.2} m step up onto a level top, approached at {:.1} m/s for {:.0} s from {:.1} m before \
                 it; success as above (no fall, at least {:.0} m along the command: the base 1 m past the edge, \
                 every foot on the top). The paper's grass beyond the bed is not modelled.\n",
                terrain::OUTDOOR_STEP_M,
                step.command[0],
                t0.duration_s,
                t0.run_up_m,
                t0.success_distance_m
            );
            let _ = writeln!(
                s,
                "| controller | successes | falls | mean distance, m |\n|---|---|---|---|"
            );
            for (c, t) in &runs {
                if let Some(f) = &t.outdoor_step {
                    let _ = writeln!(
                        s,
                        "| {} | {}/{} | {} | {:.2} |",
                        c.name, f.successes, f.trials, f.falls, f.mean_distance_m
                    );
                }
            }
            let _ = writeln!(s);
        }
    }

    fn beyond_section(&self, s: &mut String) {
        let columns: Vec<(&str, &[FeatureResult])> = self
            .controllers
            .iter()
            .filter_map(|c| Some((c.name.as_str(), c.beyond_paper.as_deref()?)))
            .collect();
        if columns.is_empty() {
            return;
        }
        let _ = writeln!(
            s,
            "## Beyond the paper: {} m stairs and {} deg slopes\n\n\
             The terrain test's protocol (start, command, duration, success rule) on features past the paper's \
             range, on a course of their own. Cells: successes of trials (mean distance along the command, m).\n",
            terrain::BEYOND_STEP_HEIGHTS_M
                .iter()
                .map(|h| format!("{h:.2}"))
                .collect::<Vec<_>>()
                .join(", "),
            terrain::BEYOND_SLOPES_DEG
                .iter()
                .map(|d| format!("{d:.0}"))
                .collect::<Vec<_>>()
                .join(", "),
        );
        feature_rows(s, &columns);
        let _ = writeln!(s);
    }

    fn friction_section(&self, s: &mut String) {
        let runs: Vec<(&str, &[FrictionPoint])> = self
            .controllers
            .iter()
            .filter_map(|c| Some((c.name.as_str(), c.friction_sweep.as_deref()?)))
            .collect();
        let Some((_, first)) = runs.first() else {
            return;
        };
        let Some(point) = first.first() else {
            return;
        };
        let _ = writeln!(
            s,
            "## Contact friction on the hardest climbs\n\n\
             The terrain test's protocol on its {:.0} deg ramp and {:.2} m stairs, every robot's feet meeting the ground at one \
             friction coefficient per row: trial k is the same robot on every row, only the friction changes. Below \
             tan {:.0} deg = {:.3} no robot stands on the ramp. Cells: successes of trials (mean distance along the \
             command, m).\n",
            friction::SWEEP_SLOPE_DEG,
            friction::SWEEP_STEP_M,
            friction::SWEEP_SLOPE_DEG,
            friction::least_friction_to_stand(friction::SWEEP_SLOPE_DEG),
        );
        let headers: Vec<String> = runs
            .iter()
            .flat_map(|(name, _)| {
                point
                    .features
                    .iter()
                    .map(move |f| format!("{name}: {}", f.name))
            })
            .collect();
        let _ = writeln!(
            s,
            "| contact friction | {} |\n|---|{}",
            headers.join(" | "),
            "---|".repeat(headers.len())
        );
        for (k, p) in first.iter().enumerate() {
            let cells: Vec<String> = runs
                .iter()
                .flat_map(|(_, points)| {
                    let n = point.features.len();
                    (0..n).map(move |f| {
                        points
                            .get(k)
                            .and_then(|p| p.features.get(f))
                            .map(cell)
                            .unwrap_or_else(|| "-".into())
                    })
                })
                .collect();
            let _ = writeln!(s, "| {:.2} | {} |", p.contact_friction, cells.join(" | "));
        }
        let _ = writeln!(s);
    }

    fn sine_section(&self, s: &mut String) {
        let runs: Vec<(&ControllerReport, &Vec<SineRun>)> = self
            .controllers
            .iter()
            .filter_map(|c| Some((c, c.sine.as_ref()?)))
            .collect();
        if runs.is_empty() {
            return;
        }
        let _ = writeln!(
            s,
            "## Sinusoidal commands (Fig. 3)\n\n\
             On flat ground, after 1 s standing, one command axis follows A sin(2 pi t / {:.0} s) for {:.0} s \
             (vx: A = {:.1} m/s, vy: {:.1} m/s, yaw rate: {:.1} rad/s), the others stay 0. Velocities in the \
             heading frame; metrics over all trials and samples of the 20 s. Cross-axis: RMS of the planar \
             velocity not commanded (the other axis; for the yaw run, the planar speed).\n",
            super::sine::PERIOD_S,
            super::sine::DURATION_S,
            super::sine::AMPLITUDES[0],
            super::sine::AMPLITUDES[1],
            super::sine::AMPLITUDES[2],
        );
        let _ = writeln!(s, "| controller | command | tracking RMSE | cross-axis RMS, m/s | mean abs vz, m/s | roll RMS, deg | pitch RMS, deg | falls |\n|---|---|---|---|---|---|---|---|");
        for (c, rs) in &runs {
            for r in rs.iter() {
                let unit = if r.axis == "yaw_rate" { "rad/s" } else { "m/s" };
                let _ = writeln!(
                    s,
                    "| {} | {} | {:.3} {} | {:.3} | {:.3} | {:.2} | {:.2} | {}/{} |",
                    c.name,
                    r.axis,
                    r.tracking_rmse,
                    unit,
                    r.cross_axis_rms,
                    r.mean_abs_vz_m_s,
                    r.roll_rms_deg,
                    r.pitch_rms_deg,
                    r.falls,
                    r.trials
                );
            }
        }
        let _ = writeln!(
            s,
            "\nThe gait while the command is at least {:.0} % of its amplitude: the tripod score (the fraction of samples whose stance set is exactly one tripod) and the share of samples with n feet on the ground (contact force above {} N).\n",
            100.0 * super::sine::GAIT_MIN_COMMAND_FRACTION,
            host_sim::rewards::STANCE_FORCE_N
        );
        let _ = writeln!(s, "| controller | command | tripod score | 0-2 feet | 3 feet | 4 feet | 5 feet | 6 feet |\n|---|---|---|---|---|---|---|---|");
        for (c, rs) in &runs {
            for r in rs.iter() {
                let f = &r.feet_down_fraction;
                let _ = writeln!(
                    s,
                    "| {} | {} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} |",
                    c.name,
                    r.axis,
                    r.tripod_score,
                    f[0] + f[1] + f[2],
                    f[3],
                    f[4],
                    f[5],
                    f[6]
                );
            }
        }
        let _ = writeln!(s);
        for a in super::sine::AXES {
            self.plot_link(s, &format!("sine_{a}.png"));
        }
    }

    fn curriculum_section(&self, s: &mut String) {
        let runs: Vec<(&ControllerReport, &CurriculumResult)> = self
            .controllers
            .iter()
            .filter_map(|c| Some((c, c.curriculum.as_ref()?)))
            .collect();
        if runs.is_empty() {
            return;
        }
        let _ = writeln!(
            s,
            "## Curriculum (Fig. 4)\n\n\
             The mean terrain row of the robots on each tile kind's column, over training iterations, from the \
             run's `metrics.csv` (final: the mean of the last {} logged iterations). Rows: the checkpoint's grid; \
             a lineage that changed grids (its README says) logged earlier iterations in the rows of the grid it \
             had then, which `metrics.csv` does not record.\n",
            super::curriculum::FINAL_WINDOW
        );
        let _ = writeln!(s, "| controller | metrics | iterations | rows | tile kind: final row (highest) |\n|---|---|---|---|---|");
        let mut kinds: Vec<String> = Vec::new();
        for (c, r) in &runs {
            let its = r
                .iterations
                .map(|(a, b)| format!("{a:.0}-{b:.0}"))
                .unwrap_or_else(|| "-".into());
            let levels = if r.kinds.is_empty() {
                r.note.clone().unwrap_or_default()
            } else {
                r.kinds
                    .iter()
                    .map(|k| format!("{} {:.2} ({:.2})", k.kind, k.final_level, k.max_level))
                    .collect::<Vec<_>>()
                    .join("; ")
            };
            kinds.extend(r.kinds.iter().map(|k| k.kind.clone()));
            let _ = writeln!(
                s,
                "| {} | {} | {} | {} | {} |",
                c.name,
                r.metrics
                    .as_deref()
                    .map(|m| format!("`{m}`"))
                    .unwrap_or_else(|| "-".into()),
                its,
                r.rows,
                levels
            );
        }
        let _ = writeln!(s);
        kinds.sort();
        kinds.dedup();
        for k in kinds {
            self.plot_link(s, &format!("curriculum_{k}.png"));
        }
    }
}
