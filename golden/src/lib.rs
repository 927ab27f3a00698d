//! Golden vectors of the liftfw core: generated on the host, replayed bit for bit on the target.
//!
//! Issue 8 asks for proof that the core computes on the Cortex-M4 exactly what it computes on
//! the host. This crate holds everything both sides share, so that they run the *same source*:
//!
//! - the case generator ([`generate`]): deterministic (SplitMix64, fixed seed), covering the
//!   envelope, its edges and nonsense bit patterns, for every configuration in [`config`];
//! - the evaluator ([`evaluate`]): decodes one input, calls the core, encodes every output field
//!   as raw little-endian bits;
//! - the file format and its checker ([`verify`]): the host writes inputs + outputs
//!   (`golden-gen`), the QEMU program embeds the file (`include_bytes!`), re-evaluates each input
//!   and compares the bytes.
//!
//! # File format (all little-endian)
//! `b"LFGV"`, version `u16`, then records until the end: `kind u8`, `input_len u32`,
//! `output_len u32`, input bytes, output bytes.
//!
//! # Kinds
//! | kind | core call | input | output |
//! |---|---|---|---|
//! | [`Kind::EstimatorEstimate`] | `Estimator::estimate` | config, measurements, speed, accel, flags | every field |
//! | [`Kind::EstimatorSequence`] | `Estimator::step` + `details` | config, 50 ticks of measurements | every field of every tick |
//! | [`Kind::ProfileSequence`] | `Profile::new`, `set_target`, `stop`, `set_cruise`, `reset`, `step` | a script of operations ([`OP_STEPS`]…) | each reference in full ([`OP_STEPS`]) or folded into a 64-bit hash with the last one ([`OP_RUN`]); the target after every operation |
//! | [`Kind::ConsoleParse`] | `console::parse` | the line's bytes | the `Debug` text of the result (+ `goto`'s raw bits) |
//! | [`Kind::DetectorSequence`] | `StickSlipDetector::step` | settings + the parameters of a synthesised trace ([`DetectorTrace`]) | every report, run-length coded (lossless) + a fold |
//! | [`Kind::ControlTick`] | `Controller::command`, `Controller::step` | config, start, a script of commands and plant changes | every command's answer; outputs and state run-length coded, events as `Debug` text |
//!
//! Long runs (detector traces, control runs) synthesise their inputs from a few parameters in
//! integer arithmetic on both sides (the same source), so the file holds the parameters, not
//! thousands of ticks. Each kind after the first two draws from its own seed: adding a kind
//! leaves the records of the others unchanged.
//!
//! # Adding a kind
//! 1. a new [`Kind`] variant (never renumber the old ones) and its entry in [`Kind::ALL`];
//! 2. its input codec and an arm in [`evaluate`] that calls the core and [`put_*`](Sink) its
//!    outputs field by field (raw bits, fixed order);
//! 3. a case generator called from [`generate`].
//!
//! The QEMU harness needs no change: it replays whatever kinds the file holds and prints a
//! `GOLDEN` line per entry of [`Kind::ALL`].
#![no_std]
#![forbid(unsafe_code)]

use liftfw::estimator::MotorConfig;
use liftfw::estimator::{Estimate, Estimator, EstimatorConfig, Measurements, TickEstimate};
use liftfw::model::friction::{FrictionLaw, LawVariable};
use liftfw::model::geometry::{DriveConfig, GeometryConfig};
use liftfw::model::screw::MechanicsConfig;
use liftfw::units::{
    Amperes, Instant, Kilograms, Metres, NewtonMetres, RadiansPerSecond, RadiansPerSecond2, Ratio,
};

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

    fn from_u8(v: u8) -> Option<Kind> {
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
    /// A configuration index outside [`config`].
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
struct Reader<'a> {
    b: &'a [u8],
}

impl<'a> Reader<'a> {
    fn take(&mut self, n: usize) -> Result<&'a [u8], Error> {
        if self.b.len() < n {
            return Err(Error::Truncated);
        }
        let (h, t) = self.b.split_at(n);
        self.b = t;
        Ok(h)
    }
    fn array<const N: usize>(&mut self) -> Result<[u8; N], Error> {
        let mut a = [0u8; N];
        a.copy_from_slice(self.take(N)?);
        Ok(a)
    }
    fn u8(&mut self) -> Result<u8, Error> {
        Ok(self.array::<1>()?[0])
    }
    fn u16(&mut self) -> Result<u16, Error> {
        Ok(u16::from_le_bytes(self.array()?))
    }
    fn u32(&mut self) -> Result<u32, Error> {
        Ok(u32::from_le_bytes(self.array()?))
    }
    fn i32(&mut self) -> Result<i32, Error> {
        Ok(i32::from_le_bytes(self.array()?))
    }
    fn i64(&mut self) -> Result<i64, Error> {
        Ok(i64::from_le_bytes(self.array()?))
    }
}

/// Number of configurations in [`config`].
pub const CONFIGS: u8 = 6;

/// The estimator configurations the vectors run under: the presets and both corners of every
/// validated range (so configuration-time quantisation is proven bit-exact too).
pub fn config(id: u8) -> Option<EstimatorConfig> {
    let d = EstimatorConfig::DEFAULT;
    Some(match id {
        0 => d,
        1 => EstimatorConfig {
            law: FrictionLaw::PTFE,
            ..d
        },
        2 => EstimatorConfig {
            law: FrictionLaw::LITHIUM,
            ..d
        },
        3 => EstimatorConfig {
            law: FrictionLaw::BALL_SCREW,
            ..d
        },
        // Upper corners of the ranges.
        4 => EstimatorConfig {
            geometry: GeometryConfig {
                length: Metres::lit("2"),
                alpha0_deg: fixed_deg(60),
                alpha_max_deg: fixed_deg(89),
                h0: Metres::lit("1"),
                mu_pin: Ratio::ONE,
            },
            drive: DriveConfig {
                counts_per_rev: 65_536,
                gear_ratio: fixed_deg(1000),
                pitch_radius: Metres::lit("0.05"),
                lead_angle_deg: fixed_deg(20),
            },
            mechanics: MechanicsConfig {
                inertia_ukgm2: 100_000,
                damping_unms: 1_000_000,
                support_torque: NewtonMetres::lit("10"),
                nut_mass: Kilograms::lit("5"),
                ..MechanicsConfig::DEFAULT
            },
            law: FrictionLaw {
                base: Ratio::ONE,
                amp: Ratio::ONE,
                rate: fixed::types::I32F32::lit("1000000"),
                slope: fixed::types::I32F32::lit("1000"),
                s_max: fixed::types::I32F32::lit("0.5"),
                variable: LawVariable::SlidingSpeed,
            },
            motor: MotorConfig {
                torque_constant: Ratio::ONE,
                gear_efficiency: Ratio::lit("0.1"),
                ..MotorConfig::DEFAULT
            },
            tick_us: 100,
            speed_bandwidth_hz: 1000,
            rest_speed: RadiansPerSecond::lit("50"),
        },
        // Lower corners.
        5 => EstimatorConfig {
            geometry: GeometryConfig {
                length: Metres::lit("0.05"),
                alpha0_deg: fixed_deg(12),
                alpha_max_deg: fixed_deg(17),
                h0: Metres::ZERO,
                mu_pin: Ratio::ZERO,
            },
            drive: DriveConfig {
                counts_per_rev: 4,
                gear_ratio: fixed_deg(1),
                pitch_radius: Metres::lit("0.001"),
                lead_angle_deg: fixed::types::I16F16::lit("0.5"),
            },
            mechanics: MechanicsConfig {
                inertia_ukgm2: 0,
                damping_unms: 0,
                support_torque: NewtonMetres::ZERO,
                nut_mass: Kilograms::ZERO,
                ..MechanicsConfig::DEFAULT
            },
            law: FrictionLaw {
                base: Ratio::ZERO,
                amp: Ratio::ONE.sat_neg(),
                rate: fixed::types::I32F32::ZERO,
                slope: fixed::types::I32F32::lit("-1000"),
                s_max: fixed::types::I32F32::MAX,
                variable: LawVariable::ScrewRate,
            },
            motor: MotorConfig {
                torque_constant: Ratio::lit("0.001"),
                gear_efficiency: Ratio::ONE,
                ..MotorConfig::DEFAULT
            },
            tick_us: 10_000,
            speed_bandwidth_hz: 1,
            rest_speed: RadiansPerSecond::ZERO,
        },
        _ => return None,
    })
}

