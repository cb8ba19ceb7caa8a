//! An RC receiver model: a CRSF byte stream (RC channels at 50 Hz, link statistics every
//! tenth frame) from stick and switch positions, with link loss injection.

use std::collections::VecDeque;

use hexapod_core::hal::RcInput;
use hexapod_core::rc::crsf::{
    encode_link_statistics, encode_rc_channels, LinkStatistics, CHANNEL_MAX, CHANNEL_MID,
    CHANNEL_MIN, NUM_CHANNELS,
};

/// Period of RC channel frames, microseconds.
pub const FRAME_PERIOD_US: u64 = 20_000;

/// The transmitter and receiver.
#[derive(Clone, Debug)]
pub struct RcSource {
    channels: [u16; NUM_CHANNELS],
    bytes: VecDeque<u8>,
    next_frame_us: u64,
    frames: u32,
    lost: bool,
}

impl Default for RcSource {
    fn default() -> Self {
        Self::new()
    }
}

fn stick(x: f32) -> u16 {
    let half = (CHANNEL_MAX - CHANNEL_MIN) as f32 / 2.0;
    (CHANNEL_MID as f32 + x.clamp(-1.0, 1.0) * half).round() as u16
}

impl RcSource {
    /// Sticks centred, arm switch off, link up.
    pub fn new() -> Self {
        let mut channels = [CHANNEL_MID; NUM_CHANNELS];
        channels[2] = CHANNEL_MIN;
        channels[4] = CHANNEL_MIN;
        Self {
            channels,
            bytes: VecDeque::new(),
            next_frame_us: 0,
            frames: 0,
            lost: false,
        }
    }

    /// Stick positions in [-1, 1]: forward (pitch), left (negative roll), turn left
    /// (negative yaw).
    pub fn set_sticks(&mut self, forward: f32, left: f32, turn_left: f32) {
        self.channels[1] = stick(forward);
        self.channels[0] = stick(-left);
        self.channels[3] = stick(-turn_left);
    }

    /// The arm switch (AUX1).
    pub fn set_arm(&mut self, on: bool) {
        self.channels[4] = if on { CHANNEL_MAX } else { CHANNEL_MIN };
    }

    /// Link lost: the receiver stops sending channels (ExpressLRS "no pulses" failsafe).
    pub fn set_lost(&mut self, lost: bool) {
        self.lost = lost;
    }

    /// Emits the frames due by `now_us`.
    pub fn tick(&mut self, now_us: u64) {
        while now_us >= self.next_frame_us {
            self.next_frame_us += FRAME_PERIOD_US;
            if self.lost {
                continue;
            }
            self.bytes.extend(encode_rc_channels(&self.channels));
            self.frames += 1;
            if self.frames.is_multiple_of(10) {
                let ls = LinkStatistics {
                    uplink_link_quality: 100,
                    uplink_rssi_1: 60,
                    ..Default::default()
                };
                self.bytes.extend(encode_link_statistics(&ls));
            }
        }
    }

    /// Injects raw bytes (noise, corrupted frames) into the stream.
    pub fn inject_bytes(&mut self, bytes: &[u8]) {
        self.bytes.extend(bytes);
    }
}

impl RcInput for RcSource {
    fn read(&mut self, buf: &mut [u8]) -> usize {
        let n = buf.len().min(self.bytes.len());
        for (slot, b) in buf.iter_mut().zip(self.bytes.drain(..n)) {
            *slot = b;
        }
        n
    }
}
