//! The lead-screw image (built without the `ball-screw` feature) on a ball screw's record and
//! console: it carries the ball screw's values through, never falls back to factory defaults
//! on a ball-screw lift, locks it out with the motor braked and refuses every ball-screw key
//! and value. Compiled only without the feature: `cargo test -p liftfw --lib` (the root's
//! dev-dependency on host-sim leaves the feature off) runs them; `cargo test --workspace`
//! builds the ball-screw variant and skips them.
#![allow(clippy::unwrap_used, clippy::expect_used)]

extern crate std;
use std::string::String;
use std::vec::Vec;

use super::record::{self, HEADER_LEN};
use super::settings::{self, BALL_KEYS, OPAQUE_COUNT, SETTINGS};
use super::sim_flash::{SimFlash, ERASE_SIZE};
use super::store::{ConfigStore, Parked, Source, StoreError};
use super::ValidatedConfig;
use crate::console::service;
use crate::control::config::NEEDS_BALL_SCREW;
use crate::control::config::{ControlConfig, ScrewKind};
use crate::control::{Bridge, Command, Controller, FaultKind, Inputs, Refusal, State};
use crate::model::friction::{FrictionLaw, LawVariable};
use crate::units::{Instant, Metres, Newtons, Ratio};
use crate::ConfigError;

const SIZE: usize = 4 * ERASE_SIZE;
type Flash = SimFlash<SIZE>;

/// The proof that this is the lead-screw build: the ball screw's keys are no settings, and
/// the record holds their 15 values as opaque words. Fails (and the module does not build) with
/// the feature.
#[test]
fn this_build_is_the_lead_screw_variant() {
    const { assert!(!cfg!(feature = "ball-screw")) };
    assert_eq!(OPAQUE_COUNT, 15);
    assert_eq!(SETTINGS.len(), 58);
    for k in BALL_KEYS {
        assert!(settings::find(k).is_none(), "{k}");
    }
    // The record is as long as the ball-screw build's: same format, same version.
    assert_eq!(record::record_len(), HEADER_LEN + 8 * 72 + 4);
}

/// A ball screw's configuration with some ball-screw values changed from the factory's (as the
/// ball-screw firmware would have saved it).
fn ball_lift() -> ControlConfig {
    let mut c = ControlConfig::DEFAULT;
    c.screw = ScrewKind::Ball;
    c.ball_screw.preload = Newtons::lit("1500");
    c.ball_screw.loaded_balls = 52;
    c.ball_screw.r_m = Metres::lit("0.016");
    c.lube.band = Ratio::lit("0.3");
    c
}

/// A store whose both copies hold `cfg` as record `seq` (written as another firmware wrote it:
/// this one would refuse to save it).
fn store_with(cfgs: [(&ControlConfig, u32); 2]) -> ConfigStore<Flash> {
    let mut s = ConfigStore::new(Flash::new(), 0..SIZE as u32).unwrap();
    for (copy, (cfg, seq)) in cfgs.into_iter().enumerate() {
        s.put_record_for_tests(copy, cfg, seq).unwrap();
    }
    ConfigStore::new(s.into_flash(), 0..SIZE as u32).unwrap()
}

