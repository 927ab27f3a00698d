//! Stick-slip detector: one step per control tick on board-visible signals only.
//!
//! **What it sees.** While the screw sticks and the motor keeps turning (the speed loop holds
//! the gear output at the reference), the coupling winds up and the torque the motor delivers
//! rises at k·θ̇_i; when static friction lets go the screw slips in a fraction of a millisecond,
//! the coupling unwinds and the motor torque falls by about k·Δ(θ − θ_i). The board measures
//! that torque through the motor current ([`crate::estimator::Estimate::measured_screw_torque`]):
//! stick-slip is a sawtooth of it, each *slip* a sudden fall. Smooth sliding has a flat torque.
//!
//! **How.** The measured torque, projected on the direction of travel (positive resists the
//! motion), is averaged over 4 ticks; a leaky peak follows its rises and sags by
//! `threshold/16` per tick, so slow falls (the load changing with the arm angle) never count.
//! A *slip* is a fall of the average below the peak by at least `drop_threshold`, or twice
//! the torque's noise level if that is more (an EWMA of the clipped |second difference|:
//! a steady wind-up ramp has none, the ADC noise does); a slip lasts until its fall has made no
//! new low for 8 ms, and its size is the amplitude estimate, the coupling-torque drop per
//! slip in N·m (divide by k for the twist). Slips closer together than `window_ms` form a
//! chain; a chain of 2 slips (3 where the model says the operating point is on a rising branch
//! of μ(θ̇)) raises the flag and counts an episode. Fast stick-slip (periods of 5–16 ms), whose
//! ripple the motor's electromechanical lag shrinks below any safe drop threshold, is found by
//! its periodicity instead ([`Periodicity`]). The flag falls when no slip came for four of the
//! last slip intervals (at least 250 ms, at most `window_ms`) or when the motion ends; a chain
//! within `window_ms` of that fall raises it again as the same episode (no new onset).
//!
//! **When.** Only while the bridge drives a motion at a steady reference speed, from 25 ms
//! after the reference last changed: the end of a ramp moves the motor current by the rotor's
//! inertia torque (≈ 9 N·m at the screw for the default 60 ms ramp to 3 rad/s), the braking at
//! the end of a move drops it to zero, and a screw that breaks away from rest on the start
//! ramp (creeping, the wind-up takes 30–40 ms) sets the speed loop ringing; none of them is a
//! slip.
//!
//! **The model's part.** On the falling branch of μ(θ̇) (dμ/dθ̇ < 0 at the reference speed) the
//! friction adds negative damping and sliding is unstable: two slips suffice. On a rising
//! branch the model predicts smooth sliding, so the detector asks for a third slip before it
//! believes the current (a lubricant that wore off still shows up, one slip later).
//!
//! Everything is integer: Q16 N·m, tick counters; no division on the hot path. The float64
//! twins and the property tests that hold this to them are in this module's tests.

use crate::keys::{self, check_bounds, Bound, ConfigError};
use crate::math::div_pow2_i64;
use crate::model::friction::CompiledLaw;
use crate::units::{NewtonMetres, RadiansPerSecond, Ratio, Q};

/// What the controller does when an episode starts.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Reaction {
    /// Report the episode in the log (an [`crate::control::Event::StickSlip`]) and the status.
    Log,
    /// As `Log`, and the event asks for a warning line on the console.
    #[default]
    Warn,
    /// As `Warn`, and the rest of the motion runs at `escape_speed` to leave the stick-slip
    /// region (the next motion starts at the configured cruise speed again).
    ChangeSpeed,
}

impl Reaction {
    /// Name for logs and the console.
    pub fn name(self) -> &'static str {
        match self {
            Reaction::Log => "log",
            Reaction::Warn => "warn",
            Reaction::ChangeSpeed => "speed",
        }
    }
}

/// The detector's settings (console keys `stickslip.*`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct StickSlipConfig {
    /// What to do when an episode starts.
    pub reaction: Reaction,
    /// Smallest fall of the measured screw torque (4-tick mean) that counts as a slip,
    /// 0.2…50 N·m.
    pub drop_threshold: NewtonMetres,
    /// Slips further apart than this start a new chain, 100…10 000 ms.
    pub window_ms: u32,
    /// Cruise screw speed for the rest of a motion once an episode started (reaction
    /// `speed`), 0.2…20 rad/s.
    pub escape_speed: RadiansPerSecond,
}

impl StickSlipConfig {
    /// Warn; 0.5 N·m (tuned on the scored set's tuning seed, once the speed loop's ripple at
    /// encoder-limited speeds was gone, docs/stick-slip.md); a 2 s chain window (the slowest
    /// stick-slip seen in host-sim, dry at 0.3 rad/s and rated load, cycles every 0.8 s);
    /// escape at 1.5 rad/s.
    pub const DEFAULT: StickSlipConfig = StickSlipConfig {
        reaction: Reaction::Warn,
        drop_threshold: NewtonMetres::lit("0.5"),
        window_ms: 2000,
        escape_speed: RadiansPerSecond::lit("1.5"),
    };

