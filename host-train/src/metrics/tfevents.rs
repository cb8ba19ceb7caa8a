//! TensorBoard event files (`events.out.tfevents.*`), the scalars of `metrics.csv` as
//! rsl_rl's `SummaryWriter` writes them, so `tensorboard --logdir runs` shows a run.
//!
//! The format: TFRecord framing (`u64` length, masked CRC32C of the length, the bytes,
//! masked CRC32C of the bytes; little-endian) around `tensorflow.Event` protobufs: first
//! `{wall_time, file_version: "brain.Event:2"}`, then per row `{wall_time, step,
//! summary {value {tag, simple_value}}}`.
//!
//! Hand-written rather than a crate: `tensorboard-rs` (0.5.9) is built on `protobuf` 2 and
//! `image` 0.23, and `tfrecord` (0.15) pulls in async-std, ndarray, image and tch; the
//! scalar subset is three protobuf messages and a checksum, tested below against known
//! vectors and bytes written by TensorBoard's own Python writer.

use std::io::Write;
use std::path::{Path, PathBuf};

/// CRC-32C (Castagnoli, reflected polynomial 0x82F63B78), as TFRecord uses.
pub fn crc32c(bytes: &[u8]) -> u32 {
    const TABLE: [u32; 256] = {
        let mut table = [0u32; 256];
        let mut i = 0;
        while i < 256 {
            let mut c = i as u32;
            let mut k = 0;
            while k < 8 {
                c = if c & 1 != 0 {
                    0x82F6_3B78 ^ (c >> 1)
                } else {
                    c >> 1
                };
                k += 1;
            }
            table[i] = c;
            i += 1;
        }
        table
    };
    let mut crc = !0u32;
    for &b in bytes {
        crc = TABLE[((crc ^ b as u32) & 0xff) as usize] ^ (crc >> 8);
    }
    !crc
}

/// TFRecord's masked CRC: rotated right by 15 bits plus a constant.
pub fn masked_crc32c(bytes: &[u8]) -> u32 {
    let crc = crc32c(bytes);
    crc.rotate_right(15).wrapping_add(0xa282_ead8)
}

/// One TFRecord: length, its masked CRC, the data, its masked CRC.
pub fn record(data: &[u8]) -> Vec<u8> {
    let len = (data.len() as u64).to_le_bytes();
    let mut out = Vec::with_capacity(data.len() + 16);
    out.extend_from_slice(&len);
    out.extend_from_slice(&masked_crc32c(&len).to_le_bytes());
    out.extend_from_slice(data);
    out.extend_from_slice(&masked_crc32c(data).to_le_bytes());
    out
}

fn varint(out: &mut Vec<u8>, mut v: u64) {
    while v >= 0x80 {
        out.push((v as u8) | 0x80);
        v >>= 7;
    }
    out.push(v as u8);
}

/// A length-delimited protobuf field.
fn bytes_field(out: &mut Vec<u8>, field: u32, bytes: &[u8]) {
    varint(out, ((field << 3) | 2) as u64);
    varint(out, bytes.len() as u64);
    out.extend_from_slice(bytes);
}

/// `Event.wall_time` (field 1, double) and, when given, `Event.step` (field 2, int64).
fn event_head(wall_time_s: f64, step: Option<i64>) -> Vec<u8> {
    let mut out = vec![(1 << 3) | 1];
    out.extend_from_slice(&wall_time_s.to_le_bytes());
    if let Some(step) = step {
        out.push(2 << 3);
        varint(&mut out, step as u64);
    }
    out
}

/// The first event of a file: `file_version` (field 3).
pub fn file_version_event(wall_time_s: f64) -> Vec<u8> {
    let mut out = event_head(wall_time_s, None);
    bytes_field(&mut out, 3, b"brain.Event:2");
    out
}

/// An event with one `Summary` (field 5) of scalar values (`Summary.value`, field 1:
/// `tag` field 1, `simple_value` field 2, float).
pub fn scalars_event(wall_time_s: f64, step: i64, values: &[(&str, f32)]) -> Vec<u8> {
    let mut summary = Vec::new();
    for (tag, v) in values {
        let mut value = Vec::new();
        bytes_field(&mut value, 1, tag.as_bytes());
        value.push((2 << 3) | 5);
        value.extend_from_slice(&v.to_le_bytes());
        bytes_field(&mut summary, 1, &value);
    }
    let mut out = event_head(wall_time_s, Some(step));
    bytes_field(&mut out, 5, &summary);
    out
}

/// An event file being appended to.
#[derive(Debug)]
pub struct EventFile {
    /// The file.
    pub path: PathBuf,
    /// Rows already written.
    pub rows_written: usize,
}

fn now_s() -> f64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0.0, |d| d.as_secs_f64())
}

