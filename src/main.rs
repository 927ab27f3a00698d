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
use core::mem::MaybeUninit;
use defmt::{error, info, warn};
use embassy_executor::{Executor, SpawnError, SpawnToken, Spawner};
use embassy_futures::select::{select, Either};
use embassy_stm32::flash::{Blocking, Flash};
use embassy_stm32::peripherals::FLASH;
use embassy_stm32::usart::{self, BufferedUart};
use embassy_stm32::{bind_interrupts, peripherals, Peri};
use embassy_sync::blocking_mutex::raw::{CriticalSectionRawMutex, NoopRawMutex};
use embassy_sync::blocking_mutex::Mutex;
use embassy_sync::channel::Channel;
use embassy_sync::signal::Signal;
use embassy_time::{Duration, Instant as Clock, Ticker};
use liftfw::config::store::{
    friction_stamp, geometry_stamp, ConfigStore, Loaded, Parked, Source, StoreError,
};
use liftfw::config::ValidatedConfig;
use liftfw::console::service::{self, Action, Lift};
use liftfw::console::{Feed, LineBuffer};
use liftfw::control::config::ControlConfig;
use liftfw::control::park::ParkLog;
use liftfw::control::{Bridge, Command, Controller, Event, Fault, Refusal, State, Status};
use liftfw::detect::stickslip::Reaction;
use liftfw::units::Instant;
use liftfw::ConfigError;
use static_cell::{ConstStaticCell, StaticCell};
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

type StoreFlash = Flash<'static, Blocking>;

/// The controller's storage: zero-initialised RAM (a `static` holding the controller itself
/// would carry a 2 KiB initial image in flash). It holds the constructor's `Result`, written
/// in one move (see [`install_controller`]).
static CONTROLLER: StaticCell<Result<Controller, ConfigError>> = StaticCell::new();

/// The controller, shared by the control and console tasks. Both run on the one thread-mode
/// executor and no interrupt handler touches the controller, so a lock needs no critical
/// section: with one, interrupts (the time driver's alarm, the console's receive) stayed off
/// through a whole status, ≈ 52 000 instructions (0.3 ms) on a held lowering (BENCHMARKS.md).
type SharedController = Mutex<NoopRawMutex, RefCell<&'static mut Controller>>;

/// Its storage: filled by boot before any task runs, so the tasks get the controller itself
/// (an `Option` in a `static` made every access handle a "not installed yet" that cannot
/// happen).
static LIFT: StaticCell<SharedController> = StaticCell::new();

/// The console's UART ring buffers and reply, in statics rather than in the console task's
/// future: spawning a task builds its future on the boot stack and copies it into the
/// task's storage, so 4.4 KiB of buffers in the future were 4.4 KiB more boot stack.
static CONSOLE_TX: ConstStaticCell<[u8; CONSOLE_TX_LEN]> =
    ConstStaticCell::new([0; CONSOLE_TX_LEN]);
/// The console's transmit ring, bytes: the longest piece of a reply written at once.
const CONSOLE_TX_LEN: usize = 256;
static CONSOLE_RX: ConstStaticCell<[u8; 64]> = ConstStaticCell::new([0; 64]);
static CONSOLE_REPLY: ConstStaticCell<Reply> = ConstStaticCell::new(Reply(heapless::String::new()));

/// The console's reply buffer. Its `core::fmt::Write` is only what the core's replies use:
/// they are written with `write_str` alone (`liftfw::text`, `console::fill`), never with
/// `write!`, so `write_fmt` takes a plain string only (anything else is an error, the reply is
/// then marked cut) instead of linking `core::fmt::write`'s argument loop into the sink's
/// vtable, and `write_char` goes through `write_str`.
struct Reply(heapless::String<REPLY_LEN>);

