//! The STM32G431's peripheral bus as the firmware sees it: the address map (RM0440 ch. 2
//! "Memory map", Table 3 "STM32G4 memory map and peripheral register boundary addresses"),
//! the clock gates, the interrupt lines (RM0440 Table 97, "STM32G4 vector table": FLASH 4,
//! ADC1_2 18, TIM1_BRK 24, TIM1_UP 25, TIM1_TRG_COM 26, TIM1_CC 27, TIM2 28, TIM3 29, TIM4 30,
//! USART2 38), the emulated time, and the board's signals (bridge inputs, switches, sensors).
//!
//! An access to an address with no model, or to a register or bit a model does not implement,
//! sets [`Bus::error`] naming the address and register, and the run stops.

use crate::adc::{self, Adc};
use crate::flash::{self, Flash, Store};
use crate::gpio::{self, Port};
use crate::scs::{self, Scs};
use crate::sys::{self, ClockBit, Dbgmcu, Iwdg, Pwr, Rcc, ResetCause};
use crate::tim::{self, Kind, Timer};
use crate::usart::{self, Usart};
use crate::TICK_HZ;
use std::io::Write;

/// The analog inputs, as 12-bit codes (what the pins carry, V / 3.3 V × 4096).
#[derive(Clone, Copy, Debug, Default)]
pub struct Analog {
    /// PA0: BTS7960 R_IS.
    pub r_is: u16,
    /// PA1: L_IS.
    pub l_is: u16,
    /// PA4: the supply divider.
    pub supply: u16,
}

/// What the bridge inputs and the brake output say.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BoardOut {
    /// R_EN (PB12) and L_EN (PB13) high.
    pub enabled: (bool, bool),
    /// Duty of RPWM (PA8) and LPWM (PA9), 0..=1.
    pub duty: (f64, f64),
    /// PB9: the holding brake's coil powered.
    pub brake_release: bool,
}

/// Peripherals on the bus.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Dev {
    Tim2,
    Tim3,
    Tim4,
    Iwdg,
    Usart2,
    Pwr,
    Tim1,
    Rcc,
    Flash,
    GpioA,
    GpioB,
    Adc1,
    Adc2,
    AdcCommon,
    Scs,
    Dbgmcu,
}

fn decode(addr: u32) -> Option<(Dev, u32, &'static str)> {
    let (dev, base, name) = match addr {
        0x4000_0000..=0x4000_03FF => (Dev::Tim2, 0x4000_0000, "TIM2"),
        0x4000_0400..=0x4000_07FF => (Dev::Tim3, 0x4000_0400, "TIM3"),
        0x4000_0800..=0x4000_0BFF => (Dev::Tim4, 0x4000_0800, "TIM4"),
        0x4000_3000..=0x4000_33FF => (Dev::Iwdg, 0x4000_3000, "IWDG"),
        0x4000_4400..=0x4000_47FF => (Dev::Usart2, 0x4000_4400, "USART2"),
        0x4000_7000..=0x4000_73FF => (Dev::Pwr, 0x4000_7000, "PWR"),
        0x4001_2C00..=0x4001_2FFF => (Dev::Tim1, 0x4001_2C00, "TIM1"),
        0x4002_1000..=0x4002_13FF => (Dev::Rcc, 0x4002_1000, "RCC"),
        0x4002_2000..=0x4002_23FF => (Dev::Flash, 0x4002_2000, "FLASH"),
        0x4800_0000..=0x4800_03FF => (Dev::GpioA, 0x4800_0000, "GPIOA"),
        0x4800_0400..=0x4800_07FF => (Dev::GpioB, 0x4800_0400, "GPIOB"),
        0x5000_0000..=0x5000_00FF => (Dev::Adc1, 0x5000_0000, "ADC1"),
        0x5000_0100..=0x5000_01FF => (Dev::Adc2, 0x5000_0100, "ADC2"),
        0x5000_0300..=0x5000_03FF => (Dev::AdcCommon, 0x5000_0300, "ADC12_COMMON"),
        0xE000_E000..=0xE000_EFFF => (Dev::Scs, 0xE000_E000, "SCS"),
        0xE004_2000..=0xE004_23FF => (Dev::Dbgmcu, 0xE004_2000, "DBGMCU"),
        _ => return None,
    };
    Some((dev, addr - base, name))
}

