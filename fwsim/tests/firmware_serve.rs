//! `fwsim serve` end to end (what `host-sim serve --firmware` runs): the firmware's console on
//! TCP, its store's flash kept in a file, and a restart of the program as a power cycle.
//!
//! Needs the ELF: `FWSIM_ELF=path` (scripts/test-all runs it with `--ignored`).
#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// A running `fwsim serve` and a console connection to it.
struct Served {
    child: Option<Child>,
    console: TcpStream,
    /// Console text not yet consumed.
    pending: String,
}

impl Drop for Served {
    fn drop(&mut self) {
        if let Some(c) = self.child.as_mut() {
            let _ = c.kill();
            let _ = c.wait();
        }
    }
}

fn serve(flash: &std::path::Path) -> Served {
    let elf = std::env::var("FWSIM_ELF").expect("FWSIM_ELF must name the firmware ELF");
    let mut child = Command::new(env!("CARGO_BIN_EXE_fwsim"))
        .args([
            "serve",
            "--elf",
            &elf,
            "--listen",
            "127.0.0.1:0",
            "--speed",
            "0",
        ])
        .args(["--from-mm", "200", "--flash"])
        .arg(flash)
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    // "fwsim serve: ELF on the emulated STM32G431; console on tcp://ADDR (...)"
    let mut out = BufReader::new(child.stdout.take().unwrap());
    let mut line = String::new();
    out.read_line(&mut line).unwrap();
    // serve prints the console to stdout while no client is connected: keep reading it.
    std::thread::spawn(move || {
        let mut sink = String::new();
        while out.read_line(&mut sink).is_ok_and(|n| n > 0) {
            sink.clear();
        }
    });
    let addr = line
        .split("tcp://")
        .nth(1)
        .and_then(|r| r.split_whitespace().next())
        .unwrap_or_else(|| panic!("no address in {line:?}"))
        .to_string();
    let console = TcpStream::connect(&addr).unwrap();
    console
        .set_read_timeout(Some(Duration::from_millis(200)))
        .unwrap();
    Served {
        child: Some(child),
        console,
        pending: String::new(),
    }
}

impl Served {
    /// Sends `line` and returns the first console line after it for which `done` holds
    /// (within 20 s of wall time).
    fn command(&mut self, line: &str, done: impl Fn(&str) -> bool) -> String {
        self.console
            .write_all(format!("{line}\r\n").as_bytes())
            .unwrap();
        let end = Instant::now() + Duration::from_secs(20);
        let mut buf = [0u8; 512];
        while Instant::now() < end {
            while let Some(i) = self.pending.find("\r\n") {
                let l: String = self.pending.drain(..i + 2).collect();
                let l = l.trim_end();
                if done(l) {
                    return l.to_string();
                }
            }
            match self.console.read(&mut buf) {
                Ok(0) => panic!("the console closed"),
                Ok(n) => self.pending.push_str(&String::from_utf8_lossy(&buf[..n])),
                Err(e)
                    if matches!(
                        e.kind(),
                        std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
                    ) => {}
                Err(e) => panic!("console: {e}"),
            }
        }
        panic!("no reply to {line:?} (console: {:?})", self.pending)
    }
}

#[test]
#[ignore = "needs FWSIM_ELF"]
fn serve_keeps_the_store_in_its_flash_file_across_a_restart() {
    let flash = std::env::temp_dir().join(format!("fwsim-serve-test-{}.bin", std::process::id()));
    let _ = std::fs::remove_file(&flash);

    let mut s = serve(&flash);
    let version = s.command("version", |l| l.starts_with("liftfw console v"));
    println!("console: version → {version}");
    let reply = s.command("set limits.upper 390", |l| {
        l.starts_with("ok") || l.starts_with("error")
    });
    assert!(reply.starts_with("ok"), "{reply}");
    let reply = s.command("save", |l| l.starts_with("ok") || l.starts_with("error"));
    assert!(reply.starts_with("ok: saved"), "{reply}");
    // serve writes the store's pages to the file every 100 ms of emulated time.
    wait_for_store_file(&flash);
    // The program killed: the board loses its power.
    drop(s);

    let mut s = serve(&flash);
    let got = s.command("get limits.upper", |l| l.starts_with("limits.upper"));
    assert_eq!(got, "limits.upper = 390 mm");
    drop(s);
    let _ = std::fs::remove_file(&flash);
}

