//! The speed-profile planner: a reference position and speed that accelerate along the ramp,
//! cruise, and brake along the same ramp so that the reference comes to rest exactly on the
//! target (seed 000's Fig. 2 profile when the target is far; a triangle when it is near).
//!
//! Units: motor encoder counts (of the *screw* position, see the halt planner in
//! [`super::Controller`]) and control ticks. Position and speed are `i64` in Q32 so that a
//! 10 kHz tick with a 2 s ramp still has 16 significant bits of acceleration.
//!
//! Braking: the reference may move at most `√(2·a·d)` when `d` counts remain, so it always
//! has room to stop at `a`; the last step snaps onto the target, so the reference never
//! passes it. The S-curve shape runs the trapezoid over `ramp − n` ticks through a moving
//! average of `n`, the power of two nearest half the ramp (`s_curve_window`): the configured
//! ramp time, the same end position (a moving average keeps the area under the speed curve;
//! its entries in Q16 counts, each remainder carried into the next, keep the output within
//! 0.001 count of the exact average, and it snaps onto the target once the window has
//! drained), no acceleration step (where an entry spans several ticks, ramps above 64 ticks
//! a half, the speed steps once an entry), at most twice the trapezoid's peak acceleration.

use super::config::RampShape;
use crate::math::div_pow2_i64;

/// Length of the S-curve's moving-average window, entries (each spans one or more ticks).
const SMOOTH_LEN: usize = 64;
const _: () = assert!(
    SMOOTH_LEN <= u8::MAX as usize,
    "`Profile::filled` counts entries in a u8"
);

/// The longest ramp, ticks: `motion.ramp_ms` ≤ 2000 at `control.tick_us` ≥ 100.
const MAX_RAMP_TICKS: u32 = 20_000;

/// Reference position and speed for one tick.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Reference {
    /// Position, counts in Q32.
    pub position: i64,
    /// Speed, counts per tick in Q32 (signed).
    pub speed: i64,
    /// True once the reference rests on the target.
    pub done: bool,
}

impl Reference {
    /// Position rounded to whole counts.
    pub fn counts(&self) -> i32 {
        crate::units::sat32((self.position + (1 << 31)) >> 32)
    }
}

/// The planner's configuration (quantised once) and state.
#[derive(Clone, Debug)]
pub struct Profile {
    accel: i64,
    cruise: i64,
    /// `2|d| − v·dir` (Q32 counts) from which the braking speed surely exceeds cruise, so the
    /// square root can be skipped (see [`Self::step_trapezoid`]).
    cruise_room: i64,
    /// a²/4 (Q64), the discriminant's constant term.
    accel_sq_4: u128,
    /// The last two braking roots, newest first: the next one's guess ([`braking_speed`]).
    roots: [u32; 2],
    shape: RampShape,
    // Trapezoid generator state.
    p: i64,
    v: i64,
    target: i64,
    done: bool,
    /// The last step was within braking reach of the target (the braking root was taken):
    /// the load identification samples no braking tick.
    near_target: bool,
    /// Window entries written since the last reset (≤ `entries`): the others count as 0.
    filled: u8,
    // S-curve smoothing: a moving average of the trapezoid's speed. Entries and their sum in
    // Q16 counts (an entry: Σ of a Q32 speed over its ticks, floored, the remainder carried;
    // < 2^30: cruise ≤ 64 counts a tick, ≤ 128 ticks an entry at the longest ramp,
    // `MAX_RAMP_TICKS`): 256 B of RAM instead of 512.
    window: [i32; SMOOTH_LEN],
    /// Entries in use (a power of two ≤ SMOOTH_LEN) and log2 of the window's ticks.
    entries: u8,
    shift: u8,
    ticks_per_entry: u32,
    tick_in_entry: u32,
    entry_acc: i64,
    /// The last entry's remainder below Q16 (Q32, 0 … 2^16 − 1).
    carry: i64,
    head: usize,
    sum: i64,
    out_p: i64,
    out_v: i64,
}

/// Q32 one.
const ONE: i64 = 1 << 32;

