//! A simulated NOR flash with power-cut injection, for host tests and the fuzz target.
//!
//! It behaves like the STM32G4's internal flash where the store lives: 8-byte program unit
//! (a double word, written once after an erase: the G4 refuses a second write of anything but
//! all zeros), 2 KiB erase pages, byte reads. Every double word programmed and every page erased is one *step*.
//! With [`SimFlash::cut_after`] the power fails at a chosen step: that operation is left
//! [`CutMode::Clean`] (not started) or [`CutMode::Torn`] (a pseudo-random subset of its bits
//! changed, as an interrupted program or erase leaves NOR cells), the call returns
//! [`SimFlashError::PowerCut`], and every later call fails the same way until
//! [`SimFlash::reboot`]. (`sequential-storage` ships a mock flash too, but only behind its
//! private `_test` feature, which pulls in `std`; this one is `no_std` and ~150 lines.)
//!
//! Not modelled: the G4 raises an ECC fault (NMI) when firmware reads a torn double word; the
//! simulation returns the torn bits instead. docs/config-store.md discusses it.

use embedded_storage::nor_flash::{
    ErrorType, NorFlash, NorFlashError, NorFlashErrorKind, ReadNorFlash,
};
use embedded_storage_async::nor_flash as asynch;

/// Program unit, bytes.
pub const WRITE_SIZE: usize = 8;
/// Erase unit, bytes (one STM32G431 page).
pub const ERASE_SIZE: usize = 2048;

/// What an interrupted operation leaves behind.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CutMode {
    /// The interrupted double word or page is untouched.
    Clean,
    /// The interrupted double word has some of its bits programmed; the interrupted page has
    /// some of its bits erased (pseudo-random, from the seed).
    Torn {
        /// Seed of the bit pattern.
        seed: u32,
    },
}

/// Why a simulated operation failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SimFlashError {
    /// The power failed (at or before this operation).
    PowerCut,
    /// Offset or length not a multiple of the unit.
    NotAligned,
    /// Outside the flash.
    OutOfBounds,
    /// Programming a double word that is not erased with anything but zeros (the G4 refuses it).
    NotErased,
}

impl NorFlashError for SimFlashError {
    fn kind(&self) -> NorFlashErrorKind {
        match self {
            SimFlashError::NotAligned => NorFlashErrorKind::NotAligned,
            SimFlashError::OutOfBounds => NorFlashErrorKind::OutOfBounds,
            SimFlashError::PowerCut | SimFlashError::NotErased => NorFlashErrorKind::Other,
        }
    }
}

/// `SIZE` bytes of simulated flash (a multiple of [`ERASE_SIZE`]), erased at creation.
#[derive(Clone, Debug)]
pub struct SimFlash<const SIZE: usize> {
    data: [u8; SIZE],
    steps: u32,
    cut_at: Option<u32>,
    mode: CutMode,
    dead: bool,
    rng: u32,
}

impl<const SIZE: usize> Default for SimFlash<SIZE> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const SIZE: usize> SimFlash<SIZE> {
    /// Erased flash, power on, no cut planned.
    pub const fn new() -> Self {
        SimFlash {
            data: [0xFF; SIZE],
            steps: 0,
            cut_at: None,
            mode: CutMode::Clean,
            dead: false,
            rng: 1,
        }
    }

    /// Fail the power at the `step`-th step from now (0: the very next one).
    pub fn cut_after(&mut self, step: u32, mode: CutMode) {
        self.cut_at = Some(self.steps.saturating_add(step));
        self.mode = mode;
        if let CutMode::Torn { seed } = mode {
            self.rng = seed | 1;
        }
    }

    /// Power back on: the contents stay as the cut left them, no cut planned.
    pub fn reboot(&mut self) {
        self.dead = false;
        self.cut_at = None;
    }

    /// Steps (double words programmed, pages erased) so far.
    pub fn steps(&self) -> u32 {
        self.steps
    }

    /// Whether the power failed and the flash has not been rebooted.
    pub fn is_dead(&self) -> bool {
        self.dead
    }

    /// The raw contents.
    pub fn bytes(&self) -> &[u8] {
        &self.data
    }

    /// The raw contents, to corrupt them.
    pub fn bytes_mut(&mut self) -> &mut [u8] {
        &mut self.data
    }

    fn next_mask(&mut self) -> u8 {
        // xorshift32: deterministic, seedable, good enough to pick bits.
        let mut x = self.rng;
        x ^= x << 13;
        x ^= x >> 17;
        x ^= x << 5;
        self.rng = x;
        x as u8
    }

