//! The Cortex-M4F core: Unicorn's ARM CPU (QEMU's TCG, Cortex-M4 model: Thumb-2, the FPU)
//! with the memory map of the STM32G431, and what Unicorn leaves to the harness on a core
//! without its NVIC: reset from the vector table, exception entry and return, sleep.
//!
//! - Reset (ARMv7-M B1.5.5): SP_main from the vector table's word 0, PC from word 1, at VTOR
//!   (0 at reset: the flash is aliased there when BOOT0 is low).
//! - Exception entry (B1.5.6 PushStack, B1.5.7 ExceptionTaken): R0–R3, R12, LR, the return
//!   address and xPSR pushed on the current stack (8-byte aligned with xPSR bit 9 when
//!   CCR.STKALIGN), with S0–S15 and FPSCR (the extended frame, 0x68 bytes) when CONTROL.FPCA
//!   is set; LR = EXC_RETURN (0xFFFFFFF1/F9/FD, bit 4 clear for an extended frame); IPSR = the
//!   exception; CONTROL.FPCA cleared; PC from the vector. FPCCR.LSPEN's lazy stacking is
//!   performed eagerly (the same state, without the deferred memory writes).
//! - Exception return (B1.5.8): Unicorn 2.1 raises an exception at the branch to an EXC_RETURN
//!   value instead of returning; the harness pops the frame (FPU part when EXC_RETURN bit 4 is
//!   0), restores xPSR (IPSR back to the interrupted exception or thread mode), CONTROL.FPCA,
//!   and continues.
//! - WFI/WFE: Unicorn stops with an invalid-instruction error, PC past the instruction. WFE
//!   returns at once if the event register is set (SEV, found by a code hook on the image's
//!   SEV instructions), else both sleep until an interrupt would preempt (WFI: ignoring
//!   PRIMASK, B1.5.19); time jumps to the next peripheral event.
//! - Interrupts are taken between slices of execution; a slice ends at the next peripheral
//!   event, at a register write that may raise one, or within 200 instructions while an
//!   interrupt is pending but masked (so unmasking takes it within that latency).
//! - Time: every instruction is one HCLK cycle, charged per translated block by a block hook
//!   (docs/fwsim.md "Cycle model", "Counting").
//!
//! Only the main stack is modelled (thread mode with PSP stops the run).

use crate::bus::Bus;
use crate::elf::Image;
use crate::flash::{Store, FLASH_BASE, FLASH_SIZE, STORE_LEN, STORE_OFFSET};
use crate::scs::HARD_FAULT;
use crate::sys::ResetCause;
use unicorn_engine::{
    Arch, ArmCpuModel, HookType, MemType, Mode, Prot, RegisterARM, TlbEntry, TlbType, Unicorn,
};

/// RAM: 32 KiB at 0x2000_0000 (memory.x; SRAM1 + SRAM2 + CCM SRAM contiguous).
pub const RAM_BASE: u32 = 0x2000_0000;
/// RAM size.
pub const RAM_SIZE: u32 = 32 * 1024;

/// Why a run stopped.
#[derive(Debug, Clone, PartialEq)]
pub enum Stop {
    /// A reset is due (the MCU restarts).
    Reset(ResetCause),
    /// The emulation cannot go on: an unimplemented register, a fault, a lockup.
    Error(String),
}

/// The MCU.
pub struct Mcu {
    /// The CPU with the bus as its data.
    pub uc: Unicorn<'static, Bus>,
    /// Sleeping in WFI/WFE.
    sleeping: Option<bool>,
    /// The CPU executes nothing before this time (a hung CPU, for the watchdog test); the
    /// peripherals run.
    pub stall_until: u64,
    /// The longest an interrupt waited, pending but masked (PRIMASK, BASEPRI, or a handler of
    /// its priority or higher running), before its handler was entered: instructions (HCLK
    /// cycles), resolved to the ≤ 200-instruction slices the run takes while one is pending.
    pub irq_latency_max: u64,
    /// Where the CPU was when the longest wait was first seen (inside the code that kept the
    /// interrupt masked).
    pub irq_latency_pc: u32,
    /// … and when it ended (within a 200-instruction slice of the code that unmasked it).
    pub irq_latency_end_pc: u32,
    /// Since when (instruction count) the highest pending interrupt has waited, and the PC then.
    pending_since: Option<(u64, u32)>,
}

