//! The configuration record: a fixed little-endian layout, versioned and CRC-checked.
//!
//! ```text
//! offset  size  field
//!      0     4  magic "LFCF"
//!      4     2  format version (VERSION)
//!      6     2  n = number of settings that follow
//!      8     4  schema: CRC-32 of the stored settings' keys, in order, each followed by '\n'
//!     12     4  sequence number of the save (1, 2, …)
//!     16   8·n  each stored setting's raw bits as i64, in registry order
//!  16+8n     4  CRC-32 (IEEE, as zlib) of bytes 0 … 16+8n
//! ```
//!
//! A hand-written layout rather than serde/postcard: it needs no derives on the configuration
//! types (other modules own them), its size does not depend on the values (postcard's varints
//! do), a field's position cannot move silently when someone reorders a struct (the order is
//! this registry's, and the schema word catches changes to it), and decoding is 60 lines with
//! no error path that is not tested byte by byte.

use crate::config::settings::{self, Setting, BALL_KEYS, OPAQUE_COUNT, SETTINGS};
use crate::control::config::ControlConfig;
use crate::keys;

/// Record magic, "LFCF".
pub const MAGIC: [u8; 4] = *b"LFCF";
/// Format version written by this firmware. 2: `drive.screw` added; 3: the ball screw's
/// `ballscrew.*` settings added; 4: the holding brake's `drive.brake`, `drive.brake_ms`; 5: the
/// drive's inertia `motor.inertia`. Older records are read with their own key list, the settings
/// they lack keep their factory value (see docs/config-store.md).
pub const VERSION: u16 = 5;
/// Bytes before the settings.
pub const HEADER_LEN: usize = 16;

/// Number of settings in the record (with the ball-screw values a build without the
/// `ball-screw` feature carries as opaque words: the record is the same in both builds).
pub fn stored_count() -> usize {
    SETTINGS.iter().filter(|s| s.stored()).count() + OPAQUE_COUNT
}

/// Record length for this firmware.
pub fn record_len() -> usize {
    HEADER_LEN + 8 * stored_count() + 4
}

/// Largest record this firmware writes (every setting stored): the size of the store's buffers.
pub const MAX_RECORD_LEN: usize = HEADER_LEN + 8 * (SETTINGS.len() + OPAQUE_COUNT) + 4;

/// CRC-32/ISO-HDLC (the zlib/Ethernet CRC), bitwise: no table in flash; a record costs ~3k
/// shift-xor steps, once per load or save.
pub fn crc32(data: &[u8]) -> u32 {
    crc32_update(0xFFFF_FFFF, data) ^ 0xFFFF_FFFF
}

/// [`crc32`] over data fed in pieces: start with `0xFFFF_FFFF`, end with `^ 0xFFFF_FFFF`.
/// (`const`: the schema words are computed at compile time.)
pub(crate) const fn crc32_update(mut crc: u32, data: &[u8]) -> u32 {
    let mut i = 0;
    while i < data.len() {
        crc ^= data[i] as u32;
        let mut bit = 0;
        while bit < 8 {
            crc = (crc >> 1) ^ (0xEDB8_8320 & (crc & 1).wrapping_neg());
            bit += 1;
        }
        i += 1;
    }
    crc
}

/// `key` starts with `prefix` (`str::starts_with` is not `const`).
pub(crate) const fn starts_with(key: &str, prefix: &str) -> bool {
    let (key, prefix) = (key.as_bytes(), prefix.as_bytes());
    if key.len() < prefix.len() {
        return false;
    }
    let mut i = 0;
    while i < prefix.len() {
        if key[i] != prefix[i] {
            return false;
        }
        i += 1;
    }
    true
}

/// The format version that added a stored setting (1: there from the start).
const fn added_in(key: &str) -> u16 {
    if starts_with(key, keys::DRIVE_SCREW.name) && key.len() == keys::DRIVE_SCREW.name.len() {
        2
    } else if starts_with(key, "ballscrew.") {
        3
    } else if starts_with(key, "drive.brake") {
        4
    } else if starts_with(key, keys::MOTOR_INERTIA.name) {
        5
    } else {
        1
    }
}

/// The format version that added the ball screw's values.
const BALL_ADDED_IN: u16 = added_in("ballscrew.");

/// How many opaque ball-screw words records of `version` hold, in this build.
fn opaque_in(version: u16) -> usize {
    if BALL_ADDED_IN <= version {
        OPAQUE_COUNT
    } else {
        0
    }
}

