//! The liftfw core on an emulated Cortex-M4 (QEMU `mps2-an386`), run by `scripts/qemu-test`.
//!
//! 1. **Bit-exact twin** (issue 8 item 2): replays the golden vectors the host generated
//!    (`golden-gen`, embedded at build time) through the same evaluator and compares every output
//!    byte. Any mismatch fails the run (exit status 1).
//! 2. **Instruction counts** (issue 8 item 3, issue 3 item 8): the estimator step, fixed point
//!    against the f32 (micromath, hardware FPU) and f64 (libm, soft-float) references, plus the
//!    kernels it is made of. Method (docs/qemu.md): QEMU runs with `-icount shift=10`, so virtual
//!    time advances exactly 1024 ns per instruction; SysTick counts the 25 MHz CPU clock (40 ns),
//!    i.e. 25.6 ticks per instruction. A call's count is `(ticks − empty-call ticks) / 25.6`.
//!    Lines starting `ICOUNT` are for scripts; a calibration block of 1000 `nop`s checks the
//!    conversion on every run.
//!
//! Exit status: 0 all vectors match, 1 a mismatch or a malformed file, 101 a panic.
#![no_std]
#![no_main]

use core::hint::black_box;
use cortex_m::peripheral::{syst::SystClkSource, SYST};
use cortex_m_rt::entry;
use liftfw::estimator::{Estimator, EstimatorConfig, Measurements};
use liftfw::math::{exp_neg_q16, recip_q30, sqrt_q30};
use liftfw::units::{
    Amperes, Angle, Instant, Kilograms, RadiansPerSecond, RadiansPerSecond2, Ratio,
};
use liftfw_golden::{verify, Kind};
use liftfw_ref_float::{EstimatorF32, EstimatorF64, FloatMeasurements};
use semihosting::println;
// The device vector table cortex-m-rt asks for (see Cargo.toml).
use stm32_metapac as _;

/// The golden vectors, generated on the host from the same source.
static GOLDEN: &[u8] = include_bytes!(env!("LIFTFW_GOLDEN_FILE"));

/// Calls per measured function (a lift motion of this many ticks).
const N: usize = 256;

#[entry]
fn main() -> ! {
    let golden_ok = replay_golden();
    count_instructions();
    semihosting::process::exit(if golden_ok { 0 } else { 1 })
}

fn replay_golden() -> bool {
    match verify(GOLDEN) {
        Ok(r) => {
            for (i, k) in Kind::ALL.iter().enumerate() {
                println!(
                    "GOLDEN {} records={} mismatches={}",
                    k.name(),
                    r.records[i],
                    r.mismatches[i]
                );
            }
            if let Some((rec, kind, at)) = r.first_mismatch {
                println!("GOLDEN first mismatch: record {rec} (kind {kind}), output byte {at}");
            }
            println!(
                "GOLDEN {} ({} bytes of vectors)",
                if r.passed() { "PASS" } else { "FAIL" },
                GOLDEN.len()
            );
            r.passed()
        }
        Err(e) => {
            println!("GOLDEN FAIL: {e}");
            false
        }
    }
}

/// SysTick ticks spent in `f`, its input made opaque after the first read so that the work
/// cannot be hoisted out of the window, its output consumed before the second.
#[inline(always)]
fn ticks<I, R>(input: I, f: impl FnOnce(I) -> R) -> u32 {
    let t0 = SYST::get_current();
    let input = black_box(input);
    black_box(f(input));
    let t1 = SYST::get_current();
    t0.wrapping_sub(t1) & 0x00FF_FFFF
}

/// Ticks → instructions: 1024 ns per instruction / 40 ns per tick = 25.6 ticks, rounded.
fn insns(ticks: u32) -> u32 {
    (ticks * 10 + 128) / 256
}

struct Stats {
    name: &'static str,
    samples: [u32; N],
    n: usize,
}

impl Stats {
    fn new(name: &'static str) -> Self {
        Stats {
            name,
            samples: [0; N],
            n: 0,
        }
    }
    fn push(&mut self, ticks: u32, overhead: u32) {
        if let Some(s) = self.samples.get_mut(self.n) {
            *s = insns(ticks.saturating_sub(overhead));
            self.n += 1;
        }
    }
    fn report(&mut self) -> u32 {
        let s = &mut self.samples[..self.n];
        s.sort_unstable();
        let (min, max) = (
            s.first().copied().unwrap_or(0),
            s.last().copied().unwrap_or(0),
        );
        let median = s.get(s.len() / 2).copied().unwrap_or(0);
        let mean = s.iter().map(|&v| u64::from(v)).sum::<u64>() / (s.len().max(1) as u64);
        println!(
            "ICOUNT {} n={} min={} median={} mean={} max={}",
            self.name, self.n, min, median, mean, max
        );
        median
    }
}

