//! A settable clock for host tests: implements [`hexapod_core::hal::Clock`].

use core::cell::Cell;

use hexapod_core::hal::Clock;

/// Simulation time that only moves when told to.
#[derive(Clone, Debug, Default)]
pub struct MockClock {
    now_us: Cell<u64>,
}

impl MockClock {
    /// A clock at `start_us`.
    pub fn new(start_us: u64) -> Self {
        Self {
            now_us: Cell::new(start_us),
        }
    }

    /// Moves time forward by `dt_us` (time never goes back).
    pub fn advance(&self, dt_us: u64) {
        self.now_us.set(self.now_us.get().saturating_add(dt_us));
    }
}

impl Clock for MockClock {
    fn now_us(&self) -> u64 {
        self.now_us.get()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn advances_monotonically() {
        let c = MockClock::new(5);
        c.advance(10);
        assert_eq!(c.now_us(), 15);
        c.advance(u64::MAX);
        assert_eq!(c.now_us(), u64::MAX);
    }
}