/// The register at `addr`, by name ("TIM1.CCR1"), for traces and errors.
pub fn register_name(addr: u32) -> String {
    let Some((dev, off, p)) = decode(addr) else {
        return format!("{addr:#010x} (no peripheral modelled there)");
    };
    let reg: Option<String> = match dev {
        Dev::Tim1 | Dev::Tim2 | Dev::Tim3 | Dev::Tim4 => tim::name(off).map(Into::into),
        Dev::Iwdg => sys::iwdg_name(off).map(Into::into),
        Dev::Usart2 => usart::name(off).map(Into::into),
        Dev::Pwr => sys::pwr_name(off).map(Into::into),
        Dev::Rcc => sys::rcc_name(off).map(Into::into),
        Dev::Flash => flash::name(off).map(Into::into),
        Dev::GpioA | Dev::GpioB => gpio::name(off).map(Into::into),
        Dev::Adc1 | Dev::Adc2 => adc::name(off).map(Into::into),
        Dev::AdcCommon => match off {
            0 => Some("CSR".into()),
            8 => Some("CCR".into()),
            0xC => Some("CDR".into()),
            _ => None,
        },
        Dev::Scs => Scs::name(off),
        Dev::Dbgmcu => sys::dbgmcu_name(off).map(Into::into),
    };
    match reg {
        Some(r) => format!("{p}.{r}"),
        None => format!("{p}+{off:#x}"),
    }
}

/// Registers that take narrower accesses: the NVIC/SCB byte registers, the timers' 16-bit
/// registers (CNT, PSC, ARR, CCRx: stm32-metapac declares them 16 bits wide, a half-word store
/// at their address; the upper half is reserved or, on TIM2, zero-extended as the bus does),
/// USART's and the ADCs' data registers.
fn narrow_ok(dev: Dev, off: u32, lane: u32) -> bool {
    match dev {
        Dev::Scs => true,
        Dev::Tim1 | Dev::Tim2 | Dev::Tim3 | Dev::Tim4 => {
            lane == 0 && matches!(off, 0x24 | 0x28 | 0x2C | 0x30 | 0x34 | 0x38 | 0x3C | 0x40)
        }
        Dev::Usart2 => lane == 0 && matches!(off, 0x24 | 0x28),
        // The ADCs' data registers (16-bit fields: embassy-stm32 reads DR as a half-word).
        Dev::Adc1 | Dev::Adc2 => lane == 0 && matches!(off, 0x40 | 0x80 | 0x84 | 0x88 | 0x8C),
        _ => false,
    }
}

/// The clock enable of each peripheral (RM0440 RCC_AHBxENR/APBxENR): register index (see
/// `sys::Rcc`), bit, name.
fn clock(dev: Dev) -> Option<ClockBit> {
    let c = |reg, bit, what| Some(ClockBit { reg, bit, what });
    match dev {
        Dev::Tim2 => c(3, 0, "APB1ENR1.TIM2EN"),
        Dev::Tim3 => c(3, 1, "APB1ENR1.TIM3EN"),
        Dev::Tim4 => c(3, 2, "APB1ENR1.TIM4EN"),
        Dev::Usart2 => c(3, 17, "APB1ENR1.USART2EN"),
        Dev::Pwr => c(3, 28, "APB1ENR1.PWREN"),
        Dev::Tim1 => c(5, 11, "APB2ENR.TIM1EN"),
        Dev::Flash => c(0, 8, "AHB1ENR.FLASHEN"),
        Dev::GpioA => c(1, 0, "AHB2ENR.GPIOAEN"),
        Dev::GpioB => c(1, 1, "AHB2ENR.GPIOBEN"),
        Dev::Adc1 | Dev::Adc2 | Dev::AdcCommon => c(1, 13, "AHB2ENR.ADC12EN"),
        Dev::Iwdg | Dev::Rcc | Dev::Scs | Dev::Dbgmcu => None,
    }
}

