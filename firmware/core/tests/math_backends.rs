//! micromath against libm on the control path's inputs: each function over the range the
//! control path feeds it, and the attitude filter and the leg kinematics end to end
//! (`cargo test -p hexapod-core --test math_backends -- --nocapture` prints the table in
//! docs/decisions/0001-firmware-math-crates.md).

use hexapod_core::attitude::{AttitudeConfig, AttitudeFilter, GRAVITY_M_S2};
use hexapod_core::kinematics;
use hexapod_core::math::{bench, FloatFns, Libm};
use hexapod_core::nalgebra::Vector3;
use hexapod_core::robot::{Leg, Q0_LEG_RAD};

struct Micromath;

impl FloatFns for Micromath {
    fn sqrt(x: f32) -> f32 {
        micromath::F32Ext::sqrt(x)
    }
    fn atan2(y: f32, x: f32) -> f32 {
        micromath::F32Ext::atan2(y, x)
    }
    fn sin(x: f32) -> f32 {
        micromath::F32Ext::sin(x)
    }
    fn cos(x: f32) -> f32 {
        micromath::F32Ext::cos(x)
    }
    fn acos(x: f32) -> f32 {
        micromath::F32Ext::acos(x)
    }
    fn round(x: f32) -> f32 {
        micromath::F32Ext::round(x)
    }
}

/// Largest |micromath - libm| of `f` over `n` points spread evenly over [lo, hi].
fn max_dev(n: u32, lo: f32, hi: f32, f: impl Fn(f32) -> (f32, f32)) -> (f32, f32) {
    let mut worst = (0.0f32, lo);
    for k in 0..=n {
        let x = lo + (hi - lo) * k as f32 / n as f32;
        let (m, l) = f(x);
        let d = (m - l).abs();
        if d > worst.0 {
            worst = (d, x);
        }
    }
    worst
}

