//! `liftctl`: the command line.

use clap::{Args, Parser, Subcommand};
use liftctl::board::{self, Board, Error};
use liftctl::settings::{self, Change, Mirror};
use liftctl::watch::{self, WatchOptions};
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Duration;

#[derive(Parser, Debug)]
#[command(
    name = "liftctl",
    version,
    about = "Set a liftfw lift's limit stops and settings and watch it, over its console",
    long_about = "Set a liftfw lift's limit stops and settings and watch it, over the board's \
console (USB serial, 115200 8N1) or host-sim's simulated board (tcp://127.0.0.1:5151).\n\n\
Every change is checked here with the firmware's own rules first, then by the board; the \
board's error messages are shown unchanged. Changes run until the lift is switched off; \
`liftctl config save` (or --save) stores them in the board's flash.",
    after_help = "Examples:\n  liftctl -p /dev/ttyUSB0 status\n  liftctl -p tcp://127.0.0.1:5151 limits\n  \
liftctl limits set --upper 400mm --lower 150mm --save\n  liftctl goto 380mm && liftctl watch --until-rest\n  \
liftctl limits set --upper here\n  liftctl config export lift.toml\n  liftctl watch --csv run.csv --plot run.png"
)]
struct Cli {
    /// The board: a serial port (/dev/ttyUSB0, COM3) or tcp://HOST:PORT (host-sim serve).
    #[arg(
        short,
        long,
        env = "LIFTCTL_PORT",
        default_value = "/dev/ttyUSB0",
        global = true
    )]
    port: String,
    /// Serial baud rate.
    #[arg(long, default_value_t = 115_200, global = true)]
    baud: u32,
    /// Seconds to wait for each reply.
    #[arg(long, default_value_t = 2.0, global = true)]
    timeout: f64,
    #[command(subcommand)]
    command: Cmd,
}

#[derive(Subcommand, Debug)]
enum Cmd {
    /// State, height, speed, current, friction torque, stick-slip, fault.
    Status {
        /// Print the board's line as it came.
        #[arg(long)]
        raw: bool,
    },
    /// Show the limit stops (and the mechanism's range), or set them.
    Limits {
        #[command(subcommand)]
        set: Option<LimitsCmd>,
    },
    /// Read, change, store, export or import settings.
    #[command(subcommand)]
    Config(ConfigCmd),
    /// Show the active or last fault, or clear it.
    Fault {
        #[command(subcommand)]
        clear: Option<FaultCmd>,
    },
    /// Lift to the upper limit stop.
    Up,
    /// Lower to the lower limit stop.
    Down,
    /// Stop.
    Stop,
    /// Drive the head to a height, e.g. 300mm.
    Goto {
        /// Height with unit (mm, cm, m).
        height: String,
    },
    /// Live status; optional CSV log and PNG plot.
    Watch(WatchArgs),
    /// The board's console protocol, firmware version and settings schema.
    Version,
}

#[derive(Subcommand, Debug)]
enum LimitsCmd {
    /// Set one or both stops: a height (450mm, 0.45m) or `here` (the current height).
    Set {
        /// Upper stop.
        #[arg(long)]
        upper: Option<String>,
        /// Lower stop.
        #[arg(long)]
        lower: Option<String>,
        /// Store the settings in flash afterwards.
        #[arg(long)]
        save: bool,
    },
}

#[derive(Subcommand, Debug)]
enum ConfigCmd {
    /// Show settings (all if no key is given).
    Get {
        /// Keys, e.g. limits.upper motion.cruise_speed.
        keys: Vec<String>,
    },
    /// Change settings: KEY VALUE [KEY VALUE ...], e.g. motion.ramp_ms 400ms.
    Set {
        /// Key and value pairs.
        #[arg(num_args = 2.., value_names = ["KEY", "VALUE"])]
        pairs: Vec<String>,
        /// Store the settings in flash afterwards.
        #[arg(long)]
        save: bool,
    },
    /// Describe settings: key, meaning, unit and range (all if no key is given). Needs no
    /// board: the firmware's own registry, with the help lines the board leaves out.
    Keys {
        /// Keys, e.g. limits.upper motion.cruise_speed.
        keys: Vec<String>,
    },
    /// Store the running settings in the board's flash.
    Save,
    /// Write the running settings as TOML (to stdout without FILE).
    Export {
        /// Output file.
        file: Option<PathBuf>,
    },
    /// Apply the settings of a TOML file (as `export` writes it).
    Import {
        /// Input file.
        file: PathBuf,
        /// Store the settings in flash afterwards.
        #[arg(long)]
        save: bool,
    },
}

