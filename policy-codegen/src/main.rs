//! `policy-codegen` CLI: random checkpoint, code generation (and its freshness check),
//! ONNX export, accuracy report, ELF size budget.

use anyhow::{bail, Context, Result};
use clap::{Parser, Subcommand};
use policy_codegen::{
    accuracy, bench, checkpoint, emit, onnx, quantize_default, random, records, sim, size,
};
use std::path::{Path, PathBuf};

#[derive(Parser)]
#[command(about = "Checkpoint -> fixed-point Rust for the hexapod firmware")]
struct Cli {
    #[command(subcommand)]
    command: Cmd,
}

#[derive(Subcommand)]
enum Cmd {
    /// Writes a randomly initialized checkpoint (policy.safetensors + config.toml).
    RandomCheckpoint {
        /// Output directory.
        #[arg(long, default_value = "assets/policies/random-init")]
        out: PathBuf,
        /// Seed.
        #[arg(long, default_value_t = 0)]
        seed: u64,
        /// Init scale of the output layers (0.1: near-zero actions; 0.5-1: actions of a
        /// trained policy's size).
        #[arg(long, default_value_t = 0.1)]
        output_gain: f32,
    },
    /// Generates the hexapod-policy crate from a checkpoint directory (or an ONNX MLP).
    Generate {
        /// Checkpoint directory.
        #[arg(long, default_value = policy_codegen::SHIPPED_CHECKPOINT)]
        checkpoint: PathBuf,
        /// ONNX file of a plain MLP actor (replaces --checkpoint).
        #[arg(long)]
        onnx: Option<PathBuf>,
        /// Crate directory.
        #[arg(long, default_value = "firmware/policy")]
        out: PathBuf,
        /// Only check that the files on disk are up to date (exit 1 when stale).
        #[arg(long)]
        check: bool,
    },
    /// Writes the deployed networks (estimator, memory, actor, with the normalizers as
    /// Sub/Div) as one ONNX model, `policy.onnx`, and `reference.json`: fixed inputs and
    /// the f32 forward pass's outputs, for checking a runtime against the checkpoint.
    ExportOnnx {
        /// Checkpoint directory.
        #[arg(long, default_value = policy_codegen::SHIPPED_CHECKPOINT)]
        checkpoint: PathBuf,
        /// Output directory.
        #[arg(long, default_value = "runs/onnx")]
        out: PathBuf,
        /// Reference inputs (synthetic observations, seed 11).
        #[arg(long, default_value_t = 16)]
        count: usize,
    },
    /// Max |a_fixed - a_f32| over observations (synthetic, or a recording).
    Accuracy {
        /// Checkpoint directory.
        #[arg(long, default_value = policy_codegen::SHIPPED_CHECKPOINT)]
        checkpoint: PathBuf,
        /// Recorded observations (f32 rows of actor obs 63 + history 210).
        #[arg(long)]
        observations: Option<PathBuf>,
        /// Synthetic observations when no recording is given.
        #[arg(long, default_value_t = 10_000)]
        count: usize,
        /// Fail when the largest difference exceeds this.
        #[arg(long)]
        max_abs_diff: Option<f32>,
    },
    /// Compares the QEMU benchmark's output with the host's fixed-point step on the same
    /// input (bit for bit) and checks the instructions per MAC.
    BenchCheck {
        /// Captured stdout of `firmware/qemu-bench` (`cargo run --release`).
        output: PathBuf,
        /// Checkpoint the crate was generated from.
        #[arg(long, default_value = policy_codegen::SHIPPED_CHECKPOINT)]
        checkpoint: PathBuf,
        /// Fail above this many instructions per MAC (SMLALD kernel).
        #[arg(long, default_value_t = 1.5)]
        max_insns_per_mac: f32,
    },
    /// Closed loop in host-sim: f32 vs fixed point on the same robots, and the largest
    /// action difference on the observations the f32 run recorded.
    SimCompare {
        /// Checkpoint directory.
        #[arg(long, default_value = policy_codegen::SHIPPED_CHECKPOINT)]
        checkpoint: PathBuf,
        /// Robots.
        #[arg(long, default_value_t = 16)]
        num_envs: usize,
        /// Policy steps (50 per second).
        #[arg(long, default_value_t = 700)]
        steps: usize,
        /// Environment seeds 1..=N (each run with both policies).
        #[arg(long, default_value_t = 3)]
        seeds: u64,
        /// Also write the recorded observations (for `accuracy --observations`).
        #[arg(long)]
        record: Option<PathBuf>,
    },
    /// Checks a firmware ELF's flash and RAM use against memory.x.
    Size {
        /// The ELF.
        elf: PathBuf,
        /// The linker memory map.
        #[arg(long, default_value = "memory.x")]
        memory_x: PathBuf,
    },
}