/// Largest distance to the target the trapezoid step works with (2^29 counts, Q32).
const D_MAX: i64 = 1 << 61;

/// Largest next speed v' from which the ramp still stops on the target after this step moves
/// (v + v')/2: v'² ≤ 2a(d − (v + v')/2), i.e. v' = √(a²/4 + a·room) − a/2 with
/// room = 2|d| − v·dir. Q32 operands give a Q64 discriminant; its Q40 root is Q20, exact
/// (`isqrt_u64_near`) from a guess extrapolated from the last two roots in `roots` (newest
/// first; updated here): braking at a constant rate the root moves almost linearly, so the
/// guess is within 1 on nearly every tick (≈ 15 instructions instead of ≈ 95 for the full
/// root); a stale or wrong guess only costs the full root. Kept out of line: only the braking
/// ticks need it.
#[inline(never)]
fn braking_speed(accel: u64, a2_4: u128, room: i64, roots: &mut [u32; 2]) -> i64 {
    // Unsigned, 64 × 64-bit products (half the instructions of signed ones): with room ≥ 0 (no
    // overshoot, every braking tick in practice) a²/4 + a·room, else a²/4 − a·|room|.
    // a ≤ 2^38 and |room| < 2^63: no overflow.
    let q = if let Ok(r) = u64::try_from(room) {
        (a2_4 + u128::from(accel) * u128::from(r)) >> 24
    } else {
        let back = u128::from(accel) * u128::from(room.unsigned_abs());
        if a2_4 <= back {
            return 0;
        }
        (a2_4 - back) >> 24
    };
    if q == 0 {
        // √0 − a/2 < 0.
        0
    } else {
        let q40 = u64::try_from(q).unwrap_or(u64::MAX);
        let [r0, r1] = *roots;
        let guess = (2 * i64::from(r0) - i64::from(r1)).clamp(0, i64::from(u32::MAX)) as u32;
        let root = crate::math::isqrt_u64_near(q40, guess);
        *roots = [root, r0];
        // a/2 < 2^37.
        ((i64::from(root) << 12) - (accel / 2) as i64).max(0)
    }
}

/// `target − p` saturated and clamped to ±[`D_MAX`] (a far target: off the tick's path).
#[cold]
#[inline(never)]
fn far_distance(target: i64, p: i64) -> i64 {
    target.saturating_sub(p).clamp(-D_MAX, D_MAX)
}

/// Smallest `2|d| − v·dir` at which the braking speed `√(a²/4 + a(2|d| − v·dir)) − a/2` exceeds
/// `cruise` by more than 2^14 (Q32), the most the fixed-point root (Q40 → Q20, floored) can
/// lose: from there the braking limit is surely inactive. Exact form:
/// `(cruise + δ)²/a + cruise + δ + 1`, saturated.
fn cruise_room(cruise: i64, accel: i64) -> i64 {
    // cruise ≥ 1 and accel ≥ 1 ([`Profile::new`]); one shared 128-bit product and division
    // (crate::math::mul_div_u64), not an inline expansion: this runs when a motion is
    // planned, not per tick. Saturated at u64::MAX, the sum still exceeds i64::MAX.
    let c = cruise.unsigned_abs() + (1 << 14);
    let room = crate::math::mul_div_u64(c, c, accel.max(1).unsigned_abs()).saturating_add(c + 1);
    i64::try_from(room).unwrap_or(i64::MAX)
}

/// The S-curve's moving-average window for a ramp of `ramp` ticks (≥ 2): the power of two
/// nearest half the ramp (the lower on a tie), at most `ramp` − 1, so that the trapezoid's
/// `ramp − n` ticks through the window's `n` take the configured ramp time. (Half and half had
/// been meant, but a fixed 64-tick window made the default 60 ms ramp take 93 ms and a 10 ms
/// one 68 ms.)
fn s_curve_window(ramp: u32) -> u32 {
    let half = (ramp / 2).max(1);
    let lo = 1u32 << (31 - half.leading_zeros());
    let hi = lo << 1;
    if hi - half < half - lo && hi < ramp {
        hi
    } else {
        lo
    }
}

