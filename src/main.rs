//! liftfw firmware for the default board (STM32G431CB + BTS7960, see docs/board.md).
//!
//! The firmware owns time and hardware only. Three tasks:
//! - `control`: fixed rate; samples the board into [`liftfw::control::Inputs`], calls
//!   [`Controller::step`], applies the [`liftfw::control::Outputs`], feeds the watchdog when
//!   the core says so, and asks for the parked position to be recorded ([`ParkLog`]).
//! - `console`: USART2 lines through the core's console service
//!   ([`liftfw::console::service`]): status, get/set/save, limits, motion, faults.
//! - `storage`: the only task that touches flash ([`ConfigStore`]): saves the configuration
//!   when the console asks, and the parked/moving position record.
//!
//! The controller lives in a critical-section mutex: the control task locks it for one
//! `step`, the console for one call; nothing formats text inside the lock. Every decision
//! lives in the core library.
//!
//! Cross-build only: `scripts/fw-build` (or `cargo fw` where the target is installed).
#![no_std]
#![no_main]

mod board;

use board::{Board, ConsolePins, CONSOLE_BAUD, STORE_RANGE};
use core::cell::RefCell;
use defmt::{error, info, warn};
use embassy_embedded_hal::adapter::BlockingAsync;
use embassy_executor::Spawner;
use embassy_futures::select::{select, Either};
use embassy_stm32::flash::{Blocking, Flash};
use embassy_stm32::usart::{self, BufferedUart};
use embassy_stm32::{bind_interrupts, peripherals};
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::blocking_mutex::Mutex;
use embassy_sync::channel::Channel;
use embassy_sync::signal::Signal;
use embassy_time::{Duration, Instant as Clock, Ticker};
use liftfw::config::store::{geometry_stamp, ConfigStore, Parked, Source, StoreError};
use liftfw::config::ValidatedConfig;
use liftfw::console::service::{self, Action, Lift};
use liftfw::console::{Feed, LineBuffer};
use liftfw::control::config::ControlConfig;
use liftfw::control::park::ParkLog;
use liftfw::control::{Bridge, Command, Controller, Event, Fault, Refusal, State, Status};
use liftfw::detect::stickslip::Reaction;
use liftfw::units::Instant;
use static_cell::StaticCell;
use {defmt_rtt as _, panic_probe as _};

/// Control-loop rate. The one place it is set; the core reads elapsed time from `now`.
const CONTROL_HZ: u64 = 1_000;

/// Ticks between two periodic status lines on the defmt log (1 s at 1 kHz).
const STATUS_EVERY_TICKS: u32 = 1_000;

/// Longest console reply (`help keys` lists every setting with its range).
const REPLY_LEN: usize = 4096;

bind_interrupts!(struct Irqs {
    USART2 => usart::BufferedInterruptHandler<peripherals::USART2>;
});

type StoreFlash = BlockingAsync<Flash<'static, Blocking>>;

/// The controller's storage: zero-initialised RAM (a `static` holding the controller itself
/// would carry a 1.6 KiB initial image in flash).
static CONTROLLER: StaticCell<Controller> = StaticCell::new();

/// The controller, shared by the control and console tasks.
static LIFT: Mutex<CriticalSectionRawMutex, RefCell<Option<&'static mut Controller>>> =
    Mutex::new(RefCell::new(None));

/// Work for the storage task.
enum StoreRequest {
    /// `save` from the console.
    Config(ValidatedConfig),
    /// The position record, with the stamp of the geometry it is counted in.
    Position(Parked, u32),
}

static STORE_REQUESTS: Channel<CriticalSectionRawMutex, StoreRequest, 2> = Channel::new();

/// Unsolicited console lines the control task asks for (faults, homing, stick-slip warnings);
/// dropped when the console is behind (the defmt log has them all).
static NOTICES: Channel<CriticalSectionRawMutex, Event, 4> = Channel::new();
static SAVED: Signal<CriticalSectionRawMutex, Result<u32, StoreError>> = Signal::new();

