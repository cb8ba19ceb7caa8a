//! The ARMv7-M MPU encoding of one region: normal, non-cacheable, shareable, full access.
//! Plain `core` code: CI runs its tests on the host with `rustc --test`.

/// MPU_RASR without SIZE: full access (AP = 0b011, bits 26:24), normal memory
/// non-cacheable (TEX = 0b001 in bits 21:19, C = B = 0), shareable (S, bit 18), enabled
/// (bit 0); executable (XN = 0), all subregions on (SRD = 0).
const RASR_NON_CACHEABLE: u32 = (0b011 << 24) | (0b001 << 19) | (1 << 18) | 1;
/// MPU_CTRL: MPU on (bit 0), default memory map for privileged accesses outside the
/// regions (PRIVDEFENA, bit 2).
pub const CTRL_ENABLE_PRIVDEFENA: u32 = (1 << 2) | 1;

/// MPU_RASR for `len` bytes at `base` as normal non-cacheable memory, if the MPU can
/// describe the range as one region (a power of two of at least 32 bytes, `base`
/// aligned to it). The SIZE field (bits 5:1) holds log2(len) - 1.
pub fn rasr_non_cacheable(base: u32, len: u32) -> Option<u32> {
    let describable = len >= 32 && len.is_power_of_two() && base.is_multiple_of(len);
    describable.then(|| RASR_NON_CACHEABLE | ((len.trailing_zeros() - 1) << 1))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn axi_sram_region_matches_the_reference_encoding() {
        // 512 KB at 0x2400_0000: TEX 1, S 1, C 0, B 0, AP full, SIZE 18 (2^19 bytes), enabled.
        assert_eq!(
            rasr_non_cacheable(0x2400_0000, 512 * 1024),
            Some(0x030C_0025)
        );
        assert_eq!(rasr_non_cacheable(0x2000_0000, 32), Some(0x030C_0009));
        assert_eq!(CTRL_ENABLE_PRIVDEFENA, 0b101);
    }

    #[test]
    fn rejects_ranges_one_region_cannot_describe() {
        assert_eq!(rasr_non_cacheable(0x2400_0000, 384 * 1024), None);
        assert_eq!(rasr_non_cacheable(0x2404_0000, 512 * 1024), None);
        assert_eq!(rasr_non_cacheable(0x2000_0000, 16), None);
        assert_eq!(rasr_non_cacheable(0, 0), None);
    }
}
