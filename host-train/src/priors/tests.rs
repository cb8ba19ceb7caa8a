//! Tests across the priors pipeline: loader on good and bad files, dataset sampling, AMP
//! states shared with the simulator, replay in host-sim, and the committed dataset.

use super::clip::{ClipError, LoopMode, MotionClip};
use super::command::{default_commands, GaitCommand};
use super::dataset::{MotionDataset, PriorStates, ReferenceMotion};
use super::generate::{generate_clip, GeneratorConfig};
use super::sim_tracking::{replay_clip, sim_amp_state, ReplayConfig};
use hexapod_core::amp::{AMP_BASE_ANG_VEL, AMP_JOINT_POS, AMP_JOINT_VEL};
use hexapod_core::robot::{joint_index, Joint, Leg, TRIPOD_A, TRIPOD_B};
use host_sim::frames::rotate;
use host_sim::robot::{RobotState, RobotWorld};
use rand::SeedableRng;
use serde_json::Value;
use std::path::{Path, PathBuf};

fn clip(name: &str, vx: f64, vy: f64, wz: f64) -> MotionClip {
    generate_clip(
        &GaitCommand::new(name, vx, vy, wz),
        &GeneratorConfig::default(),
    )
    .unwrap()
    .0
}

/// Parses `clip` after `edit` changed its JSON.
fn parse_edited(clip: &MotionClip, edit: impl FnOnce(&mut Value)) -> Result<MotionClip, ClipError> {
    let mut v: Value = serde_json::from_str(&clip.to_json()).unwrap();
    edit(&mut v);
    MotionClip::parse(Path::new("bad.json"), &v.to_string())
}

fn assert_field_error(err: ClipError, frame: usize, field: &str) {
    let text = err.to_string();
    match err {
        ClipError::Field {
            file,
            frame: f,
            field: name,
            ..
        } => {
            assert_eq!(file, PathBuf::from("bad.json"));
            assert_eq!((f, name.as_str()), (frame, field), "{text}");
            assert!(text.starts_with("bad.json: frame "), "{text}");
        }
        other => panic!("expected a field error, got {other}"),
    }
}

#[test]
fn generated_clip_round_trips_through_the_loader() {
    let c = clip("fwd", 0.3, 0.0, 0.0);
    let back = MotionClip::parse(Path::new("fwd.json"), &c.to_json()).unwrap();
    assert_eq!(back.frames.len(), 30);
    assert_eq!(back.loop_mode, LoopMode::Wrap);
    assert_eq!(back.command, [0.3, 0.0, 0.0]);
    for (a, b) in c.frames.iter().zip(&back.frames) {
        for (x, y) in a.to_row().iter().zip(b.to_row().iter()) {
            assert!((x - y).abs() < 2e-6);
        }
    }
    assert_eq!(back.metadata, c.metadata);
}

#[test]
fn loader_refuses_wrong_frame_lengths() {
    let c = clip("fwd", 0.2, 0.0, 0.0);
    let err = parse_edited(&c, |v| {
        v["Frames"][7].as_array_mut().unwrap().pop();
    })
    .unwrap_err();
    assert!(
        matches!(
            err,
            ClipError::FrameLength {
                frame: 7,
                got: 72,
                ..
            }
        ),
        "{err}"
    );
    assert!(err
        .to_string()
        .contains("bad.json: frame 7: has 72 values, expected 73"));
}

#[test]
fn loader_refuses_non_finite_values() {
    let c = clip("fwd", 0.2, 0.0, 0.0);
    // JSON has no NaN: a huge number overflows f32 to infinity.
    let err = parse_edited(&c, |v| v["Frames"][3][9] = Value::from(1e300)).unwrap_err();
    assert_field_error(err, 3, "joint_pos[2]");
    let err = MotionClip::parse(
        Path::new("bad.json"),
        &c.to_json()
            .replacen("\"Frames\":[[", "\"Frames\":[[NaN,", 1),
    )
    .unwrap_err();
    assert!(matches!(err, ClipError::Json { .. }), "{err}");
}