/// `drive.screw = ball` stored: no factory fallback to run on, the record kept byte for byte
/// however the image tries to write, and messages that say which firmware it needs.
#[test]
fn ball_screw_record_locks_the_store_and_is_kept() {
    let cfg = ball_lift();
    let mut store = store_with([(&cfg, 5), (&cfg, 5)]);
    let before: Vec<u8> = store.flash().bytes().to_vec();
    let loaded = store.load();
    let want = ConfigError::Conflict {
        field: "drive.screw",
        reason: NEEDS_BALL_SCREW,
    };
    assert_eq!(loaded.source, Source::NeedsBallScrew(want));
    assert!(loaded.source.needs_ball_screw());
    let mut msg = String::new();
    loaded.source.write_to(&mut msg).unwrap();
    assert!(msg.contains("needs the ball-screw firmware"), "{msg}");
    assert!(msg.contains("drive.screw"), "{msg}");
    assert!(!msg.contains("factory defaults"), "{msg}");
    // Every write is refused: a `save` of whatever runs, a position record, a factory reset.
    assert_eq!(
        store.save(&ValidatedConfig::factory()),
        Err(StoreError::Locked)
    );
    assert_eq!(
        store.save_position(Parked::At(1000), 7),
        Err(StoreError::Locked)
    );
    assert_eq!(store.erase(), Err(StoreError::Locked));
    assert_eq!(store.flash().bytes(), &before[..]);
    let mut out = String::new();
    service::write_saved(&mut out, Err(StoreError::Locked)).unwrap();
    assert!(out.contains("ball-screw firmware"), "{out}");
}

/// The `ball` law (variable τ) on a lead screw is the ball-screw firmware's too; and a copy
/// of a ball screw's record next to an older lead-screw one still locks (a save the ball-screw
/// firmware did not finish must not bring back the lead-screw configuration).
#[test]
fn ball_law_or_one_ball_copy_locks_too() {
    let mut law = ControlConfig::DEFAULT;
    law.estimator.law = FrictionLaw::BALL_SCREW;
    assert_eq!(law.estimator.law.variable, LawVariable::Lubrication);
    let mut store = store_with([(&law, 3), (&law, 3)]);
    assert_eq!(
        store.load().source,
        Source::NeedsBallScrew(ConfigError::Conflict {
            field: "friction.variable",
            reason: NEEDS_BALL_SCREW,
        })
    );
    let lead = ControlConfig::DEFAULT;
    for cfgs in [
        [(&ball_lift(), 9), (&lead, 8)],
        [(&lead, 8), (&ball_lift(), 9)],
    ] {
        let mut store = store_with(cfgs);
        let loaded = store.load();
        assert!(loaded.source.needs_ball_screw(), "{:?}", loaded.source);
        assert_eq!(store.save(&loaded.config), Err(StoreError::Locked));
    }
}

/// A lead-screw lift's record whose ball-screw values were changed (by the ball-screw firmware,
/// or written by it before the lift was converted): loaded, saved again by this image, the 15
/// words are bit for bit what they were, and the ball-screw build reads them back unchanged.
#[test]
fn ball_screw_values_round_trip_as_opaque_words() {
    let mut cfg = ball_lift();
    cfg.screw = ScrewKind::Lead;
    let mut store = store_with([(&cfg, 4), (&cfg, 4)]);
    let loaded = store.load();
    assert_eq!(
        loaded.source,
        Source::Stored {
            seq: 4,
            both_copies: true
        }
    );
    assert_eq!(loaded.config.get(), &cfg);
    // A change through the console, saved: the ball screw's words are the loaded ones.
    let ramp = settings::find("motion.ramp_ms").unwrap();
    let changed = settings::apply(&loaded.config, ramp, 321).unwrap();
    assert_eq!(store.save(&changed), Ok(5));
    let again = ConfigStore::new(store.into_flash(), 0..SIZE as u32)
        .unwrap()
        .load();
    assert_eq!(again.config.get().ball_screw, cfg.ball_screw);
    assert_eq!(again.config.get().lube, cfg.lube);
    assert_eq!(again.config.get().motion.ramp_ms, 321);
    // The words at the end of the record are the typed fields' raw bits.
    let mut buf = [0u8; record::MAX_RECORD_LEN];
    let len = record::encode(again.config.get(), 6, &mut buf).unwrap();
    let words = HEADER_LEN + 8 * (SETTINGS.iter().filter(|s| s.stored()).count());
    for (j, key) in BALL_KEYS.iter().enumerate() {
        let at = words + 8 * j;
        let mut w = [0; 8];
        w.copy_from_slice(&buf[at..at + 8]);
        assert_eq!(
            i64::from_le_bytes(w),
            settings::opaque_get(j, &cfg),
            "{key}"
        );
    }
    assert_eq!(len, words + 8 * OPAQUE_COUNT + 4);
    // Equality of configurations sees the opaque words.
    let mut other = *again.config.get();
    other.ball_screw.preload = Newtons::lit("1400");
    assert!(ValidatedConfig(other) != again.config);
}

