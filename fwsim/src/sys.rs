//! RCC, PWR, IWDG and DBGMCU.
//!
//! - RCC: RM0440 ch. 7 "Reset and clock control (RCC)", stm32-metapac 21 `rcc_g4`. The clock
//!   tree the firmware can reach: HSI16, the main PLL (f = f_in / M × N / R), SYSCLK from HSI16
//!   or PLLR, the AHB/APB prescalers and the timers' ×2 when an APB prescaler is not 1; the
//!   oscillators' ready flags (HSIRDY at once, PLLRDY after the PLL's lock time), CFGR.SWS
//!   following SW; the enable and reset registers (a peripheral used while its clock is off, or
//!   held in reset, stops the run); CSR's reset flags (BORRSTF/PINRSTF at power-on, IWDGRSTF,
//!   SFTRSTF) and RMVF; the flash wait states required for SYSCLK (RM0440 "Read access latency"
//!   table, range 1 boost) and the boost mode above 150 MHz (RM0440 PWR "Dynamic voltage
//!   scaling") checked when SYSCLK switches: either missing stops the run.
//! - PWR: RM0440 ch. 6 "Power control (PWR)": CR1.VOS (range 1), CR5.R1MODE (boost when 0),
//!   CR1.DBP, SR2 (VOSF: settled at once in this model), the pull registers.
//! - IWDG: RM0440 ch. 42 "Independent watchdog (IWDG)": key register (0x5555 unlocks PR/RLR,
//!   0xCCCC starts, 0xAAAA reloads), the 12-bit down-counter at LSI / (4 << PR), LSI = 32 kHz
//!   (the datasheet's typical), SR.PVU/RVU busy for five LSI periods after a write (RM0440
//!   IWDG_SR), the reset when the counter reaches 0. DBGMCU's freeze bit only acts with a
//!   debugger attached, which the harness is not.
//! - DBGMCU: RM0440 ch. 47 "Debug support": IDCODE (DEV_ID 0x468, STM32G431/441), CR and the
//!   freeze registers, plain storage.

use crate::TICK_HZ;

/// A register access the model does not implement.
pub type Unimplemented = String;

/// HSI16, Hz.
pub const HSI_HZ: u64 = 16_000_000;
/// LSI (IWDG clock), Hz: the STM32G431's datasheet typical.
pub const LSI_HZ: u64 = 32_000;
/// PLL lock time modelled, s (datasheet t_LOCK is tens of µs; the firmware only polls).
const PLL_LOCK_S: f64 = 40e-6;

/// Why the last reset happened (RCC_CSR's flags).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ResetCause {
    /// Power applied (BORRSTF, PINRSTF).
    PowerOn,
    /// The IWDG expired (IWDGRSTF, PINRSTF).
    Watchdog,
    /// AIRCR.SYSRESETREQ (SFTRSTF, PINRSTF).
    Software,
}

/// RCC state.
#[derive(Clone, Debug)]
pub struct Rcc {
    cr: u32,
    icscr: u32,
    cfgr: u32,
    pllcfgr: u32,
    /// Time PLLON was set.
    pll_on_at: Option<u64>,
    /// Reset registers: AHB1, AHB2, AHB3, APB1R1, APB1R2, APB2.
    pub rstr: [u32; 6],
    /// Enable registers, same order.
    pub enr: [u32; 6],
    smenr: [u32; 6],
    ccipr: u32,
    ccipr2: u32,
    bdcr: u32,
    csr: u32,
    crrcr: u32,
    cier: u32,
}

