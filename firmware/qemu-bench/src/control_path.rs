//! The control path without the network on the Cortex-M7, for three sets of float
//! functions: the core's (`libm`), `libm` with the FPU's square root (`vsqrt.f32`), and
//! micromath's approximations. Per 20 ms control period the firmware runs 20 attitude
//! updates (1 kHz IMU), the tilt for the supervisor, and one control step (observation,
//! history, input quantization, clamps); the network is replaced by a policy that only
//! quantizes its inputs the way the fixed-point policy does. Also the leg kinematics
//! (forward and inverse for the six legs; not on the firmware's control path).

use core::fmt::Write;
use core::hint::black_box;
use core::marker::PhantomData;
use cortex_m::peripheral::SYST;
use cortex_m_semihosting::hio::HostStream;
use hexapod_core::attitude::{AttitudeConfig, AttitudeFilter};
use hexapod_core::control::{ControlStep, Policy, Sensors};
use hexapod_core::kinematics;
use hexapod_core::math::{bench, FloatFns, Libm, LibmFpuSqrt};
use hexapod_core::nalgebra::Vector3;
use hexapod_core::obs::{actor_obs, ProprioHistory, ACTOR_OBS_DIM, HISTORY_DIM};
use hexapod_core::robot::{Leg, NUM_JOINTS, Q0_LEG_RAD, Q0_RAD};
use hexapod_policy::POLICY;

use crate::ticks_since;

/// micromath 2.1's approximations (the `F32Ext` functions).
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

const HISTORY_WORDS: usize = HISTORY_DIM.div_ceil(2);
const OBS_WORDS: usize = ACTOR_OBS_DIM.div_ceil(2);

/// Quantizes the history and the actor observation like `QuantizedPolicy::step` (round
/// with `F`, saturate to i16, pack two per word) and returns a zero action.
struct QuantizeOnly<F> {
    words: [u32; HISTORY_WORDS + OBS_WORDS],
    _f: PhantomData<F>,
}

fn quantize_with<F: FloatFns>(values: &[f32], scales: &[f32], out: &mut [u32]) {
    let mut it = values
        .iter()
        .zip(scales)
        .map(|(&x, &s)| (F::round(x * s) as i32).clamp(i16::MIN as i32, i16::MAX as i32) as i16);
    for word in out.iter_mut() {
        let lo = it.next().unwrap_or(0) as u16 as u32;
        let hi = it.next().unwrap_or(0) as u16 as u32;
        *word = lo | (hi << 16);
    }
}

impl<F: FloatFns> Policy for QuantizeOnly<F> {
    fn act(
        &mut self,
        command: [f32; 3],
        prev_action: &[f32; NUM_JOINTS],
        history: &ProprioHistory,
    ) -> Option<[f32; NUM_JOINTS]> {
        let obs = actor_obs(command, prev_action, history.newest());
        let (hist, rest) = self.words.split_at_mut(HISTORY_WORDS);
        quantize_with::<F>(&history.flatten(), POLICY.history_scale, hist);
        quantize_with::<F>(&obs, POLICY.actor_obs_scale, rest);
        black_box(&self.words);
        Some([0.0; NUM_JOINTS])
    }
}

