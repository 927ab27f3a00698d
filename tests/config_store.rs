//! The configuration store against the simulated flash: round trip of every setting, power
//! loss at every step of a save, corruption of every byte, version mismatch, refused values.
#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)]

use embassy_futures::block_on;
use liftfw::config::record::{self, DecodeError};
use liftfw::config::settings::{self, Kind, SETTINGS};
use liftfw::config::sim_flash::{CutMode, SimFlash, ERASE_SIZE};
use liftfw::config::store::{ConfigStore, Corruption, Source, CONFIG_KEY};
use liftfw::config::ValidatedConfig;
use liftfw::control::config::ControlConfig;
use liftfw::units::Metres;
use liftfw::ConfigError;
use sequential_storage::cache::Cache;
use sequential_storage::map::{MapConfig, MapStorage};

/// Two copies of two 2 KiB pages: the store's size on the board.
const SIZE: usize = 4 * ERASE_SIZE;
const HALF: usize = SIZE / 2;
type Flash = SimFlash<SIZE>;

fn store(flash: Flash) -> ConfigStore<Flash> {
    ConfigStore::new(flash, 0..SIZE as u32).unwrap()
}

fn load(flash: Flash) -> (liftfw::config::store::Loaded, Flash) {
    let mut s = store(flash);
    let loaded = s.load();
    (loaded, s.into_flash())
}

/// A valid configuration that differs from the factory one by its upper stop (`i` mm lower).
fn variant(i: u32) -> ValidatedConfig {
    let mut c = ControlConfig::DEFAULT;
    c.limits.upper = Metres::from_bits(Metres::lit("0.400").to_bits() - (i as i32) * 16_777);
    ValidatedConfig::new(c).unwrap()
}

/// Flash after `n` saves of `variant(1..=n)`.
fn after_saves(n: u32) -> Flash {
    let mut s = store(Flash::new());
    s.load();
    for i in 1..=n {
        assert_eq!(s.save(&variant(i)), Ok(i));
    }
    s.into_flash()
}

#[test]
fn empty_store_loads_factory_defaults_and_says_so() {
    let (loaded, _) = load(Flash::new());
    assert_eq!(loaded.source, Source::Missing);
    assert_eq!(loaded.config, ValidatedConfig::factory());
    let msg = format!("{}", loaded.source);
    assert!(msg.contains("no stored configuration"), "{msg}");
    assert!(msg.contains("factory defaults"), "{msg}");
}

#[test]
fn saved_configuration_survives_a_reboot() {
    let flash = after_saves(3);
    let (loaded, _) = load(flash);
    assert_eq!(
        loaded.source,
        Source::Stored {
            seq: 3,
            both_copies: true
        }
    );
    assert_eq!(loaded.config, variant(3));
    assert_eq!(
        format!("{}", loaded.source),
        "configuration #3 loaded from flash"
    );
}

/// Stored settings this build cannot move off the factory value: the lead-screw image refuses
/// `drive.screw = ball`, the only other value (docs/board.md "Build variants").
const FIXED_IN_THIS_BUILD: &[&str] = if cfg!(feature = "ball-screw") {
    &[]
} else {
    &["drive.screw"]
};

/// A valid configuration in which every stored setting differs from the factory value, except
/// [`FIXED_IN_THIS_BUILD`] (which must have no valid change).
fn everything_changed() -> ValidatedConfig {
    let mut cfg = ValidatedConfig::factory();
    for id in settings::all() {
        let s = id.setting();
        if !s.stored() {
            continue;
        }
        let raw = s.get(cfg.get());
        let choices: Vec<i64>;
        let candidates: &[i64] = match s.kind {
            Kind::Choice(names) => {
                let n = names.len() as i64;
                choices = (1..n).map(|k| (raw + k) % n).collect();
                &choices
            }
            Kind::Number { .. } => &[
                raw.saturating_sub(1),
                raw.saturating_add(1),
                raw.saturating_sub(2),
                raw.saturating_add(3),
                // `friction.s_max` at `none` (the largest value) has no valid neighbour: 1.0.
                1 << 32,
            ],
        };
        let next = candidates
            .iter()
            .filter(|&&c| c != raw)
            .find_map(|&c| settings::apply(&cfg, id, c).ok());
        let fixed = FIXED_IN_THIS_BUILD.contains(&s.key);
        match next {
            Some(next) => {
                assert!(!fixed, "{} should be fixed in this build", s.key);
                cfg = next;
            }
            None => assert!(fixed, "no valid change of {}", s.key),
        }
    }
    cfg
}