/// Register names.
pub fn rcc_name(off: u32) -> Option<&'static str> {
    Some(match off {
        0x00 => "CR",
        0x04 => "ICSCR",
        0x08 => "CFGR",
        0x0C => "PLLCFGR",
        0x18 => "CIER",
        0x1C => "CIFR",
        0x20 => "CICR",
        0x28 => "AHB1RSTR",
        0x2C => "AHB2RSTR",
        0x30 => "AHB3RSTR",
        0x38 => "APB1RSTR1",
        0x3C => "APB1RSTR2",
        0x40 => "APB2RSTR",
        0x48 => "AHB1ENR",
        0x4C => "AHB2ENR",
        0x50 => "AHB3ENR",
        0x58 => "APB1ENR1",
        0x5C => "APB1ENR2",
        0x60 => "APB2ENR",
        0x68 => "AHB1SMENR",
        0x6C => "AHB2SMENR",
        0x70 => "AHB3SMENR",
        0x78 => "APB1SMENR1",
        0x7C => "APB1SMENR2",
        0x80 => "APB2SMENR",
        0x88 => "CCIPR",
        0x90 => "BDCR",
        0x94 => "CSR",
        0x98 => "CRRCR",
        0x9C => "CCIPR2",
        _ => return None,
    })
}

/// Index into the RSTR/ENR arrays for a register offset (RSTR at 0x28.., ENR at 0x48.., SMENR
/// at 0x68..).
fn bus_index(off: u32, base: u32) -> Option<usize> {
    match off.checked_sub(base)? {
        0x00 => Some(0),
        0x04 => Some(1),
        0x08 => Some(2),
        0x10 => Some(3),
        0x14 => Some(4),
        0x18 => Some(5),
        _ => None,
    }
}

/// A peripheral's clock: which register (index as above) and bit.
#[derive(Clone, Copy, Debug)]
pub struct ClockBit {
    /// Bus register index.
    pub reg: usize,
    /// Bit.
    pub bit: u32,
    /// The enable register's name and field, for errors.
    pub what: &'static str,
}

impl Rcc {
    /// RCC after a reset of cause `cause` (RM0440 reset values; CSR's flags per cause).
    pub fn new(cause: ResetCause) -> Self {
        let flags = match cause {
            ResetCause::PowerOn => 1 << 27 | 1 << 26,
            ResetCause::Watchdog => 1 << 29 | 1 << 26,
            ResetCause::Software => 1 << 28 | 1 << 26,
        };
        Self {
            // HSION, HSIRDY.
            cr: 0x0000_0500,
            icscr: 0x4000_0000,
            // SW = SWS = HSI16.
            cfgr: 0x0000_0005,
            pllcfgr: 0x0000_1000,
            pll_on_at: None,
            rstr: [0; 6],
            // AHB1ENR.FLASHEN and APB1ENR1.RTCAPBEN are set at reset.
            enr: [0x0000_0100, 0, 0, 0x0000_0400, 0, 0],
            smenr: [
                0x0000_130F,
                0x050F_667F,
                0x0000_0101,
                0xF2FE_CA3F,
                0x0000_0103,
                0x0437_F801,
            ],
            ccipr: 0,
            ccipr2: 0,
            bdcr: 0,
            csr: flags,
            crrcr: 0,
            cier: 0,
        }
    }

    fn pll_hz(&self) -> Result<u64, Unimplemented> {
        let src = match self.pllcfgr & 3 {
            2 => HSI_HZ,
            s => return Err(format!("RCC.PLLCFGR.PLLSRC = {s} (only HSI16 is modelled)")),
        };
        let m = u64::from(self.pllcfgr >> 4 & 0xF) + 1;
        let n = u64::from(self.pllcfgr >> 8 & 0x7F);
        let r = 2 * (u64::from(self.pllcfgr >> 25 & 3) + 1);
        Ok(src / m * n / r)
    }

    /// SYSCLK, Hz (as CFGR.SWS says).
    pub fn sysclk(&self) -> Result<u64, Unimplemented> {
        match self.cfgr >> 2 & 3 {
            1 => Ok(HSI_HZ),
            3 => self.pll_hz(),
            s => Err(format!("RCC.CFGR.SWS = {s} (HSE/MSI not modelled)")),
        }
    }

    fn ahb_div(&self) -> u64 {
        match self.cfgr >> 4 & 0xF {
            h if h < 8 => 1,
            h => 1 << (h - 7 + u32::from(h >= 12)),
        }
    }

    /// HCLK (the CPU's clock), Hz.
    pub fn hclk(&self) -> Result<u64, Unimplemented> {
        Ok(self.sysclk()? / self.ahb_div())
    }

    fn apb_div(ppre: u32) -> u64 {
        if ppre < 4 {
            1
        } else {
            1 << (ppre - 3)
        }
    }

