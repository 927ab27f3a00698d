//! The firmware ELF on the emulated board, each scenario beside the same one with the core in
//! the loop (the `Controller` driving the same plant) where one exists.
//!
//! These need the ELF: `FWSIM_ELF=path` (scripts/test-all builds it with scripts/fw-build and
//! runs them with `--ignored`). Without it they fail: they are ignored in a plain `cargo test`.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use fwsim::elf::Image;
use fwsim::flash::Store;
use fwsim::lift::{counts_at, parked_store, plant_config};
use fwsim::machine::Machine;
use fwsim::plant::{Buttons, Rig};
use fwsim::sys::ResetCause;
use fwsim::TICK_HZ;
use host_sim::physics::Lubricant;
use host_sim::sim::{Driver, Sim, SimConfig};
use liftfw::control::config::ControlConfig;
use liftfw::control::{Bridge, Command, Controller, Inputs, Outputs, Switches};
use liftfw::units::{Instant, Metres};
use std::sync::{Arc, Mutex};

fn image(var: &str) -> Image {
    let path = std::env::var(var)
        .unwrap_or_else(|_| panic!("{var} must name the firmware ELF (scripts/fw-build)"));
    Image::load(std::path::Path::new(&path)).unwrap()
}

fn rig(store: Store, from_mm: f64) -> Rig {
    let m = Machine::new(image("FWSIM_ELF"), store).unwrap();
    Rig::new(m, plant_config(Lubricant::Dry, 1000.0, from_mm, 1).unwrap()).unwrap()
}

fn height_mm(r: &Rig) -> f64 {
    r.sim.record(r.t).height * 1e3
}

/// Boots and returns the greeting.
fn boot(r: &mut Rig) -> String {
    let mut seen = String::new();
    assert!(
        r.run_until_console("\r\n", 1.0, &mut seen).unwrap(),
        "no greeting: {seen:?}"
    );
    r.run_for(0.05).unwrap();
    seen + &r.machine.take_console()
}

/// A board parked at 200 mm, booted, that accepted the motion command `goto`.
fn parked_at_200_mm_then(goto: &str) -> Rig {
    let mut r = rig(parked_store(counts_at(200.0).unwrap()).unwrap(), 200.0);
    boot(&mut r);
    let reply = r.command(goto, 1.0).unwrap();
    assert!(reply.starts_with("ok"), "{goto}: {reply}");
    r
}

/// The core in the loop: the same plant, the core's `Controller` at 1 kHz, the buttons pressed
/// by `script(t, controller) -> buttons` (which may also send commands).
fn core_in_the_loop(
    cfg: SimConfig,
    parked: Option<i32>,
    secs: f64,
    mut script: impl FnMut(f64, &mut Controller) -> u8 + Send + 'static,
) -> (Sim, f64, Arc<Mutex<Controller>>) {
    let c = Arc::new(Mutex::new(
        Controller::new_at(&ControlConfig::DEFAULT, parked).unwrap(),
    ));
    let inner = Arc::clone(&c);
    let driver = Driver::Board(Box::new(move |t: f64, inputs: &Inputs| {
        let mut c = inner.lock().unwrap();
        let buttons = script(t, &mut c);
        let mut i = *inputs;
        i.switches = Switches(i.switches.0 | buttons);
        let o: Outputs = c.step(Instant((t * 1e6).round() as u64 as u32), &i);
        c.finish_tick();
        o
    }));
    let mut sim = Sim::new(cfg, driver).unwrap();
    let n = (secs / sim.cfg.dt).round() as u64;
    let t = sim.step_n(n);
    (sim, t, c)
}

