//! Every preset in `configs/` runs on the real simulator: one short iteration each (few
//! robots, short rollout), with its own network shapes, reward switches and priors.

use host_train::amp::prior_source::load_prior_source;
use host_train::config::{EnvKind, TrainConfig};
use host_train::env::make_env;
use host_train::runner::Runner;
use std::path::Path;

#[test]
fn every_preset_trains_an_iteration_on_the_simulator() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    for name in [
        "default",
        "ablation-gs",
        "ablation-gl",
        "ablation-gsl",
        "baseline",
        "concurrent",
        "paper",
        "flat-tripod",
        "rough-tripod",
        "rough-climb",
        "rough-climb-hard",
    ] {
        let mut cfg = TrainConfig::load(&root.join(format!("configs/{name}.toml"))).unwrap();
        assert_eq!(cfg.env.kind, EnvKind::Sim, "{name}");
        cfg.env.num_envs = 4;
        cfg.ppo.num_steps_per_env = 8;
        cfg.ppo.num_learning_epochs = 1;
        cfg.amp.replay_buffer_size = 1000;
        cfg.amp.priors_dir = root.join(&cfg.amp.priors_dir).display().to_string();
        cfg.sim.terrain.rows = cfg.sim.terrain.rows.min(2);
        cfg.validate().unwrap();
        let priors = load_prior_source(&cfg).unwrap();
        assert_eq!(priors.is_some(), cfg.amp_enabled(), "{name}");
        let dir =
            std::env::temp_dir().join(format!("hexapod-preset-{name}-{}", std::process::id()));
        let mut runner = Runner::new(&cfg, make_env(&cfg).unwrap(), priors, &dir).unwrap();
        let row = runner.iterate().unwrap_or_else(|e| panic!("{name}: {e}"));
        assert!(row["loss/value"].is_finite(), "{name}");
        assert_eq!(
            row["amp/d_prior"] != 0.0,
            cfg.amp_enabled(),
            "{name}: discriminator trained iff style is on"
        );
        assert_eq!(
            row["estimator/error_m_s"].is_finite(),
            cfg.policy.use_estimator,
            "{name}"
        );
        runner.save().unwrap();
        std::fs::remove_dir_all(&dir).ok();
    }
}