/// The voltage code ADC `which` converts on channel `ch`: the board's wiring (ADC1 IN1 = PA0,
/// IN2 = PA1, ADC2 IN17 = PA4), the pin in analog mode.
fn adc_input(gpioa: &Port, analog: Analog, which: u8, ch: u32) -> Result<u16, String> {
    let (pin, code) = match (which, ch) {
        (1, 1) => (0, analog.r_is),
        (1, 2) => (1, analog.l_is),
        (2, 17) => (4, analog.supply),
        _ => {
            return Err(format!(
                "ADC{which} converts IN{ch}, which the board does not wire"
            ))
        }
    };
    if gpioa.mode(pin) != 3 {
        return Err(format!(
            "ADC{which} converts IN{ch} while PA{pin} is not in analog mode"
        ));
    }
    Ok(code)
}

/// Everything on the bus, and the emulated time.
pub struct Bus {
    /// Time (ticks of [`TICK_HZ`]) at instruction count `base_insns`.
    pub base_t: u64,
    /// Instruction count at `base_t`.
    pub base_insns: u64,
    /// Instructions executed since reset.
    pub insns: u64,
    /// Translated blocks executed since reset (statistics).
    pub blocks: u64,
    /// The most instructions in one executed block (statistics).
    pub longest_block: u32,
    /// Register reads, writes and slices of execution since reset (statistics).
    pub stats: [u64; 3],
    /// Ticks per CPU cycle (HCLK): 1 instruction = 1 cycle (docs/fwsim.md).
    pub cycle_ticks: u64,
    /// Stop the slice at this instruction count.
    pub stop_at: u64,
    /// NVIC, SCB.
    pub scs: Scs,
    /// RCC.
    pub rcc: Rcc,
    /// PWR.
    pub pwr: Pwr,
    /// FLASH and the store's pages.
    pub flash: Flash,
    /// GPIOA, GPIOB.
    pub gpioa: Port,
    /// GPIOB.
    pub gpiob: Port,
    /// TIM1.
    pub tim1: Timer,
    /// TIM2.
    pub tim2: Timer,
    /// TIM3.
    pub tim3: Timer,
    /// TIM4.
    pub tim4: Timer,
    /// ADC1, ADC2 and their common registers.
    pub adc1: Adc,
    /// ADC2.
    pub adc2: Adc,
    /// ADC12 common.
    pub adc_common: adc::Common,
    /// USART2.
    pub usart2: Usart,
    /// IWDG.
    pub iwdg: Iwdg,
    dbgmcu: Dbgmcu,
    /// The analog pins.
    pub analog: Analog,
    /// The first unimplemented access or other error: the run stops.
    pub error: Option<String>,
    /// What the firmware did that the chip does not allow but the model can run on (each
    /// said once): a finding to check on the board.
    pub findings: Vec<String>,
    /// The register trace (`--trace-mmio`).
    pub trace: Option<Box<dyn Write>>,
    /// The event register (set by SEV).
    pub event: bool,
    /// The ADC clock in ticks, while RCC and ADC12_CCR are unchanged.
    adc_ticks: Option<u64>,
    /// The plant's last encoder count (4 per line).
    last_count: Option<u16>,
}

impl Bus {
    /// The bus after a reset of cause `cause`, with the store's pages `store`.
    pub fn new(cause: ResetCause, store: Store) -> Self {
        let mut b = Self {
            base_t: 0,
            base_insns: 0,
            insns: 0,
            blocks: 0,
            longest_block: 0,
            stats: [0; 3],
            cycle_ticks: TICK_HZ / sys::HSI_HZ,
            stop_at: 0,
            scs: Scs::default(),
            rcc: Rcc::new(cause),
            pwr: Pwr::default(),
            flash: Flash::new(store),
            gpioa: Port::new('A'),
            gpiob: Port::new('B'),
            tim1: Timer::new("TIM1", Kind::Advanced),
            tim2: Timer::new("TIM2", Kind::General32),
            tim3: Timer::new("TIM3", Kind::General16),
            tim4: Timer::new("TIM4", Kind::General16),
            adc1: Adc::new("ADC1"),
            adc2: Adc::new("ADC2"),
            adc_common: adc::Common::default(),
            usart2: Usart::default(),
            iwdg: Iwdg::new(),
            dbgmcu: Dbgmcu::default(),
            analog: Analog::default(),
            error: None,
            findings: Vec::new(),
            trace: None,
            event: false,
            adc_ticks: None,
            last_count: None,
        };
        b.clocks_changed();
        b
    }

