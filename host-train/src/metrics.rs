//! Training metrics: one row per iteration, written as CSV (columns are the union of all
//! keys seen) and drawn as PNG line plots, one file per group of related series. Beside
//! `metrics.csv` the same rows go to a TensorBoard event file ([`tfevents`]), one scalar
//! per key (`group/name`) with the iteration as the step.

pub mod compare;
pub mod tfevents;
pub mod windows;

use host_sim::plot::{write_panels, Line, Panel};
use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// One panel of a training plot: title, y axis name (quantity and unit), the key prefixes
/// it draws, and whether each key gets a panel of its own (quantities of unlike scale).
pub struct PlotPanel {
    /// Title; for a panel per key, the key is appended.
    pub title: &'static str,
    /// y axis name.
    pub y_label: &'static str,
    /// Keys drawn: those starting with one of these.
    pub prefixes: &'static [&'static str],
    /// One panel per key instead of one for all.
    pub per_key: bool,
}

const fn panel(
    title: &'static str,
    y_label: &'static str,
    prefixes: &'static [&'static str],
) -> PlotPanel {
    PlotPanel {
        title,
        y_label,
        prefixes,
        per_key: false,
    }
}

/// Plot files: file stem and its panels, stacked (m/s and rad/s never share an axis).
pub const PLOT_GROUPS: &[(&str, &[PlotPanel])] = &[
    (
        "reward_terms",
        &[
            panel(
                "reward per policy step (reward/*)",
                "reward per step",
                &["reward/"],
            ),
            panel(
                "episode reward terms (episode/rew_*: episode sum / episode length)",
                "reward per second",
                &["episode/rew_"],
            ),
        ],
    ),
    (
        "episode_length",
        &[panel(
            "mean episode length",
            "episode length (policy steps)",
            &["episode/length"],
        )],
    ),
    (
        "terrain_level",
        &[panel(
            "mean terrain level (curriculum row)",
            "terrain level (row)",
            &["episode/terrain_level"],
        )],
    ),
    (
        "discriminator",
        &[panel(
            "discriminator output (+1 like the prior, -1 not) and style reward",
            "D output / style reward",
            &["amp/d_", "amp/style"],
        )],
    ),
    (
        "discriminator_saliency",
        &[panel(
            "what the discriminator reads: mean |dD/dx| per AMP feature group (normalized inputs)",
            "mean |dD/dx|",
            &["amp_saliency/"],
        )],
    ),
    (
        "tracking_error",
        &[
            panel(
                "planar velocity tracking error",
                "velocity error (m/s)",
                &["tracking/lin_vel"],
            ),
            panel(
                "yaw rate tracking error",
                "yaw rate error (rad/s)",
                &["tracking/yaw_rate"],
            ),
        ],
    ),
    (
        "estimator_error",
        &[panel(
            "velocity estimator error",
            "velocity error (m/s)",
            &["estimator/"],
        )],
    ),
    (
        "losses",
        &[PlotPanel {
            title: "loss",
            y_label: "loss",
            prefixes: &["loss/"],
            per_key: true,
        }],
    ),
    (
        "throughput",
        &[panel(
            "simulation throughput",
            "env steps per second",
            &["perf/env_steps_per_s"],
        )],
    ),
];

/// All rows of a run.
#[derive(Default)]
pub struct MetricsLog {
    rows: Vec<BTreeMap<String, f64>>,
    /// The event file beside the CSV, appended to on each write.
    events: std::sync::Mutex<Option<tfevents::EventFile>>,
    /// Rows carried over from before a resume: earlier event files hold them already.
    events_start: usize,
}

impl MetricsLog {
    /// An empty log.
    pub fn new() -> Self {
        Self::default()
    }

    /// Appends a row (must contain `iteration`).
    pub fn push(&mut self, row: BTreeMap<String, f64>) {
        self.rows.push(row);
    }

    /// The rows so far.
    pub fn rows(&self) -> &[BTreeMap<String, f64>] {
        &self.rows
    }

    fn columns(&self) -> Vec<String> {
        let mut keys: BTreeSet<String> = BTreeSet::new();
        for r in &self.rows {
            keys.extend(r.keys().cloned());
        }
        keys.remove("iteration");
        std::iter::once("iteration".to_string())
            .chain(keys)
            .collect()
    }

    /// Writes every row as CSV (missing values empty).
    pub fn write_csv(&self, path: &Path) -> std::io::Result<()> {
        let cols = self.columns();
        let mut out = cols.join(",");
        out.push('\n');
        for r in &self.rows {
            let line: Vec<String> = cols
                .iter()
                .map(|c| r.get(c).map(|v| format!("{v}")).unwrap_or_default())
                .collect();
            out.push_str(&line.join(","));
            out.push('\n');
        }
        std::fs::write(path, out)?;
        self.write_events(path.parent().unwrap_or(Path::new(".")))
    }

