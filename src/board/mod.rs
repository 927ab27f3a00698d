//! The default board: STM32G431CB + BTS7960 H-bridge + quadrature encoder (docs/board.md).
//!
//! This module owns every pin and peripheral choice; `main.rs` only sequences tasks.
//! Nothing here decides anything: the control core gets raw counts and codes
//! ([`liftfw::control::Inputs`]) and its [`liftfw::control::Outputs`] are applied verbatim.
//!
//! | Pin  | Peripheral        | Function                                        |
//! |------|-------------------|-------------------------------------------------|
//! | PA8  | TIM1_CH1 (AF6)    | BTS7960 RPWM: lifting half-bridge input, 20 kHz |
//! | PA9  | TIM1_CH2 (AF6)    | BTS7960 LPWM: lowering half-bridge input        |
//! | PB12 | GPIO out          | BTS7960 R_EN (high = right half-bridge enabled) |
//! | PB13 | GPIO out          | BTS7960 L_EN (high = left half-bridge enabled)  |
//! | PA0  | ADC1_IN1 (inj.)   | BTS7960 R_IS current sense                      |
//! | PA1  | ADC1_IN2 (inj.)   | BTS7960 L_IS current sense                      |
//! | PA4  | ADC2_IN17         | 12 V supply through the 47k/10k divider         |
//! | PB6  | TIM4_CH1 (AF2)    | encoder A                                       |
//! | PB7  | TIM4_CH2 (AF2)    | encoder B                                       |
//! | PA2  | USART2_TX (AF7)   | console TX, 115 200 8N1                         |
//! | PA3  | USART2_RX (AF7)   | console RX                                      |
//! | PB10 | GPIO in, pull-up  | upper limit switch, NC to GND (high = active)   |
//! | PB11 | GPIO in, pull-up  | lower limit switch, NC to GND (high = active)   |
//! | PB14 | GPIO in, pull-up  | UP button, NO to GND (low = pressed)            |
//! | PB15 | GPIO in, pull-up  | DOWN button, NO to GND (low = pressed)          |
//! | PB5  | GPIO in, pull-up  | STOP button, NC to GND (high = pressed)         |
//! | PB9  | GPIO out          | holding-brake coil driver (high = released)     |
//!
//! Timers: TIM1 = bridge PWM (its CH4, no pin, triggers the current ADC), TIM2 = embassy-time
//! driver (cargo feature `time-driver-tim2`), TIM4 = encoder, TIM3 = encoder edge timestamps
//! (no pins). SWD stays on PA13/PA14.
//!
//! Every peripheral goes through embassy-stm32's drivers. Through the PAC, because the crate
//! has no driver for them: TIM4's master mode (`sensors.rs`), the IWDG's debug freeze
//! (DBGMCU) and the reset flags (RCC_CSR) in [`Watchdog`], the flash ECC flag in the NMI
//! handler, and GPIOB's set/reset register in the HardFault handler (which cannot reach the
//! drivers the tasks own).

pub mod bridge;
pub mod sensors;

use embassy_stm32::peripherals::{FLASH, PA2, PA3, USART2};
use embassy_stm32::time::Hertz;
use embassy_stm32::wdg::IndependentWatchdog;
use embassy_stm32::{Peri, Peripherals};

pub use bridge::HBridge;
pub use sensors::Sensors;

/// H-bridge PWM frequency: above hearing, and within the BTS7960's switching budget
/// (its datasheet characterises up to 25 kHz).
pub const PWM_FREQUENCY: Hertz = Hertz::khz(20);

/// Independent-watchdog timeout in µs: 50 control ticks at 1 kHz. Long enough to
/// ride out a defmt burst, short enough that a hung loop stops the motor within
/// a fraction of a millimetre of nut travel.
pub const WATCHDOG_TIMEOUT_US: u32 = 50_000;

/// Console baud rate (8N1).
pub const CONSOLE_BAUD: u32 = 115_200;

/// Clock tree: 170 MHz SYSCLK from HSI16 through the PLL (16 / 4 × 85 / 2), range-1 boost.
///
/// HSI keeps the default board crystal-free; its ±1 % is plenty for 115 200 Bd and a
/// 20 kHz PWM. The ADCs run from SYSCLK (the HAL divides it by 4 to 42.5 MHz, under 60 MHz).
pub fn clock_config() -> embassy_stm32::Config {
    use embassy_stm32::rcc::{mux, Pll, PllMul, PllPreDiv, PllRDiv, PllSource, Sysclk};

    let mut config = embassy_stm32::Config::default();
    config.rcc.pll = Some(Pll {
        source: PllSource::HSI,
        prediv: PllPreDiv::DIV4,
        mul: PllMul::MUL85,
        divp: None,
        divq: None,
        divr: Some(PllRDiv::DIV2),
    });
    config.rcc.sys = Sysclk::PLL1_R;
    // Above 150 MHz the core regulator must be in range-1 boost mode (RM0440 §6.1.5): this
    // picks the boost wait states and RM0440's switching sequence; the mode itself is
    // selected by [`init`].
    config.rcc.boost = true;
    config.rcc.mux.adc12sel = mux::Adcsel::SYS;
    config
}