impl core::fmt::Write for Reply {
    // `write_str` and `write_char` are not inlined: the reply is the firmware's only dyn
    // `Write`, so LTO turns the core's `out.write_*` calls into direct calls of these and
    // would otherwise inline heapless's `push_str`/`push` into each of them.
    #[inline(never)]
    fn write_str(&mut self, s: &str) -> core::fmt::Result {
        self.0.push_str(s).map_err(|_| core::fmt::Error)
    }

    #[inline(never)]
    fn write_char(&mut self, c: char) -> core::fmt::Result {
        // Any char (the user's words echoed in error replies go out char by char).
        self.write_str(c.encode_utf8(&mut [0; 4]))
    }

    fn write_fmt(&mut self, args: core::fmt::Arguments<'_>) -> core::fmt::Result {
        match args.as_str() {
            Some(s) => self.write_str(s),
            None => Err(core::fmt::Error),
        }
    }
}

/// Work for the storage task.
enum StoreRequest {
    /// `save` from the console.
    Config(ValidatedConfig),
    /// The position record, with the stamp of the geometry it is counted in.
    Position(Parked, u32),
    /// The thread's identified friction scale, with the stamp of the law it scales.
    Friction(liftfw::units::Ratio, u32),
}

static STORE_REQUESTS: Channel<CriticalSectionRawMutex, StoreRequest, 2> = Channel::new();

/// Unsolicited console lines the control task asks for (faults, homing, stick-slip warnings);
/// dropped when the console is behind (the defmt log has them all).
static NOTICES: Channel<CriticalSectionRawMutex, Event, 4> = Channel::new();
static SAVED: Signal<CriticalSectionRawMutex, Result<u32, StoreError>> = Signal::new();

/// The thread-mode executor: [`boot`] runs before it polls anything and spawns the three tasks.
static EXECUTOR: StaticCell<Executor> = StaticCell::new();

/// Entry: boot, then run the tasks. Boot awaits nothing (the store is blocking, like the
/// flash), so it runs as the executor's `init` rather than as a task of its own (what
/// `#[embassy_executor::main]` makes of it: a task pool, a spawn and a poll, for nothing).
#[cortex_m_rt::entry]
fn main() -> ! {
    EXECUTOR.init(Executor::new()).run(boot)
}

/// Boot, in steps that each keep their temporaries in their own frame: `boot` holds only what
/// the steps hand on. Inlined into one frame, the HAL bring-up, the store, the controller and
/// the spawned tasks' futures all had slots in one 9.5 KiB frame (scripts/fw-build prints
/// the bound; BENCHMARKS.md "Stack"). Out of line, so that the stack bound can tell boot
/// (which runs once, before any task) from the executor's loop under every task.
#[inline(never)]
fn boot(spawner: Spawner) {
    let (board, console, flash, watchdog_reset) = bring_up();
    // Configuration and parked position, before the watchdog runs (a store repair may erase a
    // page: tens of ms). Any failure leaves the factory configuration and an unhomed lift.
    let boot = load_store(flash);
    let greeting = log_source(&boot.loaded.source);
    let parked = trusted_position(&boot);
    let controller = install_controller(boot.loaded.config.get(), parked);
    if let Some(scale) = boot.friction {
        controller.restore_friction_scale(scale);
    }
    #[cfg(not(feature = "ball-screw"))]
    if boot.loaded.source.needs_ball_screw() {
        // A lead-screw image on a ball screw's record: braked and locked, the record kept.
        error!("the stored configuration needs the ball-screw firmware (cargo fw-ball): lift locked, motor braked, record kept");
        controller.report_needs_ball_screw(Instant(Clock::now().as_micros() as u32));
    }
    if boot.loaded.source.lost_stored(boot.position_record) {
        error!("stored configuration lost: factory defaults in force, fault latched until `fault clear`");
        controller.report_factory_defaults(Instant(Clock::now().as_micros() as u32));
    }
    if watchdog_reset {
        error!("the last reset came from the watchdog: fault latched");
        controller.report_watchdog_reset(Instant(Clock::now().as_micros() as u32));
    }
    let lift = LIFT.init(Mutex::new(RefCell::new(controller)));
    spawn_tasks(spawner, board, lift, console, greeting, boot, parked);
}

