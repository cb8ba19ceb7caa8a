//! RMA end to end on the point-mass stand-in: PPO trains the teacher's mu (and not the
//! memory encoder), adaptation regresses the memory encoder, and the adapted checkpoint
//! loads through the normal inference path and policy-codegen's loader as the deployed
//! networks (estimator, memory, actor).

use candle_core::Tensor;
use hexapod_core::obs::{ACTOR_OBS_DIM, HISTORY_DIM};
use host_train::algo::adaptation::{Adaptation, AdaptationConfig};
use host_train::checkpoint;
use host_train::config::{EnvKind, PriorKind, RmaConfig, RmaPhase, TrainConfig};
use host_train::env::make_env;
use host_train::runner::Runner;

fn teacher_config() -> TrainConfig {
    let mut c = TrainConfig::default();
    c.env.kind = EnvKind::Fake;
    c.env.num_envs = 8;
    c.ppo.num_steps_per_env = 16;
    c.ppo.num_learning_epochs = 2;
    c.ppo.num_mini_batches = 2;
    c.policy.estimator_hidden = vec![16];
    c.policy.memory_hidden = vec![32];
    c.policy.actor_hidden = vec![16, 16];
    c.policy.critic_hidden = vec![16];
    c.policy.privileged_encoder_hidden = vec![8];
    c.policy.terrain_encoder_hidden = vec![8];
    c.rewards.style = false;
    c.amp.prior_kind = PriorKind::Synthetic;
    c.rma = Some(RmaConfig {
        encoder_hidden: vec![16],
        ..Default::default()
    });
    c
}

fn weights(map: &candle_nn::VarMap, prefix: &str) -> Vec<Vec<f32>> {
    let data = map.data().lock().unwrap();
    let mut keys: Vec<&String> = data.keys().filter(|k| k.starts_with(prefix)).collect();
    keys.sort();
    keys.iter()
        .map(|k| {
            data[*k]
                .as_tensor()
                .flatten_all()
                .unwrap()
                .to_vec1()
                .unwrap()
        })
        .collect()
}

#[test]
fn a_teacher_trains_mu_then_adapts_into_a_deployable_checkpoint() {
    let cfg = teacher_config();
    let dir = std::env::temp_dir().join(format!("hexapod-rma-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let mut runner =
        Runner::new(&cfg, make_env(&cfg).unwrap(), None, &dir.join("teacher")).unwrap();
    let (mu0, memory0) = (
        weights(&runner.ppo.params, "env_factor_encoder."),
        weights(&runner.ppo.params, "memory."),
    );
    for _ in 0..2 {
        runner.iterate().unwrap();
    }
    assert_ne!(
        weights(&runner.ppo.params, "env_factor_encoder."),
        mu0,
        "PPO trains mu"
    );
    assert_eq!(
        weights(&runner.ppo.params, "memory."),
        memory0,
        "the memory waits"
    );
    let teacher_dir = runner.save().unwrap();
    let (_, teacher) = checkpoint::load_for_inference(&teacher_dir).unwrap();
    assert!(teacher.ac.teacher_latent);

    let acfg = AdaptationConfig {
        steps_per_iteration: 8,
        mini_batches: 2,
        teacher_mix_iterations: 1,
        ..Default::default()
    };
    let mut adapt = Adaptation::new(teacher, make_env(&cfg).unwrap(), acfg).unwrap();
    for _ in 0..2 {
        adapt.iterate().unwrap();
    }
    let probe = adapt.observations().clone();
    let adapted = adapt.into_adapted();
    let out = dir.join("adapted");
    checkpoint::save(&out, &adapted, 2).unwrap();

    let (saved, mut loaded) = checkpoint::load_for_inference(&out).unwrap();
    assert_eq!(saved.rma.as_ref().map(|r| r.phase), Some(RmaPhase::Adapted));
    assert!(!loaded.ac.teacher_latent);
    // The acting policy is the deployed one: the memory's latent, as trained.
    let act = loaded.act(&probe, true).unwrap();
    let n = probe.actor.len() / ACTOR_OBS_DIM;
    let obs = Tensor::from_slice(&probe.actor, (n, ACTOR_OBS_DIM), &adapted.device).unwrap();
    let hist = Tensor::from_slice(&probe.history, (n, HISTORY_DIM), &adapted.device).unwrap();
    let want: Vec<f32> = adapted
        .ac
        .policy(&obs, &hist)
        .unwrap()
        .mean
        .flatten_all()
        .unwrap()
        .to_vec1()
        .unwrap();
    assert_eq!(act.mean, want);

    // policy-codegen reads the same estimator, memory and actor.
    let reference = policy_codegen::checkpoint::load(&out).unwrap().policy;
    for i in 0..n {
        let a: [f32; ACTOR_OBS_DIM] = probe.actor[i * ACTOR_OBS_DIM..(i + 1) * ACTOR_OBS_DIM]
            .try_into()
            .unwrap();
        let h: [f32; HISTORY_DIM] = probe.history[i * HISTORY_DIM..(i + 1) * HISTORY_DIM]
            .try_into()
            .unwrap();
        let t = reference.trace(&a, &h);
        for (x, y) in t
            .actor
            .last()
            .unwrap()
            .iter()
            .zip(&want[i * 18..(i + 1) * 18])
        {
            assert!((x - y).abs() < 1e-5, "robot {i}: codegen {x} vs candle {y}");
        }
    }
    std::fs::remove_dir_all(&dir).unwrap();
}
