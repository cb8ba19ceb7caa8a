//! Environment-level checks: observation layout, determinism, randomization ranges, bad actions.

use hexapod_core::obs::*;
use hexapod_core::robot::NUM_JOINTS;
use host_sim::config::EnvConfig;
use host_sim::env::HexapodEnv;
use host_sim::vec_env::VecEnv;

fn quiet_config(num_envs: usize) -> EnvConfig {
    let mut c = EnvConfig {
        num_envs,
        observation_noise: false,
        ..Default::default()
    };
    c.randomization.enabled = false;
    c.push.enabled = false;
    c
}

#[test]
fn standing_observations_match_core_layout_and_scales() {
    let mut env = HexapodEnv::new(quiet_config(2)).unwrap();
    env.reset();
    env.set_command(0, [0.25, -0.1, 0.4]);
    let mut r = env.step(&[0.0; 2 * NUM_JOINTS]);
    for _ in 0..100 {
        r = env.step(&[0.0; 2 * NUM_JOINTS]);
    }
    assert!(!r.dones[0], "standing robot must not terminate");
    let a = &r.obs.actor[..ACTOR_OBS_DIM];
    let cmd = env.command(0);
    for k in 0..3 {
        assert!((a[ACTOR_COMMAND.start + k] - cmd[k] * COMMAND_SCALE[k]).abs() < 1e-6);
    }
    let p = &a[ACTOR_PROPRIO];
    // Upright: gravity along -z of the base.
    assert!(
        (p[PROPRIO_GRAVITY.start + 2] + 1.0).abs() < 0.01,
        "{:?}",
        &p[PROPRIO_GRAVITY]
    );
    // Standing at the nominal pose: q - q0 near zero, small velocities.
    assert!(
        p[PROPRIO_JOINT_POS].iter().all(|x| x.abs() < 0.05),
        "{:?}",
        &p[PROPRIO_JOINT_POS]
    );
    let priv_ = &r.obs.privileged[..PRIVILEGED_DIM];
    assert!(
        (priv_[PRIV_BASE_HEIGHT] - hexapod_core::robot::NOMINAL_BASE_HEIGHT_M).abs() < 0.02,
        "height {}",
        priv_[PRIV_BASE_HEIGHT]
    );
    let fz: f32 = (0..6)
        .map(|l| priv_[PRIV_CONTACT_FORCES.start + 3 * l + 2])
        .sum();
    assert!(
        (fz / CONTACT_FORCE_SCALE - 25.5 * 9.81).abs() < 25.0,
        "fz {fz}"
    );
    // Height scan on flat ground: (0.30 - 0.3 - 0) * 5 ~ 0.
    assert!(r.obs.heights[..HEIGHT_SCAN_DIM]
        .iter()
        .all(|h| h.abs() < 0.15));
    // History: newest entry is the actor's o^p.
    let hist = &r.obs.history[..HISTORY_DIM];
    assert_eq!(&hist[HISTORY_DIM - PROPRIO_DIM..], p);
    // AMP state: joint positions absolute.
    let amp = &r.obs.amp[..61];
    let q0 = hexapod_core::robot::Q0_RAD;
    assert!((amp[1] - q0[1]).abs() < 0.05);
}

#[test]
fn same_seed_same_trajectory() {
    let run = || {
        let mut env = HexapodEnv::new(EnvConfig {
            num_envs: 3,
            ..Default::default()
        })
        .unwrap();
        let mut obs = env.reset();
        let mut t = 0.0f32;
        for k in 0..60 {
            let actions: Vec<f32> = (0..3 * NUM_JOINTS)
                .map(|j| ((k * 7 + j) as f32 * 0.37).sin() * 0.5)
                .collect();
            let r = env.step(&actions);
            t += r.rewards.iter().sum::<f32>();
            obs = r.obs;
        }
        (obs.actor, obs.privileged, t)
    };
    let (a1, p1, t1) = run();
    let (a2, p2, t2) = run();
    assert_eq!(a1, a2);
    assert_eq!(p1, p2);
    assert_eq!(t1, t2);
}

#[test]
fn randomized_friction_stays_in_range() {
    let mut env = HexapodEnv::new(EnvConfig {
        num_envs: 32,
        ..Default::default()
    })
    .unwrap();
    let obs = env.reset();
    let frictions: Vec<f32> = (0..32)
        .map(|i| obs.privileged[i * PRIVILEGED_DIM + PRIV_FRICTION])
        .collect();
    assert!(
        frictions.iter().all(|f| (0.1..=2.5).contains(f)),
        "{frictions:?}"
    );
    let spread = frictions.iter().cloned().fold(f32::MIN, f32::max)
        - frictions.iter().cloned().fold(f32::MAX, f32::min);
    assert!(spread > 1.0, "friction is not randomized: {frictions:?}");
}

