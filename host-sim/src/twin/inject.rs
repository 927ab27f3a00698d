//! Faults a user injects into a closed-loop run (`host-sim lift --fault`, `host-sim run
//! --fault`, a scenario file's `faults = [...]`, `host-sim serve --fault` and its side
//! channel): each is a kind, a time and a size, and optionally how long it lasts.
//!
//! Text form (flags, files, the side channel): `KIND@TIME[:SIZE][+DURATION]`, times in
//! simulated seconds, e.g. `encoder-loss@2`, `current-offset@1.5:4`, `supply-sag@3:9.5+0.5`.
//!
//! | kind | what happens from TIME (for DURATION, or to the end) | SIZE |
//! |---|---|---|
//! | `encoder-loss` | the encoder counter stops counting (a broken wire or Hall sensor) | — |
//! | `current-offset` | the current sensor reads this much more than flows | A (default 5) |
//! | `current-scale` | the current sensor reads this factor of what flows | factor (default 0.5) |
//! | `lower-switch-dead`, `upper-switch-dead` | that limit switch never closes | — |
//! | `lower-switch-stuck`, `upper-switch-stuck` | that limit switch reads closed | — |
//! | `supply-sag`, `supply-surge` | the battery's open-circuit voltage becomes SIZE | V (9 / 17) |
//! | `jam` | the screw jams (a Coulomb torque of SIZE at the screw) | N·m (default 1000) |
//! | `overload` | this much mass is added on the head | kg (default 500) |
//! | `watchdog-stall` | the control task hangs: the board's outputs freeze; past the IWDG's 50 ms the board resets and boots with a latched `watchdog reset` fault | s (default 0.2) |
//!
//! The sensor faults change what the board reads ([`liftfw::control::Inputs`]), the supply,
//! jam and overload change the plant, the stall withholds the control tick: the core sees a
//! fault only the way the firmware would.

use liftfw::control::{Inputs, Switches};
use std::fmt;
use std::str::FromStr;

/// The board's watchdog period (IWDG, docs/board.md): a stall longer than this resets it.
pub const WATCHDOG_S: f64 = 0.050;

/// What goes wrong.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    /// The encoder stops counting.
    EncoderLoss,
    /// The current sensor reads `size` A more.
    CurrentOffset,
    /// The current sensor reads `size` × the current.
    CurrentScale,
    /// The lower limit switch never closes.
    LowerSwitchDead,
    /// The upper limit switch never closes.
    UpperSwitchDead,
    /// The lower limit switch reads closed.
    LowerSwitchStuck,
    /// The upper limit switch reads closed.
    UpperSwitchStuck,
    /// The battery's open-circuit voltage drops to `size` V.
    SupplySag,
    /// The battery's open-circuit voltage rises to `size` V.
    SupplySurge,
    /// The screw jams: `size` N·m of Coulomb torque at the screw.
    Jam,
    /// `size` kg more on the head.
    Overload,
    /// The control task hangs for `size` s.
    WatchdogStall,
}

/// Every kind with its name and default size.
const KINDS: [(Kind, &str, f64); 12] = [
    (Kind::EncoderLoss, "encoder-loss", 0.0),
    (Kind::CurrentOffset, "current-offset", 5.0),
    (Kind::CurrentScale, "current-scale", 0.5),
    (Kind::LowerSwitchDead, "lower-switch-dead", 0.0),
    (Kind::UpperSwitchDead, "upper-switch-dead", 0.0),
    (Kind::LowerSwitchStuck, "lower-switch-stuck", 0.0),
    (Kind::UpperSwitchStuck, "upper-switch-stuck", 0.0),
    (Kind::SupplySag, "supply-sag", 9.0),
    (Kind::SupplySurge, "supply-surge", 17.0),
    (Kind::Jam, "jam", 1000.0),
    (Kind::Overload, "overload", 500.0),
    (Kind::WatchdogStall, "watchdog-stall", 0.2),
];

impl Kind {
    /// The name in the text form.
    pub fn name(self) -> &'static str {
        KINDS.iter().find(|k| k.0 == self).map_or("?", |k| k.1)
    }

    fn default_size(self) -> f64 {
        KINDS.iter().find(|k| k.0 == self).map_or(0.0, |k| k.2)
    }
}

/// One injected fault.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Injection {
    /// What.
    pub kind: Kind,
    /// From this simulated time, s.
    pub at: f64,
    /// How much (unit per [`Kind`]).
    pub size: f64,
    /// For this long, s (`None`: to the end of the run; a stall's length is its size).
    pub duration: Option<f64>,
}

impl Injection {
    /// Whether it acts at time `t`.
    pub fn active(&self, t: f64) -> bool {
        let len = match self.kind {
            Kind::WatchdogStall => Some(self.size),
            _ => self.duration,
        };
        t >= self.at && len.is_none_or(|d| t < self.at + d)
    }
}

