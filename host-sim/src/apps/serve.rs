//! `host-sim serve`: the simulated board with its console on a loopback TCP port.
//!
//! The closed loop of `host-sim run --mode closed` (the liftfw core's `Controller` driving the
//! float64 plant at its 1 kHz tick) runs without end, in real time or faster, and every line a
//! TCP client sends goes through the core's console service (`liftfw::console::service`)
//! exactly as the firmware's UART console does: the same parser, the same replies, the same
//! refusals. `save` writes the core's `ConfigStore` on a simulated flash (`SimFlash`), kept in
//! the process and, with `--flash FILE`, in a file image, so a saved configuration survives a
//! simulated power cycle ([`Server::power_cycle`]) and a restart of `host-sim serve`.
//!
//! A power cycle keeps the plant (the lift does not move while the power is off: the lead
//! screw is self-locking) and the encoder position, and boots a new controller from what the
//! store loads, as the firmware does.

use crate::twin::inject::{Injection, Plan};
use crate::twin::physics::Lubricant;
use crate::twin::sim::{Driver, Sim, SimConfig};
use clap::Args;
use liftfw::config::sim_flash::{SimFlash, ERASE_SIZE};
use liftfw::config::store::{geometry_stamp, ConfigStore, Loaded, Parked};
use liftfw::config::ValidatedConfig;
use liftfw::console::service::{self, Action};
use liftfw::console::{Feed, LineBuffer};
use liftfw::control::park::ParkLog;
use liftfw::control::{Bridge, Controller};
use liftfw::units::{Instant, Metres};
use std::collections::HashMap;
use std::io::{self, Read, Write};
use std::net::{Shutdown, SocketAddr, TcpListener, TcpStream};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{self, Receiver, Sender};
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::thread::{self, JoinHandle};
use std::time::{Duration, Instant as WallClock};

/// Size of the simulated configuration flash: two copies of two 2 KiB pages, as on the board.
pub const FLASH_SIZE: usize = 4 * ERASE_SIZE;
/// The simulated flash.
pub type Flash = SimFlash<FLASH_SIZE>;

/// Plant lubricant (the core's configuration comes from the flash, factory: dry).
pub use crate::cli::Lube;

/// `host-sim serve` options.
#[derive(Args, Clone, Debug)]
pub struct ServeArgs {
    /// Address to listen on (loopback only makes sense: the console has no authentication).
    #[arg(long, default_value = "127.0.0.1:5151")]
    pub listen: SocketAddr,
    /// Simulated seconds per wall-clock second; 0 runs as fast as the machine can.
    #[arg(long, default_value_t = 1.0)]
    pub speed: f64,
    /// Keep the configuration flash in this file (created on the first `save`), so a saved
    /// configuration survives a restart of `host-sim serve` (a power cycle).
    #[arg(long, value_name = "FILE")]
    pub flash: Option<PathBuf>,
    /// Arm angle at the start, degrees (15 = fully down).
    #[arg(long, default_value_t = 30.0)]
    pub start_deg: f64,
    /// Mass on the head, kg.
    #[arg(long, default_value_t = 1000.0)]
    pub load_kg: f64,
    /// Thread lubrication of the plant.
    #[arg(long, value_enum, default_value_t = Lube::Dry)]
    pub lubricant: Lube,
    /// Base integration step, s (the control period must be a whole number of steps).
    #[arg(long, default_value_t = 4e-6)]
    pub dt: f64,
    /// Seed of the sensor noise.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Also serve the console on a pseudo-terminal (Unix), a serial port to any program:
    /// `liftctl -p /dev/pts/N`, `screen /dev/pts/N`. Its path is printed at the start.
    #[arg(long)]
    pub pty: bool,
    /// Inject a fault: KIND@TIME[:SIZE][+DURATION], simulated seconds from the start (see
    /// `host-sim lift --help`); repeat the flag for more.
    #[arg(long, value_name = "FAULT", value_parser = parse_fault)]
    pub fault: Vec<Injection>,
    /// Also listen here for faults at run time, one `KIND@DELAY[:SIZE][+DURATION]` per line
    /// (DELAY from the moment it arrives): a side channel for the test bench, not the
    /// product's console (which has no such command).
    #[arg(long, value_name = "ADDR")]
    pub fault_listen: Option<SocketAddr>,
}

