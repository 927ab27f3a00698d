//! The file format: magic, version, record kinds, errors, and the byte codecs both sides share.

/// File magic.
pub const MAGIC: [u8; 4] = *b"LFGV";
/// File format version.
pub const VERSION: u16 = 1;
/// Longest estimator sequence in one record (bounds the target's work per record).
pub const MAX_SEQUENCE: usize = 64;

/// What a record exercises.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u8)]
pub enum Kind {
    /// `Estimator::estimate` at a given speed and acceleration (no filter state).
    EstimatorEstimate = 1,
    /// A fresh `Estimator` fed a sequence of `step(now, measurements)`: the filter and its state.
    EstimatorSequence = 2,
    /// A `control::profile::Profile` (ramp/planner) driven by a script of `set_target`, `stop`,
    /// `set_cruise`, `reset` and `step` operations.
    ProfileSequence = 3,
    /// `console::parse` of one line: the `Debug` text of its result (request, or error with the
    /// offending words).
    ConsoleParse = 4,
    /// A `detect::stickslip::StickSlipDetector` fed a synthesised torque trace (stick-slip
    /// sawtooth, noise, nonsense) tick by tick: every output of every tick.
    DetectorSequence = 5,
    /// A `control::Controller` stepped tick by tick (`step(now, &Inputs)`) against a small
    /// integer plant, with commands, switches, load and supply changes at scripted ticks.
    ControlTick = 6,
}

impl Kind {
    /// All kinds, in file order.
    pub const ALL: [Kind; 6] = [
        Kind::EstimatorEstimate,
        Kind::EstimatorSequence,
        Kind::ProfileSequence,
        Kind::ConsoleParse,
        Kind::DetectorSequence,
        Kind::ControlTick,
    ];

    pub(crate) fn from_u8(v: u8) -> Option<Kind> {
        Kind::ALL.into_iter().find(|k| *k as u8 == v)
    }

    /// Short name, for reports.
    pub fn name(self) -> &'static str {
        match self {
            Kind::EstimatorEstimate => "estimator.estimate",
            Kind::EstimatorSequence => "estimator.step",
            Kind::ProfileSequence => "profile.step",
            Kind::ConsoleParse => "console.parse",
            Kind::DetectorSequence => "stickslip.step",
            Kind::ControlTick => "control.tick",
        }
    }
}

/// A malformed file or record.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Error {
    /// The file does not start with [`MAGIC`].
    BadMagic,
    /// Another format version.
    BadVersion(u16),
    /// A record or field runs past the end.
    Truncated,
    /// A kind this build does not know.
    UnknownKind(u8),
    /// A configuration index outside [`config`](crate::config).
    UnknownConfig(u8),
    /// A sequence longer than [`MAX_SEQUENCE`].
    SequenceTooLong(u16),
    /// A field outside its codec's range (e.g. an unknown operation code).
    BadField(u8),
}

impl core::fmt::Display for Error {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Error::BadMagic => write!(f, "not a golden-vector file"),
            Error::BadVersion(v) => write!(f, "format version {v}, expected {VERSION}"),
            Error::Truncated => write!(f, "truncated record"),
            Error::UnknownKind(k) => write!(f, "unknown record kind {k}"),
            Error::UnknownConfig(c) => write!(f, "unknown configuration {c}"),
            Error::SequenceTooLong(n) => write!(f, "sequence of {n} steps (max {MAX_SEQUENCE})"),
            Error::BadField(v) => write!(f, "field value {v} outside its codec"),
        }
    }
}

/// Where encoded bytes go: a `Vec` on the host, a comparator on the target.
pub trait Sink {
    /// Append bytes.
    fn put(&mut self, bytes: &[u8]);
    /// Append an `i32`, little-endian.
    fn put_i32(&mut self, v: i32) {
        self.put(&v.to_le_bytes());
    }
    /// Append an `i64`, little-endian.
    fn put_i64(&mut self, v: i64) {
        self.put(&v.to_le_bytes());
    }
    /// Append a `u64`, little-endian.
    fn put_u64(&mut self, v: u64) {
        self.put(&v.to_le_bytes());
    }
    /// Append a `u32`, little-endian.
    fn put_u32(&mut self, v: u32) {
        self.put(&v.to_le_bytes());
    }
    /// Append a `u16`, little-endian.
    fn put_u16(&mut self, v: u16) {
        self.put(&v.to_le_bytes());
    }
    /// Append a byte.
    fn put_u8(&mut self, v: u8) {
        self.put(&[v]);
    }
}

