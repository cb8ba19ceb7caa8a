//! `hexapod plot`: draw a run's or a checkpoint's `metrics.csv` as the training plots.

use crate::metrics::MetricsLog;
use anyhow::anyhow;
use std::path::PathBuf;

/// Arguments of `hexapod plot`.
#[derive(clap::Args, Debug)]
pub struct PlotArgs {
    /// A run or checkpoint directory (holding `metrics.csv`), or a CSV file.
    pub metrics: PathBuf,
    /// Where to write the PNGs (default: `plots/` beside the CSV).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Drop the rows after this iteration (plots that end at a checkpoint).
    #[arg(long)]
    pub until: Option<usize>,
}

/// Runs the subcommand.
pub fn run(args: PlotArgs) -> anyhow::Result<()> {
    let csv = if args.metrics.is_dir() {
        args.metrics.join("metrics.csv")
    } else {
        args.metrics.clone()
    };
    let mut log = MetricsLog::read_csv(&csv).map_err(|e| anyhow!(e))?;
    if let Some(last) = args.until {
        log.truncate_after(last as f64);
    }
    if log.rows().is_empty() {
        anyhow::bail!("{}: no rows to plot", csv.display());
    }
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
