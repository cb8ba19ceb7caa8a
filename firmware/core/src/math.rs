//! The float functions of the control path (attitude filter, kinematics, input
//! quantization), behind one trait so that implementations can be measured against each
//! other on the target (`firmware/qemu-bench`) and on recorded inputs.
//!
//! The core uses [`Libm`]: the `libm` crate is pure Rust and (nearly) correctly rounded, so
//! the host and the Cortex-M7 compute the same bits. nalgebra's own float functions are not
//! used on these paths: on the host they resolve to std (the system's libm), on the target
//! to `libm`, and could differ in the last bit. `docs/decisions/0001-firmware-math-crates.md`
//! has the measurements behind the choice (micromath's approximations, implemented as a
//! [`FloatFns`] in `tests/math_backends.rs` and `firmware/qemu-bench`, and the FPU's
//! `vsqrt.f32`).

/// The float functions the control path calls.
pub trait FloatFns {
    /// Square root.
    fn sqrt(x: f32) -> f32;
    /// Four-quadrant arctangent of `y / x`.
    fn atan2(y: f32, x: f32) -> f32;
    /// Sine.
    fn sin(x: f32) -> f32;
    /// Cosine.
    fn cos(x: f32) -> f32;
    /// Arccosine.
    fn acos(x: f32) -> f32;
    /// Round half away from zero.
    fn round(x: f32) -> f32;
}

/// The `libm` crate: what the core uses.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Libm;

impl FloatFns for Libm {
    #[inline]
    fn sqrt(x: f32) -> f32 {
        libm::sqrtf(x)
    }
    #[inline]
    fn atan2(y: f32, x: f32) -> f32 {
        libm::atan2f(y, x)
    }
    #[inline]
    fn sin(x: f32) -> f32 {
        libm::sinf(x)
    }
    #[inline]
    fn cos(x: f32) -> f32 {
        libm::cosf(x)
    }
    #[inline]
    fn acos(x: f32) -> f32 {
        libm::acosf(x)
    }
    #[inline]
    fn round(x: f32) -> f32 {
        libm::roundf(x)
    }
}

/// `libm` with the square root on the FPU (`vsqrt.f32`, IEEE 754 correctly rounded like
/// `libm::sqrtf`, so the same bits) when built for an Arm target with a hardware FPU;
/// plain [`Libm`] elsewhere.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LibmFpuSqrt;

impl FloatFns for LibmFpuSqrt {
    #[inline]
    fn sqrt(x: f32) -> f32 {
        #[cfg(all(target_arch = "arm", target_abi = "eabihf"))]
        {
            let bits: u32;
            // SAFETY: s15 is saved and restored around its use; the value goes in and out
            // through core registers (the `sreg` operand class needs the unstable `vfp2`
            // target feature). No memory is touched but the two stack words.
            unsafe {
                core::arch::asm!(
                    "vpush {{s15}}",
                    "vmov s15, {x}",
                    "vsqrt.f32 s15, s15",
                    "vmov {y}, s15",
                    "vpop {{s15}}",
                    x = in(reg) x.to_bits(),
                    y = lateout(reg) bits,
                    options(pure, nomem),
                );
            }
            f32::from_bits(bits)
        }
        #[cfg(not(all(target_arch = "arm", target_abi = "eabihf")))]
        {
            libm::sqrtf(x)
        }
    }
    #[inline]
    fn atan2(y: f32, x: f32) -> f32 {
        Libm::atan2(y, x)
    }
    #[inline]
    fn sin(x: f32) -> f32 {
        Libm::sin(x)
    }
    #[inline]
    fn cos(x: f32) -> f32 {
        Libm::cos(x)
    }
    #[inline]
    fn acos(x: f32) -> f32 {
        Libm::acos(x)
    }
    #[inline]
    fn round(x: f32) -> f32 {
        Libm::round(x)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fpu_sqrt_falls_back_to_libm_on_the_host() {
        for x in [0.0f32, 1e-30, 0.5, 2.0, 96.17, 1e30] {
            assert_eq!(LibmFpuSqrt::sqrt(x).to_bits(), Libm::sqrt(x).to_bits());
        }
    }

    #[test]
    fn the_host_computes_the_committed_attitude_bits() {
        let f = bench::attitude_run::<Libm>();
        let bits = bench::state_bits::<Libm>(&f);
        assert_eq!(bits, bench::EXPECTED_LIBM_BITS, "{bits:#010x?} {f:?}");
        // The run is a real attitude: rolled and pitched by at most 0.22 rad.
        assert!(
            f.tilt_rad() > 0.01 && f.tilt_rad() < 0.25,
            "{}",
            f.tilt_rad()
        );
    }
}

/// A deterministic IMU sequence and the filter state it leads to, for timing the float
/// functions on the target (`firmware/qemu-bench`) and checking that host and target
/// compute the same bits.
pub mod bench {
    use crate::attitude::{AttitudeConfig, AttitudeFilter, GRAVITY_M_S2};
    use nalgebra::Vector3;

