//! # liftfw — portable control core of a screw-jack car scissor lift
//!
//! Everything that decides, computes or estimates lives here; the embassy firmware
//! (`src/main.rs`, `src/board/`) only moves numbers between the hardware and [`control::Controller::step`],
//! and `host-sim` runs the very same `step` against a float64 plant.
//!
//! The core is `no_std`, allocation-free and float-free on the hot path. Floats appear only
//! where a configuration is validated and quantised once (design in float, quantise once).
//!
//! Module map (data flows one way per tick: sensors → estimate → decide → actuators):
//! - [`units`]: typed fixed-point quantities with their Q formats.
//! - [`math`]: integer kernels (e^(−y), √, 1/x) with proven error bounds.
//! - [`model`]: the fixed-point screw-nut model of seed 000 (geometry, friction laws, contact).
//! - [`estimator`]: the real-time friction-torque estimator built on the model.
//! - [`detect`]: detectors on board-visible signals and the model's state (stick-slip).
//! - [`control`]: the per-tick entry point shared by the board and host-sim.
#![cfg_attr(not(test), no_std)]
#![forbid(unsafe_code)]
#![warn(missing_docs)]
#![cfg_attr(test, allow(clippy::unwrap_used, clippy::expect_used))]

pub mod config;
pub mod console;
pub mod control;
pub mod detect;
pub mod estimator;
pub mod math;
pub mod model;
pub mod text;
pub mod units;

/// A configuration value was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ConfigError {
    /// `field` lies outside `range`.
    OutOfRange {
        /// The setting's key, as the console names it.
        field: &'static str,
        /// Its accepted range with unit.
        range: &'static str,
    },
    /// `field` contradicts another setting.
    Conflict {
        /// The setting's key, as the console names it.
        field: &'static str,
        /// What it must satisfy.
        reason: &'static str,
    },
}

impl ConfigError {
    /// The message (its `Display`), written without `core::fmt`'s machinery
    /// ([`console::fill`]).
    pub fn write_to(&self, out: &mut dyn core::fmt::Write) -> core::fmt::Result {
        use console::{fill, Arg};
        match self {
            ConfigError::OutOfRange { field, range } => fill(
                out,
                "\x01 out of range (allowed \x01)",
                &[Arg::Str(field), Arg::Str(range)],
            ),
            ConfigError::Conflict { field, reason } => {
                fill(out, "\x01: \x01", &[Arg::Str(field), Arg::Str(reason)])
            }
        }
    }
}

impl core::fmt::Display for ConfigError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        self.write_to(f)
    }
}

/// One row of a range table ([`check_bounds`]): `lo ≤ v ≤ hi` on a quantity's raw bits
/// (`to_bits`, or the integer itself), else [`ConfigError::OutOfRange`] naming the setting at
/// position `setting` of [`config::settings::SETTINGS`] with its range text (the registry's
/// range is the text of the check: one copy of both strings, and 12 bytes a row).
pub(crate) struct Bound {
    pub lo: i32,
    pub hi: i32,
    pub setting: u8,
}

impl Bound {
    /// The row of the setting with this key ([`config::settings::key_index`]: a compile-time
    /// error if there is none).
    pub const fn new(lo: i32, hi: i32, key: &str) -> Bound {
        Bound {
            lo,
            hi,
            setting: config::settings::key_index(key),
        }
    }
}

/// [`check_range`] over a table, in order: the first value outside its row's bounds is the
/// error. One out-of-line loop over constant rows instead of one inlined check (with its own
/// error path and string loads) per setting.
pub(crate) fn check_bounds<const N: usize>(
    values: [i32; N],
    bounds: &'static [Bound; N],
) -> Result<(), ConfigError> {
    check_bounds_slice(&values, bounds)
}

/// [`check_bounds`]' one copy for every table length.
#[inline(never)]
fn check_bounds_slice(values: &[i32], bounds: &'static [Bound]) -> Result<(), ConfigError> {
    for (&v, b) in values.iter().zip(bounds) {
        if v < b.lo || v > b.hi {
            // Rows are made by `Bound::new`, so the index is in bounds; `get` keeps it total.
            let all = &config::settings::SETTINGS;
            let s = all.get(usize::from(b.setting)).unwrap_or(&all[0]);
            return Err(ConfigError::OutOfRange {
                field: s.key,
                range: s.range,
            });
        }
    }
    Ok(())
}

/// `Ok` if `lo ≤ v ≤ hi`, else [`ConfigError::OutOfRange`] naming `field` and `range`: a single
/// range check (a run of them on one configuration type is smaller as a [`check_bounds`] table).
pub(crate) fn check_range<T: PartialOrd>(
    v: T,
    lo: T,
    hi: T,
    field: &'static str,
    range: &'static str,
) -> Result<(), ConfigError> {
    if v >= lo && v <= hi {
        Ok(())
    } else {
        Err(ConfigError::OutOfRange { field, range })
    }
}
