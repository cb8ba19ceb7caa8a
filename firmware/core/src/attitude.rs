//! A Mahony complementary filter (f32, no heap): gyro integration corrected toward the
//! accelerometer's gravity direction. Gives the projected gravity of the observation and
//! the tilt the supervisor watches; yaw drifts and is not needed.

use crate::math::{FloatFns, Libm};
use nalgebra::{Quaternion, UnitQuaternion, Vector3};

/// Standard gravity, m/s^2.
pub const GRAVITY_M_S2: f32 = 9.806_65;

/// Filter gains.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct AttitudeConfig {
    /// Proportional gain of the accelerometer correction, rad/s.
    pub kp: f32,
    /// Integral gain (gyro bias estimation), rad/s^2.
    pub ki: f32,
    /// Accelerometer readings whose norm is off by more than this fraction of g are not
    /// trusted (impacts, strong accelerations).
    pub accel_tolerance: f32,
}

impl Default for AttitudeConfig {
    fn default() -> Self {
        Self {
            kp: 2.0,
            ki: 0.05,
            accel_tolerance: 0.3,
        }
    }
}

/// The filter state: orientation of the base in the world (base -> world).
///
/// A Mahony filter written on nalgebra's types rather than taken from the `ahrs` crate:
/// `ahrs` 0.8 depends on nalgebra 0.34 (rapier, and so this crate, use 0.35), integrates
/// with a fixed sample period (the IMU's samples arrive with their own timestamps), has
/// no accelerometer gating and starts from identity instead of the first reading
/// (docs/decisions/0001-firmware-math-crates.md).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct AttitudeFilter {
    config: AttitudeConfig,
    q: UnitQuaternion<f32>,
    bias_integral: Vector3<f32>,
    initialized: bool,
}

/// The world's up axis in the base frame for a base -> world orientation: the third row
/// of its rotation matrix (`R^T e_z`), without the rest of the matrix.
pub fn up_in_base(q: &UnitQuaternion<f32>) -> Vector3<f32> {
    let (w, x, y, z) = (q.w, q.i, q.j, q.k);
    Vector3::new(
        2.0 * (x * z - w * y),
        2.0 * (w * x + y * z),
        w * w - x * x - y * y + z * z,
    )
}

/// `x^2 + y^2 + z^2`, summed in that order.
fn norm_squared(v: &Vector3<f32>) -> f32 {
    v.x * v.x + v.y * v.y + v.z * v.z
}

impl AttitudeFilter {
    /// A filter that initialises from its first accelerometer sample.
    pub const fn new(config: AttitudeConfig) -> Self {
        Self {
            config,
            q: UnitQuaternion::new_unchecked(Quaternion::new(1.0, 0.0, 0.0, 0.0)),
            bias_integral: Vector3::new(0.0, 0.0, 0.0),
            initialized: false,
        }
    }

    /// Forgets the state.
    pub fn reset(&mut self) {
        *self = Self::new(self.config);
    }

    /// True once a sample has been accepted.
    pub fn is_initialized(&self) -> bool {
        self.initialized
    }

    /// The estimated orientation, base -> world (yaw drifts).
    pub fn orientation(&self) -> &UnitQuaternion<f32> {
        &self.q
    }

    /// The estimated gyro bias correction (the integral term), rad/s.
    pub fn bias_integral(&self) -> &Vector3<f32> {
        &self.bias_integral
    }

    /// The world's up axis expressed in the base frame.
    pub fn up(&self) -> Vector3<f32> {
        up_in_base(&self.q)
    }

    /// Unit gravity direction in the base frame (-z when level): the observation's
    /// projected gravity.
    pub fn gravity_base(&self) -> Vector3<f32> {
        -self.up()
    }

    /// [`Self::up`] as an array (x, y, z).
    pub fn up_base(&self) -> [f32; 3] {
        self.up().into()
    }

    /// [`Self::gravity_base`] as an array (x, y, z).
    pub fn projected_gravity(&self) -> [f32; 3] {
        self.gravity_base().into()
    }

    /// Angle between the base's z axis and the world's up axis, rad.
    pub fn tilt_rad(&self) -> f32 {
        self.tilt_rad_with::<Libm>()
    }

    /// [`Self::tilt_rad`] with the float functions of `F`.
    pub fn tilt_rad_with<F: FloatFns>(&self) -> f32 {
        F::acos(self.up().z.clamp(-1.0, 1.0))
    }

    /// Updates with a gyro (rad/s) and accelerometer (specific force, m/s^2) sample.
    pub fn update(&mut self, gyro_rad_s: [f32; 3], accel_m_s2: [f32; 3], dt_s: f32) {
        self.update_with::<Libm>(&gyro_rad_s.into(), &accel_m_s2.into(), dt_s);
    }