    /// Check the ranges (one constant table, `crate::keys::check_bounds`).
    pub fn validate(&self) -> Result<(), ConfigError> {
        static BOUNDS: [Bound; 3] = [
            Bound::new(
                NewtonMetres::lit("0.2").to_bits(),
                NewtonMetres::lit("50").to_bits(),
                &keys::STICKSLIP_DROP,
            ),
            // A `u32` above `i32::MAX` wraps negative: refused like any value below 100.
            Bound::new(100, 10_000, &keys::STICKSLIP_WINDOW_MS),
            Bound::new(
                RadiansPerSecond::lit("0.2").to_bits(),
                RadiansPerSecond::lit("20").to_bits(),
                &keys::STICKSLIP_ESCAPE_SPEED,
            ),
        ];
        check_bounds(
            [
                self.drop_threshold.to_bits(),
                self.window_ms as i32,
                self.escape_speed.to_bits(),
            ],
            &BOUNDS,
        )
    }
}

/// Settling after the reference last changed (the end of the start ramp, every tick of any
/// ramp) before slips count, ms: at the end of a ramp the motor current moves by the rotor's
/// inertia torque (≈ 9 N·m at the screw for the default ramp) and the speed loop's transient
/// dies out within ≈ 25 ms (host-sim). Nothing counts during a ramp: starting at creep speed
/// (0.2–0.3 rad/s) the coupling winds up for 30–40 ms before the screw breaks away from rest,
/// on the ramp, and the speed loop then rings by 1–3 N·m for ≈ 50 ms at 12–15 ms per swing
/// (encoder edges 10 ms apart): a breakaway and two swings made a "chain" on smooth runs.
pub const SETTLE_MS: u32 = 25;
/// Tolerance on the reference's change per tick that still counts as a steady speed, Q16 rad/s
/// per tick (the profile's rounding moves it by 1 LSB; the slowest valid ramp, 0.2 rad/s in
/// 2 s, changes it by 6).
const ACCEL_TOL: i32 = 2;
/// A slip lasts until its fall has made no new low for this long; no new slip starts
/// meanwhile, ms.
pub const EVENT_MS: u32 = 8;
/// The flag holds at least this long after the last slip, ms.
pub const MIN_HOLD_MS: u32 = 250;
/// Length of the torque mean, ticks (a power of two).
const MEAN_LEN: usize = 4;
/// log2 of [`MEAN_LEN`]: the mean divides by a shift ([`div_pow2_i64`], the same as `/`).
const MEAN_SHIFT: u32 = MEAN_LEN.trailing_zeros();
const _: () = assert!(MEAN_LEN.is_power_of_two() && MEAN_SHIFT >= 1);

/// What the detector needs each tick.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct DetectorInputs {
    /// The bridge drives a commanded motion.
    pub driving: bool,
    /// Direction of travel: +1 lifting, −1 lowering.
    pub direction: i8,
    /// Reference screw speed of this tick.
    pub reference: RadiansPerSecond,
    /// Screw torque the motor delivers, from its current.
    pub measured_torque: NewtonMetres,
}

/// The detector's report for one tick.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct StickSlipOutput {
    /// An episode is under way.
    pub active: bool,
    /// The episode started this tick.
    pub onset: bool,
    /// A slip was detected this tick.
    pub slip: bool,
    /// Coupling-torque drop of the last slip (peak-to-trough of the 4-tick mean), N·m.
    pub amplitude: NewtonMetres,
    /// Episodes since boot.
    pub episodes: u32,
    /// The model puts the operating point on a falling branch of μ(θ̇).
    pub falling_branch: bool,
}