/// Counts the bytes put (to size a record before writing it).
#[derive(Default)]
pub struct Counter(pub usize);

impl Sink for Counter {
    fn put(&mut self, bytes: &[u8]) {
        self.0 += bytes.len();
    }
}

/// Compares the bytes put against an expected slice.
pub struct Compare<'a> {
    expected: &'a [u8],
    pos: usize,
    /// Byte offset of the first difference (or of the first byte past either end).
    pub first_mismatch: Option<usize>,
}

impl<'a> Compare<'a> {
    /// Compare against `expected`.
    pub fn new(expected: &'a [u8]) -> Self {
        Compare {
            expected,
            pos: 0,
            first_mismatch: None,
        }
    }

    /// Whether everything put matched and covered the whole expected slice.
    pub fn finish(&mut self) -> bool {
        if self.first_mismatch.is_none() && self.pos != self.expected.len() {
            self.first_mismatch = Some(self.pos.min(self.expected.len()));
        }
        self.first_mismatch.is_none()
    }
}

impl Sink for Compare<'_> {
    fn put(&mut self, bytes: &[u8]) {
        for (i, b) in bytes.iter().enumerate() {
            let at = self.pos + i;
            if self.first_mismatch.is_none() && self.expected.get(at) != Some(b) {
                self.first_mismatch = Some(at);
            }
        }
        self.pos += bytes.len();
    }
}

/// A little-endian reader over a byte slice; every read is checked.
pub(crate) struct Reader<'a> {
    pub(crate) b: &'a [u8],
}

impl<'a> Reader<'a> {
    pub(crate) fn take(&mut self, n: usize) -> Result<&'a [u8], Error> {
        if self.b.len() < n {
            return Err(Error::Truncated);
        }
        let (h, t) = self.b.split_at(n);
        self.b = t;
        Ok(h)
    }
    pub(crate) fn array<const N: usize>(&mut self) -> Result<[u8; N], Error> {
        let mut a = [0u8; N];
        a.copy_from_slice(self.take(N)?);
        Ok(a)
    }
    pub(crate) fn u8(&mut self) -> Result<u8, Error> {
        Ok(self.array::<1>()?[0])
    }
    pub(crate) fn u16(&mut self) -> Result<u16, Error> {
        Ok(u16::from_le_bytes(self.array()?))
    }
    pub(crate) fn u32(&mut self) -> Result<u32, Error> {
        Ok(u32::from_le_bytes(self.array()?))
    }
    pub(crate) fn i32(&mut self) -> Result<i32, Error> {
        Ok(i32::from_le_bytes(self.array()?))
    }
    pub(crate) fn i64(&mut self) -> Result<i64, Error> {
        Ok(i64::from_le_bytes(self.array()?))
    }
}

/// Longest record input, bytes.
pub(crate) const INPUT_MAX: usize = 32 + MAX_SEQUENCE * 17;

/// A record's input, built on the stack.
pub(crate) struct InputBuf {
    pub(crate) data: [u8; INPUT_MAX],
    pub(crate) len: usize,
    pub(crate) overflow: bool,
}

impl InputBuf {
    pub(crate) fn new() -> Self {
        InputBuf {
            data: [0; INPUT_MAX],
            len: 0,
            overflow: false,
        }
    }
}

impl Sink for InputBuf {
    fn put(&mut self, b: &[u8]) {
        match self.data.get_mut(self.len..self.len + b.len()) {
            Some(dst) => dst.copy_from_slice(b),
            None => self.overflow = true,
        }
        self.len += b.len();
    }
}

/// FNV-1a over 64-bit words: a portable fold of many outputs into one (same code both sides).
pub(crate) struct Fold(pub(crate) u64);

impl Fold {
    pub(crate) fn new() -> Self {
        Fold(0xcbf2_9ce4_8422_2325)
    }
    pub(crate) fn word(&mut self, w: u64) {
        self.0 = (self.0 ^ w).wrapping_mul(0x0000_0100_0000_01b3);
    }
}

/// Formatted text into a [`Sink`].
pub(crate) struct Text<'a, S: Sink>(pub(crate) &'a mut S);

impl<S: Sink> core::fmt::Write for Text<'_, S> {
    fn write_str(&mut self, s: &str) -> core::fmt::Result {
        self.0.put(s.as_bytes());
        Ok(())
    }
}