impl Profile {
    /// A planner at rest at `position` counts. `cruise_q32` is the cruise speed in Q32 counts per
    /// tick and `ramp_ticks` the ramp time in ticks (≥ 1).
    pub fn new(position: i32, cruise_q32: i64, ramp_ticks: u32, shape: RampShape) -> Profile {
        // (At most the configuration's longest ramp, 2 s at 10 kHz: the S-curve's Q16 entries
        // then stay below 2^30.)
        let ramp_ticks = ramp_ticks.clamp(2, MAX_RAMP_TICKS);
        let cruise = cruise_q32.clamp(1, 64 * ONE);
        let (trap_ticks, window_ticks) = match shape {
            RampShape::Trapezoid => (ramp_ticks, 1),
            RampShape::SCurve => {
                let n = s_curve_window(ramp_ticks);
                (ramp_ticks - n, n)
            }
        };
        // n = entries × ticks an entry, both powers of two (≤ SMOOTH_LEN entries).
        let entries = window_ticks.min(SMOOTH_LEN as u32);
        let ticks_per_entry = window_ticks / entries;
        let p = i64::from(position) << 32;
        let accel = (cruise / i64::from(trap_ticks.max(1))).max(1);
        Profile {
            accel,
            cruise,
            cruise_room: cruise_room(cruise, accel),
            // accel ≥ 1: a²/4, an unsigned 64×64-bit product (smaller inline than the i128 call).
            accel_sq_4: {
                let a = u128::from(accel.unsigned_abs());
                a * a >> 2
            },
            roots: [0; 2],
            shape,
            p,
            v: 0,
            target: p,
            done: true,
            near_target: false,
            filled: 0,
            window: [0; SMOOTH_LEN],
            // (≤ 64 entries, n ≤ 2^13: both fit u8.)
            entries: entries as u8,
            shift: window_ticks.trailing_zeros() as u8,
            ticks_per_entry,
            tick_in_entry: 0,
            entry_acc: 0,
            carry: 0,
            head: 0,
            sum: 0,
            out_p: p,
            out_v: 0,
        }
    }

    /// Entries of the moving-average window actually used (0 for the trapezoid).
    fn smooth_entries(&self) -> usize {
        match self.shape {
            RampShape::Trapezoid => 0,
            RampShape::SCurve => SMOOTH_LEN,
        }
    }

    /// Move the target to `counts` (the reference keeps its current speed and re-plans).
    pub fn set_target(&mut self, counts: i32) {
        self.target = i64::from(counts) << 32;
        self.done = false;
    }

    /// Brake along the ramp from the current speed: the target becomes the stopping point.
    pub fn stop(&mut self) {
        let v = self.v.unsigned_abs();
        // v²/(2a) + v/2 (the discrete ramp covers half a step more than the continuous one).
        // (Once per stop: the shared 128-bit product and division, see `cruise_room`.)
        // Saturated, not cast: with an absurd acceleration (a few Q32 LSB per tick²) the
        // distance exceeds i64 and a cast would wrap it to a target behind the head.
        // 1 ≤ accel ≤ 64·2^32 (`new`), so 2·accel fits.
        let two_a = self.accel.max(1).unsigned_abs() << 1;
        let dist = i64::try_from(crate::math::mul_div_u64(v, v, two_a).saturating_add(v >> 1))
            .unwrap_or(i64::MAX);
        // dist ≥ 0, and 0 when v is.
        self.target = if self.v < 0 {
            self.p.saturating_sub(dist)
        } else {
            self.p.saturating_add(dist)
        };
        self.done = false;
    }

    /// Change the cruise speed (Q32 counts per tick) during a motion: the reference ramps to
    /// it at the configured acceleration (the stick-slip reaction's escape speed).
    pub fn set_cruise(&mut self, cruise_q32: i64) {
        self.cruise = cruise_q32.clamp(1, 64 * ONE);
    }

