//! Typed fixed-point quantities.
//!
//! Placeholder until the fixed-point model lands: only time is needed by the control skeleton.

/// A point in time, in microseconds since boot, wrapping every 2^32 µs (71.6 min).
///
/// Only differences of instants are meaningful; they are taken with wrapping arithmetic,
/// so a wrap is harmless as long as two compared instants are less than 35 min apart.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Instant(pub u32);

impl Instant {
    /// Microseconds elapsed from `earlier` to `self` (wrapping).
    #[inline]
    pub fn micros_since(self, earlier: Instant) -> u32 {
        self.0.wrapping_sub(earlier.0)
    }
}
