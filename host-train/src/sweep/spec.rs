//! The sweep file (`hexapod sweep run SPEC.toml`): presets x variants x seeds, the overrides
//! every job shares, what the suite measures afterwards, and the Slurm resources. Loading a
//! spec resolves every job's training config, so a missing preset or an unknown override is
//! refused before anything trains.

use crate::cli::suite::{self, SuiteOptions};
use crate::config::{resolve_path, TrainConfig};
use anyhow::{bail, Context};
use serde::Deserialize;
use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

/// A sweep file.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SweepSpec {
    /// Name of the sweep; its directory is `runs/sweeps/<name>` unless `out_dir` is given.
    pub name: String,
    /// Output directory (relative to the working directory).
    #[serde(default)]
    pub out_dir: Option<String>,
    /// Training presets (TOML), one controller each.
    pub presets: Vec<String>,
    /// Seeds; each sets `env.seed` and `runner.seed` (as `hexapod train --seed`).
    #[serde(default = "default_seeds")]
    pub seeds: Vec<u64>,
    /// `KEY=VALUE` overrides for every job (as `hexapod train --set`), before the variant's.
    #[serde(default)]
    pub set: Vec<String>,
    /// A checkpoint every job starts from (as `hexapod train --resume`), for example a
    /// `hexapod pretrain` warm start, so all controllers share one start; or a table from
    /// preset file stem to checkpoint, when the presets' networks differ (each controller's
    /// own warm start); none: each job starts from a random policy.
    #[serde(default)]
    pub init_checkpoint: Option<InitCheckpoint>,
    /// Variants of every preset (`[[variant]]` tables); none: each preset as it is.
    #[serde(default, rename = "variant")]
    pub variants: Vec<Variant>,
    /// Controllers the sweep does not train, reported beside its own from a committed suite
    /// report (`[[reference]]` tables), for example the model-based MPC.
    #[serde(default, rename = "reference")]
    pub references: Vec<ReferenceSpec>,
    /// What the suite measures after training.
    #[serde(default)]
    pub eval: EvalSpec,
    /// Resources of each Slurm array task.
    #[serde(default)]
    pub slurm: SlurmSpec,
}

/// The warm start of a sweep's jobs.
#[derive(Clone, Debug, Deserialize)]
#[serde(untagged)]
pub enum InitCheckpoint {
    /// One checkpoint for every job.
    All(String),
    /// One checkpoint per preset, keyed by the preset's file stem.
    PerPreset(std::collections::BTreeMap<String, String>),
}

/// A reference controller: its name in the report and its suite report (`report.json`).
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ReferenceSpec {
    /// Column name in the report.
    pub name: String,
    /// Its `hexapod eval --suite` report, `report.json`.
    pub report: String,
}

/// A reference controller, resolved.
#[derive(Clone, Debug)]
pub struct Reference {
    /// Column name in the report.
    pub name: String,
    /// Its suite report.
    pub report: PathBuf,
}

/// One variant: a name and its overrides.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Variant {
    /// Short name, part of the controller's name (`<preset>-<variant>`).
    pub name: String,
    /// `KEY=VALUE` overrides.
    #[serde(default)]
    pub set: Vec<String>,
}

/// The evaluation of every trained policy (`hexapod eval --suite`).
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct EvalSpec {
    /// Suite name (`paper`).
    pub suite: String,
    /// Protocols (empty: all of the suite's).
    pub protocols: Vec<String>,
    /// The suite's quick variant.
    pub quick: bool,
    /// Trials per test point (default: the suite's).
    pub trials: Option<usize>,
    /// Seed of the suite (the same for every job, so every controller meets the same robots).
    pub seed: u64,
}

impl Default for EvalSpec {
    fn default() -> Self {
        Self {
            suite: "paper".into(),
            protocols: Vec::new(),
            quick: false,
            trials: None,
            seed: 1,
        }
    }
}

