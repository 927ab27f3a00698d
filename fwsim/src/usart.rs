//! USART2 (0x4000_4400), asynchronous mode without FIFO.
//!
//! Sources: RM0440 ch. 37 "Universal synchronous/asynchronous receiver transmitter (USART/UART)"
//! and stm32-metapac 21's `usart_v4`: CR1 (UE, RE, TE, the interrupt enables RXNEIE, TCIE,
//! TXEIE, IDLEIE, PEIE), CR2/CR3 (stop bits; EIE, OVRDIS), BRR (baud = f_CK / BRR with
//! OVER8 = 0, PRESC), ISR (TXE: TDR empty; TC: the last frame left the shift register; RXNE;
//! ORE: a frame arrived while RXNE was set, the new byte is lost; IDLE: one idle frame after a
//! reception), ICR (write 1 to clear), RDR (reading clears RXNE), TDR; with CR1.FIFOEN the
//! 8-deep transmit and receive FIFOs ("USART FIFOs and thresholds": TXFNF in place of TXE,
//! RXFNE in place of RXNE, TXFE, RXFF; ORE when a frame arrives with the RX FIFO full; the
//! threshold interrupts are not modelled). A frame is 10 bit times (8N1). The baud rate must be within 2 % of 115 200 (the host's), else the run stops:
//! the host would read garbage.

/// A register access the model does not implement.
pub type Unimplemented = String;

const UE: u32 = 1;
const RE: u32 = 1 << 2;
const TE: u32 = 1 << 3;
const IDLEIE: u32 = 1 << 4;
const RXNEIE: u32 = 1 << 5;
const TCIE: u32 = 1 << 6;
const TXEIE: u32 = 1 << 7;
const PEIE: u32 = 1 << 8;
const FIFOEN: u32 = 1 << 29;
const ORE: u32 = 1 << 3;
const IDLE: u32 = 1 << 4;
const RXNE: u32 = 1 << 5;
const TC: u32 = 1 << 6;
const TXE: u32 = 1 << 7;

/// The console's baud rate.
pub const BAUD: u64 = 115_200;

/// USART2's state.
#[derive(Clone, Debug, Default)]
pub struct Usart {
    cr1: u32,
    cr2: u32,
    cr3: u32,
    brr: u32,
    presc: u32,
    gtpr: u32,
    rtor: u32,
    /// Flags other than TXE/TC (computed).
    isr: u32,
    /// Received bytes waiting (RDR, or the RX FIFO).
    rdr: std::collections::VecDeque<u8>,
    /// Bytes waiting to be shifted out (TDR, or the TX FIFO).
    tdr: std::collections::VecDeque<u8>,
    /// The shift register: byte and the time its frame ends.
    shift: Option<(u8, u64)>,
    /// Bytes from the host not yet arrived: each arrives a frame after the previous.
    pub rx_queue: std::collections::VecDeque<u8>,
    /// Time the next byte from the host completes its frame.
    rx_next: Option<u64>,
    /// Time the line went idle after the last received byte.
    idle_at: Option<u64>,
    /// Bytes sent to the host.
    pub tx_out: Vec<u8>,
    /// Ticks per frame (10 bits).
    frame: u64,
    /// Bytes lost to overrun.
    pub overruns: u64,
}

/// Register names.
pub fn name(off: u32) -> Option<&'static str> {
    Some(match off {
        0x00 => "CR1",
        0x04 => "CR2",
        0x08 => "CR3",
        0x0C => "BRR",
        0x10 => "GTPR",
        0x14 => "RTOR",
        0x18 => "RQR",
        0x1C => "ISR",
        0x20 => "ICR",
        0x24 => "RDR",
        0x28 => "TDR",
        0x2C => "PRESC",
        _ => return None,
    })
}

impl Usart {
    /// Resets the registers, keeping the host's queue.
    pub fn reset(&mut self) {
        let q = std::mem::take(&mut self.rx_queue);
        *self = Self::default();
        self.rx_queue = q;
    }

    fn enabled(&self) -> bool {
        self.cr1 & UE != 0
    }

    /// Depth of TDR/RDR: the FIFOs' 8 with FIFOEN, else 1.
    fn depth(&self) -> usize {
        if self.cr1 & FIFOEN != 0 {
            8
        } else {
            1
        }
    }

    /// Brings the transmitter and receiver up to `now`.
    pub fn advance(&mut self, now: u64) {
        loop {
            if let Some((b, end)) = self.shift {
                if now >= end {
                    self.tx_out.push(b);
                    self.shift = self.tdr.pop_front().map(|n| (n, end + self.frame));
                    continue;
                }
            }
            break;
        }
        // Receiver: bytes arrive back to back while the host has some queued.
        if self.enabled() && self.cr1 & RE != 0 && self.frame > 0 {
            loop {
                if self.rx_queue.is_empty() {
                    self.rx_next = None;
                    break;
                }
                let t = *self.rx_next.get_or_insert(now + self.frame);
                if now < t {
                    break;
                }
                let b = self.rx_queue.pop_front().unwrap_or(0);
                if self.rdr.len() >= self.depth() {
                    self.isr |= ORE;
                    self.overruns += 1;
                } else {
                    self.rdr.push_back(b);
                }
                self.idle_at = Some(t + self.frame);
                self.rx_next = Some(t + self.frame);
            }
            if let Some(t) = self.idle_at {
                if now >= t && self.rx_queue.is_empty() {
                    self.isr |= IDLE;
                    self.idle_at = None;
                }
            }
        }
    }

