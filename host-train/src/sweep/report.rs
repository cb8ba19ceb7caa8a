//! `hexapod sweep report`: the jobs' suite reports gathered per controller over seeds: the
//! paper's Table III (largest tolerated push, mean and spread over seeds) and the Fig. 5
//! success matrix (successes over all seeds' trials, one column per controller), the Fig. 3
//! sinusoidal-command measures with the gait, and the Fig. 4 curriculum's final rows, as
//! `report.json` and `report.md` in the sweep's directory.

use super::spec::Sweep;
use super::task::{evaluated, state};
use anyhow::{bail, Context};
use serde::{Deserialize, Serialize};
use std::fmt::Write as _;

// What is read of a job's `suite/report.json` (the suite's own types only serialize).
#[derive(Deserialize)]
struct SuiteFile {
    complete: bool,
    controllers: Vec<ControllerFile>,
}
#[derive(Deserialize)]
struct ControllerFile {
    iteration: Option<usize>,
    push: Option<PushFile>,
    terrain: Option<TerrainFile>,
    #[serde(default)]
    sine: Option<Vec<SineFile>>,
    #[serde(default)]
    curriculum: Option<CurriculumFile>,
}
#[derive(Deserialize)]
struct SineFile {
    axis: String,
    trials: usize,
    falls: usize,
    tracking_rmse: f64,
    cross_axis_rms: f64,
    mean_abs_vz_m_s: f64,
    roll_rms_deg: f64,
    pitch_rms_deg: f64,
    // Suite reports made before the gait was measured have neither.
    #[serde(default)]
    tripod_score: Option<f64>,
    #[serde(default)]
    feet_down_fraction: Option<[f64; 7]>,
}
#[derive(Deserialize)]
struct CurriculumFile {
    kinds: Vec<KindFile>,
}
#[derive(Deserialize)]
struct KindFile {
    kind: String,
    final_level: f64,
}
#[derive(Deserialize)]
struct PushFile {
    conditions: Vec<ConditionFile>,
}
#[derive(Deserialize)]
struct ConditionFile {
    axis: String,
    gait: String,
    current: ToleranceFile,
    strict: ToleranceFile,
}
#[derive(Deserialize)]
struct ToleranceFile {
    tolerated_m_s: f64,
    failed_m_s: Option<f64>,
}
#[derive(Deserialize)]
struct TerrainFile {
    features: Vec<FeatureFile>,
    outdoor_step: Option<FeatureFile>,
}
#[derive(Deserialize)]
struct FeatureFile {
    name: String,
    trials: usize,
    successes: usize,
    falls: usize,
    mean_distance_m: f64,
}

/// Mean and spread of one figure over seeds.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct Spread {
    /// Mean.
    pub mean: f64,
    /// Sample standard deviation (0 for one seed).
    pub sd: f64,
    /// Smallest.
    pub min: f64,
    /// Largest.
    pub max: f64,
    /// Every seed's value, in seed order.
    pub values: Vec<f64>,
}