/// A controller locked out: bridge braked and holding brake engaged on every tick, no motion,
/// `fault clear` refused with its reason, and a reconfiguration keeps the fault.
#[test]
fn locked_out_controller_stays_braked() {
    let cfg = ValidatedConfig::factory();
    let mut c = Controller::new(cfg.get(), 5000).unwrap();
    c.report_needs_ball_screw(Instant(0));
    let inputs = Inputs {
        encoder_count: 5000,
        encoder_edge_age: 0,
        current_raw: 2048,
        supply_raw: 2820,
        switches: Default::default(),
    };
    assert_eq!(c.command(Command::Up), Err(Refusal::Faulted));
    assert_eq!(c.command(Command::ClearFault), Err(Refusal::NeedsBallScrew));
    assert!(Refusal::NeedsBallScrew
        .message()
        .contains("needs the ball-screw firmware"));
    for t in 1..2000 {
        let out = c.step(Instant(t * 1000), &inputs);
        assert_eq!(out.bridge, Bridge::Brake, "tick {t}");
        assert!(!out.brake_release, "tick {t}");
        if t == 500 {
            assert_eq!(c.command(Command::ClearFault), Err(Refusal::NeedsBallScrew));
            assert_eq!(c.command(Command::Down), Err(Refusal::Faulted));
        }
    }
    let mut next = *cfg.get();
    next.motion.ramp_ms = 300;
    assert_eq!(
        c.reconfigure(&ValidatedConfig::new(next).unwrap().0),
        Ok(())
    );
    assert_eq!(c.status().state, State::Fault);
    assert_eq!(c.fault().map(|f| f.kind), Some(FaultKind::NeedsBallScrew));
    assert!(FaultKind::NeedsBallScrew
        .name()
        .contains("needs the ball-screw firmware"));
}

/// The console of the lead-screw image refuses every ball-screw key and value with a reply
/// that names the firmware it needs, and leaves the configuration as it was.
#[test]
fn console_refuses_ball_screw_keys_and_values() {
    let mut cfg = ValidatedConfig::factory();
    let before = cfg;
    let mut c = Controller::new(cfg.get(), 5000).unwrap();
    let lines = [
        "set drive.screw ball",
        "set friction.law ball",
        "set friction.variable tau",
        "set ballscrew.r_m 20mm",
        "set BallScrew.Preload 1kN",
        "get ballscrew.lube_band",
        "help ballscrew.lead",
    ];
    for line in lines {
        let mut out = String::new();
        let o = service::handle(line.as_bytes(), &mut c, &mut cfg, &mut out);
        assert_eq!(o.reply, Ok(()), "{line}");
        assert!(out.starts_with("error: "), "{line}: {out}");
        assert!(
            out.contains("needs the ball-screw firmware"),
            "{line}: {out}"
        );
        assert_eq!(cfg, before, "{line}");
    }
    // An unknown key is still an unknown key.
    let mut out = String::new();
    service::handle(b"set ballscrews.r_m 1", &mut c, &mut cfg, &mut out);
    assert!(out.contains("unknown key"), "{out}");
    // The lead-screw values of the same settings are accepted.
    for line in ["set drive.screw lead", "set friction.law ptfe"] {
        let mut out = String::new();
        service::handle(line.as_bytes(), &mut c, &mut cfg, &mut out);
        assert!(!out.starts_with("error"), "{line}: {out}");
    }
}