    /// Now, ticks.
    pub fn now(&self) -> u64 {
        self.base_t + (self.insns - self.base_insns) * self.cycle_ticks
    }

    /// Ends the slice after the instruction executing now.
    pub fn end_slice(&mut self) {
        self.stop_at = self.insns;
    }

    /// Moves time forward to `t` without executing (sleep, a flash stall).
    pub fn skip_to(&mut self, t: u64) {
        let now = self.now();
        if t > now {
            self.base_t = t;
            self.base_insns = self.insns;
        }
    }

    /// Ticks per cycle of a clock of `hz`, which must divide [`TICK_HZ`].
    fn ticks_of(hz: u64) -> Result<u64, String> {
        if hz == 0 || !TICK_HZ.is_multiple_of(hz) {
            return Err(format!(
                "a clock of {hz} Hz (the model's time base is {TICK_HZ} Hz)"
            ));
        }
        Ok(TICK_HZ / hz)
    }

    fn clocks_changed(&mut self) {
        self.adc_ticks = None;
        let r = (|| -> Result<(), String> {
            let now = self.now();
            let cpu = Self::ticks_of(self.rcc.hclk()?)?;
            self.base_t = now;
            self.base_insns = self.insns;
            self.cycle_ticks = cpu;
            let [_, _, t1, t2] = self.rcc.apb()?;
            let (t1, t2) = (Self::ticks_of(t1)?, Self::ticks_of(t2)?);
            for t in [&mut self.tim2, &mut self.tim3, &mut self.tim4] {
                t.advance(now);
                t.clk_ticks = t1;
            }
            self.tim1.advance(now);
            self.tim1.clk_ticks = t2;
            Ok(())
        })();
        if let Err(e) = r {
            self.fail(e);
        }
    }

    fn adc_clk(&self) -> Result<u64, String> {
        Self::ticks_of(self.rcc.adc12_hz()? / self.adc_common.divider()?)
    }

    /// The ADC clock's ticks, recomputed when RCC or ADC12_CCR is written (the ADCs are read
    /// hundreds of times per millisecond while the firmware polls a conversion).
    fn adc_clk_cached(&mut self) -> Result<u64, String> {
        if let Some(t) = self.adc_ticks {
            return Ok(t);
        }
        let t = self.adc_clk()?;
        self.adc_ticks = Some(t);
        Ok(t)
    }

    /// Records the first error.
    pub fn fail(&mut self, e: String) {
        if self.error.is_none() {
            self.error = Some(e);
        }
    }

    /// ADC `which` with what it needs from the rest of the bus (the analog pins, TIM1's CC4).
    fn adc_with<R>(
        &mut self,
        which: u8,
        adc_clk: u64,
        f: impl FnOnce(&mut Adc, &adc::Env) -> R,
    ) -> R {
        let now = self.now();
        let (gpioa, analog, tim1) = (&self.gpioa, self.analog, &self.tim1);
        let input = |ch: u32| adc_input(gpioa, analog, which, ch);
        let cc4 = |t: u64| tim1.last_match(3, t);
        let env = adc::Env {
            now,
            adc_clk,
            input: &input,
            tim1_cc4_before: &cc4,
        };
        let a = if which == 1 {
            &mut self.adc1
        } else {
            &mut self.adc2
        };
        f(a, &env)
    }

    fn adc_access(&mut self, which: u8, write: Option<u32>, off: u32) -> Result<u32, String> {
        let adc_clk = self.adc_clk_cached()?;
        self.adc_with(which, adc_clk, |a, env| match write {
            Some(v) => a.write(off, v, env).map(|()| 0),
            None => a.read(off, env),
        })
    }