fn parse_fault(s: &str) -> Result<Injection, String> {
    s.parse()
}

impl Default for ServeArgs {
    fn default() -> Self {
        ServeArgs {
            listen: SocketAddr::from(([127, 0, 0, 1], 5151)),
            speed: 1.0,
            flash: None,
            start_deg: 30.0,
            load_kg: 1000.0,
            lubricant: Lube::Dry,
            dt: 4e-6,
            seed: 1,
            pty: false,
            fault: Vec::new(),
            fault_listen: None,
        }
    }
}

/// Ground truth of the plant (not what the board measures), for tests and the operator.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Truth {
    /// Simulated time, s.
    pub t: f64,
    /// Head height, m.
    pub height: f64,
    /// Screw speed, rad/s.
    pub screw_speed: f64,
    /// Motor current, A.
    pub current: f64,
    /// Thread friction torque T_r, N·m.
    pub friction_torque: f64,
}

/// What the connection threads and the handle ask of the simulation thread.
enum Msg {
    /// A console line (or an overlong one), and where the reply goes.
    Feed(Option<Vec<u8>>, Sender<String>),
    /// Power off and on; the reply is the boot message.
    PowerCycle(Sender<String>),
    /// A fault from the side channel, `at` counted from now; the reply says when it acts.
    Inject(Injection, Sender<String>),
}

/// The simulated board: controller, running configuration, store, and the parked-position
/// log the firmware's control task runs (`liftfw::control::park`).
struct Board {
    controller: Controller,
    running: ValidatedConfig,
    store: ConfigStore<Flash>,
    flash_file: Option<PathBuf>,
    park: ParkLog,
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(PoisonError::into_inner)
}

fn new_store(flash: Flash) -> io::Result<ConfigStore<Flash>> {
    ConfigStore::new(flash, 0..FLASH_SIZE as u32)
        .map_err(|e| io::Error::other(format!("configuration store: {e}")))
}

/// Read a flash image, or an erased flash if the file does not exist yet.
fn read_flash(path: Option<&Path>) -> io::Result<Flash> {
    let mut flash = Flash::new();
    if let Some(p) = path {
        match std::fs::read(p) {
            Ok(bytes) if bytes.len() == FLASH_SIZE => flash.bytes_mut().copy_from_slice(&bytes),
            Ok(bytes) => {
                return Err(io::Error::other(format!(
                    "{}: {} bytes, a flash image has {FLASH_SIZE}",
                    p.display(),
                    bytes.len()
                )))
            }
            Err(e) if e.kind() == io::ErrorKind::NotFound => {}
            Err(e) => return Err(io::Error::other(format!("{}: {e}", p.display()))),
        }
    }
    Ok(flash)
}

/// Write the flash image next to the file and rename it over, so a crash leaves the old or
/// the new image.
fn write_flash(path: &Path, bytes: &[u8]) -> io::Result<()> {
    let tmp = path.with_extension("tmp");
    std::fs::write(&tmp, bytes)?;
    std::fs::rename(&tmp, path)
}

impl Board {
    /// Boot as the firmware does: load the configuration (factory defaults if none) and the
    /// parked position, and start the controller there, or unhomed when the flash holds no
    /// trusted position (a power cut during a motion, another geometry, a ball screw). A
    /// blank flash is a lift just installed: it boots at `installed` counts (the installer
    /// homed it), and records that once it is still. Returns the board, the boot message and
    /// the parked position it booted at, if it came from the flash.
    fn boot(
        flash: Flash,
        installed: i32,
        flash_file: Option<PathBuf>,
    ) -> io::Result<(Board, String, Option<i32>)> {
        let blank = flash.bytes().iter().all(|&b| b == 0xFF);
        let mut store = new_store(flash)?;
        let Loaded { config, source } = store.load();
        let stamp = geometry_stamp(config.get());
        let parked = store
            .load_position(stamp)
            .filter(|_| config.get().screw.holds_without_power());
        let position = if blank { Some(installed) } else { parked };
        // Installed and homed: the installer's first parked record, written at once (the file
        // is written only with `--flash` and at the first save or record after the boot).
        if blank {
            store
                .save_position(Parked::At(installed), stamp)
                .map_err(|e| io::Error::other(format!("position record: {e}")))?;
        }
        let made = Controller::new_at(config.get(), position);
        let mut controller = made
            .map_err(|e| io::Error::other(format!("controller refused the configuration: {e}")))?;
        // As the firmware's boot: a lost configuration blocks motion until acknowledged.
        let position_record = store.has_position_record();
        if source.lost_stored(position_record) {
            controller.report_factory_defaults(Instant(0));
        }
        let board = Board {
            controller,
            running: config,
            store,
            flash_file,
            park: ParkLog::new(position.map(Parked::At)),
        };
        let mut msg = format!("boot: {source}");
        match (parked, blank) {
            (Some(p), _) => msg.push_str(&format!("; parked at {p} counts")),
            (None, true) => {}
            (None, false) => msg.push_str(
                "; position unknown: hold DOWN (or `down`) to home on the lower limit switch",
            ),
        }
        Ok((board, msg, parked))
    }