/// Configuration (quantised to ticks) and state.
#[derive(Clone, Debug)]
pub struct StickSlipDetector {
    threshold: i32,
    leak: i32,
    /// Least autocorrelation of a periodic torque, Q16 N·m² per tick².
    per_min: i64,
    window_ticks: u32,
    settle_ticks: u32,
    event_ticks: u32,
    min_hold_ticks: u32,
    // State.
    ring: [i32; MEAN_LEN],
    head: usize,
    sum: i64,
    filled: usize,
    prev_reference: i32,
    steady: u32,
    peak: i32,
    in_event: u32,
    event_drop: i32,
    since_slip: u32,
    interval: u32,
    chain: u32,
    falling: bool,
    /// The branch test in halves on the two ticks before the one that arms it, one law
    /// evaluation each (two on one tick put the control tick over its instruction budget): on the tick with
    /// `steady + 2 == settle_ticks` the speed above the reference speed v and μ(v), on the
    /// next one the answer, used on the next one again.
    branch_above: (RadiansPerSecond, Ratio),
    branch_next: bool,
    /// Ticks since the flag last fell in this motion (`u32::MAX`: not yet).
    since_fall: u32,
    /// Fast-periodic test and its run of periodic ticks.
    periodicity: Periodicity,
    periodic_run: u32,
    /// Σ of the slips' peaks (the 4-tick mean torque resisting the motion before each fall:
    /// the breakaway torque) and their count, since boot (`Controller::stick_slip_lift`).
    breakaway_sum: i64,
    breakaways: u32,
    /// Last two torques (for the second difference) and the noise level: EWMA (1/64) of
    /// |second difference|, each sample clipped at 4× the level so slips barely move it, Q16.
    last: [i32; 2],
    noise: i32,
    out: StickSlipOutput,
}

/// Shortest period the periodicity test claims, ticks (5 ms: the truth's shortest significant
/// cycle; beyond 16 ms the slips are slow enough for the drop test).
pub const LAG_MIN: usize = 5;
/// Longest lag of the periodicity test, ticks.
pub const LAG_MAX: usize = 16;
/// The lag below the shortest period: faster stick-slip (micro stick-slip with periods of
/// 2.5–4.5 ms: by definition not an episode, however large its drops) correlates better at
/// this lag than at LAG_MIN, and is vetoed.
pub const LAG_FAST: usize = LAG_MIN - 1;
/// Lags kept, LAG_FAST…LAG_MAX.
const LAGS: usize = LAG_MAX - LAG_FAST + 1;
/// Weight of the autocorrelation EWMAs: 2^−PER_SHIFT per tick (256 ticks: the normalised
/// autocorrelation of white noise then stays within ≈ ±0.05 of zero). The lags are updated on
/// alternate ticks (half of them each tick), each by 2^−(PER_SHIFT − 1): the same time
/// constant at half the cost.
const PER_SHIFT: u32 = 8;
/// |filtered torque| clip, Q16 N·m (64 N·m), so the products stay in i32 (h kept in Q8).
const DIFF_CLIP: i32 = 64 << 16;
/// Torque clip of the periodicity filter, Q16 N·m (±8192 N·m: 80× the motor's largest torque at
/// the screw; nothing real is clipped).
const X_CLIP: i32 = (1 << 29) - 1;
/// Periodic: the best lag's autocorrelation of the filtered torque is at least PER_NUM/PER_DEN
/// (0.35) of its power. White noise reaches 0.3 for 48 ticks now and then: each lag's EWMA sees
/// half the ticks, so its ratio to the power scatters by ≈ 0.08, and a 4 s creeping run has
/// 13 lags × ≈ 15 independent windows of it (a smooth run of the tuning seeds alarmed at 0.3;
/// a float model of the test over their 320 runs puts the longest periodic run on a smooth
/// run at 36 ticks at 0.3, 18 at 0.35, and loses one of 20 fast episodes it found)…
const PER_NUM: i32 = 7;
const PER_DEN: i32 = 20;
/// …and at least (drop threshold / 5)², 0.01 N·m² at 0.5 N·m. With the veto of periods
/// under 5 ms (LAG_FAST) the micro stick-slip that held the first version at 0.04 is gone;
/// seeds 1, 2, 3 and 7 (256 runs) have no false alarm anywhere between 0.006 and 0.02, and the
/// smallest significant fast stick-slip (1.0 N·m drops every 7 ms) reaches 0.021.
const PER_MIN_NUM: i64 = 1;
const PER_MIN_DEN: i64 = 5;
/// Periodic this many ticks in a row raises the flag (48: smooth and micro runs of seeds 1, 2,
/// 3, 7 reach 30 at most over their whole motion, fast stick-slip episodes ≥ 86).
const PER_TICKS: u32 = 48;
/// The lag of the harmonic veto: a period of ≈ 3 ticks (micro stick-slip, lifting dry at
/// 5–6 rad/s: 2–3 N·m drops every 2.9 ms) correlates at its multiples 6, 9, 12 and 15 as well,
/// and lag LAG_FAST (1.4 periods) and LAG_MIN (1.7) not at all, so the veto below misses it;
/// lag 3 (one period) then correlates better than the best lag. For a period of 5–16 ticks lag
/// 3 is 0.2–0.6 of a period (≤ 0.38 of the best lag's correlation) and white noise adds a
/// quarter of h's power to it (h = x − x₋₁ − x₋₂ + x₋₃ is correlated with h₋₃ by +σ², its
/// power 4σ²), which the fraction test already bounds (≤ 2.3× the best lag's correlation:
/// 0.38 + 0.58 < 1).
pub const LAG_HARMONIC: usize = 3;
/// A period under LAG_MIN (≈ 4.5 ticks and less): lag LAG_FAST correlates better than lag
/// LAG_MIN, or at least 1/FAST_VETO as well as the best lag. For a sine (the ripple after the
/// motor's lag) of 5.2 ticks c₄/c₅ = 0.12, of 3.7 ticks c₄ > 0 > c₅; micro stick-slip of 3.7 ms
/// in the scored sets' noise keeps c₄ − c₅ ≥ 0.14 c₀, of 4.2 ms it needs the second test.
/// A period near 4 ticks makes c₄ positive: where c₄ ≤ 0 the first test does not apply (a
/// sharp 7-tick sawtooth through the motor's lag has c₄ ≈ c₅ ≈ −0.4 c₀, and the order of the
/// two flipped with the noise).
const FAST_VETO: i32 = 2;