/// Whether a stored setting is in records of `version`.
#[cfg(test)]
fn in_version(key: &str, version: u16) -> bool {
    added_in(key) <= version
}

/// Per setting of [`SETTINGS`]: the format version whose records first hold it (`u8::MAX`:
/// not stored). Computed at compile time, so the firmware compares no key strings.
const ADDED_IN: [u8; SETTINGS.len()] = {
    let mut t = [u8::MAX; SETTINGS.len()];
    let mut i = 0;
    while i < SETTINGS.len() {
        if crate::config::settings::stored_at(i) {
            t[i] = added_in(SETTINGS[i].key) as u8;
        }
        i += 1;
    }
    t
};

/// Per format version (index `version - 1`): how many settings its records hold, and its
/// schema word (CRC-32 of their keys in order, each followed by `\n`). Compile time.
const LAYOUTS: [(usize, u32); VERSION as usize] = {
    let mut t = [(0, 0); VERSION as usize];
    let mut v = 1;
    while v <= VERSION {
        let (mut n, mut crc) = (0, 0xFFFF_FFFF);
        let mut i = 0;
        while i < SETTINGS.len() {
            if ADDED_IN[i] as u16 <= v {
                crc = crc32_update(crc, SETTINGS[i].key.as_bytes());
                crc = crc32_update(crc, b"\n");
                n += 1;
            }
            i += 1;
        }
        // The opaque ball-screw words follow (in the ball-screw build they are in SETTINGS).
        if OPAQUE_COUNT != 0 && BALL_ADDED_IN <= v {
            let mut j = 0;
            while j < BALL_KEYS.len() {
                crc = crc32_update(crc, BALL_KEYS[j].as_bytes());
                crc = crc32_update(crc, b"\n");
                n += 1;
                j += 1;
            }
        }
        t[(v - 1) as usize] = (n, crc ^ 0xFFFF_FFFF);
        v += 1;
    }
    t
};

/// The settings records of `version` hold, in their order.
fn stored_in(version: u16) -> impl Iterator<Item = &'static Setting> {
    SETTINGS
        .iter()
        .zip(ADDED_IN.iter())
        .filter(move |(_, &added)| u16::from(added) <= version)
        .map(|(s, _)| s)
}

/// `version`'s key list: how many settings, and its schema fingerprint; `None` for a version
/// this firmware does not know.
fn layout(version: u16) -> Option<(usize, u32)> {
    LAYOUTS.get(usize::from(version).wrapping_sub(1)).copied()
}

/// The schema fingerprint of `version`'s key list.
#[cfg(test)]
fn schema_of(version: u16) -> u32 {
    layout(version).map_or(0, |l| l.1)
}

/// The schema fingerprint: CRC-32 of the stored keys in order, each followed by `\n`.
pub fn schema() -> u32 {
    LAYOUTS[VERSION as usize - 1].1
}

/// Why a stored record was not used.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum DecodeError {
    /// Shorter than a header and CRC, or longer than this firmware's buffer.
    BadLength,
    /// Not a configuration record.
    BadMagic,
    /// The CRC does not match: some byte changed after it was written.
    BadCrc,
    /// An intact record of another format version.
    Version {
        /// The record's version.
        found: u16,
    },
    /// An intact record of this version whose list of settings differs from this firmware's
    /// (a firmware that changed the list without raising the version).
    Schema,
    /// A value that does not fit its field (only possible with a forged CRC).
    BadField {
        /// The setting's key.
        field: &'static str,
    },
}

impl DecodeError {
    /// The message (its `Display`), written without `core::fmt`'s machinery
    /// ([`crate::text`]).
    pub fn write_to(&self, out: &mut dyn core::fmt::Write) -> core::fmt::Result {
        match self {
            DecodeError::BadLength => out.write_str("record has a wrong length"),
            DecodeError::BadMagic => out.write_str("record has no LFCF magic"),
            DecodeError::BadCrc => out.write_str("record fails its CRC"),
            DecodeError::Version { found } => {
                out.write_str("record is format version ")?;
                crate::text::uint(out, u64::from(*found))?;
                out.write_str(", this firmware reads version ")?;
                crate::text::uint(out, u64::from(VERSION))
            }
            DecodeError::Schema => {
                out.write_str("record lists other settings than this firmware (schema mismatch)")
            }
            DecodeError::BadField { field } => {
                out.write_str("record value of ")?;
                out.write_str(field)?;
                out.write_str(" does not fit")
            }
        }
    }
}

impl core::fmt::Display for DecodeError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        self.write_to(f)
    }
}

