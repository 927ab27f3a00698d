//! A weighing creep at the start of a lowering (docs/model.md "A stick-slipping lowering",
//! docs/control.md "Load identification").
//!
//! A thread whose static friction exceeds its sliding friction (the dry law) stick-slips while
//! lowering, in cycles of a few milliseconds at the cruise speed: the motor's lag leaves their
//! breakaways unresolved in the current and their mean torque is no measure of the car
//! (`ident::LoadIdent::hold_start`). At a slow constant speed the cycles last tens to hundreds
//! of milliseconds and the current follows the coupling's wind-up to each breakaway (host-sim,
//! dry 1000 kg from 200 mm at 0.3 rad/s: 60 ms wind-ups, the measured torque within the drive's
//! own torque of the coupling's at the peaks). So a lowering that does not know its car (at
//! boot, after the lower stop) on such a thread starts at [`CREEP_SPEED`] until the stick-slip
//! detector has seen [`CREEP_BREAKAWAYS`] slips or [`CREEP_MS`] have passed, then ramps on to
//! the cruise. Its breakaways weigh the car: the stuck thread's torque at the breakaway is
//! M·|τ(1)| (`ident::stick::StuckLowering`). The lowering then keeps that load (a held
//! lowering: its own samples, light as they read, do not set it) and its T_r is the stuck
//! thread's mean over the sticks' wind-up.
//!
//! Cold: once at a lowering's start, a counter on the creep's ticks, once at its end.

use super::{Controller, FaultKind, State};
use crate::detect::stickslip::Reaction;
use crate::ident::pair::Breakaway;
use crate::ident::stick::StuckLowering;
use crate::units::{Instant, Kilograms, NewtonMetres, RadiansPerSecond, Q};

/// The creep's speed at the screw (at most the configured cruise): a tenth of the default
/// cruise, where host-sim's dry wind-ups last 60…150 ms at 700…1300 kg.
pub const CREEP_SPEED: RadiansPerSecond = RadiansPerSecond::lit("0.3");
/// Breakaways that end the creep.
pub const CREEP_BREAKAWAYS: u32 = 2;
/// The longest creep, ms: a light car's slips may fall below the detector's threshold, a
/// heavy one's first stick from rest may be long.
pub const CREEP_MS: u32 = 600;

/// Ticks from the creep's start before its peaks are watched: the ramp to the creep speed
/// (≤ 6 ms at the default 60 ms ramp to 3 rad/s) and the stick-slip detector's settling
/// (`detect::stickslip::SETTLE_MS`), with room.
const ARMED_TICKS: u32 = 32;
/// A peak counts while the drive's acceleration torque stays within this (`creep_tick`).
const CALM_TORQUE: NewtonMetres = NewtonMetres::lit("1");

/// The creep under way.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Creep {
    /// Creeping.
    pub(super) on: bool,
    /// Pieces of the start's checks left (`creep_tick`: one a tick, while the profile ramps
    /// to the creep speed and the detector settles), the next first.
    pending: u8,
    /// The pose's G_up and G_down (Q23 N/kg) and the law's μ(0), for the stuck thread's model.
    g: (i32, i32),
    mu0: crate::units::Ratio,
    /// The stuck thread's model at the creep's pose.
    stuck: Option<StuckLowering>,
    /// The least peak a first breakaway may have (Q16, the detector's mean): half the breakaway
    /// of the load the last lift's breakaways read, where the creep pairs with them (the lift's
    /// twist unwinds first, and its falls are no breakaways); else 0.
    gate: i32,
    /// Ticks of it, and of it since the measured torque first resisted the descent.
    ticks: u32,
    resisting: u16,
    /// The detector's breakaway count when it began.
    breakaways: u32,
    /// The largest 4-tick mean of the measured torque resisting the motion since the last
    /// breakaway (Q16, the detector's mean).
    max: i64,
    /// The accepted breakaways' peaks (Σ and count), and the detector's slips seen.
    sum: i64,
    count: u32,
    seen: u32,
    /// The first breakaway was seen last tick: the detector's flag is due (`confirm`).
    confirm_due: bool,
}

/// The start's pieces, one a tick: the state, the law's branch, its μ(0), G_up, G_down, the
/// stuck thread's model in two.
const PIECES: u8 = 7;

