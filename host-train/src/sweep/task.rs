//! One job of a sweep, start to finish: train (resuming from the run's latest checkpoint when
//! one exists), adapt an RMA teacher into its deployed student (`hexapod rma-adapt`), then
//! evaluate with the suite. A job's progress is read off its files, so a job
//! interrupted anywhere (a time limit, a preempted node, Ctrl-C) continues where it stopped
//! when the sweep runs again, and a finished job is never run twice.
//!
//! Training and the suite run as child processes of this same `hexapod` binary, exactly as a
//! user would type them (the command is printed), each with its own Ctrl-C handling.

use super::spec::{Job, Sweep};
use crate::checkpoint::{load_iteration, resolve_dir};
use anyhow::{bail, Context};
use std::path::{Path, PathBuf};
use std::process::Command;

/// Where a job stands.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum JobState {
    /// Nothing trained yet.
    Pending,
    /// Trained up to this iteration, short of the config's.
    Training(usize),
    /// Trained (and, for an RMA teacher, adapted), not yet evaluated (or its report is
    /// incomplete).
    Trained,
    /// Trained and evaluated: its suite report is complete.
    Done,
}

impl std::fmt::Display for JobState {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            JobState::Pending => write!(f, "pending"),
            JobState::Training(i) => write!(f, "trained to iteration {i}"),
            JobState::Trained => write!(f, "trained, not evaluated"),
            JobState::Done => write!(f, "done"),
        }
    }
}

/// The iteration of the run's latest checkpoint, if it has one.
pub fn trained_iterations(job: &Job) -> Option<usize> {
    let dir = resolve_dir(&job.run_dir()).ok()?;
    load_iteration(&dir).ok()
}

/// Whether the job's suite report exists and says it is complete.
pub fn evaluated(job: &Job) -> bool {
    let path = job.suite_dir().join("report.json");
    let Ok(text) = std::fs::read_to_string(path) else {
        return false;
    };
    serde_json::from_str::<serde_json::Value>(&text)
        .ok()
        .and_then(|v| v.get("complete")?.as_bool())
        .unwrap_or(false)
}

/// Whether an RMA teacher's student is written: `rma-adapt` writes its `adaptation.csv`
/// after the checkpoint, so the file marks a finished adaptation.
pub fn adapted(job: &Job) -> bool {
    job.adapted_dir()
        .join(crate::cli::rma_adapt::ADAPTATION_CSV)
        .is_file()
}

/// Where `job` stands, read off its files.
pub fn state(job: &Job) -> JobState {
    match trained_iterations(job) {
        None => JobState::Pending,
        Some(i) if i < job.max_iterations => JobState::Training(i),
        Some(_) if evaluated(job) => JobState::Done,
        Some(_) => JobState::Trained,
    }
}

/// The `hexapod train` arguments of a job (resuming from its run directory when it has a
/// checkpoint, else from the sweep's `init_checkpoint` if it names one).
pub fn train_args(job: &Job) -> Vec<String> {
    let mut a = vec![
        "train".to_string(),
        "-c".into(),
        job.preset.display().to_string(),
        "--run-dir".into(),
        job.run_dir().display().to_string(),
        "--seed".into(),
        job.seed.to_string(),
        "--no-progress".into(),
    ];
    for o in &job.overrides {
        a.push("--set".into());
        a.push(o.clone());
    }
    if trained_iterations(job).is_some() {
        a.push("--resume".into());
        a.push(job.run_dir().display().to_string());
    } else if let Some(init) = &job.init_checkpoint {
        a.push("--resume".into());
        a.push(init.display().to_string());
    }
    a
}

/// The `hexapod eval --suite` arguments of a job.
pub fn suite_args(sweep: &Sweep, job: &Job) -> Vec<String> {
    let o = sweep.suite_options(job);
    let mut a = vec![
        "eval".to_string(),
        "--suite".into(),
        o.suite,
        "--checkpoint".into(),
        job.evaluated_checkpoint().display().to_string(),
        "--out".into(),
        o.out.display().to_string(),
        "--seed".into(),
        o.seed.to_string(),
    ];
    if !o.protocols.is_empty() {
        a.push("--protocol".into());
        a.push(o.protocols.join(","));
    }
    if o.quick {
        a.push("--quick".into());
    }
    if let Some(t) = o.trials {
        a.push("--trials".into());
        a.push(t.to_string());
    }
    a
}