/// A lift motion as the encoder sees it: from α ≈ 16° up at 3 rad/s cruise after a 60 ms ramp,
/// 1 kHz ticks, 800 kg, the motor drawing 10 A (the default drive: 48 counts/rev × 60:1).
fn motion(k: usize) -> (Instant, Measurements) {
    let t = k as i64; // ms
                      // Screw angle in counts·1000: 2880/(2π) counts per rad, 3 rad/s → 1375 counts/s.
    let ramp = 60i64;
    let milli_counts = if t < ramp {
        1375 * t * t / (2 * ramp)
    } else {
        1375 * ramp / 2 + 1375 * (t - ramp)
    };
    (
        Instant(1_000 * k as u32),
        Measurements {
            position_counts: 20_000 + (milli_counts / 1000) as i32,
            motor_current: Amperes::lit("10"),
            load: Kilograms::lit("800"),
            commanded_dir: 1,
        },
    )
}

/// Operating points over the envelope for the stateless model: (counts, speed, accel).
fn point(k: usize) -> (Measurements, RadiansPerSecond, RadiansPerSecond2) {
    let k = k as i32;
    let m = Measurements {
        // 0 … ≈ 490 000 counts: α₀ … past α_max.
        position_counts: k * 1_913,
        motor_current: Amperes::from_bits((k - 128) << 16),
        load: Kilograms::from_bits((k * 8) << 12),
        commanded_dir: 1,
    };
    // −400 … 400 rad/s and −2000 … 2000 rad/s².
    let speed = RadiansPerSecond::from_bits((k - 128) * (400 << 16) / 128);
    let accel = RadiansPerSecond2::from_bits((k - 128) * (2000 << 8) / 128);
    (m, speed, accel)
}

