//! Selects the Cortex-M DSP kernels: `cfg(arm_dsp)` is set for targets with the ARMv7E-M
//! (or ARMv8-M Mainline) DSP extension. Stable Rust exposes no `target_feature = "dsp"` cfg,
//! so the target triple decides, as the cortex-m crates do.

fn main() {
    println!("cargo::rustc-check-cfg=cfg(arm_dsp)");
    let target = std::env::var("TARGET").unwrap_or_default();
    if target.starts_with("thumbv7em") || target.starts_with("thumbv8m.main") {
        println!("cargo::rustc-cfg=arm_dsp");
    }
}