#[test]
fn randomized_drives_and_masses_stay_in_range() {
    let n = 24;
    let mut env = HexapodEnv::new(EnvConfig {
        num_envs: n,
        ..Default::default()
    })
    .unwrap();
    env.reset();
    env.step(&vec![0.0; n * NUM_JOINTS]);
    let nominal_kg = hexapod_core::robot::TOTAL_MASS_KG;
    let (mut lo_kg, mut hi_kg) = (f32::MAX, f32::MIN);
    for i in 0..n {
        let d = env.drive_params(i);
        for j in 0..NUM_JOINTS {
            let stiffness = d.kp1_per_s[j] * d.kp2_nms_per_rad[j];
            assert!((80.0..=120.0).contains(&stiffness), "stiffness {stiffness}");
            assert!(
                (1.6..=2.4).contains(&d.kp2_nms_per_rad[j]),
                "damping {}",
                d.kp2_nms_per_rad[j]
            );
            assert!((0.8..=1.2).contains(&d.motor_strength[j]));
        }
        let m = env.total_mass_kg(i);
        assert!(
            m >= 0.9 * nominal_kg - 1e-3 && m <= 1.1 * nominal_kg + 5.0 + 1e-3,
            "mass {m}"
        );
        lo_kg = lo_kg.min(m);
        hi_kg = hi_kg.max(m);
    }
    assert!(
        hi_kg - lo_kg > 1.0,
        "masses are not randomized: {lo_kg}..{hi_kg}"
    );
}

#[test]
fn nan_action_resets_only_that_robot() {
    let mut env = HexapodEnv::new(quiet_config(2)).unwrap();
    env.reset();
    let mut actions = vec![0.0; 2 * NUM_JOINTS];
    actions[NUM_JOINTS + 3] = f32::NAN;
    let r = env.step(&actions);
    assert_eq!(r.invalid_actions, vec![false, true]);
    assert_eq!(r.dones, vec![false, true]);
    assert!(r.obs.actor.iter().all(|x| x.is_finite()));
}

#[test]
fn targets_take_the_firmware_action_path() {
    use hexapod_core::control::{action_to_targets, max_target_step_rad};
    use hexapod_core::robot::{Q0_RAD, Q_MAX_RAD, Q_MIN_RAD};
    let mut env = HexapodEnv::new(quiet_config(1)).unwrap();
    env.reset();
    let mut previous = env.targets_rad(0);
    assert_eq!(previous, Q0_RAD, "targets start at the spawn pose");
    // A saturated action: the targets move by at most one step of the velocity limit and
    // never beyond the joint limits, exactly as the firmware's control step computes them.
    let action = [100.0; NUM_JOINTS];
    for _ in 0..5 {
        if env.step(&action).dones[0] {
            break;
        }
        let targets = env.targets_rad(0);
        assert_eq!(targets, action_to_targets(&action, &previous).1);
        for j in 0..NUM_JOINTS {
            assert!((targets[j] - previous[j]).abs() <= max_target_step_rad(j) + 1e-6);
            assert!((Q_MIN_RAD[j]..=Q_MAX_RAD[j]).contains(&targets[j]));
        }
        previous = targets;
    }
    // The rate limit held: after one step no target is at the action's far end.
    assert!(previous.iter().zip(&Q_MAX_RAD).any(|(t, m)| t < m));
}