/// The `hexapod rma-adapt` arguments of an RMA teacher's job (the job's seed).
pub fn adapt_args(job: &Job) -> Vec<String> {
    vec![
        "rma-adapt".to_string(),
        "--teacher".into(),
        job.run_dir().display().to_string(),
        "--out".into(),
        job.adapted_dir().display().to_string(),
        "--seed".into(),
        job.seed.to_string(),
    ]
}

/// This binary, to run the job's steps with.
pub fn hexapod_exe() -> anyhow::Result<PathBuf> {
    let exe = std::env::current_exe().context("locating the hexapod binary")?;
    Ok(exe.canonicalize().unwrap_or(exe))
}

fn run_step(exe: &Path, args: &[String], what: &str, job: &Job) -> anyhow::Result<()> {
    eprintln!("[{}] hexapod {}", job.name(), args.join(" "));
    let mut cmd = Command::new(exe);
    cmd.args(args);
    // A Slurm task trains on the cores it was given, not on every core of the node.
    if std::env::var_os("RAYON_NUM_THREADS").is_none() {
        if let Ok(n) = std::env::var("SLURM_CPUS_PER_TASK") {
            cmd.env("RAYON_NUM_THREADS", n);
        }
    }
    let status = cmd
        .status()
        .with_context(|| format!("job {}: starting {}", job.name(), exe.display()))?;
    if !status.success() {
        bail!(
            "job {}: {what} failed ({status}); its output is above; run the sweep again to resume",
            job.name()
        );
    }
    Ok(())
}