fn fixed_deg(v: i32) -> fixed::types::I16F16 {
    fixed::types::I16F16::from_num(v)
}

fn estimator(cfg_id: u8) -> Result<Estimator, Error> {
    let cfg = config(cfg_id).ok_or(Error::UnknownConfig(cfg_id))?;
    Estimator::new(&cfg).map_err(|_| Error::UnknownConfig(cfg_id))
}

/// Every field of an estimate, as raw bits in a fixed order.
pub fn put_estimate(s: &mut impl Sink, e: &Estimate) {
    let p = &e.pose;
    s.put_i32(p.x.to_bits());
    s.put_i32(p.cos_alpha.to_bits());
    s.put_i32(p.sin_alpha.to_bits());
    s.put_i32(p.inv_sin_alpha.to_bits());
    s.put_i32(p.alpha.0);
    s.put_i32(p.height.to_bits());
    s.put_u8(u8::from(p.clamped));
    s.put_i32(e.screw_speed.to_bits());
    s.put_i32(e.screw_accel.to_bits());
    s.put_i32(e.axial_load.to_bits());
    s.put_i32(e.pin_friction.to_bits());
    s.put_i32(e.structure_damping.to_bits());
    s.put_i32(e.mu.to_bits());
    let c = &e.contact;
    s.put_i32(c.mu_s.to_bits());
    s.put_i32(c.xi.to_bits());
    s.put_i32(c.axial.to_bits());
    s.put_i32(c.normal.to_bits());
    s.put_i32(c.friction_torque.to_bits());
    s.put_i32(c.thread_torque.to_bits());
    s.put_i32(e.model_screw_torque.to_bits());
    s.put_i32(e.model_motor_torque.to_bits());
    s.put_i32(e.measured_screw_torque.to_bits());
    s.put_i32(e.residual.to_bits());
    s.put_i32(e.self_locking_margin.to_bits());
    s.put_u8(e.flags.0);
}

/// Every field of a tick estimate, as raw bits in a fixed order.
pub fn put_tick(s: &mut impl Sink, t: &TickEstimate) {
    s.put_i32(t.height.to_bits());
    s.put_i32(t.screw_speed.to_bits());
    s.put_i32(t.screw_accel.to_bits());
    s.put_i32(t.friction_torque.to_bits());
    s.put_i32(t.axial.to_bits());
    s.put_i32(t.thread_torque.to_bits());
    s.put_i32(t.model_screw_torque.to_bits());
    s.put_i32(t.model_motor_torque.to_bits());
    s.put_i32(t.measured_screw_torque.to_bits());
    s.put_u8(t.flags.0);
}

fn put_measurements(s: &mut impl Sink, m: &Measurements) {
    s.put_i32(m.position_counts);
    s.put_i32(m.motor_current.to_bits());
    s.put_i32(m.load.to_bits());
    s.put(&m.commanded_dir.to_le_bytes());
}

fn read_measurements(r: &mut Reader<'_>) -> Result<Measurements, Error> {
    Ok(Measurements {
        position_counts: r.i32()?,
        motor_current: Amperes::from_bits(r.i32()?),
        load: Kilograms::from_bits(r.i32()?),
        commanded_dir: i8::from_le_bytes(r.array()?),
    })
}

/// One `estimate` case.
#[derive(Clone, Copy, Debug)]
pub struct EstimateCase {
    /// Index into [`config`].
    pub cfg: u8,
    /// Measurements.
    pub m: Measurements,
    /// Screw speed handed to the model.
    pub speed: RadiansPerSecond,
    /// Screw acceleration handed to the model.
    pub accel: RadiansPerSecond2,
    /// Incoming flags.
    pub flags: u8,
}

impl EstimateCase {
    fn put(&self, s: &mut impl Sink) {
        s.put_u8(self.cfg);
        put_measurements(s, &self.m);
        s.put_i32(self.speed.to_bits());
        s.put_i32(self.accel.to_bits());
        s.put_u8(self.flags);
    }
}

/// Run one record's input through the core and put its outputs.
pub fn evaluate(kind: u8, input: &[u8], out: &mut impl Sink) -> Result<(), Error> {
    let mut r = Reader { b: input };
    match Kind::from_u8(kind).ok_or(Error::UnknownKind(kind))? {
        Kind::EstimatorEstimate => {
            let est = estimator(r.u8()?)?;
            let m = read_measurements(&mut r)?;
            let speed = RadiansPerSecond::from_bits(r.i32()?);
            let accel = RadiansPerSecond2::from_bits(r.i32()?);
            let flags = r.u8()?;
            put_estimate(out, &est.estimate(&m, speed, accel, flags));
        }
        Kind::EstimatorSequence => {
            let mut est = estimator(r.u8()?)?;
            let n = r.u16()?;
            if usize::from(n) > MAX_SEQUENCE {
                return Err(Error::SequenceTooLong(n));
            }
            for _ in 0..n {
                let now = Instant(r.u32()?);
                let m = read_measurements(&mut r)?;
                // The tick's own fields, then the whole estimate recomputed from them: both
                // paths of the model, bit for bit.
                let t = est.step(now, &m);
                put_tick(out, &t);
                put_estimate(out, &est.details(&m, &t));
                // As the control tick runs it: the steps that enter a segment read one prepared
                // ahead (the same bits as a refill, replayed on both sides).
                est.prepare();
            }
        }
        Kind::ProfileSequence => eval_profile(&mut r, out)?,
        Kind::DetectorSequence => eval_detector(&mut r, out)?,
        Kind::ControlTick => eval_control(&mut r, out)?,
        Kind::ConsoleParse => {
            // The whole input is the line; `Debug` spells every field of the result (variant,
            // setting, raw value bits, error kind, the offending words) and is the same code
            // on both sides.
            let line = r.take(r.b.len())?;
            let parsed = liftfw::console::parse(line);
            core::fmt::write(&mut Text(out), format_args!("{parsed:?}"))
                .map_err(|_| Error::BadField(0))?;
            // The one field `Debug` shows in decimal rather than as raw bits.
            if let Ok(Some(liftfw::console::Request::Goto(h))) = parsed {
                out.put_i32(h.to_bits());
            }
        }
    }
    if r.b.is_empty() {
        Ok(())
    } else {
        Err(Error::Truncated)
    }
}

/// Longest record input, bytes.
const INPUT_MAX: usize = 32 + MAX_SEQUENCE * 17;

/// A record's input, built on the stack.
struct InputBuf {
    data: [u8; INPUT_MAX],
    len: usize,
    overflow: bool,
}