#[test]
fn loader_refuses_non_periodic_loops() {
    let c = clip("fwd", 0.4, 0.0, 0.0);
    // Two thirds of a cycle declared as a loop: the jump from the last frame to the first is
    // not what the velocities say.
    let err = parse_edited(&c, |v| v["Frames"].as_array_mut().unwrap().truncate(20)).unwrap_err();
    let text = err.to_string();
    assert!(text.contains("loop wrap"), "{text}");
    match err {
        ClipError::Field { frame, field, .. } => {
            assert_eq!(frame, 0);
            assert!(field.starts_with("joint_pos["), "{field}");
        }
        other => panic!("{other}"),
    }
    // The same frames as a clamped clip are fine.
    let ok = parse_edited(&c, |v| {
        v["Frames"].as_array_mut().unwrap().truncate(20);
        v["LoopMode"] = Value::from("Clamp");
    });
    assert!(ok.is_ok());
}

#[test]
fn loader_refuses_inconsistent_frames() {
    let c = clip("fwd", 0.2, 0.0, 0.0);
    let err = parse_edited(&c, |v| v["Frames"][5][3] = Value::from(0.5)).unwrap_err();
    assert_field_error(err, 5, "base_quat[0]");
    let err = parse_edited(&c, |v| v["Frames"][4][25 + 3 * 2 + 1] = Value::from(0.0)).unwrap_err();
    assert_field_error(err, 4, "foot_pos[7]");
    let err = parse_edited(&c, |v| v["Frames"][2][67 + 4] = Value::from(0.5)).unwrap_err();
    assert_field_error(err, 2, "contact[4]");
    let err = parse_edited(&c, |v| v["Frames"][9][7] = Value::from(2.0)).unwrap_err();
    assert_field_error(err, 9, "joint_pos[0]");
    let err = parse_edited(&c, |v| v["FrameDuration"] = Value::from(0.0167)).unwrap_err();
    assert!(
        matches!(
            err,
            ClipError::Header {
                field: "FrameDuration",
                ..
            }
        ),
        "{err}"
    );
    let err = parse_edited(&c, |v| v["MotionWeight"] = Value::from(-1.0)).unwrap_err();
    assert!(
        matches!(
            err,
            ClipError::Header {
                field: "MotionWeight",
                ..
            }
        ),
        "{err}"
    );
    let err = parse_edited(&c, |v| v["Extra"] = Value::from(1)).unwrap_err();
    assert!(matches!(err, ClipError::Json { .. }), "{err}");
}

#[test]
fn transitions_follow_the_weights_at_random_phases_one_step_apart() {
    let mut a = clip("a", 0.2, 0.0, 0.0);
    let mut b = clip("b", 0.0, 0.0, 0.5);
    a.motion_weight = 3.0;
    b.motion_weight = 1.0;
    let data = MotionDataset::new(vec![a, b]);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
    let samples = data.sample_transitions(&mut rng, 4000);
    let frame_states: Vec<_> = (0..2).flat_map(|c| data.amp_states(c)).collect();
    let (mut from_a, mut at_frames) = (0, 0);
    for (s, s_next) in &samples {
        // Clip b turns at 0.5 rad/s throughout, clip a does not turn.
        let turning = s[AMP_BASE_ANG_VEL.start + 2] > 0.25;
        assert_eq!(
            turning,
            s_next[AMP_BASE_ANG_VEL.start + 2] > 0.25,
            "a pair stays in its clip"
        );
        from_a += (!turning) as usize;
        at_frames += frame_states.contains(s) as usize;
        // One policy step apart: the joints move by the trapezoidal integral of their
        // velocities, within the loader's continuity tolerance (0.05 rad).
        for j in AMP_JOINT_POS {
            let predicted =
                s[j] + 0.02 * 0.5 * (s[AMP_JOINT_VEL.start + j] + s_next[AMP_JOINT_VEL.start + j]);
            assert!(
                (predicted - s_next[j]).abs() < 0.05,
                "joint {j}: {} -> {} (predicted {predicted})",
                s[j],
                s_next[j]
            );
        }
    }
    let share = from_a as f64 / samples.len() as f64;
    assert!((share - 0.75).abs() < 0.03, "{share}");
    assert!(
        at_frames < samples.len() / 20,
        "{at_frames} samples at frame instants: not interpolated"
    );
}