impl Controller {
    /// A lowering starts from rest: creep if it does not know its car (`ident::LoadIdent`'s load
    /// is the prior). The checks that need the law and the pose run on the next ticks
    /// (`creep_tick`): a button starts a lowering inside a control tick. Cold: once per motion.
    #[cold]
    #[inline(never)]
    pub(super) fn start_creep(&mut self) {
        // (Or to pair its breakaways with the last lift's while the scale is not known:
        // `Controller::breakaway_pair`.)
        let id = &self.loadid;
        let on = !self.holds_actively() && (!id.ident.identified() || id.lift_breakaway.is_some());
        let c = &mut self.loadid.creep;
        c.on = on;
        if on {
            // The rest of the creep's state is set by its first tick (`creep_check`).
            c.pending = PIECES;
            self.motion.profile.set_cruise(self.derived.creep_q32);
        }
    }

    /// One piece of the start's checks (the creep's first ticks): it creeps only where its law's
    /// friction falls with the speed at the cruise (the stick-slip detector's falling branch:
    /// sliding is unstable there, and the thread stick-slips: the dry law, not PTFE's or
    /// lithium's) and the lowering weighs the load at this pose (G_down ≥ G_up/8, as the
    /// pair); else the cruise goes back to the configured one.
    fn creep_check(&mut self) {
        let breakaways = self.breakaway_totals().1;
        let c = &mut self.loadid.creep;
        c.pending -= 1;
        let pos = self.live.enc.position();
        let go = match c.pending {
            6 => {
                // (No breakaway this early: the detector settles for 25 ms.)
                *c = Creep {
                    on: true,
                    pending: 6,
                    breakaways,
                    max: i64::MIN,
                    ..Creep::default()
                };
                true
            }
            5 => {
                let law = self.est.law();
                crate::detect::stickslip::falling_branch(law, self.derived.cfg.motion.cruise_speed)
            }
            4 => {
                c.mu0 = self.est.law().mu(RadiansPerSecond::ZERO);
                true
            }
            3 => {
                c.g.0 = self.est.g_per_kg(pos, 1);
                true
            }
            2 => {
                c.g.1 = self.est.g_per_kg(pos, -1);
                c.g.1 >= c.g.0 >> 3
            }
            1 => {
                let (up, down) = (i64::from(c.g.0), i64::from(c.g.1));
                c.stuck = StuckLowering::start(self.est.screw(), c.mu0, up, down);
                c.stuck.is_some()
            }
            _ => {
                let paired = self.loadid.lift_breakaway.is_some();
                let load = self.loadid.load;
                c.stuck.as_mut().is_some_and(|s| {
                    let ok = s.finish(self.est.screw());
                    c.gate = if paired {
                        crate::units::sat32(s.breakaway_torque(load) >> 1)
                    } else {
                        0
                    };
                    ok
                })
            }
        };
        if !go {
            c.on = false;
            self.motion.profile.set_cruise(self.derived.cruise_q32);
        }
    }

