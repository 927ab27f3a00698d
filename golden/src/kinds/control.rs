//! The control tick: `control::Controller::step`.

use crate::format::{Counter, Error, InputBuf, Kind, Reader, Sink, Text, MAX_SEQUENCE};
use crate::record;
use crate::rng::SplitMix64;
use liftfw::control::config::{ButtonMode, ControlConfig, RampShape};
use liftfw::control::{Bridge, Command, Controller, Inputs, Refusal, State, Switches};
use liftfw::units::{Instant, Metres};

/// Longest control run, ticks.
pub const MAX_CONTROL_TICKS: u32 = 4000;

/// Control script events (`tick u32`, `what u8`, `arg i32`).
const EV_UP: u8 = 0;
const EV_DOWN: u8 = 1;
const EV_STOP: u8 = 2;
const EV_GOTO: u8 = 3;
const EV_CLEAR: u8 = 4;
const EV_SWITCHES: u8 = 5;
const EV_LOAD: u8 = 6;
const EV_SUPPLY: u8 = 7;
const EV_GAIN: u8 = 8;
const EV_NONSENSE: u8 = 9;

/// Number of controller configurations.
const CONTROL_CONFIGS: u8 = 3;

fn control_config(id: u8) -> Option<ControlConfig> {
    let mut c = ControlConfig::DEFAULT;
    match id {
        0 => {}
        1 => c.motion.ramp_shape = RampShape::SCurve,
        2 => c.motion.buttons = ButtonMode::Latched,
        _ => return None,
    }
    Some(c)
}

fn refusal_code(r: Result<(), Refusal>) -> u8 {
    match r {
        Ok(()) => 0,
        Err(Refusal::Faulted) => 1,
        Err(Refusal::SupplyLow) => 2,
        Err(Refusal::AtLimit) => 3,
        Err(Refusal::OutsideLimits) => 4,
        Err(Refusal::Moving) => 5,
        Err(Refusal::NoFault) => 6,
        Err(Refusal::NotHomed) => 7,
        Err(Refusal::InMotion) => 8,
        Err(Refusal::BadConfig) => 9,
        Err(Refusal::NeedsBallScrew) => 10,
    }
}

fn state_code(s: State) -> u8 {
    match s {
        State::Idle => 0,
        State::Lifting => 1,
        State::Lowering => 2,
        State::Holding => 3,
        State::Fault => 4,
    }
}

/// [`Kind::ControlTick`](crate::Kind::ControlTick): the controller stepped against a small plant.
pub(crate) fn eval(r: &mut Reader<'_>, out: &mut impl Sink) -> Result<(), Error> {
    let cfg_id = r.u8()?;
    let cfg = control_config(cfg_id).ok_or(Error::UnknownConfig(cfg_id))?;
    let start = r.i32()?;
    let ticks = r.u32()?;
    let seed = u64::from_le_bytes(r.array()?);
    let n = r.u16()?;
    if ticks > MAX_CONTROL_TICKS {
        return Err(Error::BadField(0));
    }
    if usize::from(n) > MAX_SEQUENCE {
        return Err(Error::SequenceTooLong(n));
    }
    let events = r.take(usize::from(n) * 9)?;
    let mut c = Controller::new(&cfg, start).map_err(|_| Error::UnknownConfig(cfg_id))?;
    let mut rng = SplitMix64(seed);
    // The plant: screw position and speed in Q16 counts (per tick), a first-order lag toward
    // the duty; the current follows the duty and the load, the supply sags with it.
    let (mut pos, mut vel) = (i64::from(start) << 16, 0i64);
    let (mut switches, mut load, mut supply, mut gain, mut nonsense) =
        (0u8, 300i64, 2820i64, 8i64, 0u64);
    let mut next = 0usize;
    let mut prev: Option<(u8, i16, u8, u8)> = None;
    let mut last_duty = 0i16;
    for t in 0..ticks {
        while let Some(ev) = events.get(next * 9..next * 9 + 9) {
            let at = u32::from_le_bytes([ev[0], ev[1], ev[2], ev[3]]);
            if at != t {
                break;
            }
            let arg = i32::from_le_bytes([ev[5], ev[6], ev[7], ev[8]]);
            let cmd = |c: &mut Controller, k| refusal_code(c.command(k));
            let res = match ev[4] {
                EV_UP => cmd(&mut c, Command::Up),
                EV_DOWN => cmd(&mut c, Command::Down),
                EV_STOP => cmd(&mut c, Command::Stop),
                EV_GOTO => cmd(&mut c, Command::GoTo(Metres::from_bits(arg))),
                EV_CLEAR => cmd(&mut c, Command::ClearFault),
                EV_SWITCHES => {
                    switches = arg as u8;
                    0xff
                }
                EV_LOAD => {
                    load = i64::from(arg);
                    0xff
                }
                EV_SUPPLY => {
                    supply = i64::from(arg);
                    0xff
                }
                EV_GAIN => {
                    gain = i64::from(arg);
                    0xff
                }
                EV_NONSENSE => {
                    nonsense = u64::from(arg as u8);
                    0xff
                }
                w => return Err(Error::BadField(w)),
            };
            out.put_u32(t);
            out.put_u8(0xfe); // an event's answer, not a tick
            out.put_u8(res);
            next += 1;
        }
        let duty = i64::from(last_duty);
        vel += ((duty * gain) - vel) >> 4;
        pos = pos.saturating_add(vel);
        let dir = duty.signum();
        let noise = rng.range(-3, 3);
        let mut x = Inputs {
            encoder_count: (pos >> 16) as u16,
            encoder_edge_age: 0,
            current_raw: (2048 + dir * load + duty / 128 + noise).clamp(0, 4095) as u16,
            supply_raw: (supply - duty.abs() / 512 + noise).clamp(0, 4095) as u16,
            switches: Switches(switches),
        };
        if (rng.next_u64() & 0xff) < nonsense {
            match rng.range(0, 3) {
                0 => x.encoder_count = rng.bits() as u16,
                1 => x.current_raw = rng.bits() as u16,
                2 => x.supply_raw = rng.bits() as u16,
                _ => x.switches = Switches(rng.bits() as u8),
            }
        }
        let o = c.step(Instant(t.wrapping_mul(cfg.estimator.tick_us)), &x);
        c.finish_tick();
        let (tag, duty) = match o.bridge {
            Bridge::Coast => (0, 0),
            Bridge::Brake => (1, 0),
            Bridge::Drive(d) => (2, d),
        };
        last_duty = duty;
        let flags = u8::from(o.feed_watchdog) | u8::from(o.brake_release) << 1;
        let now = (tag, duty, flags, state_code(c.state()));
        // Run-length coded: a tick's outputs wherever they change or carry an event.
        if prev != Some(now) || o.event.is_some() {
            out.put_u32(t);
            out.put_u8(tag);
            out.put(&duty.to_le_bytes());
            out.put_u8(flags);
            out.put_u8(now.3);
            if let Some(e) = o.event {
                let mut len = Counter::default();
                let _ = core::fmt::write(&mut Text(&mut len), format_args!("{e:?}"));
                out.put_u16(len.0 as u16);
                core::fmt::write(&mut Text(out), format_args!("{e:?}"))
                    .map_err(|_| Error::BadField(0))?;
            } else {
                out.put_u16(0);
            }
            prev = Some(now);
        }
    }
    out.put_u32(u32::MAX);
    Ok(())
}

