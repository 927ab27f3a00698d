//! What liftctl's end-to-end tests share: the simulated board in process, the `liftctl` binary
//! run as a person runs it, and fake boards on loopback TCP.
#![allow(dead_code, clippy::unwrap_used, clippy::expect_used)]

use host_sim::apps::serve::{ServeArgs, Server};
use liftfw::console::{Feed, LineBuffer};
use std::io::{Read, Write};
use std::net::{SocketAddr, TcpListener};
use std::process::{Command, Output};
use std::sync::{Arc, Mutex};

/// `host-sim serve` in process, on a free loopback port, faster than real time.
pub fn board() -> Server {
    Server::start(&ServeArgs {
        listen: "127.0.0.1:0".parse().unwrap(),
        speed: 0.0,
        ..ServeArgs::default()
    })
    .unwrap()
}

/// How a `liftctl` run ended.
pub struct Run {
    pub code: i32,
    pub out: String,
    pub err: String,
}

/// `liftctl --port tcp://ADDR ARGS…`.
pub fn liftctl(addr: SocketAddr, args: &[&str]) -> Run {
    liftctl_on(&format!("tcp://{addr}"), args)
}

/// `liftctl --port PORT ARGS…`, without `LIFTCTL_PORT` from the environment.
pub fn liftctl_on(port: &str, args: &[&str]) -> Run {
    let Output {
        status,
        stdout,
        stderr,
    } = Command::new(env!("CARGO_BIN_EXE_liftctl"))
        .arg("--port")
        .arg(port)
        .args(args)
        .env_remove("LIFTCTL_PORT")
        .output()
        .unwrap();
    Run {
        code: status.code().unwrap_or(-1),
        out: String::from_utf8(stdout).unwrap(),
        err: String::from_utf8(stderr).unwrap(),
    }
}

/// A file in this test process's own temporary folder (`tag` tells the test files apart).
pub fn temp(tag: &str, name: &str) -> std::path::PathBuf {
    let d = std::env::temp_dir().join(format!("liftctl-{tag}-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d.join(name)
}

/// The lines a fake board received.
pub type Seen = Arc<Mutex<Vec<String>>>;

/// A board on loopback whose replies a closure decides (`None`: the reply is lost). Returns
/// its address and the lines it received.
pub fn fake(
    mut answer: impl FnMut(&[u8]) -> Option<Vec<u8>> + Send + 'static,
) -> (SocketAddr, Seen) {
    let l = TcpListener::bind("127.0.0.1:0").unwrap();
    let addr = l.local_addr().unwrap();
    let seen = Arc::new(Mutex::new(Vec::new()));
    let log = Arc::clone(&seen);
    std::thread::spawn(move || {
        for s in l.incoming() {
            let Ok(mut s) = s else { return };
            let mut lb = LineBuffer::new();
            let mut buf = [0u8; 256];
            while let Ok(n) = s.read(&mut buf) {
                if n == 0 {
                    break;
                }
                for &b in &buf[..n] {
                    if let Feed::Line(line) = lb.feed(b) {
                        log.lock()
                            .unwrap()
                            .push(String::from_utf8_lossy(line).to_string());
                        if let Some(mut r) = answer(line) {
                            if !r.is_empty() {
                                r.extend_from_slice(b"\r\n");
                                let _ = s.write_all(&r);
                            }
                        }
                    }
                }
            }
        }
    });
    (addr, seen)
}
