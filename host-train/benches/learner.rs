//! Learner benchmark: the PPO minibatch step and the discriminator step with gradient
//! penalty, at the paper's network sizes, in candle and (same run, same thread count) in
//! PyTorch (`bench/learner_torch.py`), printed as ratios; plus end-to-end training
//! throughput (env steps/s including updates) on the simulator.
//!
//! `cargo bench -p host-train --bench learner -- [--batch N]... [--reps N] [--no-torch] [--e2e-envs N] [--e2e-config F] [--only ppo|discriminator]`
//!
//! By default both batch sizes the presets train with are measured: 1,536 (a minibatch of the
//! CPU presets' 128 x 24 rollout split in 2) and 24,576 (the paper's 4,096 x 24 split in 4).
//! The end-to-end figure is printed beside the ceiling MuJoCo's physics alone would allow on
//! the same threads (its steps/s x threads / decimation), measured in the same run.

use anyhow::{bail, Context};
use candle_core::{DType, Device, Tensor};
use candle_nn::VarMap;
use hexapod_core::nets::ACTOR_OUT;
use hexapod_core::obs::{ACTOR_OBS_DIM, HEIGHT_SCAN_DIM, HISTORY_DIM, PRIVILEGED_DIM};
use host_train::algo::adam::Adam;
use host_train::algo::ppo::{Minibatch, Ppo};
use host_train::amp::discriminator::{Discriminator, DISC_IN};
use host_train::amp::prior_source::SyntheticTripod;
use host_train::config::{EnvKind, TrainConfig};
use host_train::runner::Runner;
use rand::{Rng, SeedableRng};
use std::path::Path;
use std::process::Command;
use std::time::Instant;

/// The command line, printed by `--help` and after an unknown argument.
const USAGE: &str = "cargo bench -p host-train --bench learner -- [--batch N]... [--reps N] [--no-torch] [--e2e-envs N] [--e2e-iterations N] [--e2e-config F] [--only ppo|discriminator]";

#[global_allocator]
static GLOBAL: mimalloc::MiMalloc = mimalloc::MiMalloc;

struct Args {
    batches: Vec<usize>,
    reps: usize,
    torch: bool,
    e2e_envs: usize,
    e2e_iterations: usize,
    e2e_config: String,
    /// Measure only this step (`ppo` or `discriminator`), for profiling one of them.
    only: Option<String>,
}

fn parse_args() -> anyhow::Result<Args> {
    let mut a = Args {
        batches: Vec::new(),
        reps: 5,
        torch: true,
        e2e_envs: 128,
        e2e_iterations: 3,
        e2e_config: "flat-tripod.toml".into(),
        only: None,
    };
    let mut it = std::env::args().skip(1);
    while let Some(arg) = it.next() {
        let mut num = |name: &str| -> anyhow::Result<usize> {
            it.next()
                .with_context(|| format!("{name} needs a value"))?
                .parse()
                .with_context(|| format!("bad {name}"))
        };
        match arg.as_str() {
            "--batch" => a.batches.push(num("--batch")?),
            "--e2e-config" => {
                a.e2e_config = it.next().context("--e2e-config needs a preset file name")?
            }
            "--reps" => a.reps = num("--reps")?,
            "--e2e-envs" => a.e2e_envs = num("--e2e-envs")?,
            "--e2e-iterations" => a.e2e_iterations = num("--e2e-iterations")?,
            "--no-torch" => a.torch = false,
            "--only" => {
                let step = it.next().context("--only needs ppo or discriminator")?;
                if step != "ppo" && step != "discriminator" {
                    bail!("--only {step}: ppo or discriminator");
                }
                a.only = Some(step);
            }
            "--bench" => {}
            "--help" | "-h" => {
                println!("{USAGE}");
                std::process::exit(0);
            }
            other => bail!("unknown argument {other}\nusage: {USAGE}"),
        }
    }
    if a.batches.is_empty() {
        a.batches = vec![1536, 24_576];
    }
    if a.batches.contains(&0) || a.reps == 0 {
        bail!("--batch and --reps must be positive");
    }
    Ok(a)
}

