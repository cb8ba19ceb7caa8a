//! Runs every data-driven scenario in `scenarios/*.toml`.

use std::path::Path;

use sil_tests::scenario::Scenario;

#[test]
fn every_scenario_file_passes() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios");
    let mut paths: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .collect();
    paths.sort();
    assert!(paths.len() >= 3, "scenarios missing in {}", dir.display());
    let mut failures = Vec::new();
    for path in &paths {
        let scenario = Scenario::load(path).unwrap_or_else(|e| panic!("{e}"));
        match scenario.run() {
            Ok(sil) => {
                eprintln!(
                    "ok   {}: {} ({:.1} s simulated)",
                    path.file_name().unwrap().to_string_lossy(),
                    scenario.description,
                    sil.time_s()
                );
                for (b, bus) in sil.h.rig.buses.iter().enumerate() {
                    let s = &bus.stats;
                    if let (Some((lat, lat_max)), Some((load, load_max))) =
                        (s.feedback_latency_us(), s.load(usize::MAX))
                    {
                        eprintln!(
                            "     bus {b}: feedback latency mean {lat:.0} us (worst {lat_max:.0}),                              load per cycle mean {:.1} % (worst {:.1} %), {} error frames, {} lost",
                            100.0 * load,
                            100.0 * load_max,
                            s.error_frames,
                            s.lost
                        );
                    }
                }
            }
            Err(e) => failures.push(format!("{}: {e}", path.display())),
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

#[test]
fn a_scenario_with_a_wrong_expectation_fails() {
    let scenario: Scenario = toml::from_str(
        r#"
        description = "stands, but expects to be sitting"
        seed = 1
        [[step]]
        do = "stand_up"
        [[step]]
        do = "expect"
        max_height_m = 0.15
        "#,
    )
    .unwrap();
    let err = scenario.run().err().expect("the expectation fails");
    assert!(err.to_string().contains("base height"), "{err}");
}

#[test]
fn unknown_fields_are_rejected() {
    let r: Result<Scenario, _> = toml::from_str(
        r#"
        description = "typo"
        seed = 1
        [[step]]
        do = "run"
        secs = 1.0
        "#,
    );
    assert!(r.is_err());
}
