//! Smoke training on the point-mass stand-in: PPO + AMP improve, checkpoints round-trip
//! through resume, a NaN stops the run and keeps the last good checkpoint.

use host_sim::vec_env::{Observations, StepResult, VecEnv};
use host_train::algo::ppo::PpoError;
use host_train::amp::prior_source::{MotionPriorSource, SyntheticTripod};
use host_train::checkpoint;
use host_train::config::TrainConfig;
use host_train::env::fake::PointMassEnv;
use host_train::error::TrainError;
use host_train::runner::Runner;
use std::path::{Path, PathBuf};

fn smoke_config() -> TrainConfig {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../configs/smoke.toml");
    TrainConfig::load(&path).unwrap()
}

fn run_dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("hexapod-smoke-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    d
}

fn env_for(cfg: &TrainConfig) -> Box<dyn VecEnv> {
    Box::new(PointMassEnv::new(
        cfg.env.num_envs,
        cfg.env.fake_episode_steps,
        cfg.rewards.task,
        cfg.rewards.penalties,
        cfg.env.seed,
    ))
}

fn priors() -> Option<Box<dyn MotionPriorSource>> {
    Some(Box::new(SyntheticTripod::default()))
}

fn mean(rows: &[std::collections::BTreeMap<String, f64>], key: &str) -> f64 {
    rows.iter().map(|r| r[key]).sum::<f64>() / rows.len() as f64
}

#[test]
fn ppo_with_amp_learns_and_resumes() {
    let mut cfg = smoke_config();
    cfg.runner.max_iterations = 40;
    cfg.runner.save_interval = 20;
    let dir = run_dir("learn");
    let mut runner = Runner::new(&cfg, env_for(&cfg), priors(), &dir).unwrap();
    let last = runner.learn(false).unwrap();
    let rows = runner.metrics.rows();
    let (first, end) = (&rows[..8], &rows[rows.len() - 8..]);
    // The estimator learns the velocity from the joint history.
    assert!(mean(end, "estimator/error_m_s") < 0.5 * mean(first, "estimator/error_m_s"));
    // The discriminator separates prior from policy transitions.
    assert!(mean(end, "amp/d_prior") > 0.5 && mean(end, "amp/d_policy") < -0.5);
    // The policy tracks its commands better and collects more task reward.
    assert!(mean(end, "tracking/lin_vel_error_m_s") < mean(first, "tracking/lin_vel_error_m_s"));
    assert!(mean(end, "reward/env") > mean(first, "reward/env"));
    assert!(dir.join("metrics.csv").exists() && dir.join("plots/reward_terms.png").exists());
    assert_eq!(last, dir.join("checkpoints/model_000040"));

    // Resume from the middle checkpoint: same iteration counter, training continues.
    let mid = dir.join("checkpoints/model_000020");
    let mut cfg2 = checkpoint::load_config(&mid).unwrap();
    cfg2.runner.max_iterations = 22;
    let mut resumed = Runner::new(&cfg2, env_for(&cfg2), priors(), &run_dir("resume")).unwrap();
    resumed.resume(&mid).unwrap();
    assert_eq!(resumed.iteration, 20);
    assert!(
        resumed.ppo.ac.norm_actor.count() > 0.0,
        "normalizers restored"
    );
    resumed.learn(false).unwrap();
    assert_eq!(resumed.metrics.rows().len(), 2);
    std::fs::remove_dir_all(&dir).ok();
}

/// A run's metrics rows without the wall-clock ones (`perf/*`).
fn learning_rows(runner: &Runner) -> Vec<Vec<(String, u64)>> {
    let rows = runner.metrics.rows().iter();
    rows.map(|r| {
        let kept = r.iter().filter(|(k, _)| !k.starts_with("perf/"));
        kept.map(|(k, v)| (k.clone(), v.to_bits())).collect()
    })
    .collect()
}

#[test]
fn the_same_seed_gives_the_same_training_and_another_seed_another() {
    let mut cfg = smoke_config();
    cfg.env.num_envs = 16;
    cfg.runner.max_iterations = 3;
    let run = |cfg: &TrainConfig, name: &str| {
        let dir = run_dir(name);
        let mut runner = Runner::new(cfg, env_for(cfg), priors(), &dir).unwrap();
        runner.learn(false).unwrap();
        std::fs::remove_dir_all(&dir).ok();
        learning_rows(&runner)
    };
    let (a, b) = (run(&cfg, "seed-a"), run(&cfg, "seed-b"));
    assert_eq!(a.len(), 3);
    assert_eq!(
        a, b,
        "two runs of one config (the networks' first weights included)"
    );
    cfg.runner.seed += 1;
    assert_ne!(
        a,
        run(&cfg, "seed-c"),
        "runner.seed draws other first weights"
    );
}

