//! Persistent configuration: the whole [`ControlConfig`] as one versioned, CRC-checked record
//! in NOR flash, written power-fail-safe through `sequential-storage`.
//!
//! - [`settings`]: the registry of every setting by its console key (typed get/set on raw
//!   bits, unit and range for messages). The flash record is laid out in registry order.
//! - [`record`]: the record's fixed little-endian layout (magic, version, schema fingerprint,
//!   sequence number, one `i64` per stored setting, CRC-32).
//! - [`store`]: [`store::ConfigStore`], load (never fails: falls back to factory defaults and
//!   says why) and save over any blocking `embedded-storage` `NorFlash`.
//! - [`sim_flash`]: a simulated STM32G4-like flash with power-cut injection, for host tests.
//!
//! A configuration reaches the controller only as a [`ValidatedConfig`], which can only be
//! built through [`ControlConfig::validate`] and [`crate::estimator::Estimator::new`]: a value from the console
//! or from flash that fails either never leaves this module. docs/config-store.md describes the
//! scheme and the power-loss argument.

mod blocking;
mod position;
pub mod record;
pub mod settings;
pub mod sim_flash;
pub mod store;

#[cfg(all(test, not(feature = "ball-screw")))]
mod lead_only_tests;

use crate::control::config::ControlConfig;
use crate::ConfigError;

/// A [`ControlConfig`] that passed [`ControlConfig::validate`] against its own geometry and
/// [`crate::estimator::Estimator::new`]: the only form in which a configuration reaches the controller.
///
/// Replacing the controller's `ValidatedConfig` is one assignment between ticks, so a running
/// motion never sees a half-applied change.
#[derive(Clone, Copy, Debug, Eq)]
pub struct ValidatedConfig(ControlConfig);

/// Equal when every stored setting of the registry holds the same raw bits: the same as
/// `ControlConfig`'s field-by-field `==` (the stored settings cover every field, a
/// compile-time test in [`settings`] guards that, and raw bits identify a field's value), as
/// one loop over the table instead of a compare per field in the firmware (the store's
/// read-back check and the console's "nothing changes" test use it).
impl PartialEq for ValidatedConfig {
    fn eq(&self, other: &Self) -> bool {
        settings::SETTINGS
            .iter()
            .filter(|s| s.stored())
            .all(|s| s.get(&self.0) == s.get(&other.0))
            && (0..settings::OPAQUE_COUNT)
                .all(|j| settings::opaque_get(j, &self.0) == settings::opaque_get(j, &other.0))
    }
}

impl ValidatedConfig {
    /// Validate a whole configuration: the estimator's settings first (geometry, drive,
    /// mechanics, friction law, motor, tick), then motion, protections, sensing and the limit
    /// stops against the geometry.
    pub fn new(cfg: ControlConfig) -> Result<ValidatedConfig, ConfigError> {
        // The estimator as the controller builds it.
        let estimator = cfg.build_estimator()?;
        cfg.validate(estimator.geometry())?;
        Ok(ValidatedConfig(cfg))
    }

    /// The factory configuration ([`ControlConfig::DEFAULT`]; a unit test proves it valid). Its
    /// limit stops are the factory limits, inside the limit switches.
    pub const fn factory() -> ValidatedConfig {
        ValidatedConfig(ControlConfig::DEFAULT)
    }

    /// The configuration.
    pub const fn get(&self) -> &ControlConfig {
        &self.0
    }
}

impl Default for ValidatedConfig {
    fn default() -> Self {
        Self::factory()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn equality_is_the_configurations_field_by_field_equality() {
        let a = ControlConfig::DEFAULT;
        assert_eq!(ValidatedConfig(a), ValidatedConfig(a));
        for s in settings::SETTINGS.iter() {
            let raw = s.get(&a);
            for c in [raw.wrapping_add(1), raw.wrapping_sub(1), 0, 1] {
                let mut b = a;
                if s.set(&mut b, c) {
                    assert_eq!(
                        ValidatedConfig(a) == ValidatedConfig(b),
                        a == b,
                        "{}",
                        s.key
                    );
                }
            }
        }
    }

    #[test]
    fn factory_configuration_passes_validation() {
        assert_eq!(
            ValidatedConfig::new(ControlConfig::DEFAULT),
            Ok(ValidatedConfig::factory())
        );
    }
}