const R: [RegisterARM; 8] = [
    RegisterARM::R0,
    RegisterARM::R1,
    RegisterARM::R2,
    RegisterARM::R3,
    RegisterARM::R12,
    RegisterARM::LR,
    RegisterARM::PC,
    RegisterARM::XPSR,
];

fn uc_err(what: &str, e: unicorn_engine::uc_error) -> String {
    format!("{what}: {e:?}")
}

impl Mcu {
    /// Powers up (or resets) the MCU with `image` in flash, the store's pages `store` and, after
    /// a reset that keeps the power, the RAM's previous contents.
    pub fn new(
        image: &Image,
        store: Store,
        cause: ResetCause,
        ram: Option<&[u8]>,
    ) -> Result<Self, String> {
        let mut uc = Unicorn::new_with_data(
            Arch::ARM,
            Mode::THUMB | Mode::MCLASS,
            Bus::new(cause, store),
        )
        .map_err(|e| uc_err("unicorn", e))?;
        uc.ctl_set_cpu_model(ArmCpuModel::CORTEX_M4 as i32)
            .map_err(|e| uc_err("cpu model", e))?;
        // Page permissions from the memory map below instead of the M-profile default map
        // (ARMv7-M B3.1, which makes SRAM executable): the firmware does not enable the MPU
        // (an MPU register access stops the run). QEMU under Unicorn keeps no dirty-page
        // tracking, so a store to a page whose TLB entry allows execution always takes the
        // slow path that looks for translated code on the page; with RAM read/write only, a
        // page's stores take the fast path after its first (a quarter of the run time).
        uc.ctl_set_tlb_type(TlbType::VIRTUAL)
            .map_err(|e| uc_err("tlb type", e))?;
        uc.add_tlb_hook(1, 0, |uc: &mut Unicorn<Bus>, addr, kind| {
            // Unicorn restores the CPU state of the accessing instruction before this hook,
            // in the middle of a translated block that goes on executing. Inside a block QEMU
            // keeps the IT state at 0 in the CPU state (it writes it back only when leaving
            // the block: translate.c, arm_tr_tb_start), so a restored IT state from inside an
            // IT block would outlive the block and condition the next one's instructions.
            // Put the 0 back. (Fetches fill the TLB before a block runs: nothing restored.)
            if matches!(kind, MemType::READ | MemType::WRITE) {
                if let Ok(cpsr) = uc.reg_read(RegisterARM::CPSR) {
                    const IT: u64 = 0x0600_FC00;
                    if cpsr & IT != 0 {
                        let _ = uc.reg_write(RegisterARM::CPSR, cpsr & !IT);
                    }
                }
            }
            Some(TlbEntry {
                paddr: addr,
                perms: page_perms(addr),
            })
        })
        .map_err(|e| uc_err("tlb hook", e))?;
        // Flash below the store: plain read/execute memory with the image.
        uc.mem_map(
            u64::from(FLASH_BASE),
            u64::from(STORE_OFFSET),
            Prot::READ | Prot::EXEC,
        )
        .map_err(|e| uc_err("map flash", e))?;
        let mut flash = vec![0xFFu8; STORE_OFFSET as usize];
        for (addr, data) in &image.segments {
            let a = *addr;
            if a >= RAM_BASE {
                continue;
            }
            let off = a
                .checked_sub(FLASH_BASE)
                .ok_or(format!("segment at {a:#x} outside flash"))? as usize;
            if off + data.len() > flash.len() {
                return Err(format!(
                    "segment at {a:#x} runs into the configuration store"
                ));
            }
            flash[off..off + data.len()].copy_from_slice(data);
        }
        uc.mem_write(u64::from(FLASH_BASE), &flash)
            .map_err(|e| uc_err("load flash", e))?;
        debug_assert_eq!(STORE_OFFSET as usize + STORE_LEN, FLASH_SIZE as usize);
        // The store's pages: every access goes through the flash model (programming, ECC).
        uc.mmio_map(
            u64::from(FLASH_BASE + STORE_OFFSET),
            STORE_LEN as u64,
            Some(|uc: &mut Unicorn<Bus>, off: u64, size: usize| {
                let v = uc.get_data_mut().store_read(off as usize, size);
                check_stop(uc);
                u64::from(v)
            }),
            Some(|uc: &mut Unicorn<Bus>, off: u64, size: usize, v: u64| {
                let b = uc.get_data_mut();
                b.store_write(off as usize, size, v as u32);
                // An operation may have started: the CPU stalls on its next fetch.
                b.end_slice();
            }),
        )
        .map_err(|e| uc_err("map store", e))?;
        // RAM: read and write, not execute (the firmware runs from flash only). QEMU keeps no
        // dirty tracking under Unicorn: a store to a page Unicorn maps executable always looks
        // for translated code on the page (a quarter of the run time when RAM was executable).
        uc.mem_map(
            u64::from(RAM_BASE),
            u64::from(RAM_SIZE),
            Prot::READ | Prot::WRITE,
        )
        .map_err(|e| uc_err("map ram", e))?;
        if let Some(ram) = ram {
            uc.mem_write(u64::from(RAM_BASE), ram)
                .map_err(|e| uc_err("ram", e))?;
        }
        for (addr, data) in &image.segments {
            if *addr >= RAM_BASE {
                uc.mem_write(u64::from(*addr), data)
                    .map_err(|e| uc_err("load ram", e))?;
            }
        }
        // Peripherals (4 KiB-aligned windows; the bus decodes within them).
        for (base, size) in [
            (0x4000_0000u64, 0x8000u64),
            (0x4001_0000, 0x6000),
            (0x4002_0000, 0x4000),
            (0x4800_0000, 0x2000),
            (0x5000_0000, 0x1000),
            (0xE000_0000, 0x10_0000),
        ] {
            uc.mmio_map(
                base,
                size,
                Some(move |uc: &mut Unicorn<Bus>, off: u64, size: usize| {
                    let v = uc.get_data_mut().read((base + off) as u32, size);
                    check_stop(uc);
                    u64::from(v)
                }),
                Some(
                    move |uc: &mut Unicorn<Bus>, off: u64, size: usize, v: u64| {
                        let b = uc.get_data_mut();
                        b.write((base + off) as u32, size, v as u32);
                        // A write may raise an interrupt or change the clock: end the slice.
                        b.end_slice();
                    },
                ),
            )
            .map_err(|e| uc_err("map peripherals", e))?;
        }
        // Instruction count: the time base, charged per translated block. The hook runs when a
        // block starts, before any of its instructions: it stops the slice there once the
        // budget is spent (the block runs in the next slice), else charges the whole block. A
        // block ends at every branch, exception-raising instruction (WFI, WFE, UDF, BKPT, SVC)
        // and exception return, so a slice always ends on a charged block boundary: the count
        // is exact at every stop. Inside a block, a peripheral access sees the time at the
        // block's end (docs/fwsim.md "Cycle model").
        let mut blocks = BlockLengths::new(flash.clone());
        uc.add_block_hook(1, 0, move |uc: &mut Unicorn<Bus>, addr, size| {
            let n = match blocks.count(addr as u32, size) {
                Some(n) => n,
                None => {
                    // Code outside the flash image (none in our firmware): read it.
                    let mut code = vec![0u8; size as usize];
                    let _ = uc.mem_read(addr, &mut code);
                    thumb_count(&code)
                }
            };
            let b = uc.get_data_mut();
            if b.insns >= b.stop_at {
                let _ = uc.emu_stop();
            } else {
                b.insns += u64::from(n);
                b.blocks += 1;
                b.longest_block = b.longest_block.max(n);
            }
        })
        .map_err(|e| uc_err("block hook", e))?;
        // SEV sets the event register (Unicorn executes it as a NOP): hooks on the image's SEV
        // encodings (0xBF40), so only those addresses pay for a hook.
        for a in sev_addresses(&flash) {
            let a = u64::from(FLASH_BASE) + a as u64;
            uc.add_code_hook(a, a, |uc: &mut Unicorn<Bus>, _, _| {
                uc.get_data_mut().event = true;
            })
            .map_err(|e| uc_err("sev hook", e))?;
        }
        // Accesses to unmapped or protected memory, everywhere but the RAM (fully mapped): a
        // memory hook over a page keeps every store to it on QEMU's slow path (no dirty
        // tracking under Unicorn), so the RAM has none.
        for (begin, end) in [
            (0u64, u64::from(RAM_BASE) - 1),
            (u64::from(RAM_BASE + RAM_SIZE), u64::from(u32::MAX)),
        ] {
            uc.add_mem_hook(
                HookType::MEM_INVALID,
                begin,
                end,
                |uc: &mut Unicorn<Bus>, kind: MemType, addr, size, value| {
                    let what = match kind {
                        MemType::READ_UNMAPPED | MemType::READ_PROT => "read of",
                        MemType::WRITE_UNMAPPED | MemType::WRITE_PROT => "write to",
                        _ => "fetch from",
                    };
                    uc.get_data_mut().fail(format!(
                        "{what} {addr:#010x} ({size} bytes, value {value:#x}): nothing modelled there"
                    ));
                    false
                },
            )
            .map_err(|e| uc_err("mem hook", e))?;
        }

        let mut mcu = Self {
            uc,
            sleeping: None,
            stall_until: 0,
            irq_latency_max: 0,
            irq_latency_pc: 0,
            irq_latency_end_pc: 0,
            pending_since: None,
        };
        // Vector table at 0 = the flash's start (BOOT0 low).
        let sp = mcu.read_word(FLASH_BASE)?;
        let pc = mcu.read_word(FLASH_BASE + 4)?;
        mcu.reg_w(RegisterARM::MSP, sp)?;
        mcu.reg_w(RegisterARM::SP, sp)?;
        mcu.reg_w(RegisterARM::LR, 0xFFFF_FFFF)?;
        mcu.reg_w(RegisterARM::PC, pc & !1)?;
        Ok(mcu)
    }