#[test]
fn interpolation_joins_neighbouring_frames_and_wraps_the_cycle() {
    let c = clip("f", 0.3, 0.0, 0.0);
    let m = ReferenceMotion::from_clip(&c);
    let n = m.states.len();
    // At frame instants the state is the frame's, by the function the simulator uses.
    for (k, f) in c.frames.iter().enumerate() {
        let (a, b) = (m.state_at(k as f32).amp_state(), f.amp_state());
        assert!(
            a.iter().zip(&b).all(|(x, y)| (x - y).abs() < 1e-6),
            "frame {k}"
        );
    }
    let mid = m.state_at(4.5);
    for j in 0..18 {
        let expected = 0.5 * (c.frames[4].joint_pos_rad[j] + c.frames[5].joint_pos_rad[j]);
        assert!((mid.q_rad[j] - expected).abs() < 1e-6);
    }
    // A periodic clip: between the last frame and the first.
    let wrap = m.state_at(n as f32 - 0.5);
    for j in 0..18 {
        let expected = 0.5 * (c.frames[n - 1].joint_pos_rad[j] + c.frames[0].joint_pos_rad[j]);
        assert!((wrap.q_rad[j] - expected).abs() < 1e-6);
    }
    assert_eq!(m.start_range_steps(), n as f32);
}

#[test]
fn tracked_states_are_the_simulator_performing_the_clips() {
    let dir = committed_dir();
    let tracked = MotionDataset::load(&dir, PriorStates::Tracked, true).unwrap();
    let optimized = MotionDataset::load(&dir, PriorStates::Optimized, true).unwrap();
    assert_eq!(tracked.motions().len(), optimized.motions().len());
    let forward = tracked
        .motions()
        .iter()
        .find(|m| m.name == "forward_0.3")
        .unwrap();
    // Four recorded cycles after the warm-up, not wrapping.
    assert_eq!(forward.states.len(), 4 * 30);
    assert!(!forward.wrap);
    let mean = |m: &ReferenceMotion, f: &dyn Fn(&host_sim::reference::ReferenceState) -> f32| {
        m.states.iter().map(f).sum::<f32>() / m.states.len() as f32
    };
    let planned = optimized
        .motions()
        .iter()
        .find(|m| m.name == "forward_0.3")
        .unwrap();
    // The robot under its drives walks lower than the plan, and near the commanded speed.
    let (h_sim, h_plan) = (
        mean(forward, &|s| s.base_height_m),
        mean(planned, &|s| s.base_height_m),
    );
    assert!(
        h_sim < h_plan - 0.002,
        "tracked {h_sim} m, planned {h_plan} m"
    );
    let v = mean(forward, &|s| s.lin_vel_base_m_s[0]);
    assert!((v - 0.3).abs() < 0.05, "{v} m/s");
    // Reference states for initialization: every state of every motion.
    assert_eq!(
        tracked.reference_states().len(),
        tracked
            .motions()
            .iter()
            .map(|m| m.states.len())
            .sum::<usize>()
    );
    // Each carries its motion's command: the forward clip's states ask for what the
    // simulator measured it doing.
    let starts = tracked.reference_states();
    let first_forward: usize = tracked
        .motions()
        .iter()
        .take_while(|m| m.name != "forward_0.3")
        .map(|m| m.states.len())
        .sum();
    assert_eq!(starts[first_forward].state, forward.states[0]);
    assert_eq!(starts[first_forward].command, forward.command);
    assert!(
        (forward.command[0] - 0.3).abs() < 0.05,
        "{:?}",
        forward.command
    );
}