    /// Appends the rows not yet written to the TensorBoard event file in `dir` (created on
    /// the first call, `events.out.tfevents.*`).
    fn write_events(&self, dir: &Path) -> std::io::Result<()> {
        let mut events = self.events.lock().unwrap_or_else(|e| e.into_inner());
        if events.as_ref().is_none_or(|f| f.path.parent() != Some(dir)) {
            *events = Some(tfevents::EventFile::create(dir)?);
        }
        let file = events.as_mut().expect("created above");
        let from = (self.events_start + file.rows_written).min(self.rows.len());
        file.append(&self.rows[from..])
    }

    /// Reads a `metrics.csv` written by [`MetricsLog::write_csv`]; empty cells are missing
    /// values. Errors name the line and column of a malformed cell.
    pub fn read_csv(path: &Path) -> Result<Self, String> {
        let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
        let mut lines = text.lines();
        let header: Vec<&str> = lines
            .next()
            .ok_or_else(|| format!("{}: empty file", path.display()))?
            .split(',')
            .collect();
        if header.first() != Some(&"iteration") {
            return Err(format!(
                "{}: the first column must be `iteration`",
                path.display()
            ));
        }
        let mut log = Self::new();
        for (n, line) in lines.enumerate().filter(|(_, l)| !l.is_empty()) {
            let cells: Vec<&str> = line.split(',').collect();
            if cells.len() != header.len() {
                return Err(format!(
                    "{}: line {}: {} cells, the header has {}",
                    path.display(),
                    n + 2,
                    cells.len(),
                    header.len()
                ));
            }
            let mut row = BTreeMap::new();
            for (key, cell) in header.iter().zip(&cells).filter(|(_, c)| !c.is_empty()) {
                let value: f64 = cell.parse().map_err(|_| {
                    format!(
                        "{}: line {}: `{key}` is not a number: {cell:?}",
                        path.display(),
                        n + 2
                    )
                })?;
                row.insert(key.to_string(), value);
            }
            if !row.contains_key("iteration") {
                return Err(format!("{}: line {}: no iteration", path.display(), n + 2));
            }
            log.push(row);
        }
        Ok(log)
    }

    /// The log of a run resumed at iteration `next_iteration`: the rows of its `metrics.csv`
    /// before that iteration (a resumed run keeps its history; the event file of this
    /// process gets only the new rows).
    pub fn resume_from_csv(path: &Path, next_iteration: usize) -> Result<Self, String> {
        let mut log = Self::read_csv(path)?;
        log.truncate_after(next_iteration as f64 - 1.0);
        log.events_start = log.rows.len();
        Ok(log)
    }

    /// Keeps the rows up to `last_iteration` (a checkpoint's plots end where it does).
    pub fn truncate_after(&mut self, last_iteration: f64) {
        self.rows
            .retain(|r| r.get("iteration").is_some_and(|i| *i <= last_iteration));
    }

    /// The `(iteration, value)` points of `key` (finite values only).
    fn points(&self, key: &str) -> Vec<(f64, f64)> {
        self.rows
            .iter()
            .filter_map(|r| Some((*r.get("iteration")?, *r.get(key)?)))
            .filter(|(_, y)| y.is_finite())
            .collect()
    }

    /// Draws one PNG per non-empty plot group into `dir`; returns the files written.
    pub fn plot(&self, dir: &Path) -> Result<Vec<PathBuf>, String> {
        let mut written = Vec::new();
        let cols = self.columns();
        for (stem, group) in PLOT_GROUPS {
            let mut panels = Vec::new();
            for spec in group.iter() {
                let keys: Vec<&String> = cols
                    .iter()
                    .filter(|c| spec.prefixes.iter().any(|p| c.starts_with(p)))
                    .collect();
                let lines: Vec<(&String, Vec<(f64, f64)>)> = keys
                    .into_iter()
                    .map(|k| (k, self.points(k)))
                    .filter(|(_, p)| !p.is_empty())
                    .collect();
                if spec.per_key {
                    for (i, (key, pts)) in lines.into_iter().enumerate() {
                        panels.push(
                            Panel::new(key.as_str(), "iteration", spec.y_label)
                                .integer_x()
                                .line(Line::nth(i, key.as_str(), pts)),
                        );
                    }
                } else if !lines.is_empty() {
                    let mut p = Panel::new(spec.title, "iteration", spec.y_label).integer_x();
                    for (i, (key, pts)) in lines.into_iter().enumerate() {
                        p = p.line(Line::nth(i, legend_label(key, spec.prefixes), pts));
                    }
                    panels.push(p);
                }
            }
            if panels.is_empty() {
                continue;
            }
            let path = dir.join(format!("{stem}.png"));
            let per_key = group.iter().any(|g| g.per_key);
            let (columns, size) = if per_key {
                (2, (620, 300))
            } else {
                (1, (1100, 420))
            };
            write_panels(&path, None, columns, size, &panels)
                .map_err(|e| format!("{}: {e}", path.display()))?;
            written.push(path);
        }
        Ok(written)
    }
}

