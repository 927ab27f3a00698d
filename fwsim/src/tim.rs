//! STM32G4 timers TIM1 (advanced), TIM2 (32-bit), TIM3 and TIM4 (16-bit general purpose).
//!
//! Register map and bit fields: RM0440 ch. 28 "Advanced-control timers (TIM1/TIM8/TIM20)" and
//! ch. 29 "General-purpose timers (TIM2/TIM3/TIM4/TIM5)", and stm32-metapac 21's
//! `timer_v2` tables (the ones embassy-stm32 uses for the G4). Behaviours modelled:
//! - the time-base unit (RM0440 "Time-base unit"): CNT counts up at f_CK_PSC / (PSC + 1),
//!   PSC always preloaded, ARR preloaded when CR1.ARPE, the update event at the overflow
//!   reloading the shadow registers and setting SR.UIF; EGR.UG re-initialises the counter and
//!   sets UIF unless CR1.URS ("Update generation");
//! - output compare / PWM (RM0440 "Output compare mode", "PWM mode"): SR.CCxIF at CNT = CCRx,
//!   CCRx preloaded when CCMRx.OCxPE, OCxREF for PWM modes 1/2 and forced levels, the output
//!   OCx = OCxREF ^ CCER.CCxP when CCER.CCxE (and BDTR.MOE on TIM1);
//! - encoder interface mode (SMCR.SMS = 0001..0011, RM0440 "Encoder interface mode"): the
//!   counter follows the encoder's edges (from the plant), 2 or 4 counts per line;
//! - input capture on TRC (CCMR.CCxS = 11, "Input capture mode"): CCRx latches CNT at the
//!   trigger, CCxIF (CCxOF when already set);
//! - the interrupt lines: SR & DIER.
//!
//! Anything else (other slave modes, centre-aligned/down counting, DMA requests, one-pulse,
//! the break input, CCR5/CCR6) stops the run.

/// A register access the model does not implement.
pub type Unimplemented = String;

/// Which timer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    /// TIM1: advanced, 16-bit, RCR and BDTR.
    Advanced,
    /// TIM2: 32-bit counter.
    General32,
    /// TIM3, TIM4: 16-bit.
    General16,
}

/// One timer's state.
#[derive(Clone, Debug)]
pub struct Timer {
    /// "TIM1" ...
    pub name: &'static str,
    kind: Kind,
    cr1: u32,
    cr2: u32,
    smcr: u32,
    dier: u32,
    sr: u32,
    ccmr: [u32; 2],
    ccer: u32,
    psc: u32,
    arr: u32,
    rcr: u32,
    ccr: [u32; 4],
    bdtr: u32,
    /// Shadow (active) prescaler, reload and compares.
    psc_active: u32,
    arr_active: u32,
    ccr_active: [u32; 4],
    /// The counter: index `anchor_n` (unwrapped) at time `anchor_t`.
    anchor_t: u64,
    anchor_n: u64,
    /// Events processed up to this time.
    last: u64,
    /// Ticks per timer kernel clock (set from the RCC model).
    pub clk_ticks: u64,
    /// The counter in encoder mode.
    enc_cnt: u32,
}

/// Register names (offsets from the timer's base).
pub fn name(off: u32) -> Option<&'static str> {
    Some(match off {
        0x00 => "CR1",
        0x04 => "CR2",
        0x08 => "SMCR",
        0x0C => "DIER",
        0x10 => "SR",
        0x14 => "EGR",
        0x18 => "CCMR1",
        0x1C => "CCMR2",
        0x20 => "CCER",
        0x24 => "CNT",
        0x28 => "PSC",
        0x2C => "ARR",
        0x30 => "RCR",
        0x34 => "CCR1",
        0x38 => "CCR2",
        0x3C => "CCR3",
        0x40 => "CCR4",
        0x44 => "BDTR",
        0x48 => "CCR5",
        0x4C => "CCR6",
        0x50 => "CCMR3",
        0x54 => "DTR2",
        0x58 => "ECR",
        0x5C => "TISEL",
        0x60 => "AF1",
        0x64 => "AF2",
        0x3DC => "DCR",
        0x3E0 => "DMAR",
        _ => return None,
    })
}

