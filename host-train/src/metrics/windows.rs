//! Window means of a run's metrics: the mean of each key over the rows whose iteration lies
//! in a window (`900:1000`), printed as a Markdown table (`hexapod plot RUN --windows ...`).
//! The reports quote their training figures from these tables.

use crate::metrics::MetricsLog;

/// The keys tabulated when none are asked for: the discriminator's outputs, the style
/// reward, tracking errors, the action noise and the throughput.
pub const DEFAULT_WINDOW_KEYS: &[&str] = &[
    "amp/d_prior",
    "amp/d_policy",
    "amp/d_policy_rollout",
    "reward/style",
    "tracking/lin_vel_error_m_s",
    "tracking/yaw_rate_error_rad_s",
    "train/action_std",
    "perf/env_steps_per_s",
];

/// An inclusive range of iterations.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Window {
    /// First iteration in the window.
    pub first: usize,
    /// Last iteration in the window.
    pub last: usize,
}

impl std::str::FromStr for Window {
    type Err = String;

    /// `FIRST:LAST`, both iterations, `FIRST <= LAST`.
    fn from_str(text: &str) -> Result<Self, Self::Err> {
        let bad = || {
            format!("window `{text}`: expected FIRST:LAST, two iterations with FIRST <= LAST (e.g. 900:1000)")
        };
        let (a, b) = text.split_once(':').ok_or_else(bad)?;
        let first = a.trim().parse::<usize>().map_err(|_| bad())?;
        let last = b.trim().parse::<usize>().map_err(|_| bad())?;
        if first > last {
            return Err(bad());
        }
        Ok(Window { first, last })
    }
}

/// The mean of `key` over the rows of `window` that have a finite value for it (a row
/// without the key, e.g. before a metric existed, is skipped), with the number of rows.
pub fn window_mean(log: &MetricsLog, key: &str, window: Window) -> Option<(f64, usize)> {
    let values: Vec<f64> = log
        .rows()
        .iter()
        .filter(|row| {
            row.get("iteration")
                .is_some_and(|&it| it >= window.first as f64 && it <= window.last as f64)
        })
        .filter_map(|row| row.get(key).copied())
        .filter(|v| v.is_finite())
        .collect();
    if values.is_empty() {
        return None;
    }
    Some((
        values.iter().sum::<f64>() / values.len() as f64,
        values.len(),
    ))
}

/// A Markdown table: one row per window, one column per key (`-` where the window has no
/// value for it), plus `reward/style / max` when `style_max_per_step` is given (the style
/// reward's largest value per policy step, `style_weight x dt`).
pub fn window_table(
    log: &MetricsLog,
    keys: &[String],
    windows: &[Window],
    style_max_per_step: Option<f64>,
) -> String {
    let style_share =
        style_max_per_step.filter(|m| *m > 0.0 && keys.iter().any(|k| k == "reward/style"));
    let mut header = vec!["iterations".to_string(), "rows".to_string()];
    header.extend(keys.iter().cloned());
    if style_share.is_some() {
        header.push("reward/style / max".to_string());
    }
    let mut out = format!(
        "| {} |\n|{}\n",
        header.join(" | "),
        "---|".repeat(header.len())
    );
    for &window in windows {
        let rows = log
            .rows()
            .iter()
            .filter(|row| {
                row.get("iteration")
                    .is_some_and(|&it| it >= window.first as f64 && it <= window.last as f64)
            })
            .count();
        let mut cells = vec![
            format!("{}-{}", window.first, window.last),
            rows.to_string(),
        ];
        for key in keys {
            cells.push(match window_mean(log, key, window) {
                Some((mean, _)) => format_value(mean),
                None => "-".to_string(),
            });
        }
        if let Some(max) = style_share {
            cells.push(match window_mean(log, "reward/style", window) {
                Some((mean, _)) => format!("{:.2}", mean / max),
                None => "-".to_string(),
            });
        }
        out.push_str(&format!("| {} |\n", cells.join(" | ")));
    }
    out
}

/// Three significant digits for small values, whole numbers for large ones.
fn format_value(v: f64) -> String {
    if v.abs() >= 100.0 {
        format!("{v:.0}")
    } else if v.abs() >= 1.0 {
        format!("{v:.2}")
    } else {
        format!("{v:.3}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::BTreeMap;

    fn log() -> MetricsLog {
        let mut log = MetricsLog::new();
        for it in 1..=10 {
            let mut row = BTreeMap::new();
            row.insert("iteration".to_string(), it as f64);
            row.insert("reward/style".to_string(), 0.001 * it as f64);
            if it > 5 {
                row.insert("late".to_string(), it as f64);
            }
            row.insert("nan".to_string(), if it == 3 { 1.0 } else { f64::NAN });
            log.push(row);
        }
        log
    }

    #[test]
    fn a_window_averages_its_rows_only_and_skips_missing_and_non_finite_values() {
        let log = log();
        let w: Window = "3:6".parse().unwrap();
        let (mean, n) = window_mean(&log, "reward/style", w).unwrap();
        assert_eq!(n, 4);
        assert!((mean - 0.0045).abs() < 1e-12);
        assert_eq!(window_mean(&log, "late", w), Some((6.0, 1)));
        assert_eq!(window_mean(&log, "nan", w), Some((1.0, 1)));
        assert_eq!(window_mean(&log, "late", "1:5".parse().unwrap()), None);
        assert_eq!(window_mean(&log, "absent", w), None);
    }

    #[test]
    fn the_table_has_a_row_per_window_and_the_style_share_of_its_maximum() {
        let log = log();
        let keys = vec!["reward/style".to_string(), "late".to_string()];
        let windows = ["1:2".parse().unwrap(), "8:10".parse().unwrap()];
        let table = window_table(&log, &keys, &windows, Some(0.02));
        let lines: Vec<&str> = table.lines().collect();
        assert_eq!(lines.len(), 4, "{table}");
        assert_eq!(
            lines[0],
            "| iterations | rows | reward/style | late | reward/style / max |"
        );
        assert_eq!(lines[2], "| 1-2 | 2 | 0.002 | - | 0.07 |");
        assert_eq!(lines[3], "| 8-10 | 3 | 0.009 | 9.00 | 0.45 |");
    }

    #[test]
    fn malformed_windows_are_refused_with_the_expected_form() {
        for bad in ["10", "a:b", "10:5", ":5", "1:2:3"] {
            let err = bad.parse::<Window>().unwrap_err();
            assert!(err.contains("FIRST:LAST"), "{bad}: {err}");
        }
        assert_eq!("5:5".parse::<Window>(), Ok(Window { first: 5, last: 5 }));
    }
}