/// A reply longer than the console's 256-byte transmit ring (`help keys`, every setting)
/// arrives whole, byte for byte what the core writes: embassy-stm32's buffered write takes a
/// buffer only whole (longer than the ring it failed, and the reply was lost), so the console
/// task sends a ring's worth at a time.
#[test]
#[ignore = "needs FWSIM_ELF"]
fn a_reply_longer_than_the_transmit_ring_arrives_whole() {
    let mut r = rig(parked_store(counts_at(200.0).unwrap()).unwrap(), 200.0);
    boot(&mut r);
    let mut all = String::new();
    liftfw::console::write_help(&mut all, liftfw::console::HelpTopic::Keys).unwrap();
    // The default (lead-screw) image has no `ballscrew.*` settings; the workspace's tests may
    // build the host's core with them.
    let want: String = all
        .split("\r\n")
        .filter(|l| !l.trim_start().starts_with("ballscrew."))
        .flat_map(|l| [l, "\r\n"])
        .collect();
    assert!(
        want.len() > 256,
        "{} bytes: not longer than the ring",
        want.len()
    );
    let _ = r.machine.take_console();
    r.machine.console_send(b"help keys\r\n");
    let mut seen = String::new();
    // At 115 200 baud, ≈ 87 µs a byte.
    let end = r.t + 0.2 + want.len() as f64 * 1e-4;
    while r.t < end && !seen.ends_with(&want) {
        r.run_for(1e-3).unwrap();
        seen.push_str(&r.machine.take_console());
    }
    assert_eq!(seen, want, "{} of {} bytes", seen.len(), want.len());
}

#[test]
#[ignore = "needs FWSIM_ELF"]
fn boot_greeting_and_version_as_the_core_writes_them() {
    let mut r = rig(Store::default(), 150.0);
    let greeting = boot(&mut r);
    let mut version = String::new();
    liftfw::console::service::write_version(&mut version).unwrap();
    assert!(
        greeting.contains(&version),
        "greeting {greeting:?} lacks {version:?}"
    );
    assert!(
        greeting.contains("hold DOWN"),
        "an unparked lift asks to home: {greeting:?}"
    );
    assert_eq!(r.command("version", 1.0).unwrap(), version);
    // The defmt log decoded from RTT: the boot line with the firmware's version.
    let log: Vec<String> = r
        .machine
        .take_log()
        .iter()
        .map(|l| l.text.clone())
        .collect();
    assert!(
        log.iter().any(|l| l.contains("liftfw 0.1.0 booting")),
        "defmt log: {log:#?}"
    );
    assert!(r.machine.resets.is_empty());
}

#[test]
#[ignore = "needs FWSIM_ELF"]
fn homing_then_a_lift_halts_where_the_core_in_the_loop_does() {
    let target = 180.0;
    let mut r = rig(Store::default(), 150.0);
    boot(&mut r);
    r.buttons = Buttons {
        down: true,
        ..Buttons::default()
    };
    let mut seen = String::new();
    assert!(
        r.run_until_console("homed", 20.0, &mut seen).unwrap(),
        "never homed: {seen:?}"
    );
    r.buttons = Buttons::default();
    r.run_for(0.5).unwrap();
    let reply = r.command(&format!("goto {target}mm"), 1.0).unwrap();
    assert!(reply.starts_with("ok"), "{reply}");
    let mut rest = None;
    while r.t < 60.0 {
        r.run_for(0.1).unwrap();
        let st = r.machine.board_out();
        let moving = fwsim::plant::bridge_of(&st) != Bridge::Brake
            && fwsim::plant::bridge_of(&st) != Bridge::Coast;
        if !moving && r.t > 1.0 {
            let at = *rest.get_or_insert(r.t);
            if r.t > at + 0.5 {
                break;
            }
        } else {
            rest = None;
        }
    }
    let fw = height_mm(&r);

    // The same with the core in the loop: DOWN held until homed, then the same goto.
    let cfg = plant_config(Lubricant::Dry, 1000.0, 150.0, 1).unwrap();
    // The firmware's scenario: DOWN released at the "homed" notice, `goto` 0.5 s later.
    let mut homed_at: Option<f64> = None;
    let mut sent = false;
    let (sim, t_end, _) = core_in_the_loop(cfg, None, r.t, move |t, c| {
        // After its first ticks (the core refuses motion before it has read the supply).
        if t < 0.05 {
            return 0;
        }
        match homed_at {
            None if c.status().homed => {
                homed_at = Some(t);
                0
            }
            None => Switches::BUTTON_DOWN,
            Some(h) => {
                if !sent && t >= h + 0.5 {
                    sent = true;
                    c.command(Command::GoTo(Metres::from_f64(target * 1e-3)))
                        .unwrap();
                }
                0
            }
        }
    });
    let core = sim.record(t_end).height * 1e3;
    println!(
        "firmware halted at {fw:.3} mm, core in the loop at {core:.3} mm (target {target} mm)"
    );
    assert!((fw - target).abs() <= 0.5, "firmware halted at {fw:.3} mm");
    assert!(
        (fw - core).abs() <= 0.1,
        "firmware {fw:.3} mm vs core {core:.3} mm"
    );
}