#[embassy_executor::main]
async fn main(spawner: Spawner) {
    let p = embassy_stm32::init(board::clock_config());
    info!("liftfw {} booting", env!("CARGO_PKG_VERSION"));
    let watchdog_reset = board::Watchdog::caused_last_reset();

    let (board, console, flash) = Board::new(p);

    // Configuration and parked position, before the watchdog runs (a store repair may erase a
    // page: tens of ms). Any failure leaves the factory configuration and an unhomed lift.
    let flash = BlockingAsync::new(Flash::new_blocking(flash));
    let (store, config, source, parked) = match ConfigStore::new(flash, STORE_RANGE) {
        Ok(mut store) => {
            let loaded = store.load().await;
            let stamp = geometry_stamp(loaded.config.get());
            let parked = store.load_position(stamp).await;
            (Some(store), loaded.config, loaded.source, parked)
        }
        Err(e) => {
            error!("configuration store unusable: {}", e);
            let source = Source::Unreadable(e);
            (None, ValidatedConfig::factory(), source, None)
        }
    };
    let ecc = board::STORE_ECC_ERRORS.load(core::sync::atomic::Ordering::Relaxed);
    if ecc > 0 {
        warn!(
            "{} flash ECC error(s) read in the store (torn writes): treated as damaged data",
            ecc
        );
    }
    if source.is_fallback() {
        warn!("configuration: {}", source);
    } else {
        info!("configuration: {}", source);
    }
    // A ball screw is not self-locking: with the power off the load may have turned it since
    // it was parked, so only a lead screw's parked position is trusted (docs/control.md).
    let parked = if config.get().screw.holds_without_power() {
        parked
    } else {
        if parked.is_some() {
            warn!("ball screw: the parked position is not trusted after a power-off");
        }
        None
    };
    let made = match parked {
        Some(counts) => {
            info!("parked at {} counts", counts);
            Controller::new(config.get(), counts)
        }
        None => {
            warn!("position unknown: hold DOWN to home on the lower limit switch");
            Controller::new_unhomed(config.get())
        }
    };
    // The running configuration was validated already; the factory one is the fallback.
    let mut controller = match made.or_else(|_| Controller::new_unhomed(&ControlConfig::DEFAULT)) {
        Ok(c) => c,
        Err(e) => defmt::panic!("factory configuration refused: {}", e),
    };
    if watchdog_reset {
        error!("the last reset came from the watchdog: fault latched");
        controller.report_watchdog_reset(Instant(Clock::now().as_micros() as u32));
    }
    let park = ParkLog::new(parked.map(Parked::At));
    let controller: &'static mut Controller = CONTROLLER.init(controller);
    LIFT.lock(|c| c.replace(Some(controller)));

    info!(
        "board up: PWM full scale {} counts, control at {} Hz",
        board.bridge.full_scale(),
        CONTROL_HZ
    );
    let store_ok = store.is_some();
    if let Some(store) = store {
        spawner.spawn(defmt::unwrap!(storage(store)));
    }
    spawner.spawn(defmt::unwrap!(control(board, park)));
    spawner.spawn(defmt::unwrap!(console_task(
        console, config, source, store_ok
    )));
}

