//! BTS7960 H-bridge (e.g. the IBT-2 module) on TIM1 CH1/CH2 plus two enable pins.
//!
//! Each BTS7960 is a complete half-bridge with its own driver and internal dead time:
//! IN high → high side on, IN low → low side on, INH (EN) low → both off. So the bridge
//! takes two independent edge-aligned PWM channels, not complementary outputs:
//!
//! | command        | R_EN, L_EN | RPWM (CH1)   | LPWM (CH2)   | motor                  |
//! |----------------|------------|--------------|--------------|------------------------|
//! | `Coast`        | low        | 0 %          | 0 %          | both halves off        |
//! | `Brake`        | high       | 0 %          | 0 %          | both low sides on      |
//! | `Drive(d > 0)` | high       | \|d\|        | 0 %          | lifts; off-phase brakes|
//! | `Drive(d < 0)` | high       | 0 %          | \|d\|        | lowers; off-phase brakes|
//!
//! During the PWM off-phase both low sides conduct (slow decay), so the motor current is
//! continuous and the average motor voltage is `duty × V_supply`.
//!
//! TIM1 CH4 has no pin: its compare event, placed at the middle of the on-phase, triggers
//! the injected current-sense conversion (see `sensors.rs`).

use embassy_stm32::gpio::{AfType, Flex, Level, Output, OutputType, Speed};
use embassy_stm32::pac::timer::regs::{ArrCore, Ccr1ch};
use embassy_stm32::pac::timer::vals::{Ocm, Urs};
use embassy_stm32::pac::TIM1;
use embassy_stm32::peripherals::{PA8, PA9, PB12, PB13};
use embassy_stm32::timer::{Ch1, Ch2, TimerChannel, TimerPin};
use embassy_stm32::{peripherals, Peri};
use liftfw::control::Bridge;

use super::PWM_FREQUENCY;

/// The motor H-bridge.
pub struct HBridge {
    /// TIM1 and its two pins, configured in [`HBridge::new`]; [`HBridge::apply`] writes the
    /// compare registers directly ([`set_compare`]).
    _tim: Peri<'static, peripherals::TIM1>,
    _rpwm: Flex<'static>,
    _lpwm: Flex<'static>,
    enable_right: Output<'static>,
    enable_left: Output<'static>,
    /// Compare value for 100 % duty (ARR + 1).
    full_scale: u32,
}

/// A PWM pin: low, then TIM1's alternate function for channel `C` (push-pull, very high
/// speed), as embassy-stm32's `PwmPin::new` sets it up. The `TimerPin` bound keeps the HAL's
/// compile-time check: a pin without that function does not build (PA8, PA9: AF6).
fn pwm_pin<C: TimerChannel>(
    pin: Peri<'static, impl TimerPin<peripherals::TIM1, C>>,
) -> Flex<'static> {
    let af = pin.af_num();
    let mut pin = Flex::new(pin);
    pin.set_low();
    pin.set_as_af_unchecked(af, AfType::output(OutputType::PushPull, Speed::VeryHigh));
    pin
}

