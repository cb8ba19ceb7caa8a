//! From CRSF frames to what the supervisor needs: a velocity command, the arm request and
//! whether the link is alive (failsafe).
//!
//! Channel assignment (AETR, mode 2): ch1 roll -> lateral velocity vy, ch2 pitch -> forward
//! velocity vx, ch4 yaw -> turn rate wz, ch5 (AUX1) -> arm switch. Right stick to the right
//! moves right (negative vy); yaw stick to the right turns clockwise (negative wz).
//!
//! Failsafe: the link counts as lost when no RC channels frame arrived for
//! `RcConfig::timeout_us`, or the receiver reports 0 % uplink link quality. While lost
//! the command is zero and the arm request is off.

use super::crsf::{CrsfFrame, CrsfParser, CHANNEL_MAX, CHANNEL_MID, CHANNEL_MIN, NUM_CHANNELS};

/// Mapping and failsafe parameters. The full-stick speeds default to the command ranges
/// the policy is trained on (`host-sim`'s default `commands`: 0.5 m/s, 0.3 m/s, 0.5 rad/s).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RcConfig {
    /// Forward speed at full stick, m/s.
    pub vx_max_m_s: f32,
    /// Lateral speed at full stick, m/s.
    pub vy_max_m_s: f32,
    /// Turn rate at full stick, rad/s.
    pub wz_max_rad_s: f32,
    /// Stick deadband around centre, fraction of half travel.
    pub deadband: f32,
    /// No channels for this long = link lost, microseconds.
    pub timeout_us: u64,
    /// Arm switch threshold (channel value).
    pub arm_threshold: u16,
}

impl Default for RcConfig {
    fn default() -> Self {
        Self {
            vx_max_m_s: 0.5,
            vy_max_m_s: 0.3,
            wz_max_rad_s: 0.5,
            deadband: 0.05,
            timeout_us: 200_000,
            arm_threshold: 1400,
        }
    }
}

/// What the operator asks for now.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RcState {
    /// Velocity command (vx m/s, vy m/s, wz rad/s), base frame; zero in failsafe.
    pub command: [f32; 3],
    /// Arm switch on (false in failsafe).
    pub arm: bool,
    /// Link alive.
    pub link_ok: bool,
}

impl RcState {
    /// The failsafe state.
    pub const FAILSAFE: Self = Self {
        command: [0.0; 3],
        arm: false,
        link_ok: false,
    };
}

/// The receiver: parser, last channels, failsafe.
#[derive(Clone, Debug)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RcReceiver {
    /// The CRSF parser (with its error counters).
    pub parser: CrsfParser,
    config: RcConfig,
    channels: [u16; NUM_CHANNELS],
    last_channels_us: Option<u64>,
    link_quality_zero: bool,
}

impl RcReceiver {
    /// A receiver that has not heard anything yet (failsafe).
    pub const fn new(config: RcConfig) -> Self {
        Self {
            parser: CrsfParser::new(),
            config,
            channels: [CHANNEL_MID; NUM_CHANNELS],
            last_channels_us: None,
            link_quality_zero: false,
        }
    }

    /// Feeds received UART bytes.
    pub fn feed(&mut self, bytes: &[u8], now_us: u64) {
        for &b in bytes {
            match self.parser.push(b) {
                Some(CrsfFrame::RcChannels(ch)) => {
                    self.channels = ch;
                    self.last_channels_us = Some(now_us);
                }
                Some(CrsfFrame::LinkStatistics(ls)) => {
                    self.link_quality_zero = ls.uplink_link_quality == 0;
                }
                _ => {}
            }
        }
    }

    /// The operator's request at `now_us`.
    pub fn state(&self, now_us: u64) -> RcState {
        let fresh = self
            .last_channels_us
            .is_some_and(|t| now_us.saturating_sub(t) <= self.config.timeout_us);
        if !fresh || self.link_quality_zero {
            return RcState::FAILSAFE;
        }
        let c = &self.config;
        let stick = |v: u16| normalize(v, c.deadband);
        RcState {
            command: [
                c.vx_max_m_s * stick(self.channels[1]),
                -c.vy_max_m_s * stick(self.channels[0]),
                -c.wz_max_rad_s * stick(self.channels[3]),
            ],
            arm: self.channels[4] > c.arm_threshold,
            link_ok: true,
        }
    }
}

/// Channel value to [-1, 1] with a deadband, rescaled so full stick is 1.
fn normalize(v: u16, deadband: f32) -> f32 {
    let half = (CHANNEL_MAX - CHANNEL_MIN) as f32 / 2.0;
    let x = ((v as f32 - CHANNEL_MID as f32) / half).clamp(-1.0, 1.0);
    if x.abs() <= deadband {
        0.0
    } else {
        (x - deadband * x.signum()) / (1.0 - deadband)
    }
}

#[cfg(test)]
mod tests {
    use super::super::crsf::{encode_link_statistics, encode_rc_channels, LinkStatistics};
    use super::*;

    fn channels(pitch: u16, roll: u16, yaw: u16, arm: u16) -> [u16; NUM_CHANNELS] {
        let mut ch = [CHANNEL_MID; NUM_CHANNELS];
        ch[0] = roll;
        ch[1] = pitch;
        ch[3] = yaw;
        ch[4] = arm;
        ch
    }

    #[test]
    fn sticks_map_to_the_command() {
        let mut rx = RcReceiver::new(RcConfig::default());
        assert_eq!(rx.state(0), RcState::FAILSAFE);
        rx.feed(
            &encode_rc_channels(&channels(
                CHANNEL_MAX,
                CHANNEL_MAX,
                CHANNEL_MIN,
                CHANNEL_MAX,
            )),
            1_000,
        );
        let s = rx.state(2_000);
        assert!(s.link_ok && s.arm);
        let c = RcConfig::default();
        assert!((s.command[0] - c.vx_max_m_s).abs() < 0.01, "{s:?}");
        assert!((s.command[1] + c.vy_max_m_s).abs() < 0.01, "{s:?}");
        assert!((s.command[2] - c.wz_max_rad_s).abs() < 0.01, "{s:?}");
        rx.feed(
            &encode_rc_channels(&channels(
                CHANNEL_MID + 20,
                CHANNEL_MID,
                CHANNEL_MID,
                CHANNEL_MIN,
            )),
            3_000,
        );
        let s = rx.state(3_000);
        assert_eq!(s.command, [0.0; 3], "inside the deadband");
        assert!(!s.arm);
    }

    #[test]
    fn failsafe_after_timeout_or_zero_link_quality() {
        let mut rx = RcReceiver::new(RcConfig::default());
        rx.feed(
            &encode_rc_channels(&channels(
                CHANNEL_MAX,
                CHANNEL_MID,
                CHANNEL_MID,
                CHANNEL_MAX,
            )),
            0,
        );
        assert!(rx.state(200_000).arm);
        assert_eq!(rx.state(200_001), RcState::FAILSAFE);
        rx.feed(
            &encode_rc_channels(&channels(
                CHANNEL_MAX,
                CHANNEL_MID,
                CHANNEL_MID,
                CHANNEL_MAX,
            )),
            300_000,
        );
        assert!(rx.state(300_000).link_ok);
        let lost = LinkStatistics {
            uplink_link_quality: 0,
            ..Default::default()
        };
        rx.feed(&encode_link_statistics(&lost), 300_000);
        assert_eq!(rx.state(300_000), RcState::FAILSAFE);
    }
}