/// The chip at 170 MHz in range-1 boost mode: embassy-stm32 brought up on HSI16, the boost
/// mode selected by hand, then [`clock_config`]'s clock tree.
///
/// embassy-stm32 0.6 selects the boost mode through stm32-metapac 21's PWR_CR5, which has
/// R1MODE at bit 0; RM0440 (PWR_CR5, offset 0x80, reset value 0x0000 0100) has it at bit 8
/// (0 = boost). Its write leaves R1MODE at 1, range-1 normal mode, which RM0440 ("Dynamic
/// voltage scaling management") allows up to 150 MHz only. embassy's `init` resets PWR before
/// it sets the clocks, so the bit is cleared between `init` (left on HSI16) and `reinit`;
/// boost mode at 16 MHz is allowed, and `reinit` then follows RM0440's sequence (AHB / 2,
/// wait states for boost, the switch, AHB / 1).
pub fn init() -> embassy_stm32::Peripherals {
    let mut p = embassy_stm32::init(embassy_stm32::Config::default());
    // RM0440 PWR_CR5: R1MODE (bit 8) = 0, range-1 boost; the other bits are reserved (0).
    embassy_stm32::pac::PWR
        .cr5()
        .write_value(embassy_stm32::pac::pwr::regs::Cr5(0));
    embassy_stm32::rcc::reinit(clock_config().rcc, &mut p.RCC);
    p
}

/// The console UART's peripheral and pins, handed to the console task as they are.
pub struct ConsolePins {
    /// USART2.
    pub usart: Peri<'static, USART2>,
    /// USART2_TX.
    pub tx: Peri<'static, PA2>,
    /// USART2_RX.
    pub rx: Peri<'static, PA3>,
}

/// Everything the control task touches each tick.
pub struct Board {
    /// Motor H-bridge.
    pub bridge: HBridge,
    /// Encoder, ADC channels and switch inputs.
    pub sensors: Sensors,
    /// The independent watchdog, configured; the control task starts it.
    pub watchdog: Watchdog,
    /// The spring-applied holding brake's coil driver.
    pub brake: BrakeOutput,
}

/// The holding brake's output (PB9, push-pull, driving the gate of the coil's low-side
/// MOSFET; docs/board.md). Low, the brake's springs hold it engaged: at reset, while the pin
/// floats (10 kΩ gate pull-down), on a HardFault and whenever the core says so.
pub struct BrakeOutput {
    pin: embassy_stm32::gpio::Output<'static>,
}

impl BrakeOutput {
    /// Power the coil (release the brake) or not (engaged), as
    /// [`liftfw::control::Outputs::brake_release`] says.
    pub fn apply(&mut self, release: bool) {
        if release {
            self.pin.set_high();
        } else {
            self.pin.set_low();
        }
    }
}

/// Flash range of the configuration store, as offsets from the start of flash: the last four
/// 2 KiB pages of the G431's 128 KiB (memory.x gives the program the 120 KiB below it).
pub const STORE_RANGE: core::ops::Range<u32> = 0x1E000..0x20000;

impl Board {
    /// Claims the board's peripherals. The bridge comes up coasting (both enables low)
    /// before anything else runs. The flash goes to the configuration store.
    pub fn new(p: Peripherals) -> (Self, ConsolePins, Peri<'static, FLASH>) {
        let bridge = HBridge::new(p.TIM1, p.PA8, p.PA9, p.PB12, p.PB13);
        // The brake stays engaged (low) from the first instruction on.
        let brake = BrakeOutput {
            pin: embassy_stm32::gpio::Output::new(
                p.PB9,
                embassy_stm32::gpio::Level::Low,
                embassy_stm32::gpio::Speed::Low,
            ),
        };
        let sensors = Sensors::new(sensors::SensorPeripherals {
            encoder_timer: p.TIM4,
            encoder_a: p.PB6,
            encoder_b: p.PB7,
            edge_timer: p.TIM3,
            current_adc: p.ADC1,
            current_right: p.PA0,
            current_left: p.PA1,
            supply_adc: p.ADC2,
            supply: p.PA4,
            limit_upper: p.PB10,
            limit_lower: p.PB11,
            button_up: p.PB14,
            button_down: p.PB15,
            button_stop: p.PB5,
        });
        let watchdog = Watchdog::new(p.IWDG);
        let console = ConsolePins {
            usart: p.USART2,
            tx: p.PA2,
            rx: p.PA3,
        };
        (
            Self {
                bridge,
                sensors,
                watchdog,
                brake,
            },
            console,
            p.FLASH,
        )
    }
}

