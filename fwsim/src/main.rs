//! `fwsim`: the flashed firmware on an emulated STM32G431 against host-sim's plant
//! (docs/fwsim.md).

use clap::{Parser, Subcommand};
use fwsim::elf::Image;
use fwsim::flash::Store;
use fwsim::lift::{self, LiftArgs};
use fwsim::machine::Machine;
use fwsim::plant::Rig;
use host_sim::cli::Lube;
use host_sim::physics::Lubricant;
use std::io::{Read, Write};
use std::path::{Path, PathBuf};

#[derive(Parser)]
#[command(
    about = "Run the firmware ELF from scripts/fw-build on an emulated STM32G431 against host-sim's plant"
)]
struct Cli {
    #[command(subcommand)]
    cmd: Cmd,
}

#[derive(Subcommand)]
enum Cmd {
    /// Boot the firmware with the pins idle (no plant) and print its console and defmt log.
    Boot {
        /// The firmware ELF (scripts/fw-build's output).
        #[arg(long)]
        elf: PathBuf,
        /// Emulated seconds.
        #[arg(long, default_value_t = 0.2)]
        seconds: f64,
        /// Write every register access to this file.
        #[arg(long)]
        trace_mmio: Option<PathBuf>,
    },
    /// README's main job with the firmware in the loop: a loaded lift from one height to a set
    /// height, the firmware's status beside the plant's truth, then the halt error.
    Lift {
        /// The firmware ELF.
        #[arg(long)]
        elf: PathBuf,
        /// Thread lubrication of the plant (the firmware is set to the same law).
        #[arg(long, value_enum, default_value_t = Lube::Ptfe)]
        lubricant: Lube,
        /// Mass on the head, kg.
        #[arg(long, default_value_t = 1000.0)]
        load_kg: f64,
        /// Start height, mm (the lift is parked there).
        #[arg(long, default_value_t = 150.0)]
        from_mm: f64,
        /// Target height, mm.
        #[arg(long, default_value_t = 180.0)]
        to_mm: f64,
        /// Sensor-noise seed.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Show the firmware's defmt log.
        #[arg(long)]
        log: bool,
        /// Write every register access to this file.
        #[arg(long)]
        trace_mmio: Option<PathBuf>,
    },
    /// The board on a loopback TCP port: the firmware's console (liftctl -t ADDR), the plant
    /// moving, the store's flash kept in a file (a restart is a power cycle).
    Serve {
        /// The firmware ELF.
        #[arg(long)]
        elf: PathBuf,
        /// Address to listen on.
        #[arg(long, default_value = "127.0.0.1:5151")]
        listen: std::net::SocketAddr,
        /// Keep the configuration store's flash pages in this file.
        #[arg(long)]
        flash: Option<PathBuf>,
        /// Emulated seconds per wall-clock second; 0 runs as fast as it can.
        #[arg(long, default_value_t = 1.0)]
        speed: f64,
        /// Start height, mm.
        #[arg(long, default_value_t = 180.0)]
        from_mm: f64,
        /// Mass on the head, kg.
        #[arg(long, default_value_t = 1000.0)]
        load_kg: f64,
        /// Thread lubrication of the plant.
        #[arg(long, value_enum, default_value_t = Lube::Dry)]
        lubricant: Lube,
        /// Show the firmware's defmt log.
        #[arg(long)]
        log: bool,
        /// Write every register access to this file.
        #[arg(long)]
        trace_mmio: Option<PathBuf>,
    },
}

fn main() {
    let cli = Cli::parse();
    let r = match cli.cmd {
        Cmd::Boot {
            elf,
            seconds,
            trace_mmio,
        } => boot(&elf, seconds, trace_mmio.as_deref()),
        Cmd::Lift {
            elf,
            lubricant,
            load_kg,
            from_mm,
            to_mm,
            seed,
            log,
            trace_mmio,
        } => lift::main(
            &elf,
            &LiftArgs {
                lubricant: lubricant.into(),
                load_kg,
                from_mm,
                to_mm,
                seed,
                show_log: log,
            },
            trace_mmio.as_deref(),
        )
        .and_then(|o| {
            if o.error_mm.abs() <= 0.5 {
                Ok(())
            } else {
                Err(format!("halt error {:+.3} mm beyond ±0.5 mm", o.error_mm))
            }
        }),
        Cmd::Serve {
            elf,
            listen,
            flash,
            speed,
            from_mm,
            load_kg,
            lubricant,
            log,
            trace_mmio,
        } => serve(&ServeArgs {
            elf,
            listen,
            flash,
            speed,
            from_mm,
            load_kg,
            lubricant: lubricant.into(),
            log,
            trace: trace_mmio,
        }),
    };
    if let Err(e) = r {
        eprintln!("fwsim: {e}");
        std::process::exit(1);
    }
}