impl Spread {
    /// The spread of `values` (at least one).
    pub fn of(values: Vec<f64>) -> Self {
        let n = values.len() as f64;
        let mean = values.iter().sum::<f64>() / n;
        let sd = if values.len() > 1 {
            (values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt()
        } else {
            0.0
        };
        let min = values.iter().copied().fold(f64::INFINITY, f64::min);
        let max = values.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        Self {
            mean,
            sd,
            min,
            max,
            values,
        }
    }
}

/// One controller's largest tolerated push under one rule, axis and gait.
#[derive(Clone, Debug, Serialize)]
pub struct PushRow {
    /// Controller.
    pub controller: String,
    /// `X`, `Y` or `Z`.
    pub axis: String,
    /// `walk` or `stand`.
    pub gait: String,
    /// `strict` or `current`.
    pub rule: String,
    /// Largest tolerated magnitude, m/s, over seeds.
    pub tolerated_m_s: Spread,
    /// Seeds whose search never found a failing magnitude (their figure is a lower bound).
    pub lower_bounds: usize,
}

/// One controller on one terrain feature, over seeds.
#[derive(Clone, Debug, Serialize)]
pub struct FeatureCell {
    /// Successes over every seed's trials.
    pub successes: usize,
    /// Trials over every seed.
    pub trials: usize,
    /// Falls over every seed's trials.
    pub falls: usize,
    /// Success rate per seed.
    pub success_rate: Spread,
    /// Mean distance walked per seed, m.
    pub mean_distance_m: Spread,
}

/// One terrain feature, one cell per controller (none where a controller has no result).
#[derive(Clone, Debug, Serialize)]
pub struct FeatureRow {
    /// The feature (`stairs up 0.13 m`, ...).
    pub feature: String,
    /// Cells in controller order.
    pub cells: Vec<Option<FeatureCell>>,
}

/// One controller on one sinusoidal-command axis (Fig. 3), over seeds.
#[derive(Clone, Debug, Serialize)]
pub struct SineRow {
    /// Controller.
    pub controller: String,
    /// `vx`, `vy` or `yaw_rate`.
    pub axis: String,
    /// Tracking RMSE (m/s or rad/s).
    pub tracking_rmse: Spread,
    /// Cross-axis RMS, m/s.
    pub cross_axis_rms: Spread,
    /// Mean |vz|, m/s.
    pub mean_abs_vz_m_s: Spread,
    /// Roll RMS, deg.
    pub roll_rms_deg: Spread,
    /// Pitch RMS, deg.
    pub pitch_rms_deg: Spread,
    /// Falls over every seed's trials, and the trials.
    pub falls: (usize, usize),
    /// Tripod score (seeds whose report measured it).
    pub tripod_score: Option<Spread>,
    /// Feet-down histogram, the mean over those seeds.
    pub feet_down_fraction: Option<[f64; 7]>,
}

/// One controller's final curriculum row on one tile kind (Fig. 4), over seeds.
#[derive(Clone, Debug, Serialize)]
pub struct CurriculumRow {
    /// Controller.
    pub controller: String,
    /// Tile kind.
    pub kind: String,
    /// The mean terrain row of the last logged iterations.
    pub final_level: Spread,
}

/// One controller's jobs.
#[derive(Clone, Debug, Serialize)]
pub struct ControllerSummary {
    /// Controller.
    pub name: String,
    /// Seeds whose job is done and reported.
    pub seeds: Vec<u64>,
    /// Training iterations of those jobs' policies.
    pub iterations: Vec<Option<usize>>,
    /// For a reference controller (`[[reference]]`, not trained by the sweep): its suite report.
    pub reference: Option<String>,
}

/// One reported run: a sweep job's or a reference's suite report.
struct Entry {
    controller: String,
    seed: Option<u64>,
    file: ControllerFile,
}

/// The gathered report.
#[derive(Clone, Debug, Serialize)]
pub struct SweepReport {
    /// Sweep name.
    pub sweep: String,
    /// The sweep file.
    pub spec_file: String,
    /// Jobs left out because they were not finished (only with `--partial`).
    pub missing: Vec<String>,
    /// Controllers in the sweep's order.
    pub controllers: Vec<ControllerSummary>,
    /// Table III and the other axes.
    pub push: Vec<PushRow>,
    /// The success matrix.
    pub terrain: Vec<FeatureRow>,
    /// The outdoor step, one cell per controller.
    pub outdoor_step: Vec<Option<FeatureCell>>,
    /// The sinusoidal commands and the gait (Fig. 3).
    pub sine: Vec<SineRow>,
    /// The curriculum's final rows (Fig. 4).
    pub curriculum: Vec<CurriculumRow>,
    /// The learning curves' figure, relative to the report (`curves.rs`), once drawn.
    pub curves: Option<String>,
}

fn sine_rows(name: &str, jobs: &[&Entry]) -> Vec<SineRow> {
    let runs: Vec<&Vec<SineFile>> = jobs.iter().filter_map(|e| e.file.sine.as_ref()).collect();
    let Some(first) = runs.first() else {
        return Vec::new();
    };
    first
        .iter()
        .map(|axis| {
            let per_seed: Vec<&SineFile> = runs
                .iter()
                .filter_map(|r| r.iter().find(|x| x.axis == axis.axis))
                .collect();
            let of =
                |f: &dyn Fn(&SineFile) -> f64| Spread::of(per_seed.iter().map(|x| f(x)).collect());
            let gait: Vec<(f64, [f64; 7])> = per_seed
                .iter()
                .filter_map(|x| Some((x.tripod_score?, x.feet_down_fraction?)))
                .collect();
            SineRow {
                controller: name.to_string(),
                axis: axis.axis.clone(),
                tracking_rmse: of(&|x| x.tracking_rmse),
                cross_axis_rms: of(&|x| x.cross_axis_rms),
                mean_abs_vz_m_s: of(&|x| x.mean_abs_vz_m_s),
                roll_rms_deg: of(&|x| x.roll_rms_deg),
                pitch_rms_deg: of(&|x| x.pitch_rms_deg),
                falls: (
                    per_seed.iter().map(|x| x.falls).sum(),
                    per_seed.iter().map(|x| x.trials).sum(),
                ),
                tripod_score: (!gait.is_empty())
                    .then(|| Spread::of(gait.iter().map(|g| g.0).collect())),
                feet_down_fraction: (!gait.is_empty()).then(|| {
                    std::array::from_fn(|k| {
                        gait.iter().map(|g| g.1[k]).sum::<f64>() / gait.len() as f64
                    })
                }),
            }
        })
        .collect()
}

fn curriculum_rows(name: &str, jobs: &[&Entry]) -> Vec<CurriculumRow> {
    let curves: Vec<&CurriculumFile> = jobs
        .iter()
        .filter_map(|e| e.file.curriculum.as_ref())
        .collect();
    let mut kinds: Vec<&str> = Vec::new();
    for k in curves.iter().flat_map(|c| &c.kinds) {
        if !kinds.contains(&k.kind.as_str()) {
            kinds.push(&k.kind);
        }
    }
    kinds
        .into_iter()
        .map(|kind| CurriculumRow {
            controller: name.to_string(),
            kind: kind.to_string(),
            final_level: Spread::of(
                curves
                    .iter()
                    .filter_map(|c| c.kinds.iter().find(|k| k.kind == kind))
                    .map(|k| k.final_level)
                    .collect(),
            ),
        })
        .collect()
}

fn cell(results: &[&FeatureFile]) -> Option<FeatureCell> {
    if results.is_empty() {
        return None;
    }
    Some(FeatureCell {
        successes: results.iter().map(|f| f.successes).sum(),
        trials: results.iter().map(|f| f.trials).sum(),
        falls: results.iter().map(|f| f.falls).sum(),
        success_rate: Spread::of(
            results
                .iter()
                .map(|f| f.successes as f64 / f.trials.max(1) as f64)
                .collect(),
        ),
        mean_distance_m: Spread::of(results.iter().map(|f| f.mean_distance_m).collect()),
    })
}

/// The first controller of a complete suite report.
fn read_suite_report(path: &std::path::Path) -> anyhow::Result<ControllerFile> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
    let file: SuiteFile = serde_json::from_str(&text)
        .map_err(|e| anyhow::anyhow!("{}: not a suite report: {e}", path.display()))?;
    file.controllers
        .into_iter()
        .next()
        .filter(|_| file.complete)
        .with_context(|| format!("{}: an incomplete suite report", path.display()))
}

