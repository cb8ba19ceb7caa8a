//! Checkpoints: `policy.safetensors` (every network and normalizer, f32, candle VarBuilder
//! keys), `config.toml` (the resolved config), `optimizer.safetensors` (Adam moments and
//! learning rates) and `state.json` (iteration, and each robot's curriculum tile when the run
//! trains on terrain tiles) in one directory, written atomically.

use crate::algo::ppo::{Ppo, PpoError};
use crate::config::TrainConfig;
use candle_core::{Device, Tensor};
use candle_nn::VarMap;
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// Network weights and normalizers.
pub const POLICY_FILE: &str = "policy.safetensors";
/// The resolved config.
pub const CONFIG_FILE: &str = "config.toml";
/// Optimizer state.
pub const OPTIMIZER_FILE: &str = "optimizer.safetensors";
/// Runner state.
pub const STATE_FILE: &str = "state.json";

/// Why a checkpoint could not be written or used.
#[derive(Debug, thiserror::Error)]
pub enum CheckpointError {
    /// A file is missing or unreadable.
    #[error("checkpoint {path}: {source}")]
    Io {
        /// File.
        path: String,
        /// Cause.
        source: std::io::Error,
    },
    /// A file is not what it should be.
    #[error("checkpoint {path} is malformed: {message}")]
    Malformed {
        /// File.
        path: String,
        /// What is wrong.
        message: String,
    },
    /// The config asks for a tensor the checkpoint lacks.
    #[error("checkpoint {path} has no tensor `{name}` (was it trained with a different config?)")]
    MissingTensor {
        /// File.
        path: String,
        /// Key.
        name: String,
    },
    /// A tensor's shape differs from what the config builds.
    #[error(
        "checkpoint {path}: tensor `{name}` has shape {found:?} but the config builds {expected:?}"
    )]
    ShapeMismatch {
        /// File.
        path: String,
        /// Key.
        name: String,
        /// Shape from the config.
        expected: Vec<usize>,
        /// Shape in the file.
        found: Vec<usize>,
    },
    /// The learner its config describes could not be built.
    #[error("checkpoint {path}: building its learner: {source}")]
    Learner {
        /// Directory.
        path: String,
        /// Cause.
        source: PpoError,
    },
}

pub(crate) fn io(path: &Path) -> impl FnOnce(std::io::Error) -> CheckpointError + '_ {
    move |source| CheckpointError::Io {
        path: path.display().to_string(),
        source,
    }
}

fn collect(maps: &[&VarMap]) -> HashMap<String, Tensor> {
    let mut out = HashMap::new();
    for map in maps {
        for (k, v) in map.data().lock().expect("var map lock").iter() {
            out.insert(k.clone(), v.as_tensor().clone());
        }
    }
    out
}

/// The runner's state beside the weights (`state.json`).
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct RunState {
    /// Iterations done.
    pub iteration: usize,
    /// Each robot's terrain tile (curriculum row, column) when the run trains on tiles, so a
    /// resumed run goes on from the curriculum it had reached (absent in older checkpoints
    /// and on flat ground).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub terrain_tiles: Option<Vec<[usize; 2]>>,
}

/// Writes a checkpoint of `ppo` at `iteration` into `dir` (replacing it atomically).
pub fn save(dir: &Path, ppo: &Ppo, iteration: usize) -> Result<(), CheckpointError> {
    save_with_state(
        dir,
        ppo,
        &RunState {
            iteration,
            terrain_tiles: None,
        },
    )
}

/// Writes a checkpoint of `ppo` with the runner's `state` into `dir` (replacing it
/// atomically).
pub fn save_with_state(dir: &Path, ppo: &Ppo, run_state: &RunState) -> Result<(), CheckpointError> {
    write_atomically(dir, |tmp| write_files(tmp, ppo, run_state))
}

/// Fills a fresh `<dir>.tmp` with `fill`, then puts it in place of `dir`: a reader never
/// sees a half-written checkpoint, and on an error `dir` is left as it was.
pub(crate) fn write_atomically(
    dir: &Path,
    fill: impl FnOnce(&Path) -> Result<(), CheckpointError>,
) -> Result<(), CheckpointError> {
    let tmp: PathBuf = dir.with_extension("tmp");
    if tmp.exists() {
        std::fs::remove_dir_all(&tmp).map_err(io(&tmp))?;
    }
    std::fs::create_dir_all(&tmp).map_err(io(&tmp))?;
    fill(&tmp)?;
    if dir.exists() {
        std::fs::remove_dir_all(dir).map_err(io(dir))?;
    }
    std::fs::rename(&tmp, dir).map_err(io(dir))
}