#[test]
fn every_setting_round_trips_through_flash() {
    let changed = everything_changed();
    let factory = ControlConfig::DEFAULT;
    for s in SETTINGS
        .iter()
        .filter(|s| s.stored() && !FIXED_IN_THIS_BUILD.contains(&s.key))
    {
        assert_ne!(s.get(changed.get()), s.get(&factory), "{}", s.key);
    }
    let mut st = store(Flash::new());
    st.load();
    assert_eq!(st.save(&changed), Ok(1));
    let (loaded, _) = load(st.into_flash());
    assert_eq!(
        loaded.source,
        Source::Stored {
            seq: 1,
            both_copies: true
        }
    );
    assert_eq!(loaded.config, changed);
    for s in SETTINGS.iter() {
        assert_eq!(
            s.get(loaded.config.get()),
            s.get(changed.get()),
            "{}",
            s.key
        );
    }
}

/// Cut the power at every step of save number `prior + 1` and check the flash then holds the
/// previous configuration or the new one, whole; and that the store works again afterwards.
fn power_loss_at_every_step(prior: u32, mode_for_step: impl Fn(u32) -> CutMode) -> u32 {
    let before = after_saves(prior);
    let old = if prior == 0 {
        ValidatedConfig::factory()
    } else {
        variant(prior)
    };
    let new = variant(prior + 1);
    // Steps the uninterrupted save takes.
    let steps = {
        let mut s = store(before.clone());
        s.load();
        let start = s.flash().steps();
        assert_eq!(s.save(&new), Ok(prior + 1));
        s.flash().steps() - start
    };
    assert!(steps > 0);
    let mut outcomes = [0u32; 2];
    for step in 0..steps {
        let mut s = store(before.clone());
        s.load();
        s.flash().cut_after(step, mode_for_step(step));
        assert!(
            s.save(&new).is_err(),
            "save {} survived a cut at step {step}",
            prior + 1
        );
        let mut flash = s.into_flash();
        assert!(flash.is_dead());
        flash.reboot();

        let mut s = store(flash);
        let loaded = s.load();
        if loaded.config == new {
            assert!(matches!(loaded.source, Source::Stored { seq, .. } if seq == prior + 1));
            outcomes[1] += 1;
        } else {
            assert_eq!(
                loaded.config,
                old,
                "save {} cut at step {step} ({:?}): neither old nor new; {}",
                prior + 1,
                mode_for_step(step),
                loaded.source
            );
            if prior > 0 {
                assert!(matches!(loaded.source, Source::Stored { seq, .. } if seq == prior));
            } else {
                assert!(loaded.source.is_fallback());
            }
            outcomes[0] += 1;
        }
        // The store recovers: the next save and load work.
        let again = variant(prior + 7);
        let r = s.save(&again);
        assert!(
            r.is_ok(),
            "save {} cut at step {step}: recovery save {r:?}",
            prior + 1
        );
        let (reloaded, _) = load(s.into_flash());
        assert_eq!(reloaded.config, again, "step {step}");
    }
    // Cuts while the first copy is written keep the old record, cuts in the second the new.
    assert!(outcomes[0] > 0 && outcomes[1] > 0, "{outcomes:?}");
    steps
}

#[test]
fn power_loss_at_every_step_of_a_save_keeps_old_or_new_clean_cut() {
    // 12 saves fill each copy's two pages more than twice: the cuts fall into plain appends,
    // page closes, and the erase + migration of a full page, in both copies.
    let total: u32 = (0..12)
        .map(|prior| power_loss_at_every_step(prior, |_| CutMode::Clean))
        .sum();
    assert!(total > 12 * 100, "{total}");
}

#[test]
fn power_loss_at_every_step_of_a_save_keeps_old_or_new_torn_writes() {
    for prior in 0..12 {
        power_loss_at_every_step(prior, |step| CutMode::Torn {
            seed: 0x9E37_79B9 ^ (prior << 16) ^ step,
        });
    }
}

