//! CRSF (Crossfire / ExpressLRS serial protocol): a streaming frame parser and encoders.
//!
//! Frame: `[address 0xC8][len][type][payload ...][crc8]`, `len` counting type, payload and
//! CRC (2..=62), CRC-8/DVB-S2 (poly 0xD5) over type and payload. Types used here:
//! 0x16 RC channels packed (16 channels x 11 bits, LSB first, 22 bytes) and 0x14 link
//! statistics (10 bytes). The parser never panics: bad lengths and CRCs are counted and
//! the parser resynchronises on the next address byte.

/// Address byte of frames to the flight controller (the sync byte).
pub const CRSF_SYNC: u8 = 0xC8;
/// Frame type: link statistics.
pub const TYPE_LINK_STATISTICS: u8 = 0x14;
/// Frame type: RC channels packed.
pub const TYPE_RC_CHANNELS: u8 = 0x16;
/// Largest frame on the wire (address + len + 62).
pub const MAX_FRAME_LEN: usize = 64;
/// Number of RC channels.
pub const NUM_CHANNELS: usize = 16;
/// Channel value at 988 us.
pub const CHANNEL_MIN: u16 = 172;
/// Channel value at 1500 us.
pub const CHANNEL_MID: u16 = 992;
/// Channel value at 2012 us.
pub const CHANNEL_MAX: u16 = 1811;
const RC_PAYLOAD_LEN: usize = 22;
const LINK_PAYLOAD_LEN: usize = 10;

/// CRC-8/DVB-S2 (poly 0xD5, init 0).
pub fn crc8_dvb_s2(bytes: &[u8]) -> u8 {
    let mut crc = 0u8;
    for &b in bytes {
        crc ^= b;
        for _ in 0..8 {
            crc = if crc & 0x80 != 0 {
                (crc << 1) ^ 0xD5
            } else {
                crc << 1
            };
        }
    }
    crc
}

/// Link statistics as the receiver reports them.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct LinkStatistics {
    /// Uplink RSSI of antenna 1, -dBm.
    pub uplink_rssi_1: u8,
    /// Uplink RSSI of antenna 2, -dBm.
    pub uplink_rssi_2: u8,
    /// Uplink link quality, percent of packets received.
    pub uplink_link_quality: u8,
    /// Uplink SNR, dB.
    pub uplink_snr: i8,
    /// Active antenna.
    pub active_antenna: u8,
    /// RF mode (packet rate index).
    pub rf_mode: u8,
    /// Uplink transmit power index.
    pub uplink_tx_power: u8,
    /// Downlink RSSI, -dBm.
    pub downlink_rssi: u8,
    /// Downlink link quality, percent.
    pub downlink_link_quality: u8,
    /// Downlink SNR, dB.
    pub downlink_snr: i8,
}

/// A decoded frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum CrsfFrame {
    /// 16 channel values (172..=1811 nominal, 11 bits).
    RcChannels([u16; NUM_CHANNELS]),
    /// Link statistics.
    LinkStatistics(LinkStatistics),
    /// A valid frame of another type (ignored).
    Other(u8),
}

/// Counters of rejected input.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct CrsfCounters {
    /// Frames whose CRC did not match.
    pub crc_errors: u32,
    /// Length bytes outside 2..=62, or a known type with the wrong payload length.
    pub bad_length: u32,
    /// Bytes skipped while looking for the sync byte.
    pub skipped_bytes: u32,
    /// Valid frames decoded.
    pub frames: u32,
}

/// Streaming CRSF parser with a fixed buffer.
#[derive(Clone, Debug)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct CrsfParser {
    buf: [u8; MAX_FRAME_LEN],
    len: usize,
    /// Rejected-input counters.
    pub counters: CrsfCounters,
}

impl Default for CrsfParser {
    fn default() -> Self {
        Self::new()
    }
}

impl CrsfParser {
    /// An empty parser.
    pub const fn new() -> Self {
        Self {
            buf: [0; MAX_FRAME_LEN],
            len: 0,
            counters: CrsfCounters {
                crc_errors: 0,
                bad_length: 0,
                skipped_bytes: 0,
                frames: 0,
            },
        }
    }

    /// Feeds one byte; returns a frame when one completes.
    pub fn push(&mut self, byte: u8) -> Option<CrsfFrame> {
        if self.len == 0 {
            if byte == CRSF_SYNC {
                self.buf[0] = byte;
                self.len = 1;
            } else {
                self.counters.skipped_bytes = self.counters.skipped_bytes.saturating_add(1);
            }
            return None;
        }
        if self.len == 1 && !(2..=62).contains(&byte) {
            self.counters.bad_length = self.counters.bad_length.saturating_add(1);
            self.len = 0;
            // The bad length byte may itself be a sync byte.
            return self.push(byte);
        }
        self.buf[self.len] = byte;
        self.len += 1;
        let total = self.buf[1] as usize + 2;
        if self.len < total {
            return None;
        }
        self.len = 0;
        let body = &self.buf[2..total - 1];
        if crc8_dvb_s2(body) != self.buf[total - 1] {
            self.counters.crc_errors = self.counters.crc_errors.saturating_add(1);
            return None;
        }
        let frame = decode(body[0], &body[1..]);
        match frame {
            Some(f) => {
                self.counters.frames = self.counters.frames.saturating_add(1);
                Some(f)
            }
            None => {
                self.counters.bad_length = self.counters.bad_length.saturating_add(1);
                None
            }
        }
    }
}