/// Encode `cfg` as a record with sequence number `seq` into `out`; returns the length, or
/// `None` if `out` is too short.
pub fn encode(cfg: &ControlConfig, seq: u32, out: &mut [u8]) -> Option<usize> {
    let (n, schema) = LAYOUTS[VERSION as usize - 1];
    let len = HEADER_LEN + 8 * n + 4;
    let out = out.get_mut(..len)?;
    out[0..4].copy_from_slice(&MAGIC);
    out[4..6].copy_from_slice(&VERSION.to_le_bytes());
    out[6..8].copy_from_slice(&(n as u16).to_le_bytes());
    out[8..12].copy_from_slice(&schema.to_le_bytes());
    out[12..16].copy_from_slice(&seq.to_le_bytes());
    for (i, s) in stored_in(VERSION).enumerate() {
        let at = HEADER_LEN + 8 * i;
        out[at..at + 8].copy_from_slice(&s.get(cfg).to_le_bytes());
    }
    let settings = n - opaque_in(VERSION);
    for j in 0..opaque_in(VERSION) {
        let at = HEADER_LEN + 8 * (settings + j);
        out[at..at + 8].copy_from_slice(&settings::opaque_get(j, cfg).to_le_bytes());
    }
    let crc = crc32(&out[..len - 4]);
    out[len - 4..].copy_from_slice(&crc.to_le_bytes());
    Some(len)
}

fn le_u16(b: &[u8], at: usize) -> u16 {
    let mut w = [0; 2];
    w.copy_from_slice(&b[at..at + 2]);
    u16::from_le_bytes(w)
}

fn le_u32(b: &[u8], at: usize) -> u32 {
    let mut w = [0; 4];
    w.copy_from_slice(&b[at..at + 4]);
    u32::from_le_bytes(w)
}

/// Decode a record into `(config, sequence)`. The configuration is *not* validated yet: see
/// [`crate::config::ValidatedConfig::new`]. Settings start from [`ControlConfig::DEFAULT`], so a
/// field the record does not hold (`drive.screw` in a version-1 record) keeps its factory value.
pub fn decode(bytes: &[u8]) -> Result<(ControlConfig, u32), DecodeError> {
    if bytes.len() < HEADER_LEN + 4 || bytes.len() > MAX_RECORD_LEN {
        return Err(DecodeError::BadLength);
    }
    if bytes[0..4] != MAGIC {
        return Err(DecodeError::BadMagic);
    }
    let body = bytes.len() - 4;
    if crc32(&bytes[..body]) != le_u32(bytes, body) {
        return Err(DecodeError::BadCrc);
    }
    let version = le_u16(bytes, 4);
    // An older format is this one without the settings added since: decoded with its own key
    // list, the missing settings keep their factory value.
    let Some((count, schema)) = layout(version) else {
        return Err(DecodeError::Version { found: version });
    };
    let n = usize::from(le_u16(bytes, 6));
    if n != count || le_u32(bytes, 8) != schema {
        return Err(DecodeError::Schema);
    }
    if bytes.len() != HEADER_LEN + 8 * n + 4 {
        return Err(DecodeError::BadLength);
    }
    let seq = le_u32(bytes, 12);
    let mut cfg = ControlConfig::DEFAULT;
    for (i, s) in stored_in(version).enumerate() {
        let at = HEADER_LEN + 8 * i;
        let mut w = [0; 8];
        w.copy_from_slice(&bytes[at..at + 8]);
        if !s.set(&mut cfg, i64::from_le_bytes(w)) {
            return Err(DecodeError::BadField { field: s.key });
        }
    }
    let settings = n - opaque_in(version);
    for j in 0..opaque_in(version) {
        let at = HEADER_LEN + 8 * (settings + j);
        let mut w = [0; 8];
        w.copy_from_slice(&bytes[at..at + 8]);
        if !settings::opaque_set(j, &mut cfg, i64::from_le_bytes(w)) {
            // (Not the key: `BALL_KEYS` stays out of this build's flash.)
            return Err(DecodeError::BadField {
                field: "ballscrew.*",
            });
        }
    }
    Ok((cfg, seq))
}

#[cfg(test)]
mod tests {
    use super::*;
    extern crate std;

    #[test]
    fn crc32_matches_the_standard_check_value() {
        assert_eq!(crc32(b"123456789"), 0xCBF4_3926);
    }

