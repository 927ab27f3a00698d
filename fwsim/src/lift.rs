//! `fwsim lift`: README's main job (host-sim lift) with the real firmware in the loop: a car of
//! `load_kg` on the plant, the lift parked at `from_mm` (a position record in the store, as the
//! firmware leaves it when it parks), the friction law set to the plant's lubricant over the
//! console, `goto` the target; every half second the firmware's own `status` (what the core on
//! the board believes) beside the plant's truth; then the halt error.

use crate::elf::Image;
use crate::flash::{Store, STORE_LEN};
use crate::machine::Machine;
use crate::plant::Rig;
use host_sim::physics::{Geometry, Lubricant};
use host_sim::sim::SimConfig;
use liftfw::config::sim_flash::SimFlash;
use liftfw::config::store::{geometry_stamp, ConfigStore, Parked};
use liftfw::config::ValidatedConfig;
use liftfw::control::config::ControlConfig;
use liftfw::control::Controller;
use liftfw::units::Metres;

/// What to run.
#[derive(Clone, Debug)]
pub struct LiftArgs {
    /// Plant lubricant; the firmware is configured with the same law.
    pub lubricant: Lubricant,
    /// Mass on the head, kg.
    pub load_kg: f64,
    /// Start height, mm.
    pub from_mm: f64,
    /// Target height, mm.
    pub to_mm: f64,
    /// Sensor-noise seed.
    pub seed: u64,
    /// Print the defmt log as it comes.
    pub show_log: bool,
}

/// What a lift run measured.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LiftOutcome {
    /// True head height at the end, mm.
    pub final_mm: f64,
    /// Final height − target, mm.
    pub error_mm: f64,
    /// Emulated seconds.
    pub emulated_s: f64,
    /// Wall seconds.
    pub wall_s: f64,
    /// Instructions executed.
    pub insns: u64,
}

/// The store with the factory configuration saved and a parked-position record at `counts`, written
/// by the core's own store code (the firmware's format) on a host flash of the store's size.
pub fn parked_store(counts: i32) -> Result<Store, String> {
    let flash: SimFlash<STORE_LEN> = SimFlash::new();
    let mut store =
        ConfigStore::new(flash, 0..STORE_LEN as u32).map_err(|e| format!("store: {e:?}"))?;
    let stamp = geometry_stamp(&ControlConfig::DEFAULT);
    store
        .save(&ValidatedConfig::factory())
        .map_err(|e| format!("store: {e:?}"))?;
    store
        .save_position(Parked::At(counts), stamp)
        .map_err(|e| format!("store: {e:?}"))?;
    let bytes = store.into_flash().bytes().to_vec();
    Ok(Store {
        bytes,
        torn: vec![false; STORE_LEN / 8],
    })
}

/// Encoder counts at a head height (the core's own geometry, factory configuration).
pub fn counts_at(mm: f64) -> Result<i32, String> {
    let probe = Controller::new(&ControlConfig::DEFAULT, 0).map_err(|e| e.to_string())?;
    probe
        .estimator()
        .geometry()
        .counts_for_height(Metres::from_f64(mm * 1e-3))
        .ok_or_else(|| format!("{mm} mm is outside the mechanism"))
}

/// The plant for a lift from `from_mm` with `load_kg` (host-sim lift's configuration).
pub fn plant_config(
    lubricant: Lubricant,
    load_kg: f64,
    from_mm: f64,
    seed: u64,
) -> Result<SimConfig, String> {
    let g = Geometry::paper();
    let s = (from_mm * 1e-3 - g.h0) / g.length;
    if !(0.0..1.0).contains(&s) {
        return Err(format!("{from_mm} mm is outside the mechanism"));
    }
    let mut cfg = SimConfig::paper(lubricant.law(), 0.3, s.asin().to_degrees());
    cfg.plant.load = load_kg;
    cfg.duration = 1e9;
    cfg.record_rate = 0.0;
    cfg.seed = seed;
    Ok(cfg)
}

/// A `key=value` field of a status line.
pub fn field<'a>(line: &'a str, key: &str) -> Option<&'a str> {
    line.split_whitespace()
        .find_map(|w| w.strip_prefix(key).and_then(|r| r.strip_prefix('=')))
}

fn number(s: &str) -> f64 {
    let end = s
        .find(|c: char| !(c.is_ascii_digit() || c == '.' || c == '-' || c == '+' || c == 'e'))
        .unwrap_or(s.len());
    s[..end].parse().unwrap_or(f64::NAN)
}

