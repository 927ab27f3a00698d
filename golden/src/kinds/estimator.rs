//! The estimator: `Estimator::estimate` of single cases and `Estimator::step` sequences.

use crate::configs::{config, estimator, CONFIGS};
use crate::format::{Error, InputBuf, Kind, Reader, Sink, MAX_SEQUENCE};
use crate::record;
use crate::rng::SplitMix64;
use liftfw::estimator::{Estimate, Estimator, EstimatorConfig, Measurements, TickEstimate};
use liftfw::units::{Amperes, Instant, Kilograms, RadiansPerSecond, RadiansPerSecond2};

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

pub(crate) fn put_measurements(s: &mut impl Sink, m: &Measurements) {
    s.put_i32(m.position_counts);
    s.put_i32(m.motor_current.to_bits());
    s.put_i32(m.load.to_bits());
    s.put(&m.commanded_dir.to_le_bytes());
}

pub(crate) fn read_measurements(r: &mut Reader<'_>) -> Result<Measurements, Error> {
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
    /// Index into [`config`](crate::config).
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
    pub(crate) fn put(&self, s: &mut impl Sink) {
        s.put_u8(self.cfg);
        put_measurements(s, &self.m);
        s.put_i32(self.speed.to_bits());
        s.put_i32(self.accel.to_bits());
        s.put_u8(self.flags);
    }
}

/// [`Kind::EstimatorEstimate`](crate::Kind::EstimatorEstimate): `Estimator::estimate` of one case.
pub(crate) fn eval_estimate(r: &mut Reader<'_>, out: &mut impl Sink) -> Result<(), Error> {
    let est = estimator(r.u8()?)?;
    let m = read_measurements(r)?;
    let speed = RadiansPerSecond::from_bits(r.i32()?);
    let accel = RadiansPerSecond2::from_bits(r.i32()?);
    let flags = r.u8()?;
    put_estimate(out, &est.estimate(&m, speed, accel, flags));
    Ok(())
}

/// [`Kind::EstimatorSequence`](crate::Kind::EstimatorSequence): a fresh estimator stepped
/// through a sequence of measurements.
pub(crate) fn eval_sequence(r: &mut Reader<'_>, out: &mut impl Sink) -> Result<(), Error> {
    let mut est = estimator(r.u8()?)?;
    let n = r.u16()?;
    if usize::from(n) > MAX_SEQUENCE {
        return Err(Error::SequenceTooLong(n));
    }
    for _ in 0..n {
        let now = Instant(r.u32()?);
        let m = read_measurements(r)?;
        // The tick's own fields, then the whole estimate recomputed from them: both
        // paths of the model, bit for bit.
        let t = est.step(now, &m);
        put_tick(out, &t);
        put_estimate(out, &est.details(&m, &t));
        // As the control tick runs it: the steps that enter a segment read one prepared
        // ahead (the same bits as a refill, replayed on both sides).
        est.prepare();
    }
    Ok(())
}

/// Motor counts at which the pose reaches `alpha_max` (binary search on the core's own pose).
pub(crate) fn counts_at_alpha_max(est: &Estimator) -> i32 {
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

/// The estimator's records: [`ESTIMATE_CASES_PER_CONFIG`] `estimate` cases, then
/// [`SEQUENCES_PER_CONFIG`] step sequences, for every configuration, from one stream.
pub(crate) fn generate(rng: &mut SplitMix64, s: &mut impl Sink) -> Result<(), Error> {
    for cfg in 0..CONFIGS {
        let est = estimator(cfg)?;
        let c_max = counts_at_alpha_max(&est);
        let rest = config(cfg).map_or(0, |c| c.rest_speed.to_bits());
        for k in 0..ESTIMATE_CASES_PER_CONFIG {
            let case = estimate_case(rng, cfg, c_max, rest, k);
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
    Ok(())
}