/// No interrupt waits long, even while the console reads the status of a held lowering (dry,
/// 1000 kg from 200 mm: the creep weighs the car, each status sweeps three stuck readings).
/// The controller's lock once took a critical section: interrupts (the time driver's alarm,
/// the console's receive) stayed off through every status, 31 165 instructions at worst here.
#[test]
#[ignore = "needs FWSIM_ELF"]
fn interrupts_wait_briefly_while_the_console_reads_a_held_lowering() {
    let mut r = parked_at_200_mm_then("goto 195mm");
    let mut statuses = 0;
    let mut held = false;
    while r.t < 8.0 {
        let line = r.command("status", 0.2).unwrap();
        statuses += 1;
        held |= line.contains("state=lowering") && line.contains("stick_slip=yes");
        if line.contains("state=holding") || line.contains("state=idle") {
            break;
        }
        r.run_for(0.02).unwrap();
    }
    let worst = r.machine.mcu.irq_latency_max;
    println!(
        "{statuses} statuses, held lowering seen: {held}, longest interrupt wait {worst} instructions ({:.1} us at 170 MHz), from pc {:#010x} to {:#010x}",
        worst as f64 / 170.0,
        r.machine.mcu.irq_latency_pc,
        r.machine.mcu.irq_latency_end_pc
    );
    assert!(
        held && statuses > 10,
        "{statuses} statuses, held lowering seen: {held}"
    );
    assert!(worst < 8_000, "an interrupt waited {worst} instructions");
}

#[test]
#[ignore = "needs FWSIM_ELF"]
fn config_save_then_power_cycle_keeps_the_stops() {
    let mut r = rig(parked_store(counts_at(200.0).unwrap()).unwrap(), 200.0);
    boot(&mut r);
    assert!(r
        .command("set limits.upper 390", 1.0)
        .unwrap()
        .starts_with("ok"));
    let saved = r.command("save", 2.0).unwrap();
    assert!(saved.starts_with("ok: saved"), "{saved}");
    r.machine.power_cycle(0.5).unwrap();
    let greeting = boot(&mut r);
    assert!(!greeting.contains("factory"), "{greeting}");
    assert_eq!(
        r.command("get limits.upper", 1.0).unwrap(),
        "limits.upper = 390 mm"
    );
}

#[test]
#[ignore = "needs FWSIM_ELF"]
fn the_watchdog_is_fed_every_tick_and_a_stalled_cpu_resets() {
    let mut r = rig(parked_store(counts_at(200.0).unwrap()).unwrap(), 200.0);
    boot(&mut r);
    let before = r.machine.mcu.bus_ref().iwdg.feeds;
    r.run_for(1.0).unwrap();
    let feeds = r.machine.mcu.bus_ref().iwdg.feeds - before;
    assert!(
        (990..=1010).contains(&feeds),
        "{feeds} feeds in 1 s at a 1 kHz tick"
    );
    assert!(r.machine.resets.is_empty());
    // The CPU stops executing (a hung loop); the IWDG resets the chip within its 50 ms.
    let t0 = r.machine.now();
    r.machine.stall_cpu(0.2).unwrap();
    let reset = r.machine.resets.first().copied().expect("no reset");
    assert_eq!(reset.cause, ResetCause::Watchdog);
    let after = reset.t - t0 as f64 / TICK_HZ as f64;
    assert!(
        (0.045..=0.055).contains(&after),
        "reset {after} s after the stall"
    );
    // The firmware reports it.
    let mut seen = String::new();
    r.run_until_console("\r\n", 1.0, &mut seen).unwrap();
    r.run_for(0.05).unwrap();
    assert_eq!(
        r.command("fault", 1.0).unwrap().split_whitespace().next(),
        Some("fault=watchdog-reset")
    );
}

