//! The simulated board's console for the `host-sim serve` tests: a TCP client that sends a line
//! and reads its one-line reply, and the serve arguments of a run faster than real time.
#![allow(dead_code, clippy::unwrap_used, clippy::expect_used)]

use host_sim::apps::serve::{ServeArgs, Server};
use std::io::{BufRead, BufReader, Write};
use std::net::TcpStream;
use std::time::{Duration, Instant};

/// One console connection.
pub struct Console {
    w: TcpStream,
    r: BufReader<TcpStream>,
}

impl Console {
    /// Connect to `server`'s console (replies time out after 20 s).
    pub fn open(server: &Server) -> Console {
        let w = TcpStream::connect(server.addr()).unwrap();
        w.set_read_timeout(Some(Duration::from_secs(20))).unwrap();
        let r = BufReader::new(w.try_clone().unwrap());
        Console { w, r }
    }

    /// Send raw bytes and read one reply line (without its CR LF).
    pub fn send(&mut self, bytes: &[u8]) -> String {
        self.w.write_all(bytes).unwrap();
        let mut s = String::new();
        self.r.read_line(&mut s).unwrap();
        assert!(s.ends_with("\r\n"), "{s:?}");
        s.trim_end().to_string()
    }

    /// Send `line` and read its reply.
    pub fn ask(&mut self, line: &str) -> String {
        self.send(format!("{line}\r\n").as_bytes())
    }

    /// Ask `status` until `pred` holds (at most 60 s of wall time).
    pub fn wait_status(&mut self, pred: impl Fn(&str) -> bool) -> String {
        let t0 = Instant::now();
        loop {
            let s = self.ask("status");
            if pred(&s) {
                return s;
            }
            assert!(t0.elapsed() < Duration::from_secs(60), "still {s}");
            std::thread::sleep(Duration::from_millis(20));
        }
    }
}

/// A simulated board on a free loopback port, as fast as the machine runs it.
pub fn fast() -> ServeArgs {
    ServeArgs {
        listen: "127.0.0.1:0".parse().unwrap(),
        speed: 0.0,
        ..ServeArgs::default()
    }
}
