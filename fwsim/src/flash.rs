//! The embedded flash's interface (FLASH, 0x4002_2000) and the configuration store's pages.
//!
//! Sources: RM0440 ch. 3 "Embedded flash memory (FLASH)": FLASH_ACR (LATENCY, caches, their
//! reset bits), unlocking FLASH_CR with KEY1 = 0x4567_0123 then KEY2 = 0xCDEF_89AB (a wrong key
//! locks the register until reset, "Unlocking the flash memory"), the standard programming
//! sequence (PG set, a double word written as two word writes to consecutive addresses, the
//! operation starting at the second: "Flash memory programming sequence"), page erase (PER,
//! PNB, STRT: "Page erase"), the error flags of FLASH_SR (PROGERR: the double word was not
//! erased and the data is not all zeros; PGAERR: the second word is not the first one's
//! partner; SIZERR: a byte or half-word write; PGSERR: a write without PG, or an operation
//! started while an error flag is set; WRPERR is not reachable: no write protection is
//! configured), and the ECC (FLASH_ECCR: a double-bit error sets ECCD and ADDR_ECC and raises
//! the NMI; "Error code correction (ECC)"). Times: the STM32G431 datasheet's typical t_PROG =
//! 81.7 µs per double word and t_ERASE = 22.02 ms per 2 KiB page. While BSY the flash cannot be
//! read, so the CPU, which runs from it, stalls (the harness advances time without executing).
//!
//! Only the configuration store's pages (the last 8 KiB, memory.x) can be programmed here: the
//! firmware has no reason to write its own code, and such a write stops the run. A power cut
//! while BSY ([`Flash::power_cut`]) leaves the double word being programmed, or the page being
//! erased, torn: bits part-way between old and new, its ECC not matching (an ECCD on read).

use crate::TICK_HZ;

/// Start of flash.
pub const FLASH_BASE: u32 = 0x0800_0000;
/// Flash size (STM32G431CB: 128 KiB).
pub const FLASH_SIZE: u32 = 128 * 1024;
/// The configuration store: offset and length (the firmware's `STORE_RANGE`, memory.x).
pub const STORE_OFFSET: u32 = 0x1E000;
/// Store length.
pub const STORE_LEN: usize = 0x2000;
/// Page size.
pub const PAGE: usize = 2048;

/// A register access the model does not implement.
pub type Unimplemented = String;

const KEY1: u32 = 0x4567_0123;
const KEY2: u32 = 0xCDEF_89AB;
const T_PROG_S: f64 = 81.7e-6;
const T_ERASE_S: f64 = 22.02e-3;

const SR_EOP: u32 = 1;
const SR_PROGERR: u32 = 1 << 3;
const SR_PGAERR: u32 = 1 << 5;
const SR_SIZERR: u32 = 1 << 6;
const SR_PGSERR: u32 = 1 << 7;
const SR_ERRORS: u32 = 0xC3FA;
const SR_BSY: u32 = 1 << 16;
const CR_PG: u32 = 1;
const CR_PER: u32 = 1 << 1;
const CR_STRT: u32 = 1 << 16;
const CR_LOCK: u32 = 1 << 31;

/// An operation in progress.
#[derive(Clone, Debug)]
enum Op {
    /// Programming the double word at store offset `off` with `data`.
    Program { off: usize, data: [u8; 8] },
    /// Erasing the store page `page`.
    Erase { page: usize },
}

/// Record of a finished or started operation (for the power-cut test's schedule).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OpTimes {
    /// Start, ticks.
    pub start: u64,
    /// End, ticks.
    pub end: u64,
    /// True for an erase.
    pub erase: bool,
}

/// The store's contents: bytes and, per double word, whether its ECC is broken.
#[derive(Clone, Debug, PartialEq)]
pub struct Store {
    /// Bytes (erased = 0xFF).
    pub bytes: Vec<u8>,
    /// Per double word: a torn write left its ECC inconsistent.
    pub torn: Vec<bool>,
}

impl Default for Store {
    fn default() -> Self {
        Self {
            bytes: vec![0xFF; STORE_LEN],
            torn: vec![false; STORE_LEN / 8],
        }
    }
}

impl Store {
    /// Serialised: the bytes, then one byte per double word (1 = torn).
    pub fn to_file_bytes(&self) -> Vec<u8> {
        let mut v = self.bytes.clone();
        v.extend(self.torn.iter().map(|&t| u8::from(t)));
        v
    }