    /// One control tick, and the parked-position record it asks for (written at once, and to
    /// the flash file: a restart is a power cycle).
    fn tick(&mut self, now: Instant, inputs: &liftfw::control::Inputs) -> Bridge {
        let out = self.controller.step(now, inputs);
        self.controller.finish_tick();
        if let Some(p) = self.park.step(&self.controller.status()) {
            let stamp = geometry_stamp(self.controller.config());
            match self.store.save_position(p, stamp) {
                Ok(()) => {
                    self.write_file();
                }
                Err(e) => eprintln!("host-sim serve: position record failed: {e}"),
            }
        }
        out.bridge
    }

    fn write_file(&mut self) -> bool {
        match &self.flash_file {
            Some(path) => match write_flash(path, self.store.flash().bytes()) {
                Ok(()) => true,
                Err(e) => {
                    eprintln!("host-sim serve: cannot write {}: {e}", path.display());
                    false
                }
            },
            None => true,
        }
    }

    fn line(&mut self, line: Option<&[u8]>) -> String {
        let mut out = String::new();
        let o = match line {
            Some(l) => service::handle(l, &mut self.controller, &mut self.running, &mut out),
            None => service::handle_feed(
                Feed::Overflow,
                &mut self.controller,
                &mut self.running,
                &mut out,
            ),
        };
        let moving = matches!(
            self.controller.state(),
            liftfw::control::State::Lifting | liftfw::control::State::Lowering
        );
        if o.action == Action::Save && moving {
            // As the firmware's console task: no flash writes while the lift moves.
            out.push_str(
                "error: save refused while the lift moves (flash writes stall the CPU); `stop` \
                 first",
            );
        } else if o.action == Action::Save {
            let mut r = self.store.save(&self.running);
            if r.is_ok() && !self.write_file() {
                r = Err(liftfw::config::store::StoreError::Flash(
                    liftfw::config::store::FlashErrorKind::Other,
                ));
            }
            // A String sink never refuses text.
            let _ = service::write_saved(&mut out, r);
        }
        out
    }

    /// Power off and on: the plant stays where it is (a lead screw is self-locking), the
    /// controller boots from what the flash holds, the parked position included: after a
    /// power cut during a motion it boots unhomed, as the board does.
    fn power_cycle(&mut self) -> io::Result<String> {
        let old = std::mem::replace(&mut self.store, new_store(Flash::new())?);
        let mut flash = old.into_flash();
        flash.reboot();
        let here = self.controller.position_counts();
        let (board, msg, _) = Board::boot(flash, here, self.flash_file.take())?;
        *self = board;
        Ok(msg)
    }
}

/// A running simulated board.
pub struct Server {
    addr: SocketAddr,
    tx: Sender<Msg>,
    stop: Arc<AtomicBool>,
    truth: Arc<Mutex<Truth>>,
    /// A clone of each open client's stream (to shut them at the end), by connection number;
    /// its thread removes it when the client goes, so a closed connection keeps no descriptor.
    streams: Arc<Mutex<HashMap<u64, TcpStream>>>,
    sim: Option<JoinHandle<()>>,
    accept: Option<JoinHandle<()>>,
    boot: String,
    fault_addr: Option<SocketAddr>,
    #[cfg(unix)]
    pty: Option<pty::Pty>,
}