/// Autocorrelation of the high-passed torque h = x − x₋₁ − x₋₂ + x₋₃ at lags LAG_FAST…LAG_MAX:
/// fast stick-slip (periods of 5–16 ms, lowering dry) reaches the current through the motor's
/// 3.4 ms electromechanical lag as a ripple of a few tenths of a N·m, below any safe drop
/// threshold, but strictly periodic. White noise is not (h is correlated at lags ≤ 3 only);
/// the filter's double zero at DC removes the load's slow changes and the coupling's wind-up
/// ramps, its zero at 500 Hz the current dithering between two ADC codes (period 2), both of
/// which are periodic too. Gain at 137 Hz (a 7.3 ms period): 1.26.
///
/// Periodic = the best of lags LAG_MIN…LAG_MAX reaches the power and fraction thresholds, and
/// lag LAG_FAST correlates less than lag LAG_MIN and less than a FAST_VETO-th of the best (else
/// the period is under ≈ 4.5 ticks: micro stick-slip by the truth's definition, however large
/// its ripple). Cost: one product per tick for the power, half the
/// 13 lags per tick (alternate ticks), the decision on every other tick.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Periodicity {
    /// The last three torques, newest first.
    x: [i32; 3],
    /// Filtered values, a doubled power-of-two ring: each value is stored at `head` and
    /// `head + HIST_LEN`, so the LAG_MAX values before the newest are one contiguous window.
    hist: [i32; 2 * HIST_LEN],
    head: usize,
    filled: usize,
    /// Ticks the EWMAs have run: no decision before they have settled (2^PER_SHIFT).
    seen: u32,
    /// Which half of the lags this tick updates (and whether it decides).
    odd: bool,
    /// The last decision (held over the tick that does not decide).
    periodic: bool,
    /// The best of the lags updated on the even tick (the odd tick adds its own and decides).
    best_even: i32,
    /// EWMAs of h² and h·h₋ₗ (c[0]: lag LAG_FAST), Q16 N·m², from h kept in Q8 (1/256 N·m, a
    /// 17th of one current-sense code at the screw): |h| ≤ 2^14 after the clip, so every
    /// product is one 32-bit multiply and every EWMA stays within ±2^28.
    c0: i32,
    c: [i32; LAGS],
    /// EWMA of h·h₋₃ (LAG_HARMONIC), updated on the odd ticks.
    c3: i32,
}

/// Length of the periodicity history ring (≥ LAG_MAX + 1, a power of two).
const HIST_LEN: usize = 32;

impl Periodicity {
    /// The period of the torque's fast cycles, Q8 ticks, while the test finds it periodic: the
    /// best of lags LAG_MIN…LAG_MAX, or a lag three or two of whose cycles are within a lag of
    /// it correlate positively, at least two fifths as well (the best of them; a cycle of P ticks
    /// correlates at 2P and 3P as well, up to 16, and better where they are nearer a whole lag:
    /// 5.6 ticks correlated at 11 twice as well as at 5; half a period correlates negatively),
    /// refined by the parabola through it and its neighbours. `None` when not periodic. At the status, not in
    /// the tick (a division).
    pub fn period_q8(&self) -> Option<i32> {
        if !self.periodic {
            return None;
        }
        let c = &self.c;
        let k = self.period_lag();
        let lag = (LAG_FAST + k) as i64;
        if k + 1 >= LAGS {
            // The last lag: the edge of a cycle as long or longer (the slow reading's).
            return None;
        }
        let (a, b, d) = (i64::from(c[k - 1]), i64::from(c[k]), i64::from(c[k + 1]));
        // Vertex of the parabola: δ = (a − d)/(2·(a − 2b + d)) ∈ [−½, ½] at a local maximum.
        let den = 2 * (a - 2 * b + d);
        let delta_q8 = if den < 0 { ((a - d) << 8) / den } else { 0 };
        i32::try_from((lag << 8) + delta_q8.clamp(-128, 128)).ok()
    }

