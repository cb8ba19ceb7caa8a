//! `hexapod sweep`: run a sweep file's jobs (train, then the suite) locally or on Slurm, show
//! where each stands, and gather their reports ([`crate::sweep`]).

use crate::sweep::{report, slurm, spec, task};
use anyhow::bail;
use clap::{Args, Subcommand, ValueEnum};
use std::path::PathBuf;

/// Arguments of `hexapod sweep`.
#[derive(Args, Debug)]
pub struct SweepArgs {
    #[command(subcommand)]
    command: SweepCommand,
}

/// Where the jobs run.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum Backend {
    /// One after another on this machine.
    Local,
    /// One `sbatch --array` job, a task per unfinished job.
    Slurm,
}

#[derive(Subcommand, Debug)]
enum SweepCommand {
    /// Run every unfinished job (a finished job is skipped, an interrupted one resumes).
    Run {
        /// The sweep file (TOML; see configs/sweeps/).
        spec: PathBuf,
        /// Where the jobs run.
        #[arg(long, value_enum, default_value_t = Backend::Local)]
        backend: Backend,
        /// Slurm: write the batch script but do not submit it.
        #[arg(long)]
        no_submit: bool,
        /// Slurm: return only when every task has ended (`sbatch --wait`).
        #[arg(long)]
        wait: bool,
    },
    /// One job of the sweep (what each Slurm array task runs).
    Task {
        /// The sweep file.
        spec: PathBuf,
        /// The job's index (`$SLURM_ARRAY_TASK_ID`).
        #[arg(long)]
        index: usize,
    },
    /// Where each job stands.
    Status {
        /// The sweep file.
        spec: PathBuf,
    },
    /// Gather the jobs' suite reports into `<sweep dir>/report.{md,json}`.
    Report {
        /// The sweep file.
        spec: PathBuf,
        /// Report the finished jobs even if some are not.
        #[arg(long)]
        partial: bool,
    },
}

fn print_status(sweep: &spec::Sweep) -> usize {
    let mut unfinished = 0;
    println!(
        "sweep `{}`: {} jobs in {}",
        sweep.spec.name,
        sweep.jobs.len(),
        sweep.dir.display()
    );
    for job in &sweep.jobs {
        let st = task::state(job);
        unfinished += (st != task::JobState::Done) as usize;
        println!("  {:>3}  {:<40} {}", job.index, job.name(), st);
    }
    unfinished
}

/// Runs `hexapod sweep`.
pub fn run(args: SweepArgs) -> anyhow::Result<()> {
    match args.command {
        SweepCommand::Run {
            spec,
            backend,
            no_submit,
            wait,
        } => {
            let sweep = spec::load(&spec)?;
            if backend == Backend::Local && (no_submit || wait) {
                bail!("--no-submit and --wait are for --backend slurm");
            }
            let todo: Vec<&spec::Job> = sweep
                .jobs
                .iter()
                .filter(|j| task::state(j) != task::JobState::Done)
                .collect();
            if todo.is_empty() {
                print_status(&sweep);
                println!(
                    "every job is done: `hexapod sweep report {}`",
                    spec.display()
                );
                return Ok(());
            }
            let exe = task::hexapod_exe()?;
            match backend {
                Backend::Local => {
                    for (k, job) in todo.iter().enumerate() {
                        eprintln!(
                            "== job {} of {} left: {} ({})",
                            k + 1,
                            todo.len(),
                            job.name(),
                            task::state(job)
                        );
                        task::run(&sweep, job, &exe)?;
                    }
                    print_status(&sweep);
                    println!("report: `hexapod sweep report {}`", spec.display());
                }
                Backend::Slurm => {
                    let indices: Vec<usize> = todo.iter().map(|j| j.index).collect();
                    if no_submit {
                        let workdir = std::env::current_dir()?;
                        let spec_file = sweep.path.canonicalize()?;
                        std::fs::create_dir_all(&sweep.dir)?;
                        let script = sweep.dir.join("sweep.sbatch");
                        std::fs::write(
                            &script,
                            slurm::batch_script(&sweep, &indices, &exe, &spec_file, &workdir),
                        )?;
                        println!(
                            "wrote {} ({} tasks); submit with `sbatch {}`",
                            script.display(),
                            indices.len(),
                            script.display()
                        );
                        return Ok(());
                    }
                    let id = slurm::submit(&sweep, &indices, &exe, wait)?;
                    if wait {
                        let unfinished = print_status(&sweep);
                        if unfinished > 0 {
                            bail!(
                                "array job {id}: {unfinished} jobs did not finish; logs in {}",
                                sweep.dir.join("logs").display()
                            );
                        }
                        println!("report: `hexapod sweep report {}`", spec.display());
                    } else {
                        println!(
                            "submitted array job {id}: {} tasks (logs in {}); watch with `squeue -j {id}` or `hexapod sweep status {}`",
                            indices.len(),
                            sweep.dir.join("logs").display(),
                            spec.display()
                        );
                    }
                }
            }
            Ok(())
        }
        SweepCommand::Task { spec, index } => {
            let sweep = spec::load(&spec)?;
            let Some(job) = sweep.jobs.get(index) else {
                bail!(
                    "sweep `{}` has jobs 0 to {}; no job {index}",
                    sweep.spec.name,
                    sweep.jobs.len() - 1
                );
            };
            task::run(&sweep, job, &task::hexapod_exe()?)
        }
        SweepCommand::Status { spec } => {
            let sweep = spec::load(&spec)?;
            print_status(&sweep);
            Ok(())
        }
        SweepCommand::Report { spec, partial } => {
            let sweep = spec::load(&spec)?;
            let mut r = report::gather(&sweep, partial)?;
            r.curves = crate::sweep::curves::write(&sweep)?
                .and_then(|p| p.file_name().map(|f| f.to_string_lossy().to_string()));
            r.write(&sweep)?;
            println!("{}", r.markdown());
            eprintln!("report: {}", sweep.dir.join("report.md").display());
            Ok(())
        }
    }
}