const CEN: u32 = 1;
const URS: u32 = 1 << 2;
const ARPE: u32 = 1 << 7;
const UIF: u32 = 1;

impl Timer {
    /// A timer at its reset values (RM0440: every register 0, ARR all ones).
    pub fn new(name: &'static str, kind: Kind) -> Self {
        let arr = if kind == Kind::General32 {
            u32::MAX
        } else {
            0xFFFF
        };
        Self {
            name,
            kind,
            cr1: 0,
            cr2: 0,
            smcr: 0,
            dier: 0,
            sr: 0,
            ccmr: [0; 2],
            ccer: 0,
            psc: 0,
            arr,
            rcr: 0,
            ccr: [0; 4],
            bdtr: 0,
            psc_active: 0,
            arr_active: arr,
            ccr_active: [0; 4],
            anchor_t: 0,
            anchor_n: 0,
            last: 0,
            clk_ticks: 8,
            enc_cnt: 0,
        }
    }

    /// Back to the reset values (RCC's reset bit), keeping the clock.
    pub fn reset(&mut self) {
        let clk = self.clk_ticks;
        *self = Self::new(self.name, self.kind);
        self.clk_ticks = clk;
    }

    fn cnt_mask(&self) -> u32 {
        if self.kind == Kind::General32 {
            u32::MAX
        } else {
            0xFFFF
        }
    }

    /// Slave mode (SMCR.SMS[3:0], bit 16 is SMS[3]).
    fn sms(&self) -> u32 {
        self.smcr & 7 | (self.smcr >> 13 & 8)
    }

    /// Encoder interface mode: 2 or 4 counts per encoder line.
    fn encoder_factor(&self) -> Option<u32> {
        match self.sms() {
            1 | 2 => Some(2),
            3 => Some(4),
            _ => None,
        }
    }

    /// True when the counter runs on the internal clock.
    fn running(&self) -> bool {
        self.cr1 & CEN != 0 && self.sms() == 0
    }

    fn tpc(&self) -> u64 {
        self.clk_ticks * (u64::from(self.psc_active) + 1)
    }

    fn period(&self) -> u64 {
        u64::from(self.arr_active) + 1
    }

    /// Unwrapped count index at time `t`.
    fn index(&self, t: u64) -> u64 {
        self.anchor_n + t.saturating_sub(self.anchor_t) / self.tpc()
    }

    /// CNT at time `t`.
    pub fn cnt(&self, t: u64) -> u32 {
        if let Some(_f) = self.encoder_factor() {
            return self.enc_cnt;
        }
        if !self.running() {
            return self.anchor_n as u32;
        }
        (self.index(t) % self.period()) as u32
    }

    /// Re-anchors the counter at `now` to count `c`, keeping the prescaler's phase.
    fn reanchor(&mut self, now: u64, c: u32) {
        if self.running() {
            let tpc = self.tpc();
            self.anchor_t = now - (now.saturating_sub(self.anchor_t)) % tpc;
        } else {
            self.anchor_t = now;
        }
        self.anchor_n = u64::from(c);
    }

    /// Output channels (CCxS = 00).
    fn is_output(&self, ch: usize) -> bool {
        self.ccmr[ch / 2] >> (8 * (ch % 2)) & 3 == 0
    }

    fn ocm(&self, ch: usize) -> u32 {
        let r = self.ccmr[ch / 2] >> (8 * (ch % 2));
        (r >> 4 & 7) | (r >> 13 & 8)
    }

    fn ocpe(&self, ch: usize) -> bool {
        self.ccmr[ch / 2] >> (8 * (ch % 2) + 3) & 1 != 0
    }

