//! The evaluation course and spawn poses: riser heights and slope angles read back through
//! the terrain's height lookup (what the observations and the base height use) and the
//! collider, and robots spawned at a pose start there, facing the given way, and stand.

use hexapod_core::robot::NUM_JOINTS;
use host_sim::config::{EnvConfig, FrictionCombine};
use host_sim::course::{Course, Feature, FEATURE_LENGTH_M, TREAD_M};
use host_sim::env::{HexapodEnv, SpawnPose};
use host_sim::frames::yaw_rad;
use host_sim::vec_env::VecEnv;
use rapier3d::parry::query::Ray;
use rapier3d::prelude::Vector;

const STEPS_CM: [f32; 8] = [3.0, 5.0, 8.0, 10.0, 13.0, 15.0, 17.0, 20.0];
const SLOPES_DEG: [f32; 6] = [5.0, 10.0, 15.0, 20.0, 25.0, 30.0];

fn paper_features() -> Vec<Feature> {
    let mut f = Vec::new();
    for cm in STEPS_CM {
        f.push(Feature::StairsUp {
            step_height_m: cm / 100.0,
        });
        f.push(Feature::StairsDown {
            step_height_m: cm / 100.0,
        });
    }
    for deg in SLOPES_DEG {
        f.push(Feature::SlopeUp { slope_deg: deg });
        f.push(Feature::SlopeDown { slope_deg: deg });
    }
    f.push(Feature::Step { height_m: 0.15 });
    f
}

#[test]
fn risers_and_slopes_are_exact_in_the_height_lookup() {
    let course = Course::new(&paper_features());
    let t = course.terrain();
    let edge = course.feature_edge_x_m();
    for (lane, feature) in course.features().iter().enumerate() {
        let y = course.lane_center_y_m(lane);
        let h = |along: f32| t.height_at_m(edge + along, y);
        // The run-up is level and at zero.
        for k in 0..20 {
            assert_eq!(
                t.height_at_m(
                    course.start_pose(lane).position_m[0] - 0.9 + k as f32 * 0.09,
                    y
                ),
                0.0
            );
        }
        match *feature {
            Feature::StairsUp { step_height_m } | Feature::StairsDown { step_height_m } => {
                let sign = if matches!(feature, Feature::StairsUp { .. }) {
                    1.0
                } else {
                    -1.0
                };
                // Tread centres: k risers climbed (or descended) after k treads.
                let flights = (FEATURE_LENGTH_M / TREAD_M).floor() as usize;
                for k in 1..=flights {
                    let centre = (k as f32 - 0.5) * TREAD_M + 0.025;
                    let want = sign * step_height_m * k as f32;
                    assert!(
                        (h(centre) - want).abs() < 1e-5,
                        "{}: tread {k} at {} m, want {want}",
                        feature.describe(),
                        h(centre)
                    );
                    // The tread is level from its riser's top to the next riser.
                    assert!((h(centre - 0.1) - h(centre + 0.1)).abs() < 1e-6);
                }
                let riser = h(TREAD_M + 0.1) - h(TREAD_M - 0.1);
                assert!(
                    (riser - sign * step_height_m).abs() < 1e-5,
                    "{}: riser {riser}",
                    feature.describe()
                );
            }
            Feature::SlopeUp { slope_deg } | Feature::SlopeDown { slope_deg } => {
                let sign = if matches!(feature, Feature::SlopeUp { .. }) {
                    1.0
                } else {
                    -1.0
                };
                for (a, b) in [(0.5f32, 1.5f32), (1.13, 3.71), (2.0, 4.9)] {
                    let deg = ((h(b) - h(a)) / (b - a)).atan().to_degrees();
                    assert!(
                        (deg - sign * slope_deg).abs() < 0.01,
                        "{}: {deg} deg",
                        feature.describe()
                    );
                }
                // Level landing after the ramp.
                assert!((h(FEATURE_LENGTH_M + 0.5) - h(FEATURE_LENGTH_M + 2.0)).abs() < 1e-5);
            }
            Feature::Step { height_m } => {
                assert!((h(0.5) - height_m).abs() < 1e-6 && (h(3.0) - height_m).abs() < 1e-6);
            }
            Feature::Flat => {}
        }
    }
}