    /// ADC `which`'s interrupt line.
    fn adc_line(&mut self, which: u8) -> bool {
        let Ok(adc_clk) = self.adc_clk_cached() else {
            return false;
        };
        self.adc_with(which, adc_clk, |a, env| a.line(env))
    }

    /// A CPU read of `size` bytes at `addr` (a mapped peripheral region).
    pub fn read(&mut self, addr: u32, size: usize) -> u32 {
        self.stats[0] += 1;
        let r = self.read_inner(addr, size);
        let v = match r {
            Ok(v) => v,
            Err(e) => {
                self.fail(format!(
                    "{e} (read at {addr:#010x}, {})",
                    register_name(addr)
                ));
                0
            }
        };
        self.trace_access('R', addr, v);
        v
    }

    fn read_inner(&mut self, addr: u32, size: usize) -> Result<u32, String> {
        let word = addr & !3;
        let lane = (addr & 3) * 8;
        let (dev, off, _) = decode(word).ok_or("no peripheral modelled at this address")?;
        if size != 4 && !narrow_ok(dev, off, addr & 3) {
            return Err(format!("{size}-byte read"));
        }
        if let Some(c) = clock(dev) {
            self.rcc.check(c)?;
        }
        let now = self.now();
        let v = match dev {
            Dev::Tim1 => self.tim1.read(off, now)?,
            Dev::Tim2 => self.tim2.read(off, now)?,
            Dev::Tim3 => self.tim3.read(off, now)?,
            Dev::Tim4 => self.tim4.read(off, now)?,
            Dev::Iwdg => self.iwdg.read(off, now)?,
            Dev::Usart2 => self.usart2.read(off, now)?,
            Dev::Pwr => self.pwr.read(off)?,
            Dev::Rcc => self.rcc.read(off, now)?,
            Dev::Flash => self.flash.read(off, now)?,
            Dev::GpioA => self.gpioa.read(off)?,
            Dev::GpioB => self.gpiob.read(off)?,
            Dev::Adc1 => self.adc_access(1, None, off)?,
            Dev::Adc2 => self.adc_access(2, None, off)?,
            Dev::AdcCommon => self.adc_common.read(off)?,
            Dev::Scs => self.scs.read(off)?,
            Dev::Dbgmcu => self.dbgmcu.read(off)?,
        };
        let mask = if size == 4 {
            u32::MAX
        } else {
            (1 << (8 * size)) - 1
        };
        Ok(v >> lane & mask)
    }

    /// A CPU write of `size` bytes at `addr`.
    pub fn write(&mut self, addr: u32, size: usize, value: u32) {
        self.stats[1] += 1;
        self.trace_access('W', addr, value);
        if let Err(e) = self.write_inner(addr, size, value) {
            self.fail(format!(
                "{e} (write of {value:#x} at {addr:#010x}, {})",
                register_name(addr)
            ));
        }
    }

    fn write_inner(&mut self, addr: u32, size: usize, value: u32) -> Result<(), String> {
        let word = addr & !3;
        let lane = (addr & 3) * 8;
        let (dev, off, _) = decode(word).ok_or("no peripheral modelled at this address")?;
        let mask = if size == 4 {
            u32::MAX
        } else {
            ((1u32 << (8 * size)) - 1) << lane
        };
        if size != 4 && !narrow_ok(dev, off, addr & 3) {
            return Err(format!("{size}-byte write"));
        }
        if let Some(c) = clock(dev) {
            self.rcc.check(c)?;
        }
        let now = self.now();
        let v = value << lane;
        match dev {
            Dev::Tim1 => self.tim1.write(off, v, now)?,
            Dev::Tim2 => self.tim2.write(off, v, now)?,
            Dev::Tim3 => self.tim3.write(off, v, now)?,
            Dev::Tim4 => self.tim4.write(off, v, now)?,
            Dev::Iwdg => self.iwdg.write(off, v, now)?,
            Dev::Usart2 => {
                let hz = self.rcc.usart2_hz()?;
                self.usart2.write(off, v, now, hz)?;
            }
            Dev::Pwr => self.pwr.write(off, v)?,
            Dev::Rcc => {
                let reset = self
                    .rcc
                    .write(off, v, now, self.flash.latency(), self.pwr.boost())?;
                if let Some((reg, bits)) = reset {
                    self.peripheral_resets(reg, bits);
                }
                self.clocks_changed();
            }
            Dev::Flash => {
                self.flash.write(off, v, now)?;
            }
            Dev::GpioA => self.gpioa.write(off, v)?,
            Dev::GpioB => self.gpiob.write(off, v)?,
            Dev::Adc1 => {
                self.adc_access(1, Some(v), off)?;
            }
            Dev::Adc2 => {
                self.adc_access(2, Some(v), off)?;
            }
            Dev::AdcCommon => {
                self.adc_ticks = None;
                self.adc_common.write(off, v)?;
            }
            Dev::Scs => self.scs.write(off, v, mask)?,
            Dev::Dbgmcu => self.dbgmcu.write(off, v)?,
        }
        Ok(())
    }

