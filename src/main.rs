//! liftfw firmware for the default board (STM32G431CB + BTS7960, see docs/board.md).
//!
//! The firmware owns time and hardware only: a fixed-rate task samples the board into
//! [`liftfw::control::Inputs`], calls [`Controller::step`] and applies the returned
//! [`liftfw::control::Outputs`]. Every decision lives in the core library.
//!
//! Cross-build only: `scripts/fw-build` (or `cargo fw` where the target is installed).
#![no_std]
#![no_main]

mod board;

use board::{Board, ConsolePins, CONSOLE_BAUD};
use defmt::{info, warn};
use embassy_executor::Spawner;
use embassy_stm32::usart::{self, BufferedUart};
use embassy_stm32::{bind_interrupts, peripherals};
use embassy_time::{Duration, Instant as Clock, Ticker};
use liftfw::control::config::ControlConfig;
use liftfw::control::{Bridge, Controller};
use liftfw::units::Instant;
use {defmt_rtt as _, panic_probe as _};

/// Control-loop rate. The one place it is set; the core reads elapsed time from `now`.
const CONTROL_HZ: u64 = 1_000;

/// Ticks between two periodic status lines on the defmt log (1 s at 1 kHz).
const STATUS_EVERY_TICKS: u32 = 1_000;

bind_interrupts!(struct Irqs {
    USART2 => usart::BufferedInterruptHandler<peripherals::USART2>;
});

#[embassy_executor::main]
async fn main(spawner: Spawner) {
    let p = embassy_stm32::init(board::clock_config());
    info!("liftfw {} booting", env!("CARGO_PKG_VERSION"));

    let (board, console) = Board::new(p);
    info!(
        "board up: PWM full scale {} counts, control at {} Hz",
        board.bridge.full_scale(),
        CONTROL_HZ
    );

    spawner.spawn(defmt::unwrap!(control(board)));
    spawner.spawn(defmt::unwrap!(console_echo(console)));
}

/// The fixed-rate control loop: sample → `step` → apply. If a tick is late, embassy's
/// `Ticker` keeps its schedule and runs the missed ticks back to back; each one passes the
/// real `now`, so the core sees the short intervals as they are.
#[embassy_executor::task]
async fn control(mut board: Board) {
    // Until the flash store is wired (issue #6), boot on the factory configuration with the
    // lift assumed fully down.
    let mut controller = match Controller::new(&ControlConfig::DEFAULT, 0) {
        Ok(c) => c,
        Err(e) => defmt::panic!("factory configuration refused: {}", e),
    };
    let mut ticker = Ticker::every(Duration::from_hz(CONTROL_HZ));
    let mut last_bridge = Bridge::Coast;
    let mut ticks: u32 = 0;
    loop {
        ticker.next().await;
        // Truncation to u32 is the core's wrapping µs clock (71.6 min period).
        let now = Instant(Clock::now().as_micros() as u32);
        let inputs = board.sensors.sample();
        let outputs = controller.step(now, &inputs);
        board.bridge.apply(outputs.bridge);
        if outputs.feed_watchdog {
            board.watchdog.feed();
        } else {
            warn!("core withheld the watchdog feed at {} us", now.0);
        }

        // State changes and faults (with their snapshot) go to the defmt log.
        match outputs.event {
            Some(liftfw::control::Event::Fault(f)) => defmt::error!("FAULT {}", f),
            Some(e) => info!("{}", e),
            None => {}
        }
        if outputs.bridge != last_bridge {
            info!("bridge {} -> {}", last_bridge, outputs.bridge);
            last_bridge = outputs.bridge;
        }
        ticks = ticks.wrapping_add(1);
        if ticks % STATUS_EVERY_TICKS == 0 {
            info!("t={} us {}", now.0, controller.status());
        }
    }
}

/// USART2 console placeholder: echoes what it receives. The command protocol replaces it.
#[embassy_executor::task]
async fn console_echo(pins: ConsolePins) {
    use embedded_io_async::{Read, Write};

    let mut config = usart::Config::default();
    config.baudrate = CONSOLE_BAUD;
    let mut tx_buffer = [0u8; 64];
    let mut rx_buffer = [0u8; 64];
    let mut uart = match BufferedUart::new(
        pins.usart,
        pins.rx,
        pins.tx,
        &mut tx_buffer,
        &mut rx_buffer,
        Irqs,
        config,
    ) {
        Ok(uart) => uart,
        Err(e) => {
            warn!("console disabled: USART2 config rejected: {}", e);
            return;
        }
    };
    if uart.write_all(b"liftfw console (echo)\r\n").await.is_err() {
        warn!("console write failed");
    }
    let mut chunk = [0u8; 16];
    loop {
        match uart.read(&mut chunk).await {
            Ok(n) => {
                if uart.write_all(&chunk[..n]).await.is_err() {
                    warn!("console write failed");
                }
            }
            // Framing/noise/overrun: drop the bytes and keep listening.
            Err(e) => warn!("console read error: {}", e),
        }
    }
}