fn count_instructions() {
    let mut syst = match cortex_m::Peripherals::take() {
        Some(p) => p.SYST,
        None => return,
    };
    syst.set_clock_source(SystClkSource::Core);
    syst.set_reload(0x00FF_FFFF);
    syst.clear_current();
    syst.enable_counter();

    let overhead = (0..16).map(|_| ticks((), |()| 0u32)).min().unwrap_or(0);
    println!("ICOUNT-CALIBRATION empty window = {overhead} ticks");
    // 1000 nops must read as 1000 instructions.
    let nops = ticks((), |()| {
        // Note(unsafe): a block of `nop`s, no memory or register effects.
        unsafe { core::arch::asm!(".rept 1000", "nop", ".endr", options(nomem, nostack)) }
    });
    println!(
        "ICOUNT-CALIBRATION 1000 nops = {} instructions",
        insns(nops.saturating_sub(overhead))
    );

    let cfg = EstimatorConfig::DEFAULT;
    let (Ok(mut fixed), Ok(mut f32e), Ok(mut f64e)) = (
        Estimator::new(&cfg),
        EstimatorF32::new(&cfg),
        EstimatorF64::new(&cfg),
    ) else {
        println!("ICOUNT skipped: default configuration refused");
        return;
    };

    // The estimator step (filter + model), on the same motion for all three.
    let mut s_fixed = Stats::new("estimator.step fixed");
    let mut s_f32 = Stats::new("estimator.step f32-micromath");
    let mut s_f64 = Stats::new("estimator.step f64-softfloat");
    for k in 0..N {
        let (now, m) = motion(k);
        let m32 = FloatMeasurements::<f32>::from_fixed(&m);
        let m64 = FloatMeasurements::<f64>::from_fixed(&m);
        s_fixed.push(ticks(&m, |m| fixed.step(now, m)), overhead);
        s_f32.push(ticks(&m32, |m| f32e.step(now.0, m)), overhead);
        s_f64.push(ticks(&m64, |m| f64e.step(now.0, m)), overhead);
    }
    let fixed_median = s_fixed.report();
    let f32_median = s_f32.report();
    s_f64.report();

    // The model alone (no filter), over the envelope.
    let mut e_fixed = Stats::new("estimator.estimate fixed");
    let mut e_f32 = Stats::new("estimator.estimate f32-micromath");
    let mut e_f64 = Stats::new("estimator.estimate f64-softfloat");
    for k in 0..N {
        let (m, w, a) = point(k);
        let m32 = FloatMeasurements::<f32>::from_fixed(&m);
        let m64 = FloatMeasurements::<f64>::from_fixed(&m);
        let (w32, a32) = (w.to_f64() as f32, a.to_f64() as f32);
        let (w64, a64) = (w.to_f64(), a.to_f64());
        e_fixed.push(ticks(&m, |m| fixed.estimate(m, w, a, 0)), overhead);
        e_f32.push(ticks(&m32, |m| f32e.estimate(m, w32, a32, 0)), overhead);
        e_f64.push(ticks(&m64, |m| f64e.estimate(m, w64, a64, 0)), overhead);
    }
    e_fixed.report();
    e_f32.report();
    e_f64.report();

    // Where the fixed-point instructions go: the parts, measured on their own.
    let geo = *fixed.geometry();
    let law = *fixed.law();
    let screw = *fixed.screw();
    let mut p_pose = Stats::new("part geometry.pose");
    let mut p_mu = Stats::new("part law.mu");
    let mut p_contact = Stats::new("part screw.contact");
    let mut p_sqrt = Stats::new("kernel sqrt_q30");
    let mut p_recip = Stats::new("kernel recip_q30");
    let mut p_exp = Stats::new("kernel exp_neg_q16");
    let mut p_atan2 = Stats::new("kernel atan2 (idsp)");
    for k in 0..N {
        let (m, w, _) = point(k);
        let pose = geo.pose(m.position_counts);
        p_pose.push(ticks(m.position_counts, |c| geo.pose(c)), overhead);
        p_mu.push(ticks(w, |w| law.mu(w)), overhead);
        let mu = law.mu(w);
        let wn = geo.axial_load(&pose, liftfw::model::geometry::Geometry::weight(m.load));
        p_contact.push(
            ticks((mu, wn), |(mu, wn)| screw.contact(mu, 1, wn)),
            overhead,
        );
        let v = (k as u32) << 22 | 0x1234;
        p_sqrt.push(ticks(v, sqrt_q30), overhead);
        p_recip.push(ticks(v | 1 << 20, recip_q30), overhead);
        p_exp.push(ticks((k as u32) << 14, exp_neg_q16), overhead);
        p_atan2.push(
            ticks(
                (pose.sin_alpha, pose.cos_alpha),
                |(s, c): (Ratio, Ratio)| Angle::atan2(s, c),
            ),
            overhead,
        );
    }
    for s in [
        &mut p_pose,
        &mut p_mu,
        &mut p_contact,
        &mut p_sqrt,
        &mut p_recip,
        &mut p_exp,
        &mut p_atan2,
    ] {
        s.report();
    }

    // The stick-slip detector step (issue 7) on a stick-slip sawtooth of the measured torque:
    // 25 → 75 N·m over 50 ticks, then a 3-tick fall, at a steady 3 rad/s reference (the
    // branch test of μ(θ̇) runs once, 50 ms into the steady motion, and is in the max).
    let mut det = liftfw::detect::stickslip::StickSlipDetector::new(
        &liftfw::detect::stickslip::StickSlipConfig::DEFAULT,
        cfg.tick_us,
    );
    let mut s_det = Stats::new("stickslip.step fixed");
    for k in 0..N {
        let ph = (k % 53) as i32;
        let torque = if ph < 50 { 25 + ph } else { 75 - 16 * (ph - 49) };
        let x = liftfw::detect::stickslip::DetectorInputs {
            driving: true,
            direction: 1,
            reference: RadiansPerSecond::from_bits(3 << 16),
            measured_torque: liftfw::units::NewtonMetres::from_bits(torque << 16),
        };
        s_det.push(ticks(&x, |x| det.step(x, &law)), overhead);
    }
    s_det.report();

    println!(
        "ICOUNT-GOAL estimator.step fixed median {} (goal <= 400: {}), f32 median {} ({})",
        fixed_median,
        if fixed_median <= 400 { "met" } else { "OVER" },
        f32_median,
        if fixed_median <= f32_median {
            "fixed no slower"
        } else {
            "fixed SLOWER"
        }
    );
}