    /// Processes the time-base events in (last, now]: compare flags, update events (UIF, the
    /// shadow registers' reload).
    pub fn advance(&mut self, now: u64) {
        while self.running() && now > self.last {
            let m = self.period();
            let n_last = self.index(self.last);
            let n_now = self.index(now);
            let n_upd = (n_last / m + 1) * m;
            let seg_end = n_now.min(n_upd);
            for ch in 0..4 {
                let v = u64::from(self.ccr_active[ch]);
                if self.is_output(ch) && v < m && hits(n_last, seg_end, v, m) {
                    self.sr |= 1 << (ch + 1);
                }
            }
            if n_now >= n_upd {
                let t_upd = self.anchor_t + (n_upd - self.anchor_n) * self.tpc();
                self.update_event();
                self.sr |= UIF;
                self.anchor_t = t_upd;
                self.anchor_n = 0;
                self.last = t_upd;
            } else {
                self.last = now;
            }
        }
        self.last = self.last.max(now);
    }

    /// The shadow registers take their preloaded values (an update event).
    fn update_event(&mut self) {
        self.psc_active = self.psc;
        self.arr_active = self.arr;
        for ch in 0..4 {
            self.ccr_active[ch] = self.ccr[ch];
        }
    }

    /// The time of the next event that raises an enabled interrupt, after `now`.
    pub fn next_event(&self, now: u64) -> Option<u64> {
        if !self.running() {
            return None;
        }
        let m = self.period();
        let n = self.index(now);
        let at = |k: u64| self.anchor_t + (k - self.anchor_n) * self.tpc();
        let mut best: Option<u64> = None;
        let mut consider = |k: u64| {
            let t = at(k);
            best = Some(best.map_or(t, |b| b.min(t)));
        };
        // Any update reloads shadows (compare values move): the next one bounds the horizon
        // whatever DIER says, so the compare search below is exact up to it.
        consider((n / m + 1) * m);
        for ch in 0..4 {
            let v = u64::from(self.ccr_active[ch]);
            if self.dier >> (ch + 1) & 1 != 0 && self.is_output(ch) && v < m {
                let base = n - n % m + v;
                consider(if base > n { base } else { base + m });
            }
        }
        best
    }

    /// The latest time at or before `to` at which channel `ch`'s compare matched: the trigger
    /// time of TIM1_CC4 for the injected ADC sequence.
    pub fn last_match(&self, ch: usize, to: u64) -> Option<u64> {
        if !self.running() || !self.is_output(ch) {
            return None;
        }
        let m = self.period();
        let v = u64::from(self.ccr_active[ch]);
        if v >= m {
            return None;
        }
        // Matches fall at index j·m + v of the count that started at t0 (signed: `to` may lie
        // before the last re-anchoring; the period is taken as unchanged before it).
        let tpc = i128::from(self.tpc());
        let t0 = i128::from(self.anchor_t) - i128::from(self.anchor_n) * tpc;
        let (m, v) = (i128::from(m), i128::from(v));
        let counts = (i128::from(to) - t0).div_euclid(tpc);
        let j = (counts - v).div_euclid(m);
        let t = t0 + (j * m + v) * tpc;
        u64::try_from(t).ok()
    }

    /// The interrupt lines' state: (update, capture/compare, trigger/commutation, break) for
    /// TIM1's four vectors; a general-purpose timer ORs them into one.
    pub fn lines(&self) -> [bool; 4] {
        let f = self.sr & self.dier;
        [f & 1 != 0, f & 0x1E != 0, f & 0x60 != 0, f & 0x180 != 0]
    }

    /// Reads register `off` at time `now`.
    pub fn read(&mut self, off: u32, now: u64) -> Result<u32, Unimplemented> {
        self.advance(now);
        Ok(match off {
            0x00 => self.cr1,
            0x04 => self.cr2,
            0x08 => self.smcr,
            0x0C => self.dier,
            0x10 => self.sr,
            0x18 => self.ccmr[0],
            0x1C => self.ccmr[1],
            0x20 => self.ccer,
            0x24 => self.cnt(now),
            0x28 => self.psc,
            0x2C => self.arr,
            0x30 if self.kind == Kind::Advanced => self.rcr,
            0x34..=0x40 => self.ccr[((off - 0x34) / 4) as usize],
            0x44 if self.kind == Kind::Advanced => self.bdtr,
            _ => return Err(self.unimpl("read of", off)),
        })
    }