    /// A tick of the creep, while lowering: it ends after [`CREEP_BREAKAWAYS`] slips or
    /// [`CREEP_MS`].
    #[cold]
    #[inline(never)]
    pub(super) fn creep_tick(&mut self, now: Instant) {
        if self.loadid.creep.pending > 0 {
            self.creep_check();
            return;
        }
        if self.loadid.creep.confirm_due {
            self.loadid.creep.confirm_due = false;
            if self.motion.stick_slip.confirm().onset {
                self.stick_slip_onset();
            }
            return;
        }
        let n = self.breakaway_totals().1;
        let limit = CREEP_MS.saturating_mul(1000) / self.derived.cfg.estimator.tick_us.max(1);
        // (The detector's step comes later in the tick: its mean and its slips are both the
        // last tick's.)
        let mean = i64::from(self.motion.stick_slip.mean_torque());
        // A peak counts only while the rotor turns down at a steady speed, as it does winding
        // the coupling up to a breakaway: not while the current accelerates it (the drive's
        // acceleration torque J·n²·η·θ̈ above `CALM_TORQUE`) or it turns the other way. After
        // a lift on a dry thread the coupling may still swing the rotor to and fro when the
        // lowering starts (host-sim, dry 1000 kg on a thread twice as dry: ±1.3 rad/s at
        // ±150 rad/s² for 50 ms), and the current turning it around read as an 18 N·m
        // "breakaway" (3 332 kg: the lowering refused), where the thread's was 12.7.
        let e = &self.live.latest.estimate;
        let inertia =
            (i64::from(e.screw_accel.bits()) * i64::from(self.derived.drive_inertia)) >> 8;
        let calm = inertia.unsigned_abs() <= u64::from(CALM_TORQUE.bits().unsigned_abs())
            && e.screw_speed < RadiansPerSecond::ZERO;
        let c = &mut self.loadid.creep;
        c.ticks = c.ticks.saturating_add(1);
        // After a lift the coupling still holds the lift's twist: the creep unwinds it first
        // (the torque resists the descent from when it has: host-sim, dry 1000 kg 1.5× drier,
        // after ≈ 0.5 s at 0.3 rad/s), and the creep's time runs from there.
        if c.resisting > 0 || mean > 0 {
            c.resisting = c.resisting.saturating_add(1);
        }
        // From when the detector watches (its settling after the ramp to the creep): the
        // start's current (the rotor's acceleration) is no breakaway.
        if c.ticks >= ARMED_TICKS - u32::from(PIECES) && calm {
            c.max = c.max.max(mean);
        }
        let seen = n.wrapping_sub(c.breakaways);
        let mut done = u32::from(c.resisting) >= limit || c.ticks >= limit.saturating_mul(3);
        let mut first_breakaway = false;
        if seen > c.seen {
            // The detector saw a slip: the largest 4-tick mean since the last one is its peak
            // (the detector's own peak leaks while the current falls). The first from rest is
            // a breakaway; a later one only within a quarter of it: where the thread does not
            // self-lock while it slides (dry, 150 mm: μ falls with the slip's speed) the screw
            // runs ahead after a slip and the coupling swings through zero, which the detector
            // may also count (host-sim, dry 1300 kg from 150 mm: a second "peak" of −7 N·m
            // after a breakaway of 12).
            c.seen = seen;
            let first = c.sum;
            let was = c.count;
            if c.count == 0 && c.max <= i64::from(c.gate) {
                // No breakaway yet: the torque did not resist the descent, or not enough (the
                // lift's twist unwinding, its falls counted as slips).
            } else if c.count == 0 || c.max.abs_diff(first) <= (first >> 2).unsigned_abs() {
                c.count += 1;
                c.sum = c.sum.saturating_add(c.max.max(0));
            } else {
                done = true;
            }
            c.max = i64::MIN;
            first_breakaway = was == 0 && c.count == 1;
        }
        // The first breakaway: the thread stick-slips (the detector's flag on the next tick,
        // `confirm`: this one's budget has the breakaway's bookkeeping).
        c.confirm_due = first_breakaway;
        if c.count >= CREEP_BREAKAWAYS || done {
            self.end_creep(now);
        }
    }

    /// The creep's end: the car weighed by its breakaways (if any), the lowering held at that
    /// load (and refused above the overload limit), the cruise (or, after a stick-slip onset
    /// with the `speed` reaction, the escape speed).
    fn end_creep(&mut self, now: Instant) {
        self.loadid.creep.on = false;
        let out = self.motion.stick_slip.output();
        let cruise = if self.derived.cfg.stick_slip.reaction == Reaction::ChangeSpeed && out.active
        {
            self.derived.escape_q32
        } else {
            self.derived.cruise_q32
        };
        self.motion.profile.set_cruise(cruise);
        if let Some((m, b)) = self.creep_load() {
            let id = &mut self.loadid;
            id.creep_breakaway = b;
            id.ident.set_load(m);
            id.ident.hold_start();
            id.load = m;
            id.offset = id.ident.torque_offset(self.derived.cfg.rated_load);
            // An overload is refused here, before the car has come down a tenth of a
            // millimetre (the trip's floor: the driest thread the board still assumes).
            if id.ident.lowering_floor(m) > id.overload && self.live.state != State::Fault {
                self.latch(now, FaultKind::Overload);
            }
        }
    }

    /// The load the creep's breakaways give: their mean peak (the detector's, resisting the
    /// motion: the magnitude of the measured torque) less the model's own screw torque and the
    /// drive's no-load torque is the stuck thread's breakaway |P| = M·|τ(1)|, read at the
    /// creep's pose with the law in force's μ(0); and, paired with the last lift's
    /// (`Controller::breakaway_pair`), the mean breakaway. `None` without a breakaway.
    fn creep_load(&self) -> Option<(Kilograms, Option<Breakaway>)> {
        let c = &self.loadid.creep;
        if c.count == 0 || self.live.state != State::Lowering {
            return None;
        }
        // A 4-tick mean of the wind-up's ramp lags its last tick by 1.5 ticks of k_c·ω.
        let lag = i64::from(self.derived.creep_lag.bits());
        // (One or two breakaways: a shift, not a division.)
        let p = self.peak_thread_torque((c.sum >> (c.count - 1).min(1)) + lag, -1);
        let b = self.loadid.lift_breakaway.map(|_| Breakaway {
            torque: crate::units::NewtonMetres::from_raw(crate::units::sat32(-p)),
            g_per_kg: c.g.1,
        });
        Some((c.stuck?.load(p)?, b))
    }
}