fn write_files(tmp: &Path, ppo: &Ppo, run_state: &RunState) -> Result<(), CheckpointError> {
    let weights = collect(&[&ppo.params, &ppo.stats, &ppo.disc_params]);
    let policy_path = tmp.join(POLICY_FILE);
    candle_core::safetensors::save(&weights, &policy_path).map_err(|e| {
        CheckpointError::Malformed {
            path: policy_path.display().to_string(),
            message: e.to_string(),
        }
    })?;
    let mut opt: HashMap<String, Tensor> = HashMap::new();
    let state = ppo
        .opt
        .state("optimizer.policy")
        .map_err(|e| malformed(tmp, e))?;
    opt.extend(state);
    if let Some(d) = &ppo.disc_opt {
        opt.extend(
            d.state("optimizer.discriminator")
                .map_err(|e| malformed(tmp, e))?,
        );
    }
    let opt_path = tmp.join(OPTIMIZER_FILE);
    candle_core::safetensors::save(&opt, &opt_path).map_err(|e| malformed(&opt_path, e))?;
    let cfg_path = tmp.join(CONFIG_FILE);
    std::fs::write(&cfg_path, ppo.cfg.to_toml_string()).map_err(io(&cfg_path))?;
    let state_path = tmp.join(STATE_FILE);
    let state_json = serde_json::to_string(run_state).map_err(|e| malformed(&state_path, e))?;
    std::fs::write(&state_path, state_json + "\n").map_err(io(&state_path))
}

pub(crate) fn malformed(path: &Path, e: impl ToString) -> CheckpointError {
    CheckpointError::Malformed {
        path: path.display().to_string(),
        message: e.to_string(),
    }
}

/// The checkpoint a path names: the directory itself when it holds `config.toml` and
/// `policy.safetensors`, or, for
/// a run directory (`runs/<name>`, with `checkpoints/model_NNNNNN`), its latest checkpoint.
pub fn resolve_dir(path: &Path) -> Result<std::path::PathBuf, CheckpointError> {
    if is_checkpoint(path) {
        return Ok(path.to_path_buf());
    }
    let latest = run_checkpoints(path).pop().map(|(_, p)| p);
    latest.ok_or_else(|| CheckpointError::Malformed {
        path: path.display().to_string(),
        message: "neither a checkpoint (config.toml, policy.safetensors) nor a run directory with checkpoints/model_NNNNNN".into(),
    })
}

fn is_checkpoint(dir: &Path) -> bool {
    dir.join(CONFIG_FILE).is_file() && dir.join(POLICY_FILE).is_file()
}

/// A run directory's checkpoints, `<run>/checkpoints/model_NNNNNN` holding `config.toml` and
/// `policy.safetensors`, with their iterations, in iteration order (none when the run has no
/// readable `checkpoints/`).
pub fn run_checkpoints(run: &Path) -> Vec<(usize, PathBuf)> {
    let Ok(entries) = std::fs::read_dir(run.join("checkpoints")) else {
        return Vec::new();
    };
    let mut found: Vec<(usize, PathBuf)> = entries
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| is_checkpoint(p))
        .filter_map(|p| {
            let name = p.file_name()?.to_string_lossy().into_owned();
            let iteration = name.strip_prefix("model_")?.parse().ok()?;
            Some((iteration, p))
        })
        .collect();
    found.sort();
    found
}

/// The run (or report) a checkpoint belongs to, and its model name:
/// `<run>/checkpoints/model_N` gives `(Some(run), "model_N")`, a checkpoint committed beside
/// its report, `<report>/checkpoint-model_N`, gives `(Some(report), "model_N")`, any other
/// directory `(None, its name)`.
pub fn name_parts(dir: &Path) -> (Option<String>, String) {
    let component = |up: usize| {
        dir.ancestors()
            .nth(up)
            .and_then(|p| p.file_name())
            .map(|s| s.to_string_lossy().into_owned())
    };
    let Some(leaf) = component(0) else {
        return (None, "checkpoint".into());
    };
    if leaf.starts_with("model_") && component(1).as_deref() == Some("checkpoints") {
        if let Some(run) = component(2) {
            return (Some(run), leaf);
        }
    }
    if let Some(model) = leaf.strip_prefix("checkpoint-") {
        if let Some(report) = component(1) {
            return (Some(report), model.to_string());
        }
    }
    (None, leaf)
}