fn boot(elf: &Path, seconds: f64, trace: Option<&Path>) -> Result<(), String> {
    let image = Image::load(elf)?;
    let mut m = Machine::new(image, Store::default())?;
    if let Some(p) = trace {
        m.trace_to(p)?;
    }
    // Limit switches and STOP closed (inactive), buttons open; 0 A, 12.6 V.
    m.set_gpiob_inputs(1 << 10 | 1 << 11 | 1 << 5, 0);
    m.set_analog(fwsim::bus::Analog {
        r_is: 2048,
        l_is: 0,
        supply: 2818,
    });
    let end = (seconds * fwsim::TICK_HZ as f64) as u64;
    let step = fwsim::TICK_HZ / 1000;
    let wall = std::time::Instant::now();
    let mut r = Ok(());
    while m.now() < end {
        let t = (m.now() + step).min(end);
        r = m.run_until(t);
        for l in m.take_log() {
            println!("[defmt] {}", l.text);
        }
        let c = m.take_console();
        if !c.is_empty() {
            print!("{c}");
        }
        if r.is_err() {
            break;
        }
    }
    m.flush_trace();
    for f in &m.findings {
        println!("board check: {f}");
    }
    println!(
        "\n{:.3} s emulated in {:.3} s wall, {} instructions, {} resets",
        m.t(),
        wall.elapsed().as_secs_f64(),
        m.mcu.bus_ref().insns,
        m.resets.len()
    );
    r
}

struct ServeArgs {
    elf: PathBuf,
    listen: std::net::SocketAddr,
    flash: Option<PathBuf>,
    speed: f64,
    from_mm: f64,
    load_kg: f64,
    lubricant: Lubricant,
    log: bool,
    trace: Option<PathBuf>,
}

fn serve(a: &ServeArgs) -> Result<(), String> {
    let image = Image::load(&a.elf)?;
    let store = match &a.flash {
        Some(p) if p.exists() => {
            Store::from_file_bytes(&std::fs::read(p).map_err(|e| format!("{}: {e}", p.display()))?)?
        }
        _ => Store::default(),
    };
    let mut saved = store.clone();
    let mut machine = Machine::new(image, store)?;
    if let Some(p) = &a.trace {
        machine.trace_to(p)?;
    }
    let cfg = lift::plant_config(a.lubricant, a.load_kg, a.from_mm, 1)?;
    let mut rig = Rig::new(machine, cfg)?;
    let listener =
        std::net::TcpListener::bind(a.listen).map_err(|e| format!("{}: {e}", a.listen))?;
    listener.set_nonblocking(true).map_err(|e| e.to_string())?;
    println!(
        "fwsim serve: {} on the emulated STM32G431; console on tcp://{} (Ctrl-C stops; {})",
        a.elf.display(),
        listener.local_addr().map_err(|e| e.to_string())?,
        match &a.flash {
            Some(p) => format!("store flash in {}", p.display()),
            None => "store flash in memory only".into(),
        }
    );
    let _ = std::io::stdout().flush();
    let mut client: Option<std::net::TcpStream> = None;
    let wall = std::time::Instant::now();
    let t0 = rig.t;
    let mut buf = [0u8; 512];
    loop {
        if client.is_none() {
            if let Ok((s, _)) = listener.accept() {
                let _ = s.set_nonblocking(true);
                let _ = s.set_nodelay(true);
                client = Some(s);
            }
        }
        if let Some(s) = client.as_mut() {
            match s.read(&mut buf) {
                Ok(0) => client = None,
                Ok(n) => rig.machine.console_send(&buf[..n]),
                Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => {}
                Err(_) => client = None,
            }
        }
        rig.run_for(1e-3)?;
        let out = rig.machine.console_out.split_off(0);
        if !out.is_empty() {
            match client.as_mut() {
                Some(s) => {
                    if s.write_all(&out).is_err() {
                        client = None;
                    }
                }
                None => print!("{}", String::from_utf8_lossy(&out)),
            }
        }
        if a.log {
            for l in rig.machine.take_log() {
                println!("[defmt] {}", l.text);
            }
        } else {
            rig.machine.discard_log();
        }
        // The store's file follows the emulated flash (checked every 100 ms).
        if let Some(p) = &a.flash {
            if ((rig.t * 1e3).round() as u64).is_multiple_of(100) {
                let now = rig.machine.store();
                if now != saved {
                    std::fs::write(p, now.to_file_bytes())
                        .map_err(|e| format!("{}: {e}", p.display()))?;
                    saved = now;
                }
            }
        }
        if a.speed > 0.0 {
            let ahead = (rig.t - t0) / a.speed - wall.elapsed().as_secs_f64();
            if ahead > 0.002 {
                std::thread::sleep(std::time::Duration::from_secs_f64(ahead));
            }
        }
    }
}
