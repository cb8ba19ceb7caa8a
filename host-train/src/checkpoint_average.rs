//! Weight averaging of checkpoints (stochastic weight averaging, Izmailov et al. 2018, as
//! used for policies by Nikishin et al. 2018): the element-wise mean of every tensor of
//! several checkpoints of one run, written as a checkpoint of its own.
//!
//! Successive checkpoints of a PPO run wander around a region of similar returns; on the
//! terrain suite two checkpoints 250 iterations apart differ by up to 13 of 280 trials
//! (`assets/reports/terrain-stages`, stage 11's path). Their mean sits nearer the middle of
//! that region; there it beat every checkpoint of one training seed and tied the last one of
//! another. Every tensor of `policy.safetensors` is averaged (networks and observation
//! normalizers alike), summed in f64 in the order given and divided once; the config and
//! the runner state are the last checkpoint's, the optimizer state is left out (a run
//! resumed from the average starts its Adam moments afresh), and `average.json` names the
//! checkpoints averaged.

use crate::checkpoint::{
    io, load_config, load_state, malformed, read_tensors, run_checkpoints, same_networks,
    write_atomically, CheckpointError, CONFIG_FILE, POLICY_FILE, STATE_FILE,
};
use candle_core::{DType, Device, Tensor};
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// What went into an averaged checkpoint (`average.json`).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct AverageRecord {
    /// The averaged checkpoints, as given.
    pub checkpoints: Vec<String>,
    /// Their iterations, in the same order.
    pub iterations: Vec<usize>,
}

/// The file naming the averaged checkpoints.
pub const AVERAGE_FILE: &str = "average.json";

/// The checkpoints `model_NNNNNN` of a run directory (`<run>/checkpoints/`) whose iteration
/// lies in `from..=to`, in iteration order.
pub fn run_checkpoints_between(
    run: &Path,
    from: usize,
    to: usize,
) -> Result<Vec<PathBuf>, CheckpointError> {
    let found: Vec<PathBuf> = run_checkpoints(run)
        .into_iter()
        .filter(|(iteration, _)| (from..=to).contains(iteration))
        .map(|(_, p)| p)
        .collect();
    if found.is_empty() {
        return Err(malformed(
            &run.join("checkpoints"),
            format!("no checkpoint model_NNNNNN with an iteration in {from}..={to}"),
        ));
    }
    Ok(found)
}

/// Averages the checkpoints `dirs` (at least one, all with the same networks) into `out`,
/// replacing it atomically. Returns what it averaged.
pub fn average(dirs: &[PathBuf], out: &Path) -> Result<AverageRecord, CheckpointError> {
    let Some(last) = dirs.last() else {
        return Err(malformed(out, "no checkpoint to average"));
    };
    let reference = load_config(&dirs[0])?;
    // Per tensor: its shape, its dtype, and the f64 sum of its elements so far.
    let mut sums: HashMap<String, (Vec<usize>, DType, Vec<f64>)> = HashMap::new();
    let mut iterations = Vec::with_capacity(dirs.len());
    for (k, dir) in dirs.iter().enumerate() {
        let cfg = load_config(dir)?;
        same_networks(&reference, &cfg).map_err(|why| {
            malformed(
                dir,
                format!("its networks differ from {}'s: {why}", dirs[0].display()),
            )
        })?;
        iterations.push(load_state(dir)?.iteration);
        let path = dir.join(POLICY_FILE);
        let tensors = read_tensors(&path)?;
        if k > 0 && tensors.len() != sums.len() {
            return Err(malformed(
                &path,
                format!(
                    "{} tensors where {} has {}",
                    tensors.len(),
                    dirs[0].display(),
                    sums.len()
                ),
            ));
        }
        for (name, t) in tensors {
            let elements = t
                .flatten_all()
                .and_then(|t| t.to_dtype(DType::F64))
                .and_then(|t| t.to_vec1::<f64>())
                .map_err(|e| malformed(&path, e))?;
            match sums.get_mut(&name) {
                None if k == 0 => {
                    sums.insert(name, (t.dims().to_vec(), t.dtype(), elements));
                }
                None => {
                    return Err(CheckpointError::MissingTensor {
                        path: dirs[0].join(POLICY_FILE).display().to_string(),
                        name,
                    })
                }
                Some((dims, _, _)) if dims.as_slice() != t.dims() => {
                    return Err(CheckpointError::ShapeMismatch {
                        path: path.display().to_string(),
                        name,
                        expected: dims.clone(),
                        found: t.dims().to_vec(),
                    })
                }
                Some((_, _, sum)) => sum.iter_mut().zip(&elements).for_each(|(s, x)| *s += x),
            }
        }
    }
    let n = dirs.len() as f64;
    let mut mean = HashMap::with_capacity(sums.len());
    for (name, (dims, dtype, sum)) in sums {
        let values: Vec<f64> = sum.into_iter().map(|s| s / n).collect();
        let t = Tensor::from_vec(values, dims, &Device::Cpu)
            .and_then(|t| t.to_dtype(dtype))
            .map_err(|e| malformed(out, e))?;
        mean.insert(name, t);
    }
    let record = AverageRecord {
        checkpoints: dirs.iter().map(|d| d.display().to_string()).collect(),
        iterations,
    };
    write(out, last, &mean, &record)?;
    Ok(record)
}