impl InputBuf {
    fn new() -> Self {
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

/// Write one record: its input and the outputs [`evaluate`] gives for it.
fn record(s: &mut impl Sink, kind: Kind, input: &InputBuf) -> Result<(), Error> {
    let bytes = match input.data.get(..input.len) {
        Some(b) if !input.overflow => b,
        _ => return Err(Error::Truncated),
    };
    let mut out_len = Counter::default();
    evaluate(kind as u8, bytes, &mut out_len)?;
    s.put_u8(kind as u8);
    s.put_u32(bytes.len() as u32);
    s.put_u32(out_len.0 as u32);
    s.put(bytes);
    evaluate(kind as u8, bytes, s)
}

/// SplitMix64: a tiny, well-mixed, seedable generator (no dependency, same on every target).
pub struct SplitMix64(pub u64);

impl SplitMix64 {
    /// Next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    /// 32 random bits.
    pub fn bits(&mut self) -> i32 {
        (self.next_u64() >> 32) as i32
    }
    /// Uniform in `lo..=hi` (i64 arithmetic, no bias worth caring about here).
    pub fn range(&mut self, lo: i64, hi: i64) -> i64 {
        let span = (hi - lo) as u64 + 1;
        lo + (self.next_u64() % span) as i64
    }
    /// True with probability `num/den`.
    pub fn chance(&mut self, num: u64, den: u64) -> bool {
        self.next_u64() % den < num
    }
}

/// Motor counts at which the pose reaches `alpha_max` (binary search on the core's own pose).
fn counts_at_alpha_max(est: &Estimator) -> i32 {
    let g = est.geometry();
    let (mut lo, mut hi) = (0i64, i64::from(i32::MAX));
    while lo < hi {
        let mid = (lo + hi) / 2;
        if g.pose(mid as i32).alpha >= g.alpha_max() {
            hi = mid;
        } else {
            lo = mid + 1;
        }
    }
    lo as i32
}

/// Edge values of a 32-bit field around `centre`.
const EDGES: [i64; 9] = [
    i32::MIN as i64,
    i32::MIN as i64 + 1,
    -65_536,
    -1,
    0,
    1,
    65_536,
    i32::MAX as i64 - 1,
    i32::MAX as i64,
];

/// Number of `estimate` cases per configuration.
pub const ESTIMATE_CASES_PER_CONFIG: u32 = 500;
/// Number of step sequences per configuration.
pub const SEQUENCES_PER_CONFIG: u32 = 6;
/// Steps per sequence.
pub const SEQUENCE_LEN: u16 = 50;

fn estimate_case(rng: &mut SplitMix64, cfg: u8, c_max: i32, rest: i32, k: u32) -> EstimateCase {
    let pick = |rng: &mut SplitMix64, envelope: i64, edges: &[i64]| -> i32 {
        match rng.range(0, 9) {
            // Nonsense: any bit pattern.
            0 => rng.bits(),
            // An edge value.
            1 => edges[rng.range(0, edges.len() as i64 - 1) as usize] as i32,
            // Inside the envelope.
            _ => rng.range(-envelope, envelope) as i32,
        }
    };
    let c_max_i = i64::from(c_max);
    let counts_edges = [
        -1,
        0,
        1,
        c_max_i - 1,
        c_max_i,
        c_max_i + 1,
        i64::from(i32::MIN),
        i64::from(i32::MAX),
    ];
    let position_counts = match rng.range(0, 9) {
        0 => rng.bits(),
        1 => counts_edges[rng.range(0, 7) as usize] as i32,
        // α₀ − 5° … past 89.5°: 10 % either side of the working range.
        _ => rng.range(-c_max_i / 10, c_max_i + c_max_i / 10) as i32,
    };
    let rest = i64::from(rest);
    let speed_edges = [
        -rest - 1,
        -rest,
        -rest + 1,
        rest - 1,
        rest,
        rest + 1,
        0,
        i64::from(i32::MIN),
        i64::from(i32::MAX),
    ];
    // The first cases of each configuration walk the rest-band edges deterministically.
    let speed = if (k as usize) < speed_edges.len() {
        speed_edges[k as usize] as i32
    } else {
        pick(rng, 400 << 16, &speed_edges)
    };
    EstimateCase {
        cfg,
        m: Measurements {
            position_counts,
            motor_current: Amperes::from_bits(pick(rng, 30 << 16, &EDGES)),
            load: Kilograms::from_bits(match rng.range(0, 9) {
                0 => rng.bits(),
                1 => EDGES[rng.range(0, 8) as usize] as i32,
                _ => rng.range(0, 2000 << 12) as i32,
            }),
            commanded_dir: if rng.chance(1, 10) {
                rng.bits() as i8
            } else {
                rng.range(-1, 1) as i8
            },
        },
        speed: RadiansPerSecond::from_bits(speed),
        accel: RadiansPerSecond2::from_bits(pick(rng, 2000 << 8, &EDGES)),
        flags: if rng.chance(1, 10) {
            rng.bits() as u8
        } else {
            0
        },
    }
}

/// One motion as the encoder sees it: accelerate, cruise, brake, with optional glitches.
fn sequence(rng: &mut SplitMix64, cfg: &EstimatorConfig, c_max: i32, out: &mut impl Sink) {
    let mut now = if rng.chance(1, 4) {
        u32::MAX - 20 * cfg.tick_us // the µs clock wraps inside this run
    } else {
        rng.next_u64() as u32
    };
    // Position in Q16 counts; speed in Q16 counts per tick, acceleration per tick².
    let mut pos = rng.range(0, i64::from(c_max)) << 16;
    let mut vel: i64 = 0;
    let acc = rng.range(-(1 << 16), 1 << 16);
    let glitchy = rng.chance(1, 3);
    let load = Kilograms::from_bits(rng.range(0, 2000 << 12) as i32);
    for k in 0..SEQUENCE_LEN {
        let phase = u32::from(k) * 3 / u32::from(SEQUENCE_LEN);
        vel += match phase {
            0 => acc,
            1 => 0,
            _ => -acc,
        };
        pos += vel;
        let mut counts = (pos >> 16) as i32;
        let mut step = cfg.tick_us;
        if glitchy {
            if rng.chance(1, 10) {
                counts = rng.bits(); // encoder glitch
            }
            if rng.chance(1, 10) {
                step = rng.range(0, i64::from(cfg.tick_us) * 5) as u32; // late or early tick
            }
        }
        now = now.wrapping_add(step);
        out.put_u32(now);
        put_measurements(
            out,
            &Measurements {
                position_counts: counts,
                motor_current: Amperes::from_bits(rng.range(-(20 << 16), 20 << 16) as i32),
                load,
                commanded_dir: if vel >= 0 { 1 } else { -1 },
            },
        );
    }
}

/// Every golden record, in a fixed order, from a fixed seed.
pub fn generate(s: &mut impl Sink) -> Result<(), Error> {
    s.put(&MAGIC);
    s.put_u16(VERSION);
    let mut rng = SplitMix64(0x6c69_6674_6677_0008); // "liftfw", issue 8
    for cfg in 0..CONFIGS {
        let est = estimator(cfg)?;
        let c_max = counts_at_alpha_max(&est);
        let rest = config(cfg).map_or(0, |c| c.rest_speed.to_bits());
        for k in 0..ESTIMATE_CASES_PER_CONFIG {
            let case = estimate_case(&mut rng, cfg, c_max, rest, k);
            let mut input = InputBuf::new();
            case.put(&mut input);
            record(s, Kind::EstimatorEstimate, &input)?;
        }
    }
    for cfg in 0..CONFIGS {
        let conf = config(cfg).ok_or(Error::UnknownConfig(cfg))?;
        let c_max = counts_at_alpha_max(&estimator(cfg)?);
        for _ in 0..SEQUENCES_PER_CONFIG {
            let seed = rng.next_u64();
            let mut input = InputBuf::new();
            input.put_u8(cfg);
            input.put_u16(SEQUENCE_LEN);
            sequence(&mut SplitMix64(seed), &conf, c_max, &mut input);
            record(s, Kind::EstimatorSequence, &input)?;
        }
    }
    // A separate stream per kind: adding a kind leaves the earlier kinds' records unchanged.
    generate_profiles(&mut SplitMix64(0x6c66_7072_6f66_696c), s)?;
    generate_console(&mut SplitMix64(0x6c66_636f_6e73_6f6c), s)?;
    generate_detector(&mut SplitMix64(0x6c66_6465_7465_6374), s)?;
    generate_control(&mut SplitMix64(0x6c66_636f_6e74_726c), s)?;
    Ok(())
}

/// Outcome of replaying a golden file.
#[derive(Clone, Copy, Debug, Default)]
pub struct Report {
    /// Records replayed, per [`Kind`] (index = position in [`Kind::ALL`]).
    pub records: [u32; Kind::ALL.len()],
    /// Records whose outputs differed, per kind.
    pub mismatches: [u32; Kind::ALL.len()],
    /// The first mismatch: (record index, kind, byte offset into its output).
    pub first_mismatch: Option<(u32, u8, u32)>,
}

impl Report {
    /// No mismatch.
    pub fn passed(&self) -> bool {
        self.mismatches.iter().all(|&m| m == 0)
    }
}

/// Replay every record of a golden file and compare the outputs byte for byte.
pub fn verify(file: &[u8]) -> Result<Report, Error> {
    let mut r = Reader { b: file };
    if r.array::<4>()? != MAGIC {
        return Err(Error::BadMagic);
    }
    let v = r.u16()?;
    if v != VERSION {
        return Err(Error::BadVersion(v));
    }
    let mut rep = Report::default();
    let mut index = 0u32;
    while !r.b.is_empty() {
        let kind = r.u8()?;
        let k = Kind::ALL
            .iter()
            .position(|x| *x as u8 == kind)
            .ok_or(Error::UnknownKind(kind))?;
        let in_len = r.u32()? as usize;
        let out_len = r.u32()? as usize;
        let input = r.take(in_len)?;
        let expected = r.take(out_len)?;
        let mut cmp = Compare::new(expected);
        evaluate(kind, input, &mut cmp)?;
        rep.records[k] += 1;
        if !cmp.finish() {
            rep.mismatches[k] += 1;
            if rep.first_mismatch.is_none() {
                let at = cmp.first_mismatch.unwrap_or(0) as u32;
                rep.first_mismatch = Some((index, kind, at));
            }
        }
        index += 1;
    }
    Ok(rep)
}

// ---------------------------------------------------------------------------------------------
// The ramp/planner: `control::profile::Profile`.
// ---------------------------------------------------------------------------------------------

/// Profile operation: `arg` steps, every [`Reference`] put in full (`arg ≤`
/// [`MAX_PROFILE_STEPS`]).
pub const OP_STEPS: u8 = 0;
/// Profile operation: `arg` steps folded into a 64-bit hash of every field of every reference
/// (`arg ≤` [`MAX_PROFILE_RUN`]); puts the hash, the last reference and the step at which the
/// reference first rested (`u32::MAX`: never).
pub const OP_RUN: u8 = 1;
/// Profile operation: `set_target(arg)` (`arg` an `i32`).
pub const OP_TARGET: u8 = 2;
/// Profile operation: `stop()`.
pub const OP_STOP: u8 = 3;
/// Profile operation: `set_cruise(arg)`.
pub const OP_CRUISE: u8 = 4;
/// Profile operation: `reset(arg)` (`arg` an `i32`).
pub const OP_RESET: u8 = 5;
/// Most steps put in full by one [`OP_STEPS`].
pub const MAX_PROFILE_STEPS: i64 = 256;
/// Most steps hashed by one [`OP_RUN`].
pub const MAX_PROFILE_RUN: i64 = 65_536;

use liftfw::control::config::RampShape;
use liftfw::control::profile::{Profile, Reference};

/// Every field of a planner reference, raw bits.
pub fn put_reference(s: &mut impl Sink, r: &Reference) {
    s.put_i64(r.position);
    s.put_i64(r.speed);
    s.put_u8(u8::from(r.done));
}

/// FNV-1a over 64-bit words: a portable fold of many outputs into one (same code both sides).
struct Fold(u64);

impl Fold {
    fn new() -> Self {
        Fold(0xcbf2_9ce4_8422_2325)
    }
    fn word(&mut self, w: u64) {
        self.0 = (self.0 ^ w).wrapping_mul(0x0000_0100_0000_01b3);
    }
}

fn eval_profile(r: &mut Reader<'_>, out: &mut impl Sink) -> Result<(), Error> {
    let position = r.i32()?;
    let cruise = r.i64()?;
    let ramp = r.u32()?;
    let shape = match r.u8()? {
        0 => RampShape::Trapezoid,
        1 => RampShape::SCurve,
        v => return Err(Error::BadField(v)),
    };
    let mut p = Profile::new(position, cruise, ramp, shape);
    let n = r.u16()?;
    if usize::from(n) > MAX_SEQUENCE {
        return Err(Error::SequenceTooLong(n));
    }
    for _ in 0..n {
        let op = r.u8()?;
        let arg = r.i64()?;
        let arg32 = i32::try_from(arg).map_err(|_| Error::BadField(op));
        match op {
            OP_STEPS if (0..=MAX_PROFILE_STEPS).contains(&arg) => {
                for _ in 0..arg {
                    put_reference(out, &p.step());
                }
            }
            OP_RUN if (0..=MAX_PROFILE_RUN).contains(&arg) => {
                let mut h = Fold::new();
                let mut last = Reference::default();
                let mut rested = u32::MAX;
                for i in 0..arg as u32 {
                    last = p.step();
                    h.word(last.position as u64);
                    h.word(last.speed as u64);
                    h.word(u64::from(last.done));
                    if last.done && rested == u32::MAX {
                        rested = i;
                    }
                }
                out.put_u64(h.0);
                put_reference(out, &last);
                out.put_u32(rested);
            }
            OP_TARGET => p.set_target(arg32?),
            OP_STOP => p.stop(),
            OP_CRUISE => p.set_cruise(arg),
            OP_RESET => p.reset(arg32?),
            _ => return Err(Error::BadField(op)),
        }
        out.put_i32(p.target_counts());
    }
    Ok(())
}

/// Builds a profile script and follows it on a shadow planner (to size the runs).
struct Script {
    buf: InputBuf,
    n_at: usize,
    n: u16,
    shadow: Profile,
}

impl Script {
    fn new(position: i32, cruise: i64, ramp: u32, shape: RampShape) -> Script {
        let mut buf = InputBuf::new();
        buf.put_i32(position);
        buf.put_i64(cruise);
        buf.put_u32(ramp);
        buf.put_u8(match shape {
            RampShape::Trapezoid => 0,
            RampShape::SCurve => 1,
        });
        let n_at = buf.len;
        buf.put_u16(0);
        Script {
            buf,
            n_at,
            n: 0,
            shadow: Profile::new(position, cruise, ramp, shape),
        }
    }
    fn op(&mut self, op: u8, arg: i64) -> &mut Self {
        if usize::from(self.n) >= MAX_SEQUENCE {
            return self;
        }
        self.buf.put_u8(op);
        self.buf.put_i64(arg);
        self.n += 1;
        match op {
            OP_STEPS | OP_RUN => {
                for _ in 0..arg {
                    self.shadow.step();
                }
            }
            OP_TARGET => self.shadow.set_target(arg as i32),
            OP_STOP => self.shadow.stop(),
            OP_CRUISE => self.shadow.set_cruise(arg),
            _ => self.shadow.reset(arg as i32),
        }
        self
    }
    fn steps(&mut self, n: i64) -> &mut Self {
        self.op(OP_STEPS, n.clamp(0, MAX_PROFILE_STEPS))
    }
    fn run(&mut self, n: i64) -> &mut Self {
        self.op(OP_RUN, n.clamp(0, MAX_PROFILE_RUN))
    }
    /// Hash until the reference rests (at most `cap` steps), then a few steps in full.
    fn until_done(&mut self, cap: i64) -> &mut Self {
        let mut p = self.shadow.clone();
        let mut n = 0;
        while n < cap && !p.step().done {
            n += 1;
        }
        self.run(n + 1).steps(3)
    }
    fn finish(mut self) -> InputBuf {
        let n = self.n.to_le_bytes();
        if let Some(d) = self.buf.data.get_mut(self.n_at..self.n_at + 2) {
            d.copy_from_slice(&n);
        }
        self.buf
    }
}

/// Number of profile scripts per scenario and shape.
pub const PROFILE_CASES: u32 = 8;
/// Profile scenarios (see [`profile_case`]).
const PROFILE_SCENARIOS: u32 = 8;

const Q32: i64 = 1 << 32;

/// One profile script: `scenario` (0..[`PROFILE_SCENARIOS`]) under `shape`.
fn profile_case(rng: &mut SplitMix64, scenario: u32, shape: RampShape) -> InputBuf {
    let pos = rng.range(-1_000_000, 1_000_000);
    let cruise = rng.range(Q32 / 100, 4 * Q32);
    let ramp = rng.range(2, 2000);
    let sign = if rng.chance(1, 2) { 1 } else { -1 };
    let counts_per_tick = (cruise / Q32).max(1);
    let mut s = if scenario == 6 {
        const CRUISE: [i64; 10] = [
            i64::MIN,
            -1,
            0,
            1,
            2,
            Q32,
            64 * Q32 - 1,
            64 * Q32,
            64 * Q32 + 1,
            i64::MAX,
        ];
        const RAMP: [u32; 9] = [0, 1, 2, 3, 64, 127, 128, 129, u32::MAX];
        let c = CRUISE[rng.range(0, 9) as usize];
        let r = RAMP[rng.range(0, 8) as usize];
        Script::new(far(rng), c, r, shape)
    } else {
        Script::new(pos as i32, cruise, ramp as u32, shape)
    };
    let pos = pos as i32;
    match scenario {
        // A short move, every step in full.
        0 => {
            let d = rng.range(-300, 300) as i32;
            s.op(OP_TARGET, i64::from(pos + d))
                .steps(64)
                .until_done(4000);
        }
        // A long move: start in full, the cruise hashed.
        1 => {
            let d = rng.range(1, (counts_per_tick * 20_000).min(200_000)) * sign;
            s.op(OP_TARGET, i64::from(pos) + d)
                .steps(32)
                .until_done(60_000)
                .steps(4);
        }
        // Stop mid-ramp, then again from rest.
        2 => {
            s.op(OP_TARGET, i64::from(pos) + sign * 1_000_000)
                .steps(rng.range(1, 200))
                .run(rng.range(0, ramp))
                .op(OP_STOP, 0)
                .steps(8)
                .until_done(20_000)
                .op(OP_STOP, 0)
                .steps(4);
        }
        // Cruise changes mid-move (the stick-slip escape speed), extremes included.
        3 => {
            let c2 = if rng.chance(1, 4) {
                rng.next_u64() as i64
            } else {
                rng.range(1, 8 * Q32)
            };
            let d = rng.range(1, (counts_per_tick * 20_000).min(200_000)) * sign;
            s.op(OP_TARGET, i64::from(pos) + d)
                .run(rng.range(50, 3000))
                .op(OP_CRUISE, c2)
                .steps(16)
                .run(rng.range(0, 2000))
                .op(OP_CRUISE, rng.range(Q32 / 100, 4 * Q32))
                .steps(16)
                .until_done(60_000);
        }
        // Reversal: a new target behind the moving reference.
        4 => {
            let d = rng.range(1000, 100_000);
            s.op(OP_TARGET, i64::from(pos) + sign * d)
                .run(rng.range(1, 3000))
                .steps(8)
                .op(OP_TARGET, i64::from(pos) - sign * rng.range(0, d))
                .steps(32)
                .until_done(60_000);
        }
        // Reset mid-move, then a new move.
        5 => {
            s.op(OP_TARGET, i64::from(pos) + sign * rng.range(1000, 100_000))
                .run(rng.range(1, 2000))
                .op(OP_RESET, rng.range(-1_000_000, 1_000_000))
                .steps(4)
                .op(OP_TARGET, rng.range(-1_000_000, 1_000_000))
                .until_done(40_000);
        }
        // Extremes: clamped cruise and ramp, positions and targets past ±2^29 (far path).
        6 => {
            s.op(OP_TARGET, i64::from(far(rng)))
                .steps(32)
                .run(5000)
                .op(OP_STOP, 0)
                .steps(16)
                .run(5000)
                .op(OP_TARGET, i64::from(far(rng)))
                .run(5000)
                .op(
                    OP_CRUISE,
                    [i64::MIN, 0, 64 * Q32 + 1, i64::MAX][rng.range(0, 3) as usize],
                )
                .steps(8)
                .run(5000);
        }
        // A random script, nonsense arguments included.
        _ => {
            for _ in 0..24 {
                match rng.range(0, 5) {
                    0 => s.steps(rng.range(0, 16)),
                    1 => s.run(rng.range(0, 1500)),
                    2 => s.op(
                        OP_TARGET,
                        i64::from(if rng.chance(1, 4) {
                            far(rng)
                        } else {
                            pos + rng.range(-20_000, 20_000) as i32
                        }),
                    ),
                    3 => s.op(OP_STOP, 0),
                    4 => s.op(
                        OP_CRUISE,
                        if rng.chance(1, 4) {
                            rng.next_u64() as i64
                        } else {
                            rng.range(0, 8 * Q32)
                        },
                    ),
                    _ => s.op(OP_RESET, i64::from(far(rng))),
                };
            }
        }
    }
    s.finish()
}

/// A position from the extremes of `i32` and around ±2^29, or any bit pattern.
fn far(rng: &mut SplitMix64) -> i32 {
    const FAR: [i32; 10] = [
        i32::MIN,
        i32::MIN + 1,
        -(1 << 29) - 1,
        -(1 << 29),
        -(1 << 28),
        0,
        1 << 28,
        1 << 29,
        (1 << 29) + 1,
        i32::MAX,
    ];
    if rng.chance(1, 5) {
        rng.bits()
    } else {
        FAR[rng.range(0, 9) as usize]
    }
}

fn generate_profiles(rng: &mut SplitMix64, s: &mut impl Sink) -> Result<(), Error> {
    for scenario in 0..PROFILE_SCENARIOS {
        for shape in [RampShape::Trapezoid, RampShape::SCurve] {
            for _ in 0..PROFILE_CASES {
                let input = profile_case(&mut SplitMix64(rng.next_u64()), scenario, shape);
                record(s, Kind::ProfileSequence, &input)?;
            }
        }
    }
    Ok(())
}

// ---------------------------------------------------------------------------------------------
// The console line parser: `console::parse`.
// ---------------------------------------------------------------------------------------------

/// Formatted text into a [`Sink`].
struct Text<'a, S: Sink>(&'a mut S);

impl<S: Sink> core::fmt::Write for Text<'_, S> {
    fn write_str(&mut self, s: &str) -> core::fmt::Result {
        self.0.put(s.as_bytes());
        Ok(())
    }
}