    /// The bus.
    pub fn bus(&mut self) -> &mut Bus {
        self.uc.get_data_mut()
    }

    /// The bus, read-only.
    pub fn bus_ref(&self) -> &Bus {
        self.uc.get_data()
    }

    /// A word of memory.
    pub fn read_word(&self, addr: u32) -> Result<u32, String> {
        let mut b = [0u8; 4];
        self.uc
            .mem_read(u64::from(addr), &mut b)
            .map_err(|e| format!("read {addr:#x}: {e:?}"))?;
        Ok(u32::from_le_bytes(b))
    }

    fn write_word(&mut self, addr: u32, v: u32) -> Result<(), String> {
        self.uc
            .mem_write(u64::from(addr), &v.to_le_bytes())
            .map_err(|e| format!("stack write at {addr:#x}: {e:?}"))
    }

    fn reg(&self, r: RegisterARM) -> Result<u32, String> {
        self.uc
            .reg_read(r)
            .map(|v| v as u32)
            .map_err(|e| uc_err("reg read", e))
    }

    fn reg_w(&mut self, r: RegisterARM, v: u32) -> Result<(), String> {
        self.uc
            .reg_write(r, u64::from(v))
            .map_err(|e| uc_err("reg write", e))
    }

    /// The RAM's contents (kept across a reset that keeps the power).
    pub fn ram(&self) -> Vec<u8> {
        self.uc
            .mem_read_as_vec(u64::from(RAM_BASE), RAM_SIZE as usize)
            .unwrap_or_default()
    }