/// A path as written into generated files: relative, with forward slashes.
fn display_path(path: &Path) -> String {
    let cwd = std::env::current_dir().unwrap_or_default();
    let rel = path.strip_prefix(&cwd).unwrap_or(path);
    rel.to_string_lossy()
        .replace('\\', "/")
        .trim_end_matches('/')
        .to_string()
}

fn main() -> Result<()> {
    match Cli::parse().command {
        Cmd::RandomCheckpoint {
            out,
            seed,
            output_gain,
        } => {
            let spec = random::RandomSpec {
                seed,
                output_gain,
                ..Default::default()
            };
            let policy = random::random_policy(&spec);
            let sha = random::write_checkpoint(&out, &policy, &spec)?;
            println!(
                "wrote {} (sha256 {sha}, {} MACs)",
                out.display(),
                policy.macs()
            );
        }
        Cmd::Generate {
            checkpoint: dir,
            onnx: onnx_path,
            out,
            check,
        } => {
            let (policy, source, sha256) = match &onnx_path {
                Some(path) => {
                    let bytes = std::fs::read(path)
                        .with_context(|| format!("reading {}", path.display()))?;
                    (
                        onnx::import(&bytes)?,
                        display_path(path),
                        checkpoint::sha256_hex(&bytes),
                    )
                }
                None => {
                    let ck = checkpoint::load(&dir)?;
                    (ck.policy, display_path(&dir), ck.sha256)
                }
            };
            let q = quantize_default(&policy)?;
            let prov = emit::Provenance {
                checkpoint: source,
                sha256,
                macs: policy.macs(),
            };
            let files = emit::generate(&prov, &q)?;
            if check {
                let stale = emit::stale(&out, &files);
                if !stale.is_empty() {
                    bail!(
                        "{} is stale ({}): run `cargo run -p policy-codegen -- generate --checkpoint {}`",
                        out.display(),
                        stale.iter().map(|p| p.display().to_string()).collect::<Vec<_>>().join(", "),
                        prov.checkpoint
                    );
                }
                println!("{} is up to date with {}", out.display(), prov.checkpoint);
            } else {
                emit::write(&out, &files)?;
                println!(
                    "wrote {} from {} ({} MACs)",
                    out.display(),
                    prov.checkpoint,
                    prov.macs
                );
            }
        }
        Cmd::ExportOnnx {
            checkpoint: dir,
            out,
            count,
        } => {
            let ck = checkpoint::load(&dir)?;
            let source = display_path(&dir);
            let mut model = onnx::export_model(&ck.policy);
            model.doc_string = format!(
                "hexapod policy from {source} (policy.safetensors sha256 {}): actions = actor(concat((actor_obs - mean) / std, estimator(h), memory(h))), h = (history - mean) / std; the runtime clips actions to +-{}",
                ck.sha256,
                hexapod_core::obs::ACTION_CLIP
            );
            let bytes = prost::Message::encode_to_vec(&model);
            // The model must read back as the same policy.
            anyhow::ensure!(
                onnx::import(&bytes)? == ck.policy,
                "the exported model does not import as the checkpoint's policy"
            );
            std::fs::create_dir_all(&out).with_context(|| format!("creating {}", out.display()))?;
            let model_path = out.join("policy.onnx");
            std::fs::write(&model_path, &bytes)
                .with_context(|| format!("writing {}", model_path.display()))?;
            let recs = records::synthetic(count, 11);
            let reference = onnx::reference_json(&ck.policy, &recs, &source, &ck.sha256);
            let ref_path = out.join("reference.json");
            std::fs::write(&ref_path, reference)
                .with_context(|| format!("writing {}", ref_path.display()))?;
            println!(
                "wrote {} ({} bytes, {} MACs) and {} ({count} inputs) from {source}",
                model_path.display(),
                bytes.len(),
                ck.policy.macs(),
                ref_path.display()
            );
        }
        Cmd::Accuracy {
            checkpoint: dir,
            observations,
            count,
            max_abs_diff,
        } => {
            let ck = checkpoint::load(&dir)?;
            let q = quantize_default(&ck.policy)?;
            let (recs, what) = match &observations {
                Some(p) => (
                    records::load(p)?,
                    format!("recorded observations {}", p.display()),
                ),
                None => (
                    records::synthetic(count, 2),
                    "synthetic observations (seed 2)".to_string(),
                ),
            };
            let r =
                accuracy::compare(&ck.policy, &q, &recs).map_err(|e| anyhow::anyhow!("{e:?}"))?;
            println!(
                "{}: {} {}: max |a_fixed - a_f32| = {:.3e}, mean {:.3e}, max |a_f32| = {:.3}",
                display_path(&dir),
                r.count,
                what,
                r.max_abs_diff,
                r.mean_abs_diff,
                r.max_abs_action
            );
            if let Some(limit) = max_abs_diff {
                if r.max_abs_diff > limit {
                    bail!(
                        "max |a_fixed - a_f32| = {:.3e} exceeds {limit:e}",
                        r.max_abs_diff
                    );
                }
            }
        }
        Cmd::BenchCheck {
            output,
            checkpoint: dir,
            max_insns_per_mac,
        } => {
            let text = std::fs::read_to_string(&output)
                .with_context(|| format!("reading {}", output.display()))?;
            let bench = bench::parse(&text)?;
            let q = quantize_default(&checkpoint::load(&dir)?.policy)?;
            let host = q
                .with_view(bench::host_action_q)
                .map_err(|e| anyhow::anyhow!("{e:?}"))?;
            if bench.action_q != host {
                bail!(
                    "QEMU output {:?} differs from the host's {:?}",
                    bench.action_q,
                    host
                );
            }
            println!(
                "QEMU and host agree bit for bit on {} actions; {:.0} instructions/step, {:.3} instructions/MAC (SMLALD), {:.3} (portable)",
                host.len(), bench.smlald_insns, bench.smlald_per_mac, bench.portable_per_mac
            );
            if bench.smlald_per_mac > max_insns_per_mac {
                bail!(
                    "{:.3} instructions/MAC exceeds the budget {max_insns_per_mac}",
                    bench.smlald_per_mac
                );
            }
        }
        Cmd::SimCompare {
            checkpoint: dir,
            num_envs,
            steps,
            seeds,
            record,
        } => {
            let ck = checkpoint::load(&dir)?;
            let q = quantize_default(&ck.policy)?;
            println!(
                "closed loop in host-sim, {num_envs} robots x {steps} steps, seeds 1..={seeds}:"
            );
            println!("  seed  policy       mean reward  falls/robot  mean vx m/s  mean |a|");
            let mut all = Vec::new();
            let (mut rf, mut rx) = (Vec::new(), Vec::new());
            for seed in 1..=seeds {
                let (f, x, recs) = sim::compare_closed_loop(&ck.policy, &q, num_envs, steps, seed)?;
                for (name, r) in [("f32", &f), ("fixed-point", &x)] {
                    println!(
                        "  {seed:>4}  {name:<11}  {:>11.5}  {:>11.3}  {:>11.4}  {:>8.4}",
                        r.mean_reward, r.falls_per_robot, r.mean_vx_m_s, r.mean_abs_action
                    );
                }
                rf.push(f.mean_reward);
                rx.push(x.mean_reward);
                all.extend(recs);
            }
            let stats = |v: &[f64]| {
                let m = v.iter().sum::<f64>() / v.len().max(1) as f64;
                let var =
                    v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (v.len().max(2) - 1) as f64;
                (m, var.sqrt())
            };
            let ((mf, sf), (mx, sx)) = (stats(&rf), stats(&rx));
            println!(
                "  mean reward over seeds: f32 {mf:.5} +- {sf:.5}, fixed point {mx:.5} +- {sx:.5}"
            );
            let r =
                accuracy::compare(&ck.policy, &q, &all).map_err(|e| anyhow::anyhow!("{e:?}"))?;
            println!(
                "  on the {} observations recorded along the f32 runs: max |a_fixed - a_f32| = {:.3e}, mean {:.3e}, max |a_f32| = {:.3}",
                r.count, r.max_abs_diff, r.mean_abs_diff, r.max_abs_action
            );
            if let Some(path) = record {
                records::save(&path, &all)?;
                println!("  recorded observations written to {}", path.display());
            }
        }
        Cmd::Size { elf, memory_x } => {
            let report = size::check(&elf, &memory_x)?;
            println!("{report}");
            if !report.fits() {
                bail!("{} does not fit {}", elf.display(), memory_x.display());
            }
        }
    }
    Ok(())
}