/// A short name for a checkpoint, its [`name_parts`] joined by `separator` (`flat-tripod`,
/// `my-run-model_000400` for file names, `my-run/model_000400` for tables).
pub fn display_name_with(dir: &Path, separator: &str) -> String {
    match name_parts(dir) {
        (Some(run), model) => format!("{run}{separator}{model}"),
        (None, leaf) => leaf,
    }
}

/// A short name for outputs derived from a checkpoint path (a file name: `flat-tripod`,
/// `my-run-model_000400`, `gl-s1-model_006000`).
pub fn display_name(dir: &Path) -> String {
    display_name_with(dir, "-")
}

/// Reads the resolved config saved in a checkpoint directory.
pub fn load_config(dir: &Path) -> Result<TrainConfig, CheckpointError> {
    let path = dir.join(CONFIG_FILE);
    let text = std::fs::read_to_string(&path).map_err(io(&path))?;
    if predates_foot_friction_setting(&text) {
        eprintln!(
            "note: {} was trained before the simulator's feet held (no \
             `sim.friction_in_bias_pass`); it runs with feet that hold (BENCHMARKS.md, foot slip)",
            path.display()
        );
    }
    TrainConfig::from_toml_str(&text, &path.display().to_string()).map_err(|e| malformed(&path, e))
}

/// Whether a saved config was written before the simulator had the foot-friction setting
/// (every resolved config written since names it).
fn predates_foot_friction_setting(config_toml: &str) -> bool {
    !config_toml.contains("friction_in_bias_pass")
}

/// Iteration stored in a checkpoint.
pub fn load_iteration(dir: &Path) -> Result<usize, CheckpointError> {
    load_state(dir).map(|s| s.iteration)
}

/// The runner's state stored in a checkpoint.
pub fn load_state(dir: &Path) -> Result<RunState, CheckpointError> {
    let path = dir.join(STATE_FILE);
    let text = std::fs::read_to_string(&path).map_err(io(&path))?;
    serde_json::from_str(&text).map_err(|e| malformed(&path, e))
}

pub(crate) fn read_tensors(path: &Path) -> Result<HashMap<String, Tensor>, CheckpointError> {
    if !path.exists() {
        return Err(CheckpointError::Io {
            path: path.display().to_string(),
            source: std::io::Error::new(std::io::ErrorKind::NotFound, "no such file"),
        });
    }
    candle_core::safetensors::load(path, &Device::Cpu).map_err(|e| malformed(path, e))
}

fn load_into(
    maps: &[&VarMap],
    tensors: &HashMap<String, Tensor>,
    path: &Path,
) -> Result<(), CheckpointError> {
    for map in maps {
        let data = map.data().lock().expect("var map lock");
        let mut names: Vec<&String> = data.keys().collect();
        names.sort();
        for name in names {
            let var = &data[name];
            let t = tensors
                .get(name)
                .ok_or_else(|| CheckpointError::MissingTensor {
                    path: path.display().to_string(),
                    name: name.clone(),
                })?;
            if t.dims() != var.dims() {
                return Err(CheckpointError::ShapeMismatch {
                    path: path.display().to_string(),
                    name: name.clone(),
                    expected: var.dims().to_vec(),
                    found: t.dims().to_vec(),
                });
            }
            let t = t.to_dtype(var.dtype()).map_err(|e| malformed(path, e))?;
            var.set(&t).map_err(|e| malformed(path, e))?;
        }
    }
    Ok(())
}