    /// RCC reset bits set: those peripherals go back to their reset values.
    fn peripheral_resets(&mut self, reg: usize, bits: u32) {
        let on = |b: u32| bits >> b & 1 != 0 && self.rcc.rstr[reg] >> b & 1 != 0;
        match reg {
            1 => {
                if on(13) {
                    self.adc1 = Adc::new("ADC1");
                    self.adc2 = Adc::new("ADC2");
                    self.adc_common = adc::Common::default();
                }
                if on(0) {
                    self.gpioa = Port::new('A');
                }
                if on(1) {
                    let ext = self.gpiob.ext;
                    self.gpiob = Port::new('B');
                    self.gpiob.ext = ext;
                }
            }
            3 => {
                if on(0) {
                    self.tim2.reset();
                }
                if on(1) {
                    self.tim3.reset();
                }
                if on(2) {
                    self.tim4.reset();
                }
                if on(17) {
                    self.usart2.reset();
                }
            }
            5 if on(11) => self.tim1.reset(),
            _ => {}
        }
    }

    fn trace_access(&mut self, dir: char, addr: u32, v: u32) {
        if self.trace.is_some() {
            let t_us = self.now() as f64 * 1e6 / TICK_HZ as f64;
            let line = format!(
                "{t_us:14.3} {dir} {addr:#010x} {:<22} {v:#010x}\n",
                register_name(addr)
            );
            if let Some(w) = self.trace.as_mut() {
                let _ = w.write_all(line.as_bytes());
            }
        }
    }

    /// A CPU read of the configuration store.
    pub fn store_read(&mut self, off: usize, size: usize) -> u32 {
        let now = self.now();
        let v = self.flash.read_store(off, size, now);
        if self.flash.nmi {
            self.flash.nmi = false;
            self.scs.sys_pending |= 1 << scs::NMI;
        }
        v
    }

    /// A CPU write to the configuration store.
    pub fn store_write(&mut self, off: usize, size: usize, v: u32) {
        let now = self.now();
        if let Err(e) = self.flash.write_store(off, size, v, now) {
            self.fail(format!(
                "{e} (at {:#010x})",
                flash::FLASH_BASE + flash::STORE_OFFSET + off as u32
            ));
        }
    }

    /// Brings every peripheral up to now and sets the NVIC pending bits of the asserted
    /// interrupt lines (level-sensitive: an active interrupt is not re-pended until it returns).
    pub fn update_lines(&mut self) {
        let now = self.now();
        for t in [
            &mut self.tim1,
            &mut self.tim2,
            &mut self.tim3,
            &mut self.tim4,
        ] {
            t.advance(now);
        }
        self.usart2.advance(now);
        self.flash.settle(now);
        let l1 = self.tim1.lines();
        // TIM1's four vectors: BRK 24, UP 25, TRG_COM 26, CC 27.
        let mut lines = Vec::with_capacity(8);
        let [up, cc, trg, brk] = l1;
        for (on, irq) in [(brk, 24), (up, 25), (trg, 26), (cc, 27)] {
            if on {
                lines.push(irq);
            }
        }
        for (t, irq) in [(&self.tim2, 28), (&self.tim3, 29), (&self.tim4, 30)] {
            if t.lines().iter().any(|&l| l) {
                lines.push(irq);
            }
        }
        if self.usart2.line() {
            lines.push(38);
        }
        if self.adc_line(1) || self.adc_line(2) {
            lines.push(18);
        }
        for irq in lines {
            if !self.scs.is_active(scs::IRQ0 + irq) {
                self.scs.set_pending_irq(irq);
            }
        }
    }

