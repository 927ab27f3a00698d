//! ADC1 and ADC2 with their common registers (ADC12, 0x5000_0000).
//!
//! Sources: RM0440 ch. 21 "Analog-to-digital converters (ADC)" and stm32-metapac 21's `adc_g4`:
//! - power-up (RM0440 "ADC deep-power-down mode and ADC voltage regulator"): CR.DEEPPWD = 1 at
//!   reset; ADVREGEN then t_ADCVREG_STUP = 20 µs before calibration or enabling (earlier stops
//!   the run: the converter would not work);
//! - calibration (ADCAL, single-ended or differential by ADCALDIF): only with ADEN = 0,
//!   t_CAL = 116 ADC clock cycles, then ADCAL reads 0;
//! - enabling: ADEN, ISR.ADRDY after t_STAB (one conversion time of the slowest channel is the
//!   order the datasheet gives: 1 µs here);
//! - regular conversions on a software start (CFGR.EXTEN = 0): the sequence SQR1 (L + 1 ranks),
//!   each rank the channel's sampling time (SMPRx, 2.5..640.5 cycles) + 12.5 cycles at 12 bits,
//!   EOC per conversion, EOS at the end, DR = the last result, ADSTART cleared at the end of a
//!   single (CONT = 0) sequence;
//! - injected conversions (JSQR: JL + 1 ranks, JEXTSEL, JEXTEN) started by the hardware
//!   trigger, here JEXTSEL = 1 = TIM1_CC4 (RM0440 "ADC1/2 - External triggers for injected
//!   channels"), rising edge; JDRx hold the latest sequence's results, JEOC/JEOS set;
//! - ADC12_CCR.PRESC dividing the kernel clock (CKMODE = 0: RCC's ADC12SEL source);
//! - the clock (CCR.PRESC) the conversion times are counted in.
//!
//! The channels' voltages come from the board: ADC1 IN1 = PA0 (R_IS), IN2 = PA1 (L_IS), ADC2
//! IN17 = PA4 (the supply divider); a conversion of a pin that is not in analog mode, or of a
//! channel the board does not wire, stops the run.

use crate::TICK_HZ;

/// A register access the model does not implement.
pub type Unimplemented = String;

const ADEN: u32 = 1;
const ADDIS: u32 = 1 << 1;
const ADSTART: u32 = 1 << 2;
const JADSTART: u32 = 1 << 3;
const ADVREGEN: u32 = 1 << 28;
const DEEPPWD: u32 = 1 << 29;
const ADCAL: u32 = 1 << 31;
const ADRDY: u32 = 1;
const EOC: u32 = 1 << 2;
const EOS: u32 = 1 << 3;
const JEOC: u32 = 1 << 5;
const JEOS: u32 = 1 << 6;

/// Sampling times in half ADC cycles (SMP codes 0..=7: 2.5 .. 640.5 cycles).
const SMP_HALF: [u64; 8] = [5, 13, 25, 49, 95, 185, 495, 1281];

/// One ADC.
#[derive(Clone, Debug)]
pub struct Adc {
    /// "ADC1"/"ADC2".
    pub name: &'static str,
    isr: u32,
    ier: u32,
    cr: u32,
    cfgr: u32,
    cfgr2: u32,
    smpr: [u32; 2],
    sqr: [u32; 4],
    dr: u32,
    jsqr: u32,
    jdr: [u32; 4],
    difsel: u32,
    calfact: u32,
    vreg_on_at: Option<u64>,
    cal_done_at: Option<u64>,
    ready_at: Option<u64>,
    /// Enabled and stabilised (the state ADRDY flags; software may clear the flag).
    ready: bool,
    /// Regular sequence: (end time, result).
    regular: Option<(u64, u32)>,
    /// Injected: results of the latest sequence and the time they were ready.
    injected_at: Option<u64>,
    /// When JEOS was last cleared.
    jeos_cleared_at: u64,
}

