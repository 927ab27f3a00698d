//! liftctl against what a hostile user tried: control characters in arguments and files,
//! exit codes, import oddities and replies that only look right. The simulated board (`host-sim
//! serve`, in process) and fake boards on loopback TCP.
#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)]

mod support;

use std::net::SocketAddr;
use std::process::Command;
use support::{board, liftctl, Seen};

fn temp(name: &str) -> std::path::PathBuf {
    support::temp("harden", name)
}

/// A fake board: `answer` replies to each line (its `version` first).
fn fake(mut answer: impl FnMut(&str) -> String + Send + 'static) -> (SocketAddr, Seen) {
    let version = format!(
        "liftfw console v{} firmware=0.1.0 schema={:08x}",
        liftfw::console::service::PROTOCOL_VERSION,
        liftfw::config::record::schema()
    );
    support::fake(move |line| {
        let line = String::from_utf8_lossy(line);
        Some(if line == "version" {
            version.clone().into_bytes()
        } else if line.is_empty() {
            Vec::new()
        } else {
            answer(&line).into_bytes()
        })
    })
}

#[test]
fn control_characters_are_refused_in_every_argument_and_file_value() {
    let server = board();
    let a = server.addr();
    let before = liftctl(a, &["config", "get", "sense.current_ua_per_code"]).out;
    for args in [
        &["config", "set", "sense.current_ua_per_code", "32\rmA"][..],
        &["config", "get", "limits.upper\rgoto 200mm"],
        &["config", "set", "limits.upper", "300mm\nsave"],
        // (A NUL cannot be an argument at all: the OS refuses it.)
        &["goto", "300mm\u{7}"],
        &["limits", "set", "--upper", "300\u{1b}mm"],
    ] {
        let r = liftctl(a, args);
        assert_eq!(r.code, 1, "{args:?}: {}{}", r.out, r.err);
        assert!(
            r.err.contains("control character") && r.err.contains("nothing was sent"),
            "{args:?}: {}",
            r.err
        );
    }
    let f = temp("cr.toml");
    std::fs::write(&f, "[sense]\ncurrent_ua_per_code = \"32\\rmA\"\n").unwrap();
    let r = liftctl(a, &["config", "import", f.to_str().unwrap()]);
    assert_eq!(r.code, 1, "{}", r.err);
    assert!(r.err.contains("control character"), "{}", r.err);
    // Nothing changed, and the lift did not move.
    assert_eq!(
        liftctl(a, &["config", "get", "sense.current_ua_per_code"]).out,
        before
    );
    let s = liftctl(a, &["status", "--raw"]).out;
    assert!(s.starts_with("state=idle "), "{s}");
    server.shutdown();
}

#[test]
fn exit_codes_are_the_readmes() {
    let server = board();
    let a = server.addr();
    // Argument errors: 3 (clap's own code, 2, means "no or bad reply" here).
    for args in [
        &["frobnicate"][..],
        &["goto"],
        &["--timeout", "abc", "status"],
    ] {
        let r = liftctl(a, args);
        assert_eq!(r.code, 3, "{args:?}: {}", r.err);
    }
    assert_eq!(liftctl(a, &["--help"]).code, 0);
    // Timeouts that are no timeout: a local problem, said plainly.
    for t in ["0", "1e30", "-1", "NaN", "inf"] {
        let r = liftctl(a, &[&format!("--timeout={t}"), "status"]);
        assert_eq!(r.code, 3, "--timeout {t}: {}", r.err);
        assert!(r.err.contains("--timeout"), "{}", r.err);
    }
    // A value `config set` refuses (1) is refused alike by `config import`.
    let r = liftctl(a, &["config", "set", "protect.overcurrent", "80A"]);
    assert_eq!(r.code, 1, "{}", r.err);
    let f = temp("over.toml");
    std::fs::write(&f, "[protect]\novercurrent = \"80 A\"\n").unwrap();
    let r = liftctl(a, &["config", "import", f.to_str().unwrap()]);
    assert_eq!(r.code, 1, "{}", r.err);
    // A file that is no settings file: local (3).
    std::fs::write(&f, "not toml [").unwrap();
    assert_eq!(
        liftctl(a, &["config", "import", f.to_str().unwrap()]).code,
        3
    );
    server.shutdown();
}

#[test]
fn import_refuses_duplicate_tables_and_applies_a_friction_preset() {
    let server = board();
    let a = server.addr();
    let f = temp("dup.toml");
    std::fs::write(
        &f,
        "[LIMITS]\nupper = \"400 mm\"\n[limits]\nupper = \"380 mm\"\n",
    )
    .unwrap();
    let r = liftctl(a, &["config", "import", f.to_str().unwrap()]);
    assert_eq!(r.code, 3, "{}", r.err);
    assert!(r.err.contains("given twice"), "{}", r.err);
    assert!(liftctl(a, &["config", "get", "limits.upper"])
        .out
        .contains("410 mm"));
    // The factory law is dry; a file naming the ptfe preset applies it.
    std::fs::write(&f, "[friction]\nlaw = \"ptfe\"\n").unwrap();
    let r = liftctl(a, &["config", "import", f.to_str().unwrap()]);
    assert_eq!(r.code, 0, "{}{}", r.out, r.err);
    assert!(!r.out.contains("already runs"), "{}", r.out);
    assert!(liftctl(a, &["config", "get", "friction.law"])
        .out
        .contains("ptfe"));
    // The preset beside explicit values of its table: which would win is unclear, refused.
    std::fs::write(&f, "[friction]\nlaw = \"dry\"\nbase = \"0.2\"\n").unwrap();
    assert_eq!(
        liftctl(a, &["config", "import", f.to_str().unwrap()]).code,
        3
    );
    server.shutdown();
}