/// Slurm resources of one array task (one job: train, then evaluate).
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SlurmSpec {
    /// Partition (`--partition`); none: the cluster's default.
    pub partition: Option<String>,
    /// Account (`--account`).
    pub account: Option<String>,
    /// Time limit of one task (`--time`, Slurm's format).
    pub time: String,
    /// Cores of one task (`--cpus-per-task`); the trainer uses that many threads.
    pub cpus_per_task: usize,
    /// Memory of one task (`--mem`, e.g. `8G`).
    pub mem: Option<String>,
    /// Tasks running at once (`--array=...%N`); none: as many as the cluster gives.
    pub max_parallel: Option<usize>,
    /// Further `#SBATCH` options, verbatim (e.g. `--qos=long`).
    pub extra: Vec<String>,
}

impl Default for SlurmSpec {
    fn default() -> Self {
        Self {
            partition: None,
            account: None,
            time: "24:00:00".into(),
            cpus_per_task: 2,
            mem: None,
            max_parallel: None,
            extra: Vec::new(),
        }
    }
}

fn default_seeds() -> Vec<u64> {
    vec![1]
}

/// One job of a sweep: one preset, variant and seed, trained and then evaluated.
#[derive(Clone, Debug, PartialEq)]
pub struct Job {
    /// Position in the sweep (the Slurm array index).
    pub index: usize,
    /// The controller it belongs to: `<preset stem>` or `<preset stem>-<variant>`.
    pub controller: String,
    /// Seed.
    pub seed: u64,
    /// Preset file (resolved).
    pub preset: PathBuf,
    /// Every override, in order: the sweep's, then the variant's.
    pub overrides: Vec<String>,
    /// The job's directory: `<sweep dir>/<controller>-s<seed>`.
    pub dir: PathBuf,
    /// Training iterations the resolved config asks for.
    pub max_iterations: usize,
    /// The checkpoint a fresh job starts from (the sweep's `init_checkpoint`, resolved).
    pub init_checkpoint: Option<PathBuf>,
    /// Whether the preset trains an RMA teacher (`[rma]`), which `hexapod rma-adapt` turns
    /// into the deployed student before the suite evaluates it.
    pub rma_teacher: bool,
}

impl Job {
    /// The training run's directory (checkpoints, metrics): the job's directory itself, so
    /// the suite names the controller after the job.
    pub fn run_dir(&self) -> PathBuf {
        self.dir.clone()
    }

    /// Where an RMA teacher's adapted student is written: `<dir>/<name>-adapted`.
    pub fn adapted_dir(&self) -> PathBuf {
        self.dir.join(format!("{}-adapted", self.name()))
    }

    /// The checkpoint the suite evaluates: the adapted student for an RMA teacher (what
    /// deploys), the training run otherwise.
    pub fn evaluated_checkpoint(&self) -> PathBuf {
        if self.rma_teacher {
            self.adapted_dir()
        } else {
            self.run_dir()
        }
    }

    /// The suite report's directory.
    pub fn suite_dir(&self) -> PathBuf {
        self.dir.join("suite")
    }

    /// `<controller>-s<seed>`.
    pub fn name(&self) -> String {
        format!("{}-s{}", self.controller, self.seed)
    }
}

/// A loaded sweep: its file, its spec and its jobs.
#[derive(Clone, Debug)]
pub struct Sweep {
    /// The sweep file.
    pub path: PathBuf,
    /// Its contents.
    pub spec: SweepSpec,
    /// The sweep's directory.
    pub dir: PathBuf,
    /// Presets x variants x seeds, in that order.
    pub jobs: Vec<Job>,
    /// Reference controllers, reported after the sweep's own.
    pub references: Vec<Reference>,
}

impl Sweep {
    /// The controllers in spec order (presets, then variants within a preset).
    pub fn controllers(&self) -> Vec<String> {
        let mut seen = Vec::new();
        for j in &self.jobs {
            if !seen.contains(&j.controller) {
                seen.push(j.controller.clone());
            }
        }
        seen
    }

    /// The suite's options for one job.
    pub fn suite_options(&self, job: &Job) -> SuiteOptions {
        let e = &self.spec.eval;
        SuiteOptions {
            suite: e.suite.clone(),
            checkpoints: vec![job.run_dir()],
            mpc: None,
            out: job.suite_dir(),
            protocols: e.protocols.clone(),
            quick: e.quick,
            trials: e.trials,
            seed: e.seed,
            terrain_duration_s: None,
            contact_friction: None,
            course_cell_m: None,
        }
    }
}