    fn status(&self) -> u32 {
        let txe = u32::from(self.tdr.len() < self.depth()) * TXE;
        let tc = u32::from(self.tdr.is_empty() && self.shift.is_none()) * TC;
        let rxne = u32::from(!self.rdr.is_empty()) * RXNE;
        let fifo = if self.cr1 & FIFOEN != 0 {
            u32::from(self.tdr.is_empty()) << 23 | u32::from(self.rdr.len() >= 8) << 24
        } else {
            0
        };
        // TEACK/REACK follow TE/RE.
        let ack = (self.cr1 >> 3 & 1) << 21 | (self.cr1 >> 2 & 1) << 22;
        self.isr | txe | tc | rxne | fifo | ack
    }

    /// The interrupt line (IRQ 38).
    pub fn line(&self) -> bool {
        let s = self.status();
        self.enabled()
            && (self.cr1 & RXNEIE != 0 && s & (RXNE | ORE) != 0
                || self.cr1 & TXEIE != 0 && s & TXE != 0
                || self.cr1 & TCIE != 0 && s & TC != 0
                || self.cr1 & IDLEIE != 0 && s & IDLE != 0
                || self.cr1 & PEIE != 0 && s & 1 != 0
                || self.cr3 & 1 != 0 && s & (ORE | 6) != 0)
    }

    /// The next time something the interrupt enables see changes.
    pub fn next_event(&self) -> Option<u64> {
        [self.shift.map(|s| s.1), self.rx_next, self.idle_at]
            .into_iter()
            .flatten()
            .min()
    }

    /// Reads register `off`.
    pub fn read(&mut self, off: u32, now: u64) -> Result<u32, Unimplemented> {
        self.advance(now);
        Ok(match off {
            0x00 => self.cr1,
            0x04 => self.cr2,
            0x08 => self.cr3,
            0x0C => self.brr,
            0x10 => self.gtpr,
            0x14 => self.rtor,
            0x1C => self.status(),
            0x24 => u32::from(self.rdr.pop_front().unwrap_or(0)),
            0x2C => self.presc,
            _ => return Err(format!("read of USART2.{}", name(off).unwrap_or("?"))),
        })
    }

    /// Writes register `off`; `ker_hz` is the kernel clock (for the baud-rate check).
    pub fn write(&mut self, off: u32, v: u32, now: u64, ker_hz: u64) -> Result<(), Unimplemented> {
        self.advance(now);
        match off {
            0x00 => {
                if v & (1 << 28 | 1 << 12 | 1 << 10 | 1 << 15 | 1 << 30 | 1 << 31) != 0 {
                    return Err(format!("USART2.CR1 = {v:#x}: 7/9-bit words, parity, oversampling by 8 or FIFO threshold interrupts"));
                }
                if v & UE != 0 {
                    let div = [1, 2, 4, 6, 8, 10, 12, 16, 32, 64, 128, 256]
                        [(self.presc as usize).min(11)];
                    if self.brr == 0 {
                        return Err("USART2 enabled with BRR = 0".into());
                    }
                    let baud = ker_hz / div / u64::from(self.brr);
                    if baud.abs_diff(BAUD) * 50 > BAUD {
                        return Err(format!(
                            "USART2 at {baud} Bd: the console's host expects {BAUD}"
                        ));
                    }
                    self.frame = 10 * crate::TICK_HZ / baud;
                }
                self.cr1 = v;
            }
            0x04 => {
                if v >> 12 & 3 != 0 {
                    return Err(format!("USART2.CR2 = {v:#x}: stop bits other than 1"));
                }
                self.cr2 = v;
            }
            0x08 => {
                // DMAR/DMAT, RXFTIE (28), TXFTIE (23).
                if v & (0xC0 | 1 << 28 | 1 << 23) != 0 {
                    return Err(format!(
                        "USART2.CR3 = {v:#x}: DMA or FIFO threshold interrupts not modelled"
                    ));
                }
                self.cr3 = v;
            }
            0x0C => self.brr = v & 0xFFFF,
            0x10 => self.gtpr = v,
            0x14 => self.rtor = v,
            0x18 => {
                if v & 1 << 3 != 0 {
                    // RXFRQ: drop the received data.
                    self.rdr.clear();
                }
            }
            0x20 => self.isr &= !(v & 0x0012_1B5F),
            0x28 => {
                if !self.enabled() || self.cr1 & TE == 0 {
                    return Err("USART2.TDR written with the transmitter off".into());
                }
                let b = v as u8;
                if self.shift.is_none() {
                    self.shift = Some((b, now + self.frame));
                } else if self.tdr.len() < self.depth() {
                    self.tdr.push_back(b);
                } else {
                    return Err("USART2.TDR written while TXE/TXFNF = 0 (byte lost)".into());
                }
            }
            0x2C => self.presc = v & 0xF,
            _ => return Err(format!("write of USART2.{}", name(off).unwrap_or("?"))),
        }
        Ok(())
    }
}