impl Server {
    /// Boot the board and start serving; returns once the port listens.
    pub fn start(args: &ServeArgs) -> io::Result<Server> {
        let flash = read_flash(args.flash.as_deref())?;
        let probe = Controller::new(ValidatedConfig::factory().get(), 0)
            .map_err(|e| io::Error::other(format!("{e}")))?;
        let h = crate::twin::physics::Geometry::paper().height(args.start_deg.to_radians());
        let position = probe
            .estimator()
            .geometry()
            .counts_for_height(Metres::from_f64(h))
            .ok_or_else(|| io::Error::other("start angle outside the mechanism"))?;
        let (board, boot, parked) = Board::boot(flash, position, args.flash.clone())?;
        // A lift parked in a previous run stands where it parked (the flash says where).
        let start_deg = match parked {
            Some(p) => {
                let h = board.controller.estimator().geometry().pose(p).height;
                crate::twin::physics::Geometry::paper()
                    .alpha_of_height(h.to_f64())
                    .to_degrees()
            }
            None => args.start_deg,
        };
        let mut sc = SimConfig::paper(Lubricant::from(args.lubricant).law(), 0.3, start_deg);
        sc.plant.load = args.load_kg;
        sc.dt = args.dt;
        sc.duration = 1e9;
        sc.record_rate = 0.0;
        sc.seed = args.seed;
        let board = Arc::new(Mutex::new(board));
        let in_loop = Arc::clone(&board);
        let driver = Driver::Custom(Box::new(move |t: f64, inputs| {
            let now = Instant((t * 1e6).round() as u64 as u32);
            lock(&in_loop).tick(now, inputs)
        }));
        sc.faults = Plan::new(&args.fault).map_err(io::Error::other)?;
        let mut sim = Sim::new(sc, driver).map_err(|e| io::Error::other(e.to_string()))?;

        let listener = TcpListener::bind(args.listen)?;
        let addr = listener.local_addr()?;
        let (tx, rx) = mpsc::channel::<Msg>();
        let stop = Arc::new(AtomicBool::new(false));
        let r = sim.record(0.0);
        let truth = Arc::new(Mutex::new(Truth {
            t: 0.0,
            height: r.height,
            screw_speed: r.theta_dot,
            current: r.current,
            friction_torque: r.friction_torque,
        }));
        let streams = Arc::new(Mutex::new(HashMap::<u64, TcpStream>::new()));

        let speed = args.speed;
        let steps_per_ms = (1e-3 / args.dt).round().max(1.0) as u64;
        let sim_stop = Arc::clone(&stop);
        let sim_truth = Arc::clone(&truth);
        let sim = thread::Builder::new()
            .name("host-sim board".into())
            .spawn(move || {
                run_board(
                    &mut sim,
                    &board,
                    &rx,
                    &sim_stop,
                    &sim_truth,
                    speed,
                    steps_per_ms,
                )
            })?;

        let acc_stop = Arc::clone(&stop);
        let acc_tx = tx.clone();
        let acc_streams = Arc::clone(&streams);
        let accept = thread::Builder::new()
            .name("host-sim console".into())
            .spawn(move || {
                for (id, conn) in (0u64..).zip(listener.incoming()) {
                    if acc_stop.load(Ordering::SeqCst) {
                        break;
                    }
                    let Ok(stream) = conn else { continue };
                    if let Ok(clone) = stream.try_clone() {
                        lock(&acc_streams).insert(id, clone);
                    }
                    let tx = acc_tx.clone();
                    let _ = stream.set_nodelay(true);
                    let mine = Arc::clone(&acc_streams);
                    let spawned = thread::Builder::new()
                        .name("host-sim connection".into())
                        .spawn(move || {
                            connection(stream, &tx);
                            // The client left: drop the clone (its descriptor) too.
                            lock(&mine).remove(&id);
                        });
                    if spawned.is_err() {
                        lock(&acc_streams).remove(&id);
                    }
                }
            })?;
        let fault_addr = match args.fault_listen {
            Some(a) => {
                let l = TcpListener::bind(a)?;
                let addr = l.local_addr()?;
                let tx = tx.clone();
                let stop = Arc::clone(&stop);
                thread::Builder::new()
                    .name("host-sim faults".into())
                    .spawn(move || {
                        for conn in l.incoming() {
                            if stop.load(Ordering::SeqCst) {
                                break;
                            }
                            let Ok(s) = conn else { continue };
                            let tx = tx.clone();
                            let _ = thread::Builder::new()
                                .name("host-sim fault client".into())
                                .spawn(move || fault_client(s, &tx));
                        }
                    })?;
                Some(addr)
            }
            None => None,
        };
        #[cfg(unix)]
        let pty = if args.pty {
            let (p, master) = pty::Pty::open()?;
            let tx = tx.clone();
            thread::Builder::new()
                .name("host-sim pty".into())
                .spawn(move || connection(master, &tx))?;
            Some(p)
        } else {
            None
        };
        #[cfg(not(unix))]
        if args.pty {
            return Err(io::Error::other("--pty needs a Unix system"));
        }
        Ok(Server {
            addr,
            tx,
            stop,
            truth,
            streams,
            sim: Some(sim),
            accept: Some(accept),
            boot,
            fault_addr,
            #[cfg(unix)]
            pty,
        })
    }