#[test]
fn episodes_start_from_reference_states_when_given() {
    use host_sim::frames::rotate_inverse;
    use host_sim::reference::{ReferenceStart, ReferenceState};
    let mut c = quiet_config(4);
    c.reference_init_probability = 1.0;
    let mut env = HexapodEnv::new(c).unwrap();
    let mut q = hexapod_core::robot::Q0_RAD;
    q[1] += 0.2;
    let tilt = 0.1f32;
    let reference = ReferenceState {
        q_rad: q,
        qdot_rad_s: [0.5; NUM_JOINTS],
        lin_vel_base_m_s: [0.3, 0.0, 0.0],
        ang_vel_base_rad_s: [0.0, 0.0, 0.4],
        up_base: [tilt.sin(), 0.0, tilt.cos()],
        base_height_m: 0.30,
    };
    let start = ReferenceStart {
        state: reference,
        command: [0.3, 0.0, 0.4],
    };
    env.set_reference_states(vec![start].into());
    env.reset();
    for i in 0..4 {
        let s = env.robot_state(i);
        assert!(
            s.q_rad.iter().zip(&q).all(|(a, b)| (a - b).abs() < 1e-5),
            "{:?}",
            s.q_rad
        );
        assert!(
            s.qdot_rad_s.iter().all(|&v| (v - 0.5).abs() < 1e-5),
            "{:?}",
            s.qdot_rad_s
        );
        let v = rotate_inverse(s.base_quat_xyzw, s.base_lin_vel_world_m_s);
        let w = rotate_inverse(s.base_quat_xyzw, s.base_ang_vel_world_rad_s);
        assert!((v[0] - 0.3).abs() < 1e-4 && v[1].abs() < 1e-4, "{v:?}");
        assert!((w[2] - 0.4).abs() < 1e-4, "{w:?}");
        let up = rotate_inverse(s.base_quat_xyzw, [0.0, 0.0, 1.0]);
        assert!(
            (up[0] - tilt.sin()).abs() < 1e-5 && (up[2] - tilt.cos()).abs() < 1e-5,
            "{up:?}"
        );
        assert!(
            s.base_pos_world_m[2] >= 0.30 - 1e-4,
            "spawned at {} m",
            s.base_pos_world_m[2]
        );
    }
    // Their commands stay random unless asked for the motion's command.
    assert!((0..4).all(|i| env.command(i) != start.command));
    // Without reference states (or with probability 0) robots stand at the nominal pose.
    let mut env = HexapodEnv::new(quiet_config(1)).unwrap();
    env.reset();
    assert_eq!(env.robot_state(0).qdot_rad_s, [0.0; NUM_JOINTS]);
}

#[test]
fn a_reference_start_can_bring_its_motions_command() {
    use host_sim::reference::{ReferenceStart, ReferenceState};
    let state = ReferenceState {
        q_rad: hexapod_core::robot::Q0_RAD,
        qdot_rad_s: [0.0; NUM_JOINTS],
        lin_vel_base_m_s: [0.2, 0.1, 0.0],
        ang_vel_base_rad_s: [0.0, 0.0, -0.3],
        up_base: [0.0, 0.0, 1.0],
        base_height_m: 0.30,
    };
    let start = ReferenceStart {
        state,
        command: [0.2, 0.1, -0.3],
    };
    let mut c = quiet_config(3);
    c.reference_init_probability = 1.0;
    c.reference_init_command = true;
    let mut env = HexapodEnv::new(c.clone()).unwrap();
    env.set_reference_states(vec![start].into());
    env.set_command(2, [0.0, 0.0, 0.5]);
    let obs = env.reset();
    assert_eq!(env.command(0), start.command);
    assert_eq!(env.command(1), start.command);
    // A fixed command (play, evaluation) wins over the motion's.
    assert_eq!(env.command(2), [0.0, 0.0, 0.5]);
    // The actor sees it: same observation as a robot given that command by hand.
    let mut by_hand = HexapodEnv::new(c).unwrap();
    by_hand.set_reference_states(vec![start].into());
    by_hand.set_command(0, start.command);
    let expected = by_hand.reset();
    assert_eq!(obs.actor[..3], expected.actor[..3]);
    // With probability 0 no episode starts from it, and the command is drawn as usual.
    let mut c = quiet_config(3);
    c.reference_init_command = true;
    let mut env = HexapodEnv::new(c).unwrap();
    env.set_reference_states(vec![start].into());
    env.reset();
    assert!((0..3).all(|i| env.command(i) != start.command));
}

#[test]
fn time_out_is_flagged_for_bootstrapping() {
    let mut c = quiet_config(1);
    c.episode_length_s = 0.2;
    let mut env = HexapodEnv::new(c).unwrap();
    env.reset();
    let mut last = None;
    for _ in 0..10 {
        last = Some(env.step(&[0.0; NUM_JOINTS]));
    }
    let r = last.unwrap();
    assert!(r.dones[0] && r.time_outs[0]);
    assert!(r
        .episode_log
        .iter()
        .any(|(k, _)| k == "rew_tracking_lin_vel"));
}

