//! The settings registry: every field of [`ControlConfig`] by its console key.
//!
//! Each [`Setting`] reads and writes its field as raw bits in an `i64` (the Q format's bits, an
//! integer, or a choice index), knows its unit for parsing and display and its accepted range
//! for messages. Range checks themselves stay where they are defined
//! ([`ControlConfig::validate`], [`crate::estimator::Estimator::new`]): [`apply`] changes one
//! field of a copy and re-validates the whole configuration, so a refused change leaves the
//! running one untouched. The flash record ([`crate::config::record`]) stores the `stored`
//! settings in this table's order.

mod registry;
mod slot;
mod unit;

use crate::config::ValidatedConfig;
use crate::control::config::{ButtonMode, ControlConfig, RampShape, ScrewKind};
use crate::detect::stickslip::Reaction;
use crate::model::friction::{FrictionLaw, LawVariable};
use crate::units::{
    Amperes, Kilograms, Metres, NewtonMetres, Newtons, RadiansPerSecond, Ratio, Volts,
};
use crate::ConfigError;
use fixed::types::{I16F16, I32F32};
use registry::slot;
pub(crate) use registry::{opaque_get, opaque_set};
pub use registry::{stored_at, BALL_KEYS, LAW_PRESETS, OPAQUE_COUNT, SETTINGS};
pub use unit::*;

/// One configurable field.
#[non_exhaustive]
pub struct Setting {
    /// Console key (lower case, as [`ConfigError`] names it).
    pub key: &'static str,
    /// Raw-bits interpretation.
    pub kind: Kind,
    /// Accepted range, for messages (the text of the validation that checks it).
    pub range: &'static str,
    /// One line of help, for a person on a host: only with the `help-text` feature (liftctl
    /// and host-sim turn it on; the firmware leaves the text and this field out and
    /// its `help <key>` gives unit and range). Read it through [`Setting::about`].
    #[cfg(feature = "help-text")]
    pub(super) about: &'static str,
    // No other field, so that the table stays small. Whether it is stored
    // ([`Setting::stored`]) and its position (the field [`Setting::get`] and [`Setting::set`]
    // reach) come from where it is in [`SETTINGS`].
}

impl core::fmt::Debug for Setting {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("Setting").field("key", &self.key).finish()
    }
}

impl Setting {
    /// The one line of help, if this build has the help texts (feature `help-text`).
    #[cfg(feature = "help-text")]
    pub fn about(&self) -> Option<&'static str> {
        Some(self.about)
    }

    /// The one line of help, if this build has the help texts (feature `help-text`).
    #[cfg(not(feature = "help-text"))]
    pub fn about(&self) -> Option<&'static str> {
        None
    }

    /// Its position in [`SETTINGS`]. Every `Setting` is one of that table's (it is
    /// `#[non_exhaustive]`, so no other crate can make one, this crate makes them only there,
    /// and it is not `Clone`): the position is its address's distance from the table's start.
    pub fn index(&self) -> usize {
        let at = core::ptr::from_ref(self).addr();
        at.wrapping_sub(SETTINGS.as_ptr().addr()) / core::mem::size_of::<Setting>()
    }

    /// Part of the flash record (false only for derived settings such as `friction.law`).
    pub fn stored(&self) -> bool {
        stored_at(self.index())
    }

    /// The field's raw bits in `cfg`. (Through a copy: the registry reaches its fields by one
    /// `&mut` access (`slot`) for both directions.)
    pub fn get(&self, cfg: &ControlConfig) -> i64 {
        let mut c = *cfg;
        slot(self.index(), &mut c).read()
    }

    /// Write raw bits into the field; false (and `cfg` unchanged) if they do not fit its type.
    /// No range check: see [`apply`].
    pub fn set(&self, cfg: &mut ControlConfig, raw: i64) -> bool {
        slot(self.index(), cfg).write(raw)
    }
}

/// Index of a setting in [`SETTINGS`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SettingId(u8);

