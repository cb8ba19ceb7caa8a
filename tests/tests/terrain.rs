//! The SIL rig on host-sim's evaluation course: the ground of a `[ground]` scenario is the
//! course's lane, so the robot that walks it really climbs or descends.

use std::path::Path;

use sil_tests::scenario::Scenario;

fn scenario(name: &str) -> Scenario {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("scenarios")
        .join(name);
    Scenario::load(&path).unwrap_or_else(|e| panic!("{e}"))
}

/// Runs a course scenario; the rise of the ground under the base and of the base itself,
/// from the start to the end (negative: a fall), m.
fn ground_and_base_rise_m(name: &str) -> (f32, f32) {
    let sil = scenario(name).run().unwrap_or_else(|e| panic!("{e}"));
    let p = sil.plant();
    let [x, y, z] = p.state().base_pos_world_m;
    let ground_rise_m =
        p.ground.height_at_m(x, y) - p.ground.height_at_m(p.start_pos_m[0], p.start_pos_m[1]);
    (ground_rise_m, z - p.start_pos_m[2])
}

// 2 m along the course is 1 m past the first edge: at least two 13 cm risers, either way.

#[test]
fn walking_down_the_course_stairs_lowers_the_ground_under_the_robot() {
    let (ground_m, base_m) = ground_and_base_rise_m("stairs_down_13cm_generated_policy.toml");
    assert!(
        ground_m <= -0.25,
        "the ground under the base fell {} m",
        -ground_m
    );
    assert!(base_m <= -0.2, "the base fell only {} m", -base_m);
}

#[test]
fn climbing_the_course_stairs_raises_the_ground_under_the_robot() {
    let (ground_m, base_m) = ground_and_base_rise_m("stairs_up_13cm_generated_policy.toml");
    assert!(
        ground_m >= 0.25,
        "the ground under the base rose {ground_m} m"
    );
    assert!(base_m >= 0.2, "the base rose only {base_m} m");
}

#[test]
fn a_course_scenario_that_asks_for_more_progress_than_walked_fails() {
    let mut s = scenario("slope_down_20deg_generated_policy.toml");
    for step in &mut s.step {
        if let sil_tests::scenario::Step::Expect { min_progress_m, .. } = step {
            *min_progress_m = Some(20.0);
        }
    }
    let e = s
        .run()
        .err()
        .expect("20 m in 10 s is out of reach")
        .to_string();
    assert!(e.contains("along the course"), "{e}");
}
