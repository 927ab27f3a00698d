//! BTS7960 H-bridge (e.g. the IBT-2 module) on TIM1 CH1/CH2 plus two enable pins.
//!
//! Each BTS7960 is a complete half-bridge with its own driver and internal dead time:
//! IN high → high side on, IN low → low side on, INH (EN) low → both off. So the bridge
//! takes two independent edge-aligned PWM channels, not complementary outputs (TIM1's own
//! dead-time generator stays off: BDTR.DTG = 0):
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
//! the injected current-sense conversion (see `sensors.rs`). Everything here is
//! embassy-stm32's `SimplePwm`.

use embassy_stm32::gpio::{Level, Output, OutputType, Speed};
use embassy_stm32::peripherals::{PA8, PA9, PB12, PB13, TIM1};
use embassy_stm32::timer::low_level::{CountingMode, OutputCompareMode};
use embassy_stm32::timer::simple_pwm::{PwmPin, SimplePwm};
use embassy_stm32::timer::Channel;
use embassy_stm32::Peri;
use liftfw::control::Bridge;

use super::PWM_FREQUENCY;

/// The motor H-bridge.
pub struct HBridge {
    pwm: SimplePwm<'static, TIM1>,
    enable_right: Output<'static>,
    enable_left: Output<'static>,
    /// Compare value for 100 % duty (ARR + 1).
    full_scale: u32,
}

impl HBridge {
    /// Sets up TIM1 at [`PWM_FREQUENCY`] with both inputs low and the bridge disabled (coast).
    ///
    /// `SimplePwm::new`: edge-aligned up counting, PWM mode 1 with preload on every channel,
    /// auto-reload preload, main output enable (BDTR.MOE), an update event to load the
    /// preloaded values, counter on. At 170 MHz: PSC 0, ARR 8 499.
    pub fn new(
        tim: Peri<'static, TIM1>,
        rpwm: Peri<'static, PA8>,
        lpwm: Peri<'static, PA9>,
        r_en: Peri<'static, PB12>,
        l_en: Peri<'static, PB13>,
    ) -> Self {
        // Enables first, low: nothing may conduct while the timer is being configured.
        let enable_right = Output::new(r_en, Level::Low, Speed::Low);
        let enable_left = Output::new(l_en, Level::Low, Speed::Low);
        let mut pwm = SimplePwm::new(
            tim,
            Some(PwmPin::new(rpwm, OutputType::PushPull)),
            Some(PwmPin::new(lpwm, OutputType::PushPull)),
            None,
            None,
            PWM_FREQUENCY,
            CountingMode::EdgeAlignedUp,
        );
        let full_scale = pwm.max_duty_cycle();
        for channel in [Channel::Ch1, Channel::Ch2] {
            let mut ch = pwm.channel(channel);
            ch.set_duty_cycle_fully_off();
            ch.enable();
        }
        // CH4 drives no pin. PWM mode 2 makes OC4REF rise at CNT = CCR4, and the CC4 event
        // happens there too, so the ADC trigger lands at CCR4 whichever of the two the
        // ADC's "TIM1_CC4" input is wired to.
        {
            let mut ch4 = pwm.ch4();
            ch4.set_output_compare_mode(OutputCompareMode::PwmMode2);
            ch4.set_duty_cycle(full_scale / 2);
            ch4.enable();
        }
        Self {
            pwm,
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
        self.pwm.ch1().set_duty_cycle(right);
        self.pwm.ch2().set_duty_cycle(left);
        // Sample the current in the middle of the on-phase, where the chopped IS output
        // equals the mean motor current. With no on-phase (coast, brake) any point will do.
        let on = right.max(left);
        self.pwm
            .ch4()
            .set_duty_cycle(if on == 0 { self.full_scale / 2 } else { on / 2 });
        let level = if enabled { Level::High } else { Level::Low };
        self.enable_right.set_level(level);
        self.enable_left.set_level(level);
    }

    /// Compare value for 100 % duty (the PWM resolution: 8 500 steps at 170 MHz / 20 kHz).
    pub fn full_scale(&self) -> u32 {
        self.full_scale
    }
}

/// Q15 duty magnitude → compare value in `0..=full_scale`. `i16::MIN` saturates to 100 %.
fn duty_to_compare(q15: i16, full_scale: u32) -> u32 {
    let magnitude = u32::from(q15.unsigned_abs()).min(i16::MAX as u32);
    // magnitude ≤ 2^15 and full_scale ≤ 2^16: the product fits in u32.
    magnitude * full_scale / i16::MAX as u32
}