    /// PCLK1, PCLK2 and the timer kernel clocks on APB1, APB2 (×2 when divided).
    pub fn apb(&self) -> Result<[u64; 4], Unimplemented> {
        let h = self.hclk()?;
        let d1 = Self::apb_div(self.cfgr >> 8 & 7);
        let d2 = Self::apb_div(self.cfgr >> 11 & 7);
        let t = |d: u64| if d == 1 { h } else { 2 * h / d };
        Ok([h / d1, h / d2, t(d1), t(d2)])
    }

    /// The ADC12 kernel clock (CCIPR.ADC12SEL: 01 PLLP, 10 SYSCLK), Hz.
    pub fn adc12_hz(&self) -> Result<u64, Unimplemented> {
        match self.ccipr >> 28 & 3 {
            2 => self.sysclk(),
            s => Err(format!(
                "RCC.CCIPR.ADC12SEL = {s} (only SYSCLK is modelled)"
            )),
        }
    }

    /// USART2's kernel clock (CCIPR.USART2SEL: 00 PCLK1, 01 SYSCLK, 10 HSI16).
    pub fn usart2_hz(&self) -> Result<u64, Unimplemented> {
        match self.ccipr >> 2 & 3 {
            0 => Ok(self.apb()?[0]),
            1 => self.sysclk(),
            2 => Ok(HSI_HZ),
            _ => Err("RCC.CCIPR.USART2SEL = LSE (not modelled)".into()),
        }
    }

    /// Whether the clock bit is on and the reset bit off; else the error naming both.
    pub fn check(&self, c: ClockBit) -> Result<(), Unimplemented> {
        if self.enr[c.reg] >> c.bit & 1 == 0 {
            return Err(format!(
                "access while the peripheral's clock is off (RCC.{} = 0)",
                c.what
            ));
        }
        if self.rstr[c.reg] >> c.bit & 1 != 0 {
            return Err("access while the peripheral is held in reset".into());
        }
        Ok(())
    }

    /// Reads register `off` at `now`.
    pub fn read(&mut self, off: u32, now: u64) -> Result<u32, Unimplemented> {
        self.settle(now);
        Ok(match off {
            0x00 => self.cr,
            0x04 => self.icscr,
            0x08 => self.cfgr,
            0x0C => self.pllcfgr,
            0x18 => self.cier,
            0x1C => 0,
            0x28..=0x40 => self.rstr[bus_index(off, 0x28).ok_or_else(|| bad(off))?],
            0x48..=0x60 => self.enr[bus_index(off, 0x48).ok_or_else(|| bad(off))?],
            0x68..=0x80 => self.smenr[bus_index(off, 0x68).ok_or_else(|| bad(off))?],
            0x88 => self.ccipr,
            0x90 => self.bdcr,
            0x94 => self.csr,
            // HSI48RDY follows HSI48ON (its start-up, a few µs in the datasheet, is not
            // modelled: the firmware only polls it).
            0x98 => self.crrcr & 1 | (self.crrcr & 1) << 1,
            0x9C => self.ccipr2,
            _ => return Err(bad(off)),
        })
    }

    fn settle(&mut self, now: u64) {
        if let Some(t) = self.pll_on_at {
            if now >= t + (PLL_LOCK_S * TICK_HZ as f64) as u64 {
                self.cr |= 1 << 25;
            }
        }
    }

