//! Learning curves of several runs on one axis: iterations, environment steps or training
//! time, so that runs of different sizes (robots per iteration, discriminator steps,
//! machines) compare by what they cost. Each run's series is a moving mean over a window of
//! iterations (per-iteration values are noisy); rows without the key are skipped.

use super::MetricsLog;
use host_sim::plot::{write_panels, Line, Panel};
use std::path::Path;

/// What the curves run against.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum XAxis {
    /// Training iterations.
    Iteration,
    /// Environment steps (robots x steps per iteration), millions.
    EnvSteps,
    /// Training time, hours: the sum of each iteration's collection and update
    /// (`perf/collect_s + perf/update_s`; checkpoint writing and pauses not counted).
    WallClock,
}

impl XAxis {
    fn label(self) -> &'static str {
        match self {
            XAxis::Iteration => "iteration",
            XAxis::EnvSteps => "environment steps (millions)",
            XAxis::WallClock => "training time (h, collection + update)",
        }
    }
}

/// The series compared by default: tracking, the style reward and the discriminator's
/// verdict on the rollouts, the curriculum and the policy's action noise.
pub const COMPARED_KEYS: &[(&str, &str)] = &[
    ("tracking/lin_vel_error_m_s", "planar velocity error (m/s)"),
    ("tracking/yaw_rate_error_rad_s", "yaw rate error (rad/s)"),
    ("reward/style", "style reward per policy step"),
    ("amp/d_policy_rollout", "D output on the rollouts"),
    ("episode/terrain_level", "terrain level (row)"),
    ("train/action_std", "action noise std"),
];

/// The x coordinate of every row (`None` where the row lacks what the axis needs), in order.
pub fn x_coordinates(log: &MetricsLog, axis: XAxis) -> Vec<Option<f64>> {
    let mut total = 0.0;
    log.rows()
        .iter()
        .map(|row| {
            let get = |key: &str| row.get(key).copied().unwrap_or(f64::NAN);
            let time_s = || get("perf/collect_s") + get("perf/update_s");
            let step = match axis {
                XAxis::Iteration => return row.get("iteration").copied(),
                XAxis::WallClock => time_s() / 3600.0,
                XAxis::EnvSteps => get("perf/env_steps_per_s") * time_s() / 1e6,
            };
            if !step.is_finite() {
                return None;
            }
            total += step;
            Some(total)
        })
        .collect()
}

/// `key` against the rows' x coordinates `xs` ([`x_coordinates`]), each point the mean of
/// the last `window` finite values (fewer at the start).
pub fn smoothed_curve(
    log: &MetricsLog,
    key: &str,
    xs: &[Option<f64>],
    window: usize,
) -> Vec<(f64, f64)> {
    let window = window.max(1);
    let mut recent = std::collections::VecDeque::with_capacity(window);
    let mut sum = 0.0;
    let mut points = Vec::new();
    for (row, &x) in log.rows().iter().zip(xs) {
        let Some(y) = row.get(key).copied().filter(|y| y.is_finite()) else {
            continue;
        };
        recent.push_back(y);
        sum += y;
        if recent.len() > window {
            sum -= recent.pop_front().unwrap_or(0.0);
        }
        if let Some(x) = x {
            points.push((x, sum / recent.len() as f64));
        }
    }
    points
}