#[test]
fn replies_that_only_look_right_are_garbled() {
    let (a, _) = fake(|line| match line {
        "status" => "state=idle height=nanmm speed=0.00rad/s current=0.00A T_r=0.000Nm \
                     stick_slip=no ss_amp=0.00Nm ss_episodes=0 fault=none homed=yes"
            .into(),
        _ => "ok: sure".into(),
    });
    for args in [&["status"][..], &["up"], &["stop"], &["config", "save"]] {
        let r = liftctl(a, args);
        assert_eq!(r.code, 2, "{args:?}: {}{}", r.out, r.err);
        assert!(r.err.contains("garbled reply"), "{args:?}: {}", r.err);
    }
}

#[test]
fn ctrl_c_ends_a_wait_for_a_reply_at_once() {
    // A board that never answers `up`; liftctl waits up to 30 s, Ctrl-C (SIGINT) after 0.3 s.
    let (a, _) = fake(|_| String::new());
    let (a2, _) = (a, ());
    let child = Command::new(env!("CARGO_BIN_EXE_liftctl"))
        .args(["--port", &format!("tcp://{a2}"), "--timeout", "30", "up"])
        .env_remove("LIFTCTL_PORT")
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    std::thread::sleep(std::time::Duration::from_millis(300));
    let t0 = std::time::Instant::now();
    let pid = child.id().to_string();
    let kill = Command::new("kill").args(["-INT", &pid]).status().unwrap();
    assert!(kill.success());
    let out = child.wait_with_output().unwrap();
    assert!(
        t0.elapsed() < std::time::Duration::from_secs(3),
        "took {:?}",
        t0.elapsed()
    );
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("interrupted (Ctrl-C)"));
}

/// The default firmware is the lead-screw image: it refuses every `ballscrew.*` key, which
/// this liftctl (built with them) knows. A board that does: the simulated board behind a proxy
/// answering those keys as the lead-screw image does
/// (`liftfw::config::settings::unknown_key_template`). `limits set` and `config set` failed
/// on it (`get ballscrew.r_m` refused while reading the board's settings); fwsim's end-to-end
/// test against the real image found it.
#[test]
fn the_lead_screw_image_has_no_ball_screw_keys_and_liftctl_still_changes_the_rest() {
    use std::io::{BufRead, BufReader, Write};
    use std::time::Duration;
    let server = board();
    let upstream = std::net::TcpStream::connect(server.addr()).unwrap();
    upstream
        .set_read_timeout(Some(Duration::from_millis(300)))
        .unwrap();
    let mut reader = BufReader::new(upstream.try_clone().unwrap());
    // The greeting on connect.
    let mut line = String::new();
    while reader.read_line(&mut line).is_ok_and(|n| n > 0) {
        line.clear();
    }
    upstream
        .set_read_timeout(Some(Duration::from_secs(10)))
        .unwrap();
    let mut up = upstream;
    let (addr, seen) = support::fake(move |l| {
        let l = String::from_utf8_lossy(l).to_string();
        if l.is_empty() {
            return Some(Vec::new());
        }
        let key = l.split_whitespace().nth(1).unwrap_or("");
        if (l.starts_with("get ") || l.starts_with("set ")) && key.starts_with("ballscrew.") {
            return Some(
                format!(
                    "error: '{key}' needs the ball-screw firmware (this is the lead-screw \
                     image); `help keys` lists them"
                )
                .into_bytes(),
            );
        }
        up.write_all(format!("{l}\r\n").as_bytes()).unwrap();
        let mut reply = String::new();
        reader.read_line(&mut reply).unwrap();
        Some(reply.trim_end().as_bytes().to_vec())
    });
    let r = liftctl(addr, &["limits", "set", "--upper", "390mm"]);
    assert_eq!(r.code, 0, "{}{}", r.out, r.err);
    let r = liftctl(addr, &["config", "get", "limits.upper"]);
    assert!(r.out.contains("390"), "{}{}", r.out, r.err);
    // A ball-screw value: refused here, nothing sent.
    let before = seen.lock().unwrap().len();
    let r = liftctl(addr, &["config", "set", "ballscrew.balls", "40"]);
    assert_eq!(r.code, 1, "{}{}", r.out, r.err);
    assert!(
        r.err.contains("needs the ball-screw firmware") && r.err.contains("nothing was changed"),
        "{}",
        r.err
    );
    assert!(!seen.lock().unwrap()[before..]
        .iter()
        .any(|l| l.starts_with("set ")));
    // The export has no ball-screw table, and imports back.
    let f = temp("lead.toml");
    let r = liftctl(addr, &["config", "export", f.to_str().unwrap()]);
    assert_eq!(r.code, 0, "{}{}", r.out, r.err);
    let text = std::fs::read_to_string(&f).unwrap();
    assert!(!text.contains("ballscrew"), "{text}");
    assert!(text.contains("upper"), "{text}");
    let r = liftctl(addr, &["config", "import", f.to_str().unwrap()]);
    assert_eq!(r.code, 0, "{}{}", r.out, r.err);
}