fn valid_name(s: &str) -> bool {
    !s.is_empty()
        && s.chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '-' || c == '_' || c == '.')
}

/// A preset's file stem (its controller's name).
fn preset_stem(preset: &str) -> String {
    Path::new(preset)
        .file_stem()
        .map(|s| s.to_string_lossy().to_string())
        .unwrap_or_else(|| preset.to_string())
}

/// Reads and checks a sweep file; every job's config is resolved (preset, its `base` chain,
/// the overrides, the seed), so errors name the file and the job before anything runs.
pub fn load(path: &Path) -> anyhow::Result<Sweep> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("sweep file {}", path.display()))?;
    parse(&text, path)
}

/// [`load`] on the file's text.
pub fn parse(text: &str, path: &Path) -> anyhow::Result<Sweep> {
    let origin = path.display();
    let spec: SweepSpec = toml::from_str(text)
        .map_err(|e| anyhow::anyhow!("sweep file {origin}: {}", e.message()))?;
    if !valid_name(&spec.name) {
        bail!(
            "sweep file {origin}: name `{}` must be letters, digits, '-', '_' or '.'",
            spec.name
        );
    }
    if spec.presets.is_empty() {
        bail!("sweep file {origin}: `presets` is empty");
    }
    if spec.seeds.is_empty() {
        bail!("sweep file {origin}: `seeds` is empty");
    }
    let unique_seeds: BTreeSet<u64> = spec.seeds.iter().copied().collect();
    if unique_seeds.len() != spec.seeds.len() {
        bail!(
            "sweep file {origin}: a seed is listed twice in {:?}",
            spec.seeds
        );
    }
    let mut variant_names = BTreeSet::new();
    for v in &spec.variants {
        if !valid_name(&v.name) {
            bail!(
                "sweep file {origin}: variant name `{}` must be letters, digits, '-', '_' or '.'",
                v.name
            );
        }
        if !variant_names.insert(v.name.clone()) {
            bail!("sweep file {origin}: variant `{}` is listed twice", v.name);
        }
    }
    if spec.slurm.cpus_per_task == 0 {
        bail!("sweep file {origin}: slurm.cpus_per_task must be at least 1");
    }
    if spec.slurm.max_parallel == Some(0) {
        bail!("sweep file {origin}: slurm.max_parallel must be at least 1");
    }
    let dir = PathBuf::from(
        spec.out_dir
            .clone()
            .unwrap_or_else(|| format!("runs/sweeps/{}", spec.name)),
    );
    if let Some(InitCheckpoint::PerPreset(table)) = &spec.init_checkpoint {
        let stems: Vec<String> = spec.presets.iter().map(|p| preset_stem(p)).collect();
        if let Some(key) = table.keys().find(|k| !stems.contains(k)) {
            bail!("sweep file {origin}: init_checkpoint names `{key}`, which is none of the presets ({})", stems.join(", "));
        }
    }
    let mut jobs = Vec::new();
    let mut controllers = BTreeSet::new();
    for preset in &spec.presets {
        let file = resolve_path(preset);
        if !file.is_file() {
            bail!("sweep file {origin}: preset `{preset}` not found (relative paths are from the working directory or the workspace root)");
        }
        let stem = preset_stem(preset);
        let init = match &spec.init_checkpoint {
            None => None,
            Some(InitCheckpoint::All(c)) => Some(c),
            Some(InitCheckpoint::PerPreset(table)) => Some(table.get(&stem).with_context(|| {
                format!("sweep file {origin}: init_checkpoint has no checkpoint for the preset `{stem}`")
            })?),
        };
        // The checkpoint and its config, read once per preset.
        let init_checkpoint = match init {
            Some(c) => {
                let dir = crate::checkpoint::resolve_dir(&resolve_path(c))
                    .with_context(|| format!("sweep file {origin}: init_checkpoint `{c}`"))?;
                let saved = crate::checkpoint::load_config(&dir)?;
                Some((dir, saved))
            }
            None => None,
        };
        let variants: Vec<Option<&Variant>> = if spec.variants.is_empty() {
            vec![None]
        } else {
            spec.variants.iter().map(Some).collect()
        };
        for variant in variants {
            let controller = match variant {
                Some(v) => format!("{stem}-{}", v.name),
                None => stem.clone(),
            };
            if !controllers.insert(controller.clone()) {
                bail!("sweep file {origin}: two presets make the controller `{controller}` (same file name)");
            }
            let mut overrides = spec.set.clone();
            if let Some(v) = variant {
                overrides.extend(v.set.iter().cloned());
            }
            for &seed in &spec.seeds {
                let name = format!("{controller}-s{seed}");
                let cfg = job_config(&file, &overrides, seed)
                    .with_context(|| format!("sweep file {origin}: job {name}"))?;
                if let Some((init, saved)) = &init_checkpoint {
                    crate::checkpoint::same_networks(saved, &cfg).map_err(|e| {
                        anyhow::anyhow!(
                            "sweep file {origin}: job {name} cannot start from {}: {e}",
                            init.display()
                        )
                    })?;
                }
                jobs.push(Job {
                    index: jobs.len(),
                    controller: controller.clone(),
                    seed,
                    preset: file.clone(),
                    overrides: overrides.clone(),
                    dir: dir.join(&name),
                    max_iterations: cfg.runner.max_iterations,
                    init_checkpoint: init_checkpoint.as_ref().map(|(dir, _)| dir.clone()),
                    rma_teacher: cfg.rma_teacher(),
                });
            }
        }
    }
    let mut references = Vec::new();
    for r in &spec.references {
        if !valid_name(&r.name) || controllers.contains(&r.name) {
            bail!("sweep file {origin}: reference `{}`: a name of letters, digits, '-', '_' or '.' that no preset's controller has", r.name);
        }
        let report = resolve_path(&r.report);
        if !report.is_file() {
            bail!(
                "sweep file {origin}: reference `{}`: no suite report at `{}` (`hexapod eval --suite paper --out <dir>` writes <dir>/report.json)",
                r.name,
                r.report
            );
        }
        controllers.insert(r.name.clone());
        references.push(Reference {
            name: r.name.clone(),
            report,
        });
    }
    let sweep = Sweep {
        path: path.to_path_buf(),
        spec,
        dir,
        jobs,
        references,
    };
    if let Some(job) = sweep.jobs.first() {
        suite::validate(&sweep.suite_options(job))
            .with_context(|| format!("sweep file {origin}: [eval]"))?;
    }
    Ok(sweep)
}