/// Console lines generated (a well-formed command, a damaged one, or noise).
pub const CONSOLE_LINES: u32 = 2400;

const COMMANDS: [&str; 14] = [
    "status", "get", "set", "save", "limits", "up", "down", "stop", "goto", "fault", "version",
    "help", "?", "clear",
];

const UNITS: [&str; 30] = [
    "", "mm", "m", "cm", "um", "rad/s", "ms", "s", "us", "A", "mA", "V", "mV", "kg", "t", "g", "%",
    "counts", "deg", "°", "Nm", "n*m", "n·m", "mNm", "Nm/A", "Hz", "ohm", "Ω", "N", "kN",
];

const WORDS: [&str; 20] = [
    "trapezoid",
    "scurve",
    "hold",
    "latched",
    "lead",
    "ball",
    "none",
    "spring",
    "dry",
    "ptfe",
    "lithium",
    "rate",
    "speed",
    "tau",
    "custom",
    "off",
    "inf",
    "never",
    "keys",
    "clear",
];

/// A number as a person might type it (or not): signs, decimals, exponents, huge, garbage.
fn number(rng: &mut SplitMix64, out: &mut LineBuf) {
    if rng.chance(1, 8) {
        out.push_str("-");
    } else if rng.chance(1, 16) {
        out.push_str("+");
    }
    match rng.range(0, 7) {
        0 => out.push_u64(rng.next_u64() >> rng.range(0, 63)),
        1 => {
            out.push_u64(rng.range(0, 100) as u64);
            out.push_str(".");
            out.push_u64(rng.range(0, 99_999) as u64);
        }
        2 => {
            out.push_str(".");
            out.push_u64(rng.range(0, 999) as u64);
        }
        3 => {
            out.push_u64(rng.range(0, 9) as u64);
            out.push_str(["e", "E", "e-", "e+"][rng.range(0, 3) as usize]);
            out.push_u64(rng.range(0, 30) as u64);
        }
        4 => out.push_str(
            ["1.", "..5", "1.2.3", "0x10", "1_000", "nan", "-", "1,5"][rng.range(0, 7) as usize],
        ),
        5 => {
            for _ in 0..rng.range(15, 40) {
                out.push_u64(rng.range(0, 9) as u64);
            }
        }
        _ => out.push_u64(rng.range(0, 2000) as u64),
    }
}