/// Loads weights and normalizers (and, with `with_optimizer`, the optimizer state) from
/// `dir` into `ppo`, checking every tensor's presence and shape against the config.
pub fn load(dir: &Path, ppo: &mut Ppo, with_optimizer: bool) -> Result<(), CheckpointError> {
    let path = dir.join(POLICY_FILE);
    let tensors = read_tensors(&path)?;
    load_into(
        &[&ppo.params, &ppo.stats, &ppo.disc_params],
        &tensors,
        &path,
    )?;
    ppo.ac.sync_normalizers().map_err(|e| malformed(&path, e))?;
    if let Some(d) = &mut ppo.disc {
        d.norm.sync_from_vars().map_err(|e| malformed(&path, e))?;
    }
    if with_optimizer {
        let opt_path = dir.join(OPTIMIZER_FILE);
        if opt_path.exists() {
            let opt = read_tensors(&opt_path)?;
            ppo.opt
                .load_state("optimizer.policy", &opt)
                .map_err(|e| malformed(&opt_path, e))?;
            if let Some(d) = &mut ppo.disc_opt {
                d.load_state("optimizer.discriminator", &opt)
                    .map_err(|e| malformed(&opt_path, e))?;
            }
        }
    }
    Ok(())
}

/// Whether a checkpoint saved with `saved` has the networks `cfg` builds (policy,
/// discriminator and RMA encoder shapes); the error says which differ. The initial action
/// noise and its floor are not shapes: the checkpoint carries its learned log-std.
pub fn same_networks(saved: &TrainConfig, cfg: &TrainConfig) -> Result<(), String> {
    let mut differ = Vec::new();
    let shape = |p: &crate::config::PolicyConfig| crate::config::PolicyConfig {
        init_noise_std: 0.0,
        min_noise_std: 0.0,
        ..p.clone()
    };
    if shape(&saved.policy) != shape(&cfg.policy) {
        differ.push("[policy]");
    }
    if saved.amp.discriminator_hidden != cfg.amp.discriminator_hidden {
        differ.push("amp.discriminator_hidden");
    }
    if saved.rma.as_ref().map(|r| &r.encoder_hidden) != cfg.rma.as_ref().map(|r| &r.encoder_hidden)
    {
        differ.push("the RMA encoder ([rma])");
    }
    if differ.is_empty() {
        Ok(())
    } else {
        Err(format!("the networks differ: {}", differ.join(", ")))
    }
}

/// Builds the learner a checkpoint's config describes and loads its weights (no optimizer).
pub fn load_for_inference(dir: &Path) -> Result<(TrainConfig, Ppo), CheckpointError> {
    let cfg = load_config(dir)?;
    let mut ppo = Ppo::new(&cfg).map_err(|source| CheckpointError::Learner {
        path: dir.display().to_string(),
        source,
    })?;
    load(dir, &mut ppo, false)?;
    Ok((cfg, ppo))
}

/// Tiny learners and scratch directories for the checkpoint tests.
#[cfg(test)]
pub(crate) mod test_support {
    use crate::config::{EnvKind, PriorKind, TrainConfig};
    use std::path::PathBuf;

    /// A config of tiny networks (8 units) on the fake environment, with `actor_hidden`
    /// units in the actor's one hidden layer.
    pub fn tiny_config(actor_hidden: usize) -> TrainConfig {
        let mut c = TrainConfig::default();
        c.env.kind = EnvKind::Fake;
        c.env.num_envs = 4;
        c.policy.estimator_hidden = vec![8];
        c.policy.memory_hidden = vec![8];
        c.policy.actor_hidden = vec![actor_hidden];
        c.policy.critic_hidden = vec![8];
        c.policy.terrain_encoder_hidden = vec![8];
        c.policy.privileged_encoder_hidden = vec![8];
        c.amp.discriminator_hidden = vec![8];
        c.amp.prior_kind = PriorKind::Synthetic;
        c
    }

