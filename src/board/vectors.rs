//! The device interrupt vectors, IRQ 0 ..= 38 only (liftfw.x places them after the core's
//! exception vectors and discards the PAC's table of all 102 STM32G431 interrupts).
//!
//! The firmware enables two interrupts: TIM2 (IRQ 28, embassy-time's driver) and USART2
//! (IRQ 38, the console's `BufferedUart`). A table that stops at USART2 saves 63 entries
//! (252 B of flash). The entries are the PAC's, in its order (stm32-metapac 21,
//! `stm32g431cb/pac.rs`), each handler resolved by the linker as before: the function of that
//! name if one is defined (embassy-stm32's TIM2, `bind_interrupts!`'s USART2), otherwise
//! `DefaultHandler` (the PAC's `device.x`). liftfw.x fails the link if any later interrupt has a
//! handler of its own, and the constants below fail the build if the PAC numbers the two
//! differently.
//!
//! A handler is not all: embassy-stm32's `init` enables every DMA channel's interrupt in the
//! NVIC (`dma::init`), DMA2's among them at IRQ 56–60 and 97, past the table. Nothing sets up a
//! DMA channel to raise one, but were one raised, the CPU would fetch its vector from the code
//! after the table; [`disable_past_table`] turns every interrupt past the table off in the NVIC
//! once `init` has run (in the full table they led to `DefaultHandler`).

use embassy_stm32::pac::Interrupt;

/// Entries in the table: up to and including USART2, the highest interrupt the firmware uses.
const LEN: usize = Interrupt::USART2 as usize + 1;
const _: () = assert!(LEN == 39 && (Interrupt::TIM2 as usize) < LEN);

/// A vector-table entry: a handler, or a reserved word (zero).
#[repr(C)]
pub union Vector {
    handler: unsafe extern "C" fn(),
    reserved: u32,
}

macro_rules! vectors {
    ($($entry:tt),* $(,)?) => {
        extern "C" {
            $(vectors!(@decl $entry);)*
        }

        /// IRQ 0 ..= 38 (the linker script keeps it: `EXTERN(__LIFTFW_INTERRUPTS)`).
        #[link_section = ".vector_table.liftfw_interrupts"]
        #[no_mangle]
        #[used]
        pub static __LIFTFW_INTERRUPTS: [Vector; LEN] = [$(vectors!(@entry $entry)),*];
    };
    (@decl _) => {};
    (@decl $name:ident) => { fn $name(); };
    (@entry _) => { Vector { reserved: 0 } };
    (@entry $name:ident) => { Vector { handler: $name } };
}

vectors![
    WWDG,
    PVD_PVM,
    RTC_TAMP_LSECSS,
    RTC_WKUP,
    FLASH,
    RCC,
    EXTI0,
    EXTI1,
    EXTI2,
    EXTI3,
    EXTI4,
    DMA1_CHANNEL1,
    DMA1_CHANNEL2,
    DMA1_CHANNEL3,
    DMA1_CHANNEL4,
    DMA1_CHANNEL5,
    DMA1_CHANNEL6,
    _,
    ADC1_2,
    USB_HP,
    USB_LP,
    FDCAN1_IT0,
    FDCAN1_IT1,
    EXTI9_5,
    TIM1_BRK_TIM15,
    TIM1_UP_TIM16,
    TIM1_TRG_COM_TIM17,
    TIM1_CC,
    TIM2,
    TIM3,
    TIM4,
    I2C1_EV,
    I2C1_ER,
    I2C2_EV,
    I2C2_ER,
    SPI1,
    SPI2,
    USART1,
    USART2,
];

/// Disables in the NVIC every interrupt past the table (see the module's documentation); boot
/// calls it right after `embassy_stm32::init`. Writing 1 to an NVIC_ICERn bit disables that
/// interrupt; bits of interrupts the chip does not have are ignored.
pub fn disable_past_table() {
    // Note(unsafe): the NVIC's registers, written while nothing else uses them (boot, before
    // any task); write-1-to-clear enable bits, for interrupts nothing uses.
    let nvic = unsafe { &*cortex_m::peripheral::NVIC::PTR };
    // Note(unsafe, each): as above. ICER1 holds IRQ 32..=63: the bits from USART2 + 1 on;
    // ICER2 and ICER3 hold IRQ 64..=127 (the chip's last is FMAC, 101).
    unsafe {
        nvic.icer[1].write(!0 << (LEN - 32));
        nvic.icer[2].write(!0);
        nvic.icer[3].write(!0);
    }
}

const _: () = assert!(LEN > 32 && LEN < 64 && (Interrupt::FMAC as usize) < 128);