#[derive(Subcommand, Debug)]
enum FaultCmd {
    /// Clear a latched fault.
    Clear,
}

#[derive(Args, Debug)]
struct WatchArgs {
    /// Seconds between samples.
    #[arg(long, default_value_t = 0.2)]
    interval: f64,
    /// Stop after this many seconds (default: until Ctrl-C).
    #[arg(long)]
    duration: Option<f64>,
    /// Stop once the lift is at rest (at once if it already is).
    #[arg(long)]
    until_rest: bool,
    /// Log every sample to this CSV file.
    #[arg(long)]
    csv: Option<PathBuf>,
    /// At the end, plot height, speed, current and friction torque to this PNG.
    #[arg(long)]
    plot: Option<PathBuf>,
    /// Do not print samples.
    #[arg(long, short)]
    quiet: bool,
}

/// `s` seconds for an option that takes `min`…[`board::MAX_TIMEOUT_S`] (`min` itself
/// allowed only when it is 0).
fn secs(s: f64, what: &str, min: f64) -> Result<Duration, Error> {
    let ok = s.is_finite() && s <= board::MAX_TIMEOUT_S && (s > min || (s == 0.0 && min == 0.0));
    match Duration::try_from_secs_f64(s) {
        Ok(d) if ok => Ok(d),
        _ => Err(Error::Local(format!(
            "{what} {s}: give seconds {} {min} and at most {}",
            if min == 0.0 { "from" } else { "above" },
            board::MAX_TIMEOUT_S
        ))),
    }
}

/// Every argument that may reach the board, refused whole if it has a control character
/// (before anything is sent: `board::check_text`).
fn check_args(cmd: &Cmd) -> Result<(), Error> {
    let mut texts: Vec<(&str, &String)> = Vec::new();
    match cmd {
        Cmd::Limits {
            set: Some(LimitsCmd::Set { upper, lower, .. }),
        } => {
            texts.extend(upper.iter().map(|v| ("--upper", v)));
            texts.extend(lower.iter().map(|v| ("--lower", v)));
        }
        Cmd::Config(ConfigCmd::Get { keys } | ConfigCmd::Keys { keys }) => {
            texts.extend(keys.iter().map(|k| ("key", k)));
        }
        Cmd::Config(ConfigCmd::Set { pairs, .. }) => {
            texts.extend(pairs.iter().map(|p| ("argument", p)));
        }
        Cmd::Goto { height } => texts.push(("height", height)),
        _ => {}
    }
    texts
        .into_iter()
        .try_for_each(|(what, t)| board::check_text(what, t))
}

/// `key value` lines of a `key=value` reply.
fn print_words(line: &str) {
    for w in line.split_whitespace() {
        match w.split_once('=') {
            Some((k, v)) => println!("{k:<13}{v}"),
            None => println!("{w}"),
        }
    }
}

fn save(b: &mut Board) -> Result<(), Error> {
    println!("{}", b.ask_ok("save")?);
    Ok(())
}

fn apply(b: &mut Board, changes: &[Change], save_after: bool) -> Result<(), Error> {
    let done = settings::apply(b, changes)?;
    if done.is_empty() {
        println!("nothing to change: the board already runs with these values");
    }
    for d in &done {
        println!("ok: {d}");
    }
    if save_after {
        save(b)?;
    } else if !done.is_empty() {
        println!("not saved yet: `liftctl config save` stores the settings in flash");
    }
    Ok(())
}