    /// Current program counter.
    pub fn pc(&self) -> u32 {
        self.reg(RegisterARM::PC).unwrap_or(0)
    }

    /// Exception entry for exception `e` with the return address `ret`.
    fn enter(&mut self, e: u32, ret: u32) -> Result<(), String> {
        let control = self.reg(RegisterARM::CONTROL)?;
        if control & 2 != 0 {
            return Err("CONTROL.SPSEL = 1: the process stack is not modelled".into());
        }
        let ipsr_before = self.reg(RegisterARM::IPSR)?;
        let fpca = control & 4 != 0;
        let sp = self.reg(RegisterARM::SP)?;
        let frame = if fpca { 0x68 } else { 0x20 };
        let align = sp & 4 != 0 && self.bus_ref().scs.ccr & (1 << 9) != 0;
        let fp = (sp - frame) & !(u32::from(align) << 2);
        let mut vals = [0u32; 8];
        for (v, r) in vals.iter_mut().zip(R) {
            *v = self.reg(r)?;
        }
        vals[6] = ret;
        vals[7] = vals[7] & !(1 << 9) | u32::from(align) << 9;
        for (i, v) in vals.iter().enumerate() {
            self.write_word(fp + 4 * i as u32, *v)?;
        }
        if fpca {
            for i in 0..16 {
                let s = self.reg(s_reg(i))?;
                self.write_word(fp + 0x20 + 4 * i as u32, s)?;
            }
            let fpscr = self.reg(RegisterARM::FPSCR)?;
            self.write_word(fp + 0x60, fpscr)?;
        }
        self.reg_w(RegisterARM::SP, fp)?;
        let exc_return = match (ipsr_before != 0, fpca) {
            (true, false) => 0xFFFF_FFF1,
            (false, false) => 0xFFFF_FFF9,
            (true, true) => 0xFFFF_FFE1,
            (false, true) => 0xFFFF_FFE9,
        };
        self.reg_w(RegisterARM::LR, exc_return)?;
        let vtor = self.bus_ref().scs.vtor;
        let table = if vtor < FLASH_BASE {
            FLASH_BASE + vtor
        } else {
            vtor
        };
        let vector = self.read_word(table + 4 * e)?;
        if vector & 1 == 0 {
            return Err(format!(
                "exception {e}: vector {vector:#x} is not a Thumb address"
            ));
        }
        // xPSR: IPSR = e, Thumb, IT cleared, flags kept.
        let xpsr = self.reg(RegisterARM::XPSR)?;
        self.reg_w(RegisterARM::XPSR, xpsr & 0xF80F_0000 | 1 << 24 | e)?;
        self.reg_w(RegisterARM::CONTROL, control & !4)?;
        self.reg_w(RegisterARM::PC, vector & !1)?;
        self.bus().scs.activate(e);
        self.sleeping = None;
        Ok(())
    }

