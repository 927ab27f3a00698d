//! The board over time: the MCU across its resets (watchdog, software) and power cycles, the
//! console's bytes, the defmt log read from the RTT buffer in emulated RAM (as a probe does:
//! the up channel's write offset, the bytes up to it, the read offset written back), decoded
//! with `defmt-decoder` against the ELF's `.defmt` table.

use crate::bus::{Analog, BoardOut};
use crate::elf::Image;
use crate::flash::Store;
use crate::mcu::{Mcu, Stop};
use crate::sys::ResetCause;
use crate::TICK_HZ;
use std::io::Write;

/// One reset seen during a run.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ResetEvent {
    /// Global time, s.
    pub t: f64,
    /// Why.
    pub cause: ResetCause,
}

/// A decoded defmt line.
#[derive(Clone, Debug, PartialEq)]
pub struct LogLine {
    /// Global time the harness read it, s.
    pub t: f64,
    /// The formatted line (timestamp, level, message).
    pub text: String,
}

/// The defmt decoder over a table that lives as long as the program (the decoder borrows it).
struct Defmt {
    decoder: Box<dyn defmt_decoder::StreamDecoder + 'static>,
}

/// The emulated board.
pub struct Machine {
    image: Image,
    /// The MCU (rebuilt at every reset).
    pub mcu: Mcu,
    /// Global time of the MCU's time 0 (its last reset), ticks.
    epoch: u64,
    /// Resets so far.
    pub resets: Vec<ResetEvent>,
    /// Console bytes the firmware sent, not yet taken.
    pub console_out: Vec<u8>,
    /// RTT bytes read and not yet decoded, with the global time they were read, s.
    rtt_pending: Vec<(f64, Vec<u8>)>,
    defmt: Option<Defmt>,
    /// Raw RTT bytes read.
    pub rtt_raw: usize,
    /// What the firmware did that the chip does not allow (the run went on): see
    /// `Bus::findings`.
    pub findings: Vec<String>,
    /// Where `--trace-mmio` writes (kept across resets).
    trace_path: Option<std::path::PathBuf>,
    /// The switch inputs: GPIOB pins driven low and high.
    gpiob_in: (u16, u16),
}

impl Machine {
    /// Powers the board up with `image` and the store's pages `store`.
    pub fn new(image: Image, store: Store) -> Result<Self, String> {
        let mcu = Mcu::new(&image, store, ResetCause::PowerOn, None)?;
        let defmt = defmt_decoder::Table::parse(&image.bytes)
            .ok()
            .flatten()
            .map(|t| {
                // The decoder borrows its table for as long as it decodes: the table lives for
                // the rest of the program (one per loaded image).
                let table: &'static defmt_decoder::Table = Box::leak(Box::new(t));
                Defmt {
                    decoder: table.new_stream_decoder(),
                }
            });
        Ok(Self {
            image,
            mcu,
            epoch: 0,
            resets: Vec::new(),
            console_out: Vec::new(),
            rtt_pending: Vec::new(),
            defmt,
            rtt_raw: 0,
            findings: Vec::new(),
            trace_path: None,
            gpiob_in: (0, 0),
        })
    }

    /// Writes every register access to `path` from now on.
    pub fn trace_to(&mut self, path: &std::path::Path) -> Result<(), String> {
        let f = std::fs::File::create(path).map_err(|e| format!("{}: {e}", path.display()))?;
        self.mcu.bus().trace = Some(Box::new(std::io::BufWriter::new(f)));
        self.trace_path = Some(path.to_path_buf());
        Ok(())
    }

    /// Global time, ticks.
    pub fn now(&self) -> u64 {
        self.epoch + self.mcu.bus_ref().now()
    }

    /// Global time, s.
    pub fn t(&self) -> f64 {
        self.now() as f64 / TICK_HZ as f64
    }

    /// Runs until global time `t_end` (ticks), through resets.
    pub fn run_until(&mut self, t_end: u64) -> Result<(), String> {
        loop {
            let local_end = t_end.saturating_sub(self.epoch);
            let r = self.mcu.run_until(local_end);
            self.drain();
            match r {
                Ok(()) => return Ok(()),
                Err(Stop::Reset(cause)) => self.reset(cause)?,
                Err(Stop::Error(e)) => return Err(format!("t = {:.6} s: {e}", self.t())),
            }
        }
    }

    /// A reset that keeps the power: RAM and the store's pages stay.
    fn reset(&mut self, cause: ResetCause) -> Result<(), String> {
        let now = self.now();
        self.resets.push(ResetEvent {
            t: now as f64 / TICK_HZ as f64,
            cause,
        });
        let ram = self.mcu.ram();
        let store = self.mcu.bus().power_cut();
        self.restart(store, cause, Some(&ram), now)
    }

    fn restart(
        &mut self,
        store: Store,
        cause: ResetCause,
        ram: Option<&[u8]>,
        now: u64,
    ) -> Result<(), String> {
        let queue = std::mem::take(&mut self.mcu.bus().usart2.rx_queue);
        let analog = self.mcu.bus_ref().analog;
        let trace = self.mcu.bus().trace.take();
        self.mcu = Mcu::new(&self.image, store, cause, ram)?;
        self.epoch = now;
        let bus = self.mcu.bus();
        bus.usart2.rx_queue = queue;
        bus.analog = analog;
        bus.trace = trace;
        let (low, high) = self.gpiob_in;
        bus.set_gpiob_inputs(low, high);
        Ok(())
    }

    /// Cuts the power now and applies it again after `off_s` seconds: a flash operation under
    /// way is torn, RAM is lost. Returns the store as the cut left it.
    pub fn power_cycle(&mut self, off_s: f64) -> Result<Store, String> {
        let store = self.mcu.bus().power_cut();
        let now = self.now() + (off_s * TICK_HZ as f64) as u64;
        self.restart(store.clone(), ResetCause::PowerOn, None, now)?;
        Ok(store)
    }