    /// An empty scratch directory path under the system's temporary directory.
    pub fn tmpdir(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("hexapod-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        d
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_config_saved_now_names_the_foot_friction_setting() {
        let text = TrainConfig::default().to_toml_string();
        assert!(!predates_foot_friction_setting(&text), "{text}");
        assert!(predates_foot_friction_setting("[sim]\nseed = 1\n"));
    }

    fn tiny() -> TrainConfig {
        test_support::tiny_config(8)
    }

    fn tmpdir(name: &str) -> PathBuf {
        test_support::tmpdir(&format!("ckpt-{name}"))
    }

    #[test]
    fn a_run_directory_names_its_latest_checkpoint() {
        let cfg = tiny();
        let ppo = Ppo::new(&cfg).unwrap();
        let run = tmpdir("run");
        for it in [50, 100, 7] {
            save(
                &run.join("checkpoints").join(format!("model_{it:06}")),
                &ppo,
                it,
            )
            .unwrap();
        }
        // The run directory has its own config.toml but no weights: not a checkpoint.
        std::fs::write(run.join("config.toml"), cfg.to_toml_string()).unwrap();
        let latest = run.join("checkpoints/model_000100");
        assert_eq!(resolve_dir(&run).unwrap(), latest);
        assert_eq!(resolve_dir(&latest).unwrap(), latest);
        assert_eq!(
            display_name(&latest),
            format!(
                "{}-model_000100",
                run.file_name().unwrap().to_string_lossy()
            )
        );
        assert_eq!(
            display_name(Path::new("assets/policies/flat-tripod")),
            "flat-tripod"
        );
        assert_eq!(
            display_name(Path::new(
                "assets/reports/amp-ablation-flat/gl-s1/checkpoint-model_006000"
            )),
            "gl-s1-model_006000"
        );
        assert_eq!(
            display_name(Path::new("some/model_000100")),
            "model_000100",
            "a model directory outside a run's checkpoints/ keeps its own name"
        );
        let err = resolve_dir(&run.join("checkpoints"))
            .unwrap_err()
            .to_string();
        assert!(err.contains("nor a run directory"), "{err}");
        std::fs::remove_dir_all(&run).unwrap();
    }

    #[test]
    fn round_trip_restores_every_tensor_and_the_config() {
        let cfg = tiny();
        let mut a = Ppo::new(&cfg).unwrap();
        a.ac.norm_actor.update(&vec![0.5; 63 * 3]).unwrap();
        a.opt.lr = 0.0042;
        let dir = tmpdir("rt");
        save(&dir, &a, 17).unwrap();
        assert_eq!(load_config(&dir).unwrap(), cfg);
        assert_eq!(load_iteration(&dir).unwrap(), 17);
        let mut b = Ppo::new(&TrainConfig {
            runner: crate::config::RunnerConfig {
                seed: 99,
                ..cfg.runner.clone()
            },
            ..cfg.clone()
        })
        .unwrap();
        load(&dir, &mut b, true).unwrap();
        let (ta, tb) = (
            collect(&[&a.params, &a.stats, &a.disc_params]),
            collect(&[&b.params, &b.stats, &b.disc_params]),
        );
        assert_eq!(ta.len(), tb.len());
        for (k, t) in &ta {
            let x = t.flatten_all().unwrap().to_vec1::<f32>().unwrap();
            let y = tb[k].flatten_all().unwrap().to_vec1::<f32>().unwrap();
            assert_eq!(x, y, "{k}");
        }
        assert!((b.opt.lr - 0.0042).abs() < 1e-6);
        assert_eq!(b.ac.norm_actor.count(), 3.0);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn the_initial_action_noise_and_its_floor_are_not_network_shapes() {
        let saved = tiny();
        let mut cfg = saved.clone();
        cfg.policy.init_noise_std = 1.0;
        cfg.policy.min_noise_std = 0.35;
        assert_eq!(same_networks(&saved, &cfg), Ok(()));
        cfg.policy.actor_hidden = vec![16];
        cfg.amp.discriminator_hidden = vec![4];
        let err = same_networks(&saved, &cfg).unwrap_err();
        assert!(err.contains("[policy]"), "{err}");
        assert!(err.contains("amp.discriminator_hidden"), "{err}");
    }

    #[test]
    fn shape_mismatch_and_missing_files_are_clear_errors() {
        let cfg = tiny();
        let a = Ppo::new(&cfg).unwrap();
        let dir = tmpdir("mismatch");
        save(&dir, &a, 1).unwrap();
        let mut other = cfg.clone();
        other.policy.actor_hidden = vec![16];
        let mut b = Ppo::new(&other).unwrap();
        let err = load(&dir, &mut b, false).unwrap_err();
        assert!(
            matches!(err, CheckpointError::ShapeMismatch { .. }),
            "{err}"
        );
        assert!(err.to_string().contains("actor.layers.0"), "{err}");
        let err = load(&dir.join("nope"), &mut b, false).unwrap_err();
        assert!(err.to_string().contains("policy.safetensors"), "{err}");
        std::fs::write(dir.join(POLICY_FILE), b"not a safetensors file").unwrap();
        assert!(matches!(
            load(&dir, &mut b, false).unwrap_err(),
            CheckpointError::Malformed { .. }
        ));
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