    /// [`Self::update`] on nalgebra vectors with the float functions of `F`.
    pub fn update_with<F: FloatFns>(
        &mut self,
        gyro_rad_s: &Vector3<f32>,
        accel_m_s2: &Vector3<f32>,
        dt_s: f32,
    ) {
        if !(gyro_rad_s
            .iter()
            .chain(accel_m_s2.iter())
            .all(|v| v.is_finite())
            && dt_s.is_finite())
        {
            return;
        }
        let a_norm = F::sqrt(norm_squared(accel_m_s2));
        let accel_ok = (a_norm - GRAVITY_M_S2).abs() <= self.config.accel_tolerance * GRAVITY_M_S2;
        if !self.initialized {
            if accel_ok {
                self.align::<F>(accel_m_s2, a_norm);
            }
            return;
        }
        let mut omega = *gyro_rad_s;
        if accel_ok {
            let a = accel_m_s2 / a_norm;
            let e = a.cross(&self.up());
            self.bias_integral += e * self.config.ki * dt_s;
            omega += e * self.config.kp + self.bias_integral;
        }
        // q' = q + dt/2 q (0, omega), renormalized. Written out in (w, x, y, z) order
        // rather than with nalgebra's quaternion product and norm (storage order x, y, z,
        // w), so the results keep their bits from the array version of this filter.
        let (w, x, y, z) = (self.q.w, self.q.i, self.q.j, self.q.k);
        let h = 0.5 * dt_s;
        let (ox, oy, oz) = (omega.x, omega.y, omega.z);
        let q = [
            w + h * (-x * ox - y * oy - z * oz),
            x + h * (w * ox + y * oz - z * oy),
            y + h * (w * oy - x * oz + z * ox),
            z + h * (w * oz + x * oy - y * ox),
        ];
        let n = F::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
        if n > 0.0 && n.is_finite() {
            self.q = UnitQuaternion::new_unchecked(Quaternion::new(
                q[0] / n,
                q[1] / n,
                q[2] / n,
                q[3] / n,
            ));
        }
    }

    /// Roll and pitch from a resting accelerometer reading.
    fn align<F: FloatFns>(&mut self, a: &Vector3<f32>, a_norm: f32) {
        let a = a / a_norm;
        let roll = F::atan2(a.y, a.z);
        let pitch = F::atan2(-a.x, F::sqrt(a.y * a.y + a.z * a.z));
        let (sr, cr) = (F::sin(roll / 2.0), F::cos(roll / 2.0));
        let (sp, cp) = (F::sin(pitch / 2.0), F::cos(pitch / 2.0));
        self.q =
            UnitQuaternion::new_unchecked(Quaternion::new(cr * cp, sr * cp, cr * sp, -sr * sp));
        self.initialized = true;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Specific force of a base rolled by `roll` about x: up = (0, sin r, cos r) in base.
    fn accel_rolled(roll: f32) -> [f32; 3] {
        [0.0, GRAVITY_M_S2 * roll.sin(), GRAVITY_M_S2 * roll.cos()]
    }

    #[test]
    fn aligns_and_reports_projected_gravity() {
        let mut f = AttitudeFilter::new(AttitudeConfig::default());
        f.update([0.0; 3], [0.0, 0.0, GRAVITY_M_S2], 0.005);
        let g = f.projected_gravity();
        assert!((g[2] + 1.0).abs() < 1e-6 && g[0].abs() < 1e-6, "{g:?}");
        let mut f = AttitudeFilter::new(AttitudeConfig::default());
        f.update([0.0; 3], accel_rolled(0.3), 0.005);
        assert!((f.tilt_rad() - 0.3).abs() < 1e-4);
        assert!(
            (f.up_base()[1] - 0.3f32.sin()).abs() < 1e-4,
            "{:?}",
            f.up_base()
        );
    }

    #[test]
    fn integrates_the_gyro_and_converges_to_the_accelerometer() {
        let mut f = AttitudeFilter::new(AttitudeConfig::default());
        f.update([0.0; 3], accel_rolled(0.0), 0.005);
        // Roll at 0.5 rad/s for 1 s with the accelerometer following the true attitude.
        for k in 1..=200 {
            f.update([0.5, 0.0, 0.0], accel_rolled(0.0025 * k as f32), 0.005);
        }
        assert!((f.tilt_rad() - 0.5).abs() < 0.01, "{}", f.tilt_rad());
        // A gyro bias of 0.05 rad/s is corrected by the accelerometer: tilt error stays small.
        for _ in 0..2000 {
            f.update([0.05, 0.0, 0.0], accel_rolled(0.5), 0.005);
        }
        assert!((f.tilt_rad() - 0.5).abs() < 0.03, "{}", f.tilt_rad());
    }

    #[test]
    fn ignores_non_finite_samples() {
        let mut f = AttitudeFilter::new(AttitudeConfig::default());
        f.update([0.0; 3], [0.0, 0.0, GRAVITY_M_S2], 0.005);
        let before = f;
        f.update([f32::NAN, 0.0, 0.0], [0.0, 0.0, GRAVITY_M_S2], 0.005);
        assert_eq!(f, before);
    }
}
