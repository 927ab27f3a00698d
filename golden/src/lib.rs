//! Golden vectors of the liftfw core: generated on the host, replayed bit for bit on the target.
//!
//! The proof that the core computes on the Cortex-M4 exactly what it computes on the host. This
//! crate holds everything both sides share, so that they run the *same source*:
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
//! # Layout
//! `format.rs` (magic, [`Kind`], [`Error`], the byte codecs), `rng.rs` ([`SplitMix64`]),
//! `configs.rs` ([`config`]: the estimator configurations), [`corners`] (the validated ranges'
//! corners, shared with the root package's envelope tests), and one module per kind in `kinds/`.
//!
//! # Adding a kind
//! 1. a new [`Kind`] variant (never renumber the old ones) and its entry in [`Kind::ALL`];
//! 2. a module under `kinds/` with its input codec, an `eval` that calls the core and
//!    [`put_*`](Sink) its outputs field by field (raw bits, fixed order), and a case generator;
//! 3. their arms in [`evaluate`] and [`generate`].
//!
//! The QEMU harness needs no change: it replays whatever kinds the file holds and prints a
//! `GOLDEN` line per entry of [`Kind::ALL`].
#![no_std]
#![forbid(unsafe_code)]

pub mod corners;

mod configs;
mod format;
mod kinds;
mod rng;

pub use configs::{config, CONFIGS};
pub use format::{Compare, Counter, Error, Kind, Sink, MAGIC, MAX_SEQUENCE, VERSION};
pub use kinds::console::CONSOLE_LINES;
pub use kinds::control::{CONTROL_RUNS_PER_CONFIG, MAX_CONTROL_TICKS};
pub use kinds::detector::{
    put_stickslip, DetectorTrace, DETECTOR_TRACES_PER_CONFIG, MAX_DETECTOR_TICKS,
};
pub use kinds::estimator::{
    put_estimate, put_tick, EstimateCase, ESTIMATE_CASES_PER_CONFIG, SEQUENCES_PER_CONFIG,
    SEQUENCE_LEN,
};
pub use kinds::profile::{
    put_reference, MAX_PROFILE_RUN, MAX_PROFILE_STEPS, OP_CRUISE, OP_RESET, OP_RUN, OP_STEPS,
    OP_STOP, OP_TARGET, PROFILE_CASES,
};
pub use rng::SplitMix64;

use format::{InputBuf, Reader};

/// Run one record's input through the core and put its outputs.
pub fn evaluate(kind: u8, input: &[u8], out: &mut impl Sink) -> Result<(), Error> {
    let mut r = Reader { b: input };
    match Kind::from_u8(kind).ok_or(Error::UnknownKind(kind))? {
        Kind::EstimatorEstimate => kinds::estimator::eval_estimate(&mut r, out)?,
        Kind::EstimatorSequence => kinds::estimator::eval_sequence(&mut r, out)?,
        Kind::ProfileSequence => kinds::profile::eval(&mut r, out)?,
        Kind::DetectorSequence => kinds::detector::eval(&mut r, out)?,
        Kind::ControlTick => kinds::control::eval(&mut r, out)?,
        Kind::ConsoleParse => kinds::console::eval(&mut r, out)?,
    }
    if r.b.is_empty() {
        Ok(())
    } else {
        Err(Error::Truncated)
    }
}

/// Write one record: its input and the outputs [`evaluate`] gives for it.
pub(crate) fn record(s: &mut impl Sink, kind: Kind, input: &InputBuf) -> Result<(), Error> {
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

/// Every golden record, in a fixed order, from a fixed seed.
pub fn generate(s: &mut impl Sink) -> Result<(), Error> {
    s.put(&MAGIC);
    s.put_u16(VERSION);
    // Fixed seeds ("liftfw", "lfprofil", …in ASCII): the file is a pure function of the source.
    kinds::estimator::generate(&mut SplitMix64(0x6c69_6674_6677_0008), s)?;
    // A separate stream per kind: adding a kind leaves the earlier kinds' records unchanged.
    kinds::profile::generate(&mut SplitMix64(0x6c66_7072_6f66_696c), s)?;
    kinds::console::generate(&mut SplitMix64(0x6c66_636f_6e73_6f6c), s)?;
    kinds::detector::generate(&mut SplitMix64(0x6c66_6465_7465_6374), s)?;
    kinds::control::generate(&mut SplitMix64(0x6c66_636f_6e74_726c), s)?;
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