    /// Where the fault side channel listens (`--fault-listen`).
    pub fn fault_addr(&self) -> Option<SocketAddr> {
        self.fault_addr
    }

    /// Inject a fault `f.at` simulated seconds from now (what the side channel does).
    pub fn inject(&self, f: Injection) -> io::Result<String> {
        let (tx, rx) = mpsc::channel();
        self.tx
            .send(Msg::Inject(f, tx))
            .map_err(|_| io::Error::other("the simulation has stopped"))?;
        rx.recv()
            .map_err(|_| io::Error::other("the simulation has stopped"))
    }

    /// The pseudo-terminal's path (`--pty`), e.g. `/dev/pts/3`.
    pub fn pty_path(&self) -> Option<&Path> {
        #[cfg(unix)]
        return self.pty.as_ref().map(|p| p.path.as_path());
        #[cfg(not(unix))]
        None
    }

    /// The address the console listens on.
    pub fn addr(&self) -> SocketAddr {
        self.addr
    }

    /// What the first boot said about the stored configuration.
    pub fn boot_message(&self) -> &str {
        &self.boot
    }

    /// The plant's ground truth, refreshed every simulated millisecond.
    pub fn truth(&self) -> Truth {
        *lock(&self.truth)
    }

    /// Power off and on: the controller reboots from what the flash holds. Returns the boot
    /// message (where the configuration came from).
    pub fn power_cycle(&self) -> io::Result<String> {
        let (tx, rx) = mpsc::channel();
        self.tx
            .send(Msg::PowerCycle(tx))
            .map_err(|_| io::Error::other("the simulation has stopped"))?;
        rx.recv()
            .map_err(|_| io::Error::other("the simulation has stopped"))
    }

    /// Serve until the process ends.
    pub fn wait(mut self) {
        if let Some(h) = self.sim.take() {
            let _ = h.join();
        }
    }

    /// Stop the simulation and close every connection.
    pub fn shutdown(mut self) {
        self.stop_all();
    }

    fn stop_all(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        // Wake the accept loops.
        let _ = TcpStream::connect(self.addr);
        if let Some(a) = self.fault_addr {
            let _ = TcpStream::connect(a);
        }
        for (_, s) in lock(&self.streams).drain() {
            let _ = s.shutdown(Shutdown::Both);
        }
        for h in [self.sim.take(), self.accept.take()].into_iter().flatten() {
            let _ = h.join();
        }
        // The pty's reader blocks in read(2): a line sent from the slave side wakes it, and it
        // ends when it finds the simulation gone.
        #[cfg(unix)]
        if let Some(p) = self.pty.take() {
            p.wake();
        }
    }
}

impl Drop for Server {
    fn drop(&mut self) {
        if self.sim.is_some() || self.accept.is_some() {
            self.stop_all();
        }
    }
}

