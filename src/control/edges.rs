//! Sub-count motor position from encoder edge times: what keeps count quantisation out of the
//! speed loop at low speed.
//!
//! **Why.** The motor encoder gives 48 counts per motor turn: at a 2 rad/s screw speed that is
//! about one count per 1 ms tick, creeping at 0.2 rad/s one count every 11 ticks. Fed the bare
//! count, the speed filter sees a staircase; its speed estimate jumps by ≈ 0.3 rad/s at every
//! count while creeping, and the PI speed loop turns each jump into a current pulse — a 1–2 N·m
//! sawtooth of the screw torque in a perfectly smooth run, the very pattern of stick-slip
//! (docs/stick-slip.md).
//!
//! **What the board measures.** A count changes exactly when the shaft crosses an edge, so the
//! position at that instant is known without quantisation error: `c` when counting up (the
//! count is ⌊angle⌋), `c + 1` when counting down. The board timestamps every count change with
//! a 1 MHz capture timer (docs/board.md: TIM4's encoder clock on TRGO captured by TIM3) and
//! hands over, each tick, the µs from the latest change to the sample
//! ([`super::Inputs::encoder_edge_age`]).
//!
//! **How.** Each tick on which the count changed records an edge event (edge position, time =
//! now − age). The slope is the mean speed over the last ≤ 4 intervals between events (at most
//! [`SPAN_US`] back, never across a reversal): four single-count intervals span one encoder
//! line, so the quadrature phase error of a real Hall encoder cancels. The position at the
//! sample is the latest edge plus slope × age, clamped into the count (the shaft cannot have
//! passed the next edge without a count). In steady motion that is exact to the capture
//! timer's µs; when the motor slows, the estimate reaches the edge of its count and waits there
//! for the next edge: it is never more than one count wrong, like the bare count.
//!
//! A board without edge capture passes an age of 0: the edges are then timed to the tick
//! (1 ms), still far better than the bare count while creeping (one tick in eleven).
//!
//! Integer only: Q16 counts, µs; one 32-bit division (one `SDIV`, 2–12 cycles on the M4) per
//! tick on which the count changed.

use crate::units::Instant;

/// Slope span: edge events older than this do not count, µs (4 counts at 0.2 rad/s of screw
/// take 44 ms; slower than that, the bare count is within a count of the truth anyway).
pub const SPAN_US: u32 = 100_000;
/// Edge events kept (the newest and 4 before it).
const EVENTS: usize = 5;
/// The events' ring, a power of two ≥ EVENTS (indexed by mask, no division).
const RING: usize = 8;
/// Largest count change over the slope's span: a glitch cannot overflow the slope (at the
/// fastest drive, ≈ 2.3 counts per tick, 4 intervals span ≈ 10 counts).
const SPAN_COUNTS_MAX: i64 = 255;
/// Fraction bits of the slope, counts per µs (Q23: 255 counts · 2^23 fits an i32, so the
/// slope is one 32-bit division; its truncation, < 2^−23 counts/µs, is 2^−7 LSB of the Q16
/// position per µs of extrapolation).
const SLOPE_FRAC: u32 = 23;
/// Largest age used for the extrapolation, µs (the clamp bounds the result anyway).
const AGE_MAX: u32 = 1 << 20;

/// One recorded count change.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
struct EdgeEvent {
    /// Position of the edge crossed last, counts.
    at: i32,
    /// When, µs (the core's clock).
    t: u32,
}

/// Edge events and the slope through them.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct EdgeInterpolator {
    /// Events, newest at `head`.
    events: [EdgeEvent; RING],
    head: usize,
    /// Valid events in the same direction (0…EVENTS).
    valid: usize,
    /// Direction of the valid events: +1 counting up, −1 down.
    dir: i32,
    /// Slope through the valid events, Q23 counts per µs.
    slope: i32,
    /// Count and time of the previous sample.
    last: Option<(i32, Instant)>,
}

impl EdgeInterpolator {
    /// No edges seen yet.
    pub const fn new() -> EdgeInterpolator {
        EdgeInterpolator {
            events: [EdgeEvent { at: 0, t: 0 }; RING],
            head: 0,
            valid: 0,
            dir: 0,
            slope: 0,
            last: None,
        }
    }

