//! liftctl end to end, without hardware: the simulated board (`host-sim serve`, in process,
//! faster than real time) on loopback TCP, and the `liftctl` binary run against it as a person
//! would run it. Fake boards on loopback cover a lost reply, a garbled one and another
//! protocol version.
#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)]

mod support;

use host_sim::apps::serve::{ServeArgs, Server};
use liftfw::config::ValidatedConfig;
use liftfw::console::service;
use liftfw::control::Controller;
use std::net::SocketAddr;
use std::sync::{Arc, Mutex};
use support::{board, fake, liftctl, liftctl_on, Seen};

fn ok(addr: SocketAddr, args: &[&str]) -> String {
    let r = liftctl(addr, args);
    assert_eq!(
        r.code, 0,
        "liftctl {args:?}\nstdout: {}\nstderr: {}",
        r.out, r.err
    );
    r.out
}

fn temp(name: &str) -> std::path::PathBuf {
    support::temp("e2e", name)
}

#[test]
fn set_limits_save_power_cycle_read_back_and_stop_at_the_new_limit() {
    let server = board();
    let a = server.addr();
    assert!(ok(a, &["version"]).starts_with("liftfw console v2 firmware="));
    // Start ≈ 230 mm; a new upper stop 8 mm above, the lower one at 150 mm.
    let h0 = server.truth().height * 1e3;
    let upper = (h0 + 8.0).round();
    let upper_arg = format!("{upper}mm");
    let out = ok(
        a,
        &[
            "limits", "set", "--upper", &upper_arg, "--lower", "150mm", "--save",
        ],
    );
    assert!(out.contains("ok: saved as configuration #1"), "{out}");

    assert!(server
        .power_cycle()
        .unwrap()
        .starts_with("boot: configuration #1 loaded from flash; parked at "));
    let limits = ok(a, &["limits"]);
    assert!(
        limits.starts_with(&format!(
            "limits.lower = 150.0 mm, limits.upper = {upper:.1} mm,"
        )),
        "{limits}"
    );
    assert_eq!(
        ok(a, &["config", "get", "limits.upper"]).trim(),
        format!("limits.upper = {upper} mm")
    );

    // Drive up and watch it stop at the new stop.
    assert_eq!(ok(a, &["up"]).trim(), "ok: lifting to limits.upper");
    let csv = temp("watch.csv");
    let png = temp("watch.png");
    let w = liftctl(
        a,
        &[
            "watch",
            "--until-rest",
            "--interval",
            "0.05",
            "--duration",
            "60",
            "--csv",
            csv.to_str().unwrap(),
            "--plot",
            png.to_str().unwrap(),
        ],
    );
    let text = std::fs::read_to_string(&csv).unwrap();
    let rows: Vec<Vec<&str>> = text
        .lines()
        .skip(1)
        .map(|l| l.split(',').collect())
        .collect();
    assert!(rows.len() >= 3, "{text}");
    assert!(rows.iter().any(|r| r[1] == "lifting"), "{text}");
    let last = rows.last().unwrap();
    assert_eq!(last[1], "holding", "{text}");
    let top = rows
        .iter()
        .map(|r| r[2].parse::<f64>().unwrap())
        .fold(f64::MIN, f64::max);
    assert!(top <= upper + 1.0, "reported {top} mm, stop {upper} mm");
    let end: f64 = last[2].parse().unwrap();
    assert!(
        (end - upper).abs() < 1.0,
        "reported {end} mm, stop {upper} mm"
    );
    let truth = server.truth().height * 1e3;
    assert!(
        (truth - upper).abs() < 1.0,
        "true height {truth:.2} mm, stop {upper} mm"
    );
    // The plot needs a font; without one liftctl says so (the CSV is complete either way).
    match liftctl::watch::init_font() {
        Ok(_) => {
            assert_eq!(w.code, 0, "{}", w.err);
            let png_bytes = std::fs::read(&png).unwrap();
            assert_eq!(&png_bytes[1..4], b"PNG");
        }
        Err(_) => assert!(w.err.contains("no TrueType font"), "{}", w.err),
    }
    // Up again: already there.
    let r = liftctl(a, &["up"]);
    assert_eq!(
        (r.code, r.err.trim()),
        (
            1,
            "error: up refused: already at or beyond that limit; `goto` a height between the stops"
        )
    );
    server.shutdown();
}

