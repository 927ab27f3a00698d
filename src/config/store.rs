//! The configuration store: the record kept in two independent `sequential-storage` maps.
//!
//! `sequential-storage` appends every save as a new item (header with a CRC-16 of the length,
//! CRC-32 of the data) and only erases a page after copying its still-current items forward,
//! so an interrupted append leaves an item that fails its CRC and is skipped. One case defeats
//! a single map: a power cut *during the erase* of the page it just migrated from can leave
//! that page looking closed, and the repair on the next start then erases the page holding
//! the migrated record (found by `tests/config_store.rs` with torn erases). So the store keeps
//! two copies in two disjoint ranges and writes them one after the other, the copy that does
//! not hold the newest record first: whatever a cut destroys, it touches one copy, and the
//! other holds the newest or the previous record. Loading takes the intact, valid record with
//! the higher sequence number. Our own record adds a version, a schema fingerprint and a
//! second CRC (see [`crate::config::record`]), and loading re-validates through
//! [`ValidatedConfig::new`]. docs/config-store.md gives the whole argument.

use crate::config::blocking::{read, run, Blocking};
pub use crate::config::position::friction_stamp;
pub use crate::config::position::{geometry_stamp, Parked};
use crate::config::position::{PositionRecord, FRICTION_MAGIC};
use crate::config::record::{self, DecodeError, MAX_RECORD_LEN};
use crate::config::ValidatedConfig;
use crate::control::config::ControlConfig;
use crate::units::Ratio;
use crate::ConfigError;
use core::ops::Range;
use embedded_storage::nor_flash::{NorFlash, NorFlashError, NorFlashErrorKind};
use sequential_storage::cache::{Cache, Uncached};
use sequential_storage::map::{MapConfig, MapStorage, SerializationError, Value};

/// The map key of the configuration record (other keys are free for later records).
pub const CONFIG_KEY: u8 = 1;

/// The map key of the position record (where the lift was parked, or that it was moving).
pub const POSITION_KEY: u8 = 2;

/// The map key of the friction-scale record (the thread's identified friction on the
/// configured law, `crate::ident`): the position record's layout under its own magic
/// (`config::position`).
pub const FRICTION_KEY: u8 = 3;

/// Work buffer: key + record, rounded up to the 8-byte program unit of the G4.
const BUF_LEN: usize = (1 + MAX_RECORD_LEN).div_ceil(8) * 8;

#[repr(align(8))]
struct Buf([u8; BUF_LEN]);

type Map<'f, F> = MapStorage<u8, Blocking<'f, F>, Cache<Uncached, Uncached, Uncached, u8>>;

/// Why the store could not be used.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum StoreError {
    /// The flash range is not an even number of whole pages, at least four.
    BadRange,
    /// The flash driver failed (power, alignment, bounds, hardware).
    Flash(FlashErrorKind),
    /// No room even after `sequential-storage` reclaimed old pages.
    Full,
    /// The stored record needs the ball-screw firmware ([`Source::NeedsBallScrew`]): this
    /// image writes nothing, so that the record survives until that firmware runs.
    Locked,
    /// `sequential-storage` found its structures damaged beyond its own repair.
    Corrupted,
    /// The record read back after a save differs from what was written.
    Verify,
    /// Any other `sequential-storage` error (buffer sizes, a logic error it reports).
    Internal,
}

/// The flash driver's error class.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum FlashErrorKind {
    /// Misaligned access.
    NotAligned,
    /// Outside the flash.
    OutOfBounds,
    /// Driver-specific (including a power cut in the simulation).
    Other,
}

impl StoreError {
    /// The message (its `Display`).
    pub fn message(&self) -> &'static str {
        match self {
            StoreError::BadRange => "store range is not an even number (at least 4) of whole pages",
            StoreError::Flash(k) => match k {
                FlashErrorKind::NotAligned => "flash driver error (not aligned)",
                FlashErrorKind::OutOfBounds => "flash driver error (out of bounds)",
                FlashErrorKind::Other => "flash driver error",
            },
            StoreError::Full => "store is full",
            StoreError::Locked => "the stored record needs the ball-screw firmware; not written",
            StoreError::Corrupted => "store structure is corrupted",
            StoreError::Verify => "read-back after save differs",
            StoreError::Internal => "storage library error",
        }
    }
}