/// How [`PoisonedEnv`] breaks from its `after`-th step on.
enum Fault {
    /// NaN rewards.
    NanRewards,
    /// A panic in `step`, as a simulator bug would.
    Panic,
}

/// Breaks from the `after`-th step on, in the way `fault` says.
struct PoisonedEnv {
    inner: PointMassEnv,
    steps: usize,
    after: usize,
    fault: Fault,
}

impl VecEnv for PoisonedEnv {
    fn num_envs(&self) -> usize {
        self.inner.num_envs()
    }
    fn reset(&mut self) -> Observations {
        self.inner.reset()
    }
    fn set_command(&mut self, i: usize, command: [f32; 3]) {
        self.inner.set_command(i, command);
    }
    fn step(&mut self, actions: &[f32]) -> StepResult {
        self.steps += 1;
        let broken = self.steps > self.after;
        assert!(
            !(broken && matches!(self.fault, Fault::Panic)),
            "degenerate contact in the test env"
        );
        let mut r = self.inner.step(actions);
        if broken {
            r.rewards.iter_mut().for_each(|x| *x = f32::NAN);
        }
        r
    }
}

#[test]
fn nan_loss_stops_the_run_and_keeps_the_last_good_checkpoint() {
    let mut cfg = smoke_config();
    cfg.env.num_envs = 8;
    cfg.runner.max_iterations = 10;
    cfg.runner.save_interval = 2;
    let steps = cfg.ppo.num_steps_per_env;
    let env = PoisonedEnv {
        inner: PointMassEnv::new(8, 100, true, true, 1),
        steps: 0,
        after: 3 * steps + 5,
        fault: Fault::NanRewards,
    };
    let dir = run_dir("nan");
    let mut runner = Runner::new(&cfg, Box::new(env), priors(), &dir).unwrap();
    let err = runner.learn(false).unwrap_err();
    assert!(
        matches!(
            err.source,
            TrainError::Learner(PpoError::NonFiniteLoss { iteration: 3, .. })
        ),
        "{err}"
    );
    let good = dir.join("checkpoints/model_000002");
    assert_eq!(err.last_checkpoint.as_deref(), Some(good.as_path()));
    assert!(err.to_string().contains("model_000002"), "{err}");
    // The last good checkpoint loads and holds finite weights.
    let (_, ppo) = checkpoint::load_for_inference(&good).unwrap();
    let w = ppo.ac.actor.layers()[0]
        .weight()
        .flatten_all()
        .unwrap()
        .to_vec1::<f32>()
        .unwrap();
    assert!(w.iter().all(|x| x.is_finite()));
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn a_panic_in_the_environment_saves_the_learner_and_says_so() {
    let mut cfg = smoke_config();
    cfg.env.num_envs = 8;
    cfg.runner.max_iterations = 10;
    cfg.runner.save_interval = 2;
    let steps = cfg.ppo.num_steps_per_env;
    let env = PoisonedEnv {
        inner: PointMassEnv::new(8, 100, true, true, 1),
        steps: 0,
        after: 3 * steps + 5,
        fault: Fault::Panic,
    };
    let dir = run_dir("panic");
    let mut runner = Runner::new(&cfg, Box::new(env), priors(), &dir).unwrap();
    let err = runner.learn(false).unwrap_err();
    assert!(
        matches!(&err.source, TrainError::EnvPanic { iteration: 3, message } if message.contains("degenerate contact")),
        "{err}"
    );
    // Iterations 0-2 finished: their learner is saved as model_000003, past the periodic
    // model_000002, with all three metrics rows.
    let saved = dir.join("checkpoints/model_000003");
    assert_eq!(err.last_checkpoint.as_deref(), Some(saved.as_path()));
    assert!(err.to_string().contains("model_000003"), "{err}");
    let csv = std::fs::read_to_string(dir.join("metrics.csv")).unwrap();
    assert_eq!(csv.lines().count(), 1 + 3);
    // It resumes where the rollout broke off.
    let mut resumed = Runner::new(&cfg, env_for(&cfg), priors(), &dir).unwrap();
    resumed.resume(&saved).unwrap();
    assert_eq!(resumed.iteration, 3);
    std::fs::remove_dir_all(&dir).ok();
}

/// A point-mass stand-in that walks "terrain tiles": it reports and takes each robot's
/// curriculum tile, shared with the test, and counts its resets.
struct TiledEnv {
    inner: PointMassEnv,
    tiles: std::sync::Arc<std::sync::Mutex<Vec<[usize; 2]>>>,
    resets: std::sync::Arc<std::sync::atomic::AtomicUsize>,
}

impl TiledEnv {
    fn new(n: usize) -> Self {
        Self {
            inner: PointMassEnv::new(n, 100, true, true, 1),
            tiles: std::sync::Arc::new(std::sync::Mutex::new(vec![[0, 0]; n])),
            resets: Default::default(),
        }
    }
}

impl VecEnv for TiledEnv {
    fn num_envs(&self) -> usize {
        self.inner.num_envs()
    }
    fn reset(&mut self) -> Observations {
        self.resets
            .fetch_add(1, std::sync::atomic::Ordering::SeqCst);
        self.inner.reset()
    }
    fn set_command(&mut self, i: usize, command: [f32; 3]) {
        self.inner.set_command(i, command);
    }
    fn step(&mut self, actions: &[f32]) -> StepResult {
        self.inner.step(actions)
    }
    fn terrain_tiles(&self) -> Option<Vec<[usize; 2]>> {
        Some(self.tiles.lock().unwrap().clone())
    }
    fn set_terrain_tiles(&mut self, tiles: &[[usize; 2]]) {
        self.tiles.lock().unwrap().copy_from_slice(tiles);
    }
}

#[test]
fn a_resumed_run_goes_on_from_the_curriculum_its_checkpoint_recorded() {
    let mut cfg = smoke_config();
    cfg.env.num_envs = 8;
    cfg.runner.max_iterations = 1;
    let dir = run_dir("curriculum");
    let env = TiledEnv::new(8);
    let reached: Vec<[usize; 2]> = (0..8).map(|i| [i % 6, i % 3]).collect();
    *env.tiles.lock().unwrap() = reached.clone();
    let mut runner = Runner::new(&cfg, Box::new(env), priors(), &dir).unwrap();
    let ckpt = runner.learn(false).unwrap();
    assert_eq!(
        checkpoint::load_state(&ckpt).unwrap().terrain_tiles,
        Some(reached.clone())
    );

    // A new run of the same size starts on the recorded tiles, reset onto them.
    let fresh = TiledEnv::new(8);
    let (tiles, resets) = (fresh.tiles.clone(), fresh.resets.clone());
    let mut resumed =
        Runner::new(&cfg, Box::new(fresh), priors(), &run_dir("curriculum-b")).unwrap();
    let resets_before = resets.load(std::sync::atomic::Ordering::SeqCst);
    resumed.resume(&ckpt).unwrap();
    assert_eq!(*tiles.lock().unwrap(), reached);
    assert_eq!(
        resets.load(std::sync::atomic::Ordering::SeqCst),
        resets_before + 1
    );

    // Another number of robots takes the rows per tile kind: robot i stands on column i % 6
    // and takes the first row the checkpoint's robots reached on that column's kind (none
    // of them stood on column 3: that robot keeps its initial row).
    let mut cfg4 = cfg.clone();
    cfg4.env.num_envs = 4;
    assert_eq!(cfg4.sim.terrain.columns.len(), 6);
    let other = TiledEnv::new(4);
    let tiles4 = other.tiles.clone();
    let mut four = Runner::new(&cfg4, Box::new(other), priors(), &run_dir("curriculum-c")).unwrap();
    four.resume(&ckpt).unwrap();
    assert_eq!(
        *tiles4.lock().unwrap(),
        vec![[0, 0], [1, 1], [2, 2], [0, 3]]
    );
    // So does a checkpoint without tiles keep the initial rows.
    std::fs::write(ckpt.join(checkpoint::STATE_FILE), "{\"iteration\": 1}").unwrap();
    let old = TiledEnv::new(8);
    let tiles_old = old.tiles.clone();
    let mut from_old =
        Runner::new(&cfg, Box::new(old), priors(), &run_dir("curriculum-d")).unwrap();
    from_old.resume(&ckpt).unwrap();
    assert_eq!(from_old.iteration, 1);
    assert_eq!(*tiles_old.lock().unwrap(), vec![[0, 0]; 8]);
    std::fs::remove_dir_all(&dir).ok();
}
