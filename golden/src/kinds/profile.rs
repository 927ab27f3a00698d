//! The ramp/planner: `control::profile::Profile`.

use crate::format::{Error, Fold, InputBuf, Kind, Reader, Sink, MAX_SEQUENCE};
use crate::record;
use crate::rng::SplitMix64;
use liftfw::control::config::RampShape;
use liftfw::control::profile::{Profile, Reference};

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

/// Every field of a planner reference, raw bits.
pub fn put_reference(s: &mut impl Sink, r: &Reference) {
    s.put_i64(r.position);
    s.put_i64(r.speed);
    s.put_u8(u8::from(r.done));
}

/// [`Kind::ProfileSequence`](crate::Kind::ProfileSequence): a planner driven by a script.
pub(crate) fn eval(r: &mut Reader<'_>, out: &mut impl Sink) -> Result<(), Error> {
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

/// The planner's records: [`PROFILE_CASES`] scripts per scenario and ramp shape.
pub(crate) fn generate(rng: &mut SplitMix64, s: &mut impl Sink) -> Result<(), Error> {
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
