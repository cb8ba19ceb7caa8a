//! `hexapod plot`: draw a run's or a checkpoint's `metrics.csv` as the training plots, or
//! several runs' learning curves on one axis (iterations, environment steps, training time);
//! with `--windows`, a table of the run's metrics averaged over ranges of iterations.

use crate::config::TrainConfig;
use crate::metrics::compare::{write_comparison, XAxis, COMPARED_KEYS};
use crate::metrics::windows::{window_table, Window, DEFAULT_WINDOW_KEYS};
use crate::metrics::MetricsLog;
use anyhow::{anyhow, Context};
use std::path::{Path, PathBuf};

/// Arguments of `hexapod plot`.
#[derive(clap::Args, Debug)]
pub struct PlotArgs {
    /// A run or checkpoint directory (holding `metrics.csv`), or a CSV file; several (each
    /// optionally `LABEL=PATH`) draw their learning curves side by side (`compare_<x>.png`).
    #[arg(required = true, num_args = 1..)]
    pub metrics: Vec<PathBuf>,
    /// Where to write the PNGs (default: `plots/` beside the CSV; required to compare).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Drop the rows after this iteration (plots that end at a checkpoint).
    #[arg(long)]
    pub until: Option<usize>,
    /// Compare learning curves against this axis (implied by several runs: training time).
    #[arg(long, value_enum)]
    pub x: Option<XAxis>,
    /// Comparison curves: the moving mean over this many iterations.
    #[arg(long, default_value_t = 50)]
    pub smooth: usize,
    /// Print a Markdown table of the run's metrics averaged over these ranges of
    /// iterations (`FIRST:LAST`, inclusive; e.g. `--windows 901:1000 5901:6000`) instead of
    /// drawing plots. With the run's `config.toml` beside the CSV, and the style reward on,
    /// it adds the style reward's share of its maximum (`style_weight x dt` per policy step).
    #[arg(long, num_args = 1.., value_name = "FIRST:LAST")]
    pub windows: Vec<Window>,
    /// The metrics tabulated by `--windows` (default: discriminator outputs and style reward,
    /// left out when the run's `config.toml` has the style reward off; tracking errors, action
    /// std, env steps/s).
    #[arg(long, value_delimiter = ',', requires = "windows")]
    pub keys: Vec<String>,
}

/// Runs the subcommand.
pub fn run(args: PlotArgs) -> anyhow::Result<()> {
    if !args.windows.is_empty() {
        return windows(&args);
    }
    if args.metrics.len() > 1 || args.x.is_some() {
        return compare(&args);
    }
    let (_, csv) = labelled_csv(&args.metrics[0]);
    let log = read_log(&csv, args.until)?;
    let out = args.out.unwrap_or_else(|| {
        csv.parent()
            .unwrap_or(std::path::Path::new("."))
            .join("plots")
    });
    std::fs::create_dir_all(&out)?;
    let files = log.plot(&out).map_err(|e| anyhow!(e))?;
    println!(
        "{} rows -> {} plots in {}",
        log.rows().len(),
        files.len(),
        out.display()
    );
    Ok(())
}

/// Several runs' curves in `<out>/compare_<axis>.png`.
fn compare(args: &PlotArgs) -> anyhow::Result<()> {
    let out = args
        .out
        .as_ref()
        .context("comparing runs needs --out DIR for the plot")?;
    let axis = args.x.unwrap_or(XAxis::WallClock);
    let mut runs = Vec::new();
    for arg in &args.metrics {
        let (label, csv) = labelled_csv(arg);
        runs.push((label, read_log(&csv, args.until)?));
    }
    std::fs::create_dir_all(out)?;
    let name = match axis {
        XAxis::Iteration => "compare_iteration.png",
        XAxis::EnvSteps => "compare_env_steps.png",
        XAxis::WallClock => "compare_wall_clock.png",
    };
    let path = out.join(name);
    let panels =
        write_comparison(&path, &runs, COMPARED_KEYS, axis, args.smooth).map_err(|e| anyhow!(e))?;
    println!(
        "{} runs -> {} panels in {}",
        runs.len(),
        panels,
        path.display()
    );
    Ok(())
}

/// Each run's window table on stdout.
fn windows(args: &PlotArgs) -> anyhow::Result<()> {
    for arg in &args.metrics {
        let (label, csv) = labelled_csv(arg);
        let log = read_log(&csv, args.until)?;
        let has = |key: &str| log.rows().iter().any(|row| row.contains_key(key));
        let config = csv.with_file_name("config.toml");
        let cfg = if config.is_file() {
            Some(
                TrainConfig::load(&config)
                    .with_context(|| format!("reading the run's {}", config.display()))?,
            )
        } else {
            None
        };
        let amp_on = cfg.as_ref().is_none_or(|c| c.amp_enabled());
        // The default keys a run does not log are left out, and so are the discriminator's
        // and the style reward's when its config has the style reward off (logged as zeros);
        // a key asked for must exist.
        let keys: Vec<String> = if args.keys.is_empty() {
            DEFAULT_WINDOW_KEYS
                .iter()
                .filter(|k| has(k) && (amp_on || !is_style_key(k)))
                .map(|k| k.to_string())
                .collect()
        } else {
            args.keys.clone()
        };
        if let Some(unknown) = keys.iter().find(|k| !has(k)) {
            anyhow::bail!("{}: no column `{unknown}`", csv.display());
        }
        let style_max = cfg
            .filter(|c| c.amp_enabled())
            .map(|c| c.rewards.style_weight as f64 * hexapod_core::timing::POLICY_DT_S as f64);
        println!("{label} ({})\n", csv.display());
        println!("{}", window_table(&log, &keys, &args.windows, style_max));
    }
    Ok(())
}

/// The discriminator's metrics and the style reward: zeros in a run without the style reward.
fn is_style_key(key: &str) -> bool {
    key.starts_with("amp/") || key == "reward/style"
}

/// `LABEL=PATH` or `PATH` (labelled by its directory's name) -> (label, the CSV file).
fn labelled_csv(arg: &Path) -> (String, PathBuf) {
    let text = arg.to_string_lossy();
    let (label, path) = match text.split_once('=') {
        Some((label, path)) if !label.is_empty() => (Some(label.to_string()), PathBuf::from(path)),
        _ => (None, arg.to_path_buf()),
    };
    let csv = if path.is_dir() {
        path.join("metrics.csv")
    } else {
        path
    };
    let label = label.unwrap_or_else(|| {
        let dir = csv.parent().unwrap_or(Path::new("."));
        dir.file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_else(|| csv.display().to_string())
    });
    (label, csv)
}

/// The CSV's rows (up to `until`), refused when none are left.
fn read_log(csv: &Path, until: Option<usize>) -> anyhow::Result<MetricsLog> {
    let mut log = MetricsLog::read_csv(csv).map_err(|e| anyhow!(e))?;
    if let Some(last) = until {
        log.truncate_after(last as f64);
    }
    if log.rows().is_empty() {
        anyhow::bail!("{}: no rows to plot", csv.display());
    }
    Ok(log)
}
