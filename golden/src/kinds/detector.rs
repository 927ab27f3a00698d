//! The stick-slip detector: `detect::stickslip::StickSlipDetector`.

use crate::configs::{config, estimator, CONFIGS};
use crate::format::{Error, Fold, InputBuf, Kind, Reader, Sink};
use crate::record;
use crate::rng::SplitMix64;
use liftfw::detect::stickslip::{
    DetectorInputs, Reaction, StickSlipConfig, StickSlipDetector, StickSlipOutput,
};
use liftfw::units::{NewtonMetres, RadiansPerSecond};

/// Longest detector trace, ticks.
pub const MAX_DETECTOR_TICKS: u32 = 40_000;

/// A detector trace: the detector's settings and the parameters of the synthesised inputs
/// (the trace itself is computed by [`DetectorTrace::inputs`] on both sides: 20 000 ticks of
/// inputs would not fit the file).
#[derive(Clone, Copy, Debug)]
pub struct DetectorTrace {
    /// Index into [`config`](crate::config): the friction law and the tick.
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

/// [`Kind::DetectorSequence`](crate::Kind::DetectorSequence): the detector over a synthesised trace.
pub(crate) fn eval(r: &mut Reader<'_>, out: &mut impl Sink) -> Result<(), Error> {
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

/// The detector's records: [`DETECTOR_TRACES_PER_CONFIG`] traces per configuration.
pub(crate) fn generate(rng: &mut SplitMix64, s: &mut impl Sink) -> Result<(), Error> {
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