fn decode(frame_type: u8, p: &[u8]) -> Option<CrsfFrame> {
    match frame_type {
        TYPE_RC_CHANNELS => {
            if p.len() != RC_PAYLOAD_LEN {
                return None;
            }
            let mut ch = [0u16; NUM_CHANNELS];
            for (i, c) in ch.iter_mut().enumerate() {
                let bit = i * 11;
                let byte = bit / 8;
                let shift = bit % 8;
                let mut v = (p[byte] as u32) >> shift | (p[byte + 1] as u32) << (8 - shift);
                if shift > 5 {
                    v |= (p[byte + 2] as u32) << (16 - shift);
                }
                *c = (v & 0x7FF) as u16;
            }
            Some(CrsfFrame::RcChannels(ch))
        }
        TYPE_LINK_STATISTICS => {
            if p.len() != LINK_PAYLOAD_LEN {
                return None;
            }
            Some(CrsfFrame::LinkStatistics(LinkStatistics {
                uplink_rssi_1: p[0],
                uplink_rssi_2: p[1],
                uplink_link_quality: p[2],
                uplink_snr: p[3] as i8,
                active_antenna: p[4],
                rf_mode: p[5],
                uplink_tx_power: p[6],
                downlink_rssi: p[7],
                downlink_link_quality: p[8],
                downlink_snr: p[9] as i8,
            }))
        }
        t => Some(CrsfFrame::Other(t)),
    }
}

fn finish<const N: usize>(mut frame: [u8; N]) -> [u8; N] {
    frame[N - 1] = crc8_dvb_s2(&frame[2..N - 1]);
    frame
}

/// Encodes an RC channels frame (26 bytes on the wire); values are masked to 11 bits.
pub fn encode_rc_channels(channels: &[u16; NUM_CHANNELS]) -> [u8; 26] {
    let mut f = [0u8; 26];
    f[0] = CRSF_SYNC;
    f[1] = (RC_PAYLOAD_LEN + 2) as u8;
    f[2] = TYPE_RC_CHANNELS;
    let mut acc = 0u32;
    let mut bits = 0;
    let mut at = 3;
    for &c in channels {
        acc |= ((c & 0x7FF) as u32) << bits;
        bits += 11;
        while bits >= 8 {
            f[at] = acc as u8;
            at += 1;
            acc >>= 8;
            bits -= 8;
        }
    }
    finish(f)
}

/// Encodes a link statistics frame (14 bytes on the wire).
pub fn encode_link_statistics(s: &LinkStatistics) -> [u8; 14] {
    finish([
        CRSF_SYNC,
        (LINK_PAYLOAD_LEN + 2) as u8,
        TYPE_LINK_STATISTICS,
        s.uplink_rssi_1,
        s.uplink_rssi_2,
        s.uplink_link_quality,
        s.uplink_snr as u8,
        s.active_antenna,
        s.rf_mode,
        s.uplink_tx_power,
        s.downlink_rssi,
        s.downlink_link_quality,
        s.downlink_snr as u8,
        0,
    ])
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse_all(p: &mut CrsfParser, bytes: &[u8]) -> heapless::Vec<CrsfFrame, 8> {
        bytes.iter().filter_map(|&b| p.push(b)).collect()
    }

    #[test]
    fn crc_matches_the_dvb_s2_check_value() {
        // CRC-8/DVB-S2 catalogue check value over "123456789".
        assert_eq!(crc8_dvb_s2(b"123456789"), 0xBC);
    }

    #[test]
    fn decodes_a_captured_frame() {
        // All channels at 992 (centre): 0x3E0 repeated, as a receiver sends at rest.
        let f = encode_rc_channels(&[CHANNEL_MID; NUM_CHANNELS]);
        assert_eq!(&f[..6], &[0xC8, 0x18, 0x16, 0xE0, 0x03, 0x1F]);
        let mut p = CrsfParser::new();
        assert_eq!(
            parse_all(&mut p, &f).as_slice(),
            &[CrsfFrame::RcChannels([CHANNEL_MID; NUM_CHANNELS])]
        );
    }

    #[test]
    fn channels_and_link_statistics_round_trip() {
        let mut ch = [0u16; NUM_CHANNELS];
        for (i, c) in ch.iter_mut().enumerate() {
            *c = CHANNEL_MIN + 100 * i as u16;
        }
        ch[15] = 0x7FF;
        let ls = LinkStatistics {
            uplink_link_quality: 100,
            uplink_snr: -7,
            ..Default::default()
        };
        let mut stream = heapless::Vec::<u8, 64>::new();
        stream.extend_from_slice(&[0x00, 0xC8, 0x99]).unwrap(); // noise and a bad length
        stream.extend_from_slice(&encode_rc_channels(&ch)).unwrap();
        stream
            .extend_from_slice(&encode_link_statistics(&ls))
            .unwrap();
        let mut p = CrsfParser::new();
        let frames = parse_all(&mut p, &stream);
        assert_eq!(
            frames.as_slice(),
            &[CrsfFrame::RcChannels(ch), CrsfFrame::LinkStatistics(ls)]
        );
        assert_eq!(p.counters.bad_length, 1);
        // 0x00 and the bad length byte 0x99.
        assert_eq!(p.counters.skipped_bytes, 2);
    }

    #[test]
    fn corrupted_frames_are_counted_and_skipped() {
        let mut f = encode_rc_channels(&[CHANNEL_MAX; NUM_CHANNELS]);
        f[10] ^= 0x01;
        let mut p = CrsfParser::new();
        assert!(parse_all(&mut p, &f).is_empty());
        assert_eq!(p.counters.crc_errors, 1);
        let good = encode_rc_channels(&[CHANNEL_MIN; NUM_CHANNELS]);
        assert_eq!(parse_all(&mut p, &good).len(), 1);
    }
}