/// Clocks, the board's pins and peripherals (the bridge coasting; the board in [`BOARD`],
/// where it stays), and whether the watchdog caused the last reset.
#[inline(never)]
fn bring_up() -> (&'static mut Board, ConsolePins, Peri<'static, FLASH>, bool) {
    let p = board::init();
    info!("liftfw {} booting", env!("CARGO_PKG_VERSION"));
    let watchdog_reset = board::Watchdog::caused_last_reset();
    let (board, console, flash) = Board::new(p);
    (BOARD.init(board), console, flash, watchdog_reset)
}

/// The configuration store, for the storage task (a static rather than in the task's
/// future: see [`CONSOLE_TX`]).
static STORE: StaticCell<ConfigStore<StoreFlash>> = StaticCell::new();

/// What boot read from the configuration store.
struct Boot {
    /// The store, unless it is unusable.
    store: Option<&'static mut ConfigStore<StoreFlash>>,
    /// The running configuration and where it came from (as the store's `load` returns it:
    /// built in place, not moved field by field).
    loaded: Loaded,
    /// The parked position in encoder counts, if one is recorded.
    parked: Option<i32>,
    /// The thread's friction scale identified before the power went, if one is recorded.
    friction: Option<liftfw::units::Ratio>,
    /// The store holds an intact position record (`Source::lost_stored`).
    position_record: bool,
}

/// Opens the store and reads the configuration and the parked position (in a frame of its
/// own: `boot`'s holds only the result).
#[inline(never)]
fn load_store(flash: Peri<'static, FLASH>) -> Boot {
    let boot = match ConfigStore::new(Flash::new_blocking(flash), STORE_RANGE) {
        Ok(store) => {
            let store = STORE.init(store);
            let loaded = store.load();
            let stamp = geometry_stamp(loaded.config.get());
            let parked = store.load_position(stamp);
            let friction = store.load_friction_scale(friction_stamp(loaded.config.get()));
            let position_record = store.has_position_record();
            Boot {
                store: Some(store),
                loaded,
                parked,
                friction,
                position_record,
            }
        }
        // Logged below as the configuration's source (`Unreadable`).
        Err(e) => Boot {
            store: None,
            loaded: Loaded {
                config: ValidatedConfig::factory(),
                source: Source::Unreadable(e),
            },
            parked: None,
            friction: None,
            position_record: false,
        },
    };
    let ecc = board::STORE_ECC_ERRORS.load(core::sync::atomic::Ordering::Relaxed);
    if ecc > 0 {
        warn!(
            "{} flash ECC error(s) read in the store (torn writes): treated as damaged data",
            ecc
        );
    }
    boot
}

/// Logs where the configuration came from, with the text the console greets with: the
/// greeting's first lines (protocol version, the source's message) are written here into the
/// console's reply buffer, and the log takes the message from there (`{=str}`) instead of a
/// defmt encoding of [`Source`] (its derived format and those of the errors inside it: flash).
/// Returns the buffer, for the console task to send.
#[inline(never)]
fn log_source(source: &Source) -> &'static mut Reply {
    use core::fmt::Write as _;
    let reply = CONSOLE_REPLY.take();
    let _ = service::write_version(reply);
    let _ = reply.write_str("\r\n");
    let start = reply.0.len();
    let _ = source.write_to(reply);
    let message = reply.0.get(start..).unwrap_or_default();
    if source.is_fallback() {
        warn!("configuration: {=str}", message);
    } else {
        info!("configuration: {=str}", message);
    }
    reply
}