impl SettingId {
    /// The setting.
    pub fn setting(self) -> &'static Setting {
        // Ids are only made by `find`/`all`, so the index is in bounds; `get` keeps it total.
        SETTINGS.get(usize::from(self.0)).unwrap_or(&SETTINGS[0])
    }

    /// Its console key.
    pub fn key(self) -> &'static str {
        self.setting().key
    }

    /// Position in [`SETTINGS`].
    pub fn index(self) -> usize {
        usize::from(self.0)
    }
}

/// The setting with this key (ASCII case-insensitive), given as text or bytes (the console
/// parses lines as bytes).
pub fn find(key: &(impl AsRef<[u8]> + ?Sized)) -> Option<SettingId> {
    find_bytes(key.as_ref())
}

fn find_bytes(key: &[u8]) -> Option<SettingId> {
    SETTINGS
        .iter()
        .position(|s| s.key.as_bytes().eq_ignore_ascii_case(key))
        .map(|i| SettingId(i as u8))
}

/// Every setting, in registry order.
pub fn all() -> impl Iterator<Item = SettingId> {
    (0..SETTINGS.len()).map(|i| SettingId(i as u8))
}

/// Change one setting of a copy of `cfg` and validate the whole copy; the copy is returned
/// only if it is valid. Raw bits that do not fit the field's type are refused with the
/// setting's own range.
pub fn apply(
    cfg: &ValidatedConfig,
    id: SettingId,
    raw: i64,
) -> Result<ValidatedConfig, ConfigError> {
    let s = id.setting();
    let mut next = *cfg.get();
    if !s.set(&mut next, raw) {
        return Err(ConfigError::OutOfRange {
            field: s.key,
            range: s.range,
        });
    }
    ValidatedConfig::new(next)
}

/// The console's message template for a key [`find`] does not know (`\x01`: the key, then the
/// pointer to `help keys`): without the `ball-screw` feature a `ballscrew.*` key is not unknown
/// but needs the other image.
pub fn unknown_key_template(key: &[u8]) -> &'static str {
    let ball = key
        .get(..BALL_PREFIX.len())
        .is_some_and(|p| p.eq_ignore_ascii_case(BALL_PREFIX.as_bytes()));
    if ball && !cfg!(feature = "ball-screw") {
        "'\x01' needs the ball-screw firmware (this is the lead-screw image)\x01"
    } else {
        "unknown key '\x01'\x01"
    }
}

/// The ball-screw variant's keys' common prefix (liftctl tells a lead-screw board's refusal
/// of them by it).
pub const BALL_PREFIX: &str = "ballscrew.";

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn brake_settings_are_validated() {
        let cfg = ValidatedConfig::factory();
        assert!(!cfg.get().brake.present);
        let brake = find("drive.brake").unwrap();
        let on = apply(&cfg, brake, 1).unwrap();
        assert!(on.get().brake.present);
        assert!(apply(&cfg, brake, 2).is_err());
        let ms = find("drive.brake_ms").unwrap();
        assert_eq!(apply(&on, ms, 5).unwrap().get().brake.delay_ms, 5);
        assert_eq!(apply(&on, ms, 1000).unwrap().get().brake.delay_ms, 1000);
        for bad in [0, 4, 1001] {
            assert_eq!(
                apply(&on, ms, bad).unwrap_err(),
                ConfigError::OutOfRange {
                    field: "drive.brake_ms",
                    range: "5..1000 ms"
                }
            );
        }
    }

    #[test]
    fn refused_change_names_the_field_and_keeps_the_config() {
        let cfg = ValidatedConfig::factory();
        let lower = find("limits.lower").unwrap();
        let e = apply(&cfg, lower, Metres::lit("0.405").to_bits().into()).unwrap_err();
        assert_eq!(
            e,
            ConfigError::Conflict {
                field: "limits.lower",
                reason: "must be at least 10 mm below limits.upper"
            }
        );
        let ramp = find("motion.ramp_ms").unwrap();
        let e = apply(&cfg, ramp, -1).unwrap_err();
        assert_eq!(
            e,
            ConfigError::OutOfRange {
                field: "motion.ramp_ms",
                range: "10..2000 ms"
            }
        );
    }
}