impl core::fmt::Display for StoreError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(self.message())
    }
}

fn flash_error<E: NorFlashError>(e: &E) -> StoreError {
    StoreError::Flash(match e.kind() {
        NorFlashErrorKind::NotAligned => FlashErrorKind::NotAligned,
        NorFlashErrorKind::OutOfBounds => FlashErrorKind::OutOfBounds,
        _ => FlashErrorKind::Other,
    })
}

fn store_error<E: NorFlashError>(e: sequential_storage::Error<E>) -> StoreError {
    match e {
        sequential_storage::Error::Storage { value, .. } => flash_error(&value),
        sequential_storage::Error::FullStorage => StoreError::Full,
        sequential_storage::Error::Corrupted { .. } => StoreError::Corrupted,
        _ => StoreError::Internal,
    }
}

/// Where the loaded configuration came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Source {
    /// The newest intact record, save number `seq`.
    Stored {
        /// Sequence number of the save.
        seq: u32,
        /// Both copies hold it (false: one copy is older or damaged; the next save rewrites it).
        both_copies: bool,
    },
    /// The store is erased: nothing was ever saved. Factory defaults.
    Missing,
    /// The store holds data but no intact record (damaged, or the very first save was
    /// interrupted), or a record failed its own checks. Factory defaults.
    Corrupt(Corruption),
    /// An intact record of another format version or list of settings. Factory defaults.
    Incompatible(DecodeError),
    /// An intact record whose values this firmware refuses. Factory defaults.
    Rejected(ConfigError),
    /// The flash could not be read. Factory defaults.
    Unreadable(StoreError),
    /// An intact record of a ball-screw lift (the error names the value), read by an image
    /// built without the `ball-screw` feature. Not a fallback to run on: the store refuses to
    /// write (the record stays as it is) and the firmware latches
    /// [`crate::control::FaultKind::NeedsBallScrew`] with the motor braked. Never in the
    /// ball-screw build.
    NeedsBallScrew(ConfigError),
}

/// What exactly was corrupt.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Corruption {
    /// The store is not erased but holds no item that passes `sequential-storage`'s CRCs.
    NoIntactRecord,
    /// `sequential-storage` reported damage it could not repair.
    Structure,
    /// The item passed the storage CRCs but the record failed its own.
    Record(DecodeError),
}

impl Source {
    /// True when the configuration is the factory one because nothing usable was stored.
    pub fn is_fallback(&self) -> bool {
        !matches!(self, Source::Stored { .. })
    }

    /// A configuration had been stored but cannot be used (corrupt, another version, refused,
    /// unreadable): the factory defaults run in its place, and the firmware latches
    /// [`crate::control::FaultKind::FactoryDefaults`] until `fault clear` acknowledges it. Not
    /// for an erased store (a new board runs its factory settings knowingly) nor for
    /// [`Source::NeedsBallScrew`] (its own lock-out). `position_record`: the store holds an
    /// intact position record ([`ConfigStore::has_position_record`]); then "no intact
    /// configuration record" is a board that moved but was never saved, not a loss (a
    /// configuration item damaged in both copies while a position record survived looks the
    /// same: docs/console.md "Factory defaults after a lost configuration").
    pub fn lost_stored(&self, position_record: bool) -> bool {
        match self {
            Source::Stored { .. } | Source::Missing | Source::NeedsBallScrew(_) => false,
            Source::Corrupt(Corruption::NoIntactRecord) => !position_record,
            _ => true,
        }
    }

    /// The stored configuration needs the ball-screw firmware: lock the lift out.
    pub fn needs_ball_screw(&self) -> bool {
        matches!(self, Source::NeedsBallScrew(_))
    }