/// Control runs per configuration.
pub const CONTROL_RUNS_PER_CONFIG: u32 = 8;

/// The controller's records: [`CONTROL_RUNS_PER_CONFIG`] runs per configuration.
pub(crate) fn generate(rng: &mut SplitMix64, s: &mut impl Sink) -> Result<(), Error> {
    for cfg in 0..CONTROL_CONFIGS {
        for k in 0..CONTROL_RUNS_PER_CONFIG {
            let mut input = InputBuf::new();
            input.put_u8(cfg);
            input.put_i32(rng.range(0, 400_000) as i32);
            let ticks = rng.range(1500, i64::from(MAX_CONTROL_TICKS)) as u32;
            input.put_u32(ticks);
            input.put_u64(rng.next_u64());
            let mut evs: [(u32, u8, i32); 24] = [(0, 0, 0); 24];
            let n = match k % 4 {
                // Up, then stop; a goto; down.
                0 => {
                    evs[0] = (10, EV_UP, 0);
                    evs[1] = (rng.range(100, 800) as u32, EV_STOP, 0);
                    evs[2] = (1000, EV_GOTO, rng.range(0, 1 << 24) as i32);
                    evs[3] = (ticks - 300, EV_DOWN, 0);
                    4
                }
                // Faults: stall (no motion), then clear; supply sag; overload.
                1 => {
                    evs[0] = (5, EV_GAIN, 0);
                    evs[1] = (10, EV_UP, 0);
                    evs[2] = (900, EV_CLEAR, 0);
                    evs[3] = (901, EV_GAIN, 8);
                    evs[4] = (950, EV_UP, 0);
                    evs[5] = (1100, EV_SUPPLY, rng.range(1500, 2600) as i32);
                    evs[6] = (1300, EV_LOAD, rng.range(600, 2000) as i32);
                    evs[7] = (1400, EV_CLEAR, 0);
                    4 + 4
                }
                // Buttons and limit switches.
                2 => {
                    evs[0] = (10, EV_SWITCHES, i32::from(Switches::BUTTON_UP));
                    evs[1] = (300, EV_SWITCHES, 0);
                    evs[2] = (400, EV_SWITCHES, i32::from(Switches::BUTTON_DOWN));
                    evs[3] = (
                        700,
                        EV_SWITCHES,
                        i32::from(Switches::LIMIT_LOWER | Switches::BUTTON_DOWN),
                    );
                    evs[4] = (800, EV_SWITCHES, 0);
                    evs[5] = (900, EV_UP, 0);
                    evs[6] = (1000, EV_SWITCHES, i32::from(Switches::LIMIT_UPPER));
                    evs[7] = (1100, EV_SWITCHES, i32::from(Switches::BUTTON_STOP));
                    evs[8] = (1200, EV_SWITCHES, 0);
                    9
                }
                // Random commands and nonsense inputs.
                _ => {
                    let mut t = 0u32;
                    let mut n = 0;
                    while n < 24 {
                        t += rng.range(1, 150) as u32;
                        if t >= ticks {
                            break;
                        }
                        let what = rng.range(0, 9) as u8;
                        let arg = match what {
                            EV_SWITCHES => rng.range(0, 31) as i32,
                            EV_LOAD => rng.range(-2048, 2048) as i32,
                            EV_SUPPLY => rng.range(0, 4095) as i32,
                            EV_GAIN => rng.range(-16, 16) as i32,
                            EV_NONSENSE => rng.range(0, 40) as i32,
                            _ => rng.bits(),
                        };
                        evs[n] = (t, what, arg);
                        n += 1;
                    }
                    n
                }
            };
            input.put_u16(n as u16);
            for &(t, w, a) in evs.iter().take(n) {
                input.put_u32(t);
                input.put_u8(w);
                input.put_i32(a);
            }
            record(s, Kind::ControlTick, &input)?;
        }
    }
    Ok(())
}