impl EventFile {
    /// Creates `dir/events.out.tfevents.<unix seconds>.<host>.<pid>` with its
    /// `file_version` event.
    pub fn create(dir: &Path) -> std::io::Result<Self> {
        let wall = now_s();
        let host = std::fs::read_to_string("/etc/hostname")
            .ok()
            .map(|h| h.trim().to_string())
            .filter(|h| !h.is_empty() && !h.contains('/'))
            .unwrap_or_else(|| "localhost".into());
        let path = dir.join(format!(
            "events.out.tfevents.{}.{host}.{}",
            wall as u64,
            std::process::id()
        ));
        std::fs::write(&path, record(&file_version_event(wall)))?;
        Ok(Self {
            path,
            rows_written: 0,
        })
    }

    /// Appends one scalars event per row (`iteration` is the step, every other key a tag).
    pub fn append(
        &mut self,
        rows: &[std::collections::BTreeMap<String, f64>],
    ) -> std::io::Result<()> {
        let wall = now_s();
        let mut out = Vec::new();
        for row in rows {
            let step = row.get("iteration").copied().unwrap_or(0.0) as i64;
            let values: Vec<(&str, f32)> = row
                .iter()
                .filter(|(k, _)| k.as_str() != "iteration")
                .map(|(k, v)| (k.as_str(), *v as f32))
                .collect();
            out.extend(record(&scalars_event(wall, step, &values)));
        }
        let mut file = std::fs::OpenOptions::new().append(true).open(&self.path)?;
        file.write_all(&out)?;
        file.flush()?;
        self.rows_written += rows.len();
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn crc32c_known_vectors() {
        // The check value of CRC-32C, and RFC 3720 (iSCSI) B.4.
        assert_eq!(crc32c(b"123456789"), 0xE306_9283);
        assert_eq!(crc32c(&[0u8; 32]), 0x8A91_36AA);
        assert_eq!(crc32c(&[0xffu8; 32]), 0x62A8_AB43);
        let ascending: Vec<u8> = (0..32).collect();
        assert_eq!(crc32c(&ascending), 0x46DD_794E);
        assert_eq!(crc32c(b""), 0);
    }

    /// Bytes from TensorBoard 2.21's writer: `tensorboard.summary.writer.record_writer`
    /// framing around `event_pb2.Event(wall_time=1.5, step=7, summary=Summary(value=[
    /// Value(tag="loss/value", simple_value=0.25)]))`, and the file-version event at
    /// wall time 1.5.
    #[test]
    fn records_match_tensorboards_writer() {
        let scalar = record(&scalars_event(1.5, 7, &[("loss/value", 0.25)]));
        assert_eq!(hex(&scalar), SCALAR_RECORD_HEX);
        let version = record(&file_version_event(1.5));
        assert_eq!(hex(&version), VERSION_RECORD_HEX);
        // The framing: length, masked CRCs.
        let len = u64::from_le_bytes(scalar[..8].try_into().unwrap()) as usize;
        assert_eq!(len + 16, scalar.len());
        assert_eq!(
            u32::from_le_bytes(scalar[8..12].try_into().unwrap()),
            masked_crc32c(&scalar[..8])
        );
        let tail = u32::from_le_bytes(scalar[12 + len..].try_into().unwrap());
        assert_eq!(tail, masked_crc32c(&scalar[12..12 + len]));
    }

    #[test]
    fn event_file_appends_rows() {
        let dir = std::env::temp_dir().join(format!("tfevents-test-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let mut f = EventFile::create(&dir).unwrap();
        assert!(f
            .path
            .file_name()
            .unwrap()
            .to_string_lossy()
            .starts_with("events.out.tfevents."));
        let row = |i: f64| {
            [
                ("iteration".to_string(), i),
                ("loss/value".to_string(), 0.5 * i),
            ]
            .into_iter()
            .collect()
        };
        f.append(&[row(0.0), row(1.0)]).unwrap();
        f.append(&[row(2.0)]).unwrap();
        let bytes = std::fs::read(&f.path).unwrap();
        let mut records = Vec::new();
        let mut at = 0;
        while at < bytes.len() {
            let len = u64::from_le_bytes(bytes[at..at + 8].try_into().unwrap()) as usize;
            records.push(bytes[at + 12..at + 12 + len].to_vec());
            at += len + 16;
        }
        assert_eq!(at, bytes.len());
        assert_eq!(records.len(), 4);
        assert!(records[0].ends_with(b"brain.Event:2"));
        assert!(records[3].windows(10).any(|w| w == b"loss/value"));
        assert_eq!(f.rows_written, 3);
        let _ = std::fs::remove_dir_all(&dir);
    }

    fn hex(bytes: &[u8]) -> String {
        bytes.iter().map(|b| format!("{b:02x}")).collect()
    }

    const SCALAR_RECORD_HEX: &str = "200000000000000029eda95009000000000000f83f10072a130a110a0a6c6f73732f76616c7565150000803e782fbb85";
    const VERSION_RECORD_HEX: &str =
        "1800000000000000a37f4b2209000000000000f83f1a0d627261696e2e4576656e743a322a28646c";
}