    /// [`Self::period_q8`]'s lag (index k: lag LAG_FAST + k) before its refinement: the best of
    /// lags LAG_MIN… (index 1…; index 0 is the veto's lag), or the strongest lag, positive and
    /// of at least two fifths of the best, whose `d` cycles are within a lag of the best's:
    /// three cycles first, then two. The last of equals, as `max_by_key` (loops, not iterator
    /// chains: 124 B of flash less).
    fn period_lag(&self) -> usize {
        let c = &self.c;
        let mut kb = 1;
        for k in 2..LAGS {
            if c[k] >= c[kb] {
                kb = k;
            }
        }
        let best = i64::from(c[kb]);
        let lb = LAG_FAST + kb;
        for d in [3, 2] {
            if lb < d * LAG_MIN {
                continue;
            }
            let mut found: Option<usize> = None;
            for j in 1..LAGS - 1 {
                if ((LAG_FAST + j) * d).abs_diff(lb) <= 1
                    && c[j] > 0
                    && i64::from(c[j]) * 5 >= best * 2
                    && found.is_none_or(|f| c[j] >= c[f])
                {
                    found = Some(j);
                }
            }
            if let Some(j) = found {
                return j;
            }
        }
        kb
    }
}

impl Default for Periodicity {
    fn default() -> Self {
        Periodicity::new()
    }
}

impl Periodicity {
    /// Nothing seen yet.
    pub const fn new() -> Periodicity {
        Periodicity {
            x: [0; 3],
            hist: [0; 2 * HIST_LEN],
            head: 0,
            filled: 0,
            seen: 0,
            odd: false,
            periodic: false,
            best_even: i32::MIN,
            c0: 0,
            c: [0; LAGS],
            c3: 0,
        }
    }

    /// Forget everything. The history ring (and where its head is) stays as it is: after a
    /// reset the ring is read only once LAG_MAX + 1 new values have been written (`filled`),
    /// so no old value is ever seen, and clearing its 64 words (a `memclr`) was ≈ 380
    /// instructions on the control tick that reset. The EWMAs are zeroed when they
    /// start (`step`), not here: the tick that resets is often a busy one (a stop).
    pub fn reset(&mut self) {
        let Periodicity {
            x,
            hist: _,
            head: _,
            filled,
            seen,
            odd,
            periodic,
            best_even,
            c0: _,
            c: _,
            c3: _,
        } = self;
        *x = [0; 3];
        *filled = 0;
        *seen = 0;
        *odd = false;
        *periodic = false;
        *best_even = i32::MIN;
    }

    /// One torque sample, Q16 N·m. Returns whether the torque is periodic now (the EWMAs start
    /// once the history holds 3 torques and LAG_MAX filtered values, and decide after
    /// 2^PER_SHIFT ticks). Out of line and compiled for size: 30 B less than for speed and no
    /// measurable cost on the control tick (docs/qemu.md "Optimisation level").
    #[inline(never)]
    pub fn step(&mut self, x: i32, min_power: i64) -> bool {
        // Torques clipped to ±X_CLIP, so the filter is exact in i32 (|h| < 4 · 2^29).
        let x = x.clamp(-X_CLIP, X_CLIP);
        let d = (x - self.x[0] - self.x[1] + self.x[2]).clamp(-DIFF_CLIP, DIFF_CLIP);
        self.x = [x, self.x[0], self.x[1]];
        if self.filled < 3 {
            self.filled += 1;
            return false;
        }
        let h = d >> 8; // Q8, |h| ≤ 2^14

        self.head = (self.head + 1) & (HIST_LEN - 1);
        self.hist[self.head] = h;
        self.hist[self.head + HIST_LEN] = h;
        if self.filled <= LAG_MAX + 3 {
            if self.filled == LAG_MAX + 3 {
                // The EWMAs start on the next tick: from zero (`reset` leaves them).
                self.c0 = 0;
                self.c = [0; LAGS];
                self.c3 = 0;
            }
            self.filled += 1;
            return false;
        }
        self.c0 += (h * h - self.c0) >> PER_SHIFT;
        // w[LAG_MAX - l] = h₋ₗ for l = 0…LAG_MAX (head + HIST_LEN − LAG_MAX ≥ 16: in range).
        let at = self.head + HIST_LEN - LAG_MAX;
        let Some(w) = self
            .hist
            .get(at..=at + LAG_MAX)
            .and_then(|w| <&[i32; LAG_MAX + 1]>::try_from(w).ok())
        else {
            return false;
        };
        // One lag's EWMA (index k: lag LAG_FAST + k), its new value. Written out per lag below:
        // constant indices, no loop.
        let c = &mut self.c;
        let mut lag = |k: usize| {
            let v = c[k] + ((h * w[LAG_MAX - LAG_FAST - k] - c[k]) >> (PER_SHIFT - 1));
            c[k] = v;
            v
        };
        self.odd = !self.odd;
        if self.odd {
            self.c3 += (h * w[LAG_MAX - LAG_HARMONIC] - self.c3) >> (PER_SHIFT - 1);
            // Lags 5, 7, …, 15, with the best of the even tick's 6, 8, …, 16.
            let best = lag(1)
                .max(lag(3))
                .max(lag(5))
                .max(lag(7))
                .max(lag(9))
                .max(lag(11))
                .max(self.best_even);
            self.seen = self.seen.saturating_add(2);
            self.periodic = self.seen >= 1 << PER_SHIFT
                && i64::from(best) >= min_power
                && i64::from(best) * i64::from(PER_DEN) >= i64::from(PER_NUM) * i64::from(self.c0)
                && (self.c[0] < self.c[1] || self.c[0] <= 0)
                && self.c[0].saturating_mul(FAST_VETO) < best
                && self.c3 < best;
        } else {
            // Lag 4 (the veto's), then 6, 8, …, 16.
            lag(0);
            self.best_even = lag(2)
                .max(lag(4))
                .max(lag(6))
                .max(lag(8))
                .max(lag(10))
                .max(lag(12));
        }
        self.periodic
    }
}