    /// Exception return to the EXC_RETURN value `exc`.
    fn exit(&mut self, exc: u32) -> Result<(), String> {
        if !matches!(exc, 0xFFFF_FFF1 | 0xFFFF_FFF9 | 0xFFFF_FFE1 | 0xFFFF_FFE9) {
            return Err(format!(
                "exception return to {exc:#x} (process stack or invalid)"
            ));
        }
        let ipsr = self.reg(RegisterARM::IPSR)?;
        let bus = self.bus();
        match bus.scs.active.last() {
            Some(&a) if a == ipsr => {
                bus.scs.active.pop();
            }
            _ => return Err(format!("exception return from {ipsr}, not the active one")),
        }
        let sp = self.reg(RegisterARM::SP)?;
        let mut vals = [0u32; 8];
        for (i, v) in vals.iter_mut().enumerate() {
            *v = self.read_word(sp + 4 * i as u32)?;
        }
        let extended = exc & 0x10 == 0;
        if extended {
            for i in 0..16 {
                let s = self.read_word(sp + 0x20 + 4 * i as u32)?;
                self.reg_w(s_reg(i), s)?;
            }
            let fpscr = self.read_word(sp + 0x60)?;
            self.reg_w(RegisterARM::FPSCR, fpscr)?;
        }
        let frame = if extended { 0x68 } else { 0x20 };
        let new_sp = sp + frame + if vals[7] & 1 << 9 != 0 { 4 } else { 0 };
        for (v, r) in vals.iter().zip(R).take(6) {
            self.reg_w(r, *v)?;
        }
        let to_thread = exc & 8 != 0;
        let ret_ipsr = vals[7] & 0x1FF;
        if to_thread != (ret_ipsr == 0) {
            return Err(format!(
                "exception return: EXC_RETURN {exc:#x} with a stacked IPSR of {ret_ipsr}"
            ));
        }
        self.reg_w(RegisterARM::XPSR, vals[7] & !(1 << 9))?;
        self.reg_w(RegisterARM::SP, new_sp)?;
        let control = self.reg(RegisterARM::CONTROL)?;
        self.reg_w(
            RegisterARM::CONTROL,
            control & !4 | u32::from(extended) << 2,
        )?;
        self.reg_w(RegisterARM::PC, vals[6] & !1)?;
        Ok(())
    }

