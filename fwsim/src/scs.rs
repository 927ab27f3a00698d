//! The Cortex-M4's System Control Space (0xE000_E000): NVIC, SCB, SysTick, the FPU's control
//! registers; and the exception priority rules the harness applies at exception entry.
//!
//! Source of every behaviour: the ARMv7-M Architecture Reference Manual (ARM DDI 0403E),
//! B3.2 "System Control Space" (register map and reset values), B3.4 "NVIC" (ISER/ICER/ISPR/
//! ICPR/IABR/IPR), B1.5.4 "Exception priorities and preemption" (group priority from
//! AIRCR.PRIGROUP, BASEPRI, PRIMASK, FAULTMASK, ties to the lowest exception number), and the
//! STM32G4's `__NVIC_PRIO_BITS` = 4 (PM0214 §4.3: only IPR bits [7:4] are implemented).

/// Exception numbers (ARMv7-M B1.5.2).
pub const NMI: u32 = 2;
/// HardFault.
pub const HARD_FAULT: u32 = 3;
/// PendSV.
pub const PEND_SV: u32 = 14;
/// SysTick.
pub const SYS_TICK: u32 = 15;
/// First external interrupt (IRQ 0).
pub const IRQ0: u32 = 16;
/// Interrupts the STM32G431 has (RM0440: IRQ 0..=101).
pub const IRQS: u32 = 102;

/// Implemented priority bits (STM32G4: 4, the upper nibble).
const PRIO_MASK: u8 = 0xF0;

/// NVIC, SCB and SysTick state.
#[derive(Clone, Debug)]
pub struct Scs {
    /// NVIC_ISERn: enabled IRQs.
    pub enabled: [u32; 4],
    /// NVIC_ISPRn: pending IRQs.
    pub pending: [u32; 4],
    /// NVIC_IPRn: IRQ priorities (upper nibble only).
    pub ipr: [u8; 128],
    /// SHPR1..3: priorities of exceptions 4..=15.
    pub shpr: [u8; 12],
    /// Pending system exceptions (bit = exception number: NMI, PendSV, SysTick).
    pub sys_pending: u32,
    /// Active exceptions, innermost last.
    pub active: Vec<u32>,
    /// SCB_VTOR.
    pub vtor: u32,
    /// AIRCR.PRIGROUP.
    pub prigroup: u32,
    /// SCB_SCR (SLEEPONEXIT, SLEEPDEEP, SEVONPEND).
    pub scr: u32,
    /// SCB_CCR (reset: STKALIGN).
    pub ccr: u32,
    /// SCB_SHCSR (fault enables).
    pub shcsr: u32,
    /// SCB_CPACR (the FPU's access bits; Unicorn's FPU is always accessible, see docs).
    pub cpacr: u32,
    /// FPU_FPCCR (reset: ASPEN | LSPEN).
    pub fpccr: u32,
    /// FPU_FPDSCR.
    pub fpdscr: u32,
    /// CoreDebug_DEMCR.
    pub demcr: u32,
    /// SysTick CSR, RVR (the counter is not modelled: enabling it stops the run).
    pub systick_csr: u32,
    /// SysTick reload.
    pub systick_rvr: u32,
    /// A reset requested through AIRCR.SYSRESETREQ.
    pub reset_requested: bool,
}

impl Default for Scs {
    fn default() -> Self {
        Self {
            enabled: [0; 4],
            pending: [0; 4],
            ipr: [0; 128],
            shpr: [0; 12],
            sys_pending: 0,
            active: Vec::new(),
            vtor: 0,
            prigroup: 0,
            scr: 0,
            // ARMv7-M B3.2.8: STKALIGN resets to 1 on the Cortex-M4 (r0p1).
            ccr: 1 << 9,
            shcsr: 0,
            cpacr: 0,
            // ARMv7-M B3.2.? FPCCR: ASPEN and LSPEN reset to 1.
            fpccr: 0xC000_0000,
            fpdscr: 0,
            demcr: 0,
            systick_csr: 0,
            systick_rvr: 0,
            reset_requested: false,
        }
    }
}

/// A register access the model does not implement.
pub type Unimplemented = String;

