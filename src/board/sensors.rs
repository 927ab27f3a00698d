//! Everything the control tick samples: encoder counter, current sense, supply voltage,
//! limit switches and buttons. The board hands over raw codes; scaling is the core's job.

use embassy_stm32::adc::{AdcChannel, AnyAdcChannel, Exten, InjectedTrigger, SampleTime};
use embassy_stm32::gpio::{AfType, Flex, Input, Pull};
use embassy_stm32::pac::adc::vals::Adcaldif;
use embassy_stm32::pac::adccommon::vals::Presc;
use embassy_stm32::pac::timer::regs::ArrCore;
use embassy_stm32::pac::timer::vals::{CcmrInputCcs, Mms, Sms, Ts, Urs};
use embassy_stm32::pac::{ADC1 as Adc1, ADC12_COMMON, ADC2 as Adc2, TIM3, TIM4};
use embassy_stm32::peripherals::{
    ADC1, ADC2, PA0, PA1, PA4, PB10, PB11, PB14, PB15, PB5, PB6, PB7, TIM3 as Tim3, TIM4 as Tim4,
};
use embassy_stm32::timer::{Ch1, Ch2, TimerChannel, TimerPin};
use embassy_stm32::triggers::TIM1_CC4;
use embassy_stm32::Peri;
use liftfw::control::{Inputs, Switches};

/// Sample time of the current-sense channels: 47.5 ADC cycles at 42.5 MHz = 1.1 µs, enough
/// for the ≈1 kΩ source impedance of the IBT-2's IS resistors at 12 bits.
const CURRENT_SAMPLE_TIME: SampleTime = SampleTime::CYCLES47_5;

/// Sample time of the supply divider (47k/10k, 8.2 kΩ source, 100 nF at the pin):
/// 247.5 cycles = 5.8 µs. Read once per tick, blocking.
const SUPPLY_SAMPLE_TIME: SampleTime = SampleTime::CYCLES247_5;

