//! `hexapod train`: trains a policy from a TOML preset, with resume and overrides.

use crate::amp::prior_source::load_prior_source;
use crate::config::{EnvKind, RmaPhase, TrainConfig};
use crate::env::make_env;
use crate::runner::Runner;
use anyhow::Context;
use clap::Args;
use std::path::PathBuf;

/// Arguments of `hexapod train`.
#[derive(Args, Debug)]
pub struct TrainArgs {
    /// Preset (TOML), e.g. `configs/default.toml`.
    #[arg(long, short)]
    pub config: PathBuf,
    /// Output directory (default `runs/<run name>`).
    #[arg(long)]
    pub run_dir: Option<PathBuf>,
    /// Name of the run: its directory under `runs/` (default: the preset's
    /// `runner.experiment_name`).
    #[arg(long, conflicts_with = "run_dir")]
    pub run_name: Option<String>,
    /// Continue from this checkpoint directory (its weights, optimizer and iteration).
    #[arg(long)]
    pub resume: Option<PathBuf>,
    /// Override `runner.max_iterations`.
    #[arg(long)]
    pub max_iterations: Option<usize>,
    /// Override `env.num_envs`.
    #[arg(long)]
    pub num_envs: Option<usize>,
    /// Override `env.kind`.
    #[arg(long, value_parser = ["sim", "fake"])]
    pub env: Option<String>,
    /// No progress bar (for logs).
    #[arg(long)]
    pub no_progress: bool,
    /// Override any config key: `--set ppo.learning_rate=3e-4 --set sim.curriculum=false`
    /// (values in TOML syntax; repeatable, applied in order after the preset's `base` chain).
    #[arg(long = "set", value_name = "KEY=VALUE")]
    pub overrides: Vec<String>,
    /// Seed of the environment and the learner (`env.seed` and `runner.seed`).
    #[arg(long)]
    pub seed: Option<u64>,
    /// With `--resume`: set the action standard deviation to this value (every dimension)
    /// before training on, to restart exploration in a fine-tuning stage; without it the
    /// checkpoint's is kept. Give it once, when the stage starts, not when resuming the stage.
    #[arg(long, requires = "resume")]
    pub reset_noise_std: Option<f32>,
}

/// Applies command-line overrides and validates.
pub fn resolve_config(args: &TrainArgs) -> anyhow::Result<TrainConfig> {
    let mut cfg = TrainConfig::load_with_overrides(&args.config, &args.overrides)?;
    if let Some(seed) = args.seed {
        cfg.env.seed = seed;
        cfg.runner.seed = seed;
    }
    if let Some(n) = args.max_iterations {
        cfg.runner.max_iterations = n;
    }
    if let Some(n) = args.num_envs {
        cfg.env.num_envs = n;
    }
    if let Some(kind) = &args.env {
        cfg.env.kind = if kind == "fake" {
            EnvKind::Fake
        } else {
            EnvKind::Sim
        };
    }
    cfg.validate()?;
    Ok(cfg)
}

/// Runs `hexapod train`.
pub fn run(args: TrainArgs) -> anyhow::Result<()> {
    let cfg = resolve_config(&args)?;
    if cfg
        .rma
        .as_ref()
        .is_some_and(|r| r.phase == RmaPhase::Adapted)
    {
        anyhow::bail!(
            "rma.phase = \"adapted\" is what `hexapod rma-adapt` writes; train RMA's teacher with rma.phase = \"teacher\""
        );
    }
    if cfg.runner.num_threads > 0 {
        std::env::set_var("RAYON_NUM_THREADS", cfg.runner.num_threads.to_string());
    }
    let run_dir = args.run_dir.clone().unwrap_or_else(|| {
        PathBuf::from("runs").join(
            args.run_name
                .as_deref()
                .unwrap_or(&cfg.runner.experiment_name),
        )
    });
    let env = make_env(&cfg)?;
    let priors = load_prior_source(&cfg)?;
    let mut runner = Runner::new(&cfg, env, priors, &run_dir)?;
    if let Some(ckpt) = &args.resume {
        let ckpt = &crate::checkpoint::resolve_dir(ckpt)?;
        let saved = crate::checkpoint::load_config(ckpt)?;
        if let Err(e) = crate::checkpoint::same_networks(&saved, &cfg) {
            anyhow::bail!(
                "{}: the checkpoint's network shapes differ from {}: {e}",
                ckpt.display(),
                args.config.display()
            );
        }
        runner
            .resume(ckpt)
            .with_context(|| format!("resuming from {}", ckpt.display()))?;
        eprintln!(
            "resumed from {} at iteration {}",
            ckpt.display(),
            runner.iteration
        );
        if let Some(std) = args.reset_noise_std {
            runner
                .ppo
                .set_action_std(std)
                .context("--reset-noise-std")?;
            eprintln!("action standard deviation reset to {std}");
        }
    }
    std::fs::write(run_dir.join("config.toml"), cfg.to_toml_string())
        .with_context(|| format!("writing {}", run_dir.display()))?;
    eprintln!(
        "training `{}`: {} envs x {} steps per iteration, {} iterations -> {}",
        cfg.runner.experiment_name,
        cfg.env.num_envs,
        cfg.ppo.num_steps_per_env,
        cfg.runner.max_iterations,
        run_dir.display()
    );
    // Ctrl-C: finish the iteration, save a checkpoint and say where; a second Ctrl-C quits
    // at once.
    let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let flag = stop.clone();
    ctrlc::set_handler(move || {
        if flag.swap(true, std::sync::atomic::Ordering::SeqCst) {
            std::process::exit(130);
        }
        eprintln!("\ninterrupt: saving a checkpoint after this iteration (Ctrl-C again to quit without it)");
    })
    .context("installing the Ctrl-C handler")?;
    runner.set_stop_flag(stop);
    let last = runner.learn(!args.no_progress).map_err(|e| {
        let resume = e
            .last_checkpoint
            .as_ref()
            .map(|p| format!(" (resume with --resume {})", p.display()))
            .unwrap_or_default();
        anyhow::anyhow!("{e}{resume}")
    })?;
    if runner.stopped_early() {
        eprintln!(
            "interrupted at iteration {}: checkpoint {} (resume with --resume {}), metrics {}",
            runner.iteration,
            last.display(),
            last.display(),
            run_dir.join("metrics.csv").display()
        );
        return Ok(());
    }
    eprintln!(
        "done: checkpoint {}, metrics {}",
        last.display(),
        run_dir.join("metrics.csv").display()
    );
    Ok(())
}