/// Draws one panel per key that some run has (and that is not one constant), one line per
/// run, into the PNG `path`.
/// Returns the number of panels drawn.
pub fn write_comparison(
    path: &Path,
    runs: &[(String, MetricsLog)],
    keys: &[(&str, &str)],
    axis: XAxis,
    window: usize,
) -> Result<usize, String> {
    let xs: Vec<Vec<Option<f64>>> = runs
        .iter()
        .map(|(_, log)| x_coordinates(log, axis))
        .collect();
    let mut panels = Vec::new();
    for (key, y_label) in keys {
        let lines: Vec<Line> = runs
            .iter()
            .zip(&xs)
            .enumerate()
            .map(|(i, ((label, log), xs))| {
                Line::nth(i, label.as_str(), smoothed_curve(log, key, xs, window))
            })
            .filter(|l| !l.points.is_empty())
            .collect();
        let mut ys = lines.iter().flat_map(|l| l.points.iter().map(|p| p.1));
        let first = ys.next();
        if first.is_none_or(|y0| ys.all(|y| y == y0)) {
            // Nothing to compare (no data, or one constant: flat ground's terrain level).
            continue;
        }
        let title = format!("{key} (mean of {window} iterations)");
        let mut panel = Panel::new(title, axis.label(), *y_label);
        if axis == XAxis::Iteration {
            panel = panel.integer_x();
        }
        panels.push(lines.into_iter().fold(panel, Panel::line));
    }
    if panels.is_empty() {
        return Err("no run has any of the compared series".into());
    }
    write_panels(path, None, 2, (760, 340), &panels)
        .map_err(|e| format!("{}: {e}", path.display()))?;
    Ok(panels.len())
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::BTreeMap;

    fn log(rows: &[(f64, f64, f64, f64, Option<f64>)]) -> MetricsLog {
        let mut log = MetricsLog::new();
        for &(it, collect, update, rate, err) in rows {
            let mut row = BTreeMap::new();
            row.insert("iteration".to_string(), it);
            row.insert("perf/collect_s".to_string(), collect);
            row.insert("perf/update_s".to_string(), update);
            row.insert("perf/env_steps_per_s".to_string(), rate);
            if let Some(e) = err {
                row.insert("tracking/lin_vel_error_m_s".to_string(), e);
            }
            log.push(row);
        }
        log
    }

    #[test]
    fn axes_accumulate_time_and_steps_per_iteration() {
        // 3,072 env steps per iteration at 0.5 + 0.25 s.
        let l = log(&[
            (0.0, 0.5, 0.25, 4096.0, Some(0.3)),
            (1.0, 0.5, 0.25, 4096.0, Some(0.2)),
            (2.0, 1.0, 0.5, 2048.0, Some(0.1)),
        ]);
        let hours = x_coordinates(&l, XAxis::WallClock);
        let expect_h = [0.75, 1.5, 3.0].map(|s| s / 3600.0);
        for (h, e) in hours.iter().zip(expect_h) {
            assert!((h.unwrap() - e).abs() < 1e-12, "{hours:?}");
        }
        let steps = x_coordinates(&l, XAxis::EnvSteps);
        for (s, e) in steps.iter().zip([3072.0, 6144.0, 9216.0]) {
            assert!((s.unwrap() - e / 1e6).abs() < 1e-12, "{steps:?}");
        }
        assert_eq!(
            x_coordinates(&l, XAxis::Iteration),
            vec![Some(0.0), Some(1.0), Some(2.0)]
        );
    }

    #[test]
    fn curves_are_moving_means_and_skip_rows_without_the_key() {
        let l = log(&[
            (0.0, 1.0, 0.0, 1.0, Some(0.4)),
            (1.0, 1.0, 0.0, 1.0, None),
            (2.0, 1.0, 0.0, 1.0, Some(0.2)),
            (3.0, 1.0, 0.0, 1.0, Some(0.0)),
            (4.0, f64::NAN, 0.0, 1.0, Some(0.6)),
        ]);
        let key = "tracking/lin_vel_error_m_s";
        let c = smoothed_curve(&l, key, &x_coordinates(&l, XAxis::Iteration), 2);
        let expect = [(0.0, 0.4), (2.0, 0.3), (3.0, 0.1), (4.0, 0.3)];
        assert_eq!(c.len(), expect.len(), "{c:?}");
        for (p, e) in c.iter().zip(expect) {
            assert!(
                (p.0 - e.0).abs() < 1e-12 && (p.1 - e.1).abs() < 1e-12,
                "{c:?}"
            );
        }
        // A row without timing has no place on the time axis (its value still counts in
        // the window of the next point).
        let t = smoothed_curve(&l, key, &x_coordinates(&l, XAxis::WallClock), 2);
        assert_eq!(t.len(), 3, "{t:?}");
        assert!((t[2].0 - 4.0 / 3600.0).abs() < 1e-12 && (t[2].1 - 0.1).abs() < 1e-12);
    }

    #[test]
    fn comparison_draws_the_runs_and_refuses_runs_with_nothing_to_compare() {
        let dir = std::env::temp_dir().join(format!("compare-test-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let a = log(&[
            (0.0, 1.0, 0.5, 100.0, Some(0.3)),
            (1.0, 1.0, 0.5, 100.0, Some(0.2)),
        ]);
        let b = log(&[
            (0.0, 2.0, 0.5, 100.0, Some(0.3)),
            (1.0, 2.0, 0.5, 100.0, Some(0.1)),
        ]);
        let runs = vec![("a".to_string(), a), ("b".to_string(), b)];
        let path = dir.join("compare.png");
        let n = write_comparison(&path, &runs, COMPARED_KEYS, XAxis::WallClock, 10).unwrap();
        assert_eq!(n, 1);
        // A series that is one constant in every run (flat ground's terrain level) is left
        // out.
        let flat = |e| {
            log(&[
                (0.0, 1.0, 0.5, 100.0, Some(e)),
                (1.0, 1.0, 0.5, 100.0, Some(e)),
            ])
        };
        let constant = vec![("a".to_string(), flat(0.0)), ("b".to_string(), flat(0.0))];
        assert!(write_comparison(&path, &constant, COMPARED_KEYS, XAxis::WallClock, 10).is_err());
        assert!(std::fs::metadata(&path).unwrap().len() > 1000);
        let empty = vec![("c".to_string(), MetricsLog::new())];
        let err = write_comparison(&path, &empty, COMPARED_KEYS, XAxis::WallClock, 10);
        assert!(err.unwrap_err().contains("no run"));
        std::fs::remove_dir_all(&dir).ok();
    }
}