#[test]
fn committed_dataset_covers_the_training_commands_and_gaps_are_refused() {
    let data = MotionDataset::load_dir(&committed_dir()).unwrap();
    // The presets' command box, standing included.
    data.check_command_coverage([[-0.4, 0.5], [-0.2, 0.2], [-0.5, 0.5]], 0.1)
        .unwrap();
    // Without the clips that step in place or go at 0.5 m/s, those commands are gaps.
    let no_zero: Vec<MotionClip> = data
        .clips()
        .iter()
        .filter(|c| c.name != "in_place" && c.name != "forward_0.1")
        .cloned()
        .collect();
    let mut partial = MotionDataset::new(no_zero);
    let err = partial
        .check_command_coverage([[0.0, 0.0], [0.0, 0.0], [0.0, 0.0]], 0.1)
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("(vx 0.00 m/s, vy 0.00 m/s, wz 0.00 rad/s)"),
        "{err}"
    );
    let slow: Vec<MotionClip> = data
        .clips()
        .iter()
        .filter(|c| c.command[0] <= 0.3)
        .cloned()
        .collect();
    partial = MotionDataset::new(slow);
    let err = partial
        .check_command_coverage([[-0.4, 0.5], [-0.2, 0.2], [-0.5, 0.5]], 0.0)
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("no clip within")
            && err.contains("vx 0.35 m/s")
            && err.contains("[sim.commands]"),
        "{err}"
    );
    partial
        .check_command_coverage([[-0.4, 0.3], [-0.2, 0.2], [-0.5, 0.5]], 0.0)
        .unwrap();
}

#[test]
fn clip_and_simulator_compute_the_same_amp_state() {
    let c = clip("turn", 0.3, 0.0, 0.4);
    let states = c.amp_states();
    for (k, f) in c.frames.iter().enumerate() {
        // The simulator's state for the same instant, velocities in the world frame.
        let s = RobotState {
            base_pos_world_m: f.base_pos_world_m,
            base_quat_xyzw: f.base_quat_xyzw,
            base_lin_vel_world_m_s: rotate(f.base_quat_xyzw, f.lin_vel_base_m_s),
            base_ang_vel_world_rad_s: rotate(f.base_quat_xyzw, f.ang_vel_base_rad_s),
            q_rad: f.joint_pos_rad,
            qdot_rad_s: f.joint_vel_rad_s,
        };
        let sim = sim_amp_state(&s);
        for i in 0..sim.len() {
            assert!((sim[i] - states[k][i]).abs() < 1e-5, "frame {k} entry {i}");
        }
    }
}

fn robot() -> RobotWorld {
    let model =
        host_sim::urdf_model::UrdfModel::load(&host_sim::urdf_model::default_urdf_path()).unwrap();
    let ground = host_sim::terrain::Terrain::generate(&Default::default()).collider();
    RobotWorld::new(&model, ground, 1).unwrap()
}

#[test]
fn every_shipped_clip_walks_at_its_command_in_the_simulator() {
    // The flat-ground and ablation presets' priors. (The plain set `assets/priors`, which
    // `rough-tripod.toml` reads, has five combined turning clips that turn 25-30 % faster
    // than commanded in this replay and 21-22 % in MuJoCo's: assets/priors/README.md; the
    // climbing set `assets/priors-climb` four, its README says so.)
    let data = MotionDataset::load_dir(&committed_dir().join("../priors-sync")).unwrap();
    let cfg = ReplayConfig::default();
    for c in data.clips() {
        let r = replay_clip(&mut robot(), c, &cfg);
        assert!(r.passed, "{}", r.summary());
    }
    // A negative control: frozen joints while the clip claims 0.4 m/s must fail.
    let mut frozen = clip("frozen", 0.4, 0.0, 0.0);
    let first = frozen.frames[0].clone();
    for f in &mut frozen.frames {
        f.joint_pos_rad = first.joint_pos_rad;
    }
    let r = replay_clip(&mut robot(), &frozen, &cfg);
    assert!(!r.passed, "{}", r.summary());
}

#[test]
fn learned_targets_bring_the_replayed_joints_closer_to_the_clip() {
    let data = MotionDataset::load_dir(&committed_dir()).unwrap();
    let clip = data
        .clips()
        .iter()
        .find(|c| c.name == "forward_0.3")
        .unwrap();
    let plain = replay_clip(&mut robot(), clip, &ReplayConfig::default());
    let cfg = ReplayConfig {
        learning_passes: 2,
        ..ReplayConfig::default()
    };
    let learned = replay_clip(&mut robot(), clip, &cfg);
    let per_pass = &learned.joint_rms_per_pass_rad;
    assert_eq!(per_pass.len(), 3);
    // The first pass is the plain replay; each correction lowers the joint error.
    assert!(
        (per_pass[0] - plain.joint_rms_rad).abs() < 1e-6,
        "{per_pass:?}"
    );
    assert!(per_pass[1] < 0.8 * per_pass[0], "{per_pass:?}");
    assert!(per_pass[2] < per_pass[1], "{per_pass:?}");
    assert_eq!(learned.joint_rms_rad, per_pass[2]);
    // The base walks closer to the clip's height than when the drives sag.
    assert!(
        (learned.mean_height_m - learned.clip_height_m).abs()
            < (plain.mean_height_m - plain.clip_height_m).abs(),
        "{} / {}",
        plain.summary(),
        learned.summary()
    );
}