/// Weight of the noise EWMA: 2^−NOISE_SHIFT per tick.
const NOISE_SHIFT: u32 = 6;
/// The slip threshold is at least this many times the noise level (|second difference| of white
/// noise averages 1.95 σ; the 4-tick mean has σ/2, so 2× is ≈ 8 σ of the mean).
const NOISE_GAIN: i32 = 2;

impl StickSlipDetector {
    /// A detector for a validated configuration at a tick of `tick_us` µs (100…10 000). Out
    /// of line (16 B less than inlined into `Controller::new`).
    #[inline(never)]
    pub fn new(cfg: &StickSlipConfig, tick_us: u32) -> StickSlipDetector {
        let ticks = |ms: u32| crate::units::ms_to_ticks(ms, tick_us).max(1);
        let threshold = cfg.drop_threshold.to_bits().max(1);
        StickSlipDetector {
            threshold,
            leak: (threshold / 16).max(1),
            per_min: {
                let t = i64::from(threshold) * PER_MIN_NUM / PER_MIN_DEN;
                (t * t >> 16).max(1)
            },
            window_ticks: ticks(cfg.window_ms),
            // ≥ MEAN_LEN: the armed path (and its branch test, on the tick with
            // `steady == settle_ticks`) waits for the mean anyway, and the test's two halves
            // run on the two ticks before (a tick over 6.25 ms used to skip the test).
            settle_ticks: ticks(SETTLE_MS).max(MEAN_LEN as u32),
            event_ticks: ticks(EVENT_MS),
            min_hold_ticks: ticks(MIN_HOLD_MS),
            ring: [0; MEAN_LEN],
            head: 0,
            sum: 0,
            filled: 0,
            prev_reference: 0,
            steady: 0,
            peak: 0,
            in_event: 0,
            event_drop: 0,
            since_slip: u32::MAX,
            interval: 0,
            chain: 0,
            falling: false,
            branch_above: (RadiansPerSecond::ZERO, Ratio::ZERO),
            branch_next: false,
            since_fall: u32::MAX,
            breakaway_sum: 0,
            breakaways: 0,
            periodicity: Periodicity::new(),
            periodic_run: 0,
            last: [0; 2],
            noise: 0,
            out: StickSlipOutput::default(),
        }
    }

    /// The last report.
    pub fn output(&self) -> &StickSlipOutput {
        &self.out
    }

    /// The 4-tick mean of the measured torque resisting the motion (Q16 N·m), as of the last
    /// step (the weighing creep's breakaway peaks, `control::creep`).
    pub fn mean_torque(&self) -> i32 {
        self.ring_mean()
    }

    /// Σ of the slips' peak torques (resisting the motion, Q16 N·m) and their count, since
    /// boot: each slip's peak is the breakaway torque of the stick before it.
    pub fn breakaways(&self) -> (i64, u32) {
        (self.breakaway_sum, self.breakaways)
    }

    /// The fast stick-slip's period, Q8 ticks, while the periodicity test finds the torque
    /// periodic ([`Periodicity::period_q8`]): a stick-slipping lift too fast for its peaks
    /// (`Controller::stick_slip_lift`).
    pub fn fast_period_q8(&self) -> Option<i32> {
        if self.periodic_run < PER_TICKS {
            return None;
        }
        self.periodicity.period_q8()
    }