/// The fixed-rate control loop: sample → `step` → apply. If a tick is late, embassy's
/// `Ticker` keeps its schedule and runs the missed ticks back to back; each one passes the
/// real `now`, so the core sees the short intervals as they are.
#[embassy_executor::task]
async fn control(mut board: Board, mut park: ParkLog) {
    let mut ticker = Ticker::every(Duration::from_hz(CONTROL_HZ));
    let mut last_bridge = Bridge::Coast;
    let mut ticks: u32 = 0;
    // A position record not yet accepted by the storage task (only the newest matters).
    let mut unsent: Option<StoreRequest> = None;
    board.watchdog.start();
    loop {
        ticker.next().await;
        // Truncation to u32 is the core's wrapping µs clock (71.6 min period).
        let now = Instant(Clock::now().as_micros() as u32);
        let inputs = board.sensors.sample();
        let stepped = LIFT.lock(|c| {
            c.borrow_mut().as_mut().map(|ctl| {
                let outputs = ctl.step(now, &inputs);
                let status = ctl.status();
                let record = park
                    .step(&status)
                    .map(|p| StoreRequest::Position(p, geometry_stamp(ctl.config())));
                (outputs, status, record)
            })
        });
        let Some((outputs, status, record)) = stepped else {
            // Unreachable by construction (main installs the controller first); coast and
            // let the watchdog reset the board.
            board.bridge.apply(Bridge::Coast);
            continue;
        };
        board.bridge.apply(outputs.bridge);
        if outputs.feed_watchdog {
            board.watchdog.feed();
        } else {
            warn!("core withheld the watchdog feed at {} us", now.0);
        }
        if record.is_some() {
            unsent = record;
        }
        if let Some(r) = unsent.take() {
            if let Err(embassy_sync::channel::TrySendError::Full(r)) = STORE_REQUESTS.try_send(r) {
                unsent = Some(r);
            }
        }

        // State changes and faults (with their snapshot) go to the defmt log (stick-slip with
        // the reactions `warn` and `speed` as a warning); faults, homing and those stick-slip
        // warnings also to the console.
        if let Some(e) = outputs.event {
            let notify = match e {
                Event::Fault(f) => {
                    error!("FAULT {}", f);
                    true
                }
                Event::StickSlip { reaction, .. } if reaction != Reaction::Log => {
                    warn!("{}", e);
                    true
                }
                Event::Homed { .. } | Event::SwitchStop => {
                    info!("{}", e);
                    true
                }
                _ => {
                    info!("{}", e);
                    false
                }
            };
            if notify && NOTICES.try_send(e).is_err() {
                warn!("console notice dropped (console behind)");
            }
        }
        if outputs.bridge != last_bridge {
            info!("bridge {} -> {}", last_bridge, outputs.bridge);
            last_bridge = outputs.bridge;
        }
        ticks = ticks.wrapping_add(1);
        if ticks % STATUS_EVERY_TICKS == 0 {
            info!("t={} us {}", now.0, status);
        }
    }
}

/// The only user of the flash. Flash programming stalls the CPU (single bank): the console
/// asks for a configuration save only while the lift is at rest; the position record is a
/// few double words as a motion starts and once it has settled.
#[embassy_executor::task]
async fn storage(mut store: ConfigStore<StoreFlash>) {
    loop {
        match STORE_REQUESTS.receive().await {
            StoreRequest::Config(cfg) => {
                let r = store.save(&cfg).await;
                match r {
                    Ok(seq) => info!("configuration #{} saved", seq),
                    Err(e) => error!("configuration save failed: {}", e),
                }
                SAVED.signal(r);
            }
            StoreRequest::Position(p, stamp) => {
                if let Err(e) = store.save_position(p, stamp).await {
                    // The previous record stays; the next one retries.
                    error!("position record {} failed: {}", p, e);
                }
            }
        }
    }
}

/// An unsolicited console line (`warning:` prefix: host tools show and skip them).
fn write_notice(out: &mut dyn core::fmt::Write, e: &Event) -> core::fmt::Result {
    match *e {
        Event::Fault(f) => write!(
            out,
            "warning: fault latched: {} (`fault` shows the snapshot, `fault clear` clears it)",
            f.kind.name()
        ),
        Event::Homed { .. } => out.write_str("warning: homed on the lower limit switch"),
        Event::SwitchStop => {
            out.write_str("warning: a limit switch stopped the lift before the soft stop")
        }
        Event::StickSlip {
            amplitude,
            episode,
            reaction,
        } => liftfw::console::write_stick_slip_warning(
            out,
            episode,
            amplitude,
            reaction == Reaction::ChangeSpeed,
        ),
        Event::State { .. } => Ok(()),
    }
}

/// The console's view of the shared controller: each call locks it briefly.
struct SharedLift;

impl Lift for SharedLift {
    fn command(&mut self, cmd: Command) -> Result<(), Refusal> {
        LIFT.lock(|c| {
            c.borrow_mut()
                .as_mut()
                .map_or(Err(Refusal::Faulted), |ctl| ctl.command(cmd))
        })
    }