/// A key's legend label: without the panel's prefix when that names a family
/// (`episode/rew_joint_acc` -> `joint_acc`), the whole key otherwise.
fn legend_label(key: &str, prefixes: &[&str]) -> String {
    prefixes
        .iter()
        .filter(|p| p.ends_with('/') || p.ends_with('_'))
        .find_map(|p| key.strip_prefix(p))
        .filter(|rest| !rest.is_empty())
        .unwrap_or(key)
        .to_string()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn event_file_beside_the_csv_gets_each_row_once() {
        let dir = std::env::temp_dir().join(format!("hexapod-metrics-tb-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let mut log = MetricsLog::new();
        log.push(BTreeMap::from([
            ("iteration".into(), 0.0),
            ("loss/value".into(), 1.5),
        ]));
        log.write_csv(&dir.join("metrics.csv")).unwrap();
        log.push(BTreeMap::from([
            ("iteration".into(), 1.0),
            ("loss/value".into(), 1.25),
        ]));
        log.write_csv(&dir.join("metrics.csv")).unwrap();
        let files: Vec<_> = std::fs::read_dir(&dir)
            .unwrap()
            .map(|e| e.unwrap().path())
            .filter(|p| p.to_string_lossy().contains("tfevents"))
            .collect();
        assert_eq!(files.len(), 1, "{files:?}");
        let bytes = std::fs::read(&files[0]).unwrap();
        // The file-version record and one scalars record per row.
        let expect: usize = [
            tfevents::file_version_event(0.0),
            tfevents::scalars_event(0.0, 0, &[("loss/value", 1.5)]),
            tfevents::scalars_event(0.0, 1, &[("loss/value", 1.25)]),
        ]
        .iter()
        .map(|e| e.len() + 16)
        .sum();
        assert_eq!(bytes.len(), expect);
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn csv_has_the_union_of_columns() {
        let mut log = MetricsLog::new();
        log.push(BTreeMap::from([
            ("iteration".into(), 0.0),
            ("loss/value".into(), 1.5),
        ]));
        log.push(BTreeMap::from([
            ("iteration".into(), 1.0),
            ("episode/length".into(), 20.0),
        ]));
        let dir = std::env::temp_dir().join(format!("hexapod-metrics-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        log.write_csv(&dir.join("m.csv")).unwrap();
        let text = std::fs::read_to_string(dir.join("m.csv")).unwrap();
        assert_eq!(text, "iteration,episode/length,loss/value\n0,,1.5\n1,20,\n");
        let files = log.plot(&dir).unwrap();
        assert_eq!(files.len(), 2);
        assert!(files
            .iter()
            .all(|f| std::fs::metadata(f).unwrap().len() > 1000));
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn csv_round_trips_and_bad_cells_are_named() {
        let dir = std::env::temp_dir().join(format!("hexapod-metrics-rt-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let mut log = MetricsLog::new();
        for i in 0..3 {
            log.push(BTreeMap::from([
                ("iteration".into(), i as f64),
                ("loss/value".into(), 0.5 * i as f64),
            ]));
        }
        log.push(BTreeMap::from([("iteration".into(), 3.0)]));
        log.write_csv(&dir.join("m.csv")).unwrap();
        let mut back = MetricsLog::read_csv(&dir.join("m.csv")).unwrap();
        assert_eq!(back.rows(), log.rows());
        back.truncate_after(1.0);
        assert_eq!(back.rows().len(), 2);
        // A run resumed at iteration 2 keeps rows 0 and 1 and writes only new rows to its
        // own event file.
        let mut resumed = MetricsLog::resume_from_csv(&dir.join("m.csv"), 2).unwrap();
        assert_eq!(resumed.rows(), &log.rows()[..2]);
        resumed.push(BTreeMap::from([("iteration".into(), 2.0)]));
        let sub = dir.join("resumed");
        std::fs::create_dir_all(&sub).unwrap();
        resumed.write_csv(&sub.join("metrics.csv")).unwrap();
        assert_eq!(
            resumed
                .events
                .lock()
                .unwrap()
                .as_ref()
                .unwrap()
                .rows_written,
            1
        );
        assert_eq!(
            MetricsLog::read_csv(&sub.join("metrics.csv"))
                .unwrap()
                .rows()
                .len(),
            3
        );

        std::fs::write(dir.join("bad.csv"), "iteration,loss/value\n0,1\n1,abc\n").unwrap();
        let err = MetricsLog::read_csv(&dir.join("bad.csv")).err().unwrap();
        assert!(
            err.contains("line 3") && err.contains("loss/value"),
            "{err}"
        );
        std::fs::write(dir.join("short.csv"), "iteration,loss/value\n0\n").unwrap();
        assert!(MetricsLog::read_csv(&dir.join("short.csv"))
            .err()
            .unwrap()
            .contains("line 2"));
        std::fs::write(dir.join("nohead.csv"), "loss/value\n1\n").unwrap();
        assert!(MetricsLog::read_csv(&dir.join("nohead.csv")).is_err());
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