/// Boots, sets two stops, sends `save` and cuts the power `cut_after` seconds later (None: no
/// cut, the save completes); returns the flash operations the save started (start, end, s after
/// the save was sent), and after the next boot the two stops read back.
fn save_and_cut(cut_after: Option<f64>) -> (Vec<(f64, f64)>, String, String) {
    let mut r = rig(parked_store(counts_at(200.0).unwrap()).unwrap(), 200.0);
    boot(&mut r);
    assert!(r
        .command("set limits.upper 390", 1.0)
        .unwrap()
        .starts_with("ok"));
    assert!(r
        .command("set limits.lower 150", 1.0)
        .unwrap()
        .starts_with("ok"));
    let ops_before = r.machine.mcu.bus_ref().flash.log.len();
    let t0 = r.machine.now();
    r.machine.console_send(b"save\r\n");
    match cut_after {
        Some(s) => {
            r.run_for(s).unwrap();
            r.machine.power_cycle(0.2).unwrap();
        }
        None => {
            let mut seen = String::new();
            assert!(
                r.run_until_console("ok: saved", 2.0, &mut seen).unwrap(),
                "{seen}"
            );
        }
    }
    let ops = r.machine.mcu.bus_ref().flash.log
        [ops_before.min(r.machine.mcu.bus_ref().flash.log.len())..]
        .iter()
        .map(|o| {
            let s = |t: u64| t.saturating_sub(t0) as f64 / TICK_HZ as f64;
            (s(o.start), s(o.end))
        })
        .collect();
    if cut_after.is_none() {
        r.machine.power_cycle(0.2).unwrap();
    }
    boot(&mut r);
    (
        ops,
        r.command("get limits.upper", 1.0).unwrap(),
        r.command("get limits.lower", 1.0).unwrap(),
    )
}

#[test]
#[ignore = "needs FWSIM_ELF"]
fn a_power_cut_during_a_save_boots_with_the_old_or_the_new_stops_never_a_mix() {
    let (ops, upper, lower) = save_and_cut(None);
    assert_eq!(
        (upper.as_str(), lower.as_str()),
        ("limits.upper = 390 mm", "limits.lower = 150 mm")
    );
    assert!(
        ops.len() >= 4,
        "the save programmed {} double words/pages",
        ops.len()
    );
    let old = ("limits.upper = 410 mm", "limits.lower = 145 mm");
    let new = ("limits.upper = 390 mm", "limits.lower = 150 mm");
    // Cut in the middle of every k-th flash operation of the save and right after the last.
    let k = (ops.len() / 12).max(1);
    let mut points: Vec<f64> = ops.iter().step_by(k).map(|(s, e)| (s + e) / 2.0).collect();
    points.push(ops.last().unwrap().1 + 1e-6);
    let (mut olds, mut news) = (0, 0);
    for &p in &points {
        let (_, upper, lower) = save_and_cut(Some(p));
        let got = (upper.as_str(), lower.as_str());
        assert!(got == old || got == new, "cut at {p:.6} s: {got:?}");
        if got == old {
            olds += 1;
        } else {
            news += 1;
        }
    }
    println!(
        "{} cuts during a save of {} flash operations: {olds} old, {news} new",
        points.len(),
        ops.len()
    );
    assert!(olds > 0 && news > 0, "the cuts straddle the commit point");
}