/// Register names (offsets within one ADC).
pub fn name(off: u32) -> Option<&'static str> {
    Some(match off {
        0x00 => "ISR",
        0x04 => "IER",
        0x08 => "CR",
        0x0C => "CFGR",
        0x10 => "CFGR2",
        0x14 => "SMPR1",
        0x18 => "SMPR2",
        0x20 => "TR1",
        0x24 => "TR2",
        0x28 => "TR3",
        0x30 => "SQR1",
        0x34 => "SQR2",
        0x38 => "SQR3",
        0x3C => "SQR4",
        0x40 => "DR",
        0x4C => "JSQR",
        0x60..=0x6C => "OFRx",
        0x80 => "JDR1",
        0x84 => "JDR2",
        0x88 => "JDR3",
        0x8C => "JDR4",
        0xA0 => "AWD2CR",
        0xA4 => "AWD3CR",
        0xB0 => "DIFSEL",
        0xB4 => "CALFACT",
        0xC0 => "GCOMP",
        _ => return None,
    })
}

/// What the ADC needs from the rest of the chip for one access.
pub struct Env<'a> {
    /// Now, ticks.
    pub now: u64,
    /// Ticks per ADC clock cycle.
    pub adc_clk: u64,
    /// The voltage code on channel `ch` (None: the channel is not wired on the board or its
    /// pin is not analog: the error text).
    pub input: &'a dyn Fn(u32) -> Result<u16, String>,
    /// The latest TIM1 CC4 compare before a time, if TIM1 runs.
    pub tim1_cc4_before: &'a dyn Fn(u64) -> Option<u64>,
}

impl Adc {
    /// ADC at reset (CR: DEEPPWD; CFGR: JQDIS).
    pub fn new(name: &'static str) -> Self {
        Self {
            name,
            isr: 0,
            ier: 0,
            cr: DEEPPWD,
            cfgr: 0x8000_0000,
            cfgr2: 0,
            smpr: [0; 2],
            sqr: [0; 4],
            dr: 0,
            jsqr: 0,
            jdr: [0; 4],
            difsel: 0,
            calfact: 0,
            vreg_on_at: None,
            cal_done_at: None,
            ready_at: None,
            ready: false,
            regular: None,
            injected_at: None,
            jeos_cleared_at: 0,
        }
    }

    fn sample_half_cycles(&self, ch: u32) -> u64 {
        let code = if ch < 10 {
            self.smpr[0] >> (3 * ch) & 7
        } else {
            self.smpr[1] >> (3 * (ch - 10)) & 7
        };
        SMP_HALF[code as usize]
    }

    /// Conversion time of channel `ch`: sampling + 12.5 cycles, in ticks.
    fn conv_ticks(&self, ch: u32, adc_clk: u64) -> u64 {
        (self.sample_half_cycles(ch) + 25) * adc_clk / 2
    }

    /// Brings flags up to `now`.
    fn settle(&mut self, env: &Env) -> Result<(), Unimplemented> {
        let now = env.now;
        if let Some(t) = self.cal_done_at {
            if now >= t {
                self.cr &= !ADCAL;
                self.calfact = 0x0040_0040;
                self.cal_done_at = None;
            }
        }
        if let Some(t) = self.ready_at {
            if now >= t {
                self.isr |= ADRDY;
                self.ready = true;
                self.ready_at = None;
            }
        }
        if let Some((end, value)) = self.regular {
            if now >= end {
                self.dr = value;
                self.isr |= EOC | EOS;
                if self.cfgr & 1 << 13 == 0 {
                    self.cr &= !ADSTART;
                }
                self.regular = None;
            }
        }
        if self.cr & JADSTART != 0 {
            let jl = (self.jsqr & 3) as usize + 1;
            let total: u64 = (0..jl)
                .map(|r| self.conv_ticks(self.jsq(r), env.adc_clk))
                .sum();
            if let Some(trig) = now
                .checked_sub(total)
                .and_then(|t| (env.tim1_cc4_before)(t))
            {
                if self.injected_at != Some(trig) {
                    for r in 0..jl {
                        self.jdr[r] = u32::from((env.input)(self.jsq(r))?);
                    }
                    self.injected_at = Some(trig);
                }
                if trig + total > self.jeos_cleared_at {
                    self.isr |= JEOC | JEOS;
                }
            }
        }
        Ok(())
    }

    /// The interrupt line (ADC1_2, IRQ 18): a flag with its enable.
    pub fn line(&mut self, env: &Env) -> bool {
        if self.ier == 0 {
            return false;
        }
        let _ = self.settle(env);
        self.isr & self.ier != 0
    }

    fn jsq(&self, rank: usize) -> u32 {
        self.jsqr >> (9 + 6 * rank) & 0x1F
    }