    /// The compile-time tables are what walking the registry's keys gives (the form the
    /// records in the field were written with), for every version; unknown versions have none.
    /// The keys of `version`'s records in order: the stored settings, then (in a build without
    /// the `ball-screw` feature) the ball screw's opaque words.
    fn record_keys(version: u16) -> std::vec::Vec<&'static str> {
        let opaque = BALL_KEYS
            .iter()
            .take(OPAQUE_COUNT)
            .filter(|k| in_version(k, version));
        SETTINGS
            .iter()
            .filter(|s| s.stored() && in_version(s.key, version))
            .map(|s| s.key)
            .chain(opaque.copied())
            .collect()
    }

    /// `cfg`'s raw words in `version`'s record, in [`record_keys`] order.
    fn record_words(cfg: &ControlConfig, version: u16) -> std::vec::Vec<i64> {
        let opaque = (0..OPAQUE_COUNT)
            .filter(|_| in_version("ballscrew.", version))
            .map(|j| settings::opaque_get(j, cfg));
        SETTINGS
            .iter()
            .filter(|s| s.stored() && in_version(s.key, version))
            .map(|s| s.get(cfg))
            .chain(opaque)
            .collect()
    }

    #[test]
    fn compile_time_layouts_match_the_registry() {
        for version in 1..=VERSION {
            let keys = record_keys(version);
            let mut text = std::string::String::new();
            for k in &keys {
                text.push_str(k);
                text.push('\n');
            }
            assert_eq!(
                layout(version),
                Some((keys.len(), crc32(text.as_bytes()))),
                "version {version}"
            );
            let listed: std::vec::Vec<&str> = stored_in(version).map(|s| s.key).collect();
            assert_eq!(
                listed,
                keys[..keys.len() - opaque_in(version)],
                "version {version}"
            );
        }
        assert_eq!(layout(0), None);
        assert_eq!(layout(VERSION + 1), None);
        assert_eq!(schema(), schema_of(VERSION));
        assert_eq!(layout(VERSION).map(|l| l.0), Some(stored_count()));
        // The keys each version added.
        assert_eq!(added_in("drive.screw"), 2);
        assert_eq!(added_in("drive.screwdriver"), 1);
        assert_eq!(added_in("ballscrew.lead"), 3);
        assert_eq!(added_in("drive.brake_ms"), 4);
        assert_eq!(added_in("motor.inertia"), 5);
        assert_eq!(added_in("limits.upper"), 1);
    }

    /// The format both builds write: version 5 with 72 values (version 4's 71 and
    /// `motor.inertia`), whether the ball screw's 15 values are settings (`ball-screw`) or opaque
    /// words (without it); version 4 keeps the schema word of main 3062e48's registry (computed
    /// from its key list), so the records saved before still read.
    #[test]
    fn both_builds_write_the_same_format() {
        assert_eq!(VERSION, 5);
        assert_eq!(layout(4), Some((71, 0x2AD0_4F24)));
        assert_eq!(layout(VERSION).map(|l| l.0), Some(72));
        assert_eq!(record_len(), HEADER_LEN + 8 * 72 + 4);
        assert_eq!(record_keys(VERSION)[57..], BALL_KEYS);
        assert_eq!(record_keys(4)[56..], BALL_KEYS);
    }

    #[test]
    fn record_round_trips_and_fits_the_buffer() {
        let mut buf = [0u8; MAX_RECORD_LEN];
        let len = encode(&ControlConfig::DEFAULT, 7, &mut buf).unwrap();
        assert_eq!(len, record_len());
        assert_eq!(decode(&buf[..len]), Ok((ControlConfig::DEFAULT, 7)));
    }

    /// A record of an older `version`, built by hand with its own key list.
    fn old_record(cfg: &ControlConfig, version: u16, b: &mut [u8; MAX_RECORD_LEN]) -> usize {
        let words = record_words(cfg, version);
        let keys = words.len();
        b[0..4].copy_from_slice(&MAGIC);
        b[4..6].copy_from_slice(&version.to_le_bytes());
        b[6..8].copy_from_slice(&(keys as u16).to_le_bytes());
        b[8..12].copy_from_slice(&schema_of(version).to_le_bytes());
        b[12..16].copy_from_slice(&3u32.to_le_bytes());
        for (i, w) in words.iter().enumerate() {
            let at = HEADER_LEN + 8 * i;
            b[at..at + 8].copy_from_slice(&w.to_le_bytes());
        }
        let body = HEADER_LEN + 8 * keys;
        let crc = crc32(&b[..body]);
        b[body..body + 4].copy_from_slice(&crc.to_le_bytes());
        body + 4
    }

    /// A version-1 record (no `drive.screw`): decoded, the screw kind stays Lead.
    #[test]
    fn version_1_record_decodes_with_the_factory_screw_kind() {
        let mut cfg = ControlConfig::DEFAULT;
        cfg.motion.ramp_ms = 120;
        let mut b = [0u8; MAX_RECORD_LEN];
        let len = old_record(&cfg, 1, &mut b);
        assert_eq!(
            len,
            record_len() - 8 * 19,
            "v1 lacks drive.screw, ballscrew.*, drive.brake* and motor.inertia"
        );
        assert_eq!(decode(&b[..len]), Ok((cfg, 3)));
        // The same bytes labelled version 2 are refused: the key list differs.
        b[4..6].copy_from_slice(&2u16.to_le_bytes());
        let body = len - 4;
        let crc = crc32(&b[..body]);
        b[body..len].copy_from_slice(&crc.to_le_bytes());
        assert_eq!(decode(&b[..len]), Err(DecodeError::Schema));
    }

    /// A version-2 record (no `ballscrew.*`) of a ball-screw lift: every setting it holds is
    /// kept (the screw kind too), the ball screw's parameters take their factory values.
    #[cfg(feature = "ball-screw")]
    #[test]
    fn version_2_record_keeps_its_settings_and_gets_the_factory_ball_screw() {
        let mut cfg = ControlConfig::ball_screw_4008().unwrap();
        cfg.motion.ramp_ms = 150;
        cfg.protection.runaway_travel = crate::units::Metres::lit("0.001");
        let mut b = [0u8; MAX_RECORD_LEN];
        let len = old_record(&cfg, 2, &mut b);
        assert_eq!(len, record_len() - 8 * 18);
        assert_eq!(decode(&b[..len]), Ok((cfg, 3)));
    }

    /// A version-3 record (no `drive.brake*`) keeps its changed ball screw and gets no brake;
    /// a version-4 record keeps a brake; a future version is refused.
    #[cfg(feature = "ball-screw")]
    #[test]
    fn version_3_record_decodes_without_a_brake() {
        let mut cfg = ControlConfig::ball_screw_4008().unwrap();
        cfg.ball_screw.preload = crate::units::Newtons::lit("1500");
        cfg.lube.band = crate::units::Ratio::lit("0.3");
        let mut b = [0u8; MAX_RECORD_LEN];
        let len = old_record(&cfg, 3, &mut b);
        assert_eq!(len, record_len() - 8 * 3);
        assert_eq!(decode(&b[..len]), Ok((cfg, 3)));
        // The same bytes labelled version 4 are refused: the key list differs.
        b[4..6].copy_from_slice(&4u16.to_le_bytes());
        let crc = crc32(&b[..len - 4]);
        b[len - 4..len].copy_from_slice(&crc.to_le_bytes());
        assert_eq!(decode(&b[..len]), Err(DecodeError::Schema));
        cfg.brake.present = true;
        cfg.brake.delay_ms = 120;
        let len = encode(&cfg, 4, &mut b).unwrap();
        assert_eq!(decode(&b[..len]), Ok((cfg, 4)));
        b[4..6].copy_from_slice(&6u16.to_le_bytes());
        let crc = crc32(&b[..len - 4]);
        b[len - 4..len].copy_from_slice(&crc.to_le_bytes());
        assert_eq!(decode(&b[..len]), Err(DecodeError::Version { found: 6 }));
    }

    /// A version-4 record (before `motor.inertia`): every setting it holds is kept and the
    /// drive's inertia takes its factory value; the same bytes labelled version 5 are refused.
    #[test]
    fn version_4_record_keeps_its_settings_and_gets_the_factory_inertia() {
        let mut cfg = ControlConfig::DEFAULT;
        cfg.motion.ramp_ms = 90;
        cfg.estimator.motor.resistance = crate::units::Ratio::lit("0.12");
        let mut b = [0u8; MAX_RECORD_LEN];
        let len = old_record(&cfg, 4, &mut b);
        assert_eq!(len, record_len() - 8);
        assert_eq!(decode(&b[..len]), Ok((cfg, 3)));
        b[4..6].copy_from_slice(&5u16.to_le_bytes());
        let crc = crc32(&b[..len - 4]);
        b[len - 4..len].copy_from_slice(&crc.to_le_bytes());
        assert_eq!(decode(&b[..len]), Err(DecodeError::Schema));
        // A changed inertia round-trips in the current format.
        cfg.estimator.motor.inertia_ukgm2 = 75;
        let len = encode(&cfg, 9, &mut b).unwrap();
        assert_eq!(decode(&b[..len]), Ok((cfg, 9)));
    }
}