    fn status(&self) -> Status {
        LIFT.lock(|c| {
            c.borrow()
                .as_ref()
                .map(|ctl| ctl.status())
                .unwrap_or_default()
        })
    }

    fn fault(&self) -> Option<Fault> {
        LIFT.lock(|c| c.borrow().as_ref().and_then(|ctl| ctl.fault().copied()))
    }

    fn reconfigure(&mut self, cfg: &ControlConfig) -> Result<(), Refusal> {
        LIFT.lock(|c| {
            c.borrow_mut()
                .as_mut()
                .map_or(Err(Refusal::Faulted), |ctl| ctl.reconfigure(cfg))
        })
    }
}

/// USART2 console: one line in, the core's reply out (CRLF line ends).
#[embassy_executor::task]
async fn console_task(
    pins: ConsolePins,
    mut running: ValidatedConfig,
    source: Source,
    store_ok: bool,
) {
    use core::fmt::Write as _;
    use embedded_io_async::{Read, Write};

    let mut config = usart::Config::default();
    config.baudrate = CONSOLE_BAUD;
    let mut tx_buffer = [0u8; 256];
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
    let mut reply: heapless::String<REPLY_LEN> = heapless::String::new();
    let mut lift = SharedLift;
    // Greeting: protocol version, where the configuration came from, whether to home.
    let _ = service::write_version(&mut reply);
    let _ = write!(reply, "\r\n{source}\r\n");
    if !lift.status().homed {
        let _ = write!(reply, "{}\r\n", Refusal::NotHomed);
    }
    if uart.write_all(reply.as_bytes()).await.is_err() {
        warn!("console write failed");
    }

    let mut lines = LineBuffer::new();
    let mut chunk = [0u8; 16];
    loop {
        // A notice from the control task, or bytes from the host (BufferedUart's read is
        // cancel-safe: unread bytes stay in its ring buffer).
        let n = match select(uart.read(&mut chunk), NOTICES.receive()).await {
            Either::First(Ok(n)) => n,
            // Framing/noise/overrun: drop the bytes and keep listening.
            Either::First(Err(e)) => {
                warn!("console read error: {}", e);
                continue;
            }
            Either::Second(event) => {
                reply.clear();
                let _ = write_notice(&mut reply, &event);
                let _ = reply.write_str("\r\n");
                if uart.write_all(reply.as_bytes()).await.is_err() {
                    warn!("console write failed");
                }
                continue;
            }
        };
        for &b in chunk.get(..n).unwrap_or(&[]) {
            let feed = lines.feed(b);
            if matches!(feed, Feed::Pending) {
                continue;
            }
            reply.clear();
            let outcome = service::handle_feed(feed, &mut lift, &mut running, &mut reply);
            match outcome.action {
                Action::None => {}
                Action::Reconfigured => info!("configuration changed (not saved)"),
                Action::Save => {
                    let at_rest = !matches!(lift.status().state, State::Lifting | State::Lowering);
                    if !store_ok {
                        let _ = reply.write_str("error: save: the configuration store is unusable");
                    } else if !at_rest {
                        let _ = reply.write_str(
                            "error: save refused while the lift moves (flash writes stall the \
                             CPU); `stop` first",
                        );
                    } else {
                        SAVED.reset();
                        STORE_REQUESTS.send(StoreRequest::Config(running)).await;
                        let _ = service::write_saved(&mut reply, SAVED.wait().await);
                    }
                }
            }
            if outcome.reply.is_err() {
                // The reply outgrew the buffer: say so rather than cut it silently.
                while reply.len() > REPLY_LEN - 24 {
                    reply.pop();
                }
                let _ = reply.write_str(" ... (reply cut)");
            }
            if !reply.is_empty() {
                let _ = reply.write_str("\r\n");
                if uart.write_all(reply.as_bytes()).await.is_err() {
                    warn!("console write failed");
                }
            }
        }
    }
}
