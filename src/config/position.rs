//! The position record: where the lift was parked (or that it was moving) when the power went,
//! and the stamp of the geometry its counts mean something under.

use crate::config::record;
use crate::config::settings::SETTINGS;
use crate::control::config::ControlConfig;
pub use crate::control::park::Parked;
use core::ops::Range;

/// Position record: magic, sequence, kind, counts, geometry stamp, CRC-32. The friction-scale
/// record has the same layout under its own magic (kind 0, the scale's Q28 bits for counts,
/// [`friction_stamp`] for the stamp).
pub(super) const POSITION_LEN: usize = 4 + 4 + 1 + 4 + 4 + 4;
const POSITION_MAGIC: [u8; 4] = *b"LFPS";
/// The friction-scale record's magic.
pub(super) const FRICTION_MAGIC: [u8; 4] = *b"LFFS";

/// A position record as stored: the parked state, its sequence number, and the stamp of the
/// geometry it was counted in.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct PositionRecord {
    pub(super) parked: Parked,
    pub(super) seq: u32,
    pub(super) stamp: u32,
}

impl PositionRecord {
    pub(super) fn encode(&self) -> [u8; POSITION_LEN] {
        self.encode_as(POSITION_MAGIC)
    }

    /// [`Self::encode`] under `magic`.
    pub(super) fn encode_as(&self, magic: [u8; 4]) -> [u8; POSITION_LEN] {
        let mut b = [0u8; POSITION_LEN];
        b[..4].copy_from_slice(&magic);
        b[4..8].copy_from_slice(&self.seq.to_le_bytes());
        let (kind, counts) = match self.parked {
            Parked::At(c) => (0u8, c),
            Parked::Moving => (1u8, 0),
        };
        b[8] = kind;
        b[9..13].copy_from_slice(&counts.to_le_bytes());
        b[13..17].copy_from_slice(&self.stamp.to_le_bytes());
        let crc = record::crc32(&b[..17]);
        b[17..21].copy_from_slice(&crc.to_le_bytes());
        b
    }

    pub(super) fn decode(b: &[u8]) -> Option<PositionRecord> {
        Self::decode_as(b, POSITION_MAGIC)
    }

    /// [`Self::decode`] under `magic`.
    pub(super) fn decode_as(b: &[u8], magic: [u8; 4]) -> Option<PositionRecord> {
        let word = |i: usize| -> Option<[u8; 4]> { b.get(i..i + 4)?.try_into().ok() };
        if b.len() != POSITION_LEN || word(0)? != magic {
            return None;
        }
        if u32::from_le_bytes(word(17)?) != record::crc32(b.get(..17)?) {
            return None;
        }
        let parked = match b.get(8)? {
            0 => Parked::At(i32::from_le_bytes(word(9)?)),
            1 => Parked::Moving,
            _ => return None,
        };
        Some(PositionRecord {
            parked,
            seq: u32::from_le_bytes(word(4)?),
            stamp: u32::from_le_bytes(word(13)?),
        })
    }
}

/// The stamp of everything that gives encoder counts their meaning (geometry and drive
/// settings): a stored position counted under another stamp is not used.
/// (CRC-32 of those settings' raw bits, each as 8 little-endian bytes, in registry order.)
pub fn geometry_stamp(cfg: &ControlConfig) -> u32 {
    let mut crc = 0xFFFF_FFFF;
    for s in &SETTINGS[STAMPED.start..STAMPED.end] {
        crc = record::crc32_update(crc, &s.get(cfg).to_le_bytes());
    }
    crc ^ 0xFFFF_FFFF
}

/// The stamp a stored friction scale is valid under: the geometry stamp and the configured
/// friction law's raw bits (a scale on another law, or on another screw, means nothing).
pub fn friction_stamp(cfg: &ControlConfig) -> u32 {
    let l = &cfg.estimator.law;
    let mut crc = !geometry_stamp(cfg);
    for v in [
        i64::from(l.base.to_bits()),
        i64::from(l.amp.to_bits()),
        l.rate.to_bits(),
        l.slope.to_bits(),
        l.s_max.to_bits(),
        l.variable as i64,
    ] {
        crc = record::crc32_update(crc, &v.to_le_bytes());
    }
    crc ^ 0xFFFF_FFFF
}

/// Whether [`geometry_stamp`] covers a setting: its key starts with `geometry.` or `drive.`.
const fn stamped(key: &str) -> bool {
    record::starts_with(key, "geometry.") || record::starts_with(key, "drive.")
}

/// The settings [`geometry_stamp`] covers, as indices into [`SETTINGS`]: they are neighbours
/// in the registry (checked here at compile time), so the firmware compares no key strings.
const STAMPED: Range<usize> = {
    let mut first = 0;
    while first < SETTINGS.len() && !stamped(SETTINGS[first].key) {
        first += 1;
    }
    let mut end = first;
    while end < SETTINGS.len() && stamped(SETTINGS[end].key) {
        end += 1;
    }
    let mut i = end;
    while i < SETTINGS.len() {
        assert!(
            !stamped(SETTINGS[i].key),
            "the stamped settings must be neighbours"
        );
        i += 1;
    }
    assert!(end > first);
    first..end
};

#[cfg(test)]
mod tests {
    use super::*;
    extern crate std;

    /// The stamp is the CRC-32 of the geometry and drive settings' bits laid end to end, as
    /// it was computed (through a buffer) when the parked positions in the field were stored.
    #[test]
    fn geometry_stamp_is_the_crc_of_the_concatenated_settings() {
        let mut cfg = ControlConfig::DEFAULT;
        cfg.estimator.drive.counts_per_rev += 4;
        for cfg in [ControlConfig::DEFAULT, cfg] {
            let mut bytes = std::vec::Vec::new();
            for s in crate::config::settings::SETTINGS.iter() {
                if s.key.starts_with("geometry.") || s.key.starts_with("drive.") {
                    bytes.extend_from_slice(&s.get(&cfg).to_le_bytes());
                }
            }
            assert!(bytes.len() >= 8 * 8, "{} bytes", bytes.len());
            assert_eq!(geometry_stamp(&cfg), record::crc32(&bytes));
        }
    }
}
