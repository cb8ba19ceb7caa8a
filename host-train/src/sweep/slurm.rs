//! The Slurm backend: one `sbatch --array` job whose tasks are the sweep's unfinished jobs.
//! Each array task runs `hexapod sweep task SPEC --index $SLURM_ARRAY_TASK_ID` (train, then
//! the suite) with the cores it was given; logs go to `<sweep dir>/logs/<array id>_<index>.log`.
//! A task killed at its time limit loses at most the iterations since its last checkpoint
//! (`runner.save_interval`): submitting the sweep again resumes it.

use super::spec::Sweep;
use anyhow::{bail, Context};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::Command;

/// The batch script for the array tasks `indices`, run from `workdir` with `exe`.
pub fn batch_script(
    sweep: &Sweep,
    indices: &[usize],
    exe: &Path,
    spec_file: &Path,
    workdir: &Path,
) -> String {
    let s = &sweep.spec.slurm;
    let logs = absolute(workdir, &sweep.dir.join("logs"));
    let list: Vec<String> = indices.iter().map(|i| i.to_string()).collect();
    let mut array = list.join(",");
    if let Some(n) = s.max_parallel {
        let _ = write!(array, "%{n}");
    }
    let mut b = String::from("#!/bin/bash\n");
    let _ = writeln!(
        b,
        "# The sweep `{}` ({} jobs), written by `hexapod sweep run --backend slurm`.",
        sweep.spec.name,
        sweep.jobs.len()
    );
    let _ = writeln!(b, "#SBATCH --job-name=hexapod-{}", sweep.spec.name);
    let _ = writeln!(b, "#SBATCH --array={array}");
    let _ = writeln!(b, "#SBATCH --ntasks=1");
    let _ = writeln!(b, "#SBATCH --cpus-per-task={}", s.cpus_per_task);
    let _ = writeln!(b, "#SBATCH --time={}", s.time);
    if let Some(p) = &s.partition {
        let _ = writeln!(b, "#SBATCH --partition={p}");
    }
    if let Some(a) = &s.account {
        let _ = writeln!(b, "#SBATCH --account={a}");
    }
    if let Some(m) = &s.mem {
        let _ = writeln!(b, "#SBATCH --mem={m}");
    }
    for e in &s.extra {
        let _ = writeln!(b, "#SBATCH {e}");
    }
    let _ = writeln!(b, "#SBATCH --chdir={}", workdir.display());
    let _ = writeln!(b, "#SBATCH --output={}/%A_%a.log", logs.display());
    let _ = writeln!(b, "set -eu");
    let _ = writeln!(
        b,
        "export RAYON_NUM_THREADS=${{SLURM_CPUS_PER_TASK:-{}}}",
        s.cpus_per_task
    );
    let _ = writeln!(
        b,
        "exec {} sweep task {} --index \"$SLURM_ARRAY_TASK_ID\"",
        quote(exe),
        quote(spec_file)
    );
    b
}

fn absolute(workdir: &Path, p: &Path) -> PathBuf {
    if p.is_absolute() {
        p.to_path_buf()
    } else {
        workdir.join(p)
    }
}

fn quote(p: &Path) -> String {
    let s = p.display().to_string();
    if s.chars()
        .all(|c| c.is_ascii_alphanumeric() || "/._-+".contains(c))
    {
        s
    } else {
        format!("'{}'", s.replace('\'', "'\\''"))
    }
}

/// Writes the batch script into the sweep's directory and submits it with `sbatch`
/// (`--wait`: returns when every task has ended). Returns the array job's id.
pub fn submit(sweep: &Sweep, indices: &[usize], exe: &Path, wait: bool) -> anyhow::Result<String> {
    let workdir = std::env::current_dir().context("the working directory")?;
    let spec_file = sweep
        .path
        .canonicalize()
        .with_context(|| format!("sweep file {}", sweep.path.display()))?;
    std::fs::create_dir_all(sweep.dir.join("logs"))
        .with_context(|| format!("creating {}", sweep.dir.join("logs").display()))?;
    let script = sweep.dir.join("sweep.sbatch");
    std::fs::write(
        &script,
        batch_script(sweep, indices, exe, &spec_file, &workdir),
    )
    .with_context(|| format!("writing {}", script.display()))?;
    let mut cmd = Command::new("sbatch");
    cmd.arg("--parsable");
    if wait {
        cmd.arg("--wait");
    }
    let out = cmd.arg(&script).output().map_err(|e| {
        if e.kind() == std::io::ErrorKind::NotFound {
            anyhow::anyhow!("`sbatch` not found: the slurm backend needs a Slurm client on this machine (or use --backend local)")
        } else {
            anyhow::anyhow!("running sbatch: {e}")
        }
    })?;
    let stdout = String::from_utf8_lossy(&out.stdout).trim().to_string();
    let id = stdout
        .lines()
        .next()
        .unwrap_or("")
        .split(';')
        .next()
        .unwrap_or("")
        .to_string();
    if !out.status.success() {
        let stderr = String::from_utf8_lossy(&out.stderr);
        if wait && !id.is_empty() {
            // `--wait` exits non-zero when a task failed; the sweep's status tells which.
            eprintln!(
                "sbatch: array job {id} ended with failed tasks: {}",
                stderr.trim()
            );
            return Ok(id);
        }
        bail!("sbatch refused {}: {}", script.display(), stderr.trim());
    }
    let log = sweep.dir.join("slurm-jobs.txt");
    let mut previous = std::fs::read_to_string(&log).unwrap_or_default();
    let _ = writeln!(
        previous,
        "{id} {}",
        indices
            .iter()
            .map(|i| i.to_string())
            .collect::<Vec<_>>()
            .join(",")
    );
    std::fs::write(&log, previous).with_context(|| format!("writing {}", log.display()))?;
    Ok(id)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sweep::spec::parse;

    #[test]
    fn the_script_runs_the_unfinished_tasks_with_their_resources() {
        let spec = "name = \"cmp\"\npresets = [\"configs/baseline.toml\", \"configs/concurrent.toml\"]\nseeds = [1, 2, 3]\n\
                    [slurm]\npartition = \"cpu\"\ntime = \"12:00:00\"\ncpus_per_task = 8\nmem = \"16G\"\nmax_parallel = 4\nextra = [\"--qos=long\"]\n";
        let sweep = parse(spec, Path::new("cmp.toml")).unwrap();
        let s = batch_script(
            &sweep,
            &[1, 4, 5],
            Path::new("/opt/hexapod"),
            Path::new("/home/u/cmp sweep.toml"),
            Path::new("/home/u/hexapod"),
        );
        for line in [
            "#SBATCH --array=1,4,5%4",
            "#SBATCH --cpus-per-task=8",
            "#SBATCH --time=12:00:00",
            "#SBATCH --partition=cpu",
            "#SBATCH --mem=16G",
            "#SBATCH --qos=long",
            "#SBATCH --chdir=/home/u/hexapod",
            "#SBATCH --output=/home/u/hexapod/runs/sweeps/cmp/logs/%A_%a.log",
            "export RAYON_NUM_THREADS=${SLURM_CPUS_PER_TASK:-8}",
            "exec /opt/hexapod sweep task '/home/u/cmp sweep.toml' --index \"$SLURM_ARRAY_TASK_ID\"",
        ] {
            assert!(s.lines().any(|l| l == line), "missing `{line}` in\n{s}");
        }
        assert!(!s.contains("--account"));
    }
}
