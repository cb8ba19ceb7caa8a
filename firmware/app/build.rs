//! Puts the repository's `memory.x` (the STM32H743ZI map, shared with the size check) on
//! the linker path. embassy-stm32's `memory-x` feature stays off: a second memory.x on the
//! link path would silently win over this one.

use std::path::{Path, PathBuf};

fn main() {
    let out = PathBuf::from(std::env::var("OUT_DIR").expect("cargo sets OUT_DIR"));
    let memory_x = Path::new("../../memory.x");
    std::fs::copy(memory_x, out.join("memory.x")).expect("copy the repository's memory.x");
    println!("cargo:rustc-link-search={}", out.display());
    println!("cargo:rerun-if-changed={}", memory_x.display());
    println!("cargo:rerun-if-changed=build.rs");
}
