//! The sweep's learning curves (`curves.png` beside `report.md`): every job's `metrics.csv`,
//! one colour per controller (its first seed solid, the others dashed), smoothed over a
//! window of iterations: the
//! planar tracking error, the style reward as a fraction of its maximum, the
//! discriminator's mean output on the policy's transitions, and the mean terrain row.

use super::spec::{job_config, Job, Sweep};
use crate::metrics::MetricsLog;
use hexapod_core::timing::POLICY_DT_S;
use host_sim::plot::{write_panels, Line, Panel};
use std::collections::BTreeMap;
use std::path::PathBuf;

/// Iterations of the moving average.
pub const SMOOTHING_ITERATIONS: usize = 20;

/// One metric of the figure: its column, how a value is scaled for a job, and the panel.
struct Curve {
    column: &'static str,
    title: &'static str,
    y_label: &'static str,
    /// Per job: the factor a logged value is multiplied by (None: the job has no such curve).
    scale: fn(&Job) -> Option<f64>,
}

fn unit(_: &Job) -> Option<f64> {
    Some(1.0)
}

/// 1 / the style reward's largest value per step (`style_weight x dt`); none without style.
fn style_fraction(job: &Job) -> Option<f64> {
    let cfg = job_config(&job.preset, &job.overrides, job.seed).ok()?;
    (cfg.rewards.style && cfg.rewards.style_weight > 0.0)
        .then(|| 1.0 / (cfg.rewards.style_weight as f64 * POLICY_DT_S as f64))
}

/// 1 where the job trains a discriminator; none without (its logged output is a placeholder 0).
fn with_discriminator(job: &Job) -> Option<f64> {
    let cfg = job_config(&job.preset, &job.overrides, job.seed).ok()?;
    cfg.amp_enabled().then_some(1.0)
}

const CURVES: [Curve; 4] = [
    Curve {
        column: "tracking/lin_vel_error_m_s",
        title: "planar tracking error",
        y_label: "error (m/s)",
        scale: unit,
    },
    Curve {
        column: "reward/style",
        title: "style reward / its maximum",
        y_label: "fraction",
        scale: style_fraction,
    },
    Curve {
        column: "amp/d_policy",
        title: "discriminator on the policy (prior: +1, policy: -1)",
        y_label: "mean output",
        scale: with_discriminator,
    },
    Curve {
        column: "episode/terrain_level",
        title: "mean terrain row",
        y_label: "row",
        scale: unit,
    },
];

/// `values` by iteration, averaged over the trailing window.
fn smooth(values: &BTreeMap<i64, f64>) -> BTreeMap<i64, f64> {
    let v: Vec<(i64, f64)> = values.iter().map(|(&k, &x)| (k, x)).collect();
    (0..v.len())
        .map(|i| {
            let from = i.saturating_sub(SMOOTHING_ITERATIONS - 1);
            let window = &v[from..=i];
            (
                v[i].0,
                window.iter().map(|p| p.1).sum::<f64>() / window.len() as f64,
            )
        })
        .collect()
}

/// A job's smoothed curve, scaled; empty when the job has no such curve.
fn job_curve(job: &Job, log: &MetricsLog, curve: &Curve) -> Vec<(f64, f64)> {
    let Some(scale) = (curve.scale)(job) else {
        return Vec::new();
    };
    let values: BTreeMap<i64, f64> = log
        .rows()
        .iter()
        .filter_map(|r| {
            let x = *r.get(curve.column)?;
            let iteration = *r.get("iteration")? as i64;
            x.is_finite().then_some((iteration, x * scale))
        })
        .collect();
    smooth(&values)
        .into_iter()
        .map(|(k, x)| (k as f64, x))
        .collect()
}

/// Draws `curves.png` into the sweep's directory from the jobs that have a `metrics.csv`;
/// returns its path, or None when no job has one.
pub fn write(sweep: &Sweep) -> anyhow::Result<Option<PathBuf>> {
    let mut panels: Vec<Panel> = CURVES
        .iter()
        .map(|c| Panel::new(c.title, "iteration", c.y_label).integer_x())
        .collect();
    let mut any = false;
    for (k, name) in sweep.controllers().iter().enumerate() {
        let jobs = sweep.jobs.iter().filter(|j| &j.controller == name);
        for (n, job) in jobs.enumerate() {
            let Ok(log) = MetricsLog::read_csv(&job.run_dir().join("metrics.csv")) else {
                continue;
            };
            for (panel, curve) in panels.iter_mut().zip(&CURVES) {
                let points = job_curve(job, &log, curve);
                if points.is_empty() {
                    continue;
                }
                any = true;
                let line = Line::nth(k, format!("{name} s{}", job.seed), points);
                panel.lines.push(if n == 0 { line } else { line.dashed() });
            }
        }
    }
    if !any {
        return Ok(None);
    }
    let path = sweep.dir.join("curves.png");
    write_panels(
        &path,
        Some(&format!(
            "sweep `{}`: every job, {SMOOTHING_ITERATIONS}-iteration moving average",
            sweep.spec.name
        )),
        2,
        (760, 380),
        &panels,
    )?;
    Ok(Some(path))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn smoothing_averages_the_trailing_window() {
        let values: BTreeMap<i64, f64> = (0..30).map(|i| (i, i as f64)).collect();
        let s = smooth(&values);
        assert_eq!(s[&0], 0.0);
        assert_eq!(s[&1], 0.5);
        // Iteration 29: the mean of 10..=29.
        assert_eq!(s[&29], 19.5);
    }
}