/// The parked position, if it can be trusted. A ball screw is not self-locking: with the
/// power off the load may have turned it since it was parked, so only a lead screw's parked
/// position is trusted (docs/control.md).
#[inline(never)]
fn trusted_position(boot: &Boot) -> Option<i32> {
    let parked = if boot.loaded.config.get().screw.holds_without_power() {
        boot.parked
    } else {
        if boot.parked.is_some() {
            warn!("ball screw: the parked position is not trusted after a power-off");
        }
        None
    };
    match parked {
        Some(counts) => info!("parked at {} counts", counts),
        None => warn!("position unknown: hold DOWN to home on the lower limit switch"),
    }
    parked
}

/// The board, for the control task. Passed on by reference: a `Board` task argument (with
/// the drop glue of the HAL's drivers, which reset their peripherals when dropped) linked
/// that whole destructor for the spawn's failure path (which cannot happen: see [`token`]),
/// and by value it was one more move through boot's frame.
static BOARD: StaticCell<Board> = StaticCell::new();

/// Spawns the tasks (each spawn builds the task's future on this frame and copies it into
/// the task's storage).
#[inline(never)]
fn spawn_tasks(
    spawner: Spawner,
    board: &'static mut Board,
    lift: &'static SharedController,
    console: ConsolePins,
    greeting: &'static mut Reply,
    boot: Boot,
    parked: Option<i32>,
) {
    info!(
        "board up: PWM full scale {} counts, control at {} Hz",
        board.bridge.full_scale(),
        CONTROL_HZ as u32
    );
    let store_ok = boot.store.is_some();
    if let Some(store) = boot.store {
        spawner.spawn(token(storage(store)));
    }
    let park = ParkLog::new(parked.map(Parked::At));
    spawner.spawn(token(control(board, lift, park)));
    spawner.spawn(token(console_task(
        console,
        lift,
        greeting,
        boot.loaded.config,
        store_ok,
    )));
}

/// A task's spawn token. Each task is spawned once, into a pool of one, so this cannot fail;
/// if it did, it panics (panic-probe logs the message, then the HardFault handler stops the
/// bridge).
#[inline(always)]
fn token<S>(spawned: Result<SpawnToken<S>, SpawnError>) -> SpawnToken<S> {
    match spawned {
        Ok(token) => token,
        Err(_) => panic!("task spawned twice"),
    }
}

/// Builds the controller in [`CONTROLLER`] from the running configuration (the factory one if
/// that is refused) at the parked position, or unhomed.
///
/// Built by value in `boot`, every move of the 2 KiB controller (the constructor's
/// `Result`, the fallback, the `StaticCell`) took its own slot in boot's frame. Here
/// [`construct`] gets the static's storage: the constructor returns into one temporary in that
/// function's frame, copied once into the static. (LLVM cannot hand the static to the
/// constructor as its return slot: that needs a destination it knows to be writable, which a
/// `&mut` argument is not marked as.)
#[inline(never)]
fn install_controller(config: &ControlConfig, parked: Option<i32>) -> &'static mut Controller {
    // Opaque to the optimiser, so that the constructor is not specialised to the static's
    // address (a second copy of it, for no speed that matters at boot).
    let slot = core::hint::black_box(CONTROLLER.uninit());
    // The running configuration was validated already; the factory one is the fallback.
    if construct(slot, config, parked).is_err() {
        construct(slot, &ControlConfig::DEFAULT, None);
    }
    // Note(unsafe): every path above wrote `slot` (`construct` always does).
    match unsafe { slot.assume_init_mut() } {
        Ok(controller) => controller,
        // Cannot happen: the factory configuration is valid (the core's unit test
        // `factory_configuration_passes_validation`; host-sim builds its controllers from it).
        // If it did, a plain panic, as in `token`.
        Err(_) => panic!("factory configuration refused"),
    }
}