/// One console line, built on the stack.
struct LineBuf {
    b: [u8; 160],
    len: usize,
}

impl LineBuf {
    fn push(&mut self, c: u8) {
        if let Some(x) = self.b.get_mut(self.len) {
            *x = c;
            self.len += 1;
        }
    }
    fn push_str(&mut self, s: &str) {
        for c in s.bytes() {
            self.push(c);
        }
    }
    fn push_u64(&mut self, mut v: u64) {
        let mut d = [0u8; 20];
        let mut n = 0;
        loop {
            d[n] = b'0' + (v % 10) as u8;
            n += 1;
            v /= 10;
            if v == 0 {
                break;
            }
        }
        for i in (0..n).rev() {
            self.push(d[i]);
        }
    }
    fn space(&mut self, rng: &mut SplitMix64) {
        match rng.range(0, 9) {
            0 => self.push_str("  "),
            1 => self.push_str("\t"),
            2 => self.push_str(" \t "),
            _ => self.push_str(" "),
        }
    }
    /// A word, sometimes in another case.
    fn word(&mut self, w: &str, rng: &mut SplitMix64) {
        let mode = rng.range(0, 5);
        for c in w.bytes() {
            self.push(match mode {
                0 => c.to_ascii_uppercase(),
                1 if rng.chance(1, 2) => c.to_ascii_uppercase(),
                _ => c,
            });
        }
    }
}