    /// From [`Store::to_file_bytes`]'s format.
    pub fn from_file_bytes(b: &[u8]) -> Result<Self, String> {
        if b.len() != STORE_LEN + STORE_LEN / 8 {
            return Err(format!(
                "flash file of {} bytes, expected {}",
                b.len(),
                STORE_LEN + STORE_LEN / 8
            ));
        }
        Ok(Self {
            bytes: b[..STORE_LEN].to_vec(),
            torn: b[STORE_LEN..].iter().map(|&t| t != 0).collect(),
        })
    }
}

/// FLASH state.
#[derive(Clone, Debug)]
pub struct Flash {
    /// FLASH_ACR.
    pub acr: u32,
    cr: u32,
    sr: u32,
    eccr: u32,
    /// KEYR sequence: the next key expected (0 = KEY1, 1 = KEY2), or locked until reset.
    key_state: u8,
    /// The first word of a double word being written: (store offset, word).
    first: Option<(usize, u32)>,
    /// The operation under way and when it ends.
    busy: Option<(Op, u64, u64)>,
    /// The store's pages.
    pub store: Store,
    /// Every operation started (for power-cut schedules).
    pub log: Vec<OpTimes>,
    /// A double-bit ECC error was just read: the NMI is to be raised.
    pub nmi: bool,
}

/// Register names.
pub fn name(off: u32) -> Option<&'static str> {
    Some(match off {
        0x00 => "ACR",
        0x04 => "PDKEYR",
        0x08 => "KEYR",
        0x0C => "OPTKEYR",
        0x10 => "SR",
        0x14 => "CR",
        0x18 => "ECCR",
        0x20 => "OPTR",
        _ => return None,
    })
}

impl Flash {
    /// The interface at reset (ACR 0x600: caches on, 0 wait states; CR locked), over `store`.
    pub fn new(store: Store) -> Self {
        Self {
            acr: 0x0000_0600,
            cr: 0xC000_0000,
            sr: 0,
            eccr: 0,
            key_state: 0,
            first: None,
            busy: None,
            store,
            log: Vec::new(),
            nmi: false,
        }
    }

    /// FLASH_ACR.LATENCY.
    pub fn latency(&self) -> u32 {
        self.acr & 0xF
    }

    /// The time the operation under way ends (the CPU stalls until then).
    pub fn busy_until(&self) -> Option<u64> {
        self.busy.as_ref().map(|b| b.2)
    }

    /// Completes an operation whose time has come.
    pub fn settle(&mut self, now: u64) {
        if let Some((op, _, end)) = &self.busy {
            if now >= *end {
                match op {
                    Op::Program { off, data } => {
                        for (i, b) in data.iter().enumerate() {
                            // Programming only clears bits (NOR flash).
                            self.store.bytes[off + i] &= b;
                        }
                        self.store.torn[off / 8] = false;
                    }
                    Op::Erase { page } => {
                        let r = page * PAGE..(page + 1) * PAGE;
                        self.store.bytes[r.clone()].fill(0xFF);
                        self.store.torn[r.start / 8..r.end / 8].fill(false);
                    }
                }
                self.sr |= SR_EOP;
                self.busy = None;
            }
        }
    }

    /// Power lost at `now`: an operation under way is left torn.
    pub fn power_cut(&mut self, now: u64) {
        if let Some((op, start, end)) = self.busy.take() {
            let f = (now - start) as f64 / (end - start) as f64;
            // Which bits had flipped by the cut: a fixed pseudo-random order (xorshift over
            // the bit index), the first fraction f of them.
            let flipped = |i: usize| {
                let mut x = (i as u64 + 1).wrapping_mul(0x9E37_79B9_7F4A_7C15);
                x ^= x >> 29;
                (x % 1000) as f64 / 1000.0 < f
            };
            match op {
                Op::Program { off, data } => {
                    for (i, b) in data.iter().enumerate() {
                        let mut v = self.store.bytes[off + i];
                        for bit in 0..8 {
                            if b >> bit & 1 == 0 && flipped((off + i) * 8 + bit) {
                                v &= !(1 << bit);
                            }
                        }
                        self.store.bytes[off + i] = v;
                    }
                    self.store.torn[off / 8] = true;
                }
                Op::Erase { page } => {
                    for dw in page * PAGE / 8..(page + 1) * PAGE / 8 {
                        let was_erased = self.store.bytes[dw * 8..dw * 8 + 8]
                            .iter()
                            .all(|&b| b == 0xFF);
                        if was_erased && !self.store.torn[dw] {
                            continue;
                        }
                        for i in dw * 8..dw * 8 + 8 {
                            for bit in 0..8 {
                                if flipped(i * 8 + bit) {
                                    self.store.bytes[i] |= 1 << bit;
                                }
                            }
                        }
                        self.store.torn[dw] = true;
                    }
                }
            }
        }
    }

