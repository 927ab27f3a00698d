//! When to record the lift's position in flash, so that it survives a power cut.
//!
//! The encoder is incremental: after a power cut the board knows the height only from what it
//! wrote before. [`ParkLog`] watches the controller's state, position and homing each tick
//! ([`ParkLog::observe`]; [`ParkLog::step`] reads them from a [`Status`]) and says what to
//! write: [`Parked::Moving`] as soon as a motion starts (a cut from then on means "unknown,
//! home first"), and [`Parked::At`] once the lift has been at rest, with the encoder still,
//! for [`SETTLED_TICKS`] — after the coupling has unwound. Nothing is recorded while the
//! position is unknown (not homed): the stored state stays "moving" or absent, which is true.
//! The firmware writes only the newest request; a newer one replaces one not yet written.

use super::{State, Status};

/// What the lift's position was when the power went.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Parked {
    /// At rest at this encoder position (counts).
    At(i32),
    /// A motion had started and had not been recorded as finished: the position is unknown.
    Moving,
}

/// Ticks at rest with an unchanged encoder before the position is recorded (0.5 s at 1 kHz:
/// longer than the 300 ms settling the supervisor allows after a stop).
pub const SETTLED_TICKS: u32 = 500;

/// Decides what to record; one per controller.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ParkLog {
    /// What was last handed out to be written.
    recorded: Option<Parked>,
    /// Ticks at rest with the encoder where it was.
    still: u32,
    last_position: i32,
}

impl ParkLog {
    /// A log that knows what the flash holds now (`None`: nothing usable, e.g. unhomed boot).
    pub const fn new(stored: Option<Parked>) -> Self {
        Self {
            recorded: stored,
            still: 0,
            last_position: 0,
        }
    }

    /// One tick: what to write now, if anything.
    pub fn step(&mut self, s: &Status) -> Option<Parked> {
        self.observe(s.state, s.position, s.homed)
    }

    /// [`Self::step`] from the three values it reads (`Controller::state`,
    /// `Controller::position_counts`, `Controller::homed`): the firmware's control task calls
    /// this every tick, and builds the whole status only when it logs it.
    pub fn observe(&mut self, state: State, position: i32, homed: bool) -> Option<Parked> {
        let moving = matches!(state, State::Lifting | State::Lowering);
        if position == self.last_position && !moving {
            self.still = self.still.saturating_add(1);
        } else {
            self.still = 0;
        }
        self.last_position = position;
        let want = if moving {
            Parked::Moving
        } else if homed && self.still >= SETTLED_TICKS {
            Parked::At(position)
        } else {
            return None;
        };
        if self.recorded == Some(want) {
            return None;
        }
        self.recorded = Some(want);
        Some(want)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn status(state: State, position: i32, homed: bool) -> Status {
        Status {
            state,
            position,
            homed,
            ..Status::default()
        }
    }

    #[test]
    fn a_motion_is_marked_at_once_and_the_rest_position_once_settled() {
        let mut log = ParkLog::new(Some(Parked::At(100)));
        // At rest where the flash says: nothing to write.
        for _ in 0..2 * SETTLED_TICKS {
            assert_eq!(log.step(&status(State::Idle, 100, true)), None);
        }
        assert_eq!(
            log.step(&status(State::Lifting, 101, true)),
            Some(Parked::Moving)
        );
        for p in 102..400 {
            assert_eq!(log.step(&status(State::Lifting, p, true)), None);
        }
        // Stopped but still unwinding: nothing yet.
        for p in 400..420 {
            assert_eq!(log.step(&status(State::Holding, p, true)), None);
        }
        let mut got = None;
        for i in 0..=SETTLED_TICKS {
            if let Some(w) = log.step(&status(State::Holding, 420, true)) {
                assert_eq!(i, SETTLED_TICKS);
                got = Some(w);
            }
        }
        assert_eq!(got, Some(Parked::At(420)));
        assert_eq!(log.step(&status(State::Holding, 420, true)), None);
    }

    #[test]
    fn nothing_is_recorded_at_rest_while_unhomed() {
        let mut log = ParkLog::new(None);
        for _ in 0..3 * SETTLED_TICKS {
            assert_eq!(log.step(&status(State::Idle, 0, false)), None);
        }
        assert_eq!(
            log.step(&status(State::Lowering, -5, false)),
            Some(Parked::Moving)
        );
        for _ in 0..3 * SETTLED_TICKS {
            assert_eq!(log.step(&status(State::Holding, -50, false)), None);
        }
        // Homed: now the position is recorded.
        let hits = (0..2 * SETTLED_TICKS)
            .filter_map(|_| log.step(&status(State::Holding, 7_000, true)))
            .collect::<heapless::Vec<_, 4>>();
        assert_eq!(hits.as_slice(), &[Parked::At(7_000)]);
    }
}