    fn special(&self) -> Result<(bool, u32, bool), String> {
        Ok((
            self.reg(RegisterARM::PRIMASK)? & 1 != 0,
            self.reg(RegisterARM::BASEPRI)?,
            self.reg(RegisterARM::FAULTMASK)? & 1 != 0,
        ))
    }

    /// Runs the firmware until emulated time `t_end` (ticks).
    pub fn run_until(&mut self, t_end: u64) -> Result<(), Stop> {
        loop {
            if let Some(e) = self.bus().error.take() {
                return Err(Stop::Error(format!("{e} [pc {:#010x}]", self.pc())));
            }
            if let Some(cause) = self.bus_ref().reset_due() {
                return Err(Stop::Reset(cause));
            }
            let now = self.bus_ref().now();
            if now >= t_end {
                return Ok(());
            }
            self.bus().update_lines();
            if now < self.stall_until {
                let next = self.bus_ref().next_event().unwrap_or(t_end);
                let until = next.min(t_end).min(self.stall_until);
                self.bus().skip_to(until);
                continue;
            }
            // A flash operation stalls every fetch from flash.
            if let Some(until) = self.bus_ref().flash.busy_until() {
                let pc = self.pc();
                if (FLASH_BASE..FLASH_BASE + FLASH_SIZE).contains(&pc) {
                    self.bus().skip_to(until.min(t_end));
                    continue;
                }
            }
            let (primask, basepri, faultmask) = self.special().map_err(Stop::Error)?;
            let exec = self
                .bus_ref()
                .scs
                .execution_priority(primask, basepri, faultmask);
            let pending = self.bus_ref().scs.highest_pending();
            let insns = self.bus_ref().insns;
            if let Some((e, p)) = pending {
                if p < exec {
                    let pc = self.pc();
                    if let Some((since, from)) = self.pending_since.take() {
                        if insns - since > self.irq_latency_max {
                            self.irq_latency_max = insns - since;
                            self.irq_latency_pc = from;
                            self.irq_latency_end_pc = pc;
                        }
                    }
                    self.enter(e, pc).map_err(Stop::Error)?;
                    continue;
                }
                if self.pending_since.is_none() {
                    self.pending_since = Some((insns, self.pc()));
                }
            } else {
                self.pending_since = None;
            }
            if let Some(wfi) = self.sleeping {
                // WFI wakes on an interrupt that would preempt were PRIMASK clear.
                let wake_prio = if wfi {
                    self.bus_ref()
                        .scs
                        .execution_priority(false, basepri, faultmask)
                } else {
                    exec
                };
                if pending.is_some_and(|(_, p)| p < wake_prio) {
                    self.sleeping = None;
                    continue;
                }
                let next = self.bus_ref().next_event().unwrap_or(t_end).min(t_end);
                self.bus().skip_to(next);
                continue;
            }
            let bus = self.bus_ref();
            let horizon = bus.next_event().unwrap_or(t_end).min(t_end);
            let mut budget = (horizon.saturating_sub(now))
                .div_ceil(bus.cycle_ticks)
                .max(1);
            if pending.is_some() {
                budget = budget.min(200);
            }
            let insns = bus.insns;
            self.bus().stop_at = insns + budget;
            let pc = self.pc();
            self.bus().stats[2] += 1;
            let r = self.uc.emu_start(u64::from(pc | 1), 0, 0, 0);
            match r {
                Ok(()) => {}
                Err(unicorn_engine::uc_error::INSN_INVALID) => {
                    let pc = self.pc();
                    let mut h = [0u8; 2];
                    let _ = self.uc.mem_read(u64::from(pc.wrapping_sub(2)), &mut h);
                    match u16::from_le_bytes(h) {
                        // WFE: the event register set returns at once (and clears it).
                        0xBF20 => {
                            if !std::mem::take(&mut self.bus().event) {
                                self.sleeping = Some(false);
                            }
                        }
                        0xBF30 => self.sleeping = Some(true),
                        _ => self.fault(pc, "undefined instruction")?,
                    }
                }
                Err(unicorn_engine::uc_error::EXCEPTION) => {
                    let pc = self.pc();
                    if pc >= 0xFFFF_FF00 {
                        self.exit(pc | 1).map_err(Stop::Error)?;
                    } else {
                        let mut h = [0u8; 2];
                        let _ = self.uc.mem_read(u64::from(pc), &mut h);
                        match h[1] {
                            // UDF: the firmware's panics (-Cpanic=immediate-abort) and
                            // panic-probe end here; a UsageFault escalated to HardFault.
                            0xDE => self.fault(pc, "UDF")?,
                            0xBE => return Err(Stop::Error(format!("BKPT at {pc:#010x}"))),
                            _ => {
                                return Err(Stop::Error(format!(
                                    "CPU exception at {pc:#010x} (instruction {:#06x})",
                                    u16::from_le_bytes(h)
                                )))
                            }
                        }
                    }
                }
                Err(e) => {
                    let detail = self.bus().error.take().unwrap_or_default();
                    return Err(Stop::Error(format!(
                        "{e:?} at pc {:#010x}: {detail}",
                        self.pc()
                    )));
                }
            }
        }
    }