/// A job's training config, as `hexapod train -c <preset> --set ... --seed <seed>` makes it.
pub fn job_config(preset: &Path, overrides: &[String], seed: u64) -> anyhow::Result<TrainConfig> {
    let mut cfg = TrainConfig::load_with_overrides(preset, overrides)?;
    cfg.env.seed = seed;
    cfg.runner.seed = seed;
    cfg.validate()?;
    Ok(cfg)
}

#[cfg(test)]
mod tests {
    use super::*;

    const SPEC: &str = r#"
name = "ablation"
out_dir = "target/test-sweeps/ablation"
presets = ["configs/ablation-gsl.toml", "configs/ablation-gl.toml"]
seeds = [1, 2]
set = ["runner.max_iterations=3"]

[[variant]]
name = "base"

[[variant]]
name = "style2"
set = ["rewards.style_weight=2.0"]

[eval]
protocols = ["push"]
quick = true
"#;

    #[test]
    fn presets_times_variants_times_seeds() {
        let s = parse(SPEC, Path::new("ablation.toml")).unwrap();
        assert_eq!(s.jobs.len(), 8);
        let names: Vec<String> = s.jobs.iter().map(Job::name).collect();
        assert_eq!(names[0], "ablation-gsl-base-s1");
        assert_eq!(names[3], "ablation-gsl-style2-s2");
        assert_eq!(names[7], "ablation-gl-style2-s2");
        assert_eq!(
            s.controllers(),
            [
                "ablation-gsl-base",
                "ablation-gsl-style2",
                "ablation-gl-base",
                "ablation-gl-style2"
            ]
        );
        assert_eq!(
            s.jobs[3].overrides,
            ["runner.max_iterations=3", "rewards.style_weight=2.0"]
        );
        assert!(s.jobs.iter().all(|j| j.max_iterations == 3));
        assert!(s.jobs.iter().enumerate().all(|(i, j)| j.index == i));
        assert_eq!(
            s.jobs[0].dir,
            Path::new("target/test-sweeps/ablation/ablation-gsl-base-s1")
        );
        let cfg = job_config(&s.jobs[3].preset, &s.jobs[3].overrides, 2).unwrap();
        assert_eq!(
            (cfg.rewards.style_weight, cfg.env.seed, cfg.runner.seed),
            (2.0, 2, 2)
        );
    }