/// An encoder input: TIM4's alternate function for channel `C` with the pull-up (what
/// `Qei::new` makes of it). The `TimerPin` bound keeps the HAL's compile-time check: a pin
/// without that function does not build (PB6, PB7: AF2).
fn encoder_pin<C: TimerChannel>(pin: Peri<'static, impl TimerPin<Tim4, C>>) -> Flex<'static> {
    let af = pin.af_num();
    let mut pin = Flex::new(pin);
    pin.set_as_af_unchecked(af, AfType::input(Pull::Up));
    pin
}

/// The peripherals [`Sensors`] takes over (named for their function, see docs/board.md).
pub struct SensorPeripherals {
    /// Timer in encoder mode.
    pub encoder_timer: Peri<'static, Tim4>,
    /// Encoder channel A.
    pub encoder_a: Peri<'static, PB6>,
    /// Encoder channel B.
    pub encoder_b: Peri<'static, PB7>,
    /// Free-running 1 MHz timer that timestamps every encoder count (no pins).
    pub edge_timer: Peri<'static, Tim3>,
    /// ADC for current sense (injected conversions triggered by TIM1 CC4).
    pub current_adc: Peri<'static, ADC1>,
    /// BTS7960 R_IS (lifting half-bridge).
    pub current_right: Peri<'static, PA0>,
    /// BTS7960 L_IS (lowering half-bridge).
    pub current_left: Peri<'static, PA1>,
    /// ADC for the supply voltage (software triggered).
    pub supply_adc: Peri<'static, ADC2>,
    /// Supply divider tap.
    pub supply: Peri<'static, PA4>,
    /// Upper limit switch (NC to GND).
    pub limit_upper: Peri<'static, PB10>,
    /// Lower limit switch (NC to GND).
    pub limit_lower: Peri<'static, PB11>,
    /// UP button (NO to GND).
    pub button_up: Peri<'static, PB14>,
    /// DOWN button (NO to GND).
    pub button_down: Peri<'static, PB15>,
    /// STOP button (NC to GND).
    pub button_stop: Peri<'static, PB5>,
}

/// The board's sensors, sampled once per control tick.
pub struct Sensors {
    /// TIM4 in encoder mode and its pins (A, B), configured in [`Sensors::new`] and read
    /// through the PAC.
    _encoder: (Peri<'static, Tim4>, Flex<'static>, Flex<'static>),
    /// TIM3, the edge timer, configured in [`Sensors::new`] and read through the PAC.
    _edge_timer: Peri<'static, Tim3>,
    /// ADC1 running R_IS and L_IS as an injected sequence and ADC2 converting the supply
    /// divider on request (both set up in [`Sensors::new`], read through the PAC), and their
    /// pins (R_IS, L_IS, supply).
    _adcs: (
        Peri<'static, ADC1>,
        Peri<'static, ADC2>,
        [AnyAdcChannel<'static, ADC1>; 2],
        AnyAdcChannel<'static, ADC2>,
    ),
    switches: SwitchInputs,
}

impl Sensors {
    /// Configures the encoder timer, both ADCs and the switch inputs.
    pub fn new(p: SensorPeripherals) -> Self {
        // The two timers are set up with the register writes of embassy-stm32's `Qei::new` and
        // of the `Timer` calls that set up the edge timer before, each register written once
        // right after the RCC reset cleared it: the drivers' read-modify-writes, update events
        // and run-time prescaler with its assertion were 0.16 KiB more flash (BENCHMARKS.md,
        // session 7).
        //
        // TIM4, encoder mode 3: counts every edge of A and B (4 counts per encoder line), both
        // channels inputs on their own pins (CCxS = 01, rising polarity), the full 16-bit
        // range. It puts its encoder clock (one pulse per count, either direction) on TRGO for
        // the edge timer.
        embassy_stm32::rcc::enable_and_reset::<Tim4>();
        TIM4.ccmr_input(0).write(|w| {
            w.set_ccs(0, CcmrInputCcs::TI4);
            w.set_ccs(1, CcmrInputCcs::TI4);
        });
        TIM4.ccer().write(|w| {
            w.set_cce(0, true);
            w.set_cce(1, true);
        });
        TIM4.smcr().write(|w| w.set_sms(Sms::ENCODER_MODE_3));
        TIM4.arr().write_value(ArrCore(u16::MAX.into()));
        TIM4.cr2().write(|w| w.set_mms(Mms::ENCODER_CLOCK_OUTPUT));
        TIM4.cr1().write(|w| w.set_cen(true));
        // PB6, PB7: TIM4_CH1/CH2, inputs with pull-ups (they suit the open-collector Hall
        // encoders common on 12 V gear motors).
        let encoder_a = encoder_pin::<Ch1>(p.encoder_a);
        let encoder_b = encoder_pin::<Ch2>(p.encoder_b);

        // Edge timestamps for the core's sub-count position (`liftfw::control::edges`): TIM3
        // counts free at 1 MHz over the full 16 bits and captures its counter into CCR1 on
        // TIM4's trigger (CC1 input = TRC, trigger ITR3 = tim4_trgo, RM0440 "TIMx internal
        // trigger connection"; slave mode off, rising polarity). The prescaler is embassy's
        // `set_tick_freq`'s: the timer clock (170 MHz) over 1 MHz, minus one.
        embassy_stm32::rcc::enable_and_reset::<Tim3>();
        let ticks_per_us = embassy_stm32::rcc::frequency::<Tim3>().0 / 1_000_000;
        TIM3.psc()
            .write_value(ticks_per_us.saturating_sub(1) as u16);
        TIM3.arr().write_value(ArrCore(u16::MAX.into()));
        TIM3.smcr().write(|w| w.set_ts(Ts::ITR3));
        TIM3.ccmr_input(0)
            .write(|w| w.set_ccs(0, CcmrInputCcs::TRC));
        TIM3.ccer().write(|w| w.set_cce(0, true));
        // An update event loads the prescaler (URS: without flagging an update), then count.
        TIM3.cr1().write(|w| w.set_urs(Urs::COUNTER_ONLY));
        TIM3.egr().write(|w| w.set_ug(true));
        TIM3.cr1().write(|w| {
            w.set_urs(Urs::COUNTER_ONLY);
            w.set_cen(true);
        });

        // The ADCs at register level, with the register writes of embassy-stm32's drivers
        // (`Adc::new`, `setup_injected_conversions`, `blocking_read`, `read_injected_samples`;
        // 440 B less flash than the drivers, BENCHMARKS.md session 7). Both ADCs before any
        // conversion starts: ADC1 and ADC2 share their clock and reset (the HAL counts the
        // users of both: only the first call resets them). Then `Adc::new`'s writes for each
        // ([`adc_start`]), the common prescaler once.
        embassy_stm32::rcc::enable_and_reset::<ADC1>();
        embassy_stm32::rcc::enable_and_reset::<ADC2>();
        let kernel_hz = embassy_stm32::rcc::frequency::<ADC1>().0;
        ADC12_COMMON
            .ccr()
            .modify(|w| w.set_presc(adc_prescaler(kernel_hz)));
        adc_start(Adc1);
        adc_start(Adc2);

        // R_IS and L_IS as one injected sequence, started by TIM1's CC4 event in the middle
        // of every PWM on-phase (20 kHz); the data registers always hold the latest pair.
        // The register writes of embassy-stm32's `setup_injected_conversions`: the pins in
        // analog mode (`degrade_adc`), both sample times, the sequence (two ranks: R_IS, L_IS)
        // with its trigger in one JSQR write (the injected queue is off, CFGR.JQDIS's reset
        // value, so JSQR takes the value as written), then JADSTART. (JDISCEN and JEOSIE keep
        // their reset value, off, as the driver set them; ADC1 is enabled already.)
        let right = p.current_right.degrade_adc();
        let left = p.current_left.degrade_adc();
        let (right_ch, left_ch) = (right.get_hw_channel(), left.get_hw_channel());
        // Channels 0..=9 have their sample time in SMPR1 (PA0 = IN1, PA1 = IN2).
        Adc1.smpr().modify(|w| {
            w.set_smp(usize::from(right_ch), CURRENT_SAMPLE_TIME);
            w.set_smp(usize::from(left_ch), CURRENT_SAMPLE_TIME);
        });
        Adc1.jsqr().write(|w| {
            w.set_jl(1);
            w.set_jsq(0, right_ch);
            w.set_jsq(1, left_ch);
            w.set_jextsel(InjectedTrigger::<ADC1>::signal(&TIM1_CC4));
            w.set_jexten(Exten::RISING_EDGE);
        });
        Adc1.cr().modify(|w| w.set_jadstart(true));

        // The supply divider on ADC2: one regular conversion of PA4 (IN17, analog mode through
        // `degrade_adc`) at 247.5 cycles, software-started each tick. The HAL's
        // `blocking_read` wrote this sequence (SQR1: one rank; the sample time; every other
        // SMPR/SQR field and DIFSEL zero, their reset values) before every conversion; it is
        // written once here, as nothing else uses ADC2.
        let supply = p.supply.degrade_adc();
        let supply_ch = supply.get_hw_channel();
        if supply_ch <= 9 {
            Adc2.smpr()
                .modify(|w| w.set_smp(usize::from(supply_ch), SUPPLY_SAMPLE_TIME));
        } else {
            Adc2.smpr2()
                .modify(|w| w.set_smp(usize::from(supply_ch - 10), SUPPLY_SAMPLE_TIME));
        }
        Adc2.sqr1().write(|w| {
            w.set_l(0);
            w.set_sq(0, supply_ch);
        });

        Self {
            _encoder: (p.encoder_timer, encoder_a, encoder_b),
            _edge_timer: p.edge_timer,
            _adcs: (p.current_adc, p.supply_adc, [right, left], supply),
            switches: SwitchInputs {
                // Pull-ups everywhere: a cut wire reads as "limit reached" / "STOP pressed"
                // on the normally-closed inputs, and as "not pressed" on UP/DOWN.
                _limit_upper: Input::new(p.limit_upper, Pull::Up),
                _limit_lower: Input::new(p.limit_lower, Pull::Up),
                _button_up: Input::new(p.button_up, Pull::Up),
                _button_down: Input::new(p.button_down, Pull::Up),
                _button_stop: Input::new(p.button_stop, Pull::Up),
            },
        }
    }

    /// Samples every input for one control tick (≈10 µs, dominated by the supply conversion).
    pub fn sample(&mut self) -> Inputs {
        // The injected data registers (JDR1 = R_IS, JDR2 = L_IS), then JEOS cleared (by the
        // read-modify-write of ADC_ISR that `read_injected_samples` does).
        let [right, left] = [Adc1.jdr(0).read().jdata(), Adc1.jdr(1).read().jdata()];
        Adc1.isr().modify(|w| w.set_jeos(true));
        // Count and capture must belong together: an edge between the reads would pair the
        // old count with the new edge time, so read the capture around the count.
        let capture = || TIM3.ccr(0).read().ccr();
        let (encoder_count, edge) = loop {
            let edge = capture();
            let count = TIM4.cnt().read().cnt();
            if capture() == edge {
                break (count, edge);
            }
        };
        let now = TIM3.cnt().read().cnt();
        Inputs {
            encoder_count,
            encoder_edge_age: now.wrapping_sub(edge),
            // Only the conducting high side sources IS current; the idle one reads ≈ 0,
            // so the larger code is the active side's. 12-bit codes, as the core expects.
            current_raw: right.max(left),
            supply_raw: read_supply(),
            switches: self.switches.read(),
        }
    }
}

/// The supply divider's conversion on ADC2 (≈ 6 µs): the HAL's `convert` (EOS and EOC
/// cleared, ADSTART, wait for EOS) and the data register. A single conversion ends with ADSTART
/// cleared by the ADC, so no conversion is under way when the next tick starts one (the HAL's
/// `stop` found none either).
fn read_supply() -> u16 {
    Adc2.isr().modify(|w| {
        w.set_eos(true);
        w.set_eoc(true);
    });
    Adc2.cr().modify(|w| w.set_adstart(true));
    while !Adc2.isr().read().eos() {}
    Adc2.dr().read().rdata()
}

/// ADC12's clock prescaler for a kernel clock of `hz`: the smallest that keeps the ADC clock at
/// most 60 MHz (embassy-stm32's `from_ker_ck`; 170 MHz → ÷4 = 42.5 MHz).
fn adc_prescaler(hz: u32) -> Presc {
    match hz.saturating_sub(1) / 60_000_000 {
        0 => Presc::DIV1,
        1 => Presc::DIV2,
        2..=3 => Presc::DIV4,
        4..=5 => Presc::DIV6,
        6..=7 => Presc::DIV8,
        8..=9 => Presc::DIV10,
        10..=11 => Presc::DIV12,
        _ => panic!("ADC kernel clock above 720 MHz"),
    }
}

/// Powers up, calibrates and enables one ADC, single conversions on a software start: the
/// register writes of embassy-stm32's `Adc::new` for the G4 with the default configuration,
/// one copy for both ADCs. (`Adc::new` also set DIFSEL to all single-ended: its reset value.)
fn adc_start(adc: embassy_stm32::pac::adc::Adc) {
    // `Adc::new`'s waits of 20 µs (the HAL's `block_for_us`: core clock cycles) on
    // embassy-time's 1 MHz clock, whatever the clock tree: 21 ticks from a tick boundary
    // that may have just passed is at least 20 µs.
    let wait_20_us = || embassy_time::block_for(embassy_time::Duration::from_micros(21));
    // Out of deep power-down, the voltage regulator on, and its start-up time.
    adc.cr().modify(|w| {
        w.set_deeppwd(false);
        w.set_advregen(true);
    });
    wait_20_us();
    // Calibrate single-ended, then differential, each followed by the HAL's 20 µs.
    for mode in [Adcaldif::SINGLE_ENDED, Adcaldif::DIFFERENTIAL] {
        adc.cr().modify(|w| w.set_adcaldif(mode));
        adc.cr().modify(|w| w.set_adcal(true));
        while adc.cr().read().adcal() {}
        wait_20_us();
    }
    // Enable: ADRDY cleared (write 1), ADEN, wait for ADRDY.
    while adc.cr().read().addis() {}
    if !adc.cr().read().aden() {
        adc.isr().modify(|w| w.set_adrdy(true));
        adc.cr().modify(|w| w.set_aden(true));
        while !adc.isr().read().adrdy() {}
    }
    adc.cfgr().modify(|w| {
        w.set_cont(false);
        w.set_exten(Exten::DISABLED);
    });
}

/// The five digital inputs, with their wiring polarity resolved here.
struct SwitchInputs {
    // Kept for their configuration (input, pull-up); read together through GPIOB's IDR.
    _limit_upper: Input<'static>,
    _limit_lower: Input<'static>,
    _button_up: Input<'static>,
    _button_down: Input<'static>,
    _button_stop: Input<'static>,
}

/// The switch inputs' pins, all on GPIOB (the types of [`SensorPeripherals`]' fields, and the
/// pin table in `board/mod.rs`): PB10, PB11, PB5 normally closed, PB14, PB15 normally open.
const LIMIT_UPPER_PIN: u32 = 10;
const LIMIT_LOWER_PIN: u32 = 11;
const BUTTON_STOP_PIN: u32 = 5;
const BUTTON_UP_PIN: u32 = 14;
const BUTTON_DOWN_PIN: u32 = 15;

impl SwitchInputs {
    /// Raw (undebounced) levels as the core's active-high bit set, from one read of GPIOB's
    /// input data register (five `Input::is_high` calls, each finding its port and bit at run
    /// time, were 0.1 KiB more of the control task; the five levels are now one sample).
    fn read(&self) -> Switches {
        let idr = embassy_stm32::pac::GPIOB.idr().read().0;
        let high = |pin: u32| idr >> pin & 1 != 0;
        let bit = |active: bool, mask: u8| if active { mask } else { 0 };
        Switches(
            // Normally closed to GND: open (active, or wire cut) pulls high.
            bit(high(LIMIT_UPPER_PIN), Switches::LIMIT_UPPER)
                | bit(high(LIMIT_LOWER_PIN), Switches::LIMIT_LOWER)
                | bit(high(BUTTON_STOP_PIN), Switches::BUTTON_STOP)
                // Normally open to GND: pressed pulls low.
                | bit(!high(BUTTON_UP_PIN), Switches::BUTTON_UP)
                | bit(!high(BUTTON_DOWN_PIN), Switches::BUTTON_DOWN),
        )
    }
}
