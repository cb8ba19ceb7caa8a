//! A Mahony complementary filter (f32, no heap): gyro integration corrected toward the
//! accelerometer's gravity direction. Gives the projected gravity of the observation and
//! the tilt the supervisor watches; yaw drifts and is not needed.

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

/// The filter state: orientation of the base in the world (unit quaternion w, x, y, z).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct AttitudeFilter {
    config: AttitudeConfig,
    q: [f32; 4],
    bias_integral: [f32; 3],
    initialized: bool,
}

fn cross(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

fn norm(v: [f32; 3]) -> f32 {
    libm::sqrtf(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
}

impl AttitudeFilter {
    /// A filter that initialises from its first accelerometer sample.
    pub const fn new(config: AttitudeConfig) -> Self {
        Self {
            config,
            q: [1.0, 0.0, 0.0, 0.0],
            bias_integral: [0.0; 3],
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

    /// The world's up axis expressed in the base frame.
    pub fn up_base(&self) -> [f32; 3] {
        let [w, x, y, z] = self.q;
        [
            2.0 * (x * z - w * y),
            2.0 * (w * x + y * z),
            w * w - x * x - y * y + z * z,
        ]
    }

    /// Unit gravity direction in the base frame ([0, 0, -1] when level): the observation's
    /// projected gravity.
    pub fn projected_gravity(&self) -> [f32; 3] {
        let u = self.up_base();
        [-u[0], -u[1], -u[2]]
    }

    /// Angle between the base's z axis and the world's up axis, rad.
    pub fn tilt_rad(&self) -> f32 {
        libm::acosf(self.up_base()[2].clamp(-1.0, 1.0))
    }

    /// Updates with a gyro (rad/s) and accelerometer (specific force, m/s^2) sample.
    pub fn update(&mut self, gyro_rad_s: [f32; 3], accel_m_s2: [f32; 3], dt_s: f32) {
        if !(gyro_rad_s.iter().chain(&accel_m_s2).all(|v| v.is_finite()) && dt_s.is_finite()) {
            return;
        }
        let a_norm = norm(accel_m_s2);
        let accel_ok = (a_norm - GRAVITY_M_S2).abs() <= self.config.accel_tolerance * GRAVITY_M_S2;
        if !self.initialized {
            if accel_ok {
                self.align(accel_m_s2, a_norm);
            }
            return;
        }
        let mut omega = gyro_rad_s;
        if accel_ok {
            let a = [
                accel_m_s2[0] / a_norm,
                accel_m_s2[1] / a_norm,
                accel_m_s2[2] / a_norm,
            ];
            let e = cross(a, self.up_base());
            for k in 0..3 {
                self.bias_integral[k] += self.config.ki * e[k] * dt_s;
                omega[k] += self.config.kp * e[k] + self.bias_integral[k];
            }
        }
        let [w, x, y, z] = self.q;
        let h = 0.5 * dt_s;
        let q = [
            w + h * (-x * omega[0] - y * omega[1] - z * omega[2]),
            x + h * (w * omega[0] + y * omega[2] - z * omega[1]),
            y + h * (w * omega[1] - x * omega[2] + z * omega[0]),
            z + h * (w * omega[2] + x * omega[1] - y * omega[0]),
        ];
        let n = libm::sqrtf(q.iter().map(|v| v * v).sum());
        if n > 0.0 && n.is_finite() {
            self.q = q.map(|v| v / n);
        }
    }

    /// Roll and pitch from a resting accelerometer reading.
    fn align(&mut self, a: [f32; 3], a_norm: f32) {
        let (ax, ay, az) = (a[0] / a_norm, a[1] / a_norm, a[2] / a_norm);
        let roll = libm::atan2f(ay, az);
        let pitch = libm::atan2f(-ax, libm::sqrtf(ay * ay + az * az));
        let (sr, cr) = (libm::sinf(roll / 2.0), libm::cosf(roll / 2.0));
        let (sp, cp) = (libm::sinf(pitch / 2.0), libm::cosf(pitch / 2.0));
        self.q = [cr * cp, sr * cp, cr * sp, -sr * sp];
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