/// Writes the controller for `config` into `slot`: at `parked` counts (homed), or unhomed.
#[inline(never)]
fn construct<'a>(
    slot: &'a mut MaybeUninit<Result<Controller, ConfigError>>,
    config: &ControlConfig,
    parked: Option<i32>,
) -> &'a mut Result<Controller, ConfigError> {
    slot.write(Controller::new_at(config, parked))
}

/// The fixed-rate control loop: sample → `step` → apply → `finish_tick`. If a tick is late,
/// embassy's `Ticker` keeps its schedule and runs the missed ticks back to back; each one passes
/// the real `now`, so the core sees the short intervals as they are.
#[embassy_executor::task]
async fn control(board: &'static mut Board, lift: &'static SharedController, mut park: ParkLog) {
    let mut ticker = Ticker::every(Duration::from_hz(CONTROL_HZ));
    let mut last_bridge = Bridge::Coast;
    let mut ticks: u32 = 0;
    // A position record not yet accepted by the storage task (only the newest matters).
    let mut unsent: Option<StoreRequest> = None;
    let mut unsent_friction: Option<StoreRequest> = None;
    board.watchdog.start();
    loop {
        ticker.next().await;
        // Truncation to u32 is the core's wrapping µs clock (71.6 min period).
        let now = Instant(Clock::now().as_micros() as u32);
        let inputs = board.sensors.sample();
        // The periodic status line is due on this tick.
        let line_due = ticks.wrapping_add(1) % STATUS_EVERY_TICKS == 0;
        let (outputs, status, record, friction) = lift.lock(|c| {
            let mut ctl = c.borrow_mut();
            let outputs = ctl.step(now, &inputs);
            board.bridge.apply(outputs.bridge);
            board.brake.apply(outputs.brake_release);
            // The rest of the tick, which the outputs did not wait for (the estimator's next
            // pose nodes): a tick that crosses into a pose segment drives the bridge as soon as
            // any other.
            ctl.finish_tick();
            // The whole status (the identification's divisions) only on a tick that logs it:
            // with the lock held interrupts are off.
            let status = (line_due || outputs.event.is_some()).then(|| ctl.status());
            let record = park
                .observe(ctl.state(), ctl.position_counts(), ctl.homed())
                .map(|p| StoreRequest::Position(p, geometry_stamp(ctl.config())));
            let friction = ctl
                .take_friction_store()
                .map(|f| StoreRequest::Friction(f, friction_stamp(ctl.config())));
            (outputs, status, record, friction)
        });
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
        // The friction scale's record (rare: only when it moved), kept apart from the position's.
        if friction.is_some() {
            unsent_friction = friction;
        }
        if let Some(r) = unsent_friction.take() {
            if let Err(embassy_sync::channel::TrySendError::Full(r)) = STORE_REQUESTS.try_send(r) {
                unsent_friction = Some(r);
            }
        }

        // State changes and faults (with their snapshot) go to the defmt log (stick-slip with
        // the reactions `warn` and `speed` as a warning); faults, homing and those stick-slip
        // warnings also to the console.
        if let (Some(e), Some(s)) = (outputs.event, &status) {
            report_event(e, &s.load);
        }
        // A change of the bridge's mode (coast, brake, drive up or down) is logged, not every
        // new duty: a motion would log a frame every tick (14 000 in a 15 s lift, measured
        // under fwsim). The periodic status line carries the speed and the current.
        if bridge_mode(outputs.bridge) != bridge_mode(last_bridge) {
            info!("bridge {} -> {}", last_bridge, outputs.bridge);
        }
        last_bridge = outputs.bridge;
        ticks = ticks.wrapping_add(1);
        if let (true, Some(s)) = (line_due, &status) {
            info!("t={} us {}", now.0, s);
        }
    }
}

/// The bridge's mode for the log: coast, brake, drive lifting (duty ≥ 0), drive lowering.
fn bridge_mode(b: Bridge) -> u8 {
    match b {
        Bridge::Coast => 0,
        Bridge::Brake => 1,
        Bridge::Drive(d) if d >= 0 => 2,
        Bridge::Drive(_) => 3,
    }
}

