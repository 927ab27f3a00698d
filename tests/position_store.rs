//! The parked-position record in the configuration store (simulated flash): round trip, the
//! "moving" marker and a changed geometry both mean "unknown" (homing), and a power cut at
//! every step of a position write leaves the previous or the new state, never a wrong
//! position, and never costs the stored configuration.
#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)]

use liftfw::config::sim_flash::{CutMode, SimFlash, ERASE_SIZE};
use liftfw::config::store::{geometry_stamp, ConfigStore, Parked};
use liftfw::config::ValidatedConfig;
use liftfw::control::config::ControlConfig;
use liftfw::units::Metres;

const SIZE: usize = 4 * ERASE_SIZE;
type Flash = SimFlash<SIZE>;

fn store(flash: Flash) -> ConfigStore<Flash> {
    ConfigStore::new(flash, 0..SIZE as u32).unwrap()
}

fn stamp() -> u32 {
    geometry_stamp(&ControlConfig::DEFAULT)
}

fn custom() -> ValidatedConfig {
    let mut c = ControlConfig::DEFAULT;
    c.limits.upper = Metres::from_f64(0.380);
    ValidatedConfig::new(c).unwrap()
}

#[test]
fn nothing_stored_means_unknown() {
    let mut s = store(Flash::new());
    s.load();
    assert_eq!(s.load_position(stamp()), None);
}

#[test]
fn a_parked_position_survives_a_reboot_and_moving_means_unknown() {
    let mut s = store(Flash::new());
    s.load();
    s.save_position(Parked::At(12_345), stamp()).unwrap();
    let mut s = store(s.into_flash());
    s.load();
    assert_eq!(s.load_position(stamp()), Some(12_345));
    s.save_position(Parked::Moving, stamp()).unwrap();
    let mut s = store(s.into_flash());
    assert_eq!(s.load_position(stamp()), None);
    s.save_position(Parked::At(-7), stamp()).unwrap();
    let mut s = store(s.into_flash());
    assert_eq!(s.load_position(stamp()), Some(-7));
}

#[test]
fn a_position_counted_with_another_geometry_is_not_used() {
    let mut s = store(Flash::new());
    s.save_position(Parked::At(5_000), stamp()).unwrap();
    let mut other = ControlConfig::DEFAULT;
    other.estimator.drive.counts_per_rev = 64;
    assert_ne!(geometry_stamp(&other), stamp());
    assert_eq!(s.load_position(geometry_stamp(&other)), None);
    // Settings that do not change what a count means keep it.
    let mut faster = ControlConfig::DEFAULT;
    faster.motion.ramp_ms = 120;
    assert_eq!(s.load_position(geometry_stamp(&faster)), Some(5_000));
}

#[test]
fn many_position_writes_keep_the_configuration_and_the_newest_position() {
    // Enough writes to fill and recycle every page several times.
    let mut s = store(Flash::new());
    s.load();
    s.save(&custom()).unwrap();
    for i in 0..400 {
        s.save_position(Parked::Moving, stamp()).unwrap();
        s.save_position(Parked::At(i * 10), stamp()).unwrap();
    }
    let mut s = store(s.into_flash());
    let loaded = s.load();
    assert_eq!(loaded.config, custom(), "{}", loaded.source);
    assert_eq!(s.load_position(stamp()), Some(3_990));
}

/// Cut the power at every step of one position write (from `from` to `to`, after `history`
/// earlier writes): afterwards the store reports `from` or `to`, and the configuration loads.
fn cut_every_step(history: i32, from: Parked, to: Parked, mode: CutMode) -> (u32, u32) {
    let known = |p: Parked| match p {
        Parked::At(c) => Some(c),
        Parked::Moving => None,
    };
    let before = {
        let mut s = store(Flash::new());
        s.load();
        s.save(&custom()).unwrap();
        for i in 0..history {
            s.save_position(Parked::At(1_000 + i), stamp()).unwrap();
        }
        s.save_position(from, stamp()).unwrap();
        s.into_flash()
    };
    let steps = {
        let mut s = store(before.clone());
        s.load();
        s.load_position(stamp());
        let start = s.flash().steps();
        s.save_position(to, stamp()).unwrap();
        s.flash().steps() - start
    };
    let (mut old, mut new) = (0, 0);
    for step in 0..steps {
        let mut s = store(before.clone());
        s.load();
        s.load_position(stamp());
        s.flash().cut_after(step, mode);
        assert!(s.save_position(to, stamp()).is_err());
        let mut flash = s.into_flash();
        flash.reboot();
        let mut s = store(flash);
        let loaded = s.load();
        assert_eq!(loaded.config, custom(), "step {step}: {}", loaded.source);
        let got = s.load_position(stamp());
        if got == known(to) && known(to) != known(from) {
            new += 1;
        } else {
            assert_eq!(got, known(from), "step {step} of {steps} ({mode:?})");
            old += 1;
        }
    }
    (old, new)
}

#[test]
fn power_loss_while_marking_a_motion_keeps_the_parked_position_or_says_unknown() {
    for history in [0, 37] {
        for mode in [CutMode::Clean, CutMode::Torn { seed: 7 }] {
            let (old, new) = cut_every_step(history, Parked::At(4_321), Parked::Moving, mode);
            assert!(old > 0 && new > 0, "{old} {new}");
        }
    }
}

#[test]
fn power_loss_while_parking_says_unknown_or_the_new_position() {
    for history in [0, 37] {
        for mode in [CutMode::Clean, CutMode::Torn { seed: 7 }] {
            let (old, new) = cut_every_step(history, Parked::Moving, Parked::At(2_468), mode);
            assert!(old > 0 && new > 0, "{old} {new}");
        }
    }
}