impl HBridge {
    /// Sets up TIM1 at [`PWM_FREQUENCY`] with both inputs low and the bridge disabled (coast).
    ///
    /// The register writes of embassy-stm32's `SimplePwm::new` (edge-aligned up counting, PWM
    /// mode 1 with preload on every channel, auto-reload preload, main output enable, an update
    /// event to load the preloaded values, counter on) and of the channel set-up that followed
    /// it here, written once each to the registers the RCC reset just cleared: the driver's
    /// period search in 64-bit arithmetic, its assertions and its read-modify-writes were
    /// 0.3 KiB more flash (BENCHMARKS.md, session 7).
    pub fn new(
        tim: Peri<'static, peripherals::TIM1>,
        rpwm: Peri<'static, PA8>,
        lpwm: Peri<'static, PA9>,
        r_en: Peri<'static, PB12>,
        l_en: Peri<'static, PB13>,
    ) -> Self {
        // Enables first, low: nothing may conduct while the timer is being configured.
        let enable_right = Output::new(r_en, Level::Low, Speed::Low);
        let enable_left = Output::new(l_en, Level::Low, Speed::Low);
        let (rpwm, lpwm) = (pwm_pin::<Ch1>(rpwm), pwm_pin::<Ch2>(lpwm));
        // Clock on and reset: every TIM1 register at its reset value (0 but ARR).
        embassy_stm32::rcc::enable_and_reset::<peripherals::TIM1>();
        // Period: the timer clock divided by the PWM frequency (170 MHz / 20 kHz = 8 500
        // clocks), the prescaler and reload of embassy-stm32's `calculate_psc_arr` rounding to
        // the slower period (PSC 0 and ARR 8 499 at 170 MHz).
        let clocks = embassy_stm32::rcc::frequency::<peripherals::TIM1>().0 / PWM_FREQUENCY.0;
        let psc = clocks.saturating_sub(1) >> 16;
        let full_scale = clocks.div_ceil(psc + 1);
        TIM1.psc().write_value(psc as u16);
        TIM1.arr().write_value(ArrCore(full_scale - 1));
        // CH1, CH2 (and the pinless CH3): PWM mode 1, compare preloaded; compares at reset: 0,
        // both inputs low.
        // CH4 drives no pin. PWM mode 2 makes OC4REF rise at CNT = CCR4, and the CC4 event
        // happens there too, so the ADC trigger lands at CCR4 whichever of the two the ADC's
        // "TIM1_CC4" input is wired to.
        for (ccmr, second) in [(0, Ocm::PWM_MODE1), (1, Ocm::PWM_MODE2)] {
            TIM1.ccmr_output(ccmr).write(|w| {
                w.set_ocm(0, Ocm::PWM_MODE1);
                w.set_ocpe(0, true);
                w.set_ocm(1, second);
                w.set_ocpe(1, true);
            });
        }
        set_compare(3, full_scale / 2);
        // Main output enable (an advanced timer's outputs stay off without it).
        TIM1.bdtr().write(|w| w.set_moe(true));
        TIM1.ccer().write(|w| {
            w.set_cce(0, true);
            w.set_cce(1, true);
            w.set_cce(3, true);
        });
        // Auto-reload preload; an update event loads PSC, ARR and the compares (URS: without
        // flagging an update), then the counter runs, edge-aligned, up.
        TIM1.cr1().write(|w| {
            w.set_arpe(true);
            w.set_urs(Urs::COUNTER_ONLY);
        });
        TIM1.egr().write(|w| w.set_ug(true));
        TIM1.cr1().write(|w| {
            w.set_arpe(true);
            w.set_cen(true);
        });
        Self {
            _tim: tim,
            _rpwm: rpwm,
            _lpwm: lpwm,
            enable_right,
            enable_left,
            full_scale,
        }
    }

    /// Applies the core's command. Compare values are preloaded, so the new duty starts
    /// with the next PWM period and both channels change together.
    pub fn apply(&mut self, command: Bridge) {
        let (right, left, enabled) = match command {
            Bridge::Coast => (0, 0, false),
            Bridge::Brake => (0, 0, true),
            Bridge::Drive(q15) => {
                let on = duty_to_compare(q15, self.full_scale);
                if q15 >= 0 {
                    (on, 0, true)
                } else {
                    (0, on, true)
                }
            }
        };
        set_compare(0, right);
        set_compare(1, left);
        // Sample the current in the middle of the on-phase, where the chopped IS output
        // equals the mean motor current. With no on-phase (coast, brake) any point will do.
        let on = right.max(left);
        set_compare(3, if on == 0 { self.full_scale / 2 } else { on / 2 });
        let level = if enabled { Level::High } else { Level::Low };
        self.enable_right.set_level(level);
        self.enable_left.set_level(level);
    }

    /// Compare value for 100 % duty (the PWM resolution: 8 500 steps at 170 MHz / 20 kHz).
    pub fn full_scale(&self) -> u32 {
        self.full_scale
    }
}

/// Writes TIM1's compare register of channel `index` (0 = CH1): the one register write of
/// embassy-stm32's `SimplePwmChannel::set_duty_cycle`, without its assertion that the value is
/// at most the full scale (it read ARR back for each of the three channels every tick; every
/// value written here is at most `full_scale` by construction). 80 B less flash.
fn set_compare(index: usize, value: u32) {
    TIM1.ccr(index).write_value(Ccr1ch(value));
}

/// Q15 duty magnitude → compare value in `0..=full_scale`. `i16::MIN` saturates to 100 %.
fn duty_to_compare(q15: i16, full_scale: u32) -> u32 {
    let magnitude = u32::from(q15.unsigned_abs()).min(i16::MAX as u32);
    // magnitude ≤ 2^15 and full_scale ≤ 2^16: the product fits in u32.
    magnitude * full_scale / i16::MAX as u32
}