#[test]
fn collider_surface_is_the_height_lookup_on_the_course() {
    let course = Course::new(&paper_features());
    let t = course.terrain();
    let ground = t.collider();
    let edge = course.feature_edge_x_m();
    for lane in [0usize, 15, 17, 27, 28] {
        let y = course.lane_center_y_m(lane) + 0.0137;
        for k in 0..40 {
            // Off-lattice points on treads and ramps, away from the risers' one-cell ramps.
            let x = edge + 0.1 + k as f32 * 0.1173;
            let along = (x - edge) % TREAD_M;
            if along < 0.06
                && !matches!(
                    course.features()[lane],
                    Feature::SlopeUp { .. } | Feature::SlopeDown { .. }
                )
            {
                continue;
            }
            let ray = Ray::new(
                Vector::new(x, y, 5.0),
                Vector::new(1e-4, 1e-4, -1.0).normalize(),
            );
            let toi = ground
                .shape()
                .cast_ray(ground.position(), &ray, 20.0, true)
                .expect("ray hits the ground");
            let z = 5.0 - toi;
            assert!(
                (z - t.height_at_m(x, y)).abs() < 2e-3,
                "lane {lane} at x {x}: collider {z}, lookup {}",
                t.height_at_m(x, y)
            );
        }
    }
}

#[test]
fn a_finer_course_grid_keeps_the_treads_and_draws_steeper_risers() {
    let features = [
        Feature::StairsUp { step_height_m: 0.2 },
        Feature::SlopeUp { slope_deg: 30.0 },
    ];
    let (coarse, fine) = (Course::new(&features), Course::with_cell(&features, 0.025));
    let edge = coarse.feature_edge_x_m();
    assert_eq!(edge, fine.feature_edge_x_m());
    let at = |c: &Course, lane: usize, along: f32| {
        c.terrain()
            .height_at_m(edge + along, c.lane_center_y_m(lane) + 0.011)
    };
    for k in 0..10 {
        let mid_tread = (k as f32 + 0.5) * TREAD_M;
        assert!(
            (at(&coarse, 0, mid_tread) - at(&fine, 0, mid_tread)).abs() < 1e-5,
            "tread {k}"
        );
        assert!(
            (at(&coarse, 1, mid_tread) - at(&fine, 1, mid_tread)).abs() < 1e-4,
            "ramp {k}"
        );
    }
    // 3.75 cm past the second riser's foot: halfway up the 5 cm grid's ramp (76 deg), already
    // on the tread on the 2.5 cm grid (83 deg).
    let past_riser = TREAD_M + 0.0375;
    assert!((at(&coarse, 0, past_riser) - 0.35).abs() < 1e-4);
    assert!((at(&fine, 0, past_riser) - 0.4).abs() < 1e-4);
}

#[test]
fn robots_start_at_their_spawn_pose_facing_it_and_stand() {
    let features = [
        Feature::StairsUp { step_height_m: 0.2 },
        Feature::SlopeDown { slope_deg: 30.0 },
        Feature::Flat,
    ];
    let course = Course::new(&features);
    let mut cfg = EnvConfig {
        num_envs: 4,
        observation_noise: false,
        curriculum: false,
        ..Default::default()
    };
    cfg.push.enabled = false;
    cfg.randomization.enabled = false;
    let mut env = HexapodEnv::with_terrain(cfg, course.terrain().clone()).unwrap();
    let poses = [
        course.start_pose(0),
        course.start_pose(1),
        course.start_pose(2),
        SpawnPose {
            position_m: [3.0, 9.0],
            yaw_rad: 1.2,
        },
    ];
    for (i, pose) in poses.iter().enumerate() {
        env.set_spawn_pose(i, Some(*pose));
    }
    env.reset();
    for (i, pose) in poses.iter().enumerate() {
        let s = env.robot_state(i);
        assert_eq!(env.spawn_position_m(i), pose.position_m);
        assert!(
            (s.base_pos_world_m[0] - pose.position_m[0]).abs() < 1e-5
                && (s.base_pos_world_m[1] - pose.position_m[1]).abs() < 1e-5
        );
        assert!(
            (yaw_rad(s.base_quat_xyzw) - pose.yaw_rad).abs() < 1e-5,
            "robot {i} heading"
        );
    }
    for step in 0..100 {
        let r = env.step(&vec![0.0; 4 * NUM_JOINTS]);
        assert!(r.dones.iter().all(|d| !d), "a robot fell at step {step}");
    }
    for (i, pose) in poses.iter().enumerate() {
        let s = env.robot_state(i);
        let [x, y] = pose.position_m;
        assert!(
            (s.base_pos_world_m[0] - x).hypot(s.base_pos_world_m[1] - y) < 0.1,
            "robot {i} drifted"
        );
        let ground = env.terrain().height_at_m(x, y);
        assert!(
            (s.base_pos_world_m[2] - ground - 0.30).abs() < 0.03,
            "robot {i} stands at {} m",
            s.base_pos_world_m[2] - ground
        );
    }
}