/// Runs what is left of `job`: training to its last iteration, the adaptation of an RMA
/// teacher, then the suite.
pub fn run(sweep: &Sweep, job: &Job, exe: &Path) -> anyhow::Result<()> {
    std::fs::create_dir_all(&job.dir).with_context(|| format!("creating {}", job.dir.display()))?;
    if !matches!(state(job), JobState::Trained | JobState::Done) {
        run_step(exe, &train_args(job), "training", job)?;
        let reached = trained_iterations(job).unwrap_or(0);
        if reached < job.max_iterations {
            bail!("job {}: training stopped at iteration {reached} of {}; run the sweep again to resume", job.name(), job.max_iterations);
        }
    }
    if job.rma_teacher && !adapted(job) {
        run_step(exe, &adapt_args(job), "the RMA adaptation", job)?;
    }
    if state(job) != JobState::Done {
        run_step(exe, &suite_args(sweep, job), "the suite", job)?;
    }
    eprintln!(
        "[{}] done: {}",
        job.name(),
        job.suite_dir().join("report.md").display()
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sweep::spec::parse;

    #[test]
    fn a_fresh_job_trains_from_scratch_and_a_started_one_resumes() {
        let dir = std::env::temp_dir().join(format!("hexapod-sweep-task-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let spec = format!(
            "name = \"t\"\nout_dir = \"{}\"\npresets = [\"configs/smoke.toml\"]\nseeds = [3]\nset = [\"runner.max_iterations=2\"]\n[eval]\nprotocols = [\"push\", \"sine\"]\nquick = true\ntrials = 1\n",
            dir.display()
        );
        let sweep = parse(&spec, Path::new("t.toml")).unwrap();
        let job = &sweep.jobs[0];
        assert_eq!(state(job), JobState::Pending);
        let a = train_args(job);
        assert!(a.windows(2).any(|w| w[0] == "--seed" && w[1] == "3"));
        assert!(a
            .windows(2)
            .any(|w| w[0] == "--set" && w[1] == "runner.max_iterations=2"));
        assert!(!a.contains(&"--resume".to_string()));
        let e = suite_args(&sweep, job);
        assert!(e
            .windows(2)
            .any(|w| w[0] == "--protocol" && w[1] == "push,sine"));
        assert!(
            e.contains(&"--quick".to_string())
                && e.windows(2).any(|w| w[0] == "--trials" && w[1] == "1")
        );

        // A checkpoint at iteration 1 of 2: training resumes from the run directory.
        let ckpt = job.run_dir().join("checkpoints/model_000001");
        std::fs::create_dir_all(&ckpt).unwrap();
        std::fs::copy(
            "../assets/policies/flat-tripod/config.toml",
            ckpt.join("config.toml"),
        )
        .unwrap();
        std::fs::copy(
            "../assets/policies/flat-tripod/policy.safetensors",
            ckpt.join("policy.safetensors"),
        )
        .unwrap();
        std::fs::write(ckpt.join("state.json"), "{\"iteration\": 1}").unwrap();
        assert_eq!(
            state(job),
            JobState::Training(1),
            "{:?}",
            load_iteration(&ckpt)
        );
        assert!(train_args(job)
            .windows(2)
            .any(|w| w[0] == "--resume" && w[1] == job.run_dir().display().to_string()));

        // At its last iteration it is trained; with a complete report it is done.
        let last = job.run_dir().join("checkpoints/model_000002");
        std::fs::create_dir_all(&last).unwrap();
        for f in ["config.toml", "policy.safetensors"] {
            std::fs::copy(ckpt.join(f), last.join(f)).unwrap();
        }
        std::fs::write(last.join("state.json"), "{\"iteration\": 2}").unwrap();
        assert_eq!(state(job), JobState::Trained);
        std::fs::create_dir_all(job.suite_dir()).unwrap();
        std::fs::write(job.suite_dir().join("report.json"), "{\"complete\": false}").unwrap();
        assert_eq!(state(job), JobState::Trained);
        std::fs::write(job.suite_dir().join("report.json"), "{\"complete\": true}").unwrap();
        assert_eq!(state(job), JobState::Done);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_fresh_job_starts_from_the_sweeps_init_checkpoint_and_a_started_one_from_its_own() {
        let dir = std::env::temp_dir().join(format!("hexapod-sweep-init-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let spec = |init: &str| {
            format!(
                "name = \"t\"\nout_dir = \"{}\"\npresets = [\"configs/flat-tripod.toml\"]\ninit_checkpoint = \"{init}\"\nset = [\"runner.max_iterations=2\"]\n",
                dir.display()
            )
        };
        let sweep = parse(&spec("assets/policies/flat-tripod"), Path::new("t.toml")).unwrap();
        let job = &sweep.jobs[0];
        let init = job.init_checkpoint.clone().unwrap();
        assert!(
            init.ends_with("assets/policies/flat-tripod"),
            "{}",
            init.display()
        );
        assert!(train_args(job)
            .windows(2)
            .any(|w| w[0] == "--resume" && w[1] == init.display().to_string()));

        let ckpt = job.run_dir().join("checkpoints/model_000001");
        std::fs::create_dir_all(&ckpt).unwrap();
        for f in ["config.toml", "policy.safetensors"] {
            std::fs::copy(init.join(f), ckpt.join(f)).unwrap();
        }
        std::fs::write(ckpt.join("state.json"), "{\"iteration\": 1}").unwrap();
        assert!(train_args(job)
            .windows(2)
            .any(|w| w[0] == "--resume" && w[1] == job.run_dir().display().to_string()));
        std::fs::remove_dir_all(&dir).unwrap();

        let err = format!(
            "{:#}",
            parse(&spec("runs/no-such-checkpoint"), Path::new("t.toml")).unwrap_err()
        );
        assert!(
            err.contains("init_checkpoint") && err.contains("no-such-checkpoint"),
            "{err}"
        );
    }

    #[test]
    fn an_rma_job_is_adapted_before_the_suite_evaluates_its_student() {
        let dir = std::env::temp_dir().join(format!("hexapod-sweep-rma-{}", std::process::id()));
        let spec = format!(
            "name = \"t\"\nout_dir = \"{}\"\npresets = [\"configs/rma.toml\", \"configs/baseline.toml\"]\nseeds = [4]\n",
            dir.display()
        );
        let sweep = parse(&spec, Path::new("t.toml")).unwrap();
        let (rma, baseline) = (&sweep.jobs[0], &sweep.jobs[1]);
        assert!(rma.rma_teacher && !baseline.rma_teacher);
        let student = rma.dir.join("rma-s4-adapted");
        assert_eq!(rma.evaluated_checkpoint(), student);
        assert_eq!(baseline.evaluated_checkpoint(), baseline.run_dir());
        let a = adapt_args(rma);
        assert!(a
            .windows(2)
            .any(|w| w[0] == "--teacher" && w[1] == rma.run_dir().display().to_string()));
        assert!(a
            .windows(2)
            .any(|w| w[0] == "--out" && w[1] == student.display().to_string()));
        assert!(a.windows(2).any(|w| w[0] == "--seed" && w[1] == "4"));
        assert!(suite_args(&sweep, rma)
            .windows(2)
            .any(|w| w[0] == "--checkpoint" && w[1] == student.display().to_string()));
        assert!(!adapted(rma));
        std::fs::create_dir_all(&student).unwrap();
        std::fs::write(
            student.join(crate::cli::rma_adapt::ADAPTATION_CSV),
            "iteration\n",
        )
        .unwrap();
        assert!(adapted(rma));
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