    /// Count one step; true if the power fails on it.
    fn step(&mut self) -> bool {
        if self.cut_at == Some(self.steps) {
            self.dead = true;
            return true;
        }
        self.steps = self.steps.wrapping_add(1);
        false
    }

    fn range(&self, offset: u32, len: usize) -> Result<core::ops::Range<usize>, SimFlashError> {
        let start = offset as usize;
        let end = start.checked_add(len).ok_or(SimFlashError::OutOfBounds)?;
        if end > SIZE {
            return Err(SimFlashError::OutOfBounds);
        }
        Ok(start..end)
    }
}

impl<const SIZE: usize> ErrorType for SimFlash<SIZE> {
    type Error = SimFlashError;
}

impl<const SIZE: usize> ReadNorFlash for SimFlash<SIZE> {
    const READ_SIZE: usize = 1;

    fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), Self::Error> {
        if self.dead {
            return Err(SimFlashError::PowerCut);
        }
        let r = self.range(offset, bytes.len())?;
        bytes.copy_from_slice(&self.data[r]);
        Ok(())
    }

    fn capacity(&self) -> usize {
        SIZE
    }
}

impl<const SIZE: usize> NorFlash for SimFlash<SIZE> {
    const WRITE_SIZE: usize = WRITE_SIZE;
    const ERASE_SIZE: usize = ERASE_SIZE;

    fn erase(&mut self, from: u32, to: u32) -> Result<(), Self::Error> {
        if self.dead {
            return Err(SimFlashError::PowerCut);
        }
        if !from.is_multiple_of(ERASE_SIZE as u32)
            || !to.is_multiple_of(ERASE_SIZE as u32)
            || from > to
        {
            return Err(SimFlashError::NotAligned);
        }
        let r = self.range(from, (to - from) as usize)?;
        for page in r.step_by(ERASE_SIZE) {
            if self.step() {
                if let CutMode::Torn { .. } = self.mode {
                    for i in page..page + ERASE_SIZE {
                        let m = self.next_mask();
                        self.data[i] |= m;
                    }
                }
                return Err(SimFlashError::PowerCut);
            }
            self.data[page..page + ERASE_SIZE].fill(0xFF);
        }
        Ok(())
    }

    fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), Self::Error> {
        if self.dead {
            return Err(SimFlashError::PowerCut);
        }
        if !(offset as usize).is_multiple_of(WRITE_SIZE) || !bytes.len().is_multiple_of(WRITE_SIZE)
        {
            return Err(SimFlashError::NotAligned);
        }
        let r = self.range(offset, bytes.len())?;
        for (k, word) in bytes.chunks_exact(WRITE_SIZE).enumerate() {
            let at = r.start + k * WRITE_SIZE;
            // RM0440 (FLASH_SR.PROGERR): a double word must be erased before it is programmed,
            // except that all zeros may be written over anything. sequential-storage's page
            // markers are all zeros, which is how it redoes a marker a power cut tore.
            let erased = self.data[at..at + WRITE_SIZE].iter().all(|&b| b == 0xFF);
            if !erased && word.iter().any(|&b| b != 0) {
                return Err(SimFlashError::NotErased);
            }
            if self.step() {
                if let CutMode::Torn { .. } = self.mode {
                    for (i, &b) in word.iter().enumerate() {
                        // Programming clears bits; an interrupted one cleared only some.
                        let m = self.next_mask();
                        self.data[at + i] &= b | m;
                    }
                }
                return Err(SimFlashError::PowerCut);
            }
            self.data[at..at + WRITE_SIZE].copy_from_slice(word);
        }
        Ok(())
    }
}

/// The async traits too, for tests that drive a `sequential-storage` map over the simulation
/// directly (the store itself takes the blocking traits, as the board's flash offers them).
impl<const SIZE: usize> asynch::ReadNorFlash for SimFlash<SIZE> {
    const READ_SIZE: usize = 1;

    async fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), Self::Error> {
        ReadNorFlash::read(self, offset, bytes)
    }

    fn capacity(&self) -> usize {
        SIZE
    }
}

impl<const SIZE: usize> asynch::NorFlash for SimFlash<SIZE> {
    const WRITE_SIZE: usize = WRITE_SIZE;
    const ERASE_SIZE: usize = ERASE_SIZE;

    async fn erase(&mut self, from: u32, to: u32) -> Result<(), Self::Error> {
        NorFlash::erase(self, from, to)
    }

    async fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), Self::Error> {
        NorFlash::write(self, offset, bytes)
    }
}
