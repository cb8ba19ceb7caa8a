//! `hexapod rma-adapt`: RMA's adaptation phase (Kumar et al. 2021) on a teacher trained with
//! an `[rma]` preset (`configs/rma.toml`). The teacher's actor, estimator and mu stay frozen;
//! the memory encoder learns to regress mu's latent from the proprioceptive history on the
//! student's own rollouts ([`crate::algo::adaptation`]). The result is a normal checkpoint
//! (`rma.phase = "adapted"`: the actor reads the memory's latent) that `eval`, `eval --suite`,
//! `play` and `policy-codegen generate --checkpoint` take as they take any other.

use crate::algo::adaptation::{Adaptation, AdaptationConfig, AdaptationStats};
use crate::amp::prior_source::load_prior_source;
use crate::checkpoint;
use crate::env::make_env;
use anyhow::Context;
use clap::Args;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// File beside the adapted checkpoint's weights with one row per adaptation iteration.
pub const ADAPTATION_CSV: &str = "adaptation.csv";

/// Arguments of `hexapod rma-adapt`.
#[derive(Args, Debug)]
pub struct RmaAdaptArgs {
    /// The teacher: a checkpoint directory, or a run directory (its latest checkpoint).
    #[arg(long)]
    pub teacher: PathBuf,
    /// Checkpoint directory to write (replaced if it exists).
    #[arg(long)]
    pub out: PathBuf,
    /// Adaptation iterations (rollout + regression).
    #[arg(long, default_value_t = 200)]
    pub iterations: usize,
    /// Policy steps per robot and iteration (50 per second).
    #[arg(long, default_value_t = 24)]
    pub steps: usize,
    /// Passes over each iteration's rollout.
    #[arg(long, default_value_t = 4)]
    pub epochs: usize,
    /// Minibatches per pass.
    #[arg(long, default_value_t = 4)]
    pub mini_batches: usize,
    /// Adam learning rate of the memory encoder.
    #[arg(long, default_value_t = 5e-4)]
    pub learning_rate: f64,
    /// Share of the iterations over which the teacher's actions are mixed in, falling
    /// linearly from all to none (0: the student acts from the start).
    #[arg(long, default_value_t = 0.2)]
    pub teacher_mix: f64,
    /// Robots (default: the teacher's `env.num_envs`).
    #[arg(long)]
    pub num_envs: Option<usize>,
    /// Seed of the environment and of the mixing and minibatch draws (default: the
    /// teacher's `env.seed`).
    #[arg(long)]
    pub seed: Option<u64>,
}