/// A program built beside `fwsim` (the workspace's target directory): host-sim, liftctl.
/// Until the flash file exists (at most 20 s), then 0.5 s more for the store's last pages.
fn wait_for_store_file(flash: &std::path::Path) {
    let end = Instant::now() + Duration::from_secs(20);
    while !flash.exists() && Instant::now() < end {
        std::thread::sleep(Duration::from_millis(50));
    }
    assert!(flash.exists(), "{} never written", flash.display());
    std::thread::sleep(Duration::from_millis(500));
}

fn sibling(name: &str) -> std::path::PathBuf {
    let p = std::path::Path::new(env!("CARGO_BIN_EXE_fwsim")).with_file_name(name);
    assert!(
        p.exists(),
        "{} missing: build it first (cargo build -p host-sim -p liftctl; test-all's workspace tests do)",
        p.display()
    );
    p
}

/// `host-sim serve --firmware ELF` in a process group of its own (host-sim runs fwsim as its
/// child: killing the group cuts the board's power); returns it and the console's address.
fn host_sim_serve(flash: &std::path::Path) -> (Child, String) {
    use std::os::unix::process::CommandExt;
    let elf = std::env::var("FWSIM_ELF").expect("FWSIM_ELF must name the firmware ELF");
    let mut child = Command::new(sibling("host-sim"))
        .args([
            "serve",
            "--firmware",
            &elf,
            "--listen",
            "127.0.0.1:0",
            "--speed",
            "0",
        ])
        .arg("--flash")
        .arg(flash)
        .stdout(Stdio::piped())
        .process_group(0)
        .spawn()
        .unwrap();
    let mut out = BufReader::new(child.stdout.take().unwrap());
    let mut line = String::new();
    let addr = loop {
        line.clear();
        assert!(
            out.read_line(&mut line).unwrap() > 0,
            "host-sim serve ended"
        );
        if let Some(rest) = line.split("tcp://").nth(1) {
            break rest.split_whitespace().next().unwrap().to_string();
        }
    };
    // The boot greeting goes to stdout while no client is connected; a client connecting in
    // the middle of it would read the rest of a line as a reply. Its last line (the lift is
    // not parked): "refused: position unknown; hold DOWN …".
    loop {
        line.clear();
        assert!(out.read_line(&mut line).unwrap() > 0, "no boot greeting");
        if line.contains("hold DOWN") {
            break;
        }
    }
    std::thread::spawn(move || {
        let mut sink = String::new();
        while out.read_line(&mut sink).is_ok_and(|n| n > 0) {
            sink.clear();
        }
    });
    (child, addr)
}

/// host-sim serve and its fwsim: killed together when dropped (the board's power cut).
struct Group((Child, String));

impl Drop for Group {
    fn drop(&mut self) {
        let child = &mut self.0 .0;
        let group = format!("-{}", child.id());
        let _ = Command::new("kill").args(["-KILL", "--", &group]).status();
        let _ = child.wait();
    }
}

fn liftctl(addr: &str, args: &[&str]) -> String {
    let out = Command::new(sibling("liftctl"))
        .arg("--port")
        .arg(format!("tcp://{addr}"))
        // The emulator shares the machine with the tests beside it: generous reply timeouts.
        .args(["--timeout", "10"])
        .args(args)
        .env_remove("LIFTCTL_PORT")
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(
        out.status.success(),
        "liftctl {args:?}: {text}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    text
}

#[test]
#[ignore = "needs FWSIM_ELF and the workspace's host-sim and liftctl"]
fn host_sim_serve_firmware_with_liftctl_keeps_the_stops_across_a_restart() {
    let flash =
        std::env::temp_dir().join(format!("fwsim-host-sim-test-{}.bin", std::process::id()));
    let _ = std::fs::remove_file(&flash);

    let board = Group(host_sim_serve(&flash));
    let addr = board.0 .1.clone();
    let version = liftctl(&addr, &["version"]);
    assert!(version.contains("firmware="), "{version}");
    liftctl(&addr, &["limits", "set", "--upper", "390mm", "--save"]);
    wait_for_store_file(&flash);
    drop(board);

    let board = Group(host_sim_serve(&flash));
    let addr = board.0 .1.clone();
    let limits = liftctl(&addr, &["limits"]);
    drop(board);
    let _ = std::fs::remove_file(&flash);
    println!("liftctl limits after the restart: {}", limits.trim());
    assert!(limits.contains("limits.upper = 390.0 mm"), "{limits}");
}