    fn unimpl(&self, what: &str, off: u32) -> String {
        format!(
            "{what} {}.{}",
            self.name,
            name(off).map_or_else(|| format!("+{off:#x}"), str::to_string)
        )
    }

    /// Writes register `off` at time `now`.
    pub fn write(&mut self, off: u32, v: u32, now: u64) -> Result<(), Unimplemented> {
        self.advance(now);
        match off {
            0x00 => {
                // OPM, DIR, CMS, UIFREMAP, DITHEN: not modelled.
                if v & (0x78 | 1 << 11 | 1 << 12) != 0 {
                    return Err(format!(
                        "{}.CR1 = {v:#x}: one-pulse, down or centre-aligned counting, UIF remap or dithering",
                        self.name
                    ));
                }
                let c = self.cnt(now);
                let was = self.running();
                self.cr1 = v & 0x3FF;
                if self.running() != was {
                    self.anchor_t = now;
                    self.anchor_n = u64::from(c);
                    self.last = now;
                }
                if v & ARPE == 0 {
                    self.arr_active = self.arr;
                }
            }
            0x04 => {
                // MMS: 000 reset, 001 enable, 010 update, 1000 encoder clock (RM0440 TIMx_CR2).
                let mms = (v >> 4 & 7) | (v >> 22 & 8);
                if !matches!(mms, 0 | 8) || v & !(0x70 | 1 << 25) != 0 {
                    return Err(format!("{}.CR2 = {v:#x}: master mode {mms} (only reset and encoder clock are modelled)", self.name));
                }
                self.cr2 = v;
            }
            0x08 => {
                let sms = v & 7 | (v >> 13 & 8);
                if !matches!(sms, 0..=3) || v & !(0x0031_0077) != 0 {
                    return Err(format!("{}.SMCR = {v:#x}: slave mode {sms}", self.name));
                }
                let c = self.cnt(now);
                self.smcr = v;
                self.enc_cnt = c;
                self.reanchor(now, c);
            }
            0x0C => {
                // DMA request enables (UDE, CCxDE, TDE, COMDE) are not modelled.
                if v & 0x7F00 != 0 {
                    return Err(format!("{}.DIER = {v:#x}: DMA requests", self.name));
                }
                self.dier = v & 0xFF;
            }
            // rc_w0: writing 0 clears a flag, 1 leaves it.
            0x10 => self.sr &= v,
            0x14 => {
                if v & !0x1F != 0 {
                    return Err(format!(
                        "{}.EGR = {v:#x}: trigger, commutation or break generation",
                        self.name
                    ));
                }
                self.sr |= v & 0x1E;
                if v & 1 != 0 {
                    self.update_event();
                    self.reanchor(now, 0);
                    self.anchor_t = now;
                    self.last = now;
                    self.enc_cnt = 0;
                    if self.cr1 & URS == 0 {
                        self.sr |= UIF;
                    }
                }
            }
            0x18 | 0x1C => {
                let i = ((off - 0x18) / 4) as usize;
                self.ccmr[i] = v;
                for ch in 2 * i..2 * i + 2 {
                    let ccs = self.ccmr[ch / 2] >> (8 * (ch % 2)) & 3;
                    let ocm = self.ocm(ch);
                    // Capture on TRC (3) is modelled; TI1/TI2 (1, 2) only as encoder inputs.
                    if ccs == 0 && !matches!(ocm, 0 | 4 | 5 | 6 | 7) {
                        return Err(format!(
                            "{}.CCMR{} = {v:#x}: output compare mode {ocm} on CH{}",
                            self.name,
                            i + 1,
                            ch + 1
                        ));
                    }
                }
            }
            0x20 => self.ccer = v,
            0x24 => {
                let c = v & self.cnt_mask();
                if self.encoder_factor().is_some() {
                    self.enc_cnt = c;
                } else {
                    if u64::from(c) >= self.period() && self.running() {
                        return Err(format!("{}.CNT = {c} above ARR", self.name));
                    }
                    self.reanchor(now, c);
                }
            }
            0x28 => self.psc = v & 0xFFFF,
            0x2C => {
                self.arr = v & self.cnt_mask();
                if self.cr1 & ARPE == 0 {
                    let c = self.cnt(now);
                    self.arr_active = self.arr;
                    if self.running() && u64::from(c) >= self.period() {
                        return Err(format!(
                            "{}.ARR = {} below the counter",
                            self.name, self.arr
                        ));
                    }
                    self.reanchor(now, c);
                }
            }
            0x30 if self.kind == Kind::Advanced => {
                if v != 0 {
                    return Err(format!("{}.RCR = {v}: repetition counter", self.name));
                }
                self.rcr = v;
            }
            0x34..=0x40 => {
                let ch = ((off - 0x34) / 4) as usize;
                self.ccr[ch] = v & self.cnt_mask();
                if !(self.is_output(ch) && self.ocpe(ch)) {
                    self.ccr_active[ch] = self.ccr[ch];
                }
            }
            0x44 if self.kind == Kind::Advanced => {
                // MOE (15) and the dead-time/lock/off-state fields; the break inputs are not
                // modelled.
                if v & (1 << 12 | 1 << 24) != 0 {
                    return Err(format!("{}.BDTR = {v:#x}: break input enabled", self.name));
                }
                self.bdtr = v;
            }
            _ => return Err(self.unimpl("write of", off)),
        }
        Ok(())
    }