/// Runs `hexapod rma-adapt`.
pub fn run(args: RmaAdaptArgs) -> anyhow::Result<()> {
    anyhow::ensure!(args.iterations > 0, "--iterations must be positive");
    anyhow::ensure!(
        (0.0..=1.0).contains(&args.teacher_mix),
        "--teacher-mix must lie in [0, 1], got {}",
        args.teacher_mix
    );
    let teacher = checkpoint::resolve_dir(&args.teacher)?;
    let mut cfg = checkpoint::load_config(&teacher)?;
    if !cfg.rma_teacher() {
        anyhow::bail!(
            "{} is not an RMA teacher (its config.toml has {}); train one with `hexapod train -c configs/rma.toml`",
            teacher.display(),
            match &cfg.rma {
                None => "no [rma] section".to_string(),
                Some(r) => format!("rma.phase = {:?}", r.phase),
            }
        );
    }
    if let Some(n) = args.num_envs {
        cfg.env.num_envs = n;
    }
    if let Some(seed) = args.seed {
        cfg.env.seed = seed;
    }
    cfg.validate()?;
    if cfg.runner.num_threads > 0 {
        std::env::set_var("RAYON_NUM_THREADS", cfg.runner.num_threads.to_string());
    }
    let mut ppo = crate::algo::ppo::Ppo::new(&cfg)?;
    checkpoint::load(&teacher, &mut ppo, true)
        .with_context(|| format!("loading the teacher {}", teacher.display()))?;
    let iteration = checkpoint::load_iteration(&teacher)?;
    let mut env = make_env(&cfg)?;
    // Episodes start as they did in the teacher's training (reference states with AMP).
    if let Some(p) = load_prior_source(&cfg)? {
        let references = p.reference_states();
        if !references.is_empty() {
            env.set_reference_states(references.into());
        }
    }
    let acfg = AdaptationConfig {
        steps_per_iteration: args.steps,
        epochs: args.epochs,
        mini_batches: args.mini_batches,
        learning_rate: args.learning_rate,
        max_grad_norm: cfg.ppo.max_grad_norm as f64,
        teacher_mix_iterations: (args.teacher_mix * args.iterations as f64).ceil() as usize,
        seed: cfg.env.seed,
    };
    eprintln!(
        "adapting the memory encoder of {} (iteration {iteration}): {} robots x {} steps, {} iterations, teacher actions mixed in over the first {} -> {}",
        teacher.display(),
        cfg.env.num_envs,
        args.steps,
        args.iterations,
        acfg.teacher_mix_iterations,
        args.out.display()
    );
    let mut adapt = Adaptation::new(ppo, env, acfg)?;
    let mut rows = Vec::with_capacity(args.iterations);
    let t0 = Instant::now();
    for _ in 0..args.iterations {
        let t = Instant::now();
        let st = adapt.iterate()?;
        eprintln!(
            "{}",
            progress_line(&st, args.iterations, t.elapsed().as_secs_f64())
        );
        rows.push(st);
    }
    let ppo = adapt.into_adapted();
    checkpoint::save(&args.out, &ppo, iteration)
        .with_context(|| format!("writing {}", args.out.display()))?;
    write_csv(&args.out.join(ADAPTATION_CSV), &rows)?;
    // The suite's curriculum protocol (Fig. 4) reads metrics.csv beside a checkpoint: the
    // adapted policy's terrain curriculum is its teacher's.
    if let Some(metrics) = teacher_metrics(&teacher) {
        std::fs::copy(&metrics, args.out.join("metrics.csv"))
            .with_context(|| format!("copying {}", metrics.display()))?;
    }
    eprintln!(
        "done in {:.0} s: checkpoint {} (the actor reads the memory's latent; evaluate it with `hexapod eval --checkpoint {}`)",
        t0.elapsed().as_secs_f64(),
        args.out.display(),
        args.out.display()
    );
    Ok(())
}

/// The teacher's training metrics: beside the checkpoint or in its run directory.
fn teacher_metrics(teacher: &Path) -> Option<PathBuf> {
    let beside = teacher.join("metrics.csv");
    if beside.is_file() {
        return Some(beside);
    }
    let run = teacher.parent()?.parent()?.join("metrics.csv");
    run.is_file().then_some(run)
}

/// One iteration's progress line.
pub fn progress_line(st: &AdaptationStats, iterations: usize, seconds: f64) -> String {
    format!(
        "adapt {:>4}/{iterations}: latent MSE {:.4} (mu's latent variance {:.4}), regression loss {:.4} (last pass {:.4}), teacher actions {:>3.0}%, action gap {:.3} rms, reward/step {:.4}, falls {}/{} episodes, {:.0} env steps/s",
        st.iteration + 1,
        st.latent_mse,
        st.latent_variance,
        st.regression_loss,
        st.regression_loss_last_epoch,
        100.0 * st.teacher_share,
        st.action_gap_rms,
        st.reward_per_step,
        st.terminations,
        st.episodes,
        st.env_steps as f64 / seconds.max(1e-9)
    )
}

fn write_csv(path: &Path, rows: &[AdaptationStats]) -> anyhow::Result<()> {
    let mut f = std::io::BufWriter::new(
        std::fs::File::create(path).with_context(|| format!("writing {}", path.display()))?,
    );
    writeln!(
        f,
        "iteration,teacher_share,latent_mse,latent_variance,regression_loss,regression_loss_last_epoch,action_gap_rms,reward_per_step,terminations,episodes,env_steps"
    )?;
    for r in rows {
        writeln!(
            f,
            "{},{},{},{},{},{},{},{},{},{},{}",
            r.iteration,
            r.teacher_share,
            r.latent_mse,
            r.latent_variance,
            r.regression_loss,
            r.regression_loss_last_epoch,
            r.action_gap_rms,
            r.reward_per_step,
            r.terminations,
            r.episodes,
            r.env_steps
        )?;
    }
    f.flush()
        .with_context(|| format!("writing {}", path.display()))
}