#[test]
fn corrupting_any_byte_of_the_only_record_in_both_copies_is_detected() {
    let flash = after_saves(1);
    assert_eq!(flash.bytes()[..HALF], flash.bytes()[HALF..]);
    let magic_at = flash.bytes()[..HALF]
        .windows(4)
        .position(|w| w == record::MAGIC)
        .unwrap();
    let record_end = magic_at + record::record_len();
    // Every programmed byte, and every byte of the record (some of its bytes are 0xFF).
    let written: Vec<usize> = (0..HALF)
        .filter(|&i| flash.bytes()[i] != 0xFF || (magic_at..record_end).contains(&i))
        .collect();
    let mut counted = 0;
    for &i in &written {
        for pattern in [0x01u8, 0x80, 0xFF] {
            let mut f = flash.clone();
            f.bytes_mut()[i] ^= pattern;
            f.bytes_mut()[HALF + i] ^= pattern;
            let (loaded, _) = load(f);
            let msg = format!("{}", loaded.source);
            if (magic_at..record_end).contains(&i) {
                // A byte of the record: both CRCs see it.
                assert!(
                    matches!(loaded.source, Source::Corrupt(_)),
                    "byte {i} ^ {pattern:#x}: {msg}"
                );
                assert!(msg.contains("corrupt"), "{msg}");
                assert!(msg.contains("factory defaults"), "{msg}");
                assert_eq!(loaded.config, ValidatedConfig::factory(), "byte {i}");
                counted += 1;
            } else if loaded.source.is_fallback() {
                // Store structure (page markers, item header): defaults, said so.
                assert_eq!(loaded.config, ValidatedConfig::factory(), "byte {i}: {msg}");
                assert!(msg.contains("factory defaults"), "{msg}");
            } else {
                // A flip the store tolerates (e.g. in a page marker): the record is intact.
                assert_eq!(loaded.config, variant(1), "byte {i}: {msg}");
            }
        }
    }
    assert_eq!(counted, 3 * record::record_len());
}

#[test]
fn corrupting_any_byte_of_one_copy_keeps_the_configuration() {
    let flash = after_saves(1);
    for i in 0..SIZE {
        if flash.bytes()[i] == 0xFF {
            continue;
        }
        let mut f = flash.clone();
        f.bytes_mut()[i] ^= 0x24;
        let (loaded, _) = load(f);
        assert_eq!(loaded.config, variant(1), "byte {i}: {}", loaded.source);
        assert!(matches!(loaded.source, Source::Stored { seq: 1, .. }));
    }
}

#[test]
fn a_damaged_newest_record_falls_back_to_the_previous_intact_one() {
    let mut flash = after_saves(2);
    for half in [0, HALF] {
        let newest = half
            + flash.bytes()[half..half + HALF]
                .windows(4)
                .rposition(|w| w == record::MAGIC)
                .unwrap();
        flash.bytes_mut()[newest + 40] ^= 0x10;
    }
    let (loaded, _) = load(flash);
    assert_eq!(
        loaded.source,
        Source::Stored {
            seq: 1,
            both_copies: true
        }
    );
    assert_eq!(loaded.config, variant(1));
}

/// Store raw record bytes under the configuration key of both copies, bypassing `ConfigStore`.
fn store_raw(bytes: &[u8]) -> Flash {
    let mut flash = Flash::new();
    for range in [0..HALF as u32, HALF as u32..SIZE as u32] {
        let mut map =
            MapStorage::<u8, _, _>::new(&mut flash, MapConfig::new(range), Cache::new_uncached());
        let mut buf = [0u8; (record::MAX_RECORD_LEN + 8).div_ceil(8) * 8];
        block_on(map.store_item(&mut buf, &CONFIG_KEY, &bytes)).unwrap();
    }
    flash
}

fn with_crc(mut rec: Vec<u8>) -> Vec<u8> {
    let body = rec.len() - 4;
    let crc = record::crc32(&rec[..body]);
    rec[body..].copy_from_slice(&crc.to_le_bytes());
    rec
}

fn encoded(cfg: &ControlConfig) -> Vec<u8> {
    let mut buf = [0u8; record::MAX_RECORD_LEN];
    let n = record::encode(cfg, 5, &mut buf).unwrap();
    buf[..n].to_vec()
}

#[test]
fn record_of_another_version_is_not_used_and_says_why() {
    let mut rec = encoded(&ControlConfig::DEFAULT);
    // Version 6: a future format (this firmware writes 5 and also reads 1 to 4).
    rec[4..6].copy_from_slice(&6u16.to_le_bytes());
    let (loaded, _) = load(store_raw(&with_crc(rec)));
    assert_eq!(
        loaded.source,
        Source::Incompatible(DecodeError::Version { found: 6 })
    );
    assert_eq!(loaded.config, ValidatedConfig::factory());
    let msg = format!("{}", loaded.source);
    assert!(msg.contains("version mismatch"), "{msg}");
    assert!(msg.contains("version 6"), "{msg}");
}

#[test]
fn record_with_another_list_of_settings_is_not_used() {
    let mut rec = encoded(&ControlConfig::DEFAULT);
    rec[8] ^= 1; // schema fingerprint
    let (loaded, _) = load(store_raw(&with_crc(rec)));
    assert_eq!(loaded.source, Source::Incompatible(DecodeError::Schema));
    assert_eq!(loaded.config, ValidatedConfig::factory());
}