/// Runs it and prints as it goes.
pub fn main(
    elf: &std::path::Path,
    a: &LiftArgs,
    trace: Option<&std::path::Path>,
) -> Result<LiftOutcome, String> {
    let image = Image::load(elf)?;
    let store = parked_store(counts_at(a.from_mm)?)?;
    counts_at(a.to_mm)?;
    let mut machine = Machine::new(image, store)?;
    if let Some(p) = trace {
        machine.trace_to(p)?;
    }
    let mut rig = Rig::new(
        machine,
        plant_config(a.lubricant, a.load_kg, a.from_mm, a.seed)?,
    )?;
    let wall = std::time::Instant::now();
    println!(
        "fwsim lift: {} thread, {} kg, {:.1} mm → {:.1} mm; the firmware ELF on the emulated STM32G431 against the plant\n",
        a.lubricant.name(),
        a.load_kg,
        a.from_mm,
        a.to_mm
    );
    let mut seen = String::new();
    if !rig.run_until_console("\r\n", 1.0, &mut seen)? {
        return Err(format!(
            "no console greeting within 1 s (console: {seen:?})"
        ));
    }
    rig.run_for(0.02)?;
    let greeting = seen + &rig.machine.take_console();
    for l in greeting.lines().filter(|l| !l.trim().is_empty()) {
        println!("console: {}", l.trim_end());
    }
    let law = match a.lubricant {
        Lubricant::Dry => "dry",
        Lubricant::Ptfe => "ptfe",
        Lubricant::Lithium => "lithium",
    };
    let reply = rig.command(&format!("set friction.law {law}"), 1.0)?;
    println!("console: set friction.law {law} → {reply}");
    let reply = rig.command(&format!("goto {}mm", a.to_mm), 1.0)?;
    println!("console: goto {} mm → {reply}\n", a.to_mm);
    if reply.starts_with("error") {
        let fault = rig.command("fault", 1.0)?;
        return Err(format!("goto refused: {reply} ({fault})"));
    }
    println!(
        "{:>6}  {:>10} {:>10}  {:>9} {:>9}  {:>9} {:>9}  {:>7}  state",
        "t s", "height mm", "fw mm", "ω rad/s", "fw", "T_r N·m", "fw est.", "I A"
    );
    let mut rested_at: Option<f64> = None;
    let mut last = rig.sim.record(rig.t);
    while rig.t < 120.0 {
        let status = rig.command("status", 1.0)?;
        let r = rig.sim.record(rig.t);
        last = r;
        let state = field(&status, "state").unwrap_or("?").to_string();
        println!(
            "{:6.2}  {:10.3} {:>10}  {:9.3} {:>9}  {:9.3} {:>9}  {:7.2}  {}",
            rig.t,
            r.height * 1e3,
            field(&status, "height").map_or(f64::NAN, number),
            r.theta_dot,
            field(&status, "speed").map_or(f64::NAN, number),
            r.friction_torque,
            field(&status, "T_r").map_or(f64::NAN, number),
            r.current,
            state
        );
        if a.show_log {
            for l in rig.machine.take_log() {
                println!("    [defmt {:.3}] {}", l.t, l.text);
            }
        }
        if field(&status, "fault").is_some_and(|f| f != "none") {
            return Err(format!("fault: {status}"));
        }
        let moving = matches!(state.as_str(), "lifting" | "lowering");
        if !moving {
            let at = *rested_at.get_or_insert(rig.t);
            if rig.t > at + 0.5 {
                break;
            }
        }
        rig.run_for(0.5)?;
    }
    rig.machine.flush_trace();
    let final_mm = last.height * 1e3;
    let err = final_mm - a.to_mm;
    println!("\nhalted at {final_mm:.3} mm: error {err:+.3} mm (goal ±0.5 mm)");
    let wall_s = wall.elapsed().as_secs_f64();
    let bus = rig.machine.mcu.bus_ref();
    let insns = bus.insns;
    if std::env::var_os("FWSIM_STATS").is_some() {
        println!(
            "{insns} instructions in {} blocks (longest {}), {} register reads, {} writes, {} slices",
            bus.blocks, bus.longest_block, bus.stats[0], bus.stats[1], bus.stats[2]
        );
    }
    println!(
        "{:.2} s emulated in {:.2} s wall ({:.1}× real time), {} resets",
        rig.t,
        wall_s,
        rig.t / wall_s,
        rig.machine.resets.len()
    );
    Ok(LiftOutcome {
        final_mm,
        error_mm: err,
        emulated_s: rig.t,
        wall_s,
        insns,
    })
}
