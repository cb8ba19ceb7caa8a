//! An IMU model: gyro and accelerometer readings from the simulated base state, with
//! white noise, a constant gyro bias, and staleness injection.

use hexapod_core::attitude::GRAVITY_M_S2;
use hexapod_core::hal::{Imu, ImuSample};

use crate::rng::SplitMix64;

/// Noise parameters (ICM-42688-P class).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ImuNoise {
    /// Gyro white noise standard deviation per sample, rad/s.
    pub gyro_std_rad_s: f32,
    /// Constant gyro bias, rad/s.
    pub gyro_bias_rad_s: [f32; 3],
    /// Accelerometer white noise standard deviation per sample, m/s^2.
    pub accel_std_m_s2: f32,
}

impl Default for ImuNoise {
    fn default() -> Self {
        Self {
            gyro_std_rad_s: 0.005,
            gyro_bias_rad_s: [0.002, -0.003, 0.001],
            accel_std_m_s2: 0.05,
        }
    }
}

/// Rotates a world vector into the base frame with the base orientation `q` (w, x, y, z;
/// base -> world): `hexapod_core::frames::world_to_base` on arrays.
pub fn world_to_base(q: [f32; 4], v: [f32; 3]) -> [f32; 3] {
    hexapod_core::frames::world_to_base_wxyz(q, v)
}

/// The IMU model.
#[derive(Clone, Debug)]
pub struct ImuModel {
    noise: ImuNoise,
    rng: SplitMix64,
    pending: Option<ImuSample>,
    stale: bool,
}

impl ImuModel {
    /// A model with `noise`, seeded.
    pub fn new(noise: ImuNoise, seed: u64) -> Self {
        Self {
            noise,
            rng: SplitMix64::new(seed),
            pending: None,
            stale: false,
        }
    }

    /// Stops (or resumes) delivering samples: a stale IMU.
    pub fn set_stale(&mut self, stale: bool) {
        self.stale = stale;
    }

    /// Samples the state at `now_us`: orientation (w, x, y, z; base -> world), angular
    /// velocity in the base frame, linear acceleration of the base in the world frame.
    pub fn sample(
        &mut self,
        now_us: u64,
        orientation: [f32; 4],
        ang_vel_base_rad_s: [f32; 3],
        lin_acc_world_m_s2: [f32; 3],
    ) {
        let f_world = [
            lin_acc_world_m_s2[0],
            lin_acc_world_m_s2[1],
            lin_acc_world_m_s2[2] + GRAVITY_M_S2,
        ];
        let f = world_to_base(orientation, f_world);
        let mut gyro = [0.0; 3];
        let mut accel = [0.0; 3];
        for k in 0..3 {
            gyro[k] = ang_vel_base_rad_s[k]
                + self.noise.gyro_bias_rad_s[k]
                + self.noise.gyro_std_rad_s * self.rng.normal();
            accel[k] = f[k] + self.noise.accel_std_m_s2 * self.rng.normal();
        }
        if !self.stale {
            self.pending = Some(ImuSample {
                gyro_rad_s: gyro,
                accel_m_s2: accel,
                timestamp_us: now_us,
            });
        }
    }
}

impl Imu for ImuModel {
    fn read(&mut self) -> Option<ImuSample> {
        self.pending.take()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn level_and_rolled_readings() {
        let mut imu = ImuModel::new(
            ImuNoise {
                gyro_std_rad_s: 0.0,
                gyro_bias_rad_s: [0.0; 3],
                accel_std_m_s2: 0.0,
            },
            1,
        );
        imu.sample(10, [1.0, 0.0, 0.0, 0.0], [0.1, 0.0, 0.0], [0.0; 3]);
        let s = imu.read().unwrap();
        assert_eq!(s.accel_m_s2, [0.0, 0.0, GRAVITY_M_S2]);
        assert_eq!(s.gyro_rad_s, [0.1, 0.0, 0.0]);
        assert!(imu.read().is_none(), "one sample is read once");
        // Rolled +90 deg about x: the base's y axis points up, so the specific force
        // appears along +y.
        let h = core::f32::consts::FRAC_1_SQRT_2;
        imu.sample(20, [h, h, 0.0, 0.0], [0.0; 3], [0.0; 3]);
        let a = imu.read().unwrap().accel_m_s2;
        assert!(
            (a[1] - GRAVITY_M_S2).abs() < 1e-4 && a[2].abs() < 1e-4,
            "{a:?}"
        );
        imu.set_stale(true);
        imu.sample(30, [1.0, 0.0, 0.0, 0.0], [0.0; 3], [0.0; 3]);
        assert!(imu.read().is_none());
    }
}