/// An event of the tick to the defmt log (a motion's end with the load it identified) and,
/// for faults, homing and the stick-slip and lubrication warnings, to the console. Out of line: a tick rarely has an event, and the
/// logging calls would otherwise be inlined into the control task's poll.
#[inline(never)]
fn report_event(e: Event, load: &liftfw::ident::LoadReport) {
    // Stick-slip with the reactions `warn` and `speed`, and the lubrication warning: warnings.
    let warning = match e {
        Event::StickSlip { reaction, .. } => reaction != Reaction::Log,
        Event::CruiseLimited { .. } => true,
        #[cfg(feature = "ball-screw")]
        Event::Lubrication(_) => true,
        Event::ThreadDry(_) => true,
        _ => false,
    };
    match e {
        Event::Fault(f) => error!("FAULT {}", f),
        // The end of a motion: what it identified.
        Event::State {
            from: State::Lifting | State::Lowering,
            ..
        } => info!("{} {}", e, load),
        _ if warning => warn!("{}", e),
        _ => info!("{}", e),
    }
    let notify = warning || matches!(e, Event::Fault(_) | Event::Homed { .. } | Event::SwitchStop);
    if notify && NOTICES.try_send(e).is_err() {
        warn!("console notice dropped (console behind)");
    }
}

/// The only user of the flash. Flash programming stalls the CPU (single bank): the console
/// asks for a configuration save only while the lift is at rest; the position record is a
/// few double words as a motion starts and once it has settled.
#[embassy_executor::task]
async fn storage(store: &'static mut ConfigStore<StoreFlash>) {
    loop {
        match STORE_REQUESTS.receive().await {
            StoreRequest::Config(cfg) => {
                let r = store.save(&cfg);
                match r {
                    Ok(seq) => info!("configuration #{} saved", seq),
                    Err(e) => error!("configuration save failed: {}", e),
                }
                SAVED.signal(r);
            }
            StoreRequest::Position(p, stamp) => {
                if let Err(e) = store.save_position(p, stamp) {
                    // The previous record stays; the next one retries.
                    error!("position record {} failed: {}", p, e);
                }
            }
            StoreRequest::Friction(scale, stamp) => {
                if let Err(e) = store.save_friction_scale(scale, stamp) {
                    error!("friction record {} failed: {}", scale, e);
                }
            }
        }
    }
}

/// An unsolicited console line (`warning:` prefix: host tools show and skip them).
fn write_notice(out: &mut dyn core::fmt::Write, e: &Event) -> core::fmt::Result {
    match *e {
        Event::Fault(f) => {
            out.write_str("warning: fault latched: ")?;
            out.write_str(f.kind.name())?;
            if f.kind == liftfw::control::FaultKind::Overload {
                liftfw::console::write_load(out, f.load, f.load_identified)?;
            }
            out.write_str(" (`fault` shows the snapshot, `fault clear` clears it)")
        }
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
        #[cfg(feature = "ball-screw")]
        Event::Lubrication(r) => liftfw::console::write_lube_warning(out, r.f_last, r.law),
        Event::ThreadDry(r) => liftfw::console::write_thread_dry_warning(out, &r),
        Event::CruiseLimited { speed } => liftfw::console::write_cruise_warning(out, speed),
        Event::State { .. } => Ok(()),
    }
}