/// Reads every job's suite report, then the references'. Unfinished jobs are an error
/// naming them, unless `partial` (then they are listed in the report as missing).
pub fn gather(sweep: &Sweep, partial: bool) -> anyhow::Result<SweepReport> {
    let mut missing = Vec::new();
    let mut done: Vec<Entry> = Vec::new();
    for job in &sweep.jobs {
        if !evaluated(job) {
            missing.push(format!("{} ({})", job.name(), state(job)));
            continue;
        }
        done.push(Entry {
            controller: job.controller.clone(),
            seed: Some(job.seed),
            file: read_suite_report(&job.suite_dir().join("report.json"))?,
        });
    }
    if done.is_empty() {
        bail!(
            "sweep `{}`: no job has finished yet ({} of {}); run `hexapod sweep run {}` first",
            sweep.spec.name,
            missing.len(),
            sweep.jobs.len(),
            sweep.path.display()
        );
    }
    if !missing.is_empty() && !partial {
        bail!(
            "sweep `{}`: {} of {} jobs are not finished: {}; run the sweep again to finish them, or report what is done with --partial",
            sweep.spec.name,
            missing.len(),
            sweep.jobs.len(),
            missing.join(", ")
        );
    }
    let mut names = sweep.controllers();
    for r in &sweep.references {
        done.push(Entry {
            controller: r.name.clone(),
            seed: None,
            file: read_suite_report(&r.report)
                .with_context(|| format!("the reference controller `{}`", r.name))?,
        });
        names.push(r.name.clone());
    }
    let of = |name: &str| -> Vec<&Entry> { done.iter().filter(|e| e.controller == name).collect() };
    let controllers = names
        .iter()
        .map(|n| ControllerSummary {
            name: n.clone(),
            seeds: of(n).iter().filter_map(|e| e.seed).collect(),
            iterations: of(n).iter().map(|e| e.file.iteration).collect(),
            reference: sweep
                .references
                .iter()
                .find(|r| &r.name == n)
                .map(|r| r.report.display().to_string()),
        })
        .collect();

    let mut push = Vec::new();
    for name in &names {
        let jobs = of(name);
        let Some(first) = jobs.iter().find_map(|e| e.file.push.as_ref()) else {
            continue;
        };
        for rule in ["strict", "current"] {
            for cond in &first.conditions {
                let mut values = Vec::new();
                let mut lower_bounds = 0;
                for e in &jobs {
                    let hit = e.file.push.as_ref().and_then(|p| {
                        p.conditions
                            .iter()
                            .find(|k| k.axis == cond.axis && k.gait == cond.gait)
                    });
                    if let Some(k) = hit {
                        let t = if rule == "strict" {
                            &k.strict
                        } else {
                            &k.current
                        };
                        values.push(t.tolerated_m_s);
                        lower_bounds += t.failed_m_s.is_none() as usize;
                    }
                }
                push.push(PushRow {
                    controller: name.clone(),
                    axis: cond.axis.clone(),
                    gait: cond.gait.clone(),
                    rule: rule.into(),
                    tolerated_m_s: Spread::of(values),
                    lower_bounds,
                });
            }
        }
    }

    let mut features: Vec<String> = Vec::new();
    for e in &done {
        for f in e.file.terrain.iter().flat_map(|t| &t.features) {
            if !features.contains(&f.name) {
                features.push(f.name.clone());
            }
        }
    }
    let terrain = features
        .iter()
        .map(|feature| FeatureRow {
            feature: feature.clone(),
            cells: names
                .iter()
                .map(|n| {
                    let results: Vec<&FeatureFile> = of(n)
                        .iter()
                        .filter_map(|e| {
                            e.file
                                .terrain
                                .as_ref()?
                                .features
                                .iter()
                                .find(|f| &f.name == feature)
                        })
                        .collect();
                    cell(&results)
                })
                .collect(),
        })
        .collect();
    let outdoor_step = names
        .iter()
        .map(|n| {
            let results: Vec<&FeatureFile> = of(n)
                .iter()
                .filter_map(|e| e.file.terrain.as_ref()?.outdoor_step.as_ref())
                .collect();
            cell(&results)
        })
        .collect();
    let sine = names.iter().flat_map(|n| sine_rows(n, &of(n))).collect();
    let curriculum = names
        .iter()
        .flat_map(|n| curriculum_rows(n, &of(n)))
        .collect();
    Ok(SweepReport {
        sweep: sweep.spec.name.clone(),
        spec_file: sweep.path.display().to_string(),
        missing,
        controllers,
        push,
        terrain,
        outdoor_step,
        sine,
        curriculum,
        curves: None,
    })
}