fn committed_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets/priors")
}

#[test]
fn committed_dataset_is_complete_and_tripod() {
    let data = MotionDataset::load_dir(&committed_dir()).unwrap();
    assert!(data.duration_s() >= 8.6, "{} s", data.duration_s());
    let cmds: Vec<[f32; 3]> = data.clips().iter().map(|c| c.command).collect();
    let has = |f: &dyn Fn(&[f32; 3]) -> bool| cmds.iter().filter(|c| f(c)).count();
    assert!(
        has(&|c| c[0] > 0.0 && c[1] == 0.0 && c[2] == 0.0) >= 2,
        "forward at two speeds"
    );
    assert!(
        has(&|c| c[0] < 0.0 && c[1] == 0.0 && c[2] == 0.0) >= 2,
        "backward at two speeds"
    );
    assert!(has(&|c| c[0] == 0.0 && c[1] > 0.0) >= 1 && has(&|c| c[0] == 0.0 && c[1] < 0.0) >= 1);
    assert!(has(&|c| c[0] == 0.0 && c[2] > 0.0) >= 1 && has(&|c| c[0] == 0.0 && c[2] < 0.0) >= 1);
    assert!(has(&|c| c[0] != 0.0 && c[2] != 0.0) >= 1, "forward + turn");
    assert!(has(&|c| c[0] != 0.0 && c[1] != 0.0) >= 1, "diagonal");
    for c in data.clips() {
        let n = c.frames.len();
        for set in [TRIPOD_A, TRIPOD_B] {
            let stance = c
                .frames
                .iter()
                .filter(|f| f.contacts[set[0].index()])
                .count();
            assert!(stance as f64 / n as f64 >= 0.5, "{}: duty factor", c.name);
            for f in &c.frames {
                assert!(set
                    .iter()
                    .all(|l| f.contacts[l.index()] == f.contacts[set[0].index()]));
            }
        }
        // A and B lift off alternately, once each per cycle.
        let lift_offs: Vec<char> = (0..n)
            .flat_map(|k| {
                let (prev, cur) = (&c.frames[(k + n - 1) % n], &c.frames[k]);
                [('A', TRIPOD_A[0]), ('B', TRIPOD_B[0])]
                    .into_iter()
                    .filter(move |(_, l)| prev.contacts[l.index()] && !cur.contacts[l.index()])
                    .map(|(name, _)| name)
            })
            .collect();
        assert_eq!(lift_offs, vec!['A', 'B'], "{}", c.name);
    }
}

#[test]
fn committed_dataset_is_what_the_generator_makes() {
    assert_dataset_is_fresh(
        &committed_dir(),
        &GeneratorConfig::default(),
        "hexapod priors --out assets/priors",
    );
}

#[test]
fn committed_climbing_dataset_is_what_the_generator_makes() {
    let cfg = GeneratorConfig {
        swing_clearance_m: 0.14,
        ..GeneratorConfig::default()
    };
    let dir = committed_dir().join("../priors-climb");
    assert_dataset_is_fresh(
        &dir,
        &cfg,
        "hexapod priors --out assets/priors-climb --swing-clearance-m 0.14",
    );
}

/// The settings of `assets/priors-sync`: duty factor 0.5, feet meeting and leaving the
/// ground at 0.2 m/s, paths leading the schedule by two frames.
fn sync_config() -> GeneratorConfig {
    GeneratorConfig {
        swing_frames: 15,
        swing_contact_speed_m_s: 0.2,
        swing_lead_s: 0.04,
        ..GeneratorConfig::default()
    }
}