#[test]
fn randomized_episode_clocks_spread_the_first_time_outs_then_episodes_run_in_full() {
    let mut c = quiet_config(6);
    c.episode_length_s = 0.2; // 10 policy steps
    let mut env = HexapodEnv::new(c).unwrap();
    env.reset();
    env.randomize_episode_clocks();
    let zeros = [0.0; 6 * NUM_JOINTS];
    let mut first_time_out = [None; 6];
    let mut second_time_out = [None; 6];
    for step in 1..=20 {
        let r = env.step(&zeros);
        for i in 0..6 {
            assert!(!r.dones[i] || r.time_outs[i], "robot {i} fell standing");
            if r.time_outs[i] {
                if first_time_out[i].is_none() {
                    first_time_out[i] = Some(step);
                } else if second_time_out[i].is_none() {
                    second_time_out[i] = Some(step);
                }
            }
        }
    }
    let first: Vec<usize> = first_time_out.iter().map(|s| s.unwrap()).collect();
    assert!(first.iter().all(|&s| (1..=10).contains(&s)), "{first:?}");
    let distinct = first
        .iter()
        .collect::<std::collections::BTreeSet<_>>()
        .len();
    assert!(distinct >= 3, "first time-outs not spread: {first:?}");
    for i in 0..6 {
        assert_eq!(
            second_time_out[i],
            Some(first[i] + 10),
            "robot {i}: the next episode runs its full 10 steps"
        );
    }
}

#[test]
fn robots_spawned_on_stairs_and_blocks_stand() {
    // Spawns near a stair tile's platform edge put feet over the first step; each must
    // start above the ground under it (a foot inside the heightfield falls through it and
    // the robot sinks onto its trunk: 6 of 8 robots on 6 cm stairs did before).
    use host_sim::terrain::TileKind;
    let mut c = quiet_config(24);
    c.terrain.tiles = true;
    c.terrain.rows = 3;
    c.curriculum = false;
    let mut env = HexapodEnv::new(c).unwrap();
    let columns = env.config().terrain.columns.clone();
    let kinds = [
        TileKind::StairsUp,
        TileKind::StairsDown,
        TileKind::DiscreteObstacles,
    ];
    for i in 0..24 {
        let column = columns.iter().position(|k| *k == kinds[i % 3]).unwrap();
        env.set_terrain_tile(i, 1 + i % 2, column);
    }
    env.reset();
    for step in 0..100 {
        let r = env.step(&vec![0.0; 24 * NUM_JOINTS]);
        let fallen: Vec<usize> = (0..24).filter(|&i| r.dones[i]).collect();
        assert!(fallen.is_empty(), "robots {fallen:?} ended at step {step}");
    }
    for i in 0..24 {
        let s = env.robot_state(i);
        let up = s.base_quat_xyzw;
        // Upright: the base's z axis within 45 deg of vertical (legs in q0 on steps 20 cm
        // apart tilt the body by about 30 deg).
        let z_axis_z = 1.0 - 2.0 * (up[0] * up[0] + up[1] * up[1]);
        assert!(
            z_axis_z > 45f32.to_radians().cos(),
            "robot {i} tilted: {z_axis_z}"
        );
    }
}

#[test]
fn the_curriculum_tiles_round_trip_and_flat_ground_has_none() {
    let mut c = quiet_config(6);
    c.terrain.tiles = true;
    c.terrain.rows = 4;
    let mut env = HexapodEnv::new(c).unwrap();
    let tiles: Vec<[usize; 2]> = (0..6).map(|i| [3 - i % 4, i % 6]).collect();
    env.set_terrain_tiles(&tiles);
    env.reset();
    assert_eq!(env.terrain_tiles(), Some(tiles));
    assert_eq!(
        HexapodEnv::new(quiet_config(2)).unwrap().terrain_tiles(),
        None
    );
}

#[test]
fn a_blown_up_state_terminates_and_a_hard_push_does_not() {
    use host_sim::env::{terminated, BLOWN_UP_SPEED_M_S};
    use host_sim::robot::RobotState;
    let upright = RobotState {
        base_pos_world_m: [0.0, 0.0, 0.3],
        base_quat_xyzw: [0.0, 0.0, 0.0, 1.0],
        ..Default::default()
    };
    assert!(!terminated(&upright, false, 60.0));
    let pushed = RobotState {
        base_lin_vel_world_m_s: [6.0, 0.0, 0.0],
        ..upright
    };
    assert!(!terminated(&pushed, false, 60.0));
    let blown_up = RobotState {
        base_lin_vel_world_m_s: [0.0, 0.0, 1.5 * BLOWN_UP_SPEED_M_S],
        ..upright
    };
    assert!(terminated(&blown_up, false, 60.0));
    let spinning_nan = RobotState {
        base_ang_vel_world_rad_s: [0.0, f32::NAN, 0.0],
        ..upright
    };
    assert!(terminated(&spinning_nan, false, 60.0));
}