    /// Forget the motion (keeps the episode counter and the last amplitude).
    fn idle(&mut self) {
        self.ring = [0; MEAN_LEN];
        self.head = 0;
        self.sum = 0;
        self.filled = 0;
        self.prev_reference = 0;
        self.since_fall = u32::MAX;
        // (The periodicity stays until the next motion's first ticks reset it: a fast
        // stick-slip's period is read at rest, `fast_period_q8`.)
        self.last = [0; 2];
        self.steady = 0;
        self.in_event = 0;
        self.since_slip = u32::MAX;
        self.interval = 0;
        self.chain = 0;
        self.out.active = false;
    }

    /// One tick. `law` is the configured friction law (for the branch of μ(θ̇)), the same on
    /// every call of a detector (the branch test's halves run on two successive ticks). Total:
    /// no panic, no wrap, whatever the inputs. Out of line: inlined into
    /// `Controller::step` it took 272 B more flash (docs/qemu.md "Optimisation level").
    #[inline(never)]
    pub fn step(&mut self, x: &DetectorInputs, law: &CompiledLaw) -> StickSlipOutput {
        self.out.onset = false;
        self.out.slip = false;
        if !x.driving || x.direction == 0 {
            self.idle();
            return self.out;
        }
        // Torque resisting the motion, 4-tick mean.
        // (Negated as 0 − t, saturating: one `QSUB`.)
        let t = x.measured_torque.to_bits();
        let p = if x.direction < 0 {
            0i32.saturating_sub(t)
        } else {
            t
        };
        // (The head masked: the index needs no bounds check.)
        let head = self.head & (MEAN_LEN - 1);
        self.sum += i64::from(p) - i64::from(self.ring[head]);
        self.ring[head] = p;
        self.head = (head + 1) & (MEAN_LEN - 1);
        // Noise level from the second difference (a steady ramp — the coupling winding up while
        // stuck — has none); the first samples of a motion only fill the history.
        if self.filled >= 2 {
            // In i32 (saturating: exact for torques within ±8192 N·m, far beyond the motor's).
            let d2 = p
                .saturating_sub(self.last[0])
                .saturating_sub(self.last[0].saturating_sub(self.last[1]))
                .saturating_abs();
            // (threshold ≥ 1: the shift is the division.)
            let cap = times4(self.noise.max(self.threshold >> 2));
            let d2 = d2.min(cap);
            // 0 ≤ noise, d2 < 2^31: the step stays in i32.
            self.noise = self.noise.saturating_add(
                (d2 - self.noise).saturating_add(1 << (NOISE_SHIFT - 1)) >> NOISE_SHIFT,
            );
        }
        self.last = [p, self.last[0]];
        self.filled = (self.filled + 1).min(MEAN_LEN);
        let mean = div_pow2_i64(self.sum, MEAN_SHIFT) as i32; // |sum| ≤ 4·2^31: exact in i32 after /4
        self.since_slip = self.since_slip.saturating_add(1);
        self.since_fall = self.since_fall.saturating_add(1);

        let reference = x.reference.to_bits();
        let accel = reference.saturating_sub(self.prev_reference);
        // A motion's first tick starts a steady run at 0 whatever its reference (so a run
        // passes through every count up to `settle_ticks` on consecutive ticks: the branch
        // test's halves below).
        if reference == 0 || self.filled == 1 || accel.saturating_abs() > ACCEL_TOL {
            self.steady = 0;
        } else {
            self.steady = self.steady.saturating_add(1);
        }
        self.prev_reference = reference;
        // The branch of μ(θ̇) at this tick's speed, in two halves on this tick and the next
        // (neither runs the armed path below), used on the one after: the ticks with
        // `steady` = settle − 2, settle − 1, settle are consecutive steps of one steady run.
        if self.steady.saturating_add(2) == self.settle_ticks {
            let v = x.reference.sat_abs();
            self.branch_above = (v.sat_add(branch_step(v)), law.mu(v));
        } else if self.steady.saturating_add(1) == self.settle_ticks {
            let (above, mu_v) = self.branch_above;
            self.branch_next = law.mu(above) < mu_v;
        }
        if self.steady < self.settle_ticks || self.filled < MEAN_LEN {
            self.peak = mean;
            self.in_event = 0;
            // A fast stick-slip's period outlasts its cruise, through the braking to the
            // motion's end (`Controller::end_load_motion` reads the lift's breakaways then, at
            // rest); a new motion (the ring filling) starts afresh.
            if self.filled < MEAN_LEN || self.periodic_run < PER_TICKS {
                if self.periodicity.filled != 0 {
                    self.periodicity.reset();
                }
                self.periodic_run = 0;
            }
        } else {
            let periodic = self.periodicity.step(p, self.per_min);
            self.periodic_run = if periodic {
                self.periodic_run.saturating_add(1)
            } else {
                0
            };
            if self.periodic_run >= PER_TICKS {
                // Fast stick-slip: keeps the flag up as a slip would, raises it as a full chain.
                self.since_slip = 0;
                self.raise();
            }
            if self.steady == self.settle_ticks {
                // = falling_branch(law, the reference two ticks ago).
                self.falling = self.branch_next;
                self.out.falling_branch = self.falling;
            }
            // The peak holds during a slip (no leak) and the slip lasts until the torque has not
            // made a new low for EVENT_MS: a large unwinding (40 N·m over 10 ms) is one slip.
            let leak = if self.in_event > 0 { 0 } else { self.leak };
            self.peak = self.peak.saturating_sub(leak).max(mean);
            let drop = self.peak.saturating_sub(mean);
            if self.in_event > 0 {
                if drop > self.event_drop {
                    self.event_drop = drop;
                    self.in_event = 1;
                } else {
                    self.in_event += 1;
                }
                if self.in_event > self.event_ticks {
                    self.in_event = 0;
                    self.out.amplitude = NewtonMetres::from_raw(self.event_drop);
                    self.peak = mean;
                }
            } else if drop
                >= self.threshold.max({
                    // × NOISE_GAIN: a saturating double is one `QADD`, a saturating multiply ≈ 6.
                    const { assert!(NOISE_GAIN == 2) };
                    self.noise.saturating_add(self.noise)
                })
            {
                self.slip();
            }
        }
        if self.out.active {
            // Four intervals, at most the window, at least MIN_HOLD_MS: a window under
            // MIN_HOLD_MS (100…250 ms is valid) leaves the minimum (`clamp` panicked there).
            let hold = self
                .interval
                .saturating_mul(4)
                .min(self.window_ticks)
                .max(self.min_hold_ticks);
            if self.since_slip > hold {
                self.out.active = false;
                self.chain = 0;
                self.since_fall = 0;
            }
        }
        self.out
    }

