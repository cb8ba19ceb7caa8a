//! The CiA 402 power drive state machine: statusword decoding and controlword commands.
//!
//! ```text
//! Not ready to switch on -> Switch on disabled -(shutdown)-> Ready to switch on
//!   -(switch on)-> Switched on -(enable operation)-> Operation enabled
//! Operation enabled -(quick stop)-> Quick stop active; any state -(fault)-> Fault
//!   -(fault reset, rising edge of bit 7)-> Switch on disabled
//! ```

/// Controlword "shutdown": -> Ready to switch on.
pub const CW_SHUTDOWN: u16 = 0x0006;
/// Controlword "switch on" (also "disable operation"): -> Switched on.
pub const CW_SWITCH_ON: u16 = 0x0007;
/// Controlword "enable operation": -> Operation enabled.
pub const CW_ENABLE_OPERATION: u16 = 0x000F;
/// Controlword "disable voltage": -> Switch on disabled (torque off).
pub const CW_DISABLE_VOLTAGE: u16 = 0x0000;
/// Controlword "quick stop": -> Quick stop active.
pub const CW_QUICK_STOP: u16 = 0x0002;
/// Controlword bit 7: fault reset (acts on the rising edge).
pub const CW_FAULT_RESET: u16 = 0x0080;

/// Statusword bit 3: fault.
pub const SW_FAULT: u16 = 1 << 3;
/// Statusword bit 4: voltage enabled.
pub const SW_VOLTAGE_ENABLED: u16 = 1 << 4;
/// Statusword bit 5: quick stop (active low: 0 while a quick stop runs).
pub const SW_QUICK_STOP: u16 = 1 << 5;
/// Statusword bit 7: warning.
pub const SW_WARNING: u16 = 1 << 7;
/// Statusword bit 9: remote (the controlword is processed).
pub const SW_REMOTE: u16 = 1 << 9;
/// Statusword bit 10: target reached.
pub const SW_TARGET_REACHED: u16 = 1 << 10;
/// Statusword bit 12 in CSP mode: the drive follows the target.
pub const SW_CSP_FOLLOWING: u16 = 1 << 12;

/// A state of the power drive state machine.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum PowerState {
    /// Initialising.
    NotReadyToSwitchOn,
    /// Power stage off, waiting for "shutdown".
    SwitchOnDisabled,
    /// Ready to switch on.
    ReadyToSwitchOn,
    /// Power stage on, no torque.
    SwitchedOn,
    /// Following targets with torque on.
    OperationEnabled,
    /// Stopping or holding after a quick stop (torque on).
    QuickStopActive,
    /// Reacting to a fault.
    FaultReactionActive,
    /// Faulted: torque off.
    Fault,
}

impl PowerState {
    /// Decodes the state bits of a statusword (CiA 402 table 30).
    pub fn from_statusword(sw: u16) -> Self {
        match (sw & 0x4F, sw & 0x6F) {
            (0x00, _) => Self::NotReadyToSwitchOn,
            (0x40, _) => Self::SwitchOnDisabled,
            (0x0F, _) => Self::FaultReactionActive,
            (0x08, _) => Self::Fault,
            (_, 0x21) => Self::ReadyToSwitchOn,
            (_, 0x23) => Self::SwitchedOn,
            (_, 0x27) => Self::OperationEnabled,
            (_, 0x07) => Self::QuickStopActive,
            // Undefined combinations are treated as the safest reading.
            _ => Self::Fault,
        }
    }

    /// The state bits of the statusword (bits 0-3, 5, 6) for this state.
    pub fn statusword_bits(self) -> u16 {
        match self {
            Self::NotReadyToSwitchOn => 0x00,
            Self::SwitchOnDisabled => 0x40,
            Self::ReadyToSwitchOn => 0x21,
            Self::SwitchedOn => 0x23,
            Self::OperationEnabled => 0x27,
            Self::QuickStopActive => 0x07,
            Self::FaultReactionActive => 0x0F,
            Self::Fault => 0x08,
        }
    }

    /// True when the drive produces torque.
    pub fn torque_on(self) -> bool {
        matches!(
            self,
            Self::OperationEnabled | Self::QuickStopActive | Self::FaultReactionActive
        )
    }
}