/// The simulation thread: step the plant a millisecond at a time, serve the console between
/// steps, keep pace with the wall clock.
fn run_board(
    sim: &mut Sim,
    board: &Mutex<Board>,
    rx: &Receiver<Msg>,
    stop: &AtomicBool,
    truth: &Mutex<Truth>,
    speed: f64,
    steps_per_ms: u64,
) {
    let wall = WallClock::now();
    while !stop.load(Ordering::SeqCst) {
        let t = sim.step_n(steps_per_ms);
        if sim.take_watchdog_reset() {
            // An injected hang outlasted the IWDG: the board reboots, fault latched.
            let mut b = lock(board);
            match b.power_cycle() {
                Ok(msg) => eprintln!("host-sim serve: watchdog reset at {t:.3} s; {msg}"),
                Err(e) => eprintln!("host-sim serve: watchdog reset failed: {e}"),
            }
            b.controller
                .report_watchdog_reset(Instant((t * 1e6).round() as u64 as u32));
        }
        let r = sim.record(t);
        *lock(truth) = Truth {
            t,
            height: r.height,
            screw_speed: r.theta_dot,
            current: r.current,
            friction_torque: r.friction_torque,
        };
        while let Ok(msg) = rx.try_recv() {
            match msg {
                Msg::Feed(line, reply) => {
                    let out = lock(board).line(line.as_deref());
                    let _ = reply.send(out);
                }
                Msg::Inject(mut f, reply) => {
                    f.at += t;
                    let out = match sim.inject(f) {
                        Ok(()) => format!("ok: {f} (simulated time now {t:.3} s)"),
                        Err(e) => format!("error: {e}"),
                    };
                    let _ = reply.send(out);
                }
                Msg::PowerCycle(reply) => {
                    let out = lock(board)
                        .power_cycle()
                        .unwrap_or_else(|e| format!("error: power cycle failed: {e}"));
                    let _ = reply.send(out);
                }
            }
        }
        if speed > 0.0 {
            let ahead = t / speed - wall.elapsed().as_secs_f64();
            if ahead > 0.002 {
                thread::sleep(Duration::from_secs_f64(ahead));
            }
        }
    }
}

/// One TCP client: bytes → lines (the core's `LineBuffer`) → the board → reply + CRLF.
fn connection(mut stream: impl Read + Write, tx: &Sender<Msg>) {
    let mut lb = LineBuffer::new();
    let mut buf = [0u8; 512];
    loop {
        let n = match stream.read(&mut buf) {
            Ok(0) | Err(_) => return,
            Ok(n) => n,
        };
        for &b in &buf[..n] {
            let line = match lb.feed(b) {
                Feed::Pending => continue,
                Feed::Line(l) => Some(l.to_vec()),
                Feed::Overflow => None,
            };
            let (rtx, rrx) = mpsc::channel();
            if tx.send(Msg::Feed(line, rtx)).is_err() {
                return;
            }
            let Ok(reply) = rrx.recv() else { return };
            if reply.is_empty() {
                continue;
            }
            let text = format!("{reply}\r\n");
            if stream.write_all(text.as_bytes()).is_err() {
                return;
            }
        }
    }
}

/// One client of the fault side channel: a fault per line, `ok: …` or `error: …` back.
fn fault_client(stream: TcpStream, tx: &Sender<Msg>) {
    let Ok(mut w) = stream.try_clone() else {
        return;
    };
    let mut r = io::BufReader::new(stream);
    let mut line = String::new();
    loop {
        line.clear();
        match io::BufRead::read_line(&mut r, &mut line) {
            Ok(0) | Err(_) => return,
            Ok(_) => {}
        }
        let text = line.trim();
        if text.is_empty() {
            continue;
        }
        let reply = match text.parse::<Injection>() {
            Ok(f) => {
                let (rtx, rrx) = mpsc::channel();
                if tx.send(Msg::Inject(f, rtx)).is_err() {
                    return;
                }
                rrx.recv()
                    .unwrap_or_else(|_| "error: the simulation has stopped".into())
            }
            Err(e) => format!("error: {e}"),
        };
        if w.write_all(format!("{reply}\r\n").as_bytes()).is_err() {
            return;
        }
    }
}