#[test]
fn micromath_against_libm() {
    let n = 200_000;
    let g2 = GRAVITY_M_S2 * GRAVITY_M_S2;
    // sqrt: the accelerometer's squared norm within the filter's 30 % gate, and the
    // quaternion's squared norm after one integration step (1 +- 1e-3): relative error.
    let sqrt_accel = max_dev(n, 0.49 * g2, 1.69 * g2, |x| {
        (Micromath::sqrt(x) / Libm::sqrt(x), 1.0)
    });
    let sqrt_quat = max_dev(n, 0.999, 1.001, |x| (Micromath::sqrt(x), Libm::sqrt(x)));
    // atan2 over the circle (the alignment's roll and pitch, the IK's yaw and thigh).
    let atan2 = max_dev(n, -std::f32::consts::PI, std::f32::consts::PI, |a| {
        let (y, x) = (a.sin(), a.cos());
        (Micromath::atan2(y, x), Libm::atan2(y, x))
    });
    let sin = max_dev(n, -3.2, 3.2, |x| (Micromath::sin(x), Libm::sin(x)));
    let cos = max_dev(n, -3.2, 3.2, |x| (Micromath::cos(x), Libm::cos(x)));
    // acos: the tilt, from level (1) to the supervisor's limits and beyond.
    let acos = max_dev(n, -1.0, 1.0, |x| (Micromath::acos(x), Libm::acos(x)));
    // round: the input quantization, x * 2^k over the i16 range.
    let mut round_mismatch = 0u32;
    let mut state = 0x2545_f491u32;
    let m = 1_000_000;
    for _ in 0..m {
        state ^= state << 13;
        state ^= state >> 17;
        state ^= state << 5;
        let x = (state as f32 / u32::MAX as f32 - 0.5) * 65536.0;
        let x = if state & 1 == 0 { x } else { x / 4096.0 };
        // What the quantization keeps: the integer (micromath's -0.0 is +0.0, the same i16).
        if Micromath::round(x) as i32 != Libm::round(x) as i32 {
            round_mismatch += 1;
        }
    }
    // Just below a half, x + 0.5 rounds up in f32: micromath gives 1, libm 0.
    let below_half = f32::from_bits(0.5f32.to_bits() - 1);
    assert_eq!(Libm::round(below_half), 0.0);
    assert_eq!(Micromath::round(below_half), 1.0);

    // The attitude filter on the 2 s rocking sequence, and a 60 s one.
    let gravity_dev = |samples: u32| {
        let mut fm = AttitudeFilter::new(AttitudeConfig::default());
        let mut fl = fm;
        let (mut worst_g, mut worst_tilt) = (0.0f32, 0.0f32);
        for k in 0..samples {
            let (g, a) = bench::imu_sample(k);
            fm.update_with::<Micromath>(&g, &a, bench::IMU_DT_S);
            fl.update_with::<Libm>(&g, &a, bench::IMU_DT_S);
            worst_g = worst_g.max((fm.gravity_base() - fl.gravity_base()).amax());
            worst_tilt = worst_tilt.max((fm.tilt_rad_with::<Micromath>() - fl.tilt_rad()).abs());
        }
        (worst_g, worst_tilt)
    };
    let (g2s, tilt2s) = gravity_dev(bench::CHECK_SAMPLES);
    let (g60s, tilt60s) = gravity_dev(60_000);

    // Leg kinematics: forward and inverse over joint offsets of +-0.5 rad.
    let (mut fk_dev, mut ik_dev) = (0.0f32, 0.0f32);
    for leg in Leg::ALL {
        for k in 0..1000 {
            let t = k as f32 / 1000.0;
            let q = Vector3::new(
                Q0_LEG_RAD[0] + 0.5 * (7.0 * t).sin(),
                Q0_LEG_RAD[1] + 0.5 * (5.0 * t).sin(),
                Q0_LEG_RAD[2] + 0.5 * (3.0 * t).sin(),
            );
            let pl = kinematics::foot_position_with::<Libm>(leg, &q);
            let pm = kinematics::foot_position_with::<Micromath>(leg, &q);
            fk_dev = fk_dev.max((pm - pl).amax());
            if let (Ok(ql), Ok(qm)) = (
                kinematics::inverse_kinematics_with::<Libm>(leg, &pl),
                kinematics::inverse_kinematics_with::<Micromath>(leg, &pl),
            ) {
                ik_dev = ik_dev.max((qm - ql).amax());
            }
        }
    }

    println!("| function / path | input range | max abs deviation, micromath - libm | at |");
    println!("|---|---|---|---|");
    println!(
        "| sqrt (relative) | accelerometer norm^2, 0.7-1.3 g | {:.2e} | {:.3} |",
        sqrt_accel.0, sqrt_accel.1
    );
    println!(
        "| sqrt | quaternion norm^2, 1 +- 1e-3 | {:.2e} | {:.6} |",
        sqrt_quat.0, sqrt_quat.1
    );
    println!(
        "| atan2 | unit circle | {:.2e} rad | angle {:.4} |",
        atan2.0, atan2.1
    );
    println!("| sin | [-3.2, 3.2] | {:.2e} | {:.4} |", sin.0, sin.1);
    println!("| cos | [-3.2, 3.2] | {:.2e} | {:.4} |", cos.0, cos.1);
    println!("| acos | [-1, 1] | {:.2e} rad | {:.4} |", acos.0, acos.1);
    println!("| round | input quantization, 1e6 values | {round_mismatch} of {m} differ | |");
    println!("| attitude filter, projected gravity | 2 s rocking (bench sequence) | {g2s:.2e} | |");
    println!("| attitude filter, tilt | 2 s rocking | {tilt2s:.2e} rad | |");
    println!("| attitude filter, projected gravity | 60 s rocking | {g60s:.2e} | |");
    println!("| attitude filter, tilt | 60 s rocking | {tilt60s:.2e} rad | |");
    println!("| leg FK | 6 legs x 1000 poses | {fk_dev:.2e} m | |");
    println!("| leg IK (from libm's feet) | 6 legs x 1000 poses | {ik_dev:.2e} rad | |");

    // micromath's one-step bit-trick sqrt is off by percent, far beyond libm's rounding.
    assert!(sqrt_accel.0 > 1e-3);
    assert!(g2s > 0.0);
}