    #[test]
    fn bad_specs_are_named() {
        let err = |text: &str| format!("{:#}", parse(text, Path::new("bad.toml")).unwrap_err());
        let e = err(&SPEC.replace("configs/ablation-gl.toml", "configs/no-such.toml"));
        assert!(
            e.contains("bad.toml") && e.contains("configs/no-such.toml") && e.contains("not found"),
            "{e}"
        );
        let e = err(&SPEC.replace("rewards.style_weight=2.0", "rewards.stlye_weight=2.0"));
        assert!(
            e.contains("job ablation-gsl-style2-s1") && e.contains("stlye_weight"),
            "{e}"
        );
        let e = err(&SPEC.replace("quick = true", "quick = true\ntrails = 3"));
        assert!(e.contains("bad.toml") && e.contains("trails"), "{e}");
        let e = err(&SPEC.replace("protocols = [\"push\"]", "protocols = [\"stairs\"]"));
        assert!(
            e.contains("[eval]") && e.contains("unknown protocol `stairs`"),
            "{e}"
        );
        let e = err(&SPEC.replace("seeds = [1, 2]", "seeds = [1, 1]"));
        assert!(e.contains("seed is listed twice"), "{e}");
        let e = err(&SPEC.replace("name = \"style2\"", "name = \"base\""));
        assert!(e.contains("variant `base` is listed twice"), "{e}");
        let e = err(&SPEC.replace(
            "presets = [\"configs/ablation-gsl.toml\", \"configs/ablation-gl.toml\"]",
            "presets = []",
        ));
        assert!(e.contains("`presets` is empty"), "{e}");
        let e = err("name = \"a b\"\npresets = [\"configs/smoke.toml\"]");
        assert!(e.contains("name `a b`"), "{e}");
    }

    #[test]
    fn each_preset_starts_from_its_own_checkpoint_whose_networks_it_must_have() {
        let spec = |table: &str| {
            format!(
                "name = \"t\"\nout_dir = \"target/test-sweeps/init-table\"\npresets = [\"configs/ablation-gsl.toml\", \"configs/comparison-baseline.toml\"]\n[init_checkpoint]\n{table}\n"
            )
        };
        let err = |table: &str| {
            format!(
                "{:#}",
                parse(&spec(table), Path::new("t.toml")).unwrap_err()
            )
        };
        let shipped = "assets/policies/flat-tripod";
        let e = err(&format!("ablation-gsl = \"{shipped}\""));
        assert!(
            e.contains("no checkpoint for the preset `comparison-baseline`"),
            "{e}"
        );
        let e = err(&format!(
            "ablation-gsl = \"{shipped}\"\ncomparison-baseline = \"{shipped}\"\nablation-gl = \"{shipped}\""
        ));
        assert!(
            e.contains("`ablation-gl`, which is none of the presets"),
            "{e}"
        );
        // The baseline has no estimator and no privileged critic: the shipped policy's
        // networks are not its own.
        let e = err(&format!(
            "ablation-gsl = \"{shipped}\"\ncomparison-baseline = \"{shipped}\""
        ));
        assert!(
            e.contains("comparison-baseline-s1 cannot start from") && e.contains("[policy]"),
            "{e}"
        );
        let sweep = parse(
            &spec(&format!(
                "ablation-gsl = \"{shipped}\"\ncomparison-baseline = \"{shipped}\"\n"
            ))
            .replace(
                "configs/comparison-baseline.toml",
                "configs/ablation-gs.toml",
            )
            .replace("comparison-baseline =", "ablation-gs ="),
            Path::new("t.toml"),
        )
        .unwrap();
        assert!(sweep
            .jobs
            .iter()
            .all(|j| j.init_checkpoint.as_ref().unwrap().ends_with(shipped)));
    }
}