fn bits(v: u32) -> impl Iterator<Item = u32> {
    (0..32).filter(move |b| v >> b & 1 != 0)
}

impl Scs {
    /// The register's name, for traces and errors.
    pub fn name(off: u32) -> Option<String> {
        Some(match off {
            0x004 => "ICTR".into(),
            0x010 => "SYST_CSR".into(),
            0x014 => "SYST_RVR".into(),
            0x018 => "SYST_CVR".into(),
            0x01C => "SYST_CALIB".into(),
            0x100..=0x13C => format!("NVIC_ISER{}", (off - 0x100) / 4),
            0x180..=0x1BC => format!("NVIC_ICER{}", (off - 0x180) / 4),
            0x200..=0x23C => format!("NVIC_ISPR{}", (off - 0x200) / 4),
            0x280..=0x2BC => format!("NVIC_ICPR{}", (off - 0x280) / 4),
            0x300..=0x33C => format!("NVIC_IABR{}", (off - 0x300) / 4),
            0x400..=0x5EC => format!("NVIC_IPR{}", (off - 0x400) / 4),
            0xD00 => "SCB_CPUID".into(),
            0xD04 => "SCB_ICSR".into(),
            0xD08 => "SCB_VTOR".into(),
            0xD0C => "SCB_AIRCR".into(),
            0xD10 => "SCB_SCR".into(),
            0xD14 => "SCB_CCR".into(),
            0xD18 => "SCB_SHPR1".into(),
            0xD1C => "SCB_SHPR2".into(),
            0xD20 => "SCB_SHPR3".into(),
            0xD24 => "SCB_SHCSR".into(),
            0xD28 => "SCB_CFSR".into(),
            0xD2C => "SCB_HFSR".into(),
            0xD88 => "SCB_CPACR".into(),
            0xDFC => "DEMCR".into(),
            0xF00 => "NVIC_STIR".into(),
            0xF34 => "FPU_FPCCR".into(),
            0xF38 => "FPU_FPCAR".into(),
            0xF3C => "FPU_FPDSCR".into(),
            _ => return None,
        })
    }

    /// Reads the word at `off` (from 0xE000_E000).
    pub fn read(&mut self, off: u32) -> Result<u32, Unimplemented> {
        let idx = |base: u32| ((off - base) / 4) as usize;
        Ok(match off {
            // ICTR: 4 × 32 interrupt lines (IRQ 0..=127 exist in the NVIC's map).
            0x004 => 3,
            0x010 => self.systick_csr,
            0x014 => self.systick_rvr,
            0x100..=0x10C => self.enabled[idx(0x100)],
            0x180..=0x18C => self.enabled[idx(0x180)],
            0x200..=0x20C => self.pending[idx(0x200)],
            0x280..=0x28C => self.pending[idx(0x280)],
            0x300..=0x30C => {
                let i = idx(0x300) as u32;
                self.active
                    .iter()
                    .filter(|&&e| e >= IRQ0 && (e - IRQ0) / 32 == i)
                    .fold(0, |m, &e| m | 1 << ((e - IRQ0) % 32))
            }
            0x400..=0x47C => {
                let i = (off - 0x400) as usize;
                u32::from_le_bytes([
                    self.ipr[i],
                    self.ipr[i + 1],
                    self.ipr[i + 2],
                    self.ipr[i + 3],
                ])
            }
            // Cortex-M4 r0p1 (ARM DDI 0439B §4.3.1).
            0xD00 => 0x410F_C241,
            0xD04 => self.icsr(),
            0xD08 => self.vtor,
            0xD0C => 0xFA05_0000 | self.prigroup << 8,
            0xD10 => self.scr,
            0xD14 => self.ccr,
            0xD18..=0xD20 => {
                let i = (off - 0xD18) as usize;
                u32::from_le_bytes([
                    self.shpr[i],
                    self.shpr[i + 1],
                    self.shpr[i + 2],
                    self.shpr[i + 3],
                ])
            }
            0xD24 => self.shcsr | self.active_bits_shcsr(),
            0xD88 => self.cpacr,
            0xDFC => self.demcr,
            0xF34 => self.fpccr,
            0xF3C => self.fpdscr,
            _ => return Err(format!("read of {}", name_or_offset(off))),
        })
    }