    /// The output of channel `ch` (0-based) over one PWM period: the fraction of the period it
    /// is high (after the polarity; 0 while disabled: docs/fwsim.md, a disabled output is
    /// not driven and the BTS7960's IN pull-down holds it low).
    pub fn output_duty(&mut self, ch: usize, now: u64) -> f64 {
        self.advance(now);
        let enabled = self.ccer >> (4 * ch) & 1 != 0
            && (self.kind != Kind::Advanced || self.bdtr & 1 << 15 != 0);
        if !enabled || !self.is_output(ch) {
            return 0.0;
        }
        let m = self.period() as f64;
        let c = f64::from(self.ccr_active[ch]).min(m);
        let cnt = f64::from(self.cnt(now));
        let high_ref = match self.ocm(ch) {
            // Frozen: OCxREF keeps its reset level (low).
            0 => 0.0,
            4 => 0.0,
            5 => 1.0,
            // PWM mode 1: high while CNT < CCR; mode 2: the complement.
            6 if self.running() => c / m,
            7 if self.running() => 1.0 - c / m,
            6 => f64::from(u8::from(cnt < c)),
            _ => f64::from(u8::from(cnt >= c)),
        };
        let inverted = self.ccer >> (4 * ch + 1) & 1 != 0;
        if inverted {
            1.0 - high_ref
        } else {
            high_ref
        }
    }

    /// Encoder mode: the plant's count moved by `delta` (4 per line, positive when lifting);
    /// returns whether the timer is in encoder mode and counting.
    pub fn encoder_step(&mut self, delta: i64) -> bool {
        let Some(f) = self.encoder_factor() else {
            return false;
        };
        if self.cr1 & CEN == 0 || delta == 0 {
            return false;
        }
        // CC1P/CC2P invert TI1/TI2: one inverted input reverses the count (RM0440 "Encoder
        // interface mode", counting direction table).
        let dir = if (self.ccer >> 1 & 1) ^ (self.ccer >> 5 & 1) != 0 {
            -1
        } else {
            1
        };
        let m = i64::from(self.arr_active) + 1;
        let step = delta * i64::from(f) / 4 * dir;
        self.enc_cnt = (i64::from(self.enc_cnt) + step).rem_euclid(m) as u32;
        true
    }

