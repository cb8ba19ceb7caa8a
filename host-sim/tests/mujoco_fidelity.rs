//! Fidelity against MuJoCo on the same URDF, dt and drive law: standing base height within
//! 1 cm, standing joint torques within 10 %, base displacement under the scripted tripod gait
//! within 20 %. Needs `python3` with `mujoco` (installed by `.ci/run`); on CI a missing peer
//! fails the test, elsewhere it is skipped with a message.

use host_sim::peer::{mujoco_available, rapier_fidelity, run_mujoco};

#[test]
fn rapier_agrees_with_mujoco() {
    if !mujoco_available() {
        assert!(
            std::env::var("CI").is_err(),
            "CI must install the MuJoCo peer (pip install mujoco)"
        );
        eprintln!("skipped: python3 -c 'import mujoco' fails; pip install mujoco numpy");
        return;
    }
    let ours = rapier_fidelity().unwrap();
    let theirs = run_mujoco(0, 0).unwrap();
    eprintln!("rapier: {ours:?}");
    eprintln!("mujoco: {theirs:?}");
    let dh = (ours.stand_height_m - theirs.stand_height_m).abs();
    assert!(
        dh < 0.01,
        "standing height: rapier {} vs MuJoCo {}",
        ours.stand_height_m,
        theirs.stand_height_m
    );
    let diff: f32 = ours
        .stand_torque_nm
        .iter()
        .zip(&theirs.stand_torque_nm)
        .map(|(a, b)| (a - b).powi(2))
        .sum::<f32>()
        .sqrt();
    let norm: f32 = theirs
        .stand_torque_nm
        .iter()
        .map(|b| b * b)
        .sum::<f32>()
        .sqrt();
    assert!(
        diff / norm < 0.10,
        "standing torques differ by {:.1} %",
        100.0 * diff / norm
    );
    let d_ours = ours.walk_displacement_m[0].hypot(ours.walk_displacement_m[1]);
    let d_theirs = theirs.walk_displacement_m[0].hypot(theirs.walk_displacement_m[1]);
    eprintln!(
        "height {:.4} vs {:.4} m; torques differ by {:.1} %; gait {:.3} vs {:.3} m ({:.1} %)",
        ours.stand_height_m,
        theirs.stand_height_m,
        100.0 * diff / norm,
        d_ours,
        d_theirs,
        100.0 * (d_ours - d_theirs).abs() / d_theirs
    );
    assert!(
        (d_ours - d_theirs).abs() / d_theirs < 0.20,
        "gait displacement: rapier {d_ours} m vs MuJoCo {d_theirs} m"
    );
}