#[test]
#[ignore = "needs FWSIM_ELF"]
fn an_over_current_on_the_adc_trips_within_a_millisecond() {
    let mut r = parked_at_200_mm_then("goto 300mm");
    r.run_for(0.5).unwrap();
    assert!(matches!(
        fwsim::plant::bridge_of(&r.machine.board_out()),
        Bridge::Drive(_)
    ));
    // The BTS7960's fault level on both IS pins: full scale.
    r.force_current = Some(4095);
    let t0 = r.t;
    while matches!(
        fwsim::plant::bridge_of(&r.machine.board_out()),
        Bridge::Drive(_)
    ) {
        assert!(
            r.t < t0 + 0.01,
            "still driving 10 ms after the over-current"
        );
        r.step().unwrap();
    }
    let fw = r.t - t0;
    r.force_current = None;
    let fault = r.command("fault", 1.0).unwrap();
    assert!(fault.starts_with("fault=over-current"), "{fault}");

    // The core in the loop, the same injection at its tick.
    let cfg = plant_config(Lubricant::Dry, 1000.0, 200.0, 1).unwrap();
    let parked = Some(counts_at(200.0).unwrap());
    let c = Arc::new(Mutex::new(
        Controller::new_at(&ControlConfig::DEFAULT, parked).unwrap(),
    ));
    let inner = Arc::clone(&c);
    let tripped = Arc::new(Mutex::new(None::<f64>));
    let trip = Arc::clone(&tripped);
    let mut sent = false;
    let driver = Driver::Board(Box::new(move |t: f64, inputs: &Inputs| {
        let mut c = inner.lock().unwrap();
        // After its first ticks (the core refuses motion before it has read the supply).
        if !sent && t >= 0.05 {
            sent = true;
            c.command(Command::GoTo(Metres::from_f64(0.3))).unwrap();
        }
        let mut i = *inputs;
        if t >= 0.55 {
            i.current_raw = 4095;
        }
        let o = c.step(Instant((t * 1e6).round() as u64 as u32), &i);
        c.finish_tick();
        if t >= 0.55 && !matches!(o.bridge, Bridge::Drive(_)) {
            trip.lock().unwrap().get_or_insert(t - 0.55);
        }
        o
    }));
    let mut sim = Sim::new(cfg, driver).unwrap();
    sim.step_n((0.57 / sim.cfg.dt).round() as u64);
    let core = tripped.lock().unwrap().expect("the core did not trip");
    println!(
        "over-current to bridge off: firmware {:.3} ms, core in the loop {:.3} ms",
        fw * 1e3,
        core * 1e3
    );
    assert!(fw <= 1e-3, "firmware tripped after {:.3} ms", fw * 1e3);
}

/// Runs until the bridge has neither driven nor (after `min_t`) changed for 0.5 s, or `t_max`.
fn run_to_rest(r: &mut Rig, min_t: f64, t_max: f64) {
    let mut rest = None;
    while r.t < t_max {
        r.run_for(0.1).unwrap();
        let moving = matches!(
            fwsim::plant::bridge_of(&r.machine.board_out()),
            Bridge::Drive(_)
        );
        if !moving && r.t > min_t {
            let at = *rest.get_or_insert(r.t);
            if r.t > at + 0.5 {
                return;
            }
        } else {
            rest = None;
        }
    }
}

#[test]
#[ignore = "needs FWSIM_ELF"]
fn the_upper_limit_switch_stops_a_lift_where_the_core_in_the_loop_stops() {
    // The plant's upper switch at 200 mm, under the firmware's soft limit (410 mm): a goto
    // 300 mm from 180 mm ends on the switch (its NC contact opens, PB10 reads high).
    let switch_m = 0.200;
    let config = || {
        let mut cfg = plant_config(Lubricant::Dry, 1000.0, 180.0, 1).unwrap();
        cfg.sensors.upper_limit = switch_m;
        cfg
    };
    let parked = counts_at(180.0).unwrap();
    let m = Machine::new(image("FWSIM_ELF"), parked_store(parked).unwrap()).unwrap();
    let mut r = Rig::new(m, config()).unwrap();
    boot(&mut r);
    let reply = r.command("goto 300mm", 1.0).unwrap();
    assert!(reply.starts_with("ok"), "{reply}");
    run_to_rest(&mut r, 1.0, 20.0);
    let fw = height_mm(&r);
    let status = r.command("status", 1.0).unwrap();
    assert_eq!(
        fwsim::lift::field(&status, "state"),
        Some("holding"),
        "{status}"
    );
    assert_eq!(
        fwsim::lift::field(&status, "fault"),
        Some("none"),
        "{status}"
    );

    // The core in the loop: the same plant, the same goto after boot.
    let mut sent = false;
    let (sim, t_end, c) = core_in_the_loop(config(), Some(parked), r.t, move |t, c| {
        if !sent && t >= 0.05 {
            sent = true;
            c.command(Command::GoTo(Metres::from_f64(0.3))).unwrap();
        }
        0
    });
    let core = sim.record(t_end).height * 1e3;
    let st = c.lock().unwrap().status();
    println!(
        "upper switch at {:.0} mm: firmware stopped at {fw:.3} mm, core in the loop at {core:.3} mm",
        switch_m * 1e3
    );
    assert!(st.fault.is_none(), "core: {:?}", st.fault);
    assert!(
        fw > switch_m * 1e3 && fw < switch_m * 1e3 + 2.0,
        "firmware stopped at {fw:.3} mm"
    );
    assert!(
        (fw - core).abs() <= 0.2,
        "firmware {fw:.3} mm vs core {core:.3} mm"
    );
}