    /// Reads register `off`.
    pub fn read(&mut self, off: u32, now: u64) -> Result<u32, Unimplemented> {
        self.settle(now);
        Ok(match off {
            0x00 => self.acr,
            0x10 => self.sr | if self.busy.is_some() { SR_BSY } else { 0 },
            0x14 => self.cr,
            0x18 => self.eccr,
            // OPTR as shipped (RM0440 reset value): RDP level 0, nBOOT1, nSWBOOT0 = 1,
            // IWDG_SW (software watchdog).
            0x20 => 0xFFEF_F8AA,
            _ => return Err(format!("read of FLASH.{}", name(off).unwrap_or("?"))),
        })
    }

    /// Writes register `off`.
    pub fn write(&mut self, off: u32, v: u32, now: u64) -> Result<(), Unimplemented> {
        self.settle(now);
        match off {
            0x00 => {
                if v & 0xF > 8 {
                    return Err(format!("FLASH.ACR.LATENCY = {}", v & 0xF));
                }
                // ICRST/DCRST only while the caches are off (RM0440 FLASH_ACR).
                if v & (1 << 11) != 0 && v & (1 << 9) != 0
                    || v & (1 << 12) != 0 && v & (1 << 10) != 0
                {
                    return Err("FLASH.ACR: cache reset while the cache is enabled".into());
                }
                self.acr = v & 0x0004_7F0F;
            }
            0x08 => match (self.key_state, v) {
                (0, KEY1) => self.key_state = 1,
                (1, KEY2) => {
                    self.key_state = 0;
                    self.cr &= !CR_LOCK;
                }
                _ => {
                    return Err(format!(
                        "FLASH.KEYR: wrong key {v:#x} (the register locks until the next reset)"
                    ))
                }
            },
            0x0C => return Err("FLASH.OPTKEYR: option bytes not modelled".into()),
            // Error flags and EOP: write 1 to clear.
            0x10 => self.sr &= !(v & (SR_ERRORS | SR_EOP)),
            0x14 => {
                if self.cr & CR_LOCK != 0 {
                    if v & CR_LOCK == 0 {
                        return Err("FLASH.CR written while locked".into());
                    }
                    return Ok(());
                }
                if self.busy.is_some() {
                    return Err("FLASH.CR written while BSY".into());
                }
                if v & !(CR_PG | CR_PER | 0x3F8 | CR_STRT | 3 << 24 | 1 << 30 | CR_LOCK) != 0 {
                    return Err(format!("FLASH.CR = {v:#x}: mass erase, fast programming, option bytes or interrupts"));
                }
                self.cr = v & !CR_STRT;
                if v & CR_STRT != 0 {
                    if v & CR_PER == 0 || v & CR_PG != 0 || self.sr & SR_ERRORS != 0 {
                        self.sr |= SR_PGSERR;
                    } else {
                        let pnb = (v >> 3 & 0x7F) as usize;
                        let first = STORE_OFFSET as usize / PAGE;
                        if !(first..first + STORE_LEN / PAGE).contains(&pnb) {
                            return Err(format!(
                                "FLASH page erase of page {pnb}: outside the configuration store"
                            ));
                        }
                        self.start(Op::Erase { page: pnb - first }, now, T_ERASE_S);
                    }
                }
            }
            0x18 => {
                // ECCC/ECCD: write 1 to clear; ECCCIE.
                self.eccr &= !(v & 0xC000_0000);
                self.eccr = self.eccr & !(1 << 24) | v & 1 << 24;
            }
            _ => return Err(format!("write of FLASH.{}", name(off).unwrap_or("?"))),
        }
        Ok(())
    }

    fn start(&mut self, op: Op, now: u64, secs: f64) {
        let end = now + (secs * TICK_HZ as f64) as u64;
        self.log.push(OpTimes {
            start: now,
            end,
            erase: matches!(op, Op::Erase { .. }),
        });
        self.busy = Some((op, now, end));
    }