/// One line: a well-formed command, a damaged one, or noise.
fn console_line(rng: &mut SplitMix64, k: u32) -> LineBuf {
    let mut l = LineBuf {
        b: [0; 160],
        len: 0,
    };
    let keys = liftfw::config::settings::all().count() as i64;
    let key = |rng: &mut SplitMix64| {
        liftfw::config::settings::all()
            .nth(rng.range(0, keys - 1) as usize)
            .map_or("?", |id| id.key())
    };
    if rng.chance(1, 6) {
        l.space(rng);
    }
    match k % 10 {
        // Every command alone, then with a word after it.
        0 => {
            l.word(COMMANDS[(k / 10) as usize % COMMANDS.len()], rng);
            if (k / 10) as usize / COMMANDS.len() % 2 == 1 {
                l.space(rng);
                l.word(WORDS[rng.range(0, 19) as usize], rng);
            }
        }
        // get/help of every key (walked in order), a few misspelt.
        1 => {
            l.word(["get", "help", "?"][rng.range(0, 2) as usize], rng);
            l.space(rng);
            let id = liftfw::config::settings::all().nth((k / 10) as usize % keys as usize);
            let w = id.map_or("?", |id| id.key());
            if rng.chance(1, 8) {
                l.word(w.get(..w.len() - 1).unwrap_or(w), rng);
            } else {
                l.word(w, rng);
            }
        }
        // set <every key> <number> [unit]
        2..=4 => {
            l.word("set", rng);
            l.space(rng);
            let id = liftfw::config::settings::all().nth((k / 3) as usize % keys as usize);
            l.word(id.map_or("?", |id| id.key()), rng);
            if rng.chance(9, 10) {
                l.space(rng);
                number(rng, &mut l);
                if rng.chance(2, 3) {
                    if rng.chance(1, 2) {
                        l.space(rng);
                    }
                    l.word(UNITS[rng.range(0, UNITS.len() as i64 - 1) as usize], rng);
                }
            }
        }
        // set <key> <choice word>
        5 => {
            l.word("set", rng);
            l.space(rng);
            l.word(key(rng), rng);
            l.space(rng);
            l.word(WORDS[rng.range(0, 19) as usize], rng);
        }
        // goto <height> [unit]
        6 => {
            l.word("goto", rng);
            if rng.chance(9, 10) {
                l.space(rng);
                number(rng, &mut l);
                l.word(
                    ["", "mm", "m", "cm", "um", "A", " mm", "mm mm"][rng.range(0, 7) as usize],
                    rng,
                );
            }
        }
        // Comments, blank lines, trailing words.
        7 => match rng.range(0, 4) {
            0 => l.push_str("# a comment: set x 1"),
            1 => l.space(rng),
            2 => {
                l.word(COMMANDS[rng.range(0, 13) as usize], rng);
                l.space(rng);
                l.word(key(rng), rng);
                l.space(rng);
                number(rng, &mut l);
                l.space(rng);
                l.word("extra", rng);
            }
            3 => l.push_str("fault clear now"),
            _ => l.word("fault clear", rng),
        },
        // Overlong lines around the limit (96 bytes).
        8 => {
            let n = 90 + (k / 10) % 20;
            l.word("set", rng);
            l.space(rng);
            l.word(key(rng), rng);
            l.space(rng);
            while l.len < n as usize {
                l.push(b'0' + rng.range(0, 9) as u8);
            }
        }
        // Random bytes: printable, then anything (invalid UTF-8 included).
        _ => {
            let any = rng.chance(1, 2);
            for _ in 0..rng.range(0, 40) {
                l.push(if any {
                    rng.bits() as u8
                } else {
                    rng.range(0x20, 0x7e) as u8
                });
            }
        }
    }
    if rng.chance(1, 6) {
        l.space(rng);
    }
    l
}

fn generate_console(rng: &mut SplitMix64, s: &mut impl Sink) -> Result<(), Error> {
    for k in 0..CONSOLE_LINES {
        let l = console_line(rng, k);
        let mut input = InputBuf::new();
        input.put(l.b.get(..l.len).unwrap_or(&l.b));
        record(s, Kind::ConsoleParse, &input)?;
    }
    Ok(())
}

// ---------------------------------------------------------------------------------------------
// The stick-slip detector: `detect::stickslip::StickSlipDetector`.
// ---------------------------------------------------------------------------------------------

use liftfw::detect::stickslip::{
    DetectorInputs, Reaction, StickSlipConfig, StickSlipDetector, StickSlipOutput,
};

/// Longest detector trace, ticks.
pub const MAX_DETECTOR_TICKS: u32 = 40_000;

/// A detector trace: the detector's settings and the parameters of the synthesised inputs
/// (the trace itself is computed by [`DetectorTrace::inputs`] on both sides: 20 000 ticks of
/// inputs would not fit the file).
#[derive(Clone, Copy, Debug)]
pub struct DetectorTrace {
    /// Index into [`config`]: the friction law and the tick.
    pub cfg: u8,
    /// `stickslip.drop`, raw bits (N·m, Q16).
    pub drop: i32,
    /// `stickslip.window_ms`.
    pub window_ms: u32,
    /// Ticks.
    pub ticks: u32,
    /// Seed of the noise and nonsense.
    pub seed: u64,
    /// Driving until this tick (then idle).
    pub drive_end: u32,
    /// Direction of travel.
    pub direction: i8,
    /// Cruise reference, rad/s Q16.
    pub reference: i32,
    /// Ticks of the reference's ramp from 0.
    pub ramp: u32,
    /// Mean resisting torque, N·m Q16.
    pub base: i32,
    /// Sawtooth: torque built up over one stick phase then lost in the slip, N·m Q16.
    pub sawtooth: i32,
    /// Sawtooth period, ticks (0: none).
    pub period: u32,
    /// Ticks a slip takes to shed the torque.
    pub slip_ticks: u32,
    /// Uniform noise amplitude, N·m Q16.
    pub noise: i32,
    /// Chance per 256 ticks of a nonsense input (any bits in any field).
    pub nonsense: u8,
}

impl DetectorTrace {
    fn put(&self, s: &mut impl Sink) {
        s.put_u8(self.cfg);
        s.put_i32(self.drop);
        s.put_u32(self.window_ms);
        s.put_u32(self.ticks);
        s.put_u64(self.seed);
        s.put_u32(self.drive_end);
        s.put(&self.direction.to_le_bytes());
        s.put_i32(self.reference);
        s.put_u32(self.ramp);
        s.put_i32(self.base);
        s.put_i32(self.sawtooth);
        s.put_u32(self.period);
        s.put_u32(self.slip_ticks);
        s.put_i32(self.noise);
        s.put_u8(self.nonsense);
    }

    fn read(r: &mut Reader<'_>) -> Result<DetectorTrace, Error> {
        Ok(DetectorTrace {
            cfg: r.u8()?,
            drop: r.i32()?,
            window_ms: r.u32()?,
            ticks: r.u32()?,
            seed: u64::from_le_bytes(r.array()?),
            drive_end: r.u32()?,
            direction: i8::from_le_bytes(r.array()?),
            reference: r.i32()?,
            ramp: r.u32()?,
            base: r.i32()?,
            sawtooth: r.i32()?,
            period: r.u32()?,
            slip_ticks: r.u32()?,
            noise: r.i32()?,
            nonsense: r.u8()?,
        })
    }

    /// The inputs of tick `t` (integer arithmetic, saturating: the same on every target).
    pub fn inputs(&self, t: u32, rng: &mut SplitMix64) -> DetectorInputs {
        let sat = |v: i64| v.clamp(i64::from(i32::MIN), i64::from(i32::MAX)) as i32;
        let dir = i64::from(self.direction.signum());
        let reference =
            i64::from(self.reference) * i64::from(t.min(self.ramp)) / i64::from(self.ramp.max(1));
        let mut torque = i64::from(self.base);
        if self.period > 0 {
            // Stick: the torque builds up linearly; slip: it falls back over `slip_ticks`.
            let phase = i64::from(t % self.period);
            let stick = i64::from(self.period.saturating_sub(self.slip_ticks).max(1));
            let saw = i64::from(self.sawtooth);
            torque += if phase < stick {
                saw * phase / stick
            } else {
                saw - saw * (phase - stick + 1) / i64::from(self.slip_ticks.max(1))
            };
        }
        if self.noise > 0 {
            torque += rng.range(-i64::from(self.noise), i64::from(self.noise));
        }
        let mut x = DetectorInputs {
            driving: t < self.drive_end,
            direction: self.direction,
            reference: RadiansPerSecond::from_bits(sat(reference * dir)),
            measured_torque: NewtonMetres::from_bits(sat(torque * dir)),
        };
        if (rng.next_u64() & 0xff) < u64::from(self.nonsense) {
            match rng.range(0, 3) {
                0 => x.measured_torque = NewtonMetres::from_bits(rng.bits()),
                1 => x.reference = RadiansPerSecond::from_bits(rng.bits()),
                2 => x.direction = rng.bits() as i8,
                _ => x.driving = !x.driving,
            }
        }
        x
    }
}