    /// The next time a peripheral raises an interrupt or ends an operation, after now.
    pub fn next_event(&self) -> Option<u64> {
        let now = self.now();
        let mut ev: Vec<u64> = Vec::new();
        for t in [&self.tim1, &self.tim2, &self.tim3, &self.tim4] {
            if let Some(e) = t.next_event(now) {
                ev.push(e);
            }
        }
        ev.extend(self.usart2.next_event());
        ev.extend(self.flash.busy_until());
        ev.extend(self.iwdg.expiry());
        ev.into_iter().filter(|&t| t > now).min()
    }

    /// The bridge's inputs and the brake output as the pins drive them now.
    pub fn board_out(&mut self) -> BoardOut {
        let now = self.now();
        // An input pin or a pin not driven reads low at the BTS7960/MOSFET (the 10 kΩ
        // pull-downs of docs/board.md).
        let level = |p: &Port, n: u32| p.output(n).unwrap_or(false);
        let pwm = |p: &Port, n: u32, t: &mut Timer, ch: usize| -> f64 {
            match p.mode(n) {
                2 if p.af(n) == 6 => t.output_duty(ch, now),
                1 => f64::from(u8::from(p.odr >> n & 1 != 0)),
                _ => 0.0,
            }
        };
        let r = pwm(&self.gpioa, 8, &mut self.tim1, 0);
        let l = pwm(&self.gpioa, 9, &mut self.tim1, 1);
        BoardOut {
            enabled: (level(&self.gpiob, 12), level(&self.gpiob, 13)),
            duty: (r, l),
            brake_release: level(&self.gpiob, 9),
        }
    }

    /// The plant's encoder at time `now`: its count (4 per line) and the time of its last edge.
    /// TIM4 counts if it is in encoder mode with PB6/PB7 on AF2; each count pulses its TRGO
    /// (encoder clock), which TIM3 captures when its trigger is ITR3 (RM0440 "TIM3 internal
    /// trigger connection": ITR3 = tim4_trgo).
    pub fn encoder(&mut self, count: u16, edge_t: u64) {
        let prev = self.last_count.replace(count);
        let Some(prev) = prev else { return };
        let delta = i64::from(count.wrapping_sub(prev) as i16);
        let routed = [6, 7]
            .iter()
            .all(|&n| self.gpiob.mode(n) == 2 && self.gpiob.af(n) == 2);
        if delta == 0 || !routed {
            return;
        }
        let now = self.now();
        self.tim4.advance(now);
        if self.tim4.encoder_step(delta) && self.tim4.trgo_is_encoder_clock() {
            self.tim3.advance(now);
            self.tim3.capture_trc(edge_t.min(now), 3);
        }
    }

    /// The switch inputs on GPIOB: `high` pins driven high, `low` pins driven low (a closed
    /// contact to GND); pins in neither float (an open contact: the pull-up decides).
    pub fn set_gpiob_inputs(&mut self, low: u16, high: u16) {
        self.gpiob.ext = gpio::Pins {
            driven: low | high,
            level: high,
        };
    }

    /// Cuts the power: a flash operation under way is torn. Returns the store.
    pub fn power_cut(&mut self) -> Store {
        let now = self.now();
        self.flash.settle(now);
        self.flash.power_cut(now);
        self.flash.store.clone()
    }

    /// A reset of this cause is due: the IWDG reached 0, or AIRCR.SYSRESETREQ.
    pub fn reset_due(&self) -> Option<ResetCause> {
        if self.iwdg.expiry().is_some_and(|t| self.now() >= t) {
            return Some(ResetCause::Watchdog);
        }
        if self.scs.reset_requested {
            return Some(ResetCause::Software);
        }
        None
    }
}