#[test]
fn intact_record_with_a_value_this_firmware_refuses_falls_back() {
    let mut bad = ControlConfig::DEFAULT;
    bad.motion.ramp_ms = 5;
    let (loaded, _) = load(store_raw(&encoded(&bad)));
    assert_eq!(
        loaded.source,
        Source::Rejected(ConfigError::OutOfRange {
            field: "motion.ramp_ms",
            range: "10..2000 ms"
        })
    );
    assert_eq!(loaded.config, ValidatedConfig::factory());
    let msg = format!("{}", loaded.source);
    assert!(msg.contains("motion.ramp_ms out of range"), "{msg}");
}

/// The ball-screw build refuses a record with a law in τ on a lead screw through the path of
/// any refused value (factory defaults, the store not written: the record is still there at
/// the next boot). The lead-screw build locks on it instead (`src/config/lead_only_tests.rs`).
#[cfg(feature = "ball-screw")]
#[test]
fn record_with_a_tau_law_on_a_lead_screw_is_refused_and_kept() {
    let mut bad = ControlConfig::DEFAULT;
    bad.estimator.law = liftfw::model::friction::FrictionLaw::BALL_SCREW;
    let want = Source::Rejected(ConfigError::Conflict {
        field: "friction.variable",
        reason: liftfw::control::config::TAU_NEEDS_BALL,
    });
    let (loaded, flash) = load(store_raw(&encoded(&bad)));
    assert_eq!(loaded.source, want);
    assert_eq!(loaded.config, ValidatedConfig::factory());
    let msg = format!("{}", loaded.source);
    assert!(msg.contains("needs drive.screw = ball"), "{msg}");
    let (again, _) = load(flash);
    assert_eq!(again.source, want);
}

#[test]
fn garbage_in_the_store_reads_as_corrupt() {
    let mut flash = Flash::new();
    for (i, b) in flash.bytes_mut().iter_mut().enumerate() {
        *b = (i * 7 + 3) as u8;
    }
    let mut s = store(flash);
    let loaded = s.load();
    assert!(
        matches!(
            loaded.source,
            Source::Corrupt(Corruption::Structure | Corruption::NoIntactRecord)
        ),
        "{:?}",
        loaded.source
    );
    assert_eq!(loaded.config, ValidatedConfig::factory());
    // Saving recovers the store.
    assert!(s.save(&variant(4)).is_ok());
    let (loaded, _) = load(s.into_flash());
    assert_eq!(loaded.config, variant(4));
}

#[test]
fn store_range_must_be_two_copies_of_two_pages() {
    for pages in [0usize, 1, 2, 3, 5] {
        let r = ConfigStore::new(Flash::new(), 0..(pages * ERASE_SIZE) as u32);
        assert!(r.is_err(), "{pages} pages");
    }
    assert!(ConfigStore::new(Flash::new(), 0..SIZE as u32).is_ok());
}

#[test]
fn erase_returns_the_store_to_factory() {
    let mut s = store(after_saves(2));
    s.erase().unwrap();
    assert_eq!(s.load().source, Source::Missing);
}

#[test]
fn limit_changes_are_validated_against_the_geometry() {
    let cfg = ValidatedConfig::factory();
    let lower = settings::find("limits.lower").unwrap();
    let upper = settings::find("limits.upper").unwrap();
    let mm = |v: &str| i64::from(Metres::from_f64(v.parse::<f64>().unwrap() / 1000.0).to_bits());
    assert_eq!(
        settings::apply(&cfg, lower, mm("405")),
        Err(ConfigError::Conflict {
            field: "limits.lower",
            reason: "must be at least 10 mm below limits.upper"
        })
    );
    assert!(matches!(
        settings::apply(&cfg, upper, mm("450")),
        Err(ConfigError::OutOfRange {
            field: "limits.upper",
            ..
        })
    ));
    assert!(matches!(
        settings::apply(&cfg, lower, mm("100")),
        Err(ConfigError::OutOfRange {
            field: "limits.lower",
            ..
        })
    ));
    let ok = settings::apply(&cfg, upper, mm("380")).unwrap();
    assert_eq!(ok.get().limits.upper, Metres::from_f64(0.380));
    // A geometry change that would strand the stops is refused too, naming the stop.
    let length = settings::find("geometry.length").unwrap();
    assert!(matches!(
        settings::apply(&cfg, length, mm("300")),
        Err(ConfigError::OutOfRange {
            field: "limits.upper",
            ..
        })
    ));
}