fn spread(s: &Spread, lower_bounds: usize) -> String {
    let ge = if lower_bounds > 0 { ">= " } else { "" };
    if s.values.len() == 1 {
        format!("{ge}{:.2}", s.mean)
    } else {
        format!(
            "{ge}{:.2} ± {:.2} ({:.2}-{:.2})",
            s.mean, s.sd, s.min, s.max
        )
    }
}

fn spread3(s: &Spread) -> String {
    if s.values.len() == 1 {
        format!("{:.3}", s.mean)
    } else {
        format!("{:.3} ± {:.3} ({:.3}-{:.3})", s.mean, s.sd, s.min, s.max)
    }
}

fn cell_text(c: &Option<FeatureCell>) -> String {
    match c {
        None => "-".into(),
        Some(c) if c.success_rate.values.len() > 1 => {
            format!(
                "{}/{} (± {:.0} %, {:.2} m)",
                c.successes,
                c.trials,
                100.0 * c.success_rate.sd,
                c.mean_distance_m.mean
            )
        }
        Some(c) => format!(
            "{}/{} ({:.2} m)",
            c.successes, c.trials, c.mean_distance_m.mean
        ),
    }
}

impl SweepReport {
    /// The report as Markdown.
    pub fn markdown(&self) -> String {
        let mut s = String::new();
        let _ = writeln!(s, "# Sweep `{}`\n", self.sweep);
        let _ = writeln!(
            s,
            "Made by `hexapod sweep report {}` from each job's suite report (`<job>/suite/report.md` has every \
             figure of one seed). Figures are mean ± standard deviation over seeds (smallest-largest); \
             \">=\" where a seed's push search never found a failing magnitude.\n",
            self.spec_file
        );
        let _ = writeln!(
            s,
            "| controller | seeds | training iterations |\n|---|---|---|"
        );
        for c in &self.controllers {
            if let Some(report) = &c.reference {
                let _ = writeln!(
                    s,
                    "| {} | one run, not trained by the sweep: `{report}` | - |",
                    c.name
                );
                continue;
            }
            let seeds: Vec<String> = c.seeds.iter().map(|x| x.to_string()).collect();
            let its: Vec<String> = c
                .iterations
                .iter()
                .map(|i| i.map(|i| i.to_string()).unwrap_or_else(|| "?".into()))
                .collect();
            let _ = writeln!(
                s,
                "| {} | {} | {} |",
                c.name,
                seeds.join(", "),
                its.join(", ")
            );
        }
        if !self.missing.is_empty() {
            let _ = writeln!(
                s,
                "\n**Not finished, left out:** {}.",
                self.missing.join(", ")
            );
        }
        if !self.push.is_empty() {
            let _ = writeln!(s, "\n## Velocity-disturbance tolerance (Table III: Y axis, walking at 0.3 m/s), m/s\n");
            let _ = writeln!(
                s,
                "| controller | strict rule | current rule |\n|---|---|---|"
            );
            for c in &self.controllers {
                let row = |rule: &str| {
                    self.push
                        .iter()
                        .find(|r| {
                            r.controller == c.name
                                && r.rule == rule
                                && r.axis == "Y"
                                && r.gait == "walk"
                        })
                        .map(|r| spread(&r.tolerated_m_s, r.lower_bounds))
                        .unwrap_or_else(|| "-".into())
                };
                let _ = writeln!(s, "| {} | {} | {} |", c.name, row("strict"), row("current"));
            }
            let _ = writeln!(s, "\n### Every axis, m/s\n\n| controller | rule | axis, gait | tolerated |\n|---|---|---|---|");
            for r in &self.push {
                let _ = writeln!(
                    s,
                    "| {} | {} | {} {} | {} |",
                    r.controller,
                    r.rule,
                    r.axis,
                    r.gait,
                    spread(&r.tolerated_m_s, r.lower_bounds)
                );
            }
        }
        if !self.terrain.is_empty() {
            let names: Vec<&str> = self.controllers.iter().map(|c| c.name.as_str()).collect();
            let _ = writeln!(
                s,
                "\n## Terrain success (Fig. 5): successes / trials over every seed (± per-seed spread of the rate, mean distance)\n"
            );
            let _ = writeln!(
                s,
                "| feature | {} |\n|---|{}",
                names.join(" | "),
                "---|".repeat(names.len())
            );
            for row in &self.terrain {
                let cells: Vec<String> = row.cells.iter().map(cell_text).collect();
                let _ = writeln!(s, "| {} | {} |", row.feature, cells.join(" | "));
            }
            if self.outdoor_step.iter().any(Option::is_some) {
                let cells: Vec<String> = self.outdoor_step.iter().map(cell_text).collect();
                let _ = writeln!(s, "| outdoor step 0.15 m | {} |", cells.join(" | "));
            }
        }
        if !self.sine.is_empty() {
            let _ = writeln!(
                s,
                "\n## Sinusoidal commands (Fig. 3)\n\nTracking RMSE in m/s (rad/s for the yaw rate); cross-axis RMS and mean |vz| in m/s; roll and pitch RMS in deg.\n"
            );
            let _ = writeln!(s, "| controller | command | tracking RMSE | cross-axis RMS | mean abs vz | roll RMS | pitch RMS | falls |\n|---|---|---|---|---|---|---|---|");
            for r in &self.sine {
                let _ = writeln!(
                    s,
                    "| {} | {} | {} | {} | {} | {} | {} | {}/{} |",
                    r.controller,
                    r.axis,
                    spread3(&r.tracking_rmse),
                    spread3(&r.cross_axis_rms),
                    spread3(&r.mean_abs_vz_m_s),
                    spread(&r.roll_rms_deg, 0),
                    spread(&r.pitch_rms_deg, 0),
                    r.falls.0,
                    r.falls.1
                );
            }
            if self.sine.iter().any(|r| r.tripod_score.is_some()) {
                let _ = writeln!(s, "\n### The gait during the sinusoidal commands (command at least half its amplitude)\n\nTripod score: the fraction of samples whose stance set is exactly one tripod; then the share of samples with n feet on the ground (mean over seeds).\n");
                let _ = writeln!(s, "| controller | command | tripod score | 0-2 feet | 3 feet | 4 feet | 5 feet | 6 feet |\n|---|---|---|---|---|---|---|---|");
                for r in &self.sine {
                    let (Some(t), Some(f)) = (&r.tripod_score, &r.feet_down_fraction) else {
                        continue;
                    };
                    let _ = writeln!(
                        s,
                        "| {} | {} | {} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} |",
                        r.controller,
                        r.axis,
                        spread(t, 0),
                        f[0] + f[1] + f[2],
                        f[3],
                        f[4],
                        f[5],
                        f[6]
                    );
                }
            }
        }
        if let Some(curves) = &self.curves {
            let _ = writeln!(s, "\n## Learning curves\n\n![{curves}]({curves})");
        }
        if !self.curriculum.is_empty() {
            let _ = writeln!(s, "\n## Curriculum (Fig. 4): final terrain row per tile kind\n\n| controller | tile kind | final row |\n|---|---|---|");
            for r in &self.curriculum {
                let _ = writeln!(
                    s,
                    "| {} | {} | {} |",
                    r.controller,
                    r.kind,
                    spread(&r.final_level, 0)
                );
            }
        }
        s
    }