    /// Reads register `off`.
    pub fn read(&mut self, off: u32, env: &Env) -> Result<u32, Unimplemented> {
        self.settle(env)?;
        Ok(match off {
            0x00 => self.isr,
            0x04 => self.ier,
            0x08 => self.cr,
            0x0C => self.cfgr,
            0x10 => self.cfgr2,
            0x14 => self.smpr[0],
            0x18 => self.smpr[1],
            0x30..=0x3C => self.sqr[((off - 0x30) / 4) as usize],
            0x40 => self.dr,
            0x4C => self.jsqr,
            0x80..=0x8C => self.jdr[((off - 0x80) / 4) as usize],
            0xB0 => self.difsel,
            0xB4 => self.calfact,
            _ => {
                return Err(format!(
                    "read of {}.{}",
                    self.name,
                    name(off).unwrap_or("?")
                ))
            }
        })
    }

    /// Writes register `off`.
    pub fn write(&mut self, off: u32, v: u32, env: &Env) -> Result<(), Unimplemented> {
        self.settle(env)?;
        let now = env.now;
        match off {
            // rc_w1 flags.
            0x00 => {
                if v & (JEOC | JEOS) != 0 {
                    self.jeos_cleared_at = now;
                }
                self.isr &= !v;
            }
            0x04 => {
                if v != 0 {
                    return Err(format!(
                        "{}.IER = {v:#x}: ADC interrupts not modelled",
                        self.name
                    ));
                }
            }
            0x08 => self.write_cr(v, env)?,
            0x0C => {
                if v & 3 != 0 || v >> 3 & 3 != 0 || v & 1 << 15 != 0 {
                    return Err(format!(
                        "{}.CFGR = {v:#x}: DMA, resolution below 12 bits or left alignment",
                        self.name
                    ));
                }
                if v & 0x3E0 != 0 && v >> 10 & 3 != 0 {
                    return Err(format!(
                        "{}.CFGR: regular external trigger not modelled",
                        self.name
                    ));
                }
                if v & 1 << 31 == 0 {
                    return Err(format!(
                        "{}.CFGR.JQDIS = 0: the injected queue is not modelled",
                        self.name
                    ));
                }
                self.cfgr = v;
            }
            0x10 => {
                if v != 0 {
                    return Err(format!(
                        "{}.CFGR2 = {v:#x}: oversampling not modelled",
                        self.name
                    ));
                }
            }
            0x14 => self.smpr[0] = v,
            0x18 => self.smpr[1] = v,
            0x30..=0x3C => self.sqr[((off - 0x30) / 4) as usize] = v,
            0x4C => {
                if self.cr & JADSTART != 0 {
                    return Err(format!(
                        "{}.JSQR written while JADSTART (the queue is off)",
                        self.name
                    ));
                }
                self.jsqr = v;
            }
            0xB0 => {
                if v != 0 {
                    return Err(format!(
                        "{}.DIFSEL = {v:#x}: differential inputs not modelled",
                        self.name
                    ));
                }
                self.difsel = v;
            }
            _ => {
                return Err(format!(
                    "write of {}.{}",
                    self.name,
                    name(off).unwrap_or("?")
                ))
            }
        }
        Ok(())
    }