    /// IMU sample period of the firmware (1 kHz), s.
    pub const IMU_DT_S: f32 = 0.001;
    /// IMU samples per 20 ms control period.
    pub const SAMPLES_PER_PERIOD: usize = 20;
    /// Samples of the bit-exactness run (2 s).
    pub const CHECK_SAMPLES: u32 = 2000;

    /// The base rocking (roll 0.2 rad at 0.8 Hz, pitch 0.1 rad at 1.3 Hz) as the IMU sees
    /// it at sample `k`: gyro (rad/s, with a bias and a small ripple) and specific force
    /// (m/s^2, with a vertical bounce). Small-angle kinematics; the exact motion does not
    /// matter, only that it is the same on every target.
    pub fn imu_sample(k: u32) -> (Vector3<f32>, Vector3<f32>) {
        let t = k as f32 * IMU_DT_S;
        let (w_r, w_p) = (
            2.0 * core::f32::consts::PI * 0.8,
            2.0 * core::f32::consts::PI * 1.3,
        );
        let roll = 0.2 * libm::sinf(w_r * t);
        let pitch = 0.1 * libm::sinf(w_p * t);
        let ripple = 0.01 * libm::sinf(2.0 * core::f32::consts::PI * 37.0 * t);
        let gyro = Vector3::new(
            0.2 * w_r * libm::cosf(w_r * t) + 0.003 + ripple,
            0.1 * w_p * libm::cosf(w_p * t) - 0.002,
            0.001 - ripple,
        );
        let bounce = 1.0 + 0.05 * libm::sinf(2.0 * core::f32::consts::PI * 4.0 * t);
        let (sr, cr) = (libm::sinf(roll), libm::cosf(roll));
        let (sp, cp) = (libm::sinf(pitch), libm::cosf(pitch));
        let accel = Vector3::new(-sp, sr * cp, cr * cp) * (GRAVITY_M_S2 * bounce);
        (gyro, accel)
    }

    /// The filter after [`CHECK_SAMPLES`] samples of [`imu_sample`] with backend `F`.
    pub fn attitude_run<F: super::FloatFns>() -> AttitudeFilter {
        let mut f = AttitudeFilter::new(AttitudeConfig::default());
        for k in 0..CHECK_SAMPLES {
            let (gyro, accel) = imu_sample(k);
            f.update_with::<F>(&gyro, &accel, IMU_DT_S);
        }
        f
    }

    /// The bits of the quaternion (w, x, y, z) and the tilt after [`attitude_run`] with
    /// [`super::Libm`], as the host computes them (checked by a test here and by
    /// `firmware/qemu-bench` on the Cortex-M7).
    pub const EXPECTED_LIBM_BITS: [u32; 5] =
        [0x3f7f73df, 0xbd6d0976, 0xbcf8a874, 0x3a9ea571, 0x3e05ed8a];

    /// [`EXPECTED_LIBM_BITS`]'s layout of a filter's state.
    pub fn state_bits<F: super::FloatFns>(f: &AttitudeFilter) -> [u32; 5] {
        let q = f.orientation();
        [q.w, q.i, q.j, q.k, f.tilt_rad_with::<F>()].map(f32::to_bits)
    }
}
