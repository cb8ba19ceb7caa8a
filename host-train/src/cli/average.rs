//! `hexapod average`: the weight average of several checkpoints of one run (stochastic
//! weight averaging), written as a checkpoint (`checkpoint_average`).
//!
//! ```text
//! hexapod average --run runs/terrain-descend --from 24050 --to 25000 --out DIR
//! hexapod average --out DIR runs/x/checkpoints/model_001000 runs/x/checkpoints/model_001050
//! ```

use crate::checkpoint_average::{average, run_checkpoints_between};
use anyhow::{bail, Context};
use std::path::PathBuf;

/// Arguments of `hexapod average`.
#[derive(clap::Args, Debug)]
pub struct AverageArgs {
    /// Checkpoint directories to average (or use `--run` with `--from` and `--to`).
    pub checkpoints: Vec<PathBuf>,
    /// A run directory: average its checkpoints `checkpoints/model_NNNNNN` whose iteration
    /// lies in `--from..=--to`.
    #[arg(long, requires_all = ["from", "to"], conflicts_with = "checkpoints")]
    pub run: Option<PathBuf>,
    /// First iteration of `--run`'s range (inclusive).
    #[arg(long)]
    pub from: Option<usize>,
    /// Last iteration of `--run`'s range (inclusive).
    #[arg(long)]
    pub to: Option<usize>,
    /// The averaged checkpoint's directory (replaced if it exists).
    #[arg(long)]
    pub out: PathBuf,
}

/// Runs `hexapod average`.
pub fn run(args: AverageArgs) -> anyhow::Result<()> {
    let dirs = match (&args.run, args.from, args.to) {
        (Some(run), Some(from), Some(to)) => {
            if from > to {
                bail!("--from {from} is after --to {to}");
            }
            run_checkpoints_between(run, from, to)?
        }
        _ if args.checkpoints.is_empty() => {
            bail!("name the checkpoints to average, or a run with --run, --from and --to")
        }
        _ => args.checkpoints.clone(),
    };
    let record = average(&dirs, &args.out)
        .with_context(|| format!("averaging into {}", args.out.display()))?;
    let (first, last) = (
        record.iterations[0],
        record.iterations[record.iterations.len() - 1],
    );
    println!(
        "averaged {} checkpoints (iterations {first}..{last}) into {}",
        record.checkpoints.len(),
        args.out.display()
    );
    Ok(())
}