    /// Master mode "encoder clock output" (CR2.MMS = 1000): one TRGO pulse per count.
    pub fn trgo_is_encoder_clock(&self) -> bool {
        (self.cr2 >> 4 & 7 | self.cr2 >> 22 & 8) == 8
    }

    /// Capture on the trigger input at time `t`: channel 1 with CC1S = TRC and CC1E latches
    /// the counter; returns whether it did. `trigger` is the ITR index driving it.
    pub fn capture_trc(&mut self, t: u64, trigger: u32) -> bool {
        let ts = (self.smcr >> 4 & 7) | (self.smcr >> 17 & 0x18);
        if ts != trigger {
            return false;
        }
        let mut any = false;
        for ch in 0..4 {
            let ccs = self.ccmr[ch / 2] >> (8 * (ch % 2)) & 3;
            if ccs == 3 && self.ccer >> (4 * ch) & 1 != 0 {
                if self.sr >> (ch + 1) & 1 != 0 {
                    self.sr |= 1 << (ch + 9);
                }
                self.sr |= 1 << (ch + 1);
                self.ccr[ch] = self.cnt(t.max(self.anchor_t));
                any = true;
            }
        }
        any
    }
}

/// Whether some k in (from, to] has k ≡ v (mod m).
fn hits(from: u64, to: u64, v: u64, m: u64) -> bool {
    if to <= from {
        return false;
    }
    let first = from + 1;
    let r = (v + m - first % m) % m;
    first + r <= to
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pwm_counts_and_flags_as_the_reference_manual_says() {
        let mut t = Timer::new("TIM1", Kind::Advanced);
        t.clk_ticks = 8;
        t.write(0x2C, 8499, 0).unwrap();
        t.write(0x18, 0x6868, 0).unwrap();
        t.write(0x34, 4250, 0).unwrap();
        t.write(0x44, 1 << 15, 0).unwrap();
        t.write(0x20, 1, 0).unwrap();
        // Preloaded: the compare is not active before an update event.
        assert_eq!(t.output_duty(0, 0), 0.0);
        t.write(0x14, 1, 0).unwrap();
        t.write(0x00, CEN | ARPE, 0).unwrap();
        assert_eq!(t.output_duty(0, 10), 0.5);
        // One period = 8 500 × 8 ticks: UIF after it, CC1IF at half of it.
        t.write(0x10, 0, 0).unwrap();
        t.advance(8 * 4250 - 1);
        assert_eq!(t.read(0x10, 8 * 4250 - 1).unwrap() & 2, 0);
        assert_eq!(t.read(0x10, 8 * 4250).unwrap() & 3, 2);
        assert_eq!(t.read(0x10, 8 * 8500).unwrap() & 3, 3);
        assert_eq!(t.read(0x24, 8 * 8501).unwrap(), 1);
    }

    #[test]
    fn the_last_compare_match_is_found_across_an_update() {
        let mut t = Timer::new("TIM1", Kind::Advanced);
        t.write(0x2C, 99, 0).unwrap();
        t.write(0x1C, 0x7000, 0).unwrap();
        t.write(0x40, 50, 0).unwrap();
        t.write(0x00, CEN, 0).unwrap();
        // 100 counts of 8 ticks per period; CC4 at count 50.
        t.advance(800 + 10);
        assert_eq!(t.last_match(3, 800 + 10), Some(400));
        assert_eq!(t.last_match(3, 800 + 400), Some(1200));
        assert_eq!(t.last_match(3, 399), None);
    }

    #[test]
    fn hits_finds_congruent_indices() {
        assert!(hits(0, 10, 5, 100));
        assert!(!hits(5, 10, 5, 100));
        assert!(hits(5, 105, 5, 100));
        assert!(!hits(10, 10, 10, 100));
    }
}