impl fmt::Display for Injection {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}@{}", self.kind.name(), self.at)?;
        if self.kind.default_size() != 0.0 {
            write!(f, ":{}", self.size)?;
        }
        if let Some(d) = self.duration {
            write!(f, "+{d}")?;
        }
        Ok(())
    }
}

impl FromStr for Injection {
    type Err = String;

    /// `KIND@TIME[:SIZE][+DURATION]`.
    fn from_str(s: &str) -> Result<Self, String> {
        let names = || KINDS.iter().map(|k| k.1).collect::<Vec<_>>().join(", ");
        let (name, rest) = s.trim().split_once('@').ok_or_else(|| {
            format!("fault `{s}`: expected KIND@TIME[:SIZE][+DURATION], e.g. encoder-loss@2")
        })?;
        let &(kind, _, default) = KINDS
            .iter()
            .find(|k| k.1.eq_ignore_ascii_case(name.trim()))
            .ok_or_else(|| format!("fault `{s}`: unknown kind `{name}`; kinds: {}", names()))?;
        let (rest, duration) = match rest.split_once('+') {
            Some((r, d)) => (r, Some(number(s, "duration", d)?)),
            None => (rest, None),
        };
        let (at, size) = match rest.split_once(':') {
            Some((a, z)) => (number(s, "time", a)?, number(s, "size", z)?),
            None => (number(s, "time", rest)?, default),
        };
        if at < 0.0 || duration.is_some_and(|d| d <= 0.0) {
            return Err(format!(
                "fault `{s}`: the time must be ≥ 0 and a duration > 0"
            ));
        }
        let size_ok = match kind {
            Kind::CurrentScale => size >= 0.0,
            Kind::SupplySag | Kind::SupplySurge => size > 0.0 && size <= 60.0,
            Kind::Jam | Kind::Overload | Kind::WatchdogStall => size > 0.0,
            _ => true,
        };
        if !size_ok {
            return Err(format!(
                "fault `{s}`: size {size} is out of range for {name}"
            ));
        }
        Ok(Injection {
            kind,
            at,
            size,
            duration,
        })
    }
}

fn number(s: &str, what: &str, text: &str) -> Result<f64, String> {
    text.trim()
        .parse::<f64>()
        .ok()
        .filter(|v| v.is_finite())
        .ok_or_else(|| format!("fault `{s}`: bad {what} `{text}`"))
}

/// Parse a comma- or whitespace-separated list (a flag may be given several times as well).
pub fn parse_list(s: &str) -> Result<Vec<Injection>, String> {
    s.split(|c: char| c == ',' || c.is_whitespace())
        .filter(|p| !p.is_empty())
        .map(str::parse)
        .collect()
}

/// The most faults one run carries ([`Plan`] is `Copy`, as the simulation's configuration).
pub const MAX_FAULTS: usize = 8;

/// The faults of a run.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Plan {
    list: [Option<Injection>; MAX_FAULTS],
}

impl Plan {
    /// A plan of `faults` (at most [`MAX_FAULTS`]).
    pub fn new(faults: &[Injection]) -> Result<Plan, String> {
        let mut p = Plan::default();
        for f in faults {
            p.push(*f)?;
        }
        Ok(p)
    }

    /// Add one.
    pub fn push(&mut self, f: Injection) -> Result<(), String> {
        let slot = self
            .list
            .iter_mut()
            .find(|s| s.is_none())
            .ok_or_else(|| format!("at most {MAX_FAULTS} faults per run"))?;
        *slot = Some(f);
        Ok(())
    }

    /// The faults.
    pub fn iter(&self) -> impl Iterator<Item = &Injection> {
        self.list.iter().flatten()
    }

    /// No fault.
    pub fn is_empty(&self) -> bool {
        self.iter().next().is_none()
    }

    fn active(&self, t: f64, kind: Kind) -> Option<&Injection> {
        self.iter().filter(|f| f.kind == kind).find(|f| f.active(t))
    }

    /// The plant under the faults at `t`: battery voltage, extra load, jam torque.
    pub fn plant(&self, t: f64, battery: f64) -> PlantFaults {
        let battery = [Kind::SupplySag, Kind::SupplySurge]
            .iter()
            .find_map(|&k| self.active(t, k).map(|f| f.size))
            .unwrap_or(battery);
        PlantFaults {
            battery,
            extra_load: self.active(t, Kind::Overload).map_or(0.0, |f| f.size),
            jam_torque: self.active(t, Kind::Jam).map_or(0.0, |f| f.size),
        }
    }

    /// The hang active at `t` ends now (the watchdog reset rebooted the board).
    pub fn end_stall(&mut self, t: f64) {
        for f in self.list.iter_mut().flatten() {
            if f.kind == Kind::WatchdogStall && f.active(t) {
                f.size = (t - f.at).max(0.0);
            }
        }
    }

