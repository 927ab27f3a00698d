//! GPIO ports A and B (RM0440 ch. 9 "General-purpose I/Os (GPIO)", stm32-metapac 21 `gpio_v2`):
//! MODER, OTYPER, OSPEEDR, PUPDR, IDR, ODR, BSRR, LCKR, AFRL/AFRH, BRR.
//!
//! Reset values (RM0440 GPIOx_MODER): port A 0xABFF_FFFF (PA13/PA14/PA15 in their debug
//! alternate functions, the rest analog), port B 0xFFFF_FEBF (PB3/PB4 debug), PUPDR port A
//! 0x6400_0000, port B 0x0000_0100. IDR reads what the board drives on each pin (the
//! [`Pins`] the plant fills in); an input pin nothing drives reads its pull-up/pull-down, and a
//! floating one stops the run (on the board it reads noise).

/// A register access the model does not implement.
pub type Unimplemented = String;

/// What the board drives on a port's pins from outside.
#[derive(Clone, Copy, Debug, Default)]
pub struct Pins {
    /// Pins driven by something outside (a switch to GND, a sensor): mask.
    pub driven: u16,
    /// Their levels.
    pub level: u16,
}

/// One port.
#[derive(Clone, Debug)]
pub struct Port {
    /// 'A' or 'B'.
    pub letter: char,
    /// MODER: 00 input, 01 output, 10 alternate function, 11 analog.
    pub moder: u32,
    otyper: u32,
    ospeedr: u32,
    /// PUPDR: 01 pull-up, 10 pull-down.
    pub pupdr: u32,
    /// ODR.
    pub odr: u32,
    /// AFRL, AFRH.
    pub afr: [u32; 2],
    /// External drive.
    pub ext: Pins,
}

/// Register names.
pub fn name(off: u32) -> Option<&'static str> {
    Some(match off {
        0x00 => "MODER",
        0x04 => "OTYPER",
        0x08 => "OSPEEDR",
        0x0C => "PUPDR",
        0x10 => "IDR",
        0x14 => "ODR",
        0x18 => "BSRR",
        0x1C => "LCKR",
        0x20 => "AFRL",
        0x24 => "AFRH",
        0x28 => "BRR",
        _ => return None,
    })
}

impl Port {
    /// Port `letter` at its reset values.
    pub fn new(letter: char) -> Self {
        let (moder, pupdr, ospeedr) = match letter {
            'A' => (0xABFF_FFFF, 0x6400_0000, 0x0C00_0000),
            _ => (0xFFFF_FEBF, 0x0000_0100, 0),
        };
        Self {
            letter,
            moder,
            otyper: 0,
            ospeedr,
            pupdr,
            odr: 0,
            afr: [0; 2],
            ext: Pins::default(),
        }
    }

    /// Pin `n`'s mode.
    pub fn mode(&self, n: u32) -> u32 {
        self.moder >> (2 * n) & 3
    }

    /// Pin `n`'s alternate function number.
    pub fn af(&self, n: u32) -> u32 {
        self.afr[(n / 8) as usize] >> (4 * (n % 8)) & 0xF
    }

    /// The level the MCU drives on pin `n` if it is a push-pull output (None: not an output).
    pub fn output(&self, n: u32) -> Option<bool> {
        (self.mode(n) == 1).then_some(self.odr >> n & 1 != 0)
    }

    /// IDR: output pins read their own level, driven inputs what drives them, the others their
    /// pull; a floating input is an error.
    fn idr(&self) -> Result<u32, Unimplemented> {
        let mut v = 0;
        for n in 0..16 {
            let level = match self.mode(n) {
                // Analog: the Schmitt trigger is off, IDR reads 0 (RM0440 "Analog configuration").
                3 => false,
                1 => self.odr >> n & 1 != 0,
                _ if self.ext.driven >> n & 1 != 0 => self.ext.level >> n & 1 != 0,
                // An alternate-function input (encoder, UART RX) that nothing drives: its pull.
                m => match self.pupdr >> (2 * n) & 3 {
                    1 => true,
                    2 => false,
                    _ if m == 2 => false,
                    _ => {
                        return Err(format!(
                            "P{}{n} read as an input while floating (no pull-up/down, nothing drives it)",
                            self.letter
                        ))
                    }
                },
            };
            v |= u32::from(level) << n;
        }
        Ok(v)
    }

    /// Reads register `off`.
    pub fn read(&mut self, off: u32) -> Result<u32, Unimplemented> {
        Ok(match off {
            0x00 => self.moder,
            0x04 => self.otyper,
            0x08 => self.ospeedr,
            0x0C => self.pupdr,
            0x10 => self.idr()?,
            0x14 => self.odr,
            0x20 => self.afr[0],
            0x24 => self.afr[1],
            _ => {
                return Err(format!(
                    "read of GPIO{}.{}",
                    self.letter,
                    name(off).unwrap_or("?")
                ))
            }
        })
    }

    /// Writes register `off`.
    pub fn write(&mut self, off: u32, v: u32) -> Result<(), Unimplemented> {
        match off {
            0x00 => self.moder = v,
            0x04 => {
                if v & 0xFFFF != 0 {
                    return Err(format!(
                        "GPIO{}.OTYPER = {v:#x}: open-drain outputs",
                        self.letter
                    ));
                }
                self.otyper = v;
            }
            0x08 => self.ospeedr = v,
            0x0C => self.pupdr = v,
            0x14 => self.odr = v & 0xFFFF,
            // BSRR: the set half wins over the reset half (RM0440 GPIOx_BSRR).
            0x18 => self.odr = (self.odr & !(v >> 16)) | (v & 0xFFFF),
            0x20 => self.afr[0] = v,
            0x24 => self.afr[1] = v,
            0x28 => self.odr &= !(v & 0xFFFF),
            _ => {
                return Err(format!(
                    "write of GPIO{}.{}",
                    self.letter,
                    name(off).unwrap_or("?")
                ))
            }
        }
        Ok(())
    }
}