    /// Writes the word at `off`; `mask` says which bytes the access wrote (byte and
    /// half-word stores reach the priority registers).
    pub fn write(&mut self, off: u32, value: u32, mask: u32) -> Result<(), Unimplemented> {
        let idx = |base: u32| ((off - base) / 4) as usize;
        let word_only = || -> Result<(), Unimplemented> {
            if mask == u32::MAX {
                Ok(())
            } else {
                Err(format!(
                    "{}-byte write to {}",
                    mask.count_ones() / 8,
                    name_or_offset(off)
                ))
            }
        };
        match off {
            0x010 => {
                word_only()?;
                if value & 1 != 0 {
                    return Err(
                        "SysTick enabled (SYST_CSR.ENABLE): the SysTick counter is not modelled"
                            .into(),
                    );
                }
                self.systick_csr = value & 0x7;
            }
            0x014 => self.systick_rvr = value & 0x00FF_FFFF,
            0x100..=0x10C => {
                word_only()?;
                self.enabled[idx(0x100)] |= value & irq_mask(idx(0x100));
            }
            0x180..=0x18C => {
                word_only()?;
                self.enabled[idx(0x180)] &= !value;
            }
            0x200..=0x20C => {
                word_only()?;
                self.pending[idx(0x200)] |= value & irq_mask(idx(0x200));
            }
            0x280..=0x28C => {
                word_only()?;
                self.pending[idx(0x280)] &= !value;
            }
            0x400..=0x47C => {
                let i = (off - 0x400) as usize;
                for (b, byte) in value.to_le_bytes().iter().enumerate() {
                    if mask >> (8 * b) & 0xFF != 0 {
                        self.ipr[i + b] = byte & PRIO_MASK;
                    }
                }
            }
            0xD04 => {
                word_only()?;
                self.write_icsr(value)?;
            }
            0xD08 => {
                word_only()?;
                // VTOR[31:7] (TBLOFF; 128-byte aligned for the G4's 102 vectors: 512-aligned
                // in practice, ARMv7-M B3.2.5).
                self.vtor = value & 0xFFFF_FF80;
            }
            0xD0C => {
                word_only()?;
                if value >> 16 != 0x05FA {
                    // Writes without VECTKEY are ignored (B3.2.6).
                    return Ok(());
                }
                self.prigroup = value >> 8 & 7;
                if value & (1 << 2) != 0 {
                    self.reset_requested = true;
                }
                if value & 3 != 0 {
                    return Err("SCB_AIRCR.VECTRESET/VECTCLRACTIVE (debug-only bits)".into());
                }
            }
            0xD10 => self.scr = value & 0b1_0110,
            0xD14 => self.ccr = value & 0x31B,
            0xD18..=0xD20 => {
                let i = (off - 0xD18) as usize;
                for (b, byte) in value.to_le_bytes().iter().enumerate() {
                    if mask >> (8 * b) & 0xFF != 0 {
                        self.shpr[i + b] = byte & PRIO_MASK;
                    }
                }
            }
            0xD24 => self.shcsr = value & 0x0007_0000,
            0xD88 => self.cpacr = value & 0x00F0_0000,
            0xDFC => self.demcr = value,
            0xF00 => {
                word_only()?;
                let irq = value & 0x1FF;
                if irq < IRQS {
                    self.pending[(irq / 32) as usize] |= 1 << (irq % 32);
                }
            }
            0xF34 => self.fpccr = value & 0xC000_0000 | self.fpccr & 0x1FF,
            0xF3C => self.fpdscr = value & 0x07C0_0000,
            _ => return Err(format!("write of {}", name_or_offset(off))),
        }
        Ok(())
    }

    fn icsr(&self) -> u32 {
        let vectactive = self.active.last().copied().unwrap_or(0);
        let pending = self.highest_pending().map_or(0, |(e, _)| e);
        let isrpending = self.pending.iter().zip(&self.enabled).any(|(p, _)| *p != 0);
        let rettobase = u32::from(self.active.len() <= 1);
        vectactive
            | rettobase << 11
            | pending << 12
            | u32::from(isrpending) << 22
            | (self.sys_pending >> PEND_SV & 1) << 28
            | (self.sys_pending >> SYS_TICK & 1) << 26
            | (self.sys_pending >> NMI & 1) << 31
    }