    /// Restart at rest at `position` counts (after a fault, or when the measured position
    /// disagrees with the reference).
    pub fn reset(&mut self, position: i32) {
        let p = i64::from(position) << 32;
        self.p = p;
        self.v = 0;
        self.target = p;
        self.done = true;
        // The moving average's window (512 B) is not cleared: its entries count as 0 until
        // written again (`filled`). A button starts a motion inside a control tick, whose budget
        // the clearing took (≈ 670 instructions).
        self.filled = 0;
        self.tick_in_entry = 0;
        self.entry_acc = 0;
        self.head = 0;
        self.sum = 0;
        self.out_p = p;
        self.out_v = 0;
    }

    /// The last step was within braking reach of the target (braking, or about to): a motion
    /// that ends here is no longer steady.
    pub fn near_target(&self) -> bool {
        self.near_target
    }

    /// The target, counts.
    pub fn target_counts(&self) -> i32 {
        crate::units::sat32(self.target >> 32)
    }

    /// Advance one tick.
    pub fn step(&mut self) -> Reference {
        if !self.done {
            self.step_trapezoid();
        }
        if self.smooth_entries() == 0 {
            self.out_p = self.p;
            self.out_v = self.v;
        } else {
            self.step_smoothing();
        }
        Reference {
            position: self.out_p,
            speed: self.out_v,
            done: self.done && self.out_v == 0 && self.out_p == self.p,
        }
    }

    fn step_trapezoid(&mut self) {
        // The distance clamped to ±2^61 (2^29 counts, far beyond any lift): every sum below
        // then stays in i64 (|v|, accel ≤ cruise ≤ 2^38) in plain arithmetic, ≈ 40
        // instructions fewer than saturating ones. Beyond 2^61 the step is the one
        // for a target 2^61 away on the same side: the same unless braking from cruise takes
        // more than 2^61 (`cruise_room` > 2^62 − 2^39: a ramp of hours), where it brakes
        // earlier (proptest against the saturating step).
        // Positions within ±2^60 (|counts| < 2^28: every lift) need neither saturation nor
        // the clamp; the rest goes out of line.
        let near = |x: i64| (x as u64).wrapping_add(1 << 60) < 1 << 61;
        let near = near(self.p) && near(self.target);
        let d = if near {
            self.target - self.p
        } else {
            far_distance(self.target, self.p)
        };
        let dir = d.signum();
        // The braking limit ([`braking_speed`]). Far from the target (the whole cruise) the braking speed exceeds cruise by more than
        // the root's rounding: skip the 128-bit discriminant and the root, same result.
        let v_toward = dir * self.v;
        let room = 2 * d.abs() - v_toward;
        self.near_target = room < self.cruise_room;
        let brake = if !self.near_target {
            self.cruise
        } else {
            // accel ≥ 1 (`new`).
            braking_speed(self.accel as u64, self.accel_sq_4, room, &mut self.roots)
        };
        let v_goal = dir * brake.min(self.cruise);
        let v_new = if v_goal > self.v {
            (self.v + self.accel).min(v_goal)
        } else {
            (self.v - self.accel).max(v_goal)
        };
        let step = div_pow2_i64(self.v + v_new, 1);
        let p_new = if near {
            self.p + step
        } else {
            self.p.saturating_add(step)
        };
        // target − p_new where |target − p| ≤ 2^61 (and where p_new saturated past the
        // target: both < 0 on the side of travel); beyond, as far, on the same side.
        let remaining = d - step;
        // Arrived: the next step would reach or pass the target at a speed the ramp can stop
        // (the speed first: it is false on all but the last ticks of a move).
        let slow = v_new.unsigned_abs() <= 2 * self.accel as u64;
        if remaining == 0
            || remaining.signum() != dir
            || (slow && remaining.unsigned_abs() <= v_new.unsigned_abs().max(ONE as u64))
        {
            self.p = self.target;
            self.v = 0;
            self.done = true;
        } else {
            self.p = p_new;
            self.v = v_new;
        }
    }