    /// A fault at `pc`: HardFault (UsageFault is disabled at reset and escalates), or a lockup
    /// if HardFault is active already.
    fn fault(&mut self, pc: u32, what: &str) -> Result<(), Stop> {
        if self.bus_ref().scs.is_active(HARD_FAULT) || self.bus_ref().scs.is_active(crate::scs::NMI)
        {
            return Err(Stop::Error(format!(
                "lockup: {what} at {pc:#010x} inside HardFault/NMI"
            )));
        }
        self.bus().scs.sys_pending |= 1 << HARD_FAULT;
        // Synchronous: taken at once, returning to the faulting instruction.
        self.enter(HARD_FAULT, pc).map_err(Stop::Error)?;
        self.bus().scs.sys_pending &= !(1 << HARD_FAULT);
        Ok(())
    }
}

fn s_reg(i: usize) -> RegisterARM {
    const S: [RegisterARM; 16] = [
        RegisterARM::S0,
        RegisterARM::S1,
        RegisterARM::S2,
        RegisterARM::S3,
        RegisterARM::S4,
        RegisterARM::S5,
        RegisterARM::S6,
        RegisterARM::S7,
        RegisterARM::S8,
        RegisterARM::S9,
        RegisterARM::S10,
        RegisterARM::S11,
        RegisterARM::S12,
        RegisterARM::S13,
        RegisterARM::S14,
        RegisterARM::S15,
    ];
    S[i]
}