    /// A CPU read of the store at offset `off` (from the store's start), `size` bytes.
    pub fn read_store(&mut self, off: usize, size: usize, now: u64) -> u32 {
        self.settle(now);
        if self.store.torn[off / 8] {
            // Double-bit error: ECCD with the failing address (byte offset from the flash's
            // start), and the NMI (RM0440 "Error code correction (ECC)").
            self.eccr |= 1 << 31 | (STORE_OFFSET + (off as u32 & !7)) & 0x7FFFF;
            self.nmi = true;
        }
        let mut b = [0u8; 4];
        b[..size].copy_from_slice(&self.store.bytes[off..off + size]);
        u32::from_le_bytes(b)
    }

    /// A CPU write into the store: the programming sequence.
    pub fn write_store(
        &mut self,
        off: usize,
        size: usize,
        v: u32,
        now: u64,
    ) -> Result<(), Unimplemented> {
        self.settle(now);
        if self.busy.is_some() {
            return Err("write to the flash while BSY".into());
        }
        if self.cr & CR_PG == 0 {
            self.sr |= SR_PGSERR;
            return Ok(());
        }
        if size != 4 {
            self.sr |= SR_SIZERR | SR_PGSERR;
            return Ok(());
        }
        if self.sr & SR_ERRORS != 0 {
            self.sr |= SR_PGSERR;
            return Ok(());
        }
        match self.first.take() {
            None => {
                if !off.is_multiple_of(8) {
                    self.sr |= SR_PGAERR;
                    return Ok(());
                }
                self.first = Some((off, v));
            }
            Some((first, w0)) => {
                if off != first + 4 {
                    self.sr |= SR_PGAERR;
                    return Ok(());
                }
                let mut data = [0u8; 8];
                data[..4].copy_from_slice(&w0.to_le_bytes());
                data[4..].copy_from_slice(&v.to_le_bytes());
                let erased = self.store.bytes[first..first + 8]
                    .iter()
                    .all(|&b| b == 0xFF)
                    && !self.store.torn[first / 8];
                if !erased && data != [0; 8] {
                    self.sr |= SR_PROGERR;
                    return Ok(());
                }
                self.start(Op::Program { off: first, data }, now, T_PROG_S);
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn unlocked() -> Flash {
        let mut f = Flash::new(Store::default());
        f.write(0x08, KEY1, 0).unwrap();
        f.write(0x08, KEY2, 0).unwrap();
        f.write(0x14, CR_PG, 0).unwrap();
        f
    }

    #[test]
    fn double_word_programming_and_its_errors() {
        let mut f = unlocked();
        f.write_store(8, 4, 0x1122_3344, 0).unwrap();
        f.write_store(12, 4, 0x5566_7788, 0).unwrap();
        assert!(f.busy_until().is_some());
        f.settle(1_000_000_000);
        assert_eq!(f.read_store(8, 4, 1_000_000_000), 0x1122_3344);
        assert_eq!(f.read(0x10, 1_000_000_000).unwrap() & SR_EOP, SR_EOP);
        // Programming it again: PROGERR.
        f.write_store(8, 4, 1, 1_000_000_000).unwrap();
        f.write_store(12, 4, 1, 1_000_000_000).unwrap();
        assert_ne!(f.read(0x10, 1_000_000_000).unwrap() & SR_PROGERR, 0);
        // Misaligned first word: PGAERR.
        let mut f = unlocked();
        f.write_store(4, 4, 0, 0).unwrap();
        assert_ne!(f.read(0x10, 0).unwrap() & SR_PGAERR, 0);
        // Half-word: SIZERR.
        let mut f = unlocked();
        f.write_store(0, 2, 0, 0).unwrap();
        assert_ne!(f.read(0x10, 0).unwrap() & SR_SIZERR, 0);
    }

    #[test]
    fn a_cut_program_reads_back_with_an_ecc_error() {
        let mut f = unlocked();
        f.write_store(16, 4, 0, 0).unwrap();
        f.write_store(20, 4, 0, 0).unwrap();
        f.power_cut(1000);
        assert!(f.store.torn[2]);
        let mut f = Flash::new(f.store.clone());
        f.read_store(16, 4, 0);
        assert!(f.nmi);
        assert_eq!(f.read(0x18, 0).unwrap(), 1 << 31 | (STORE_OFFSET + 16));
    }
}