/// Every field of the detector's report, raw bits.
pub fn put_stickslip(s: &mut impl Sink, o: &StickSlipOutput) {
    s.put_u8(u8::from(o.active) | u8::from(o.onset) << 1 | u8::from(o.slip) << 2);
    s.put_i32(o.amplitude.to_bits());
    s.put_u32(o.episodes);
    s.put_u8(u8::from(o.falling_branch));
}

fn eval_detector(r: &mut Reader<'_>, out: &mut impl Sink) -> Result<(), Error> {
    let trace = DetectorTrace::read(r)?;
    let conf = config(trace.cfg).ok_or(Error::UnknownConfig(trace.cfg))?;
    let est = estimator(trace.cfg)?;
    if trace.ticks > MAX_DETECTOR_TICKS {
        return Err(Error::BadField(0));
    }
    let cfg = StickSlipConfig {
        reaction: Reaction::Warn,
        drop_threshold: NewtonMetres::from_bits(trace.drop),
        window_ms: trace.window_ms,
        ..StickSlipConfig::DEFAULT
    };
    let mut det = StickSlipDetector::new(&cfg, conf.tick_us);
    let mut rng = SplitMix64(trace.seed);
    // Run-length coded: the tick and the whole report wherever the report changes (lossless:
    // every field of every tick), then a fold of every report and the count of changes.
    let mut prev = StickSlipOutput::default();
    let mut fold = Fold::new();
    let mut changes = 0u32;
    for t in 0..trace.ticks {
        let o = det.step(&trace.inputs(t, &mut rng), est.law());
        if o != prev {
            out.put_u32(t);
            put_stickslip(out, &o);
            prev = o;
            changes += 1;
        }
        let flags = u64::from(o.active) | u64::from(o.onset) << 1 | u64::from(o.slip) << 2;
        fold.word(flags | u64::from(o.falling_branch) << 3 | u64::from(o.episodes) << 32);
        fold.word(o.amplitude.to_bits() as u64);
    }
    out.put_u32(u32::MAX);
    out.put_u64(fold.0);
    out.put_u32(changes);
    Ok(())
}

/// Detector traces per configuration.
pub const DETECTOR_TRACES_PER_CONFIG: u32 = 16;

fn detector_trace(rng: &mut SplitMix64, cfg: u8, tick_us: u32, k: u32) -> DetectorTrace {
    let nm = |x: i64| (x << 16) / 100; // hundredths of N·m → Q16
    let per_s = 1_000_000 / i64::from(tick_us.max(1)); // ticks per second
                                                       // Stick-slip cycles every 0.05 … 1 s, slips over 1 … 10 ms.
    let period = rng.range(per_s / 20, per_s).max(2) as u32;
    let slip_ticks = rng
        .range(1, (per_s / 100).max(1))
        .min(i64::from(period) - 1) as u32;
    let ticks = (per_s * rng.range(2, 4)).clamp(200, i64::from(MAX_DETECTOR_TICKS)) as u32;
    let mut t = DetectorTrace {
        cfg,
        drop: nm(rng.range(20, 5000)) as i32,
        window_ms: rng.range(100, 10_000) as u32,
        ticks,
        seed: rng.next_u64(),
        drive_end: ticks,
        direction: if rng.chance(1, 2) { 1 } else { -1 },
        reference: rng.range(13_107, 20 << 16) as i32, // 0.2 … 20 rad/s
        ramp: rng.range(2, per_s) as u32,
        base: nm(rng.range(0, 2000)) as i32,
        sawtooth: 0,
        period: 0,
        slip_ticks,
        noise: 0,
        nonsense: 0,
    };
    match k % 8 {
        // Smooth: no slip, a little noise.
        0 => t.noise = nm(rng.range(0, 5)) as i32,
        // Periodic drops around the threshold (below, at, above).
        1..=3 => {
            t.period = period;
            t.sawtooth = (i64::from(t.drop) * rng.range(50, 400) / 100) as i32;
            t.noise = nm(rng.range(0, 10)) as i32;
        }
        // Drops in heavy noise.
        4 => {
            t.period = period;
            t.sawtooth = nm(rng.range(50, 3000)) as i32;
            t.noise = (i64::from(t.sawtooth) * rng.range(10, 100) / 100) as i32;
        }
        // Stick-slip, then the motion ends (idle resets) part way.
        5 => {
            t.period = period;
            t.sawtooth = t.drop.saturating_mul(2);
            t.drive_end = rng.range(0, i64::from(ticks)) as u32;
        }
        // Nonsense inputs now and then, every field.
        6 => {
            t.period = period;
            t.sawtooth = t.drop.saturating_mul(3);
            t.nonsense = rng.range(1, 60) as u8;
        }
        // Extremes: thresholds and windows at and past their ends, saturating torques.
        _ => {
            t.drop = [0, 1, nm(20) as i32, nm(5000) as i32, i32::MAX][rng.range(0, 4) as usize];
            t.window_ms = [0, 100, 10_000, u32::MAX][rng.range(0, 3) as usize];
            t.period = [0, 1, 2, 3, period][rng.range(0, 4) as usize];
            t.base = [i32::MIN, 0, i32::MAX][rng.range(0, 2) as usize];
            t.sawtooth = rng.bits();
            t.reference = rng.bits();
            t.direction = rng.bits() as i8;
            t.noise = rng.bits().max(0) >> rng.range(0, 31);
        }
    }
    t
}

fn generate_detector(rng: &mut SplitMix64, s: &mut impl Sink) -> Result<(), Error> {
    for cfg in 0..CONFIGS {
        let tick_us = config(cfg).ok_or(Error::UnknownConfig(cfg))?.tick_us;
        for k in 0..DETECTOR_TRACES_PER_CONFIG {
            let mut input = InputBuf::new();
            detector_trace(rng, cfg, tick_us, k).put(&mut input);
            record(s, Kind::DetectorSequence, &input)?;
        }
    }
    Ok(())
}

// ---------------------------------------------------------------------------------------------
// The control tick: `control::Controller::step`.
// ---------------------------------------------------------------------------------------------

use liftfw::control::config::{ButtonMode, ControlConfig};
use liftfw::control::{Bridge, Command, Controller, Inputs, Refusal, State, Switches};

/// Longest control run, ticks.
pub const MAX_CONTROL_TICKS: u32 = 4000;

/// Control script events (`tick u32`, `what u8`, `arg i32`).
const EV_UP: u8 = 0;
const EV_DOWN: u8 = 1;
const EV_STOP: u8 = 2;
const EV_GOTO: u8 = 3;
const EV_CLEAR: u8 = 4;
const EV_SWITCHES: u8 = 5;
const EV_LOAD: u8 = 6;
const EV_SUPPLY: u8 = 7;
const EV_GAIN: u8 = 8;
const EV_NONSENSE: u8 = 9;

/// Number of controller configurations.
const CONTROL_CONFIGS: u8 = 3;

fn control_config(id: u8) -> Option<ControlConfig> {
    let mut c = ControlConfig::DEFAULT;
    match id {
        0 => {}
        1 => c.motion.ramp_shape = RampShape::SCurve,
        2 => c.motion.buttons = ButtonMode::Latched,
        _ => return None,
    }
    Some(c)
}

fn refusal_code(r: Result<(), Refusal>) -> u8 {
    match r {
        Ok(()) => 0,
        Err(Refusal::Faulted) => 1,
        Err(Refusal::SupplyLow) => 2,
        Err(Refusal::AtLimit) => 3,
        Err(Refusal::OutsideLimits) => 4,
        Err(Refusal::Moving) => 5,
        Err(Refusal::NoFault) => 6,
        Err(Refusal::NotHomed) => 7,
        Err(Refusal::InMotion) => 8,
        Err(Refusal::BadConfig) => 9,
        Err(Refusal::NeedsBallScrew) => 10,
    }
}

fn state_code(s: State) -> u8 {
    match s {
        State::Idle => 0,
        State::Lifting => 1,
        State::Lowering => 2,
        State::Holding => 3,
        State::Fault => 4,
    }
}