fn write(
    out: &Path,
    last: &Path,
    mean: &HashMap<String, Tensor>,
    record: &AverageRecord,
) -> Result<(), CheckpointError> {
    write_atomically(out, |tmp| {
        let policy = tmp.join(POLICY_FILE);
        candle_core::safetensors::save(mean, &policy).map_err(|e| malformed(&policy, e))?;
        for file in [CONFIG_FILE, STATE_FILE] {
            std::fs::copy(last.join(file), tmp.join(file)).map_err(io(&last.join(file)))?;
        }
        let record_path = tmp.join(AVERAGE_FILE);
        let text = serde_json::to_string_pretty(record).map_err(|e| malformed(&record_path, e))?;
        std::fs::write(&record_path, text + "\n").map_err(io(&record_path))
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::algo::ppo::Ppo;
    use crate::checkpoint::{load, save, test_support};
    use crate::config::TrainConfig;

    fn tiny(actor_hidden: usize) -> TrainConfig {
        test_support::tiny_config(actor_hidden)
    }

    fn tmpdir(name: &str) -> PathBuf {
        test_support::tmpdir(&format!("avg-{name}"))
    }

    fn values(dir: &Path) -> HashMap<String, Vec<f32>> {
        read_tensors(&dir.join(POLICY_FILE))
            .unwrap()
            .into_iter()
            .map(|(k, t)| (k, t.flatten_all().unwrap().to_vec1::<f32>().unwrap()))
            .collect()
    }

    #[test]
    fn the_average_is_the_element_wise_mean_and_loads_as_a_checkpoint() {
        let run = tmpdir("mean");
        let mut seeds = Vec::new();
        for (k, seed) in [3u64, 5, 8].into_iter().enumerate() {
            let mut cfg = tiny(8);
            cfg.runner.seed = seed;
            let ppo = Ppo::new(&cfg).unwrap();
            let dir = run.join(format!("checkpoints/model_{:06}", 100 * (k + 1)));
            save(&dir, &ppo, 100 * (k + 1)).unwrap();
            seeds.push(dir);
        }
        let picked = run_checkpoints_between(&run, 150, 300).unwrap();
        assert_eq!(picked, seeds[1..].to_vec());
        let out = run.join("average");
        let record = average(&seeds, &out).unwrap();
        assert_eq!(record.iterations, vec![100, 200, 300]);
        let inputs: Vec<_> = seeds.iter().map(|d| values(d)).collect();
        let mean = values(&out);
        assert_eq!(mean.len(), inputs[0].len());
        let weights = &mean["actor.layers.0.weight"];
        assert_ne!(
            inputs[0]["actor.layers.0.weight"], inputs[1]["actor.layers.0.weight"],
            "different seeds initialize different weights"
        );
        for (name, got) in &mean {
            for (i, g) in got.iter().enumerate() {
                let want = inputs.iter().map(|v| v[name][i] as f64).sum::<f64>() / 3.0;
                assert_eq!(*g, want as f32, "{name}[{i}]");
            }
        }
        assert!(!weights.is_empty());
        assert_eq!(load_state(&out).unwrap().iteration, 300);
        let mut ppo = Ppo::new(&tiny(8)).unwrap();
        load(&out, &mut ppo, true).unwrap();
        let saved: AverageRecord =
            serde_json::from_str(&std::fs::read_to_string(out.join(AVERAGE_FILE)).unwrap())
                .unwrap();
        assert_eq!(saved, record);
        std::fs::remove_dir_all(&run).unwrap();
    }

    #[test]
    fn different_networks_an_empty_list_or_range_are_clear_errors() {
        let run = tmpdir("errors");
        let a = run.join("checkpoints/model_000001");
        let b = run.join("checkpoints/model_000002");
        save(&a, &Ppo::new(&tiny(8)).unwrap(), 1).unwrap();
        save(&b, &Ppo::new(&tiny(16)).unwrap(), 2).unwrap();
        let out = run.join("average");
        let err = average(&[a.clone(), b], &out).unwrap_err().to_string();
        assert!(err.contains("networks differ"), "{err}");
        assert!(!out.exists(), "nothing is written on an error");
        let err = average(&[], &out).unwrap_err().to_string();
        assert!(err.contains("no checkpoint"), "{err}");
        let err = run_checkpoints_between(&run, 5, 9).unwrap_err().to_string();
        assert!(err.contains("5..=9"), "{err}");
        std::fs::write(a.join(POLICY_FILE), b"not safetensors").unwrap();
        let err = average(std::slice::from_ref(&a), &out).unwrap_err();
        assert!(matches!(err, CheckpointError::Malformed { .. }), "{err}");
        std::fs::remove_dir_all(&run).unwrap();
    }
}