fn random(rng: &mut rand_chacha::ChaCha8Rng, rows: usize, cols: usize) -> Tensor {
    let v: Vec<f32> = (0..rows * cols).map(|_| rng.gen_range(-1.0..1.0)).collect();
    Tensor::from_vec(v, (rows, cols), &Device::Cpu).unwrap()
}

fn median(mut xs: Vec<f64>) -> f64 {
    xs.sort_by(|a, b| a.partial_cmp(b).unwrap());
    xs[xs.len() / 2]
}

fn time<F: FnMut() -> anyhow::Result<()>>(reps: usize, mut f: F) -> anyhow::Result<f64> {
    f()?; // warm-up
    let mut t = Vec::with_capacity(reps);
    for _ in 0..reps {
        let t0 = Instant::now();
        f()?;
        t.push(t0.elapsed().as_secs_f64());
    }
    Ok(median(t))
}

/// The PPO minibatch step (paper networks, no AMP): forward, losses, backward, clipped Adam.
fn candle_ppo_step(batch: usize, reps: usize) -> anyhow::Result<f64> {
    let mut cfg = TrainConfig::default();
    cfg.rewards.style = false;
    let mut ppo = Ppo::new(&cfg)?;
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(0);
    let mb = Minibatch {
        actor: random(&mut rng, batch, ACTOR_OBS_DIM),
        history: random(&mut rng, batch, HISTORY_DIM),
        privileged: random(&mut rng, batch, PRIVILEGED_DIM),
        heights: random(&mut rng, batch, HEIGHT_SCAN_DIM),
        actions: random(&mut rng, batch, ACTOR_OUT),
        old_mean: random(&mut rng, batch, ACTOR_OUT),
        old_log_probs: random(&mut rng, batch, 1).squeeze(1)?,
        advantages: random(&mut rng, batch, 1).squeeze(1)?,
        old_values: random(&mut rng, batch, 1).squeeze(1)?,
        returns: random(&mut rng, batch, 1).squeeze(1)?,
    };
    let old_log_std = ppo.ac.log_std.detach().copy()?;
    time(reps, || {
        ppo.minibatch_step(&mb, &old_log_std, None, 0)?;
        Ok(())
    })
}

/// The discriminator step: LSGAN loss on `batch` prior and `batch` policy transitions,
/// gradient penalty on the prior ones, backward, Adam.
fn candle_disc_step(batch: usize, reps: usize) -> anyhow::Result<f64> {
    let (params, stats) = (VarMap::new(), VarMap::new());
    let disc = Discriminator::new(&[1024, 512], &params, &stats, 1, DType::F32, &Device::Cpu)?;
    let mut opt = Adam::new(&params, 1e-4)?;
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
    let prior = random(&mut rng, batch, DISC_IN);
    let policy = random(&mut rng, batch, DISC_IN);
    time(reps, || {
        let l = disc.loss(&prior, &policy, 10.0)?;
        opt.step(&l.total.backward()?, None)?;
        Ok(())
    })
}

/// End-to-end: `hexapod train` iterations on the simulator with a preset (its own priors),
/// env steps per second including updates.
fn end_to_end(config: &str, envs: usize, iterations: usize) -> anyhow::Result<(f64, f64, f64)> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../configs")
        .join(config);
    let mut cfg = TrainConfig::load(&root)?;
    cfg.env.kind = EnvKind::Sim;
    cfg.env.num_envs = envs;
    cfg.runner.max_iterations = iterations;
    let env = host_train::env::make_env(&cfg)?;
    let dir = std::env::temp_dir().join(format!("hexapod-bench-{}", std::process::id()));
    let mut runner = Runner::new(&cfg, env, Some(Box::new(SyntheticTripod::default())), &dir)?;
    runner.iterate()?; // warm-up (replay buffer, allocator)
    let (mut collect, mut update, mut steps) = (0.0, 0.0, 0.0);
    for _ in 0..iterations {
        let row = runner.iterate()?;
        collect += row["perf/collect_s"];
        update += row["perf/update_s"];
        steps += (cfg.env.num_envs * cfg.ppo.num_steps_per_env) as f64;
    }
    std::fs::remove_dir_all(&dir).ok();
    Ok((
        steps / (collect + update),
        collect / iterations as f64,
        update / iterations as f64,
    ))
}

