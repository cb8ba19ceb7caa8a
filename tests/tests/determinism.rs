//! A SIL run is a function of its seed: the same seed gives the same CAN traffic and the
//! same motion, bit for bit; another seed changes the noise (IMU) and so the motion.

use hexapod_core::controller::ZeroPolicy;
use sil_tests::sil::{generated_policy, Sil};

fn run(seed: u64) -> (String, Vec<[f32; 3]>) {
    let mut sil = Sil::new(seed).unwrap();
    sil.h.rig.record();
    sil.stand_up().expect("stands up");
    sil.run(0.2, &mut ZeroPolicy);
    let mut policy = generated_policy().expect("valid generated policy");
    sil.h.rc.set_sticks(0.6, 0.0, 0.2);
    sil.run(1.0, &mut policy);
    let positions = sil
        .plant()
        .trace
        .samples
        .iter()
        .map(|s| s.base_pos_world_m)
        .collect();
    (sil.h.rig.candump(), positions)
}

#[test]
fn the_same_seed_gives_the_same_run() {
    let a = run(71);
    let b = run(71);
    assert!(a.0 == b.0, "CAN traffic differs");
    assert!(a.1 == b.1, "motion differs");
    let c = run(72);
    assert!(a.1 != c.1, "the seed does not reach the run");
}
