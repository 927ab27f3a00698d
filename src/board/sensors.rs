//! Everything the control tick samples: encoder counter, current sense, supply voltage,
//! limit switches and buttons. The board hands over raw codes; scaling is the core's job.
//!
//! All of it through embassy-stm32's drivers (`Qei`, the low-level `Timer`, `Adc` and its
//! injected sequence, `Input`) but for one register field: TIM4's master mode (CR2.MMS), which
//! `Qei` does not set and which the edge timestamps need (see [`Sensors::new`]). The edge timer
//! is the low-level `Timer` rather than `InputCapture`, which captures from a pin and awaits an
//! interrupt: here the capture comes from TIM4's internal trigger (TRC) and the tick polls it.

use embassy_stm32::adc::{Adc, AdcChannel, AnyAdcChannel, Exten, InjectedAdc, SampleTime};
use embassy_stm32::gpio::{Input, Pull};
use embassy_stm32::peripherals::{
    ADC1, ADC2, PA0, PA1, PA4, PB10, PB11, PB14, PB15, PB5, PB6, PB7, TIM3, TIM4,
};
use embassy_stm32::time::Hertz;
use embassy_stm32::timer::low_level::{
    InputCaptureMode, InputTISelection, MasterMode, SlaveMode, Timer, TriggerSource,
};
use embassy_stm32::timer::qei::{Qei, QeiMode};
use embassy_stm32::timer::Channel;
use embassy_stm32::triggers::TIM1_CC4;
use embassy_stm32::Peri;
use liftfw::control::{Inputs, Switches};

/// Sample time of the current-sense channels: 47.5 ADC cycles at 42.5 MHz = 1.1 µs, enough
/// for the ≈1 kΩ source impedance of the IBT-2's IS resistors at 12 bits.
const CURRENT_SAMPLE_TIME: SampleTime = SampleTime::CYCLES47_5;

/// Sample time of the supply divider (47k/10k, 8.2 kΩ source, 100 nF at the pin):
/// 247.5 cycles = 5.8 µs. Read once per tick, blocking.
const SUPPLY_SAMPLE_TIME: SampleTime = SampleTime::CYCLES247_5;

/// The peripherals [`Sensors`] takes over (named for their function, see docs/board.md).
pub struct SensorPeripherals {
    /// Timer in encoder mode.
    pub encoder_timer: Peri<'static, TIM4>,
    /// Encoder channel A.
    pub encoder_a: Peri<'static, PB6>,
    /// Encoder channel B.
    pub encoder_b: Peri<'static, PB7>,
    /// Free-running 1 MHz timer that timestamps every encoder count (no pins).
    pub edge_timer: Peri<'static, TIM3>,
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
    encoder: Qei<'static, TIM4>,
    edge_timer: Timer<'static, TIM3>,
    current: InjectedAdc<'static, ADC1, 2>,
    supply_adc: Adc<'static, ADC2>,
    supply: AnyAdcChannel<'static, ADC2>,
    switches: SwitchInputs,
}