#[test]
fn refused_changes_show_the_firmware_message_and_change_nothing() {
    let server = board();
    let a = server.addr();
    let before = ok(a, &["config", "export"]);
    // Outside this mechanism: refused on the PC with the firmware's words, nothing sent.
    let r = liftctl(
        a,
        &["limits", "set", "--upper", "450mm", "--lower", "120mm"],
    );
    assert_eq!(r.code, 1, "{}", r.err);
    assert_eq!(
        r.err.trim(),
        "error: set limits.lower refused: limits.lower out of range (allowed the mechanism's \
         height range (see `limits`)); mechanism 133.5..416.4 mm"
    );
    let r = liftctl(a, &["config", "set", "motion.ramp_ms", "20.5ms"]);
    assert_eq!(
        (r.code, r.err.trim()),
        (
            1,
            "error: bad value for motion.ramp_ms: must be a whole number; expected a duration in \
             ms (or s), range 10..2000 ms"
        )
    );
    // While moving, the board refuses (the first change, in the order liftctl sends them), and
    // liftctl stops there.
    ok(a, &["goto", "400mm"]);
    let r = liftctl(
        a,
        &[
            "config",
            "set",
            "motion.ramp_ms",
            "500",
            "limits.upper",
            "390mm",
        ],
    );
    assert_eq!(r.code, 1, "{}\n{}", r.out, r.err);
    assert_eq!(
        r.err,
        "error: set motion.ramp_ms refused: the lift is moving; `stop` and let it come to rest \
         first; nothing changed\nliftctl: nothing changed: what this command had changed was set \
         back\n",
        "{}",
        r.err
    );
    ok(a, &["stop"]);
    ok(
        a,
        &["watch", "--until-rest", "--interval", "0.05", "--quiet"],
    );
    assert_eq!(ok(a, &["config", "export"]), before);
    server.shutdown();
}

#[test]
fn export_edit_import_save() {
    let server = board();
    let a = server.addr();
    let file = temp("lift.toml");
    ok(a, &["config", "export", file.to_str().unwrap()]);
    let text = std::fs::read_to_string(&file).unwrap();
    assert!(
        text.contains("[limits]\nlower = \"145 mm\"\nupper = \"410 mm\""),
        "{text}"
    );
    let edited = text
        .replace("upper = \"410 mm\"", "upper = \"380 mm\"")
        .replace("ramp_ms = \"60 ms\"", "ramp_ms = 250");
    std::fs::write(&file, &edited).unwrap();
    let out = ok(a, &["config", "import", file.to_str().unwrap(), "--save"]);
    assert!(out.contains("ok: limits.upper = 380 mm"), "{out}");
    assert!(out.contains("ok: motion.ramp_ms = 250 ms"), "{out}");
    assert!(out.contains("ok: saved as configuration #1"), "{out}");
    // Importing the same file again changes nothing.
    let out = ok(a, &["config", "import", file.to_str().unwrap()]);
    assert!(out.contains("nothing to change"), "{out}");
    // An unknown key: refused before anything is sent.
    std::fs::write(&file, edited.replace("[load]", "[load]\nmiddle = 3")).unwrap();
    let r = liftctl(a, &["config", "import", file.to_str().unwrap()]);
    // Refused (1), as `config set load.middle 3` is.
    assert_eq!(r.code, 1, "{}", r.err);
    assert!(r.err.contains("unknown key 'load.middle'"), "{}", r.err);
    assert!(r.err.contains("nothing was sent"), "{}", r.err);
    server.power_cycle().unwrap();
    assert_eq!(
        ok(a, &["config", "get", "limits.upper", "motion.ramp_ms"]),
        "limits.upper = 380 mm\nmotion.ramp_ms = 250 ms\n"
    );
    server.shutdown();
}

/// A fake backed by the real console service and a controller at rest.
fn serviced(
    mut drop: impl FnMut(&str) -> bool + Send + 'static,
) -> (SocketAddr, Seen, Arc<Mutex<ValidatedConfig>>) {
    let cfg = Arc::new(Mutex::new(ValidatedConfig::factory()));
    let shared = Arc::clone(&cfg);
    let mut c = Controller::new(ValidatedConfig::factory().get(), 40_000).unwrap();
    let (addr, seen) = fake(move |line| {
        let mut out = String::new();
        let mut running = shared.lock().unwrap();
        service::handle(line, &mut c, &mut running, &mut out);
        if drop(std::str::from_utf8(line).unwrap_or("")) {
            None
        } else {
            Some(out.into_bytes())
        }
    });
    (addr, seen, cfg)
}

#[test]
fn another_protocol_version_is_refused_before_anything_is_sent() {
    let (a, seen) = fake(|line| {
        Some(match line {
            b"version" => b"liftfw console v1 firmware=9.0.0 schema=00000000".to_vec(),
            _ => b"ok: whatever".to_vec(),
        })
    });
    let r = liftctl(a, &["limits", "set", "--upper", "400mm"]);
    assert_eq!(r.code, 2);
    assert!(
        r.err
            .contains("\"liftfw console v1 firmware=9.0.0 schema=00000000\"")
            && r.err.contains("this liftctl speaks liftfw console v2")
            && r.err.contains("nothing was sent"),
        "{}",
        r.err
    );
    assert_eq!(*seen.lock().unwrap(), ["", "version"]);
    // Something that is not a liftfw console at all.
    let (a, _) = fake(|_| Some(b"AT OK".to_vec()));
    let r = liftctl(a, &["status"]);
    assert_eq!(r.code, 2);
    assert!(
        r.err.contains("answers `version` with \"AT OK\""),
        "{}",
        r.err
    );
}