    /// How much a failed copy says about the store: the more specific wins the message.
    fn weight(&self) -> u8 {
        match self {
            Source::NeedsBallScrew(_) => 7,
            Source::Stored { .. } => 6,
            Source::Rejected(_) => 5,
            Source::Incompatible(_) => 4,
            Source::Corrupt(Corruption::Record(_)) => 3,
            Source::Corrupt(_) => 2,
            Source::Unreadable(_) => 1,
            Source::Missing => 0,
        }
    }
}

impl Source {
    /// The message for the console and the log (its `Display`), written without `core::fmt`'s
    /// machinery ([`crate::text`]).
    pub fn write_to(&self, out: &mut dyn core::fmt::Write) -> core::fmt::Result {
        const DEFAULTS: &str = "factory defaults in use (limits at the factory stops)";
        // A lost configuration latches a fault (`lost_stored`).
        const LOST: &str = "; motion refused until `fault clear` (set the stops first)";
        // "<head> (<cause>): factory defaults …" for the fallbacks with a cause.
        const CORRUPT: &str = "stored configuration is corrupt (";
        let (head, cause) = match self {
            Source::Stored { seq, both_copies } => {
                crate::text::fill(
                    out,
                    "configuration #\x01 loaded from flash",
                    &[crate::text::Arg::Uint(*seq)],
                )?;
                if !both_copies {
                    out.write_str(" (its second copy is older or damaged; `save` rewrites it)")?;
                }
                return Ok(());
            }
            Source::Missing => {
                out.write_str("no stored configuration: ")?;
                out.write_str(DEFAULTS)?;
                return out.write_str("; `save` stores the current settings");
            }
            Source::Corrupt(Corruption::NoIntactRecord) => (
                CORRUPT,
                Cause::Text("no intact record: damaged, or the first save was interrupted"),
            ),
            Source::Corrupt(Corruption::Structure) => {
                (CORRUPT, Cause::Text("store structure damaged"))
            }
            Source::Corrupt(Corruption::Record(e)) => (CORRUPT, Cause::Decode(e)),
            Source::Incompatible(e) => (
                "stored configuration not used, version mismatch (",
                Cause::Decode(e),
            ),
            Source::Rejected(e) => ("stored configuration refused (", Cause::Config(e)),
            Source::Unreadable(e) => ("configuration store unreadable (", Cause::Text(e.message())),
            Source::NeedsBallScrew(e) => {
                out.write_str("stored configuration needs the ball-screw firmware (")?;
                e.write_to(out)?;
                return out.write_str(
                    "): lift locked, fault latched with the motor braked; the record is kept \
                     unchanged; flash the ball-screw image (`cargo fw-ball`)",
                );
            }
        };
        out.write_str(head)?;
        match cause {
            Cause::Decode(e) => e.write_to(out)?,
            Cause::Config(e) => e.write_to(out)?,
            Cause::Text(t) => out.write_str(t)?,
        }
        out.write_str("): ")?;
        out.write_str(DEFAULTS)?;
        // No intact record may be a board never saved (`lost_stored`): its fault, when
        // latched, says the rest.
        if matches!(self, Source::Corrupt(Corruption::NoIntactRecord)) {
            return Ok(());
        }
        out.write_str(LOST)
    }
}

/// The error inside a fallback's message.
enum Cause<'a> {
    Decode(&'a DecodeError),
    Config(&'a ConfigError),
    Text(&'static str),
}

impl core::fmt::Display for Source {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        self.write_to(f)
    }
}

/// The result of [`ConfigStore::load`]: always a usable configuration, and where it came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Loaded {
    /// The configuration to run with.
    pub config: ValidatedConfig,
    /// Where it came from; its `Display` is the message for the console and the log.
    pub source: Source,
}

/// A record to write: encoded straight into `sequential-storage`'s buffer.
struct Outgoing<'c>(&'c ControlConfig, u32);

impl<'a> Value<'a> for Outgoing<'_> {
    fn serialize_into(&self, buffer: &mut [u8]) -> Result<usize, SerializationError> {
        record::encode(self.0, self.1, buffer).ok_or(SerializationError::BufferTooSmall)
    }

    fn deserialize_from(_: &'a [u8]) -> Result<(Self, usize), SerializationError> {
        // Records are read back as bytes and decoded by `record::decode`.
        Err(SerializationError::InvalidFormat)
    }
}

