//! Flash and RAM budget: section sizes of a firmware ELF against the regions of `memory.x`.
//!
//! Allocated sections are classified by their flags, so the check works for any ELF of
//! the program (also one linked for another board, such as the QEMU benchmark): read-only
//! sections live in flash; writable ones in RAM, and initialized writable ones (`.data`)
//! also keep their load image in flash.

use object::{Object, ObjectSection, SectionFlags, SectionKind};
use std::fmt;
use std::path::Path;

/// A `MEMORY` region of a linker script.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Region {
    /// Name (`FLASH`, `RAM`, ...).
    pub name: String,
    /// Start address.
    pub origin: u64,
    /// Size in bytes.
    pub length: u64,
}

/// Parses the `MEMORY { NAME : ORIGIN = x, LENGTH = y }` entries (comments skipped).
pub fn parse_memory_x(text: &str) -> anyhow::Result<Vec<Region>> {
    let mut clean = String::new();
    let mut rest = text;
    while let Some(start) = rest.find("/*") {
        clean.push_str(&rest[..start]);
        rest = rest[start..]
            .find("*/")
            .map_or("", |end| &rest[start + end + 2..]);
    }
    clean.push_str(rest);
    let mut regions = Vec::new();
    for line in clean.lines() {
        let line = line.split("//").next().unwrap_or("").trim();
        let Some((name, spec)) = line.split_once(':') else {
            continue;
        };
        let field = |key: &str| -> Option<u64> {
            let upper = spec.to_uppercase();
            let pos = upper.find(key)?;
            let value = spec[pos + key.len()..]
                .trim_start()
                .strip_prefix('=')?
                .trim();
            let value = value.split(',').next()?.trim();
            parse_number(value)
        };
        let name = name.split_whitespace().next().unwrap_or("").to_string();
        if let (Some(origin), Some(length)) = (field("ORIGIN"), field("LENGTH")) {
            regions.push(Region {
                name,
                origin,
                length,
            });
        }
    }
    anyhow::ensure!(!regions.is_empty(), "no MEMORY regions found");
    Ok(regions)
}

fn parse_number(s: &str) -> Option<u64> {
    let s = s.trim();
    let (digits, mult) = match s.chars().last()? {
        'K' | 'k' => (&s[..s.len() - 1], 1024),
        'M' | 'm' => (&s[..s.len() - 1], 1024 * 1024),
        _ => (s, 1),
    };
    let v = match digits
        .strip_prefix("0x")
        .or_else(|| digits.strip_prefix("0X"))
    {
        Some(hex) => u64::from_str_radix(&hex.replace('_', ""), 16).ok()?,
        None => digits.replace('_', "").parse().ok()?,
    };
    Some(v * mult)
}

/// Flash and RAM use of an ELF against a memory map.
#[derive(Clone, Debug)]
pub struct SizeReport {
    /// Bytes stored in flash (code, read-only data, `.data` load image).
    pub flash_bytes: u64,
    /// Bytes of static RAM (`.data`, `.bss`, other writable sections).
    pub ram_bytes: u64,
    /// The `FLASH` region's size.
    pub flash_limit: u64,
    /// The `RAM` region's size.
    pub ram_limit: u64,
}

impl SizeReport {
    /// Both fit.
    pub fn fits(&self) -> bool {
        self.flash_bytes <= self.flash_limit && self.ram_bytes <= self.ram_limit
    }
}

impl fmt::Display for SizeReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let pct = |a: u64, b: u64| 100.0 * a as f64 / b.max(1) as f64;
        write!(
            f,
            "flash {} / {} bytes ({:.1}%), RAM {} / {} bytes ({:.1}%)",
            self.flash_bytes,
            self.flash_limit,
            pct(self.flash_bytes, self.flash_limit),
            self.ram_bytes,
            self.ram_limit,
            pct(self.ram_bytes, self.ram_limit)
        )
    }
}

/// Measures `elf` against the `FLASH` and `RAM` regions of `memory_x`.
pub fn check(elf: &Path, memory_x: &Path) -> anyhow::Result<SizeReport> {
    let regions = parse_memory_x(&std::fs::read_to_string(memory_x)?)?;
    let limit = |name: &str| {
        regions
            .iter()
            .find(|r| r.name == name)
            .map(|r| r.length)
            .ok_or_else(|| anyhow::anyhow!("{}: no {name} region", memory_x.display()))
    };
    let data = std::fs::read(elf)?;
    let file = object::File::parse(&*data)?;
    let (mut flash, mut ram) = (0u64, 0u64);
    for section in file.sections() {
        let SectionFlags::Elf { sh_flags } = section.flags() else {
            continue;
        };
        const SHF_WRITE: u64 = 1;
        const SHF_ALLOC: u64 = 2;
        if sh_flags & SHF_ALLOC == 0 || section.size() == 0 {
            continue;
        }
        let writable = sh_flags & SHF_WRITE != 0;
        let has_image = !matches!(
            section.kind(),
            SectionKind::UninitializedData | SectionKind::UninitializedTls
        );
        if writable {
            ram += section.size();
            if has_image {
                flash += section.size();
            }
        } else {
            flash += section.size();
        }
    }
    Ok(SizeReport {
        flash_bytes: flash,
        ram_bytes: ram,
        flash_limit: limit("FLASH")?,
        ram_limit: limit("RAM")?,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_regions_and_skips_comments() {
        let text = "MEMORY\n{\n  /* FLASH : ORIGIN = 0, LENGTH = 1K */\n  FLASH : ORIGIN = 0x08000000, LENGTH = 2M\n  RAM (rwx) : ORIGIN = 0x24000000, LENGTH = 512K\n}\n";
        let r = parse_memory_x(text).unwrap();
        assert_eq!(r.len(), 2);
        assert_eq!(
            r[0],
            Region {
                name: "FLASH".into(),
                origin: 0x0800_0000,
                length: 2 << 20
            }
        );
        assert_eq!(r[1].length, 512 * 1024);
    }
}