    fn step_smoothing(&mut self) {
        // Each window entry holds the trapezoid's mean speed over `ticks_per_entry` ticks; the
        // output speed is the window mean and the output position its running sum, so the
        // output ends exactly where the trapezoid ends.
        self.entry_acc += self.v;
        self.tick_in_entry += 1;
        if self.tick_in_entry >= self.ticks_per_entry {
            // An entry not written since the reset is 0 (the window is not cleared).
            let old = if self.filled < self.entries {
                self.filled += 1;
                0
            } else {
                self.window[self.head]
            };
            // Q32 → Q16 (floor; < 2^30, a plain cast); the remainder (0 … 2^16 − 1) starts the
            // next entry, so the rounding never accumulates over a move.
            let a = self.entry_acc;
            let e = (a >> 16) as i32;
            self.window[self.head] = e;
            self.sum += i64::from(e) - i64::from(old);
            self.carry = a & 0xFFFF;
            self.head = if self.head + 1 >= usize::from(self.entries) {
                0
            } else {
                self.head + 1
            };
            self.tick_in_entry = 0;
            self.entry_acc = self.carry;
        }
        // Output speed: the mean over the completed entries. Every entry stays in the window
        // for exactly n ticks, so the output covers the trapezoid's distance, no more (adding
        // the partial entry as well counted each speed (n + ticks_per_entry)/n times: with one
        // tick per entry the reference ran 65/64 fast and ended 37 counts past a 5000-count
        // move's target before snapping back).
        // The window's ticks are a power of two: a shift rounded toward zero, exactly as `/`
        // does, instead of a 64-bit division routine. (|Σ| < 2^36 in Q16: in Q32 < 2^52.)
        let total = self.sum << 16;
        let k = u32::from(self.shift);
        let out_v = (total + ((total >> 63) & ((1i64 << k) - 1))) >> k;
        self.out_v = out_v;
        self.out_p = self.out_p.saturating_add(out_v);
        // Rounding leaves the output a few LSB off the trapezoid at rest: snap once both rest.
        // (The partial entry holds at most the last remainder then.)
        if self.done && self.sum == 0 && self.entry_acc.unsigned_abs() < 1 << 16 {
            self.out_p = self.p;
            self.out_v = 0;
            self.entry_acc = 0;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `stop` at the fastest reference the planner allows with the smallest acceleration: the
    /// braking distance (≈ 2^75 Q32 counts) does not fit i64 and must saturate ahead of the
    /// head in the direction of motion (a cast wrapped it).
    #[test]
    fn stop_distance_saturates_instead_of_wrapping() {
        for sign in [1i64, -1] {
            let mut p = Profile::new(0, 64 * ONE, 2, RampShape::Trapezoid);
            p.v = sign * 64 * ONE;
            p.accel = 1;
            p.stop();
            assert_eq!(p.target.signum(), sign, "target {} for v {}", p.target, p.v);
            assert!(p.target.unsigned_abs() >= (i64::MAX as u64) / 2);
        }
    }

    fn run(shape: RampShape, from: i32, to: i32, cruise: f64, ramp: u32) -> Vec<Reference> {
        let mut p = Profile::new(from, (cruise * ONE as f64) as i64, ramp, shape);
        p.set_target(to);
        let mut out = Vec::new();
        for _ in 0..200_000 {
            let r = p.step();
            out.push(r);
            if r.done {
                break;
            }
        }
        out
    }

    #[test]
    fn trapezoid_reaches_the_target_without_passing_it() {
        for &(from, to) in &[(0, 10_000), (5_000, -3_000), (0, 7), (100, 99)] {
            let refs = run(RampShape::Trapezoid, from, to, 1.375, 60);
            let last = refs.last().unwrap();
            assert!(last.done);
            assert_eq!(last.counts(), to);
            let dir = (to - from).signum() as i64;
            for r in &refs {
                assert!(
                    (r.position - (i64::from(to) << 32)) * dir <= 0,
                    "passed target"
                );
                assert!(r.speed * dir >= 0, "moved backwards");
            }
        }
    }

    #[test]
    fn trapezoid_accelerates_in_the_ramp_time_and_cruises() {
        let refs = run(RampShape::Trapezoid, 0, 100_000, 1.375, 60);
        let cruise = (1.375 * ONE as f64) as i64;
        let first_cruise = refs.iter().position(|r| r.speed == cruise).unwrap();
        assert!((59..=61).contains(&first_cruise), "{first_cruise}");
        // Braking also takes ≈ 60 ticks.
        let last_cruise = refs.iter().rposition(|r| r.speed == cruise).unwrap();
        let braking = refs.len() - last_cruise;
        assert!((58..=63).contains(&braking), "{braking}");
    }

    /// The S-curve's window is not cleared at a reset (a button's start tick could not pay
    /// for it): a motion after a reset mid-move (its window full of the old motion's speeds)
    /// runs exactly as the same motion on a fresh profile.
    #[test]
    fn an_s_curve_after_a_reset_mid_move_runs_as_on_a_fresh_profile() {
        let cruise = (1.375 * ONE as f64) as i64;
        for ramp in [4u32, 60, 130, 600] {
            let mut used = Profile::new(0, cruise, ramp, RampShape::SCurve);
            used.set_target(40_000);
            for _ in 0..(ramp + 500) {
                used.step();
            }
            assert!(used.sum != 0, "the window holds the old motion");
            used.reset(9_000);
            used.set_target(-2_000);
            let mut fresh = Profile::new(9_000, cruise, ramp, RampShape::SCurve);
            fresh.set_target(-2_000);
            loop {
                let (a, b) = (used.step(), fresh.step());
                assert_eq!(a, b, "ramp {ramp}");
                if a.done {
                    break;
                }
            }
        }
    }

    /// The S-curve takes the configured ramp time (to the tick; to the entry where an entry
    /// spans several ticks) from rest to cruise, as the trapezoid does, over the whole range of ramps (2…20 000 ticks: 10…2000 ms at up to
    /// 10 kHz), and its acceleration peaks at most twice the trapezoid's. (A fixed 64-tick
    /// window had made the default 60-tick ramp take 93 ticks and a 10-tick one 68.)
    #[test]
    fn an_s_curve_takes_the_configured_ramp_time() {
        let c = (1.375 * ONE as f64) as i64;
        let mut ramps: Vec<u32> = (2..=300).collect();
        ramps.extend([511, 512, 513, 600, 1000, 2000, 5000, 20_000]);
        for ramp in ramps {
            let mut p = Profile::new(0, c, ramp, RampShape::SCurve);
            p.set_target(i32::MAX / 2);
            let (mut k, mut last, mut max_dv) = (0u32, 0i64, 0i64);
            while last < c {
                let r = p.step();
                k += 1;
                max_dv = max_dv.max(r.speed - last);
                last = r.speed;
                assert!(k <= 2 * ramp + 2, "ramp {ramp}: no cruise");
            }
            // The trapezoid reaches cruise on tick `ramp` + 1; the S-curve on `ramp` − 1 or
            // `ramp`, or (its output moving once an entry) within the entry after.
            let late = ramp + p.ticks_per_entry.max(2) - 1;
            assert!(
                k + 1 >= ramp && k <= late,
                "ramp {ramp}: cruise after {k} ticks"
            );
            // One tick's step at most twice the trapezoid's a tick, and where an entry spans
            // several ticks, one entry's (the output steps once an entry).
            let trap = c as f64 / ramp as f64;
            let allowed = 2.0 * trap * f64::from(p.ticks_per_entry) * 1.01;
            assert!(
                max_dv as f64 <= allowed,
                "ramp {ramp}: step {max_dv} vs {trap}"
            );
        }
    }

    #[test]
    fn s_curve_ends_on_the_same_target_with_no_acceleration_step() {
        let refs = run(RampShape::SCurve, 0, 50_000, 1.375, 60);
        let last = refs.last().unwrap();
        assert_eq!(last.counts(), 50_000);
        // Largest speed change per tick: twice the trapezoid's (1.375/60), never a jump.
        let max_dv = refs
            .windows(2)
            .map(|w| (w[1].speed - w[0].speed).abs())
            .max()
            .unwrap();
        let trap = (1.375 * ONE as f64 / 60.0) as i64;
        assert!(max_dv <= 2 * trap + trap / 10, "{max_dv} vs {trap}");
        let first_dv = (refs[1].speed - refs[0].speed).abs();
        assert!(first_dv < trap, "S-curve starts gently: {first_dv}");
    }

    /// The Q16 window against its exact twin (the same trapezoid through an exact moving
    /// average of whole entries, in f64 counts): the reference position stays within 0.001
    /// count of it on every tick of long moves at the slowest and fastest cruises, up and down,
    /// one and several ticks an entry (the entries' truncation does not accumulate).
    #[test]
    fn an_s_curve_s_q16_window_follows_its_exact_twin() {
        for (ramp, cruise, to) in [
            (60u32, 1.375, 200_000),
            (60, 0.05, -20_000),
            (2000, 64.0, -2_000_000),
            (20_000, 64.0, 4_000_000),
            (400, 7.3, 90_000),
        ] {
            let c = (cruise * ONE as f64) as i64;
            let mut p = Profile::new(0, c, ramp, RampShape::SCurve);
            let mut trap = Profile::new(0, c, ramp - s_curve_window(ramp), RampShape::Trapezoid);
            p.set_target(to);
            trap.set_target(to);
            let n = usize::from(p.entries) * p.ticks_per_entry as usize;
            let mut entries =
                std::collections::VecDeque::from(vec![0.0f64; usize::from(p.entries)]);
            let (mut acc, mut k, mut pos) = (0.0f64, 0u32, 0.0f64);
            let mut worst: f64 = 0.0;
            loop {
                let (r, t) = (p.step(), trap.step());
                acc += t.speed as f64 / ONE as f64;
                k += 1;
                if k == p.ticks_per_entry {
                    entries.pop_front();
                    entries.push_back(acc);
                    (acc, k) = (0.0, 0);
                }
                pos += entries.iter().sum::<f64>() / n as f64;
                if r.done {
                    break;
                }
                worst = worst.max((r.position as f64 / ONE as f64 - pos).abs());
            }
            assert!(
                worst < 1e-3,
                "ramp {ramp}, cruise {cruise}: {worst} counts off"
            );
        }
    }

    #[test]
    fn s_curve_reaches_the_target_without_passing_it() {
        for &(from, to, ramp) in &[(0, 50_000, 60), (183_489, 178_227, 120), (0, -9_000, 500)] {
            let refs = run(RampShape::SCurve, from, to, 1.375, ramp);
            let last = refs.last().unwrap();
            assert_eq!(last.counts(), to);
            let dir = i64::from((to - from).signum());
            // Within the snap's few LSB of rounding, never past the target.
            let worst = refs
                .iter()
                .map(|r| (r.position - (i64::from(to) << 32)) * dir)
                .max()
                .unwrap();
            assert!(
                worst <= 1 << 28,
                "passed the target by {} counts",
                worst >> 32
            );
            assert!(refs.iter().all(|r| r.speed * dir >= 0), "moved backwards");
        }
    }

    proptest::proptest! {
        /// The step equals the saturating one it replaced (below, as it was) wherever braking
        /// from cruise takes less than 2^61 (every configuration a lift can have), for any
        /// positions and any speed the planner reaches (|v| ≤ cruise ≤ 2^38).
        #[test]
        fn step_is_the_saturating_step(
            p in proptest::prelude::any::<i64>(),
            target in proptest::prelude::any::<i64>(),
            near in -(1i64 << 44)..(1i64 << 44),
            cruise in 1i64..(64 << 32),
            v_frac in -1.0f64..1.0,
            ramp in 2u32..100_000,
            roots in proptest::prelude::any::<[u32; 2]>(),
            small in proptest::prelude::any::<bool>(),
        ) {
            // Small positions (every lift) or any; far moves and moves that end within a few
            // counts (braking, arriving).
            let (p, target) = if small { (p >> 4, target >> 4) } else { (p, target) };
            for target in [target, p.saturating_add(near)] {
                let mut a = Profile::new(0, cruise, ramp, RampShape::Trapezoid);
                proptest::prop_assume!(a.cruise_room <= (1 << 62) - (1 << 39));
                a.p = p;
                a.target = target;
                a.v = (v_frac * a.cruise as f64) as i64;
                a.roots = roots;
                a.done = false;
                let mut b = a.clone();
                a.step_trapezoid();
                saturating_step(&mut b);
                proptest::prop_assert_eq!((a.p, a.v, a.done, a.roots), (b.p, b.v, b.done, b.roots));
            }
        }
    }

    /// The trapezoid step in saturating sums (the twin of the plain arithmetic).
    fn saturating_step(s: &mut Profile) {
        let d = s.target.saturating_sub(s.p);
        let dir = d.signum();
        let v_toward = match dir {
            1 => s.v,
            -1 => s.v.saturating_neg(),
            _ => 0,
        };
        let two_d = d.saturating_abs().saturating_add(d.saturating_abs());
        let room = two_d.saturating_sub(v_toward);
        let brake = if room >= s.cruise_room {
            s.cruise
        } else {
            braking_speed(s.accel as u64, s.accel_sq_4, room, &mut s.roots)
        };
        let v_goal = dir * brake.min(s.cruise);
        let v_new = if v_goal > s.v {
            (s.v + s.accel).min(v_goal)
        } else {
            (s.v - s.accel).max(v_goal)
        };
        let step = div_pow2_i64(s.v + v_new, 1);
        let p_new = s.p.saturating_add(step);
        let remaining = s.target.saturating_sub(p_new);
        if remaining == 0
            || remaining.signum() != dir
            // (`unsigned_abs`: `abs` overflowed on a remaining of i64::MIN)
            || (remaining.unsigned_abs() <= v_new.unsigned_abs().max(ONE as u64)
                && v_new.abs() <= 2 * s.accel)
        {
            s.p = s.target;
            s.v = 0;
            s.done = true;
        } else {
            s.p = p_new;
            s.v = v_new;
        }
    }

    proptest::proptest! {
        /// The braking root (unsigned product, root from a guess) is the plain formula
        /// ⌊√⌊(a²/4 + a·room)/2^24⌋⌋·2^12 − a/2 (≥ 0) for any room and any guess history.
        #[test]
        fn braking_speed_is_the_exact_formula(
            accel in 1i64..(1 << 38),
            room in proptest::prelude::any::<i64>(),
            small in -(1i64 << 34)..(1i64 << 42),
            roots in proptest::prelude::any::<[u32; 2]>(),
        ) {
            for room in [room, small] {
                let a2_4 = i128::from(accel) * i128::from(accel) / 4;
                let disc = a2_4 + i128::from(accel) * i128::from(room);
                let (au, a2u) = (accel as u64, a2_4 as u128);
                let want = if disc <= 0 {
                    0
                } else {
                    let q = u64::try_from(disc >> 24).unwrap_or(u64::MAX);
                    ((i64::from(q.isqrt() as u32) << 12) - accel / 2).max(0)
                };
                let mut r = roots;
                proptest::prop_assert_eq!(braking_speed(au, a2u, room, &mut r), want);
                // Again from the history it left (the guess path).
                proptest::prop_assert_eq!(braking_speed(au, a2u, room, &mut r), want);
            }
        }
    }

    #[test]
    fn stop_brakes_along_the_ramp() {
        let cruise = (1.375 * ONE as f64) as i64;
        let mut p = Profile::new(0, cruise, 60, RampShape::Trapezoid);
        p.set_target(1_000_000);
        for _ in 0..200 {
            p.step();
        }
        p.stop();
        let mut n = 0;
        loop {
            let r = p.step();
            n += 1;
            if r.done {
                break;
            }
        }
        assert!((58..=63).contains(&n), "{n}");
    }
}