    fn write_cr(&mut self, v: u32, env: &Env) -> Result<(), Unimplemented> {
        let now = env.now;
        let n = self.name;
        if v & DEEPPWD == 0 && self.cr & DEEPPWD != 0 {
            self.cr &= !DEEPPWD;
        }
        if v & DEEPPWD != 0 && self.cr & DEEPPWD == 0 {
            return Err(format!("{n}: back into deep power-down (not modelled)"));
        }
        if v & ADVREGEN != 0 && self.cr & ADVREGEN == 0 {
            if self.cr & DEEPPWD != 0 {
                return Err(format!(
                    "{n}.CR.ADVREGEN set while DEEPPWD = 1 (RM0440: exit deep power-down first)"
                ));
            }
            self.vreg_on_at = Some(now);
            self.cr |= ADVREGEN;
        }
        let settled = |s: &Self| {
            s.vreg_on_at
                .is_some_and(|t| now >= t + 20 * TICK_HZ / 1_000_000)
        };
        // ADCALDIF is plain.
        self.cr = self.cr & !(1 << 30) | v & 1 << 30;
        if v & ADCAL != 0 && self.cr & ADCAL == 0 {
            if self.cr & ADEN != 0 {
                return Err(format!("{n}.CR.ADCAL while ADEN = 1 (RM0440 forbids)"));
            }
            if !settled(self) {
                return Err(format!(
                    "{n}.CR.ADCAL before the regulator's 20 µs start-up (t_ADCVREG_STUP)"
                ));
            }
            self.cr |= ADCAL;
            self.cal_done_at = Some(now + 116 * env.adc_clk);
        }
        if v & ADEN != 0 && self.cr & ADEN == 0 {
            if self.cr & ADCAL != 0 || !settled(self) {
                return Err(format!(
                    "{n}.CR.ADEN during calibration or before the regulator's start-up"
                ));
            }
            self.cr |= ADEN;
            self.ready_at = Some(now + TICK_HZ / 1_000_000);
        }
        if v & ADDIS != 0 {
            return Err(format!("{n}.CR.ADDIS: disabling not modelled"));
        }
        if v & ADSTART != 0 && self.cr & ADSTART == 0 {
            // RM0440 ADC_CR.ADSTART: only with ADEN = 1 and ADDIS = 0 (the ADRDY flag may have
            // been cleared by software; the converter must have stabilised).
            if self.cr & ADEN == 0 || !self.ready {
                return Err(format!(
                    "{n}.CR.ADSTART while the ADC is not enabled and ready"
                ));
            }
            let l = self.sqr[0] & 0xF;
            if l != 0 {
                return Err(format!(
                    "{n}: regular sequence of {} ranks (one is modelled)",
                    l + 1
                ));
            }
            let ch = self.sqr[0] >> 6 & 0x1F;
            let value = u32::from((env.input)(ch)?);
            self.regular = Some((now + self.conv_ticks(ch, env.adc_clk), value));
            self.cr |= ADSTART;
        }
        if v & JADSTART != 0 && self.cr & JADSTART == 0 {
            if self.cr & ADEN == 0 || !self.ready {
                return Err(format!(
                    "{n}.CR.JADSTART while the ADC is not enabled and ready"
                ));
            }
            let jextsel = self.jsqr >> 2 & 0x1F;
            let jexten = self.jsqr >> 7 & 3;
            if jextsel != 1 || jexten != 1 {
                return Err(format!(
                    "{n}.JSQR: injected trigger JEXTSEL {jextsel}, JEXTEN {jexten} (TIM1_CC4 = 1 on the rising edge is modelled)"
                ));
            }
            self.cr |= JADSTART;
            self.injected_at = None;
        }
        if v & (1 << 4 | 1 << 5) != 0 {
            return Err(format!("{n}.CR: ADSTP/JADSTP not modelled"));
        }
        Ok(())
    }
}

/// ADC12's common registers.
#[derive(Clone, Debug, Default)]
pub struct Common {
    /// ADC12_CCR.
    pub ccr: u32,
}

impl Common {
    /// The ADC clock divider (CCR.PRESC; CKMODE = 0).
    pub fn divider(&self) -> Result<u64, Unimplemented> {
        if self.ccr >> 16 & 3 != 0 {
            return Err("ADC12_CCR.CKMODE: synchronous clock not modelled".into());
        }
        Ok(match self.ccr >> 18 & 0xF {
            0 => 1,
            1 => 2,
            2 => 4,
            3 => 6,
            4 => 8,
            5 => 10,
            6 => 12,
            7 => 16,
            8 => 32,
            9 => 64,
            10 => 128,
            _ => 256,
        })
    }

    /// Reads register `off` (from ADC12_COMMON's base).
    pub fn read(&self, off: u32) -> Result<u32, Unimplemented> {
        match off {
            0x08 => Ok(self.ccr),
            _ => Err(format!("read of ADC12_COMMON+{off:#x}")),
        }
    }

    /// Writes register `off`.
    pub fn write(&mut self, off: u32, v: u32) -> Result<(), Unimplemented> {
        match off {
            0x08 => {
                if v & 0x1F != 0 {
                    return Err("ADC12_CCR.DUAL: dual mode not modelled".into());
                }
                self.ccr = v;
                Ok(())
            }
            _ => Err(format!("write of ADC12_COMMON+{off:#x}")),
        }
    }
}