/// Ends the slice after this instruction when the bus has an error or an NMI to deliver.
fn check_stop(uc: &mut Unicorn<Bus>) {
    let b = uc.get_data_mut();
    if b.error.is_some() || b.scs.sys_pending != 0 {
        b.end_slice();
    }
}

/// The permissions of the page at `addr` (the mapping in [`Mcu::new`]): the flash below the
/// store read/execute, the store's pages (programmed through the flash model) and RAM
/// read/write, the peripherals and the system control space read/write; elsewhere all, so the
/// access reaches Unicorn's unmapped-memory report.
fn page_perms(addr: u64) -> Prot {
    let a = addr as u32;
    if (FLASH_BASE..FLASH_BASE + STORE_OFFSET).contains(&a) {
        Prot::READ | Prot::EXEC
    } else if (FLASH_BASE + STORE_OFFSET..FLASH_BASE + FLASH_SIZE).contains(&a)
        || (RAM_BASE..RAM_BASE + RAM_SIZE).contains(&a)
        || (0x4000_0000..0x6000_0000).contains(&a)
        || a >= 0xE000_0000
    {
        Prot::READ | Prot::WRITE
    } else {
        Prot::ALL
    }
}

/// Instructions in Thumb code: a half-word whose top five bits are 0b11101, 0b11110 or
/// 0b11111 starts a 32-bit instruction (ARMv7-M ARM A5.1), any other a 16-bit one.
fn thumb_count(code: &[u8]) -> u32 {
    let mut n = 0;
    let mut i = 0;
    while i + 1 < code.len() {
        let hw = u16::from_le_bytes([code[i], code[i + 1]]);
        i += if hw >> 11 >= 0b11101 { 4 } else { 2 };
        n += 1;
    }
    n
}

/// The instruction count of each translated block in the flash image, by start address and
/// size (the block hook's arguments), decoded once.
struct BlockLengths {
    flash: Vec<u8>,
    /// Per half-word of the image: (block size in bytes, instructions); size 0 = not yet seen.
    cache: Vec<(u16, u16)>,
}

impl BlockLengths {
    fn new(flash: Vec<u8>) -> Self {
        let cache = vec![(0, 0); flash.len() / 2];
        Self { flash, cache }
    }

    /// The instructions of the block at `addr` of `size` bytes, if it lies in the image.
    fn count(&mut self, addr: u32, size: u32) -> Option<u32> {
        let off = addr.checked_sub(FLASH_BASE)? as usize;
        let end = off.checked_add(size as usize)?;
        let code = self.flash.get(off..end)?;
        let slot = self.cache.get_mut(off / 2)?;
        if usize::from(slot.0) != size as usize || size == 0 {
            let n = thumb_count(code);
            *slot = (
                u16::try_from(size).unwrap_or(0),
                u16::try_from(n).unwrap_or(0),
            );
            return Some(n);
        }
        Some(u32::from(slot.1))
    }
}

/// Offsets of every half-word 0xBF40 (SEV) at an even offset in the image.
fn sev_addresses(flash: &[u8]) -> Vec<usize> {
    flash
        .chunks_exact(2)
        .enumerate()
        .filter(|(_, h)| h == &[0x40, 0xBF])
        .map(|(i, _)| 2 * i)
        .collect()
}
