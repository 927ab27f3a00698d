//! fwsim: the firmware ELF that `scripts/fw-build` writes, run on an emulated STM32G431
//! (Unicorn's Cortex-M4F plus peripheral models written from the reference manual) in closed
//! loop with host-sim's plant. docs/fwsim.md describes the models, the cycle model and what
//! they check.
//!
//! Licence: GPL-2.0-or-later (Unicorn is GPL-2.0); nothing else in the workspace links it.

#![cfg_attr(test, allow(clippy::unwrap_used, clippy::expect_used))]

pub mod adc;
pub mod bus;
pub mod elf;
pub mod flash;
pub mod gpio;
pub mod lift;
pub mod machine;
pub mod mcu;
pub mod plant;
pub mod scs;
pub mod sys;
pub mod tim;
pub mod usart;

/// The emulated time base: 1.36 GHz, the least common multiple of the clocks the firmware
/// uses (170 MHz SYSCLK = 8 ticks, HSI16 = 85, the ADC's 42.5 MHz = 32, 1 MHz = 1 360), so
/// every clock edge falls on a tick.
pub const TICK_HZ: u64 = 1_360_000_000;