/// Instructions of one 20 ms period's attitude updates, the tilt, one control step, and
/// six legs' forward and inverse kinematics, with backend `F`.
fn measure<F: FloatFns>(empty: u32, insns_per_tick: f32) -> [f32; 4] {
    let insns = |ticks: u32| ticks.saturating_sub(empty) as f32 * insns_per_tick;
    // Each part is repeated and divided: one SysTick tick is 40 instructions.
    const PERIODS: usize = 10;
    let mut samples = [(Vector3::zeros(), Vector3::zeros()); bench::SAMPLES_PER_PERIOD * PERIODS];
    // Past the alignment: 1 s into the sequence.
    for (i, s) in samples.iter_mut().enumerate() {
        *s = bench::imu_sample(1000 + i as u32);
    }
    let mut filter = AttitudeFilter::new(AttitudeConfig::default());
    for k in 0..1000 {
        let (g, a) = bench::imu_sample(k);
        filter.update_with::<F>(&g, &a, bench::IMU_DT_S);
    }
    let start = SYST::get_current();
    for (g, a) in &samples {
        filter.update_with::<F>(black_box(g), black_box(a), bench::IMU_DT_S);
    }
    let attitude = insns(ticks_since(start)) / PERIODS as f32;
    let start = SYST::get_current();
    for _ in 0..PERIODS {
        black_box(black_box(&filter).tilt_rad_with::<F>());
    }
    let tilt_insns = insns(ticks_since(start)) / PERIODS as f32;

    let sensors = Sensors {
        ang_vel_base_rad_s: samples[0].0.into(),
        gravity_base: filter.projected_gravity(),
        q_rad: Q0_RAD,
        qdot_rad_s: [0.1; NUM_JOINTS],
    };
    let mut policy = QuantizeOnly::<F> {
        words: [0; HISTORY_WORDS + OBS_WORDS],
        _f: PhantomData,
    };
    let mut step = ControlStep::new();
    // The first step fills the history; time the second.
    step.step(&mut policy, &sensors, [0.3, 0.0, 0.1]).ok();
    let start = SYST::get_current();
    for _ in 0..PERIODS {
        black_box(
            step.step(&mut policy, black_box(&sensors), [0.3, 0.0, 0.1])
                .ok(),
        );
    }
    let control = insns(ticks_since(start)) / PERIODS as f32;

    let q = Vector3::new(
        Q0_LEG_RAD[0] + 0.2,
        Q0_LEG_RAD[1] - 0.1,
        Q0_LEG_RAD[2] + 0.3,
    );
    let start = SYST::get_current();
    for _ in 0..PERIODS {
        for leg in Leg::ALL {
            let foot = kinematics::foot_position_with::<F>(leg, black_box(&q));
            black_box(kinematics::inverse_kinematics_with::<F>(leg, &foot).ok());
        }
    }
    let kin = insns(ticks_since(start)) / PERIODS as f32;
    [attitude, tilt_insns, control, kin]
}

/// Prints the measurements and checks the filter's bits against the host's.
pub fn run(out: &mut HostStream, empty: u32, insns_per_tick: f32) -> Result<(), ()> {
    let bits = bench::state_bits::<Libm>(&bench::attitude_run::<Libm>());
    write!(out, "attitude_bits:").ok();
    for b in bits {
        write!(out, " {b:#010x}").ok();
    }
    writeln!(out).ok();
    let fpu_bits = bench::state_bits::<LibmFpuSqrt>(&bench::attitude_run::<LibmFpuSqrt>());
    let mm = bench::attitude_run::<Micromath>();
    let lm = bench::attitude_run::<Libm>();
    let dev = (mm.gravity_base() - lm.gravity_base()).amax();
    writeln!(
        out,
        "attitude after 2 s: libm == host {}, libm+vsqrt == libm {}, micromath projected-gravity deviation {:.2e}",
        bits == bench::EXPECTED_LIBM_BITS,
        fpu_bits == bits,
        dev
    )
    .ok();
    for (name, m) in [
        ("libm", measure::<Libm>(empty, insns_per_tick)),
        ("libm+vsqrt", measure::<LibmFpuSqrt>(empty, insns_per_tick)),
        ("micromath", measure::<Micromath>(empty, insns_per_tick)),
    ] {
        let [attitude, tilt, control, kin] = m;
        writeln!(
            out,
            "control path {name}: attitude update {:.0}, tilt {:.0}, control step without network {:.0}, per 20 ms period {:.0} instructions; kinematics 6 legs FK+IK {:.0}",
            attitude / bench::SAMPLES_PER_PERIOD as f32,
            tilt,
            control,
            attitude + tilt + control,
            kin
        )
        .ok();
    }
    if bits != bench::EXPECTED_LIBM_BITS || fpu_bits != bits {
        writeln!(
            out,
            "error: the attitude filter's bits differ from the host's"
        )
        .ok();
        return Err(());
    }
    Ok(())
}