    /// The position was declared to be `offset` counts further (homing): move the history with
    /// it, so the slope survives.
    pub fn shift(&mut self, offset: i32) {
        for e in &mut self.events {
            e.at = e.at.saturating_add(offset);
        }
        if let Some((c, t)) = self.last {
            self.last = Some((c.saturating_add(offset), t));
        }
    }

    /// One sample: the extended count, the board's µs since the count last changed, the
    /// sample time. Returns the position in Q16 counts, within `[count, count + 1)`. Total:
    /// no panic, no wrap, whatever the inputs.
    pub fn update(&mut self, now: Instant, count: i32, age_us: u16) -> i64 {
        (i64::from(count) << 16) + i64::from(self.update_fraction(now, count, age_us))
    }

    /// As [`EdgeInterpolator::update`], the position's fraction of a count above `count`, Q16
    /// (what the speed filter takes).
    /// `#[inline(always)]`: once a tick, in the control tick (the core is built at opt-level "z",
    /// where the call and its arguments cost ≈ 20 instructions; docs/qemu.md).
    #[inline(always)]
    pub fn update_fraction(&mut self, now: Instant, count: i32, age_us: u16) -> u16 {
        if let Some((prev, prev_t)) = self.last {
            if prev != count {
                // The latest change happened after the previous sample: an age beyond that is
                // a stale capture (or a wrapped timer), so clamp it.
                let age = u32::from(age_us).min(now.micros_since(prev_t));
                let up = count > prev;
                let at = if up { count } else { count.saturating_add(1) };
                self.record(
                    EdgeEvent {
                        at,
                        t: now.0.wrapping_sub(age),
                    },
                    if up { 1 } else { -1 },
                );
            }
        }
        self.last = Some((count, now));
        if self.valid == 0 {
            return 0;
        }
        let newest = self.events[self.head];
        let age = now.0.wrapping_sub(newest.t).min(AGE_MAX);
        // The edge relative to the count (0 counting up, 1 down; anything after a glitch),
        // plus slope × age: |slope| < 2^31, age ≤ 2^20, one 64-bit product.
        let p = (i64::from(newest.at) - i64::from(count)) * 65536
            + ((i64::from(self.slope) * i64::from(age)) >> (SLOPE_FRAC - 16));
        p.clamp(0, 0xFFFF) as u16
    }