    /// Writes register `off` at `now`. Returns the peripherals whose reset bit was released
    /// (as (register index, bits)).
    ///
    /// A clock the chip does not support (too few flash wait states; HCLK above 150 MHz
    /// without the range-1 boost mode) stops the run like an unmodelled register.
    pub fn write(
        &mut self,
        off: u32,
        v: u32,
        now: u64,
        flash_latency: u32,
        boost: bool,
    ) -> Result<Option<(usize, u32)>, Unimplemented> {
        self.settle(now);
        match off {
            0x00 => {
                if v & (1 << 16 | 1 << 19) != 0 {
                    return Err(format!("RCC.CR = {v:#x}: HSE/CSS not modelled"));
                }
                if v & 1 << 8 == 0 {
                    return Err("RCC.CR: HSI16 switched off (not modelled)".into());
                }
                let pllon = v & 1 << 24 != 0;
                if pllon && self.cr & 1 << 24 == 0 {
                    self.pll_on_at = Some(now);
                }
                if !pllon {
                    self.pll_on_at = None;
                    self.cr &= !(1 << 25);
                    if self.cfgr >> 2 & 3 == 3 {
                        return Err("RCC.CR.PLLON cleared while the PLL drives SYSCLK".into());
                    }
                }
                // The ready flags are read-only: HSIRDY stays, PLLRDY only while PLLON.
                let pllrdy = if pllon { self.cr & 1 << 25 } else { 0 };
                self.cr = (v & !(1 << 10 | 1 << 25)) | (self.cr & 1 << 10) | pllrdy;
            }
            0x04 => self.icscr = v,
            0x08 => {
                let sw = v & 3;
                let ready = match sw {
                    1 => true,
                    3 => self.cr & 1 << 25 != 0,
                    _ => return Err(format!("RCC.CFGR.SW = {sw} (HSE/MSI not modelled)")),
                };
                let sws = if ready { sw } else { self.cfgr >> 2 & 3 };
                if v & 0xFF00_0000 != 0 {
                    return Err(format!("RCC.CFGR = {v:#x}: MCO output"));
                }
                self.cfgr = (v & !0xC) | sws << 2;
                let hz = self.hclk()?;
                if hz > 150_000_000 && !boost {
                    return Err(format!(
                        "HCLK {} MHz in range-1 normal mode: PWR_CR5.R1MODE (bit 8) is still 1 (RM0440 \"Dynamic voltage scaling management\": above 150 MHz the boost mode, R1MODE = 0, is required)",
                        hz / 1_000_000
                    ));
                }
                // RM0440 "Number of wait states according to CPU clock (HCLK) frequency",
                // range 1: 34 MHz per wait state in boost mode, 30 MHz in normal mode.
                let per_ws = if boost { 34_000_000 } else { 30_000_000 };
                let need = (hz.saturating_sub(1) / per_ws) as u32;
                if flash_latency < need {
                    return Err(format!("HCLK {} MHz with {flash_latency} flash wait states (FLASH.ACR.LATENCY; RM0440 needs {need})", hz / 1_000_000));
                }
            }
            0x0C => {
                if self.cr & 1 << 24 != 0 {
                    return Err("RCC.PLLCFGR written while the PLL is on".into());
                }
                self.pllcfgr = v;
            }
            0x18 => self.cier = v,
            0x20 => {}
            0x28..=0x40 => {
                let i = bus_index(off, 0x28).ok_or_else(|| bad(off))?;
                let released = self.rstr[i] & !v;
                self.rstr[i] = v;
                return Ok(Some((i, released | v)));
            }
            0x48..=0x60 => self.enr[bus_index(off, 0x48).ok_or_else(|| bad(off))?] = v,
            0x68..=0x80 => self.smenr[bus_index(off, 0x68).ok_or_else(|| bad(off))?] = v,
            0x88 => self.ccipr = v,
            0x90 => {
                // The RTC's clock may be selected and enabled (embassy-stm32 clocks it from LSI:
                // RTCSEL = 10, RTCEN); the RTC itself is not modelled (any access to it stops
                // the run), nor is LSE.
                let rtcsel = v >> 8 & 3;
                if v & 1 != 0 || !matches!(rtcsel, 0 | 2) {
                    return Err(format!("RCC.BDCR = {v:#x}: LSE not modelled"));
                }
                // BDRST (16) resets the backup domain: reads back as written.
                self.bdcr = v & (1 << 16 | 3 << 8 | 1 << 15 | 1 << 25);
            }
            0x94 => {
                if v & 1 << 23 != 0 {
                    // RMVF clears the reset flags.
                    self.csr &= !0xFE00_0000;
                }
                if v & 1 != 0 {
                    // LSION: the IWDG starts LSI itself; LSIRDY at once.
                    self.csr |= 3;
                } else {
                    self.csr &= !3;
                }
            }
            0x98 => self.crrcr = v,
            0x9C => self.ccipr2 = v,
            _ => return Err(bad(off)),
        }
        Ok(None)
    }
}