/// What the master wants a drive to do.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum DriveRequest {
    /// Reach and stay in Operation enabled (torque on, following targets).
    Enable,
    /// Torque off via "disable voltage" (Switch on disabled); no fault reset.
    Disable,
    /// Hold via quick stop.
    QuickStop,
    /// Clear a fault (rising edge of bit 7), then stay disabled.
    FaultReset,
}

/// The controlword that moves a drive in `state` one step toward `request`.
///
/// `previous` is the controlword sent last cycle: a fault reset needs bit 7 low first, so
/// the reset is sent as a 0 -> 1 edge over two cycles.
pub fn next_controlword(state: PowerState, request: DriveRequest, previous: u16) -> u16 {
    use PowerState as S;
    match request {
        DriveRequest::Enable => match state {
            S::SwitchOnDisabled | S::NotReadyToSwitchOn => CW_SHUTDOWN,
            S::ReadyToSwitchOn => CW_SWITCH_ON,
            S::SwitchedOn | S::OperationEnabled => CW_ENABLE_OPERATION,
            // Quick stop active is left only by a deliberate recovery (the master sets the
            // target to the drive's position first, see `Master::send_commands`): keep it.
            S::QuickStopActive => CW_QUICK_STOP,
            // A faulted drive is never re-enabled implicitly.
            S::Fault | S::FaultReactionActive => CW_DISABLE_VOLTAGE,
        },
        DriveRequest::Disable => CW_DISABLE_VOLTAGE,
        DriveRequest::QuickStop => match state {
            S::OperationEnabled | S::QuickStopActive => CW_QUICK_STOP,
            _ => CW_DISABLE_VOLTAGE,
        },
        DriveRequest::FaultReset => match state {
            S::Fault if previous & CW_FAULT_RESET == 0 => CW_FAULT_RESET,
            _ => CW_DISABLE_VOLTAGE,
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const ALL: [PowerState; 8] = [
        PowerState::NotReadyToSwitchOn,
        PowerState::SwitchOnDisabled,
        PowerState::ReadyToSwitchOn,
        PowerState::SwitchedOn,
        PowerState::OperationEnabled,
        PowerState::QuickStopActive,
        PowerState::FaultReactionActive,
        PowerState::Fault,
    ];

    #[test]
    fn statusword_bits_round_trip_with_other_bits_set() {
        for s in ALL {
            let sw = s.statusword_bits() | SW_REMOTE | SW_VOLTAGE_ENABLED | SW_TARGET_REACHED;
            assert_eq!(PowerState::from_statusword(sw), s, "{sw:#06x}");
        }
        // Typical real statusword of an enabled drive in CSP.
        assert_eq!(
            PowerState::from_statusword(0x1637),
            PowerState::OperationEnabled
        );
        assert_eq!(
            PowerState::from_statusword(0x0250),
            PowerState::SwitchOnDisabled
        );
    }

    #[test]
    fn enable_walks_the_state_machine() {
        let mut s = PowerState::SwitchOnDisabled;
        let mut steps = 0;
        while s != PowerState::OperationEnabled {
            let cw = next_controlword(s, DriveRequest::Enable, 0);
            s = match (s, cw) {
                (PowerState::SwitchOnDisabled, CW_SHUTDOWN) => PowerState::ReadyToSwitchOn,
                (PowerState::ReadyToSwitchOn, CW_SWITCH_ON) => PowerState::SwitchedOn,
                (PowerState::SwitchedOn, CW_ENABLE_OPERATION) => PowerState::OperationEnabled,
                other => panic!("unexpected {other:?}"),
            };
            steps += 1;
        }
        assert_eq!(steps, 3);
    }

    #[test]
    fn quick_stop_active_is_not_left_implicitly() {
        assert_eq!(
            next_controlword(PowerState::QuickStopActive, DriveRequest::Enable, 0x000F),
            CW_QUICK_STOP
        );
        // Disabling from Quick stop active (transition 12) stays possible.
        assert_eq!(
            next_controlword(PowerState::QuickStopActive, DriveRequest::Disable, 0x0002),
            CW_DISABLE_VOLTAGE
        );
    }

    #[test]
    fn fault_reset_is_an_edge() {
        assert_eq!(
            next_controlword(PowerState::Fault, DriveRequest::FaultReset, 0),
            0x80
        );
        assert_eq!(
            next_controlword(PowerState::Fault, DriveRequest::FaultReset, 0x80),
            0
        );
        assert_eq!(
            next_controlword(PowerState::Fault, DriveRequest::Enable, 0),
            0
        );
    }
}