impl Sensors {
    /// Configures the encoder timer, both ADCs and the switch inputs.
    pub fn new(p: SensorPeripherals) -> Self {
        // Mode 3 counts every edge of A and B: 4 counts per encoder line. Pull-ups suit the
        // open-collector Hall encoders common on 12 V gear motors.
        let encoder = Qei::new(
            p.encoder_timer,
            p.encoder_a,
            p.encoder_b,
            embassy_stm32::timer::qei::Config {
                ch1_pull: Pull::Up,
                ch2_pull: Pull::Up,
                mode: QeiMode::Mode3,
                auto_reload: u16::MAX,
            },
        );

        // Edge timestamps for the core's sub-count position (`liftfw::control::edges`): TIM4
        // puts its encoder clock (one pulse per count, either direction) on TRGO; TIM3 counts
        // free at 1 MHz and captures its counter into CCR1 on that trigger (CC1 input = TRC,
        // trigger ITR3 = tim4_trgo, RM0440 "TIMx internal trigger connection").
        // `Qei` owns TIM4's driver and has no master-mode setting, and a second driver on
        // TIM4 would reset it (`Timer::new`): this one field is written through the PAC.
        embassy_stm32::pac::TIM4
            .cr2()
            .modify(|w| w.set_mms(MasterMode::ENCODER_CLOCK_OUTPUT));
        let mut edge_timer = Timer::new(p.edge_timer);
        edge_timer.set_tick_freq(Hertz(1_000_000));
        edge_timer.set_max_compare_value(u16::MAX);
        edge_timer.set_trigger_source(TriggerSource::ITR3);
        edge_timer.set_slave_mode(SlaveMode::DISABLED);
        edge_timer.set_input_ti_selection(Channel::Ch1, InputTISelection::TRC);
        edge_timer.set_input_capture_mode(Channel::Ch1, InputCaptureMode::Rising);
        edge_timer.enable_channel(Channel::Ch1, true);
        edge_timer.start();

        // Both ADCs before any conversion starts: ADC1 and ADC2 share their clock and reset
        // (the HAL counts their users: only the first `Adc::new` resets them). Each one: out of
        // deep power-down, regulator on, calibration (single-ended, then differential),
        // enable; ADC12's clock prescaler ÷4 (42.5 MHz from the 170 MHz kernel clock).
        let current_adc = Adc::new(p.current_adc, Default::default());
        let supply_adc = Adc::new(p.supply_adc, Default::default());

        // R_IS and L_IS as one injected sequence (two ranks: IN1, IN2), started by TIM1's CC4
        // event (JEXTSEL TIM1_CC4, rising edge) in the middle of every PWM on-phase (20 kHz);
        // the data registers always hold the latest pair.
        let current = current_adc.setup_injected_conversions(
            [
                (p.current_right.degrade_adc(), CURRENT_SAMPLE_TIME),
                (p.current_left.degrade_adc(), CURRENT_SAMPLE_TIME),
            ],
            TIM1_CC4,
            Exten::RISING_EDGE,
            false,
        );

        Self {
            encoder,
            edge_timer,
            current,
            supply_adc,
            supply: p.supply.degrade_adc(),
            switches: SwitchInputs {
                // Pull-ups everywhere: a cut wire reads as "limit reached" / "STOP pressed"
                // on the normally-closed inputs, and as "not pressed" on UP/DOWN.
                limit_upper: Input::new(p.limit_upper, Pull::Up),
                limit_lower: Input::new(p.limit_lower, Pull::Up),
                button_up: Input::new(p.button_up, Pull::Up),
                button_down: Input::new(p.button_down, Pull::Up),
                button_stop: Input::new(p.button_stop, Pull::Up),
            },
        }
    }

    /// Samples every input for one control tick (≈10 µs, dominated by the supply conversion).
    pub fn sample(&mut self) -> Inputs {
        // JDR1 = R_IS, JDR2 = L_IS; the driver then clears JEOS.
        let [right, left] = self.current.read_injected_samples();
        // Count and capture must belong together: an edge between the reads would pair the
        // old count with the new edge time, so read the capture around the count.
        let (encoder_count, edge) = loop {
            let edge = self.edge_timer.get_capture_value(Channel::Ch1);
            let count = self.encoder.count();
            if self.edge_timer.get_capture_value(Channel::Ch1) == edge {
                break (count, edge);
            }
        };
        let now = self.edge_timer.regs_core().cnt().read().cnt();
        Inputs {
            encoder_count,
            encoder_edge_age: now.wrapping_sub(edge),
            // Only the conducting high side sources IS current; the idle one reads ≈ 0,
            // so the larger code is the active side's. 12-bit codes, as the core expects.
            current_raw: right.max(left),
            // One regular conversion of PA4 (IN17) on ADC2, software-started: the driver writes
            // the one-rank sequence and the sample time, starts and waits for EOS (≈ 6 µs).
            supply_raw: self
                .supply_adc
                .blocking_read(&mut self.supply, SUPPLY_SAMPLE_TIME),
            switches: self.switches.read(),
        }
    }
}

/// The five digital inputs, with their wiring polarity resolved here.
struct SwitchInputs {
    limit_upper: Input<'static>,
    limit_lower: Input<'static>,
    button_up: Input<'static>,
    button_down: Input<'static>,
    button_stop: Input<'static>,
}

impl SwitchInputs {
    /// Raw (undebounced) levels as the core's active-high bit set (five reads of GPIOB's
    /// input register, ns apart).
    fn read(&self) -> Switches {
        let bit = |active: bool, mask: u8| if active { mask } else { 0 };
        Switches(
            // Normally closed to GND: open (active, or wire cut) pulls high.
            bit(self.limit_upper.is_high(), Switches::LIMIT_UPPER)
                | bit(self.limit_lower.is_high(), Switches::LIMIT_LOWER)
                | bit(self.button_stop.is_high(), Switches::BUTTON_STOP)
                // Normally open to GND: pressed pulls low.
                | bit(self.button_up.is_low(), Switches::BUTTON_UP)
                | bit(self.button_down.is_low(), Switches::BUTTON_DOWN),
        )
    }
}