    fn slip(&mut self) {
        self.breakaway_sum = self.breakaway_sum.saturating_add(i64::from(self.peak));
        self.breakaways = self.breakaways.wrapping_add(1);
        self.in_event = 1;
        self.event_drop = self.peak.saturating_sub(self.ring_mean());
        self.out.slip = true;
        if self.since_slip <= self.window_ticks {
            self.chain = self.chain.saturating_add(1);
            self.interval = self.since_slip;
        } else {
            self.chain = 1;
            self.interval = 0;
        }
        self.since_slip = 0;
        let need = if self.falling { 2 } else { 3 };
        if self.chain >= need {
            self.raise();
        }
    }

    /// A slip the controller knows to be stick-slip: the first breakaway of a weighing creep
    /// (`control::creep`: a stick from rest at a constant slow speed on the law's falling
    /// branch, where sliding is unstable). Raises the flag at once, as a chain would; the flag
    /// then falls as after any slip. Its cycles at the creep can fall by less than the
    /// threshold in the current (host-sim, dry 896 kg lowering from 34.8°: 1 N·m every 18 ms
    /// reads ≈ 0.6 N·m peak to peak), which the detector alone missed.
    pub fn confirm(&mut self) -> StickSlipOutput {
        self.out.onset = false;
        self.since_slip = 0;
        self.raise();
        self.out
    }

    fn raise(&mut self) {
        if !self.out.active {
            self.out.active = true;
            // Within `window_ms` of the flag's fall it is the same episode (the truth's
            // definition joins cycles ≤ 2 s apart): the flag rises again, no new onset.
            if self.since_fall > self.window_ticks {
                self.out.onset = true;
                self.out.episodes = self.out.episodes.wrapping_add(1);
            }
        }
    }

    fn ring_mean(&self) -> i32 {
        div_pow2_i64(self.sum, MEAN_SHIFT) as i32
    }
}

/// `x.saturating_mul(4)` as two saturating doubles (two `QADD`s; the same value for every x).
fn times4(x: i32) -> i32 {
    let d = x.saturating_add(x);
    d.saturating_add(d)
}

/// Whether μ falls with speed at the reference speed: μ(v + Δ) < μ(v), Δ = max(v/4, 0.05 rad/s).
/// Two evaluations of the law, once per steady motion (the detector splits them over two
/// ticks: the answer for the speed of the tick two before the one that arms).
pub fn falling_branch(law: &CompiledLaw, reference: RadiansPerSecond) -> bool {
    let v = reference.sat_abs();
    law.mu(v.sat_add(branch_step(v))) < law.mu(v)
}

/// The branch test's speed step Δ above |v| = `v`.
fn branch_step(v: RadiansPerSecond) -> RadiansPerSecond {
    RadiansPerSecond::from_raw(
        (v.to_bits() / 4).max(const { RadiansPerSecond::lit("0.05") }.bits()),
    )
}

#[cfg(test)]
mod tests;