    /// The store's pages as they are now.
    pub fn store(&self) -> Store {
        self.mcu.bus_ref().flash.store.clone()
    }

    /// Queues bytes from the host on the console's RX line.
    pub fn console_send(&mut self, bytes: &[u8]) {
        self.mcu.bus().usart2.rx_queue.extend(bytes);
    }

    /// The analog inputs.
    pub fn set_analog(&mut self, a: Analog) {
        self.mcu.bus().analog = a;
    }

    /// The switch contacts: GPIOB pins pulled low by a closed contact (`low`), driven high.
    pub fn set_gpiob_inputs(&mut self, low: u16, high: u16) {
        self.gpiob_in = (low, high);
        self.mcu.bus().set_gpiob_inputs(low, high);
    }

    /// The encoder: its count and the global time of its last edge, ticks.
    pub fn encoder(&mut self, count: u16, edge: u64) {
        let local = edge.saturating_sub(self.epoch);
        self.mcu.bus().encoder(count, local);
    }

    /// Bridge inputs and brake output now.
    pub fn board_out(&mut self) -> BoardOut {
        self.mcu.bus().board_out()
    }

    /// Takes the console bytes and the RTT buffer's new bytes.
    fn drain(&mut self) {
        let bus = self.mcu.bus();
        self.console_out.append(&mut bus.usart2.tx_out);
        for f in bus.findings.drain(..) {
            if !self.findings.contains(&f) {
                self.findings.push(f);
            }
        }
        let Some(cb) = self.image.rtt else { return };
        // The up channel 0 descriptor: buffer, size, write offset, read offset (one read: this
        // runs at every coupling period).
        let mut desc = [0u8; 16];
        if self.mcu.uc.mem_read(u64::from(cb + 28), &mut desc).is_err() {
            return;
        }
        let word = |i: usize| u32::from_le_bytes([desc[i], desc[i + 1], desc[i + 2], desc[i + 3]]);
        let (buf, size, write, read) = (word(0), word(4), word(8), word(12));
        if buf == 0 || size == 0 || write == read || write >= size || read >= size {
            return;
        }
        let mut bytes = Vec::new();
        let mut r = read;
        while r != write {
            let end = if write > r { write } else { size };
            let mut chunk = vec![0u8; (end - r) as usize];
            if self
                .mcu
                .uc
                .mem_read(u64::from(buf + r), &mut chunk)
                .is_err()
            {
                return;
            }
            bytes.extend_from_slice(&chunk);
            r = end % size;
        }
        let _ = self
            .mcu
            .uc
            .mem_write(u64::from(cb + 40), &write.to_le_bytes());
        self.rtt_raw += bytes.len();
        // Decoded when someone takes the log (the firmware logs every bridge change: decoding
        // each period would cost a twentieth of the run).
        let t = self.t();
        self.rtt_pending.push((t, bytes));
    }

    /// The defmt lines logged since the last call, decoded as probe-rs shows them.
    pub fn take_log(&mut self) -> Vec<LogLine> {
        let mut lines = Vec::new();
        let Some(d) = self.defmt.as_mut() else {
            self.rtt_pending.clear();
            return lines;
        };
        for (t, bytes) in self.rtt_pending.drain(..) {
            d.decoder.received(&bytes);
            loop {
                match d.decoder.decode() {
                    Ok(frame) => {
                        let ts = frame
                            .display_timestamp()
                            .map(|s| s.to_string())
                            .unwrap_or_default();
                        let level = frame
                            .level()
                            .map(|l| l.as_str().to_uppercase())
                            .unwrap_or_default();
                        lines.push(LogLine {
                            t,
                            text: format!("{ts} {level:<5} {}", frame.display_message()),
                        });
                    }
                    Err(defmt_decoder::DecodeError::UnexpectedEof) => break,
                    Err(defmt_decoder::DecodeError::Malformed) => {
                        lines.push(LogLine {
                            t,
                            text: "(malformed defmt frame)".into(),
                        });
                        break;
                    }
                }
            }
        }
        lines
    }

    /// Drops the log read so far undecoded.
    pub fn discard_log(&mut self) {
        self.rtt_pending.clear();
    }

    /// Takes the console output as text.
    pub fn take_console(&mut self) -> String {
        String::from_utf8_lossy(&std::mem::take(&mut self.console_out)).into_owned()
    }

    /// Runs until the console has printed `needle` (or `timeout_s` passes); returns the text.
    pub fn run_until_console(
        &mut self,
        needle: &str,
        timeout_s: f64,
        seen: &mut String,
    ) -> Result<bool, String> {
        let end = self.now() + (timeout_s * TICK_HZ as f64) as u64;
        let step = TICK_HZ / 1000;
        while self.now() < end {
            let t = (self.now() + step).min(end);
            self.run_until(t)?;
            seen.push_str(&self.take_console());
            if seen.contains(needle) {
                return Ok(true);
            }
        }
        Ok(false)
    }

    /// The CPU stops executing for `secs` (a hung loop), the peripherals run on; resets end
    /// the stall.
    pub fn stall_cpu(&mut self, secs: f64) -> Result<(), String> {
        let end = self.now() + (secs * TICK_HZ as f64) as u64;
        self.mcu.stall_until = end - self.epoch;
        self.run_until(end)
    }

    /// Flushes the MMIO trace.
    pub fn flush_trace(&mut self) {
        if let Some(w) = self.mcu.bus().trace.as_mut() {
            let _ = w.flush();
        }
    }
}