/// One copy's newest valid record, or why there is none.
type CopyState = Result<(ValidatedConfig, u32), Source>;

/// `a` is a later save than `b` (sequence numbers compared with wrapping arithmetic).
fn newer(a: u32, b: u32) -> bool {
    (a.wrapping_sub(b) as i32) > 0
}

/// Whether every byte of `range` reads erased.
fn is_erased<F: NorFlash>(flash: &mut F, range: &Range<u32>) -> Result<bool, StoreError> {
    // Word by word (the range is whole pages), through the read `sequential-storage` uses.
    let mut word = [0u8; 8];
    let mut at = range.start;
    while at < range.end {
        read(flash, at, &mut word).map_err(|e| flash_error(&e))?;
        if word != [0xFF; 8] {
            return Ok(false);
        }
        at += 8;
    }
    Ok(true)
}

/// The configuration store over a flash range of an even number of erase pages, at least
/// four: the first half holds copy A, the second copy B.
pub struct ConfigStore<F: NorFlash> {
    flash: F,
    copies: [Range<u32>; 2],
    buf: Buf,
    seq: u32,
    /// The copy to write first on the next save: one that does not hold the newest record.
    first: usize,
    /// Sequence number of the newest position record (0: none).
    pos_seq: u32,
    /// Sequence number of the newest friction-scale record.
    friction_seq: u32,
    /// The stored record needs the ball-screw firmware: refuse every write.
    locked: bool,
}

/// An uncached map over one copy's range: rebuilt per operation at no cost.
fn map<'f, F: NorFlash>(flash: &'f mut F, range: &Range<u32>) -> Result<Map<'f, F>, StoreError>
where
    F::Error: Copy,
{
    let config = MapConfig::try_new(range.clone()).map_err(|_| StoreError::BadRange)?;
    Ok(MapStorage::new(
        Blocking(flash),
        config,
        Cache::new_uncached(),
    ))
}