    fn write_icsr(&mut self, v: u32) -> Result<(), Unimplemented> {
        if v & 1 << 31 != 0 {
            self.sys_pending |= 1 << NMI;
        }
        if v & 1 << 28 != 0 {
            self.sys_pending |= 1 << PEND_SV;
        }
        if v & 1 << 27 != 0 {
            self.sys_pending &= !(1 << PEND_SV);
        }
        if v & 1 << 26 != 0 {
            self.sys_pending |= 1 << SYS_TICK;
        }
        if v & 1 << 25 != 0 {
            self.sys_pending &= !(1 << SYS_TICK);
        }
        Ok(())
    }

    fn active_bits_shcsr(&self) -> u32 {
        let mut v = 0;
        for &e in &self.active {
            v |= match e {
                4 => 1,
                5 => 2,
                6 => 8,
                11 => 1 << 7,
                12 => 1 << 8,
                14 => 1 << 10,
                15 => 1 << 11,
                _ => 0,
            };
        }
        v
    }

    /// Raw priority of exception `e` (NMI −2, HardFault −1).
    pub fn priority(&self, e: u32) -> i32 {
        match e {
            NMI => -2,
            HARD_FAULT => -1,
            4..=15 => i32::from(self.shpr[(e - 4) as usize]),
            _ => i32::from(self.ipr[(e - IRQ0) as usize]),
        }
    }

    /// Group priority of a raw priority (B1.5.4: the bits above PRIGROUP's split).
    fn group(&self, p: i32) -> i32 {
        if p < 0 {
            p
        } else {
            p & !((1 << (self.prigroup + 1)) - 1)
        }
    }

    /// The execution priority for the given special registers (B1.5.4): the highest-priority
    /// active exception's group priority, boosted by BASEPRI, PRIMASK and FAULTMASK; 256 in
    /// thread mode with nothing boosting.
    pub fn execution_priority(&self, primask: bool, basepri: u32, faultmask: bool) -> i32 {
        let mut p = self
            .active
            .iter()
            .map(|&e| self.group(self.priority(e)))
            .min()
            .unwrap_or(256);
        let bp = (basepri & u32::from(PRIO_MASK)) as i32;
        if bp != 0 {
            p = p.min(self.group(bp));
        }
        if primask {
            p = p.min(0);
        }
        if faultmask {
            p = p.min(-1);
        }
        p
    }

    /// The highest-priority pending, enabled exception and its group priority (ties: the
    /// lowest exception number).
    pub fn highest_pending(&self) -> Option<(u32, i32)> {
        let sys = bits(self.sys_pending);
        let irqs = (0..4).flat_map(|w| {
            bits(self.pending[w] & self.enabled[w]).map(move |b| IRQ0 + w as u32 * 32 + b)
        });
        sys.chain(irqs)
            .map(|e| (e, self.group(self.priority(e))))
            .min_by_key(|&(e, p)| (p, e))
    }

    /// Sets IRQ `n` pending (a peripheral's interrupt line is asserted).
    pub fn set_pending_irq(&mut self, n: u32) {
        self.pending[(n / 32) as usize] |= 1 << (n % 32);
    }

    /// Exception entry: `e` becomes active and stops pending.
    pub fn activate(&mut self, e: u32) {
        if e >= IRQ0 {
            let n = e - IRQ0;
            self.pending[(n / 32) as usize] &= !(1 << (n % 32));
        } else {
            self.sys_pending &= !(1 << e);
        }
        self.active.push(e);
    }

    /// Whether exception `e` is active.
    pub fn is_active(&self, e: u32) -> bool {
        self.active.contains(&e)
    }
}

/// The IRQ bits of word `w` that exist on the G431 (IRQ 0..=101).
fn irq_mask(w: usize) -> u32 {
    match w {
        0..=2 => u32::MAX,
        3 => (1 << (IRQS - 96)) - 1,
        _ => 0,
    }
}

fn name_or_offset(off: u32) -> String {
    Scs::name(off).unwrap_or_else(|| format!("SCS+{off:#05x}"))
}