#[test]
fn committed_synchronized_dataset_is_what_the_generator_makes() {
    assert_dataset_is_fresh(
        &committed_dir().join("../priors-sync"),
        &sync_config(),
        "hexapod priors --out assets/priors-sync --swing-frames 15 --swing-contact-speed-m-s 0.2 --swing-lead-s 0.04",
    );
}

#[test]
fn a_leading_swing_makes_the_simulated_tripods_land_and_lift_together() {
    // Under the drives a loaded foot stays down until its leg unloads and a swinging foot
    // meets the sagging body's ground early: with the plain min-jerk swing the robot spends
    // a quarter of its steps between tripods, with the lead and contact speed few.
    let cmd = GaitCommand::new("forward_0.3", 0.3, 0.0, 0.0);
    let plain = generate_clip(&cmd, &GeneratorConfig::default()).unwrap().0;
    let sync = generate_clip(&cmd, &sync_config()).unwrap().0;
    let cfg = ReplayConfig::default();
    let (plain, sync) = (
        replay_clip(&mut robot(), &plain, &cfg),
        replay_clip(&mut robot(), &sync, &cfg),
    );
    assert!(
        plain.passed && sync.passed,
        "{}\n{}",
        plain.summary(),
        sync.summary()
    );
    assert!(plain.tripod_score < 0.8, "{}", plain.summary());
    assert!(sync.tripod_score >= 0.85, "{}", sync.summary());
    // The reference still tracks its command at least as well.
    assert!(
        sync.lin_error_m_s <= plain.lin_error_m_s + 0.01,
        "{}",
        sync.summary()
    );
}

fn assert_dataset_is_fresh(dir: &std::path::Path, cfg: &GeneratorConfig, regenerate: &str) {
    for cmd in default_commands() {
        let fresh = generate_clip(&cmd, cfg).unwrap().0;
        let stored = MotionClip::load(&dir.join(format!("{}.json", cmd.name))).unwrap();
        assert_eq!(fresh.frames.len(), stored.frames.len(), "{}", cmd.name);
        for (k, (a, b)) in fresh.frames.iter().zip(&stored.frames).enumerate() {
            for (i, (x, y)) in a.to_row().iter().zip(b.to_row().iter()).enumerate() {
                assert!(
                    (x - y).abs() < 1e-4,
                    "{}: frame {k} {}: stale dataset, run `{regenerate}`",
                    cmd.name,
                    super::frame::field_name(i)
                );
            }
        }
    }
}

#[test]
fn a_lifted_base_stands_higher_and_folds_the_thigh_less_for_the_same_swing() {
    let cmd = GaitCommand::new("forward_0.3", 0.3, 0.0, 0.0);
    let make = |base_lift_m: f64| {
        let mut cfg = sync_config();
        cfg.swing_clearance_m = 0.20;
        cfg.qp.base_lift_m = base_lift_m;
        generate_clip(&cmd, &cfg).unwrap().0
    };
    let (plain, lifted) = (make(0.0), make(0.03));
    let mean_height = |c: &MotionClip| {
        c.frames.iter().map(|f| f.base_height_m()).sum::<f32>() / c.frames.len() as f32
    };
    let lift = mean_height(&lifted) - mean_height(&plain);
    assert!((lift - 0.03).abs() < 2e-3, "base lifted by {lift} m");
    // Thigh angle: 0 horizontal, negative folds the knee up (the joint's limit is -0.80 rad).
    let highest_thigh = |c: &MotionClip| {
        c.frames
            .iter()
            .flat_map(|f| Leg::ALL.map(|leg| f.joint_pos_rad[joint_index(leg, Joint::Thigh)]))
            .fold(f32::INFINITY, f32::min)
    };
    assert!(
        highest_thigh(&lifted) > highest_thigh(&plain) + 0.05,
        "thigh at the apex: lifted {} rad, plain {} rad",
        highest_thigh(&lifted),
        highest_thigh(&plain)
    );
    let lift_of = |c: &MotionClip| c.metadata.as_ref().map(|m| m.base_lift_m);
    assert_eq!(lift_of(&lifted), Some(0.03));
    assert_eq!(lift_of(&plain), Some(0.0));
    // Unlifted clips are written as before (no `base_lift_m` key).
    assert!(!plain.to_json().contains("base_lift_m"));
    assert!(lifted.to_json().contains("\"base_lift_m\":0.03"));
}