    fn record(&mut self, e: EdgeEvent, dir: i32) {
        // A reversal, or a pause longer than the span: the older events do not count (after a
        // pause every one of them is out of the span, being older than the newest). The kept
        // events are then at most EVENTS − 1 spans apart, so the µs clock's wrap (71 min)
        // cannot alias an old event into the span.
        let newest = self.events[self.head];
        if dir != self.dir || e.t.wrapping_sub(newest.t) > SPAN_US {
            self.valid = 0;
            self.dir = dir;
        }
        self.head = (self.head + 1) & (RING - 1);
        self.events[self.head] = e;
        self.valid = (self.valid + 1).min(EVENTS);
        // The oldest valid event within the span: times grow toward the newest, so search from
        // the oldest; in steady motion the first one checked is it.
        let mut slope = 0;
        let mut k = self.valid - 1;
        while k > 0 {
            let o = self.events[self.head.wrapping_sub(k) & (RING - 1)];
            let dt = e.t.wrapping_sub(o.t);
            if dt <= SPAN_US {
                // 0 < dt ≤ SPAN_US < 2^31; |dp| ≤ 255 so dp · 2^23 fits an i32.
                let dp = (i64::from(e.at) - i64::from(o.at))
                    .clamp(-SPAN_COUNTS_MAX, SPAN_COUNTS_MAX) as i32;
                if dt > 0 {
                    slope = (dp << SLOPE_FRAC) / dt as i32;
                }
                break;
            }
            k -= 1;
        }
        self.slope = slope;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// The float64 twin: the same events and slope in f64 counts and µs.
    #[derive(Default)]
    struct Twin {
        events: Vec<(f64, f64)>,
        dir: i32,
        slope: f64,
        last: Option<(i32, f64)>,
    }

    impl Twin {
        fn update(&mut self, now: f64, count: i32, age: f64) -> f64 {
            if let Some((prev, prev_t)) = self.last {
                if prev != count {
                    let age = age.min(now - prev_t);
                    let dir = if count > prev { 1 } else { -1 };
                    let at = if dir > 0 { count } else { count + 1 };
                    if dir != self.dir {
                        self.events.clear();
                        self.dir = dir;
                    }
                    let t = now - age;
                    self.events.push((f64::from(at), t));
                    if self.events.len() > EVENTS {
                        self.events.remove(0);
                    }
                    let n = self.events.len();
                    let oldest = (0..n - 1)
                        .rev()
                        .take_while(|&i| t - self.events[i].1 <= f64::from(SPAN_US))
                        .last();
                    self.slope = match oldest {
                        Some(i) if t > self.events[i].1 => {
                            (f64::from(at) - self.events[i].0) / (t - self.events[i].1)
                        }
                        _ => 0.0,
                    };
                }
            }
            self.last = Some((count, now));
            let base = f64::from(count);
            match self.events.last() {
                None => base,
                Some(&(at, t)) => {
                    (at + self.slope * (now - t)).clamp(base, base + 65535.0 / 65536.0)
                }
            }
        }
    }

    /// Board and sim: the count and edge age at a tick for a shaft at `pos(t)` counts, edges
    /// timed to `res` µs.
    fn sample(pos: &dyn Fn(f64) -> f64, t: f64, prev_t: f64, res: f64) -> (i32, u16) {
        let count = pos(t).floor();
        // Latest crossing in (prev_t, t] by bisection on the count.
        let (mut lo, mut hi) = (prev_t, t);
        if pos(prev_t).floor() == count {
            return (count as i32, 0);
        }
        for _ in 0..60 {
            let mid = 0.5 * (lo + hi);
            if pos(mid).floor() == count {
                hi = mid;
            } else {
                lo = mid;
            }
        }
        let age = (t / res).floor() - (hi / res).floor();
        (count as i32, (age * res) as u16)
    }

    fn run(pos: &dyn Fn(f64) -> f64, ticks: u32, res: f64) -> Vec<(f64, f64)> {
        let mut e = EdgeInterpolator::new();
        let mut out = Vec::new();
        for k in 0..ticks {
            let t = f64::from(k) * 1000.0;
            let (count, age) = sample(pos, t, (t - 1000.0).max(0.0), res);
            let p = e.update(Instant(t as u32), count, age);
            out.push((pos(t), p as f64 / 65536.0));
        }
        out
    }

    #[test]
    fn creeping_position_is_exact_to_the_capture_resolution() {
        // 0.09 counts per ms (0.2 rad/s of screw): the bare count is up to a count off.
        let v = 0.0917 / 1000.0;
        let out = run(&|t| 3.3 + v * t, 400, 1.0);
        let worst = out[60..]
            .iter()
            .map(|(x, p)| (x - p).abs())
            .fold(0.0, f64::max);
        assert!(worst < 0.002, "{worst} counts");
    }

    #[test]
    fn counts_per_tick_near_one_are_interpolated() {
        for v in [0.92, 0.98, 1.07, 2.3] {
            let out = run(&|t| -7.9 + v * t / 1000.0, 200, 1.0);
            let worst = out[20..]
                .iter()
                .map(|(x, p)| (x - p).abs())
                .fold(0.0, f64::max);
            assert!(worst < 0.01, "{v} counts/tick: {worst}");
        }
    }

    #[test]
    fn lowering_uses_the_upper_edge_of_the_count() {
        let v = -0.3 / 1000.0;
        let out = run(&|t| 100.2 + v * t, 300, 1.0);
        let worst = out[40..]
            .iter()
            .map(|(x, p)| (x - p).abs())
            .fold(0.0, f64::max);
        assert!(worst < 0.003, "{worst}");
    }

    #[test]
    fn a_stopping_shaft_is_never_more_than_a_count_off() {
        // Decelerates to rest, then reverses.
        let pos = |t: f64| {
            let s = t / 1000.0;
            20.0 + 0.5 * s - 0.004 * s * s
        };
        let out = run(&pos, 250, 1.0);
        for (x, p) in out {
            assert!((x - p).abs() < 1.0, "{x} vs {p}");
            assert!(p >= x.floor() && p < x.floor() + 1.0, "{x} vs {p}");
        }
    }

    #[test]
    fn without_edge_capture_edges_are_timed_to_the_tick() {
        // Age always 0: a tick's worth of error at most, far less than a count when creeping.
        let v = 0.0917 / 1000.0;
        let mut e = EdgeInterpolator::new();
        let mut worst: f64 = 0.0;
        for k in 0..400u32 {
            let t = f64::from(k) * 1000.0;
            let x = 3.3 + v * t;
            let p = e.update(Instant(t as u32), x.floor() as i32, 0) as f64 / 65536.0;
            if k > 60 {
                worst = worst.max((x - p).abs());
            }
        }
        assert!(worst < 0.1, "{worst}");
    }

    #[test]
    fn stale_ages_are_clamped_to_the_previous_sample() {
        let mut e = EdgeInterpolator::new();
        e.update(Instant(0), 10, 0);
        // An edge "65 ms ago" cannot be newer than the sample 1 ms ago.
        let p = e.update(Instant(1000), 11, 65_000);
        assert_eq!(p, 11 << 16);
        assert_eq!(e.events[e.head].t, 0);
    }

    #[test]
    fn homing_shifts_the_history() {
        let v = 0.5 / 1000.0;
        let mut e = EdgeInterpolator::new();
        let mut f = e.clone();
        let mut a = 0;
        let mut b = 0;
        for k in 0..100u32 {
            let t = f64::from(k) * 1000.0;
            let x = v * t;
            if k == 50 {
                f.shift(1000);
            }
            let off = if k >= 50 { 1000 } else { 0 };
            a = e.update(Instant(t as u32), x.floor() as i32, 0);
            b = f.update(Instant(t as u32), x.floor() as i32 + off, 0);
        }
        assert_eq!(b - a, 1000 << 16);
    }

    #[test]
    fn a_pause_longer_than_the_span_restarts_the_slope_as_the_twin_does() {
        // Moving, a 0.25 s stop, moving again at another speed, the µs clock wrapping in the
        // pause: the fixed point forgets the events before the pause, the twin skips them
        // as out of span; both give the same positions.
        let mut e = EdgeInterpolator::new();
        let mut twin = Twin::default();
        let t0 = u32::MAX - 150_000;
        let mut x: f64 = 10.0;
        for k in 0..700u32 {
            let v = match k {
                0..200 => 0.37,
                200..450 => 0.0,
                _ => -0.61,
            };
            x += v;
            let t = f64::from(t0) + f64::from(k) * 1000.0;
            let p = e.update(Instant((t as u64 % (1 << 32)) as u32), x.floor() as i32, 0);
            let q = twin.update(t, x.floor() as i32, 0.0);
            // The proptest's budget: the slope's truncation grows 1 LSB per 128 µs of age.
            let since = twin.events.last().map_or(0.0, |&(_, te)| t - te);
            let budget = (1.5 + since / 128.0) / 65536.0;
            assert!((p as f64 / 65536.0 - q).abs() <= budget, "{k}: {p} vs {q}");
        }
    }

    proptest! {
        /// The fixed-point interpolator agrees with its float64 twin on any sequence of counts
        /// and ages (random walks, reversals, stale ages, the µs clock wrapping) within its
        /// error budget: 1 LSB of Q16 for the final truncation, plus the slope's truncation
        /// (< 2^−23 counts/µs) times the age, i.e. 1 LSB per 128 µs since the last edge (a
        /// 0.001-count error after 11 ms, the longest edge interval when creeping).
        #[test]
        fn interpolator_matches_float_twin(
            steps in proptest::collection::vec((-3i32..=3, 0u16..=3000, 500u32..=1500), 1..300),
            start in -100_000i32..100_000,
            t0 in any::<u32>(),
        ) {
            let mut e = EdgeInterpolator::new();
            let mut twin = Twin::default();
            let mut count = start;
            let mut t = f64::from(t0);
            for (d, age, dt) in steps {
                count += d;
                t += f64::from(dt);
                let p = e.update(Instant((t as u64 % (1u64 << 32)) as u32), count, age);
                let q = twin.update(t, count, f64::from(age));
                let since = twin.events.last().map_or(0.0, |&(_, te)| t - te);
                let budget = (1.0 + since / 128.0 + 0.5) / 65536.0;
                prop_assert!((p as f64 / 65536.0 - q).abs() <= budget,
                    "{} vs {}", p as f64 / 65536.0, q);
            }
        }
    }
}
