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

#[test]
fn walking_down_the_course_stairs_lowers_the_ground_under_the_robot() {
    let s = scenario("stairs_down_13cm_generated_policy.toml");
    let sil = s.run().unwrap_or_else(|e| panic!("{e}"));
    let p = sil.plant();
    let [x, y, z] = p.state().base_pos_world_m;
    let ground_drop_m =
        p.ground.height_at_m(p.start_pos_m[0], p.start_pos_m[1]) - p.ground.height_at_m(x, y);
    // 2 m along the course is 1 m past the first edge: at least two 13 cm risers down.
    assert!(
        ground_drop_m >= 0.25,
        "the ground under the base fell {ground_drop_m} m"
    );
    assert!(
        p.start_pos_m[2] - z >= 0.2,
        "the base fell only {} m",
        p.start_pos_m[2] - z
    );
}

#[test]
fn climbing_the_course_stairs_raises_the_ground_under_the_robot() {
    let s = scenario("stairs_up_13cm_generated_policy.toml");
    let sil = s.run().unwrap_or_else(|e| panic!("{e}"));
    let p = sil.plant();
    let [x, y, z] = p.state().base_pos_world_m;
    let ground_rise_m =
        p.ground.height_at_m(x, y) - p.ground.height_at_m(p.start_pos_m[0], p.start_pos_m[1]);
    // 2 m along the course is 1 m past the first edge: at least two 13 cm risers up.
    assert!(
        ground_rise_m >= 0.25,
        "the ground under the base rose {ground_rise_m} m"
    );
    assert!(
        z - p.start_pos_m[2] >= 0.2,
        "the base rose only {} m",
        z - p.start_pos_m[2]
    );
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