#[test]
fn a_garbled_reply_or_a_timeout_gives_a_clear_message() {
    let version = format!(
        "liftfw console v2 firmware=0.1.0 schema={:08x}",
        liftfw::config::record::schema()
    );
    let v = version.clone();
    let (a, _) = fake(move |line| {
        Some(match line {
            b"version" => v.clone().into_bytes(),
            b"status" => b"state=li\x07fting h\xffeight=2".to_vec(),
            // An unsolicited warning before the reply is shown and skipped.
            b"fault" => {
                b"warning: stick-slip (episode 1, torque drop 0.40 Nm per slip)\r\nfault=none"
                    .to_vec()
            }
            _ => return None,
        })
    });
    let r = liftctl(a, &["status"]);
    assert_eq!(r.code, 2);
    assert!(
        r.err.starts_with("liftctl: garbled reply to `status`"),
        "{}",
        r.err
    );
    let r = liftctl(a, &["fault"]);
    assert_eq!(r.code, 0, "{}", r.err);
    assert_eq!(r.out.trim(), "fault        none");
    assert_eq!(
        r.err.trim(),
        "warning: stick-slip (episode 1, torque drop 0.40 Nm per slip)"
    );
    let r = liftctl(a, &["--timeout", "0.3", "limits"]);
    assert_eq!(r.code, 2);
    assert!(
        r.err
            .starts_with("liftctl: no reply to `limits` within 0.3 s"),
        "{}",
        r.err
    );
}

#[test]
fn a_lost_reply_in_the_middle_of_a_change_is_undone() {
    // The board executes `set limits.lower …` but its reply is lost.
    let (a, seen, cfg) = serviced(|line| line.starts_with("set limits.lower 200"));
    let r = liftctl(
        a,
        &[
            "--timeout",
            "0.4",
            "limits",
            "set",
            "--upper",
            "400mm",
            "--lower",
            "200mm",
        ],
    );
    assert_eq!(r.code, 2, "{}\n{}", r.out, r.err);
    assert!(
        r.err
            .contains("no reply to `set limits.lower 200mm` within 0.4 s")
            && r.err
                .contains("liftctl: nothing changed: what this command had changed was set back"),
        "{}",
        r.err
    );
    // Both stops are back where they were, on the board itself.
    assert_eq!(*cfg.lock().unwrap(), ValidatedConfig::factory());
    let seen = seen.lock().unwrap();
    assert!(
        seen.iter().any(|l| l == "set limits.lower 145 mm"),
        "{seen:?}"
    );
    assert!(
        seen.iter().any(|l| l == "set limits.upper 410 mm"),
        "{seen:?}"
    );
}

/// The serial-port path of liftctl (the `serialport` crate), against the simulated board's
/// pseudo-terminal.
#[cfg(unix)]
#[test]
fn over_a_serial_port_the_pseudo_terminal() {
    let server = Server::start(&ServeArgs {
        listen: "127.0.0.1:0".parse().unwrap(),
        speed: 0.0,
        pty: true,
        ..ServeArgs::default()
    })
    .unwrap();
    let port = server.pty_path().unwrap().to_str().unwrap().to_string();
    let run = |args: &[&str]| {
        let r = liftctl_on(&port, args);
        assert_eq!(
            r.code, 0,
            "liftctl {args:?}\nstdout: {}\nstderr: {}",
            r.out, r.err
        );
        r.out
    };
    assert!(run(&["version"]).starts_with("liftfw console v2 "));
    let out = run(&["limits", "set", "--lower", "160mm", "--save"]);
    assert!(out.contains("ok: limits.lower = 160 mm"), "{out}");
    assert!(out.contains("ok: saved as configuration #1"), "{out}");
    server.power_cycle().unwrap();
    assert_eq!(
        run(&["config", "get", "limits.lower"]),
        "limits.lower = 160 mm\n"
    );
    server.shutdown();
}

#[test]
fn config_keys_describes_settings_without_a_board() {
    // No board at this port: `config keys` never opens it.
    let r = liftctl_on(
        "/nonexistent/liftctl-port",
        &["config", "keys", "motion.ramp_ms"],
    );
    assert_eq!(r.code, 0, "stdout: {}\nstderr: {}", r.out, r.err);
    assert_eq!(
        r.out,
        "motion.ramp_ms: time from rest to cruise speed (and back); expected a duration in ms \
         (or s), range 10..2000 ms\n"
    );
    let all = liftctl_on("/nonexistent/liftctl-port", &["config", "keys"]);
    assert_eq!(all.code, 0, "{}", all.err);
    assert_eq!(
        all.out.lines().count(),
        liftfw::config::settings::SETTINGS.len()
    );
    let bad = liftctl_on(
        "/nonexistent/liftctl-port",
        &["config", "keys", "limits.middle"],
    );
    assert_eq!(bad.code, 3);
    assert!(
        bad.err.contains("unknown key 'limits.middle'"),
        "{}",
        bad.err
    );
}
