//! Curriculum (the paper's Fig. 4): the terrain row per tile kind over the training
//! iterations, read from the run's `metrics.csv` (`episode/terrain_level_<kind>`, the mean
//! row of the robots on that kind's column), up to the checkpoint's iteration.

use crate::checkpoint::load_iteration;
use crate::metrics::MetricsLog;
use serde::Serialize;
use std::path::{Path, PathBuf};

/// Column prefix of the per-kind terrain level.
pub const LEVEL_PREFIX: &str = "episode/terrain_level_";
/// The final level is the mean over this many last logged iterations.
pub const FINAL_WINDOW: usize = 50;

/// One tile kind's curve.
#[derive(Clone, Debug, Serialize)]
pub struct KindCurve {
    /// Tile kind (`StairsUp`, ...).
    pub kind: String,
    /// Mean row over the last [`FINAL_WINDOW`] logged iterations.
    pub final_level: f64,
    /// Highest mean row logged.
    pub max_level: f64,
    /// (iteration, mean row), for the plots (not in the JSON).
    #[serde(skip)]
    pub points: Vec<(f64, f64)>,
}

/// The protocol's results.
#[derive(Clone, Debug, Serialize)]
pub struct CurriculumResult {
    /// The metrics file read (`None`: none found).
    pub metrics: Option<String>,
    /// Why there are no curves, when there are none.
    pub note: Option<String>,
    /// Terrain rows of the checkpoint's grid (0 when it trained on flat ground).
    pub rows: usize,
    /// First and last iteration logged.
    pub iterations: Option<(f64, f64)>,
    /// Per tile kind.
    pub kinds: Vec<KindCurve>,
}

/// Where a checkpoint's run logged its metrics: beside it (a shipped policy), or two levels
/// up (`<run>/checkpoints/model_N`).
pub fn find_metrics(checkpoint: &Path) -> Option<PathBuf> {
    let beside = checkpoint.join("metrics.csv");
    if beside.exists() {
        return Some(beside);
    }
    let run = checkpoint.parent()?.parent()?.join("metrics.csv");
    run.exists().then_some(run)
}

/// Reads the curves of a checkpoint (rows: its terrain grid's rows, 0 without tiles).
pub fn run(checkpoint: &Path, rows: usize) -> anyhow::Result<CurriculumResult> {
    let Some(path) = find_metrics(checkpoint) else {
        return Ok(CurriculumResult {
            metrics: None,
            note: Some("no metrics.csv beside the checkpoint or in its run directory".into()),
            rows,
            iterations: None,
            kinds: Vec::new(),
        });
    };
    let mut log = MetricsLog::read_csv(&path).map_err(anyhow::Error::msg)?;
    if let Ok(iteration) = load_iteration(checkpoint) {
        log.truncate_after(iteration as f64);
    }
    let mut keys: Vec<String> = log
        .rows()
        .iter()
        .flat_map(|r| {
            r.keys()
                .filter(|k| k.starts_with(LEVEL_PREFIX))
                .cloned()
                .collect::<Vec<_>>()
        })
        .collect();
    keys.sort();
    keys.dedup();
    let kinds: Vec<KindCurve> = keys
        .iter()
        .map(|key| {
            let points: Vec<(f64, f64)> = log
                .rows()
                .iter()
                .filter_map(|r| Some((*r.get("iteration")?, *r.get(key)?)))
                .filter(|(_, y)| y.is_finite())
                .collect();
            let tail = &points[points.len().saturating_sub(FINAL_WINDOW)..];
            KindCurve {
                kind: key.trim_start_matches(LEVEL_PREFIX).to_string(),
                final_level: tail.iter().map(|p| p.1).sum::<f64>() / tail.len().max(1) as f64,
                max_level: points.iter().map(|p| p.1).fold(f64::NAN, f64::max),
                points,
            }
        })
        .filter(|k| !k.points.is_empty())
        .collect();
    let its: Vec<f64> = log
        .rows()
        .iter()
        .filter_map(|r| r.get("iteration").copied())
        .collect();
    let iterations = its.first().zip(its.last()).map(|(a, b)| (*a, *b));
    let note = kinds
        .is_empty()
        .then(|| "metrics.csv has no per-kind terrain levels (trained on flat ground)".to_string());
    Ok(CurriculumResult {
        metrics: Some(path.display().to_string()),
        note,
        rows,
        iterations,
        kinds,
    })
}