/// Double-bit ECC errors met while reading the configuration store (counted by the NMI
/// handler; the firmware logs the count after loading).
pub static STORE_ECC_ERRORS: core::sync::atomic::AtomicU32 = core::sync::atomic::AtomicU32::new(0);

/// Flash double-bit ECC errors raise an NMI on the G4. A power cut during a flash program can
/// leave a double word whose ECC does not match: inside the store that is an expected torn
/// write, so the handler clears the flag and lets the read complete with the bad data, which
/// the store's CRCs then reject (and `sequential-storage` repairs). Anywhere else it means the
/// program itself is corrupt: reset.
#[cortex_m_rt::exception]
unsafe fn NonMaskableInt() {
    let eccr = embassy_stm32::pac::FLASH.eccr().read();
    if eccr.eccd() {
        // ADDR_ECC: offset of the failing double word from the start of flash.
        let offset = eccr.addr_ecc();
        // Clear ECCD (write 1), leaving the other flags alone.
        embassy_stm32::pac::FLASH
            .eccr()
            .modify(|w| w.set_eccd(true));
        if STORE_RANGE.contains(&offset) {
            STORE_ECC_ERRORS.fetch_add(1, core::sync::atomic::Ordering::Relaxed);
            return;
        }
    }
    cortex_m::peripheral::SCB::sys_reset();
}

/// Every fault exception ends here, and so does every panic (panic-probe logs the message
/// over defmt, then faults). The bridge's enables go low at once (BTS7960 R_EN =
/// PB12, L_EN = PB13: both half-bridges off, the motor coasts), and so does the holding
/// brake's output (PB9: the brake engages), instead of the last duty running
/// on until the watchdog resets the chip (up to [`WATCHDOG_TIMEOUT_US`]); then wait for that
/// reset (or for a probe, which halts on the HardFault).
#[cortex_m_rt::exception(trampoline = false)]
unsafe fn HardFault() -> ! {
    // Atomic set/reset register: touches only these two pins' outputs.
    embassy_stm32::pac::GPIOB.bsrr().write(|w| {
        w.set_br(9, true);
        w.set_br(12, true);
        w.set_br(13, true);
    });
    loop {
        core::hint::spin_loop();
    }
}

/// The IWDG, fed only on the core's say-so ([`liftfw::control::Outputs::feed_watchdog`]):
/// embassy-stm32's `IndependentWatchdog` (for 50 ms at the 32 kHz LSI it picks prescaler ÷4,
/// PR = 0, and reload 399). The debug freeze and the reset flag have no driver in
/// embassy-stm32: they are one register field each, through the PAC.
pub struct Watchdog {
    iwdg: IndependentWatchdog<'static, embassy_stm32::peripherals::IWDG>,
}

impl Watchdog {
    fn new(iwdg: Peri<'static, embassy_stm32::peripherals::IWDG>) -> Self {
        // Freeze the IWDG while a debugger halts the core, so a breakpoint does not reset
        // the chip. No effect without a debugger attached.
        embassy_stm32::pac::DBGMCU
            .apb1lfzr()
            .modify(|w| w.set_iwdg(true));
        Self {
            iwdg: IndependentWatchdog::new(iwdg, WATCHDOG_TIMEOUT_US),
        }
    }

    /// Start it (it cannot be stopped again): the control task does so right before its first
    /// tick, after the configuration was loaded from flash.
    pub fn start(&mut self) {
        self.iwdg.unleash();
    }

    /// True when the last reset came from the IWDG (RCC_CSR.IWDGRSTF); clears the reset flags.
    pub fn caused_last_reset() -> bool {
        let rcc = embassy_stm32::pac::RCC;
        let by_iwdg = rcc.csr().read().iwdgrstf();
        rcc.csr().modify(|w| w.set_rmvf(true));
        by_iwdg
    }

    /// Reloads the counter. Once started the IWDG cannot be stopped: not feeding it for
    /// [`WATCHDOG_TIMEOUT_US`] resets the MCU; its pins then float, and the 10 kΩ
    /// pull-downs on R_EN/L_EN (docs/board.md) make the bridge coast.
    pub fn feed(&mut self) {
        self.iwdg.pet();
    }
}
