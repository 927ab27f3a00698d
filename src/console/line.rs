//! The line buffer: UART bytes in, complete lines out.

use super::MAX_LINE;

/// Collects UART bytes into lines. Backspace/DEL remove the last byte, CR, LF or CRLF end a
/// line, a line longer than [`MAX_LINE`] is dropped whole and reported as [`Feed::Overflow`]
/// once its end arrives.
#[derive(Clone, Debug, Default)]
pub struct LineBuffer {
    buf: heapless::Vec<u8, MAX_LINE>,
    overflow: bool,
    last_cr: bool,
    /// A line was handed out: clear before the next byte.
    done: bool,
}

/// What one byte did to the line.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Feed<'a> {
    /// The line goes on.
    Pending,
    /// A complete line (without its end).
    Line(&'a [u8]),
    /// A line that was too long ended.
    Overflow,
}

impl LineBuffer {
    /// An empty buffer.
    pub const fn new() -> Self {
        LineBuffer {
            buf: heapless::Vec::new(),
            overflow: false,
            last_cr: false,
            done: false,
        }
    }

    /// Feed one byte.
    pub fn feed(&mut self, b: u8) -> Feed<'_> {
        if core::mem::replace(&mut self.done, false) {
            self.buf.clear();
        }
        let after_cr = core::mem::replace(&mut self.last_cr, b == b'\r');
        match b {
            b'\n' if after_cr => Feed::Pending,
            b'\r' | b'\n' => {
                self.done = true;
                if core::mem::replace(&mut self.overflow, false) {
                    Feed::Overflow
                } else {
                    Feed::Line(&self.buf)
                }
            }
            0x08 | 0x7F => {
                self.buf.pop();
                Feed::Pending
            }
            _ => {
                if self.buf.push(b).is_err() {
                    self.overflow = true;
                }
                Feed::Pending
            }
        }
    }
}