impl<F: NorFlash> ConfigStore<F>
where
    F::Error: Copy,
{
    /// A store over `range` of `flash` (an even number of whole erase pages, at least four).
    pub fn new(flash: F, range: Range<u32>) -> Result<ConfigStore<F>, StoreError> {
        let page = F::ERASE_SIZE as u32;
        let len = range
            .end
            .checked_sub(range.start)
            .ok_or(StoreError::BadRange)?;
        if len % (2 * page) != 0 || len < 4 * page {
            return Err(StoreError::BadRange);
        }
        let mid = range.start + len / 2;
        let copies = [range.start..mid, mid..range.end];
        for c in &copies {
            MapConfig::<Blocking<'_, F>>::try_new(c.clone()).map_err(|_| StoreError::BadRange)?;
        }
        Ok(ConfigStore {
            flash,
            copies,
            buf: Buf([0; BUF_LEN]),
            seq: 0,
            first: 0,
            pos_seq: 0,
            friction_seq: 0,
            locked: false,
        })
    }

    /// The newest intact, valid configuration; otherwise the factory one and why. Never fails.
    ///
    /// May write to flash: `sequential-storage` repairs the traces of an interrupted operation
    /// on its first access.
    pub fn load(&mut self) -> Loaded {
        let a = self.load_copy(0);
        let b = self.load_copy(1);
        // Which copy's configuration runs (`None`: the factory one), decided on references
        // and copied once (moving the two results through the match copied the configuration
        // at every step).
        let (run, source) = match (&a, &b) {
            (Ok((ca, sa)), Ok((cb, sb))) => {
                // Next save writes the older copy first; equal copies: either.
                let (cfg, seq, first) = if newer(*sb, *sa) {
                    (cb, *sb, 0)
                } else {
                    (ca, *sa, 1)
                };
                self.first = first;
                self.seq = seq;
                let both_copies = sa == sb && ca == cb;
                (Some(cfg), Source::Stored { seq, both_copies })
            }
            (Ok((cfg, seq)), Err(e)) | (Err(e), Ok((cfg, seq))) => {
                // Next save writes the damaged copy (the one that failed) first.
                self.first = usize::from(a.is_ok());
                self.seq = *seq;
                if e.needs_ball_screw() {
                    // A ball screw's record in either copy (the newest, or a save the
                    // ball-screw firmware did not finish): never run this image's fallback
                    // on that lift.
                    (None, *e)
                } else {
                    let both_copies = false;
                    (
                        Some(cfg),
                        Source::Stored {
                            seq: *seq,
                            both_copies,
                        },
                    )
                }
            }
            // The more specific failure; a ball screw's record weighs most (as above).
            (Err(ea), Err(eb)) => (None, if eb.weight() > ea.weight() { *eb } else { *ea }),
        };
        self.locked = source.needs_ball_screw();
        Loaded {
            config: run.copied().unwrap_or_else(ValidatedConfig::factory),
            source,
        }
    }

    /// The newest item under `key` in `copy`, read into the work buffer (one routine for the
    /// configuration and the position record, both copies).
    fn fetch(&mut self, copy: usize, key: u8) -> Result<Option<&[u8]>, Source> {
        let mut m = map(&mut self.flash, &self.copies[copy]).map_err(Source::Unreadable)?;
        match run(m.fetch_item::<&[u8]>(&mut self.buf.0, &key)) {
            Ok(item) => Ok(item),
            Err(sequential_storage::Error::Corrupted { .. }) => {
                Err(Source::Corrupt(Corruption::Structure))
            }
            Err(e) => Err(Source::Unreadable(store_error(e))),
        }
    }

    fn load_copy(&mut self, copy: usize) -> CopyState {
        let bytes = match self.fetch(copy, CONFIG_KEY)? {
            Some(bytes) => bytes,
            None => {
                return Err(match is_erased(&mut self.flash, &self.copies[copy]) {
                    Ok(true) => Source::Missing,
                    Ok(false) => Source::Corrupt(Corruption::NoIntactRecord),
                    Err(e) => Source::Unreadable(e),
                })
            }
        };
        // Matched rather than `map_err(…)?`: each of those moved the whole configuration.
        let (cfg, seq) = match record::decode(bytes) {
            Ok(decoded) => decoded,
            Err(e @ (DecodeError::Version { .. } | DecodeError::Schema)) => {
                return Err(Source::Incompatible(e))
            }
            Err(e) => return Err(Source::Corrupt(Corruption::Record(e))),
        };
        if let Err(e) = crate::control::config::check_variant(&cfg) {
            return Err(Source::NeedsBallScrew(e));
        }
        match ValidatedConfig::new(cfg) {
            Ok(cfg) => Ok((cfg, seq)),
            Err(e) => Err(Source::Rejected(e)),
        }
    }

    /// Whether either copy holds an intact position record (of any geometry).
    pub fn has_position_record(&mut self) -> bool {
        (0..2).any(|copy| matches!(self.fetch(copy, POSITION_KEY), Ok(Some(_))))
    }

    /// Append `value` under `key` to `copy` (one routine for both records).
    fn put(&mut self, copy: usize, key: u8, value: &dyn Value<'_>) -> Result<(), StoreError> {
        let mut m = map(&mut self.flash, &self.copies[copy])?;
        run(m.store_item_generic(&mut self.buf.0, &key, value)).map_err(store_error)
    }

    /// Write `cfg` as the newest record to both copies, each read back and compared, the copy
    /// that does not hold the newest record first. Returns the save's sequence number. An
    /// interrupted save leaves the previous or the new record in force, never a mix.
    pub fn save(&mut self, cfg: &ValidatedConfig) -> Result<u32, StoreError> {
        if self.locked {
            return Err(StoreError::Locked);
        }
        let seq = self.seq.wrapping_add(1);
        let order = [self.first, 1 - self.first];
        for copy in order {
            self.save_copy(copy, cfg, seq)?;
        }
        self.seq = seq;
        Ok(seq)
    }

    fn save_copy(
        &mut self,
        copy: usize,
        cfg: &ValidatedConfig,
        seq: u32,
    ) -> Result<(), StoreError> {
        let record = Outgoing(cfg.get(), seq);
        let mut result = self.put(copy, CONFIG_KEY, &record);
        if result == Err(StoreError::Corrupted) {
            // Damage `sequential-storage` cannot repair: this copy holds nothing readable, the
            // other copy is untouched, so start this one afresh.
            self.erase_copy(copy)?;
            result = self.put(copy, CONFIG_KEY, &record);
        }
        result?;
        match self.load_copy(copy) {
            Ok((c, s)) if c == *cfg && s == seq => Ok(()),
            _ => Err(StoreError::Verify),
        }
    }

    fn erase_copy(&mut self, copy: usize) -> Result<(), StoreError> {
        let mut m = map(&mut self.flash, &self.copies[copy])?;
        run(m.erase_all()).map_err(store_error)
    }

    /// Where the lift was parked when the power went, if that is known: the newest intact
    /// position record of either copy, if it says "at rest" and was counted with `stamp`
    /// ([`geometry_stamp`] of the configuration in force). `None` (homing needed) when no
    /// record exists, the newest says a motion was under way, the geometry changed since, or
    /// the flash cannot be read.
    pub fn load_position(&mut self, stamp: u32) -> Option<i32> {
        let mut best: Option<PositionRecord> = None;
        for copy in 0..2 {
            if let Ok(Some(bytes)) = self.fetch(copy, POSITION_KEY) {
                if let Some(r) = PositionRecord::decode(bytes) {
                    if best.is_none_or(|b| newer(r.seq, b.seq)) {
                        best = Some(r);
                    }
                }
            }
        }
        let best = best?;
        self.pos_seq = best.seq;
        match best.parked {
            Parked::At(counts) if best.stamp == stamp => Some(counts),
            _ => None,
        }
    }

    /// Record the lift's position state in both copies, one after the other (a cut leaves the
    /// previous or the new record). Write [`Parked::Moving`] as a motion starts and
    /// [`Parked::At`] once the lift has settled.
    pub fn save_position(&mut self, parked: Parked, stamp: u32) -> Result<(), StoreError> {
        if self.locked {
            return Err(StoreError::Locked);
        }
        let rec = PositionRecord {
            parked,
            seq: self.pos_seq.wrapping_add(1),
            stamp,
        };
        let bytes = rec.encode();
        for copy in 0..2 {
            self.put(copy, POSITION_KEY, &bytes.as_slice())?;
        }
        self.pos_seq = rec.seq;
        Ok(())
    }

    /// The thread's friction scale identified before the power went (`crate::ident`), if a
    /// record stamped `stamp` ([`friction_stamp`] of the configuration in force) is intact in
    /// either copy (the newer of the two).
    pub fn load_friction_scale(&mut self, stamp: u32) -> Option<Ratio> {
        let mut best: Option<PositionRecord> = None;
        for copy in 0..2 {
            if let Ok(Some(bytes)) = self.fetch(copy, FRICTION_KEY) {
                if let Some(r) = PositionRecord::decode_as(bytes, FRICTION_MAGIC) {
                    if best.is_none_or(|b| newer(r.seq, b.seq)) {
                        best = Some(r);
                    }
                }
            }
        }
        let best = best?;
        self.friction_seq = best.seq;
        match best.parked {
            Parked::At(bits) if best.stamp == stamp && bits > 0 => Some(Ratio::from_bits(bits)),
            _ => None,
        }
    }

    /// Record the identified friction scale in both copies. The core asks for it only when
    /// the scale moved by more than `ident::STORE_STEP` (flash wear).
    pub fn save_friction_scale(&mut self, scale: Ratio, stamp: u32) -> Result<(), StoreError> {
        if self.locked {
            return Err(StoreError::Locked);
        }
        let rec = PositionRecord {
            parked: Parked::At(scale.to_bits()),
            seq: self.friction_seq.wrapping_add(1),
            stamp,
        };
        let bytes = rec.encode_as(FRICTION_MAGIC);
        for copy in 0..2 {
            self.put(copy, FRICTION_KEY, &bytes.as_slice())?;
        }
        self.friction_seq = rec.seq;
        Ok(())
    }

    /// Erase both copies (factory reset: the next load reports [`Source::Missing`]).
    pub fn erase(&mut self) -> Result<(), StoreError> {
        if self.locked {
            return Err(StoreError::Locked);
        }
        self.erase_copy(0)?;
        self.erase_copy(1)?;
        self.seq = 0;
        self.first = 0;
        Ok(())
    }

    /// Append `cfg` as record `seq` to `copy`, unvalidated and even when locked: a record
    /// another firmware wrote.
    #[cfg(all(test, not(feature = "ball-screw")))]
    pub(crate) fn put_record_for_tests(
        &mut self,
        copy: usize,
        cfg: &ControlConfig,
        seq: u32,
    ) -> Result<(), StoreError> {
        self.put(copy, CONFIG_KEY, &Outgoing(cfg, seq))
    }

    /// Sequence number of the last record loaded or saved (0: none).
    pub fn seq(&self) -> u32 {
        self.seq
    }

    /// The flash, e.g. to inspect the simulation.
    pub fn flash(&mut self) -> &mut F {
        &mut self.flash
    }

    /// Give the flash back.
    pub fn into_flash(self) -> F {
        self.flash
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    extern crate std;
    use std::format;
    use std::string::ToString;

    /// Every message as the `write!` form before `write_to` spelled it.
    #[test]
    fn source_messages_are_those_of_the_write_forms() {
        const DEFAULTS: &str = "factory defaults in use (limits at the factory stops)";
        const LOST: &str = "; motion refused until `fault clear` (set the stops first)";
        let decode = DecodeError::Version { found: 7 };
        let config = ConfigError::OutOfRange {
            field: "limits.upper",
            range: "the mechanism's height range (see `limits`)",
        };
        let store = StoreError::Flash(FlashErrorKind::OutOfBounds);
        let cases = [
            (
                Source::Stored {
                    seq: 42,
                    both_copies: true,
                },
                "configuration #42 loaded from flash".to_string(),
            ),
            (
                Source::Stored {
                    seq: u32::MAX,
                    both_copies: false,
                },
                format!(
                    "configuration #{} loaded from flash (its second copy is older or damaged; \
                     `save` rewrites it)",
                    u32::MAX
                ),
            ),
            (
                Source::Missing,
                format!("no stored configuration: {DEFAULTS}; `save` stores the current settings"),
            ),
            (
                Source::Corrupt(Corruption::NoIntactRecord),
                format!(
                    "stored configuration is corrupt (no intact record: damaged, or the first \
                     save was interrupted): {DEFAULTS}"
                ),
            ),
            (
                Source::Corrupt(Corruption::Structure),
                format!(
                    "stored configuration is corrupt (store structure damaged): {DEFAULTS}{LOST}"
                ),
            ),
            (
                Source::Corrupt(Corruption::Record(DecodeError::BadCrc)),
                format!("stored configuration is corrupt (record fails its CRC): {DEFAULTS}{LOST}"),
            ),
            (
                Source::Incompatible(decode),
                format!(
                    "stored configuration not used, version mismatch (record is format version \
                     7, this firmware reads version {}): {DEFAULTS}{LOST}",
                    record::VERSION
                ),
            ),
            (
                Source::Rejected(config),
                format!(
                    "stored configuration refused (limits.upper out of range (allowed the \
                     mechanism's height range (see `limits`))): {DEFAULTS}{LOST}"
                ),
            ),
            (
                Source::Unreadable(store),
                format!(
                    "configuration store unreadable (flash driver error (out of bounds)): \
                     {DEFAULTS}{LOST}"
                ),
            ),
        ];
        for (source, want) in cases {
            assert_eq!(source.to_string(), want);
        }
    }
}