fn eval_control(r: &mut Reader<'_>, out: &mut impl Sink) -> Result<(), Error> {
    let cfg_id = r.u8()?;
    let cfg = control_config(cfg_id).ok_or(Error::UnknownConfig(cfg_id))?;
    let start = r.i32()?;
    let ticks = r.u32()?;
    let seed = u64::from_le_bytes(r.array()?);
    let n = r.u16()?;
    if ticks > MAX_CONTROL_TICKS {
        return Err(Error::BadField(0));
    }
    if usize::from(n) > MAX_SEQUENCE {
        return Err(Error::SequenceTooLong(n));
    }
    let events = r.take(usize::from(n) * 9)?;
    let mut c = Controller::new(&cfg, start).map_err(|_| Error::UnknownConfig(cfg_id))?;
    let mut rng = SplitMix64(seed);
    // The plant: screw position and speed in Q16 counts (per tick), a first-order lag toward
    // the duty; the current follows the duty and the load, the supply sags with it.
    let (mut pos, mut vel) = (i64::from(start) << 16, 0i64);
    let (mut switches, mut load, mut supply, mut gain, mut nonsense) =
        (0u8, 300i64, 2820i64, 8i64, 0u64);
    let mut next = 0usize;
    let mut prev: Option<(u8, i16, u8, u8)> = None;
    let mut last_duty = 0i16;
    for t in 0..ticks {
        while let Some(ev) = events.get(next * 9..next * 9 + 9) {
            let at = u32::from_le_bytes([ev[0], ev[1], ev[2], ev[3]]);
            if at != t {
                break;
            }
            let arg = i32::from_le_bytes([ev[5], ev[6], ev[7], ev[8]]);
            let cmd = |c: &mut Controller, k| refusal_code(c.command(k));
            let res = match ev[4] {
                EV_UP => cmd(&mut c, Command::Up),
                EV_DOWN => cmd(&mut c, Command::Down),
                EV_STOP => cmd(&mut c, Command::Stop),
                EV_GOTO => cmd(&mut c, Command::GoTo(Metres::from_bits(arg))),
                EV_CLEAR => cmd(&mut c, Command::ClearFault),
                EV_SWITCHES => {
                    switches = arg as u8;
                    0xff
                }
                EV_LOAD => {
                    load = i64::from(arg);
                    0xff
                }
                EV_SUPPLY => {
                    supply = i64::from(arg);
                    0xff
                }
                EV_GAIN => {
                    gain = i64::from(arg);
                    0xff
                }
                EV_NONSENSE => {
                    nonsense = u64::from(arg as u8);
                    0xff
                }
                w => return Err(Error::BadField(w)),
            };
            out.put_u32(t);
            out.put_u8(0xfe); // an event's answer, not a tick
            out.put_u8(res);
            next += 1;
        }
        let duty = i64::from(last_duty);
        vel += ((duty * gain) - vel) >> 4;
        pos = pos.saturating_add(vel);
        let dir = duty.signum();
        let noise = rng.range(-3, 3);
        let mut x = Inputs {
            encoder_count: (pos >> 16) as u16,
            encoder_edge_age: 0,
            current_raw: (2048 + dir * load + duty / 128 + noise).clamp(0, 4095) as u16,
            supply_raw: (supply - duty.abs() / 512 + noise).clamp(0, 4095) as u16,
            switches: Switches(switches),
        };
        if (rng.next_u64() & 0xff) < nonsense {
            match rng.range(0, 3) {
                0 => x.encoder_count = rng.bits() as u16,
                1 => x.current_raw = rng.bits() as u16,
                2 => x.supply_raw = rng.bits() as u16,
                _ => x.switches = Switches(rng.bits() as u8),
            }
        }
        let o = c.step(Instant(t.wrapping_mul(cfg.estimator.tick_us)), &x);
        c.finish_tick();
        let (tag, duty) = match o.bridge {
            Bridge::Coast => (0, 0),
            Bridge::Brake => (1, 0),
            Bridge::Drive(d) => (2, d),
        };
        last_duty = duty;
        let flags = u8::from(o.feed_watchdog) | u8::from(o.brake_release) << 1;
        let now = (tag, duty, flags, state_code(c.state()));
        // Run-length coded: a tick's outputs wherever they change or carry an event.
        if prev != Some(now) || o.event.is_some() {
            out.put_u32(t);
            out.put_u8(tag);
            out.put(&duty.to_le_bytes());
            out.put_u8(flags);
            out.put_u8(now.3);
            if let Some(e) = o.event {
                let mut len = Counter::default();
                let _ = core::fmt::write(&mut Text(&mut len), format_args!("{e:?}"));
                out.put_u16(len.0 as u16);
                core::fmt::write(&mut Text(out), format_args!("{e:?}"))
                    .map_err(|_| Error::BadField(0))?;
            } else {
                out.put_u16(0);
            }
            prev = Some(now);
        }
    }
    out.put_u32(u32::MAX);
    Ok(())
}

/// Control runs per configuration.
pub const CONTROL_RUNS_PER_CONFIG: u32 = 8;

fn generate_control(rng: &mut SplitMix64, s: &mut impl Sink) -> Result<(), Error> {
    for cfg in 0..CONTROL_CONFIGS {
        for k in 0..CONTROL_RUNS_PER_CONFIG {
            let mut input = InputBuf::new();
            input.put_u8(cfg);
            input.put_i32(rng.range(0, 400_000) as i32);
            let ticks = rng.range(1500, i64::from(MAX_CONTROL_TICKS)) as u32;
            input.put_u32(ticks);
            input.put_u64(rng.next_u64());
            let mut evs: [(u32, u8, i32); 24] = [(0, 0, 0); 24];
            let n = match k % 4 {
                // Up, then stop; a goto; down.
                0 => {
                    evs[0] = (10, EV_UP, 0);
                    evs[1] = (rng.range(100, 800) as u32, EV_STOP, 0);
                    evs[2] = (1000, EV_GOTO, rng.range(0, 1 << 24) as i32);
                    evs[3] = (ticks - 300, EV_DOWN, 0);
                    4
                }
                // Faults: stall (no motion), then clear; supply sag; overload.
                1 => {
                    evs[0] = (5, EV_GAIN, 0);
                    evs[1] = (10, EV_UP, 0);
                    evs[2] = (900, EV_CLEAR, 0);
                    evs[3] = (901, EV_GAIN, 8);
                    evs[4] = (950, EV_UP, 0);
                    evs[5] = (1100, EV_SUPPLY, rng.range(1500, 2600) as i32);
                    evs[6] = (1300, EV_LOAD, rng.range(600, 2000) as i32);
                    evs[7] = (1400, EV_CLEAR, 0);
                    4 + 4
                }
                // Buttons and limit switches.
                2 => {
                    evs[0] = (10, EV_SWITCHES, i32::from(Switches::BUTTON_UP));
                    evs[1] = (300, EV_SWITCHES, 0);
                    evs[2] = (400, EV_SWITCHES, i32::from(Switches::BUTTON_DOWN));
                    evs[3] = (
                        700,
                        EV_SWITCHES,
                        i32::from(Switches::LIMIT_LOWER | Switches::BUTTON_DOWN),
                    );
                    evs[4] = (800, EV_SWITCHES, 0);
                    evs[5] = (900, EV_UP, 0);
                    evs[6] = (1000, EV_SWITCHES, i32::from(Switches::LIMIT_UPPER));
                    evs[7] = (1100, EV_SWITCHES, i32::from(Switches::BUTTON_STOP));
                    evs[8] = (1200, EV_SWITCHES, 0);
                    9
                }
                // Random commands and nonsense inputs.
                _ => {
                    let mut t = 0u32;
                    let mut n = 0;
                    while n < 24 {
                        t += rng.range(1, 150) as u32;
                        if t >= ticks {
                            break;
                        }
                        let what = rng.range(0, 9) as u8;
                        let arg = match what {
                            EV_SWITCHES => rng.range(0, 31) as i32,
                            EV_LOAD => rng.range(-2048, 2048) as i32,
                            EV_SUPPLY => rng.range(0, 4095) as i32,
                            EV_GAIN => rng.range(-16, 16) as i32,
                            EV_NONSENSE => rng.range(0, 40) as i32,
                            _ => rng.bits(),
                        };
                        evs[n] = (t, what, arg);
                        n += 1;
                    }
                    n
                }
            };
            input.put_u16(n as u16);
            for &(t, w, a) in evs.iter().take(n) {
                input.put_u32(t);
                input.put_u8(w);
                input.put_i32(a);
            }
            record(s, Kind::ControlTick, &input)?;
        }
    }
    Ok(())
}