/// The ball-screw plant of the core's closed-loop tests (tests/support: seed 001's 4008, not
/// self-locking) carrying `load_kg` from `from_mm`.
fn ball_screw_plant(load_kg: f64, from_mm: f64) -> SimConfig {
    let mut cfg = plant_config(Lubricant::Dry, load_kg, from_mm, 1).unwrap();
    let bs = host_sim::physics::ballscrew::BallScrewFriction::seed_001_4008();
    cfg.plant.screw = bs.plant_screw(cfg.plant.screw);
    cfg.plant.law = bs.equivalent_law(1000.0 * host_sim::physics::G);
    cfg
}

#[test]
#[ignore = "needs FWSIM_BALL_ELF (scripts/fw-build --ball-screw)"]
fn the_ball_screw_image_boots_and_holds_its_load() {
    // The ball-screw image with `drive.screw = ball` saved, on a ball screw carrying 1000 kg.
    let from_mm = 250.0;
    let m = Machine::new(image("FWSIM_BALL_ELF"), Store::default()).unwrap();
    let mut r = Rig::new(m, ball_screw_plant(1000.0, from_mm)).unwrap();
    boot(&mut r);
    let reply = r.command("set drive.screw ball", 1.0).unwrap();
    assert!(reply.starts_with("ok"), "{reply}");
    let saved = r.command("save", 2.0).unwrap();
    assert!(saved.starts_with("ok: saved"), "{saved}");
    // A power cycle (1 ms off: the bridge coasts from the cut until the firmware drives it).
    r.machine.power_cycle(1e-3).unwrap();
    let greeting = boot(&mut r);
    assert!(!greeting.contains("factory"), "{greeting}");
    assert_eq!(
        r.command("get drive.screw", 1.0).unwrap(),
        "drive.screw = ball"
    );
    let h0 = height_mm(&r);
    r.run_for(2.0).unwrap();
    let h1 = height_mm(&r);
    let status = r.command("status", 1.0).unwrap();
    println!(
        "ball screw, 1000 kg: {from_mm} mm before the power cycle, {h0:.3} mm after the boot, {h1:.3} mm 2 s later ({status})"
    );
    assert_eq!(
        fwsim::lift::field(&status, "fault"),
        Some("none"),
        "{status}"
    );
    assert!((h1 - h0).abs() < 0.02, "drifted {:.3} mm in 2 s", h1 - h0);
    assert!(from_mm - h1 < 1.0, "sank {:.3} mm", from_mm - h1);
    // The same image told it has a lead screw: the rest bridge shorts the motor, and the load
    // turns the ball screw back.
    let reply = r.command("set drive.screw lead", 1.0).unwrap();
    assert!(reply.starts_with("ok"), "{reply}");
    let h2 = height_mm(&r);
    r.run_for(2.0).unwrap();
    let sink = h2 - height_mm(&r);
    println!("with drive.screw = lead it sinks {sink:.3} mm in 2 s");
    assert!(sink > 0.05, "sank {sink:.3} mm");
}