fn bad(off: u32) -> String {
    format!(
        "RCC.{}",
        rcc_name(off).map_or_else(|| format!("+{off:#x}"), str::to_string)
    )
}

/// PWR state.
#[derive(Clone, Debug)]
pub struct Pwr {
    cr1: u32,
    cr2: u32,
    cr3: u32,
    cr4: u32,
    /// CR5 (reset: R1MODE = 1, range 1 normal).
    pub cr5: u32,
    pull: [u32; 14],
}

/// PWR register names.
pub fn pwr_name(off: u32) -> Option<&'static str> {
    Some(match off {
        0x00 => "CR1",
        0x04 => "CR2",
        0x08 => "CR3",
        0x0C => "CR4",
        0x10 => "SR1",
        0x14 => "SR2",
        0x18 => "SCR",
        0x20..=0x54 => "PUCR/PDCR",
        0x80 => "CR5",
        _ => return None,
    })
}

impl Default for Pwr {
    fn default() -> Self {
        Self {
            // VOS = range 1.
            cr1: 0x0000_0200,
            cr2: 0,
            // EIWUL.
            cr3: 0x0000_8000,
            cr4: 0,
            cr5: 0x0000_0100,
            pull: [0; 14],
        }
    }
}

impl Pwr {
    /// Range-1 boost mode on: CR5.R1MODE (bit 8, RM0440 PWR_CR5, reset value 0x100; the
    /// STM32G4 SVDs agree) cleared in range 1.
    pub fn boost(&self) -> bool {
        self.cr1 >> 9 & 3 == 1 && self.cr5 >> 8 & 1 == 0
    }

    /// Reads register `off`.
    pub fn read(&mut self, off: u32) -> Result<u32, Unimplemented> {
        Ok(match off {
            0x00 => self.cr1,
            0x04 => self.cr2,
            0x08 => self.cr3,
            0x0C => self.cr4,
            0x10 => 0,
            // VOSF and REGLPF: 0, the regulator settled (not modelled in time).
            0x14 => 0,
            0x20..=0x54 => self.pull[((off - 0x20) / 4) as usize],
            0x80 => self.cr5,
            _ => return Err(format!("read of PWR.{}", pwr_name(off).unwrap_or("?"))),
        })
    }

    /// Writes register `off`.
    pub fn write(&mut self, off: u32, v: u32) -> Result<(), Unimplemented> {
        match off {
            0x00 => {
                if v & 7 != 0 || v >> 9 & 3 != 1 {
                    return Err(format!(
                        "PWR.CR1 = {v:#x}: low-power modes or range 2 not modelled"
                    ));
                }
                self.cr1 = v;
            }
            0x04 => self.cr2 = v,
            0x08 => self.cr3 = v,
            0x0C => self.cr4 = v,
            0x18 => {}
            0x20..=0x54 => self.pull[((off - 0x20) / 4) as usize] = v,
            0x80 => {
                // RM0440 PWR_CR5: R1MODE is bit 8; bits 31:9 and 7:0 are reserved, kept at
                // their reset value 0. (stm32-metapac 21's `pwr_g4` puts R1MODE at bit 0: a
                // write of that bit lands here.)
                if v & !(1 << 8) != 0 {
                    return Err(format!(
                        "PWR.CR5 = {v:#x}: reserved bits set (RM0440: R1MODE is bit 8, the only one)"
                    ));
                }
                self.cr5 = v;
            }
            _ => return Err(format!("write of PWR.{}", pwr_name(off).unwrap_or("?"))),
        }
        Ok(())
    }
}

/// IWDG state.
#[derive(Clone, Debug, Default)]
pub struct Iwdg {
    unlocked: bool,
    pr: u32,
    rlr: u32,
    winr: u32,
    /// Started (by 0xCCCC; it cannot be stopped).
    pub running: bool,
    /// Time of the last reload (or start).
    reloaded_at: u64,
    /// PR/RLR busy until these times.
    pvu_until: u64,
    rvu_until: u64,
    /// Times of the reloads, for the watchdog test.
    pub feeds: u64,
}