    /// Whether the control task hangs at `t`.
    pub fn stalled(&self, t: f64) -> bool {
        self.active(t, Kind::WatchdogStall).is_some()
    }

    /// The board's inputs under the sensor faults at `t`. `frozen` keeps the encoder count a
    /// lost encoder stopped at.
    pub fn inputs(&self, t: f64, inputs: &mut Inputs, frozen: &mut Option<u16>) {
        if self.active(t, Kind::EncoderLoss).is_some() {
            let n = *frozen.get_or_insert(inputs.encoder_count);
            inputs.encoder_count = n;
            inputs.encoder_edge_age = 0;
        } else {
            *frozen = None;
        }
        // The sensor's codes per ampere and its zero (host-sim's current sensor, `sensors`).
        use crate::twin::plant::sensors::{ADC_CODES, ADC_REF, CURRENT_GAIN, CURRENT_OFFSET};
        let per_amp = CURRENT_GAIN / ADC_REF * ADC_CODES;
        let zero = CURRENT_OFFSET / ADC_REF * ADC_CODES;
        let mut amps = (f64::from(inputs.current_raw) - zero) / per_amp;
        let mut changed = false;
        if let Some(f) = self.active(t, Kind::CurrentScale) {
            amps *= f.size;
            changed = true;
        }
        if let Some(f) = self.active(t, Kind::CurrentOffset) {
            amps += f.size;
            changed = true;
        }
        if changed {
            inputs.current_raw = (zero + amps * per_amp).round().clamp(0.0, ADC_CODES - 1.0) as u16;
        }
        let sw = &mut inputs.switches.0;
        for (dead, stuck, bit) in [
            (
                Kind::LowerSwitchDead,
                Kind::LowerSwitchStuck,
                Switches::LIMIT_LOWER,
            ),
            (
                Kind::UpperSwitchDead,
                Kind::UpperSwitchStuck,
                Switches::LIMIT_UPPER,
            ),
        ] {
            if self.active(t, dead).is_some() {
                *sw &= !bit;
            }
            if self.active(t, stuck).is_some() {
                *sw |= bit;
            }
        }
    }
}

/// The plant's parameters under the faults at one instant.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlantFaults {
    /// Battery open-circuit voltage, V.
    pub battery: f64,
    /// Mass added on the head, kg.
    pub extra_load: f64,
    /// Coulomb torque of a jam at the screw, N·m.
    pub jam_torque: f64,
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    #[test]
    fn the_text_form_round_trips_and_refuses_nonsense() {
        for s in [
            "encoder-loss@2",
            "current-offset@1.5:4",
            "supply-sag@3:9.5+0.5",
            "watchdog-stall@1:0.2",
            "lower-switch-dead@0",
        ] {
            let f: Injection = s.parse().unwrap();
            assert_eq!(f.to_string(), s);
        }
        assert_eq!(
            "jam@1".parse::<Injection>().unwrap().size,
            1000.0,
            "default size"
        );
        for bad in [
            "jam",
            "jam@",
            "teleport@1",
            "jam@-1",
            "supply-sag@1:0",
            "jam@1+0",
            "overload@1:nan",
        ] {
            assert!(bad.parse::<Injection>().is_err(), "{bad}");
        }
        assert_eq!(
            parse_list("jam@1, encoder-loss@2 overload@3:100")
                .unwrap()
                .len(),
            3
        );
    }

    #[test]
    fn sensor_faults_change_what_the_board_reads() {
        let plan = Plan::new(
            &parse_list("encoder-loss@1+1, current-offset@0:2, upper-switch-stuck@0").unwrap(),
        )
        .unwrap();
        let zero = (1.65 / 3.3 * 4096.0) as u16;
        let mut frozen = None;
        let mut i = Inputs {
            encoder_count: 100,
            current_raw: zero,
            ..Inputs::default()
        };
        plan.inputs(1.0, &mut i, &mut frozen);
        assert_eq!(i.encoder_count, 100);
        let amps = (f64::from(i.current_raw) - 1.65 / 3.3 * 4096.0) / (0.025 / 3.3 * 4096.0);
        assert!((amps - 2.0).abs() < 0.05, "{amps}");
        assert!(i.switches.is_active(Switches::LIMIT_UPPER));
        let mut j = Inputs {
            encoder_count: 180,
            ..Inputs::default()
        };
        plan.inputs(1.5, &mut j, &mut frozen);
        assert_eq!(j.encoder_count, 100, "still frozen");
        let mut k = Inputs {
            encoder_count: 200,
            ..Inputs::default()
        };
        plan.inputs(2.5, &mut k, &mut frozen);
        assert_eq!(k.encoder_count, 200, "back after the fault");
    }
}