/// `host-sim serve`: boot, print where the console listens, serve until killed.
pub fn main(args: &ServeArgs) -> Result<(), Box<dyn std::error::Error>> {
    let server = Server::start(args)?;
    println!("host-sim serve: {}", server.boot_message());
    println!(
        "host-sim serve: console on tcp://{} ({}; Ctrl-C stops; {})",
        server.addr(),
        if args.speed > 0.0 {
            format!("{}x real time", args.speed)
        } else {
            "as fast as possible".to_string()
        },
        match &args.flash {
            Some(p) => format!("flash image {}", p.display()),
            None => "flash kept in memory only".to_string(),
        }
    );
    if let Some(a) = server.fault_addr() {
        println!(
            "host-sim serve: fault side channel on tcp://{a} (one KIND@DELAY[:SIZE][+DURATION] per \
             line, e.g. `echo encoder-loss@0.5 | nc {} {}`)",
            a.ip(),
            a.port()
        );
    }
    if let Some(p) = server.pty_path() {
        println!(
            "host-sim serve: console also on the pseudo-terminal {} (liftctl -p {})",
            p.display(),
            p.display()
        );
    }
    server.wait();
    Ok(())
}

/// A pseudo-terminal pair: the board reads and writes the master, programs open the slave's
/// path as a serial port.
#[cfg(unix)]
mod pty {
    use std::fs::File;
    use std::io::{self, Write};
    use std::os::fd::{FromRawFd, OwnedFd};
    use std::path::PathBuf;

    /// The slave side, kept open so the terminal does not hang up between programs.
    pub struct Pty {
        /// `/dev/pts/N`.
        pub path: PathBuf,
        slave: File,
    }

    impl Pty {
        /// Open a pair in raw mode (no echo, no line editing, no CR/NL translation): the master
        /// for the board, the slave kept here.
        pub fn open() -> io::Result<(Pty, File)> {
            let mut master: libc::c_int = -1;
            let mut slave: libc::c_int = -1;
            // SAFETY: openpty writes two descriptors into the given ints; the name, termios and
            // window-size pointers may be null.
            let rc = unsafe {
                libc::openpty(
                    &mut master,
                    &mut slave,
                    std::ptr::null_mut(),
                    std::ptr::null(),
                    std::ptr::null(),
                )
            };
            if rc != 0 {
                return Err(io::Error::last_os_error());
            }
            // SAFETY: both descriptors were just opened by openpty and are owned by nobody else.
            let (master, slave) =
                unsafe { (OwnedFd::from_raw_fd(master), OwnedFd::from_raw_fd(slave)) };
            use std::os::fd::AsRawFd;
            // SAFETY: termios is plain data; tcgetattr fills it, cfmakeraw edits it, tcsetattr
            // reads it; the descriptor is valid for the calls.
            unsafe {
                let mut t: libc::termios = std::mem::zeroed();
                if libc::tcgetattr(slave.as_raw_fd(), &mut t) != 0 {
                    return Err(io::Error::last_os_error());
                }
                libc::cfmakeraw(&mut t);
                if libc::tcsetattr(slave.as_raw_fd(), libc::TCSANOW, &t) != 0 {
                    return Err(io::Error::last_os_error());
                }
            }
            let path = std::fs::read_link(format!("/proc/self/fd/{}", slave.as_raw_fd())).or_else(
                |_| {
                    let mut buf = [0 as libc::c_char; 128];
                    // SAFETY: ttyname_r writes at most buf.len() bytes, NUL-terminated on success.
                    let rc =
                        unsafe { libc::ttyname_r(slave.as_raw_fd(), buf.as_mut_ptr(), buf.len()) };
                    if rc != 0 {
                        return Err(io::Error::from_raw_os_error(rc));
                    }
                    // SAFETY: NUL-terminated by ttyname_r.
                    let name = unsafe { std::ffi::CStr::from_ptr(buf.as_ptr()) };
                    Ok(PathBuf::from(name.to_string_lossy().into_owned()))
                },
            )?;
            Ok((
                Pty {
                    path,
                    slave: File::from(slave),
                },
                File::from(master),
            ))
        }

        /// Send an empty line from the slave side (wakes the master's reader).
        pub fn wake(mut self) {
            let _ = self.slave.write_all(b"\n");
        }
    }
}