fn torch_times(batch: usize, reps: usize, threads: usize) -> anyhow::Result<(f64, f64)> {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("../bench/learner_torch.py");
    let out = Command::new("python3")
        .arg(&script)
        .args([
            "--batch",
            &batch.to_string(),
            "--reps",
            &reps.to_string(),
            "--threads",
            &threads.to_string(),
        ])
        .output()
        .context("running python3 bench/learner_torch.py")?;
    if !out.status.success() {
        bail!(
            "PyTorch benchmark failed: {}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
    let v: serde_json::Value =
        serde_json::from_slice(&out.stdout).context("PyTorch benchmark output")?;
    Ok((
        v["ppo_step_s"].as_f64().context("ppo_step_s")?,
        v["disc_step_s"].as_f64().context("disc_step_s")?,
    ))
}

fn main() -> anyhow::Result<()> {
    let args = parse_args()?;
    let kept = host_train::alloc::keep_freed_memory();
    host_train::threads::single_threaded_elementwise();
    let threads = candle_core::utils::get_num_threads();
    println!(
        "learner benchmark: batches {:?}, median of {} reps, {} threads (candle element-wise pool: {}), mimalloc purging {}",
        args.batches,
        args.reps,
        threads,
        std::env::var("CANDLE_NUM_THREADS").unwrap_or_default(),
        if kept { "off" } else { "on" }
    );
    println!(
        "{:<34} {:>7} {:>10} {:>10} {:>8}",
        "step", "batch", "candle s", "torch s", "ratio"
    );
    for &batch in &args.batches {
        let wanted = |step: &str| args.only.as_deref().is_none_or(|o| o == step);
        let ppo = if wanted("ppo") {
            candle_ppo_step(batch, args.reps)?
        } else {
            f64::NAN
        };
        let disc = if wanted("discriminator") {
            candle_disc_step(batch, args.reps)?
        } else {
            f64::NAN
        };
        let torch = if args.torch {
            match torch_times(batch, args.reps, threads) {
                Ok(t) => Some(t),
                Err(e) => {
                    println!("PyTorch: not measured ({e})");
                    None
                }
            }
        } else {
            None
        };
        for (name, c, t) in [
            ("PPO minibatch step", ppo, torch.map(|t| t.0)),
            ("discriminator step + penalty", disc, torch.map(|t| t.1)),
        ] {
            match t {
                Some(t) => println!("{name:<34} {batch:>7} {c:>10.3} {t:>10.3} {:>7.2}x", c / t),
                None => println!("{name:<34} {batch:>7} {c:>10.3} {:>10} {:>8}", "-", "-"),
            }
        }
    }
    if args.e2e_envs > 0 {
        let (sps, collect, update) =
            end_to_end(&args.e2e_config, args.e2e_envs, args.e2e_iterations)?;
        println!(
            "end to end (sim, {} envs x 24 steps, {}): {:.0} env steps/s (collect {:.2} s + update {:.2} s per iteration, update {:.0} % of it)",
            args.e2e_envs,
            args.e2e_config,
            sps,
            collect,
            update,
            100.0 * update / (collect + update)
        );
        match host_sim::peer::run_mujoco(5000, 400) {
            Ok(p) => match p.flat_steps_per_s {
                Some(mj) => println!(
                    "ceiling: MuJoCo physics alone, flat, {:.0} steps/s x {} threads / decimation {} = {:.0} env steps/s",
                    mj,
                    threads,
                    hexapod_core::timing::DECIMATION,
                    mj * threads as f64 / hexapod_core::timing::DECIMATION as f64
                ),
                None => println!("ceiling: MuJoCo gave no flat rate"),
            },
            Err(e) => println!("ceiling: MuJoCo not measured ({e})"),
        }
    }
    Ok(())
}
