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

    /// Σ of the slips' peak torques (resisting the motion, Q16 N·m) and their count, since
    /// boot: each slip's peak is the breakaway torque of the stick before it.
    pub fn breakaways(&self) -> (i64, u32) {
        (self.breakaway_sum, self.breakaways)
    }

    /// Forget the motion (keeps the episode counter and the last amplitude).
    fn idle(&mut self) {
        self.ring = [0; MEAN_LEN];
        self.head = 0;
        self.sum = 0;
        self.filled = 0;
        self.prev_reference = 0;
        self.since_fall = u32::MAX;
        if self.periodicity.filled != 0 {
            self.periodicity.reset();
        }
        self.periodic_run = 0;
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
        let p = if x.direction < 0 {
            x.measured_torque.sat_neg()
        } else {
            x.measured_torque
        }
        .to_bits();
        self.sum += i64::from(p) - i64::from(self.ring[self.head]);
        self.ring[self.head] = p;
        self.head = (self.head + 1) % MEAN_LEN;
        // Noise level from the second difference (a steady ramp — the coupling winding up while
        // stuck — has none); the first samples of a motion only fill the history.
        if self.filled >= 2 {
            // In i32 (saturating: exact for torques within ±8192 N·m, far beyond the motor's).
            let d2 = p
                .saturating_sub(self.last[0])
                .saturating_sub(self.last[0].saturating_sub(self.last[1]))
                .saturating_abs();
            let cap = times4(self.noise.max(self.threshold / 4));
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
            if self.periodicity.filled != 0 {
                self.periodicity.reset();
            }
            self.periodic_run = 0;
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
mod tests {
    use super::*;
    use crate::model::friction::FrictionLaw;
    use crate::units::{Metres, Ratio};
    use proptest::prelude::*;

    fn law(l: FrictionLaw) -> CompiledLaw {
        l.compile(Metres::lit("0.004265"), Ratio::lit("0.998"))
            .unwrap()
    }

    /// The float64 twin: the same algorithm on f64 torques in N·m.
    struct Twin {
        thr: f64,
        leak: f64,
        window: u32,
        settle: u32,
        event: u32,
        min_hold: u32,
        ring: [f64; 4],
        head: usize,
        filled: usize,
        prev_ref: f64,
        steady: u32,
        peak: f64,
        in_event: u32,
        event_drop: f64,
        since: u32,
        interval: u32,
        chain: u32,
        falling: bool,
        since_fall: u32,
        active: bool,
        amplitude: f64,
        episodes: u32,
        last: [f64; 2],
        noise: f64,
        per: PerTwin,
        per_run: u32,
        per_min: f64,
    }

    /// The float64 twin of [`Periodicity`].
    #[derive(Clone, Default)]
    struct PerTwin {
        x: [f64; 3],
        hist: Vec<f64>,
        filled: usize,
        seen: u32,
        odd: bool,
        periodic: bool,
        c0: f64,
        c: [f64; LAG_MAX - LAG_FAST + 1],
        c3: f64,
    }

    impl PerTwin {
        fn step(&mut self, x: f64, min_power: f64) -> bool {
            let d = (x - self.x[0] - self.x[1] + self.x[2]).clamp(-64.0, 64.0);
            // Kept in Q8 like the detector (the quantisation is mirrored, the arithmetic
            // checked).
            let d = (d * 256.0).floor() / 256.0;
            self.x = [x, self.x[0], self.x[1]];
            if self.filled < 3 {
                self.filled += 1;
                return false;
            }
            self.hist.insert(0, d);
            self.hist.truncate(LAG_MAX + 1);
            if self.filled <= LAG_MAX + 3 {
                self.filled += 1;
                return false;
            }
            self.c0 += (d * d - self.c0) / 256.0;
            self.odd = !self.odd;
            let first = usize::from(self.odd);
            for k in (first..self.c.len()).step_by(2) {
                self.c[k] += (d * self.hist[LAG_FAST + k] - self.c[k]) / 128.0;
            }
            if self.odd {
                self.c3 += (d * self.hist[LAG_HARMONIC] - self.c3) / 128.0;
                self.seen += 2;
                let best = self.best();
                self.periodic = self.seen >= 256
                    && best >= min_power
                    && best * f64::from(PER_DEN) >= f64::from(PER_NUM) * self.c0
                    && (self.c[0] < self.c[1] || self.c[0] <= 0.0)
                    && f64::from(FAST_VETO) * self.c[0] < best
                    && self.c3 < best;
            }
            self.periodic
        }

        fn best(&self) -> f64 {
            self.c[1..].iter().copied().fold(f64::MIN, f64::max)
        }
    }

    impl Twin {
        fn new(thr: f64, window_ms: u32, falling: bool) -> Twin {
            // The leak is quantised as the detector quantises it (the configuration is
            // quantised once; the twin checks the arithmetic, not the quantisation).
            let leak = f64::from(((thr * 65536.0).round() as i32 / 16).max(1)) / 65536.0;
            Twin {
                thr,
                leak,
                window: window_ms,
                settle: SETTLE_MS,
                event: EVENT_MS,
                min_hold: MIN_HOLD_MS,
                ring: [0.0; 4],
                head: 0,
                filled: 0,
                prev_ref: 0.0,
                steady: 0,
                peak: 0.0,
                in_event: 0,
                event_drop: 0.0,
                since: u32::MAX,
                interval: 0,
                chain: 0,
                falling,
                since_fall: u32::MAX,
                active: false,
                amplitude: 0.0,
                episodes: 0,
                last: [0.0; 2],
                noise: 0.0,
                per: PerTwin::default(),
                per_run: 0,
                per_min: {
                    let t = ((thr * 65536.0).round() as i64) * PER_MIN_NUM / PER_MIN_DEN;
                    ((t * t) >> 16).max(1) as f64 / 65536.0
                },
            }
        }

        fn raise(&mut self) {
            if !self.active {
                self.active = true;
                if self.since_fall > self.window {
                    self.episodes += 1;
                }
            }
        }

        fn step(&mut self, driving: bool, reference: f64, torque: f64) -> (bool, bool) {
            if !driving {
                *self = Twin {
                    amplitude: self.amplitude,
                    episodes: self.episodes,
                    noise: self.noise,
                    ..Twin::new(self.thr, self.window, self.falling)
                };
                return (false, false);
            }
            self.ring[self.head] = torque;
            self.head = (self.head + 1) % 4;
            if self.filled >= 2 {
                let d2 = (torque - 2.0 * self.last[0] + self.last[1]).abs();
                let d2 = d2.min(4.0 * self.noise.max(self.thr / 4.0));
                self.noise += (d2 - self.noise) / 64.0;
            }
            self.last = [torque, self.last[0]];
            self.filled = (self.filled + 1).min(4);
            let mean = self.ring.iter().sum::<f64>() / 4.0;
            self.since = self.since.saturating_add(1);
            self.since_fall = self.since_fall.saturating_add(1);
            let accel = reference - self.prev_ref;
            if reference == 0.0 || self.filled == 1 || accel.abs() > 2.0 / 65536.0 {
                self.steady = 0;
            } else {
                self.steady += 1;
            }
            self.prev_ref = reference;
            let mut slip = false;
            if self.steady < self.settle || self.filled < 4 {
                self.peak = mean;
                self.in_event = 0;
                self.per = PerTwin::default();
                self.per_run = 0;
            } else {
                self.per_run = if self.per.step(torque, self.per_min) {
                    self.per_run + 1
                } else {
                    0
                };
                if self.per_run >= PER_TICKS {
                    self.since = 0;
                    self.raise();
                }
                let leak = if self.in_event > 0 { 0.0 } else { self.leak };
                self.peak = (self.peak - leak).max(mean);
                let drop = self.peak - mean;
                if self.in_event > 0 {
                    if drop > self.event_drop {
                        self.event_drop = drop;
                        self.in_event = 1;
                    } else {
                        self.in_event += 1;
                    }
                    if self.in_event > self.event {
                        self.in_event = 0;
                        self.amplitude = self.event_drop;
                        self.peak = mean;
                    }
                } else if drop >= self.thr.max(2.0 * self.noise) {
                    slip = true;
                    self.in_event = 1;
                    self.event_drop = drop;
                    if self.since <= self.window {
                        self.chain += 1;
                        self.interval = self.since;
                    } else {
                        self.chain = 1;
                        self.interval = 0;
                    }
                    self.since = 0;
                    let need = if self.falling { 2 } else { 3 };
                    if self.chain >= need {
                        self.raise();
                    }
                }
            }
            if self.active {
                let hold = (self.interval * 4).min(self.window).max(self.min_hold);
                if self.since > hold {
                    self.active = false;
                    self.chain = 0;
                    self.since_fall = 0;
                }
            }
            (slip, self.active)
        }
    }

    fn cfg(thr: &str) -> StickSlipConfig {
        StickSlipConfig {
            drop_threshold: NewtonMetres::lit(thr),
            ..StickSlipConfig::DEFAULT
        }
    }

    fn drive(t: NewtonMetres, reference: &str) -> DetectorInputs {
        DetectorInputs {
            driving: true,
            direction: 1,
            reference: RadiansPerSecond::lit(reference),
            measured_torque: t,
        }
    }

    /// A sawtooth: rises `rise` N·m over `period` ms, then falls back within 2 ms.
    fn sawtooth(ms: u32, period: u32, base: f64, rise: f64) -> f64 {
        let ph = ms % period;
        if ph + 2 >= period {
            base + rise * f64::from(period - ph) / 3.0 / 1.0
        } else {
            base + rise * f64::from(ph) / f64::from(period - 2)
        }
    }

    #[test]
    fn default_config_is_valid_and_out_of_range_names_the_key() {
        StickSlipConfig::DEFAULT.validate().unwrap();
        let mut c = StickSlipConfig::DEFAULT;
        c.window_ms = 50;
        assert_eq!(
            c.validate(),
            Err(ConfigError::OutOfRange {
                field: "stickslip.window_ms",
                range: "100..10000 ms"
            })
        );
        c.window_ms = u32::MAX; // wraps negative in the table: still refused
        assert!(c.validate().is_err());
        let mut c = StickSlipConfig::DEFAULT;
        c.drop_threshold = NewtonMetres::lit("50.1");
        assert_eq!(
            c.validate(),
            Err(ConfigError::OutOfRange {
                field: "stickslip.drop",
                range: "0.2..50 Nm"
            })
        );
        let mut c = StickSlipConfig::DEFAULT;
        c.escape_speed = RadiansPerSecond::lit("0.1");
        assert_eq!(
            c.validate(),
            Err(ConfigError::OutOfRange {
                field: "stickslip.escape_speed",
                range: "0.2..20 rad/s"
            })
        );
    }

    #[test]
    fn times4_is_the_saturating_multiply() {
        for x in [
            0,
            1,
            -1,
            7,
            -9,
            1 << 28,
            -(1 << 28),
            (1 << 29) - 1,
            1 << 29,
            -(1 << 29),
        ]
        .into_iter()
        .chain([
            (1 << 29) + 1,
            -(1 << 29) - 1,
            i32::MAX,
            i32::MIN,
            i32::MAX / 2,
        ]) {
            assert_eq!(times4(x), x.saturating_mul(4), "{x}");
        }
    }

    #[test]
    fn dry_law_is_falling_and_lubricants_rise_at_cruise() {
        let v = RadiansPerSecond::lit("3");
        assert!(falling_branch(&law(FrictionLaw::DRY), v));
        assert!(!falling_branch(&law(FrictionLaw::PTFE), v));
        assert!(!falling_branch(&law(FrictionLaw::LITHIUM), v));
        assert!(!falling_branch(
            &law(FrictionLaw::LITHIUM),
            RadiansPerSecond::lit("0.2")
        ));
    }

    #[test]
    fn sawtooth_torque_raises_the_flag_on_the_second_slip_with_dry_friction() {
        let l = law(FrictionLaw::DRY);
        let mut d = StickSlipDetector::new(&cfg("0.5"), 1000);
        let mut onset_at = None;
        let mut slips = 0;
        for ms in 0..1000u32 {
            let t = NewtonMetres::from_f64(sawtooth(ms, 100, 25.0, 50.0));
            let o = d.step(&drive(t, "3"), &l);
            slips += u32::from(o.slip);
            if o.onset {
                onset_at = Some((ms, slips));
            }
        }
        let (at, n) = onset_at.expect("an episode");
        assert_eq!(n, 2, "onset at the second slip");
        assert!((198..=206).contains(&at), "onset at {at} ms");
        assert_eq!(d.output().episodes, 1);
        assert!(d.output().active);
        let a = d.output().amplitude.to_f64();
        assert!(a > 30.0 && a <= 50.5, "amplitude {a}");
    }

    /// The shortest valid chain window (100 ms) is shorter than the minimum hold (250 ms): an
    /// episode must hold for the minimum, not panic (found by the golden vectors).
    #[test]
    fn a_window_shorter_than_the_minimum_hold_holds_the_minimum() {
        let l = law(FrictionLaw::DRY);
        let c = StickSlipConfig {
            window_ms: 100,
            ..cfg("0.5")
        };
        c.validate().unwrap();
        let mut d = StickSlipDetector::new(&c, 1000);
        let (mut last_slip, mut onset) = (None, false);
        for ms in 0..400u32 {
            let t = NewtonMetres::from_f64(sawtooth(ms, 40, 25.0, 50.0));
            let o = d.step(&drive(t, "3"), &l);
            onset |= o.onset;
            if o.slip {
                last_slip = Some(ms);
            }
        }
        assert!(onset, "an episode");
        let last = last_slip.unwrap();
        let flat = NewtonMetres::from_f64(25.0);
        let mut fell = None;
        for ms in 400..1000u32 {
            if !d.step(&drive(flat, "3"), &l).active && fell.is_none() {
                fell = Some(ms);
            }
        }
        let held = fell.expect("the flag falls") - last;
        assert!((250..=260).contains(&held), "held {held} ms");
    }

    #[test]
    fn flat_noisy_torque_never_alarms() {
        let l = law(FrictionLaw::DRY);
        let mut d = StickSlipDetector::new(&cfg("0.5"), 1000);
        let mut x: u32 = 12345;
        for ms in 0..20_000 {
            // ±0.2 N·m uniform noise on 37 N·m, slow drift down (the load falls as α grows).
            x = x.wrapping_mul(1_103_515_245).wrapping_add(12345);
            let n = f64::from(x >> 16) / 65536.0 * 0.4 - 0.2;
            let t = 37.0 - f64::from(ms) * 5e-4 + n;
            let o = d.step(&drive(NewtonMetres::from_f64(t), "3"), &l);
            assert!(!o.slip && !o.active);
        }
    }

    #[test]
    fn flag_falls_when_the_motion_ends_and_the_counter_stays() {
        let l = law(FrictionLaw::DRY);
        let mut d = StickSlipDetector::new(&cfg("0.5"), 1000);
        for ms in 0..500u32 {
            let t = NewtonMetres::from_f64(sawtooth(ms, 50, 20.0, 10.0));
            d.step(&drive(t, "3"), &l);
        }
        assert!(d.output().active);
        let o = d.step(&DetectorInputs::default(), &l);
        assert!(!o.active);
        assert_eq!(o.episodes, 1);
    }

    #[test]
    fn rising_branch_needs_a_third_slip() {
        let l = law(FrictionLaw::PTFE);
        let mut d = StickSlipDetector::new(&cfg("0.5"), 1000);
        let mut slips_at_onset = 0;
        let mut slips = 0;
        for ms in 0..600u32 {
            let t = NewtonMetres::from_f64(sawtooth(ms, 100, 25.0, 20.0));
            let o = d.step(&drive(t, "3"), &l);
            slips += u32::from(o.slip);
            if o.onset {
                slips_at_onset = slips;
            }
        }
        assert_eq!(slips_at_onset, 3);
    }

    #[test]
    fn changing_acceleration_is_ignored() {
        let l = law(FrictionLaw::DRY);
        let mut d = StickSlipDetector::new(&cfg("0.5"), 1000);
        for ms in 0..400i32 {
            // The acceleration changes every tick (an S-curve). Torque drops 10 N·m every 50 ms.
            let t = NewtonMetres::from_f64(30.0 - 10.0 * f64::from(ms % 50 / 49));
            let x = DetectorInputs {
                reference: RadiansPerSecond::from_raw(1000 + 10 * ms * ms),
                ..drive(t, "3")
            };
            assert!(!d.step(&x, &l).slip);
        }
    }

    #[test]
    fn slips_count_at_cruise_not_on_a_ramp() {
        let l = law(FrictionLaw::DRY);
        let mut d = StickSlipDetector::new(&cfg("0.5"), 1000);
        let mut slips = Vec::new();
        for ms in 0..400i32 {
            // Ramp for 200 ms, then cruise. Inertia torque 9 N·m during the ramp (it falls away
            // a tick after its end: the current answers the previous tick's command), slips of
            // 5 N·m every 40 ms from 60 to 380 ms.
            let inertia = if ms <= 200 { 9.0 } else { 0.0 };
            let slip = if (60..=380).contains(&ms) && ms % 40 >= 38 {
                -5.0
            } else {
                0.0
            };
            let t = NewtonMetres::from_f64(20.0 + inertia + slip);
            let x = DetectorInputs {
                reference: RadiansPerSecond::from_raw(1000 + 300 * ms.min(200)),
                ..drive(t, "3")
            };
            if d.step(&x, &l).slip {
                slips.push(ms);
            }
        }
        // Armed 25 ms after the reference's last change (ms 201): the slips from 238 on.
        assert_eq!(slips, [238, 278, 318, 358], "{slips:?}");
        assert_eq!(d.output().episodes, 1);
    }

    #[test]
    fn a_pause_within_the_window_continues_the_episode() {
        let l = law(FrictionLaw::DRY);
        let mut d = StickSlipDetector::new(&cfg("0.5"), 1000);
        let mut onsets = 0;
        let mut fell = false;
        for ms in 0..3000u32 {
            // Stick-slip every 50 ms, a 400 ms pause (the flag falls after 250 ms), again.
            let t = if (600..1000).contains(&ms) {
                20.0
            } else {
                sawtooth(ms, 50, 20.0, 10.0)
            };
            let o = d.step(&drive(NewtonMetres::from_f64(t), "3"), &l);
            onsets += u32::from(o.onset);
            fell |= ms > 600 && ms < 1000 && !o.active;
        }
        assert!(fell, "the flag fell in the pause");
        assert!(d.output().active);
        assert_eq!(onsets, 1);
        assert_eq!(d.output().episodes, 1);
    }

    /// A 7-tick sawtooth of `pp` N·m (6 ticks up, 1 down) as the current sees it, through the
    /// motor's 3.4 ms electromechanical lag (`lag` holds the filter), plus uniform noise of
    /// ±`noise`.
    fn fast_sawtooth(n: u32, pp: f64, noise: f64, x: &mut u32, lag: &mut f64) -> f64 {
        *x = x.wrapping_mul(1_103_515_245).wrapping_add(12345);
        let u = f64::from(*x >> 16) / 65536.0 * 2.0 - 1.0;
        let ph = n % 7;
        let saw = if ph == 6 {
            0.0
        } else {
            pp * f64::from(ph) / 6.0
        };
        *lag += (saw - *lag) * (1.0 - (-1.0f64 / 3.4).exp());
        20.0 + *lag + noise * u
    }

    #[test]
    fn periodicity_finds_a_fast_sawtooth_in_noise() {
        let mut p = Periodicity::default();
        let mut x: u32 = 7;
        let mut lag = 0.0;
        let min = 2621; // 0.04 N·m²
        let first = (0..2000u32)
            .position(|n| {
                p.step(
                    NewtonMetres::from_f64(fast_sawtooth(n, 2.0, 0.15, &mut x, &mut lag)).bits(),
                    min,
                )
            })
            .expect("periodic");
        // The EWMAs decide after 256 ticks.
        assert!((259..400).contains(&first), "{first}");
    }

    #[test]
    fn periodicity_vetoes_periods_under_five_ticks() {
        // Micro stick-slip by the truth's definition (period < 5 ms) with a large ripple: a
        // 1 N·m sawtooth every 4 ticks, a 0.5 N·m sine (the ripple after the motor's lag) every
        // 3.7 and 4.2 ticks. They correlate at lags 8, 11–12, 15–16 too, but at lag 4 at least
        // half as well: never periodic. The sines every 5.2 and 7 ticks are.
        let min = 655;
        let saw = |n: u32, period: f64| 20.0 + (f64::from(n) / period).fract();
        let sine = |n: u32, period: f64| {
            20.0 + 0.5 * (core::f64::consts::TAU * f64::from(n) / period).sin()
        };
        let periodic = |f: &dyn Fn(u32) -> f64| {
            let mut p = Periodicity::default();
            (0..3000u32).any(|n| p.step(NewtonMetres::from_f64(f(n)).bits(), min))
        };
        assert!(!periodic(&|n| saw(n, 4.0)), "sawtooth 4");
        assert!(!periodic(&|n| sine(n, 3.7)), "sine 3.7");
        assert!(!periodic(&|n| sine(n, 4.2)), "sine 4.2");
        assert!(periodic(&|n| sine(n, 5.2)), "sine 5.2");
        assert!(periodic(&|n| sine(n, 7.0)), "sine 7");
    }

    #[test]
    fn periodicity_ignores_noise_ramps_and_two_code_dither() {
        let min = 2621;
        let mut x: u32 = 99;
        let mut p = Periodicity::default();
        for n in 0..20_000u32 {
            // Uniform noise of ±0.3 N·m on a ramp that changes slope every 300 ticks.
            x = x.wrapping_mul(1_103_515_245).wrapping_add(12345);
            let u = f64::from(x >> 16) / 65536.0 * 0.6 - 0.3;
            let slope = if (n / 300) % 2 == 0 { 0.4 } else { -0.1 };
            let t = 30.0 + slope * f64::from(n % 300) + u;
            assert!(
                !p.step(NewtonMetres::from_f64(t).bits(), min),
                "noise at {n}"
            );
        }
        let mut p = Periodicity::default();
        for n in 0..5000u32 {
            // The current dithering between two codes (0.066 N·m apart) every tick.
            let t = 47.4 + 0.066 * f64::from(n % 2);
            assert!(
                !p.step(NewtonMetres::from_f64(t).bits(), min),
                "dither at {n}"
            );
        }
    }

    #[test]
    fn fast_stick_slip_below_the_drop_threshold_raises_the_flag() {
        let l = law(FrictionLaw::DRY);
        let mut d = StickSlipDetector::new(&cfg("0.5"), 1000);
        let mut x: u32 = 3;
        let mut lag = 0.0;
        let mut onset = None;
        for n in 0..1000u32 {
            let t = fast_sawtooth(n, 2.0, 0.1, &mut x, &mut lag);
            let o = d.step(&drive(NewtonMetres::from_f64(t), "2"), &l);
            assert!(
                !o.slip,
                "no slip at {n}: the ripple is below the drop threshold"
            );
            if o.onset {
                onset = Some(n);
            }
        }
        let n = onset.expect("an onset");
        assert!((280..450).contains(&n), "{n}");
        assert_eq!(d.output().episodes, 1);
    }

    proptest! {
        /// The fixed-point periodicity test agrees with its float64 twin: the autocorrelations
        /// within their budget (each EWMA step floors once, < 1 LSB of Q16; with the 1/128
        /// decay of the lags that bounds the error at 128 LSB, the power's at 256 LSB,
        /// 0.0039 N·m²; the budget checked is twice that), and the decision wherever the twin
        /// was not within the budget of a threshold when it decided (periods from 3 ticks: the
        /// veto of periods under LAG_MIN is exercised too).
        #[test]
        fn periodicity_matches_its_float_twin(
            steps in proptest::collection::vec((-2.0f64..2.0, 0u8..7), 300..1200),
            period in 3u32..17,
        ) {
            let mut p = Periodicity::default();
            let mut twin = PerTwin::default();
            let min = 655i64; // 0.01 N·m², the default
            let mut t = 0.0;
            let mut near = false;
            for (n, (noise, kind)) in steps.into_iter().enumerate() {
                // A sawtooth of the drawn period plus noise, sometimes a jump.
                let saw = f64::from(n as u32 % period) * 0.15;
                t = if kind == 0 { t + noise * 10.0 } else { t * 0.99 };
                let tq = NewtonMetres::from_f64(20.0 + saw + noise * 0.1 + t.clamp(-100.0, 100.0));
                let a = p.step(tq.bits(), min);
                let b = twin.step(tq.to_f64(), min as f64 / 65536.0);
                let budget = 512.0 / 65536.0;
                prop_assert!((p.c0 as f64 / 65536.0 - twin.c0).abs() <= budget);
                for k in 0..p.c.len() {
                    prop_assert!((p.c[k] as f64 / 65536.0 - twin.c[k]).abs() <= budget);
                }
                prop_assert!((p.c3 as f64 / 65536.0 - twin.c3).abs() <= budget);
                if twin.odd {
                    // A decision tick: the decision holds over the next tick.
                    let best = twin.best();
                    near = (best - min as f64 / 65536.0).abs() <= budget
                        || (best * f64::from(PER_DEN) - f64::from(PER_NUM) * twin.c0).abs()
                            <= f64::from(PER_DEN + PER_NUM) * budget
                        || (f64::from(FAST_VETO) * twin.c[0] - best).abs() <= 3.0 * budget
                        || (twin.c[0] - twin.c[1]).abs() <= 2.0 * budget
                        || twin.c[0].abs() <= budget
                        || (twin.c3 - best).abs() <= 2.0 * budget;
                }
                if !near {
                    prop_assert_eq!(a, b, "tick {}", n);
                }
            }
        }
    }

    /// Runs a detector on a reference ramp `r0 + k·step` (rad/s, Q16 raw) with a flat torque
    /// until it arms (its branch test's tick), and returns its branch answer and the reference
    /// of every tick; `None` if a zero reference restarts the run or it never arms (a ramp).
    fn branch_on_ramp(
        l: &CompiledLaw,
        r0: i32,
        step: i32,
        tick_us: u32,
    ) -> Option<(bool, Vec<i32>)> {
        let mut d = StickSlipDetector::new(&cfg("1"), tick_us);
        let mut refs = Vec::new();
        for k in 0..d.settle_ticks as i32 + 8 {
            let r = r0.saturating_add(step.saturating_mul(k));
            if r == 0 {
                return None;
            }
            refs.push(r);
            let x = DetectorInputs {
                reference: RadiansPerSecond::from_raw(r),
                ..drive(NewtonMetres::lit("10"), "1")
            };
            let answer = d.step(&x, l).falling_branch;
            if d.steady == d.settle_ticks {
                // The armed path ran its branch test on this tick.
                assert!(d.filled >= MEAN_LEN);
                return Some((answer, refs));
            }
            assert!(
                !answer,
                "the answer appears on the arming tick, not before (tick {k})"
            );
        }
        None
    }

    #[test]
    fn a_ramp_never_arms_and_cruise_tests_its_own_speed() {
        // The branch is tested at the cruise speed: on a ramp (±0.05 rad/s per tick, the
        // default 60 ms ramp to 3 rad/s and its braking; ±3 LSB, slower than any valid ramp)
        // the detector never arms; at a steady reference it answers for that speed.
        for l in [FrictionLaw::DRY, FrictionLaw::PTFE, FrictionLaw::LITHIUM] {
            let l = law(l);
            for v in (3 * 3277..20 << 16).step_by(3277) {
                for step in [3277, -3277, 3, -3] {
                    assert!(branch_on_ramp(&l, v, step, 1000).is_none(), "{v} {step}");
                }
                for tick_us in [1000, 10_000] {
                    let (got, refs) = branch_on_ramp(&l, v, 0, tick_us).unwrap();
                    assert!(refs.iter().all(|&r| r == v));
                    assert_eq!(got, falling_branch(&l, RadiansPerSecond::from_raw(v)));
                }
            }
        }
    }

    proptest! {
        /// On any steady reference (within the profile's rounding), the detector's branch
        /// answer when it arms is `falling_branch` of the reference two ticks before (its
        /// halves on those ticks).
        #[test]
        fn the_branch_test_in_halves_is_falling_branch(
            r0 in -2_000_000i32..2_000_000,
            step in -2i32..=2,
            tick_us in 100u32..=10_000,
        ) {
            for l in [FrictionLaw::DRY, FrictionLaw::PTFE, FrictionLaw::LITHIUM] {
                let l = law(l);
                let Some((got, refs)) = branch_on_ramp(&l, r0, step, tick_us) else {
                    continue; // the run restarts on a zero reference
                };
                let want = falling_branch(&l, RadiansPerSecond::from_raw(refs[refs.len() - 3]));
                prop_assert_eq!(got, want);
            }
        }
    }

    proptest! {
        /// `reset` keeps the history ring and the EWMAs (they are rewritten before they are
        /// read): a reset periodicity decides exactly like a new one on any torques after any
        /// history.
        #[test]
        fn periodicity_reset_is_a_new_one(
            before in proptest::collection::vec(-3_000_000i32..3_000_000, 0..80),
            after in proptest::collection::vec(-3_000_000i32..3_000_000, 0..400),
            period in 3usize..17,
        ) {
            let mut p = Periodicity::new();
            for &x in &before {
                p.step(x, 1);
            }
            p.reset();
            let mut q = Periodicity::new();
            for (n, &x) in after.iter().enumerate() {
                // Noise on a sawtooth of the drawn period, so that some decisions are `true`.
                let x = x / 8 + (n % period) as i32 * 40_000;
                prop_assert_eq!(p.step(x, 1), q.step(x, 1), "tick {}", n);
                prop_assert_eq!(p.x, q.x);
                if q.filled > LAG_MAX + 3 {
                    // The EWMAs run (before that they are not read).
                    prop_assert_eq!((p.c0, p.c, p.c3), (q.c0, q.c, q.c3), "tick {}", n);
                }
            }
        }
    }

    proptest! {
        /// The fixed-point detector and its float64 twin agree on every slip and on the flag,
        /// and the amplitude within 2 LSB of Q16 plus the twin's rounding, on random torque
        /// sequences up to the first tick that lands near a tie (the slip threshold, a slip's
        /// new low: ties may go either way).
        #[test]
        fn detector_matches_its_float_twin(
            steps in proptest::collection::vec((-60.0f64..60.0, 0u8..8), 1..600),
            thr in 0.2f64..10.0,
        ) {
            let l = law(FrictionLaw::DRY);
            let thr_q = NewtonMetres::from_f64(thr);
            let mut c = cfg("1");
            c.drop_threshold = thr_q;
            let mut d = StickSlipDetector::new(&c, 1000);
            let mut twin = Twin::new(thr_q.to_f64(), c.window_ms, true);
            let mut torque = 10.0;
            for (ms, (jump, kind)) in steps.into_iter().enumerate() {
                // Mostly small moves, sometimes a jump; every 200th tick the drive pauses.
                torque += if kind == 0 { jump } else { jump / 50.0 };
                torque = torque.clamp(-200.0, 200.0);
                let driving = ms % 200 != 199;
                // Quantise first: both see the same torque.
                let tq = NewtonMetres::from_f64(torque);
                let x = DetectorInputs { driving, ..drive(tq, "3") };
                let o = d.step(&x, &l);
                let (in_event, event_drop) = (twin.in_event, twin.event_drop);
                let (slip, active) = twin.step(driving, 3.0, tq.to_f64());
                // The Q16 mean truncates by < 1 LSB: skip cases that land that close to ties.
                // The noise EWMA rounds (≤ ½ LSB per tick, ≤ 32 LSB in steady state, plus the
                // clipping of its input): skip cases within that of the threshold.
                let thr = twin.thr.max(2.0 * twin.noise);
                let drop = twin.peak - twin.ring.iter().sum::<f64>() / 4.0;
                let near_tie = (drop - thr).abs() < 80.0 / 65536.0;
                // During a slip the fall's new low (`drop > event_drop`, the peak held) compares
                // two means, each truncated from a sum of whole LSB by at most ¾ LSB: within
                // 1.5 LSB of the low so far it may go either way, and the slip then ends a tick
                // earlier or later (and a later slip may start or not). Equal means (the twin's
                // are exact) are equal sums: both see no new low.
                let new_low = drop - event_drop;
                let new_low_tie = in_event > 0 && new_low != 0.0 && new_low.abs() <= 1.5 / 65536.0;
                if near_tie || new_low_tie { return Ok(()); }
                prop_assert_eq!(o.slip, slip, "tick {}", ms);
                prop_assert_eq!(o.active, active, "tick {}", ms);
                prop_assert!((o.amplitude.to_f64() - twin.amplitude).abs() <= 4.0 / 65536.0);
                prop_assert!((f64::from(d.noise) / 65536.0 - twin.noise).abs() <= 70.0 / 65536.0, "noise {} vs {}", f64::from(d.noise) / 65536.0, twin.noise);
                prop_assert_eq!(o.episodes, twin.episodes);
            }
        }
    }
}