/// The console's view of the shared controller: each call locks it briefly.
struct SharedLift(&'static SharedController);

impl Lift for SharedLift {
    fn command(&mut self, cmd: Command) -> Result<(), Refusal> {
        self.0.lock(|c| c.borrow_mut().command(cmd))
    }

    fn status(&self) -> Status {
        self.0.lock(|c| c.borrow().status())
    }

    fn fault(&self) -> Option<Fault> {
        self.0.lock(|c| c.borrow().fault().copied())
    }

    fn reconfigure(&mut self, cfg: &ControlConfig) -> Result<(), Refusal> {
        self.0.lock(|c| c.borrow_mut().reconfigure(cfg))
    }
}

/// USART2 console: one line in, the core's reply out (CRLF line ends).
#[embassy_executor::task]
async fn console_task(
    pins: ConsolePins,
    lift: &'static SharedController,
    reply: &'static mut Reply,
    mut running: ValidatedConfig,
    store_ok: bool,
) {
    use core::fmt::Write as _;
    use embedded_io_async::{Read, Write};

    let mut config = usart::Config::default();
    config.baudrate = CONSOLE_BAUD;
    let mut uart = match BufferedUart::new(
        pins.usart,
        pins.rx,
        pins.tx,
        CONSOLE_TX.take(),
        CONSOLE_RX.take(),
        Irqs,
        config,
    ) {
        Ok(uart) => uart,
        Err(e) => {
            warn!("console disabled: USART2 config rejected: {}", e);
            return;
        }
    };
    let mut lift = SharedLift(lift);
    // Greeting: protocol version and where the configuration came from (already in `reply`,
    // see `log_source`), whether to home.
    if !lift.status().homed {
        let _ = reply.write_str("\r\n");
        let _ = reply.write_str(Refusal::NotHomed.message());
    }

    let mut lines = LineBuffer::new();
    let mut chunk = [0u8; 16];
    // Bytes of `chunk` not fed yet: `next..read`.
    let (mut next, mut read) = (0, 0);
    loop {
        // One place sends every reply, notice and the greeting, each ended with CRLF (one
        // await point instead of one per kind: less state machine on the board).
        if !reply.0.is_empty() {
            let _ = reply.write_str("\r\n");
            // embassy-stm32 0.6's `BufferedUart::write` takes a buffer only whole: one longer
            // than the ring fails (`BufferTooLong`: the reply was lost), and with less room in
            // the ring than the buffer it returns `Pending` without registering its waker (the
            // reply then waited for the next received byte; fwsim: a 181-byte `fault` reply
            // right after the fault's notice). So a ring's worth at most, each into an empty
            // ring: `flush` waits for the transmission-complete interrupt, which wakes it.
            for piece in reply.0.as_bytes().chunks(CONSOLE_TX_LEN) {
                if uart.flush().await.is_err() || uart.write_all(piece).await.is_err() {
                    warn!("console write failed");
                    break;
                }
            }
            reply.0.clear();
        }
        if let Some(&b) = chunk.get(next..read).and_then(|rest| rest.first()) {
            next += 1;
            let feed = lines.feed(b);
            if matches!(feed, Feed::Pending) {
                continue;
            }
            let outcome = service::handle_feed(feed, &mut lift, &mut running, reply);
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
                        let _ = service::write_saved(reply, SAVED.wait().await);
                    }
                }
            }
            if outcome.reply.is_err() {
                // The reply outgrew the buffer: say so rather than cut it silently. Cut at the
                // last char boundary within REPLY_LEN − 24 bytes (what popping chars until it
                // fits leaves, without decoding chars backwards).
                let mut cut = reply.0.len().min(REPLY_LEN - 24);
                while !reply.0.is_char_boundary(cut) {
                    cut -= 1;
                }
                reply.0.truncate(cut);
                let _ = reply.write_str(" ... (reply cut)");
            }
            continue;
        }
        // A notice from the control task, or bytes from the host (BufferedUart's read is
        // cancel-safe: unread bytes stay in its ring buffer).
        match select(uart.read(&mut chunk), NOTICES.receive()).await {
            Either::First(Ok(n)) => (next, read) = (0, n),
            // Framing/noise/overrun: drop the bytes and keep listening.
            Either::First(Err(e)) => warn!("console read error: {}", e),
            Either::Second(event) => {
                let _ = write_notice(reply, &event);
            }
        }
    }
}
