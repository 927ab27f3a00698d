//! `host-sim serve` in process: the core's console over loopback TCP, `save` on the simulated
//! flash, and a power cycle that boots from it.
#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)]

mod board;

use board::{fast, Console};
use host_sim::apps::serve::{ServeArgs, Server};

#[test]
fn saved_settings_survive_a_power_cycle_and_unsaved_ones_do_not() {
    let server = Server::start(&fast()).unwrap();
    assert!(server.boot_message().contains("no stored configuration"));
    let mut c = Console::open(&server);
    assert!(c.ask("version").starts_with("liftfw console v2 "));
    assert!(c.ask("set limits.upper 300mm").starts_with("ok: "));
    assert_eq!(c.ask("save"), "ok: saved as configuration #1");
    assert!(c.ask("set limits.lower 200mm").starts_with("ok: "));
    let boot = server.power_cycle().unwrap();
    assert!(boot.starts_with("boot: configuration #1 loaded from flash; parked at "));
    assert_eq!(c.ask("get limits.upper"), "limits.upper = 300 mm");
    // Not saved before the power cycle: back to the factory value.
    assert_eq!(c.ask("get limits.lower"), "limits.lower = 145 mm");
    server.shutdown();
}

#[test]
fn flash_file_keeps_the_configuration_across_restarts() {
    let dir = std::env::temp_dir().join(format!("host-sim-serve-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("flash.bin");
    let _ = std::fs::remove_file(&file);
    let args = ServeArgs {
        flash: Some(file.clone()),
        ..fast()
    };
    let server = Server::start(&args).unwrap();
    let mut c = Console::open(&server);
    assert!(c.ask("set limits.upper 350mm").starts_with("ok: "));
    assert_eq!(c.ask("save"), "ok: saved as configuration #1");
    server.shutdown();
    let server = Server::start(&args).unwrap();
    assert!(server
        .boot_message()
        .starts_with("boot: configuration #1 loaded from flash; parked at "));
    let mut c = Console::open(&server);
    assert_eq!(c.ask("get limits.upper"), "limits.upper = 350 mm");
    server.shutdown();
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn the_lift_stops_at_a_new_limit() {
    let server = Server::start(&fast()).unwrap();
    let mut c = Console::open(&server);
    let h0 = server.truth().height;
    let target = (h0 * 1e3 + 8.0).round();
    assert!(c
        .ask(&format!("set limits.upper {target}mm"))
        .starts_with("ok: "));
    assert_eq!(c.ask("up"), "ok: lifting to limits.upper");
    assert!(c
        .ask("set limits.upper 400mm")
        .contains("the lift is moving"));
    let mut last = String::new();
    for _ in 0..400 {
        last = c.ask("status");
        if last.starts_with("state=holding") {
            break;
        }
        std::thread::sleep(std::time::Duration::from_millis(25));
    }
    assert!(last.starts_with("state=holding"), "{last}");
    let h = server.truth().height * 1e3;
    assert!(
        (h - target).abs() < 1.0,
        "true height {h:.2} mm, limit {target} mm"
    );
    server.shutdown();
}