    /// Writes `report.json` and `report.md` into the sweep's directory.
    pub fn write(&self, sweep: &Sweep) -> anyhow::Result<()> {
        std::fs::create_dir_all(&sweep.dir)
            .with_context(|| format!("creating {}", sweep.dir.display()))?;
        let json = sweep.dir.join("report.json");
        std::fs::write(&json, serde_json::to_string_pretty(self)?)
            .with_context(|| format!("writing {}", json.display()))?;
        let md = sweep.dir.join("report.md");
        std::fs::write(&md, self.markdown())
            .with_context(|| format!("writing {}", md.display()))?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sweep::spec::parse;
    use std::path::Path;

    /// A job trained to its last iteration (an empty checkpoint) with `json` as its suite
    /// report.
    fn write_finished_job(job: &crate::sweep::spec::Job, json: &str) {
        let ckpt = job.run_dir().join("checkpoints/model_000007");
        std::fs::create_dir_all(&ckpt).unwrap();
        std::fs::write(ckpt.join("config.toml"), "").unwrap();
        std::fs::write(ckpt.join("policy.safetensors"), "").unwrap();
        std::fs::write(
            ckpt.join("state.json"),
            format!("{{\"iteration\": {}}}", job.max_iterations),
        )
        .unwrap();
        std::fs::create_dir_all(job.suite_dir()).unwrap();
        std::fs::write(job.suite_dir().join("report.json"), json).unwrap();
    }

    fn suite_json(y_strict: f64, y_failed: Option<f64>, stairs: usize) -> String {
        suite_json_with(y_strict, y_failed, stairs, "")
    }

    /// `extra`: more fields of the controller (a leading comma included).
    fn suite_json_with(y_strict: f64, y_failed: Option<f64>, stairs: usize, extra: &str) -> String {
        let failed = y_failed
            .map(|f| f.to_string())
            .unwrap_or_else(|| "null".into());
        format!(
            r#"{{"suite": "paper", "complete": true, "controllers": [{{"name": "run", "iteration": 7,
            "push": {{"conditions": [{{"axis": "Y", "gait": "walk", "current": {{"tolerated_m_s": 3.0, "failed_m_s": 3.5}},
            "strict": {{"tolerated_m_s": {y_strict}, "failed_m_s": {failed}}}, "points": []}}]}},
            "terrain": {{"features": [{{"feature": {{}}, "name": "stairs up 0.13 m", "trials": 10, "successes": {stairs}, "falls": 1,
            "mean_distance_m": 2.0}}], "outdoor_step": null}}{extra}}}]}}"#
        )
    }

    fn sine_json(rmse: f64, tripod: Option<f64>, stairs_up_row: f64) -> String {
        let gait = tripod
            .map(|t| {
                format!(
                    r#", "tripod_score": {t}, "feet_down_fraction": [0, 0, 0, {t}, 0, 0, {}]"#,
                    1.0 - t
                )
            })
            .unwrap_or_default();
        format!(
            r#", "sine": [{{"axis": "vx", "trials": 10, "falls": 1, "tracking_rmse": {rmse}, "cross_axis_rms": 0.05,
            "mean_abs_vz_m_s": 0.03, "roll_rms_deg": 1.0, "pitch_rms_deg": 2.0{gait}}}],
            "curriculum": {{"kinds": [{{"kind": "StairsUp", "final_level": {stairs_up_row}, "max_level": 9.0}}]}}"#
        )
    }

    #[test]
    fn the_sine_runs_gait_and_curriculum_are_gathered_over_seeds() {
        let dir = std::env::temp_dir().join(format!("hexapod-sweep-sine-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let spec = format!("name = \"r\"\nout_dir = \"{}\"\npresets = [\"configs/baseline.toml\"]\nseeds = [1, 2]\n", dir.display());
        let sweep = parse(&spec, Path::new("r.toml")).unwrap();
        for (i, (rmse, tripod, row)) in [(0.1, Some(0.8), 2.0), (0.2, None, 4.0)]
            .into_iter()
            .enumerate()
        {
            let json = suite_json_with(1.0, Some(1.1), 5, &sine_json(rmse, tripod, row));
            write_finished_job(&sweep.jobs[i], &json);
        }
        let r = gather(&sweep, false).unwrap();
        let vx = &r.sine[0];
        assert!((vx.tracking_rmse.mean - 0.15).abs() < 1e-12);
        assert_eq!(vx.falls, (2, 20));
        // Only seed 1's report measured the gait.
        assert_eq!(vx.tripod_score.as_ref().unwrap().values, [0.8]);
        assert!((vx.feet_down_fraction.unwrap()[6] - 0.2).abs() < 1e-12);
        assert_eq!(r.curriculum[0].final_level.mean, 3.0);
        let md = r.markdown();
        assert!(
            md.contains("| baseline | vx | 0.150 ± 0.071 (0.100-0.200) |"),
            "{md}"
        );
        assert!(
            md.contains("| baseline | vx | 0.80 | 0.00 | 0.80 | 0.00 | 0.00 | 0.20 |"),
            "{md}"
        );
        assert!(
            md.contains("| baseline | StairsUp | 3.00 ± 1.41 (2.00-4.00) |"),
            "{md}"
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn seeds_are_gathered_per_controller_and_unfinished_jobs_are_named() {
        let dir = std::env::temp_dir().join(format!("hexapod-sweep-report-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let spec = format!("name = \"r\"\nout_dir = \"{}\"\npresets = [\"configs/baseline.toml\", \"configs/concurrent.toml\"]\nseeds = [1, 2]\n", dir.display());
        let sweep = parse(&spec, Path::new("r.toml")).unwrap();
        let write = |i: usize, json: String| write_finished_job(&sweep.jobs[i], &json);
        write(0, suite_json(1.0, Some(1.1), 6));
        write(1, suite_json(2.0, None, 9));
        write(2, suite_json(0.5, Some(0.6), 1));

        let e = format!("{:#}", gather(&sweep, false).unwrap_err());
        assert!(
            e.contains("1 of 4 jobs are not finished")
                && e.contains("concurrent-s2 (pending)")
                && e.contains("--partial"),
            "{e}"
        );

        let r = gather(&sweep, true).unwrap();
        assert_eq!(r.missing, ["concurrent-s2 (pending)"]);
        assert_eq!(r.controllers[0].seeds, [1, 2]);
        assert_eq!(r.controllers[1].seeds, [1]);
        let strict = r
            .push
            .iter()
            .find(|p| p.controller == "baseline" && p.rule == "strict")
            .unwrap();
        assert_eq!(strict.tolerated_m_s.mean, 1.5);
        assert!((strict.tolerated_m_s.sd - 0.5f64.sqrt()).abs() < 1e-12);
        assert_eq!(strict.lower_bounds, 1);
        let stairs = r.terrain[0].cells[0].as_ref().unwrap();
        assert_eq!((stairs.successes, stairs.trials, stairs.falls), (15, 20, 2));
        assert_eq!(r.terrain[0].cells[1].as_ref().unwrap().successes, 1);
        let md = r.markdown();
        assert!(
            md.contains("| baseline | >= 1.50 ± 0.71 (1.00-2.00) | 3.00 ± 0.00 (3.00-3.00) |"),
            "{md}"
        );
        assert!(
            md.contains("| stairs up 0.13 m | 15/20 (± 21 %, 2.00 m) | 1/10 (2.00 m) |"),
            "{md}"
        );
        r.write(&sweep).unwrap();
        assert!(dir.join("report.md").is_file() && dir.join("report.json").is_file());
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_reference_controller_is_reported_beside_the_trained_ones() {
        let dir = std::env::temp_dir().join(format!("hexapod-sweep-ref-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let reference = dir.join("mpc-report.json");
        std::fs::write(&reference, suite_json(0.7, Some(0.8), 3)).unwrap();
        let spec = |report: &str| {
            format!(
                "name = \"r\"\nout_dir = \"{}\"\npresets = [\"configs/baseline.toml\"]\nseeds = [1]\n[[reference]]\nname = \"mpc\"\nreport = \"{report}\"\n",
                dir.display()
            )
        };
        let sweep = parse(&spec(&reference.display().to_string()), Path::new("r.toml")).unwrap();
        write_finished_job(&sweep.jobs[0], &suite_json(1.0, Some(1.1), 6));
        let r = gather(&sweep, false).unwrap();
        assert_eq!(r.controllers.len(), 2);
        assert_eq!(r.controllers[1].name, "mpc");
        assert!(r.controllers[1].seeds.is_empty());
        assert_eq!(r.terrain[0].cells[1].as_ref().unwrap().successes, 3);
        let md = r.markdown();
        assert!(md.contains("| mpc | 0.70 | 3.00 |"), "{md}");
        assert!(
            md.contains("| mpc | one run, not trained by the sweep:"),
            "{md}"
        );

        std::fs::write(&reference, "{\"complete\": false, \"controllers\": []}").unwrap();
        let e = format!("{:#}", gather(&sweep, false).unwrap_err());
        assert!(
            e.contains("reference controller `mpc`") && e.contains("incomplete"),
            "{e}"
        );
        let e = format!(
            "{:#}",
            parse(&spec("no/such/report.json"), Path::new("r.toml")).unwrap_err()
        );
        assert!(e.contains("reference `mpc`: no suite report"), "{e}");
        let e = format!(
            "{:#}",
            parse(
                &spec(&reference.display().to_string()).replace("\"mpc\"", "\"baseline\""),
                Path::new("r.toml")
            )
            .unwrap_err()
        );
        assert!(e.contains("reference `baseline`"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