/// `liftctl config keys`: the registry's description of each key, as the console's
/// `help <key>` words it.
fn print_keys(keys: &[String]) -> Result<(), Error> {
    let ids = if keys.is_empty() {
        liftfw::config::settings::all().collect()
    } else {
        keys.iter()
            .map(|k| {
                liftfw::config::settings::find(k).ok_or_else(|| {
                    Error::Local(format!(
                        "unknown key '{k}'; `liftctl config keys` lists them"
                    ))
                })
            })
            .collect::<Result<Vec<_>, _>>()?
    };
    for id in ids {
        let mut line = String::new();
        liftfw::console::write_key_help(&mut line, id)
            .map_err(|_| Error::Local("formatting failed".into()))?;
        println!("{line}");
    }
    Ok(())
}

fn run(cli: &Cli, stop: &Arc<AtomicBool>) -> Result<(), Error> {
    if let Cmd::Config(ConfigCmd::Keys { keys }) = &cli.command {
        return print_keys(keys);
    }
    check_args(&cli.command)?;
    let timeout = secs(cli.timeout, "--timeout", 0.0)?;
    if timeout.is_zero() {
        return Err(Error::Local(
            "--timeout 0: give the seconds to wait for each reply (above 0)".into(),
        ));
    }
    // Ctrl-C ends a wait for a reply at once (`watch` ends cleanly with it).
    let mut b = board::open(&cli.port, cli.baud, timeout, Some(Arc::clone(stop)))?;
    match &cli.command {
        Cmd::Version => {
            println!("{}", b.version.line);
            match b.check_schema() {
                Ok(()) => println!("settings schema matches this liftctl"),
                Err(e) => println!("{e}"),
            }
        }
        Cmd::Status { raw } => {
            let s = b.ask("status")?;
            if board::Status::parse(&s).is_none() {
                return Err(Error::Garbled {
                    sent: "status".into(),
                    got: s,
                });
            }
            if *raw {
                println!("{s}");
            } else {
                print_words(&s);
            }
        }
        Cmd::Limits { set: None } => println!("{}", b.limits()?),
        Cmd::Limits {
            set: Some(LimitsCmd::Set { upper, lower, save }),
        } => {
            if upper.is_none() && lower.is_none() {
                return Err(Error::Local(
                    "give --upper and/or --lower (a height such as 400mm, or `here`)".into(),
                ));
            }
            let mut here = None;
            let mut changes = Vec::new();
            for (key, v) in [("limits.upper", upper), ("limits.lower", lower)] {
                let Some(v) = v else { continue };
                let text = if v.eq_ignore_ascii_case("here") {
                    let h = match here {
                        Some(h) => h,
                        None => {
                            let s = b.status()?;
                            if !s.at_rest() {
                                return Err(Error::Local(
                                    "the lift is moving: `here` needs it at rest".into(),
                                ));
                            }
                            let Some(h) = s.height_mm else {
                                return Err(Error::Invalid(
                                    "liftctl: the board does not know the height (not homed): home it \
                                     on the lower limit switch first (hold DOWN or `liftctl \
                                     down`)"
                                        .into(),
                                ));
                            };
                            here = Some(h);
                            h
                        }
                    };
                    format!("{h:.1}mm")
                } else {
                    v.clone()
                };
                changes.push(settings::parse_change(key, &text)?);
            }
            apply(&mut b, &changes, *save)?;
            println!("{}", b.limits()?);
        }
        Cmd::Config(ConfigCmd::Get { keys }) => {
            if keys.is_empty() {
                for id in liftfw::config::settings::all() {
                    println!("{} = {}", id.key(), b.get(id.key())?);
                }
            } else {
                for k in keys {
                    println!("{k} = {}", b.get(k)?);
                }
            }
        }
        Cmd::Config(ConfigCmd::Set { pairs, save }) => {
            if pairs.len() % 2 != 0 {
                return Err(Error::Local(
                    "give KEY VALUE pairs, e.g. `liftctl config set motion.ramp_ms 400ms`".into(),
                ));
            }
            let changes = pairs
                .chunks(2)
                .map(|p| settings::parse_change(&p[0], &p[1]))
                .collect::<Result<Vec<_>, _>>()?;
            apply(&mut b, &changes, *save)?;
        }
        // Handled above, before the board is opened.
        Cmd::Config(ConfigCmd::Keys { keys }) => print_keys(keys)?,
        Cmd::Config(ConfigCmd::Save) => save(&mut b)?,
        Cmd::Config(ConfigCmd::Export { file }) => {
            b.check_schema()?;
            let m = Mirror::read(&mut b)?;
            let header = format!(
                "liftfw settings exported by liftctl {} from {}\n{}\n`liftctl config import FILE` applies them; values are text as `set` takes it",
                env!("CARGO_PKG_VERSION"),
                cli.port,
                b.version.line
            );
            let text = settings::export_toml(&m, &header);
            match file {
                Some(p) => {
                    std::fs::write(p, text)
                        .map_err(|e| Error::Local(format!("{}: {e}", p.display())))?;
                    println!("exported {} settings to {}", m.texts.len(), p.display());
                }
                None => print!("{text}"),
            }
        }
        Cmd::Config(ConfigCmd::Import { file, save }) => {
            let text = std::fs::read_to_string(file)
                .map_err(|e| Error::Local(format!("{}: {e}", file.display())))?;
            // A value the firmware refuses is refused (1) as `config set` refuses it; a file
            // that is no settings file is a local problem (3).
            let changes = settings::import_toml(&text).map_err(|e| match e {
                Error::Invalid(m) => {
                    Error::Invalid(format!("{}: {m}\nnothing was sent", file.display()))
                }
                e => Error::Local(format!("{}: {e}\nnothing was sent", file.display())),
            })?;
            apply(&mut b, &changes, *save)?;
        }
        Cmd::Fault { clear: None } => {
            let f = b.fault()?;
            for (k, v) in &f {
                println!("{k:<13}{v}");
            }
        }
        Cmd::Fault {
            clear: Some(FaultCmd::Clear),
        } => println!("{}", b.ask_ok("fault clear")?),
        Cmd::Up => println!("{}", b.ask_ok("up")?),
        Cmd::Down => println!("{}", b.ask_ok("down")?),
        Cmd::Stop => println!("{}", b.ask_ok("stop")?),
        Cmd::Goto { height } => {
            // Checked here first, with the firmware's parser.
            let line = format!("goto {height}");
            if let Err(e) = liftfw::console::parse(line.as_bytes()) {
                let mut s = String::new();
                let _ = liftfw::console::write_parse_error(&mut s, &e);
                return Err(Error::Invalid(s));
            }
            println!("{}", b.ask_ok(&line)?);
        }
        Cmd::Watch(w) => {
            let o = WatchOptions {
                interval: secs(w.interval, "--interval", 0.0)?,
                duration: w.duration.map(|d| secs(d, "--duration", 0.0)).transpose()?,
                until_rest: w.until_rest,
                print: !w.quiet,
                csv: w.csv.clone(),
                plot: w.plot.clone(),
            };
            let samples = watch::watch(&mut b, &o, stop)?;
            if let Some(p) = &o.csv {
                eprintln!("{} samples → {}", samples.len(), p.display());
            }
            if let Some(p) = &o.plot {
                eprintln!("plot → {}", p.display());
            }
        }
    }
    Ok(())
}

fn main() -> ExitCode {
    // Argument errors are a local problem (3), as the README says; clap's own code is 2,
    // which means "no or bad reply" here. `--help` and `--version` succeed.
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) => {
            let _ = e.print();
            return if e.use_stderr() {
                ExitCode::from(3)
            } else {
                ExitCode::SUCCESS
            };
        }
    };
    let stop = Arc::new(AtomicBool::new(false));
    let s = Arc::clone(&stop);
    let _ = ctrlc::set_handler(move || s.store(true, Ordering::SeqCst));
    match run(&cli, &stop) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("{}", e.report());
            ExitCode::from(e.exit_code())
        }
    }
}