#[test]
fn a_spawn_pose_moves_the_robot_not_its_random_draws() {
    // Same seed, with and without a pose: the randomized dynamics are the same.
    let course = Course::new(&[Feature::Flat]);
    let cfg = EnvConfig {
        num_envs: 2,
        curriculum: false,
        ..Default::default()
    };
    let mut a = HexapodEnv::with_terrain(cfg.clone(), course.terrain().clone()).unwrap();
    let mut b = HexapodEnv::with_terrain(cfg, course.terrain().clone()).unwrap();
    b.set_spawn_pose(1, Some(course.start_pose(0)));
    a.reseed(0, 7);
    b.reseed(0, 7);
    a.reset();
    b.reset();
    for i in 0..2 {
        assert_eq!(a.total_mass_kg(i), b.total_mass_kg(i));
        assert_eq!(
            a.drive_params(i).motor_strength,
            b.drive_params(i).motor_strength
        );
    }
    // Reseeded slots draw the same robot: slot 0 of a reseeded to slot 1's seed matches.
    let mut c = HexapodEnv::with_terrain(
        EnvConfig {
            num_envs: 2,
            curriculum: false,
            ..Default::default()
        },
        course.terrain().clone(),
    )
    .unwrap();
    c.reseed(1, 7);
    c.reset();
    assert_eq!(c.total_mass_kg(1), a.total_mass_kg(0));
}

/// A robot holding its default pose on the 30 deg ramp, every randomization at its nominal
/// value but the foot friction (combined with the ground's by `combine`); its base x after
/// 1 s (landed) and after 5 s.
fn hold_pose_on_the_30_deg_ramp(foot_friction: f32, combine: FrictionCombine) -> (f32, f32, f32) {
    let course = Course::new(&[Feature::SlopeUp { slope_deg: 30.0 }]);
    let mut cfg = EnvConfig {
        num_envs: 1,
        observation_noise: false,
        curriculum: false,
        ..Default::default()
    };
    cfg.push.enabled = false;
    cfg.foot_friction_combine = combine;
    let r = &mut cfg.randomization;
    r.enabled = true;
    r.stiffness_factor = [1.0, 1.0];
    r.damping_factor = [1.0, 1.0];
    r.initial_joint_pos_factor = [1.0, 1.0];
    r.link_mass_factor = [1.0, 1.0];
    r.payload_kg = [0.0, 0.0];
    r.motor_strength = [1.0, 1.0];
    r.friction = [foot_friction, foot_friction];
    let mut env = HexapodEnv::with_terrain(cfg, course.terrain().clone()).unwrap();
    let on_ramp_x_m = course.feature_edge_x_m() + 1.2;
    env.set_spawn_pose(
        0,
        Some(SpawnPose {
            position_m: [on_ramp_x_m, course.lane_center_y_m(0)],
            yaw_rad: 0.0,
        }),
    );
    env.reset();
    let mut landed_x_m = 0.0;
    for step in 0..250 {
        let r = env.step(&[0.0; NUM_JOINTS]);
        assert!(
            !r.dones[0],
            "fell at step {step} (friction {foot_friction})"
        );
        if step == 49 {
            landed_x_m = env.robot_state(0).base_pos_world_m[0];
        }
    }
    let end_x_m = env.robot_state(0).base_pos_world_m[0];
    (landed_x_m, end_x_m, course.feature_edge_x_m())
}

/// Friction holds a standing robot on a ramp where physics says it should and lets it go
/// where it should not: above tan 30 deg = 0.577 the robot, once landed (it spawns level and
/// drops onto the ramp), stays put; at 0.5 it slides down the 1.2 m to the ramp's foot,
/// where its front legs reach the flat.
#[test]
fn the_30_deg_ramp_holds_a_standing_robot_only_above_tan_30_deg() {
    let (landed, end, _) = hold_pose_on_the_30_deg_ramp(0.7, FrictionCombine::Multiply);
    assert!(
        (end - landed).abs() < 0.005,
        "friction 0.7: slid {:.3} m after landing",
        end - landed
    );
    let (_, end, ramp_start_x_m) = hold_pose_on_the_30_deg_ramp(0.5, FrictionCombine::Multiply);
    assert!(
        end < ramp_start_x_m + 0.3,
        "friction 0.5: base at {end:.2} m, the ramp starts at {ramp_start_x_m:.2} m"
    );
}

/// Averaged with the ground's 1.0 (PhysX's rule), a foot friction of 0.4 meets the ramp at
/// 0.7 and holds the robot; multiplied, the same feet meet it at 0.4 and slide.
#[test]
fn averaged_foot_friction_meets_the_ground_between_the_foots_and_the_grounds() {
    let (landed, end, _) = hold_pose_on_the_30_deg_ramp(0.4, FrictionCombine::Average);
    assert!(
        (end - landed).abs() < 0.005,
        "foot 0.4 averaged: slid {:.3} m after landing",
        end - landed
    );
    let (_, end, ramp_start_x_m) = hold_pose_on_the_30_deg_ramp(0.4, FrictionCombine::Multiply);
    assert!(
        end < ramp_start_x_m + 0.3,
        "foot 0.4 multiplied: base at {end:.2} m, the ramp starts at {ramp_start_x_m:.2} m"
    );
}