/// IWDG register names.
pub fn iwdg_name(off: u32) -> Option<&'static str> {
    Some(match off {
        0x00 => "KR",
        0x04 => "PR",
        0x08 => "RLR",
        0x0C => "SR",
        0x10 => "WINR",
        _ => return None,
    })
}

impl Iwdg {
    /// IWDG at reset (RLR 0xFFF, WINR 0xFFF).
    pub fn new() -> Self {
        Self {
            rlr: 0xFFF,
            winr: 0xFFF,
            ..Self::default()
        }
    }

    fn lsi_period() -> u64 {
        TICK_HZ / LSI_HZ
    }

    /// The time the counter reaches 0 (the reset), if running.
    pub fn expiry(&self) -> Option<u64> {
        self.running.then(|| {
            let per_count = Self::lsi_period() * (4 << self.pr);
            self.reloaded_at + per_count * (u64::from(self.rlr) + 1)
        })
    }

    /// Reads register `off`.
    pub fn read(&mut self, off: u32, now: u64) -> Result<u32, Unimplemented> {
        Ok(match off {
            0x04 => self.pr,
            0x08 => self.rlr,
            0x0C => u32::from(now < self.pvu_until) | u32::from(now < self.rvu_until) << 1,
            0x10 => self.winr,
            _ => return Err(format!("read of IWDG.{}", iwdg_name(off).unwrap_or("?"))),
        })
    }

    /// Writes register `off`.
    pub fn write(&mut self, off: u32, v: u32, now: u64) -> Result<(), Unimplemented> {
        let busy = now + 5 * Self::lsi_period();
        match off {
            0x00 => match v & 0xFFFF {
                0x5555 => self.unlocked = true,
                0xCCCC => {
                    if !self.running {
                        self.running = true;
                        self.reloaded_at = now;
                    }
                    self.unlocked = false;
                }
                0xAAAA => {
                    self.reloaded_at = now;
                    self.feeds += 1;
                    self.unlocked = false;
                }
                _ => self.unlocked = false,
            },
            // Without the unlock key PR/RLR/WINR ignore writes (RM0440 "Register access
            // protection").
            0x04 if self.unlocked => {
                self.pr = v & 7;
                self.pvu_until = busy;
            }
            0x08 if self.unlocked => {
                self.rlr = v & 0xFFF;
                self.rvu_until = busy;
            }
            0x10 if self.unlocked => {
                if v & 0xFFF != 0xFFF {
                    return Err("IWDG window mode (WINR < 0xFFF) not modelled".into());
                }
                self.winr = v & 0xFFF;
            }
            0x04 | 0x08 | 0x10 => {}
            _ => return Err(format!("write of IWDG.{}", iwdg_name(off).unwrap_or("?"))),
        }
        Ok(())
    }
}

/// DBGMCU state (plain registers).
#[derive(Clone, Debug, Default)]
pub struct Dbgmcu {
    regs: [u32; 4],
}

/// DBGMCU register names.
pub fn dbgmcu_name(off: u32) -> Option<&'static str> {
    Some(match off {
        0x00 => "IDCODE",
        0x04 => "CR",
        0x08 => "APB1FZR1",
        0x0C => "APB1FZR2",
        0x10 => "APB2FZR",
        _ => return None,
    })
}

impl Dbgmcu {
    /// Reads register `off`.
    pub fn read(&self, off: u32) -> Result<u32, Unimplemented> {
        match off {
            // DEV_ID 0x468 (STM32G431xx), REV_ID 0x2000 (rev X).
            0x00 => Ok(0x2000_0468),
            0x04..=0x10 => Ok(self.regs[((off - 4) / 4) as usize]),
            _ => Err(format!("read of DBGMCU+{off:#x}")),
        }
    }

    /// Writes register `off`.
    pub fn write(&mut self, off: u32, v: u32) -> Result<(), Unimplemented> {
        match off {
            0x04..=0x10 => {
                self.regs[((off - 4) / 4) as usize] = v;
                Ok(())
            }
            _ => Err(format!(
                "write of DBGMCU.{}",
                dbgmcu_name(off).unwrap_or("?")
            )),
        }
    }
}
