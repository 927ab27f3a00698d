//! The controller's side of the load and friction identification (`crate::ident`): what a tick
//! hands it, the overload trip on the identified load, and what a motion's end does with a
//! lift/lowering pair (the law's scale, the lubrication warning, the store request).
//!
//! **Overload.** The trip compares the lowest load the measurements allow (the identified
//! load's interval, `ident::LoadIdent::interval`) with `(1 + protect.overload_margin)` × the
//! rated load, once a motion has identified its load (`ident::MIN_SAMPLES_MS` of steady ticks
//! after `ident::SETTLE_MS`: ≈ 0.2 s after the start at the default 60 ms ramp), lifting and
//! lowering alike. Its limit is a load, not a torque: it does not depend on the lubricant. A
//! thread drier than configured raises the torque like a heavier car would; the interval's lower
//! end takes the driest thread the board still considers possible, so a rated car on a thread up
//! to `ident::DRY_MAX` times drier never trips (its lift/lowering pair then warns about
//! lubrication).

use super::config::ControlConfig;
use super::derived::ARRIVED_COUNTS;
use super::{Bridge, Controller, Event, FaultKind, State};
use crate::estimator::Estimator;
use crate::ident::pair::Breakaway;
use crate::ident::{LoadIdent, MotionEnd, TickSample};
use crate::units::{qmul, sat32, Kilograms, NewtonMetres, RadiansPerSecond, Ratio, Q};

/// The controller's identification state: built with the configuration;
/// [`Controller::reconfigure`] keeps what was identified when the model stays the same.
#[derive(Clone, Copy, Debug)]
pub(super) struct Identification {
    /// The load and friction identification.
    pub(super) ident: LoadIdent,
    /// The identified load (or the prior): the load the status reports the model at.
    pub(super) load: Kilograms,
    /// The model's screw torque at `load` less its torque at the rated load (which the tick
    /// runs, for the speed loop's feed-forward): (L − L_rated)·g at the last gain, Q16.
    pub(super) offset: NewtonMetres,
    /// The last tick was a motion.
    moving: bool,
    /// The screw position where the motion began, and that the screw has since moved 64
    /// counts the commanded way (the identification's travel gate).
    screw_start: i32,
    travelled: bool,
    /// The estimator's pose segment of the last tick, and the ticks since it changed: a
    /// sample waits two ticks after the estimator entered a segment (those ticks compute the
    /// segment's pose nodes, the tick's most expensive).
    segment: i32,
    calm: u8,
    /// Stick-slip episodes at the end of the last motion.
    episodes: u32,
    /// The load limit of the overload trip.
    pub(super) overload: Kilograms,
    /// A friction scale waiting to be stored.
    pub(super) store: Option<Ratio>,
    /// Work left for the ticks at rest ([`Controller::rest_identification`]).
    rest_work: bool,
    /// A friction scale whose law the estimator is tabulating.
    rescaling: Option<Ratio>,
    /// Pieces of the interval's factors left to compute.
    interval_left: u8,
    /// The stick-slip detector's breakaway sums (Σ peak, count) when the motion began, and
    /// when it began (µs).
    breakaways: (i64, u32),
    start_us: u32,
    /// A lowering's weighing creep (`creep`).
    pub(super) creep: super::creep::Creep,
    /// The last lift's mean breakaway (a stick-slipping lift read by its breakaways) and the
    /// law's μ(0) at scale 1, while the scale is not known: the next lowering creeps to pair
    /// them with its own (`breakaway_pair`).
    pub(super) lift_breakaway: Option<(Breakaway, Ratio)>,
    /// This lowering's creep's mean breakaway, for that pair.
    pub(super) creep_breakaway: Option<Breakaway>,
    /// The load kept is a stick-slipping lift's (read by its breakaways), of the car still on
    /// the lift: its next lift's status reads T_r on the stuck thread from the start
    /// (`stick_slip_lift`).
    stuck_lift: bool,
}

impl Identification {
    /// For a (validated) configuration and its estimator, at rest at `position`.
    pub(super) fn new(cfg: &ControlConfig, est: &Estimator, position: i32) -> Identification {
        let ident = Controller::new_ident(cfg, est, None);
        Identification {
            load: ident.load(),
            offset: NewtonMetres::ZERO,
            ident,
            moving: false,
            screw_start: position,
            travelled: false,
            segment: 0,
            calm: 0,
            episodes: 0,
            overload: Controller::overload_limit(cfg),
            store: None,
            rest_work: false,
            rescaling: None,
            interval_left: 0,
            breakaways: (0, 0),
            start_us: 0,
            creep: super::creep::Creep::default(),
            lift_breakaway: None,
            creep_breakaway: None,
            stuck_lift: false,
        }
    }
}

/// `range` widened to hold a stuck reading's T_r (`Controller::friction_range`), itself
/// widened by the model's own accuracy (`ident::MODEL_BAND`), as the identification's. Out of
/// line: one copy for its three calls.
#[inline(never)]
fn widen(range: &mut (NewtonMetres, NewtonMetres), reading: Option<(Kilograms, NewtonMetres)>) {
    if let Some((_, t)) = reading {
        let m: NewtonMetres = qmul(t.sat_abs(), crate::ident::MODEL_BAND);
        range.0 = range.0.min(t.sat_sub(m));
        range.1 = range.1.max(t.sat_add(m));
    }
}

impl Controller {
    /// The identification for a (validated) controller: the rated load as the prior, the
    /// drive's no-load torque at the screw from `ballscrew.no_load_current` (k_t·I₀·n·η), the
    /// friction scale `stored` (from the store; `None`: the configured law), and the
    /// interval's factors at the cruise speed's μ.
    pub(super) fn new_ident(
        cfg: &ControlConfig,
        est: &Estimator,
        stored: Option<Ratio>,
    ) -> LoadIdent {
        let m = &cfg.estimator.motor;
        let t_motor: NewtonMetres = qmul(cfg.lube.no_load_current, m.torque_constant);
        let n = i64::from(cfg.estimator.drive.gear_ratio.to_bits()); // Q16
        let at_screw = NewtonMetres::from_raw(sat32((i64::from(t_motor.bits()) * n) >> 16));
        let bias: NewtonMetres = qmul(at_screw, m.gear_efficiency);
        let mut id = LoadIdent::new(cfg.rated_load, bias, stored, cfg.estimator.tick_us);
        id.set_drive_inertia(super::derived::sample_inertia_q8(
            m.inertia_ukgm2,
            cfg.estimator.drive.gear_ratio.to_bits(),
            m.gear_efficiency.bits(),
            cfg.estimator.tick_us,
        ));
        let mu = Self::cruise_mu(cfg, est, &id);
        id.set_interval(est.screw(), mu);
        id
    }

    /// The law's μ at the cruise speed, at scale 1 (the interval's factors take it).
    fn cruise_mu(cfg: &ControlConfig, est: &Estimator, id: &LoadIdent) -> Ratio {
        Self::unscaled_mu(est, id, cfg.motion.cruise_speed)
    }

    /// μ of the law in force at `speed`, back to scale 1 (the scale in force taken out).
    fn unscaled_mu(est: &Estimator, id: &LoadIdent, speed: RadiansPerSecond) -> Ratio {
        let mu_s = est.law().mu(speed);
        let scale = id.scale().bits().max(1);
        Ratio::from_raw(sat32((i64::from(mu_s.bits()) << 28) / i64::from(scale)))
    }

    /// One piece of the interval's factors (`LoadIdent::set_interval_piece`).
    fn ident_interval(cfg: &ControlConfig, est: &Estimator, id: &mut LoadIdent, piece: u8) {
        let mu = Self::cruise_mu(cfg, est, id);
        id.set_interval_piece(est.screw(), mu, piece);
    }

    /// The friction scale a stored record gives (at boot, before the first tick; or the one
    /// in force carried over a reconfiguration): the estimator runs the law scaled by it. A
    /// scale the law cannot take is ignored.
    pub fn restore_friction_scale(&mut self, scale: Ratio) {
        if self.est.set_friction_scale(scale).is_ok() {
            let id = &mut self.loadid;
            id.ident = Self::new_ident(&self.derived.cfg, &self.est, Some(scale));
            id.load = id.ident.load();
        }
    }

    /// One tick of the identification: a sample while driving at a steady reference, the end
    /// of a motion once at rest. After the protections, before the supervisor: the overload
    /// trip latches like theirs.
    /// Not on a ball screw (`drive.screw = ball`, ball-screw build): it is not self-locking,
    /// lowering back-drives it, and the identification's model (the loaded flank of a
    /// self-locking thread) does not hold there; that drive keeps its own friction
    /// identification (`lube`), its torque monitor and status at the rated load.
    #[inline]
    pub(super) fn identify_load(&mut self, now: crate::units::Instant, moving: bool, dir: i8) {
        if self.holds_actively() {
            return;
        }
        if moving {
            if !self.loadid.moving {
                self.loadid.moving = true;
                self.loadid.travelled = false;
                self.loadid.screw_start = self.screw_position();
                self.loadid.breakaways = self.breakaway_totals();
                self.loadid.start_us = now.0;
            }
            // The creep's ticks are no samples: its slow stick-slip is not the cruise's.
            let creeping = self.loadid.creep.on;
            if creeping {
                self.creep_tick(now);
            }
            // (Lowering, the settling waits for the screw to move, `screw_travelled`; a lift's
            // samples wait for it in `load_sample`.)
            let driving = matches!(self.motion.last_bridge, Bridge::Drive(_))
                && !creeping
                && (dir > 0 || self.screw_travelled(dir));
            let reference = self.motion.last_ref_rad;
            let braking = self.motion.profile.near_target();
            let segment = self.est.pose_segment_index();
            let id = &mut self.loadid;
            id.calm = if segment == id.segment {
                id.calm.saturating_add(1)
            } else {
                0
            };
            id.segment = segment;
            if id.ident.steady(driving, braking, reference) && id.calm >= 2 {
                self.load_sample(now, dir);
            }
        } else if self.loadid.moving {
            self.loadid.moving = false;
            self.loadid.creep.on = false;
            self.end_load_motion();
        } else if self.loadid.rest_work {
            self.rest_identification();
        }
    }

    /// A tick at rest with identification work left, from `ident::SETTLE_MS` on: one piece of
    /// it, so that no tick pays it all (`scripts/qemu-test` counts each piece): a step of the
    /// pair solve (one motion's load at one scale), then, when the pair changed the friction
    /// scale, the law's table rescaled in pieces (`Estimator::rescale_step`; the scaled law in
    /// force with the last), then the interval's four pieces. Out of
    /// line and cold: at rest only.
    #[cold]
    #[inline(never)]
    fn rest_identification(&mut self) {
        // The first ticks at rest stop the rotor and unwind the coupling (and cost more).
        if self.live.rest_ticks <= self.loadid.ident.settle_ticks() {
            return;
        }
        if let Some(scale) = self.loadid.rescaling {
            if !self.est.rescaling() {
                // The first tick takes the law in force times the scales' ratio.
                self.begin_rescale(scale);
            } else if self.est.rescale_step() {
                self.rescaled(scale);
            }
            return;
        }
        if let Some(piece) = self.loadid.interval_left.checked_sub(1) {
            self.loadid.interval_left = piece;
            Self::ident_interval(&self.derived.cfg, &self.est, &mut self.loadid.ident, piece);
            return;
        }
        if self.loadid.ident.solving() {
            if let Some(end) = self.loadid.ident.rest_step(self.est.screw()) {
                self.finish_identification(&end);
                let id = &mut self.loadid;
                id.load = id.ident.load();
                id.offset = id.ident.torque_offset(self.derived.cfg.rated_load);
            }
            return;
        }
        self.loadid.rest_work = false;
    }

    /// Start putting `scale` in force (`Estimator::begin_friction_scale`); a scale the law
    /// cannot take is dropped (the identification keeps the one in force).
    fn begin_rescale(&mut self, scale: Ratio) {
        if self.est.begin_friction_scale(scale).is_err() {
            self.loadid.rescaling = None;
            self.loadid.interval_left = crate::ident::INTERVAL_PIECES;
        }
    }

    /// The scaled law is in force: the identification runs with it from now on.
    fn rescaled(&mut self, scale: Ratio) {
        self.loadid.rescaling = None;
        self.loadid.ident.scale_applied(scale);
        self.loadid.interval_left = crate::ident::INTERVAL_PIECES;
    }

    /// Before a motion starts: a rescale under way completes now (its table must be one
    /// law's: up to ≈ 5 000 instructions, once, on the tick or command that starts the
    /// motion within ≈ 7 ms of a pair's end).
    #[cold]
    #[inline(never)]
    pub(super) fn finish_rescale(&mut self) {
        if let Some(scale) = self.loadid.rescaling {
            if !self.est.rescaling() {
                self.begin_rescale(scale);
            }
            if self.loadid.rescaling.is_some() {
                self.est.finish_rescale();
                self.rescaled(scale);
            }
        }
    }

    /// The screw has moved since the motion began (its twist-corrected position,
    /// `screw_position`, at least 64 counts the commanded way). Lowering, until then no tick is
    /// steady, and the settling runs from there. While the coupling winds up (or unwinds the last
    /// motion's twist) against a screw that does not move (a jam, the breakaway, a lowering
    /// after a lift) the encoder turns at the reference speed and the torque changes, which is
    /// not sliding, and the start of the sliding overshoots (host-sim estimate, report set 66 →
    /// 70 of 84: the samples had begun a settling after the reference became constant). Not
    /// counted while the current stands at its limit (`control::clip`): the rotor's momentum
    /// then winds the coupling on at a current that no longer grows, the twist reads short
    /// and a screw that never broke away seems to move (140 counts in host-sim, 1300 kg on a
    /// thread twice as dry as configured). (Later ticks where the planner waits for the screw
    /// stay in: a dry thread's stick phases are half of its mean.)
    #[inline]
    fn screw_travelled(&mut self, dir: i8) -> bool {
        if !self.loadid.travelled && !self.motion.clip.at_limit() {
            self.loadid.travelled = self
                .screw_position()
                .saturating_sub(self.loadid.screw_start)
                .saturating_mul(i32::from(dir))
                >= 64;
        }
        self.loadid.travelled
    }

    /// A steady tick's sample, and the overload trip on the identified load. Out of line:
    /// the ticks before the settling do not pay for it.
    #[inline(never)]
    fn load_sample(&mut self, now: crate::units::Instant, dir: i8) {
        // A lift's samples begin once its screw has moved (`screw_travelled`) after the
        // settling from the reference's cruise: a stick-slipping lift's breakaways count from
        // the motion's start and its samples should too (its settling from the screw's first
        // travel put the dry 700 kg lift's T_r at +5.0 % from +3.0 %, 200 mm).
        // (Once travelled it stays so for the motion: the call only until then.)
        if !self.loadid.travelled && !self.screw_travelled(dir) {
            return;
        }
        let e = &self.live.latest.estimate;
        let rated = self.derived.cfg.rated_load;
        let sample = TickSample {
            dir,
            load: rated,
            // The measured torque low-passed (1/8 a tick, the twist's filter): one tick in
            // `ident::DECIMATE` is a sample, the filter averages the ticks between.
            measured: self.motion.torque_lp,
            model: e.model_screw_torque,
            thread: e.thread_torque,
            axial: e.axial,
            speed: e.screw_speed.bits(),
            now_us: now.0,
            slipping: self.motion.stick_slip.output().active,
        };
        let (est, position) = (&self.est, self.live.enc.position());
        let id = &mut self.loadid;
        if !id.ident.add(&sample, || est.g_per_kg(position, dir)) {
            return;
        }
        // A window closed. A lowering that stick-slips keeps the load it began with from now
        // on (`LoadIdent::hold_start`: within a window of the detector's episode), if its car
        // can stick-slip as the detector sees it (`LoadIdent::resists`).
        let floor = self.derived.cfg.stick_slip.drop_threshold.bits() >> 2;
        if dir < 0 && self.motion.stick_slip.output().active && id.ident.resists(floor) {
            id.ident.hold_start();
        }
        id.load = id.ident.load();
        id.offset = id.ident.torque_offset(rated);
        if self.live.state != State::Fault {
            if let Some(floor) = id.ident.load_floor() {
                if floor > id.overload {
                    self.latch(now, FaultKind::Overload);
                }
            }
        }
    }

    /// The motion ended: its means kept, a pair solve started (the ticks at rest run it). Out
    /// of line and cold: once per motion.
    #[cold]
    #[inline(never)]
    fn end_load_motion(&mut self) {
        let lower = self.derived.lower_counts;
        let at_lower = self.live.enc.position() <= lower.saturating_add(ARRIVED_COUNTS);
        // A motion a fault ended says nothing about the friction; one that stick-slipped
        // (a detected episode) is marked: its pair may not conclude a wetter thread.
        let slipped = self.motion_slipped();
        self.loadid.episodes = self.motion.stick_slip.output().episodes;
        let fault = self.live.state == State::Fault;
        let dir = self.loadid.ident.direction();
        // A stick-slipping lift's load is its breakaways' (the status said so while it ran):
        // the load at rest and the next motion's start (a lowering that stick-slips keeps it).
        let breakaway = if slipped && !fault && !at_lower && dir > 0 {
            self.lift_breakaways(self.loadid.ident.reference())
        } else {
            None
        };
        self.loadid
            .ident
            .end_motion(self.est.screw(), self.est.law(), at_lower, fault, slipped);
        if let Some((m, _, _)) = breakaway {
            self.loadid.ident.set_load(m);
        }
        // A lift decides it; a lowering keeps it (the same car); the lower stop or a fault
        // forgets it with the load.
        if at_lower || fault {
            self.loadid.stuck_lift = false;
        } else if dir > 0 {
            self.loadid.stuck_lift = breakaway.is_some();
        }
        let lift = breakaway.map(|b| {
            let mu0 = Self::unscaled_mu(&self.est, &self.loadid.ident, RadiansPerSecond::ZERO);
            (b.2, mu0)
        });
        self.breakaway_pair(dir, lift, at_lower || fault);
        let id = &mut self.loadid;
        id.rest_work |= id.ident.solving();
        id.load = id.ident.load();
        id.offset = id.ident.torque_offset(self.derived.cfg.rated_load);
    }

    /// A motion in direction `dir` ended (`lost`: at the lower stop, where the car may change,
    /// or by a fault): a lift's breakaways `lift` are kept while the scale is not known; a
    /// lowering whose creep weighed the same car by its own makes a pair of them, which the
    /// ticks at rest solve for the scale (`ident::LoadIdent::breakaway_pair`).
    fn breakaway_pair(&mut self, dir: i8, lift: Option<(Breakaway, Ratio)>, lost: bool) {
        let id = &mut self.loadid;
        let down = id.creep_breakaway.take();
        if lost || id.ident.scale_known() {
            id.lift_breakaway = None;
        } else if dir > 0 {
            id.lift_breakaway = lift;
        } else if let (Some((up, mu0)), Some(down)) = (id.lift_breakaway, down) {
            id.ident.breakaway_pair(self.est.screw(), up, down, mu0);
            id.rest_work = true;
        }
    }

    /// A stick-slipping lift (a stick-slip episode in this motion, two breakaways or more,
    /// samples): its load from the breakaways (`ident::stick::lift`, the law in force at rest
    /// for μ(0)), at the samples' cruise reference, and T_r (the stuck thread's at the torque
    /// measured now while lifting, at the motion's mean at rest: `lift_breakaways`); before
    /// that, a lift of a car whose last lift was read so: the kept load, and T_r on the stuck
    /// thread from the start. From the first episode to the motion's end, braking included,
    /// and on the tick the lift comes to rest before `end_load_motion` keeps the reading (`end_load_motion` takes the same motions: the
    /// status and a fault's snapshot said the mean torque's load, ≈ 30 % light, while the
    /// lift braked and on that tick). `None` otherwise. At the status, not in the tick.
    #[inline(never)]
    pub(super) fn stick_slip_lift(&self) -> Option<(Kilograms, NewtonMetres)> {
        // (A ball screw has no samples, `identify_load`: `None` below.)
        let id = &self.loadid;
        let lifting = self.live.state == State::Lifting || (id.moving && id.ident.direction() > 0);
        if !lifting {
            return None;
        }
        if self.motion_slipped() {
            if let Some(r) = self.breakaway_lift(id.ident.reference()) {
                return Some(r);
            }
        }
        // The car's last lift stick-slipped (its load is that lift's breakaways'): until this
        // lift's own samples, its thread is stuck from rest, as each stick after, and T_r is
        // the stuck thread's at the torque measured now, at the kept load. The sliding model
        // there read 37 % high until the breakaways took over (≈ 0.15 s of cruise; host-sim,
        // dry 1000 kg on a 1.5× drier thread, the third move after the pair: +3.6 % over the
        // cruise).
        if !id.stuck_lift || self.live.state != State::Lifting || id.ident.thread_sum().1 != 0 {
            return None;
        }
        let (g_up, g_down, mu0) = self.stuck_terms(self.live.enc.position());
        let torque = self.measured_thread_torque(1);
        let screw = self.est.screw();
        let tr = crate::ident::stick::lift_friction(screw, mu0, g_up, g_down, id.load, torque)?;
        Some((id.load, tr))
    }

    /// What a stuck lifting thread's model takes at the pose `pos` (encoder counts): the axial
    /// force per kilogram lifting and lowering (Q23 N/kg) and the law in force's μ(0). Inlined
    /// in its three callers (out of line it cost 68 B of flash, with the third 216 B).
    #[inline(always)]
    fn stuck_terms(&self, pos: i32) -> (i64, i64, Ratio) {
        (
            i64::from(self.est.g_per_kg(pos, 1)),
            i64::from(self.est.g_per_kg(pos, -1)),
            self.est.law().mu(RadiansPerSecond::ZERO),
        )
    }

    /// A held lowering (one that stick-slips: `ident::LoadIdent::hold_start`, or weighed by its
    /// creep): its load, and its mean T_r as the stuck thread's over the sticks' wind-up, from
    /// the breakaway to the trough the mean measured thread torque of its samples implies
    /// (`ident::stick::StuckLowering::friction`; the sliding model's T_r at that load is
    /// 17…27 % off the plant's mean over stick and slip). `None` otherwise, or before its
    /// first sample. At the status, not in the tick.
    fn stick_slip_lower(&self) -> Option<(Kilograms, NewtonMetres)> {
        if !self.loadid.ident.held() {
            return None;
        }
        self.stuck_lowering(Ratio::ONE, self.loadid.load)
    }

    /// A lowering's load and mean T_r read as a stuck thread's (`stick_slip_lower`), for the
    /// load `load` at the scale in force, on a thread `f` times as dry: the stuck thread's
    /// breakaway of that load, P = M·|τ(1)|, read at μ(0)·f for the load there, and that
    /// load's mean T_r over the wind-up at the same mean torque. `None` while not lowering, or
    /// before its first sample.
    #[inline(never)]
    fn stuck_lowering(&self, f: Ratio, load: Kilograms) -> Option<(Kilograms, NewtonMetres)> {
        let id = &self.loadid;
        if self.live.state != State::Lowering {
            return None;
        }
        let (t, k) = id.ident.thread_sum();
        // Before its first sample (the creep weighed it; the settling after the ramp to the
        // cruise, ≈ 0.12 s) the low-passed measured thread torque stands in for the mean: the
        // sliding model's T_r at that load is 55 % above the stuck thread's mean there (host-sim,
        // dry 1300 kg from 150 mm: −13.9 against −8.9 N·m, 0.4 N·m of the cruise's mean).
        let mean = if k == 0 {
            self.measured_thread_torque(-1)
        } else {
            t / i64::from(k)
        };
        // The mean torque's pose (as a lift's breakaways; read at the pose of the moment, the
        // load gain 2.6 % above it by the end of a cruise from 150 mm, T_r read 1…2 % heavy).
        let pos = if k == 0 {
            self.live.enc.position()
        } else {
            self.motion_mid_pose()
        };
        let (up, down, mu0) = self.stuck_terms(pos);
        let screw = self.est.screw();
        use crate::ident::stick::StuckLowering;
        // (qmul by one is exact: at one, the model in force.)
        let at = StuckLowering::new(screw, qmul(mu0, f), up, down)?;
        let load = if f == Ratio::ONE {
            load
        } else {
            // The breakaway of `load` at the scale in force, read at f.
            at.load(StuckLowering::new(screw, mu0, up, down)?.breakaway_torque(load))?
        };
        Some((load, at.friction(screw, load, mean)?))
    }

    /// The stated range of the status's T_r `tr` (the stated load interval's heavy end
    /// `load_hi`): the identification's
    /// (`ident::LoadIdent::friction_range`: the same thread torque explained at the ends of
    /// the scale band, on the sliding model), widened to hold a lowering's stuck readings. A
    /// held lowering (`stick_slip_lower`): its stuck reading at the scale band's ends, where
    /// the sliding factors are no measure of it (host-sim, dry 1000 kg lowering on a thread
    /// 1.5× drier, before the pair: the reading −9.52 N·m, the sliding range −10.76…−7.92,
    /// the plant's −6.81; the stuck reading at 2× −6.02, at 0.8× −11.48). Any other lowering
    /// on a law whose friction falls with the speed (the stick-slip detector's falling branch:
    /// the dry law) may stick-slip unseen, in cycles too short for the current: the stuck
    /// reading of the load interval's heaviest end (host-sim, dry 700 kg from 260 mm, the
    /// creep counting no breakaway: the sliding model's −2.13 N·m in −2.58…−1.59, the
    /// plant's −2.93 over a cruise the thread stands most of). A lowering read on the
    /// reversed flank (`reversed`: `lowering_load`, an empty head) states the loaded flank's
    /// interval beside its reading, so the range holds T_r at the interval's heavy end too
    /// (host-sim, PTFE 100 kg lowering from 260 mm, seed 204: the reading 0 kg in 0…254 kg,
    /// T_r −0.072…−0.004 N·m before, the plant's −0.125). At the status (up to three stuck
    /// readings, each a bisection); out of line: inlined into the status it cost 4 B more.
    #[inline(never)]
    pub(super) fn friction_range(
        &self,
        tr: NewtonMetres,
        load_hi: Kilograms,
        reversed: bool,
    ) -> (NewtonMetres, NewtonMetres) {
        let id = &self.loadid.ident;
        let mut range = id.friction_range(tr);
        if reversed {
            widen(&mut range, Some((load_hi, self.friction_at_load(load_hi))));
        }
        if id.held() {
            let (wet, dry) = id.scale_band_factors();
            widen(&mut range, self.stuck_lowering(wet, self.loadid.load));
            widen(&mut range, self.stuck_lowering(dry, self.loadid.load));
        } else if self.motion.stick_slip.output().falling_branch {
            widen(&mut range, self.stuck_lowering(Ratio::ONE, load_hi));
        }
        range
    }

    /// The motion under way (or the one just ended, until `end_load_motion` counts it) had a
    /// stick-slip episode: one is under way, or one started since the last motion ended.
    fn motion_slipped(&self) -> bool {
        let out = self.motion.stick_slip.output();
        out.active || out.episodes != self.loadid.episodes
    }

    /// [`Self::stick_slip_lift`]'s reading of this lift's breakaways at the cruise reference
    /// `reference` (also at its end, at rest: `end_load_motion`).
    fn breakaway_lift(&self, reference: RadiansPerSecond) -> Option<(Kilograms, NewtonMetres)> {
        self.lift_breakaways(reference).map(|(m, tr, _)| (m, tr))
    }

    /// [`Self::breakaway_lift`], and the mean breakaway (`ident::LoadIdent::breakaway_pair`).
    #[inline(never)]
    fn lift_breakaways(
        &self,
        reference: RadiansPerSecond,
    ) -> Option<(Kilograms, NewtonMetres, Breakaway)> {
        let (t, k) = self.loadid.ident.thread_sum();
        if k == 0 {
            return None;
        }
        let mean = t / i64::from(k);
        let kc = i64::from(
            self.derived
                .cfg
                .estimator
                .mechanics
                .coupling_stiffness
                .bits(),
        );
        let w = i64::from(reference.bits()).abs();
        // The breakaways and the samples spread over the motion's travel (the stick-slip runs
        // from its start): their means belong to the pose half-way (the load gain falls as the
        // lift rises, by ≈ 2 % over 6 mm from 17.5°: read at the pose of the moment the mean
        // breakaway read a car 33 kg heavier by the end of that travel, host-sim, dry 1300 kg).
        let pos = self.motion_mid_pose();
        let (g_up, g_down, mu0) = self.stuck_terms(pos);
        let g_r = (g_up + g_down) / 2;
        let screw = self.est.screw();
        let rho1 = crate::ident::pair::rho_q32(screw, mu0, 1)?;
        let rho0 = crate::ident::pair::rho_q32(screw, Ratio::ZERO, 1)?;
        let (peak, m, slow) = match self.slow_breakaways(mean, kc, w) {
            Some((peak, drop)) => (
                peak,
                crate::ident::stick::lift(peak, drop, rho1, rho0, g_up, g_r),
                true,
            ),
            None => {
                let peak = self.fast_breakaway(mean, kc, w)?;
                (peak, crate::ident::stick::load(peak, rho1, g_up), false)
            }
        };
        let m = m?;
        // T_r while the lift runs: the stuck thread's at the thread torque the current
        // measures now (low-passed), not at the motion's mean. The slow sticks last `LAG_MAX`
        // ticks or more, so the current follows each wind-up, and T_r with it rises from the
        // trough to the breakaway (host-sim, dry 500 kg from 150 mm: 2.7 → 25.5 N·m over a
        // 48 ms stick); at the mean the status read a constant, and the first windows' means,
        // over part of a cycle, read it up to 40 % high. Fast cycles, and at rest: the mean.
        let at = if slow && self.live.state == State::Lifting {
            self.measured_thread_torque(1)
        } else {
            mean
        };
        let tr = crate::ident::stick::lift_friction(screw, mu0, g_up, g_down, m, at)?;
        let b = Breakaway {
            torque: NewtonMetres::from_raw(sat32(peak)),
            g_per_kg: sat32(g_up),
        };
        Some((m, tr, b))
    }

    /// A slow stick-slip's mean breakaway P and fall (Q16 N·m) from the detector's peaks, at
    /// the motion's mean thread torque `mean`, coupling stiffness `kc` and reference speed `w`
    /// (Q16): `None` unless its sticks are sticks from rest whose peaks the current resolves.
    fn slow_breakaways(&self, mean: i64, kc: i64, w: i64) -> Option<(i64, i64)> {
        let (sum, n) = self.breakaway_totals();
        let n = n.wrapping_sub(self.loadid.breakaways.1);
        if n < 2 {
            return None;
        }
        let peak = self.peak_thread_torque(
            sum.saturating_sub(self.loadid.breakaways.0) / i64::from(n),
            1,
        );
        // Over the motion (not the last slip alone, whose outliers made the estimate come and
        // go): a linear wind-up from the trough to the breakaway has its mean half-way, so the
        // slips fall by 2·(P − T̄); they come every (time since the motion began)/slips ticks.
        let drop = peak.saturating_sub(mean).saturating_mul(2);
        let tick_us = self.derived.cfg.estimator.tick_us;
        let tick = i64::from(tick_us);
        let elapsed = self
            .loadid
            .ident
            .last_tick_us()
            .wrapping_sub(self.loadid.start_us);
        // (In u32: native divisions, not the 64-bit runtime's.)
        let interval = i64::from(
            elapsed
                .checked_div(tick_us)
                .and_then(|t| t.checked_div(n))
                .unwrap_or(0),
        );
        // A stick from rest lasts the coupling's wind-up by the slip's fall at the reference
        // speed, drop/(k_c·ω) (within 2×: the speed loop lets the motor run faster than the
        // reference right after a slip): ripples and noise fall far more rarely than that. And
        // it is slow stick-slip, periods beyond `LAG_MAX` ticks, whose peaks the current
        // resolves: faster cycles reach it through the motor's electromechanical lag as a
        // ripple (`detect::stickslip`; [`Self::fast_breakaway`]).
        if interval < crate::detect::stickslip::LAG_MAX as i64 {
            return None;
        }
        let wind = drop
            .saturating_mul(1_000_000 << 16)
            .checked_div(kc.saturating_mul(w).saturating_mul(tick))?;
        if interval > wind.saturating_mul(2) {
            return None;
        }
        Some((peak, drop))
    }

    /// A fast stick-slip's breakaway P (Q16 N·m), from its period: cycles of 5…16 ticks (dry
    /// lifts of 250 kg from 150 mm, 500 kg from 260 mm: 7 and 8.5 ms) reach the current as a
    /// ripple whose peaks are not the breakaways, but the detector's periodicity test finds
    /// their period T. Each stick winds the coupling at k_c·ω until the breakaway P, and the
    /// slip, half a period of the screw on the coupling (t_s = π·√(I/k_c), ≈ 0.4 ms), lets it
    /// fall to T₀: the torque is a sawtooth between them whose mean is the motion's T̄, and
    /// its fall is k_c·ω·(T − t_s), so P = T̄ + k_c·ω·(T − t_s)/2. `None` while the torque is
    /// not periodic.
    fn fast_breakaway(&self, mean: i64, kc: i64, w: i64) -> Option<i64> {
        let period_q8 = self.motion.stick_slip.fast_period_q8()?;
        let cfg = &self.derived.cfg.estimator;
        crate::ident::stick::periodic_breakaway(
            mean,
            period_q8,
            kc,
            w,
            cfg.tick_us,
            cfg.mechanics.inertia_ukgm2,
        )
    }

    /// The pose half-way along the motion's travel so far (encoder counts): where means over
    /// the motion's samples and breakaways belong.
    fn motion_mid_pose(&self) -> i32 {
        ((i64::from(self.live.enc.position()) + i64::from(self.loadid.screw_start)) >> 1) as i32
    }

    /// What the current carries beside the thread's torque while moving in direction `dir`
    /// (Q16, signed): the model's own screw torque (inertia, damping, support) and the drive's
    /// no-load torque.
    fn own_torque(&self, dir: i8) -> i64 {
        let e = &self.live.latest.estimate;
        i64::from(e.model_screw_torque.bits()) - i64::from(e.thread_torque.bits())
            + self.loadid.ident.drive_bias(dir)
    }

    /// The thread torque the current measures while moving in direction `dir` (Q16, signed):
    /// the low-passed measured torque less [`Self::own_torque`]. At the status, not in the tick.
    fn measured_thread_torque(&self, dir: i8) -> i64 {
        i64::from(self.motion.torque_lp.bits()) - self.own_torque(dir)
    }

    /// A peak of the measured torque resisting the motion in direction `dir` (Q16: the
    /// stick-slip detector's 4-tick means) as the thread's torque resisting it: less
    /// [`Self::own_torque`], as the samples. The breakaway readings of a lift and of a
    /// lowering's creep.
    pub(super) fn peak_thread_torque(&self, peak: i64, dir: i8) -> i64 {
        peak - i64::from(dir.signum()) * self.own_torque(dir)
    }

    /// What the status reports beside the mean torque's identification, computed once: a
    /// stick-slipping lift's load and mean T_r from its breakaways, else an empty head
    /// lowering's load on the reversed flank. At the status, and once when a fault latches
    /// (its snapshot names the same load).
    pub(super) fn load_readings(&self) -> (Option<(Kilograms, NewtonMetres)>, Option<Kilograms>) {
        let stick = self.stick_slip_lift().or_else(|| self.stick_slip_lower());
        let lowering = if stick.is_none() {
            self.lowering_load()
        } else {
            None
        };
        (stick, lowering)
    }

    /// The load the status reports (`load_readings`, else the identification's) and whether it
    /// was measured (`false`: the prior).
    pub(super) fn reported_load(&self) -> (Kilograms, bool) {
        match self.load_readings() {
            (Some((m, _)), _) | (None, Some(m)) => (m, true),
            (None, None) => (self.loadid.load, self.loadid.ident.identified()),
        }
    }

    /// A lowering's load on the reversed flank, where its torque is an empty (or nearly empty)
    /// head's (`ident::LoadIdent::reversed_flank_load`), while it runs and at rest after it:
    /// the status reports it. At the status.
    pub(super) fn lowering_load(&self) -> Option<Kilograms> {
        let moving = self.live.moving();
        if moving && self.live.state != State::Lowering {
            return None;
        }
        self.loadid
            .ident
            .reversed_flank_load(self.est.screw(), self.est.law(), moving)
    }

    /// The model's friction torque T_r at `load` (the identified load, or a lowering's
    /// reading on the reversed flank, `lowering_load`): the tick's estimate runs the
    /// model at the rated load, and at a pose and speed |T_r| is proportional to the axial
    /// demand |W| = |M·G_d + D| (friction opposes the motion on either flank), so
    /// T_r(L) = T_r(L_r)·|W + (L − L_r)·G_d|/|W| (one division, here: the status, not the tick).
    /// At rest before any motion (no direction yet) lifting's G_d.
    pub(super) fn friction_at_load(&self, load: Kilograms) -> NewtonMetres {
        let e = &self.live.latest.estimate;
        if self.holds_actively() {
            // A ball screw: no load identification (`identify_load`), the model at the rated load.
            return e.friction_torque;
        }
        let dir: i8 = match self.live.state {
            State::Lowering => -1,
            State::Lifting => 1,
            _ => 0,
        };
        if dir != 0 && !self.loadid.ident.identified() {
            // No evidence yet (the settling after the start's ramp, the first windows): the
            // thread torque the current measures (low-passed, less the model's own screw
            // torque and the drive's no-load torque) instead of the prior's,
            // T_r = T_r(L_r)·T_measured/T_model (the same proportionality, on this tick's
            // torques), both directions. Lowering, the thread torque is small and the ratio
            // noisy, but unbiased: the prior (the rated load) is not. Bounded by the prior's
            // stated range, ±2·T_r(L_r).
            let thread = i64::from(e.thread_torque.bits());
            let measured = self.measured_thread_torque(dir);
            if thread.unsigned_abs() >= 1 << 12 {
                let tr = i64::from(e.friction_torque.bits());
                // |tr| < 2^31: 2·|tr| fits (no `clamp`: its panic path costs flash).
                let t = tr.saturating_mul(measured) / thread;
                // Friction opposes the motion: a ratio of the other sign than the model's
                // T_r is the start's transients (the rotor's overshoot, the coupling
                // unwinding: host-sim, PTFE 250 kg lowering read +2 N·m against −1 N·m), and
                // reads 0.
                let t = if t.signum() == tr.signum() {
                    t.signum() * t.saturating_abs().min(2 * tr.saturating_abs())
                } else {
                    0
                };
                return NewtonMetres::from_raw(sat32(t));
            }
        }
        let w = i64::from(e.axial.bits());
        let dl = i64::from(load.bits()) - i64::from(self.derived.cfg.rated_load.bits());
        if dl == 0 || w.unsigned_abs() < 256 {
            return e.friction_torque;
        }
        let dir = if dir == 0 {
            self.loadid.ident.direction()
        } else {
            dir
        };
        let g = i64::from(self.est.g_per_kg(self.live.enc.position(), dir));
        // W' = W + ΔL·G (Q8: Q12·Q23 → Q35).
        let w2 = w + ((dl * g) >> 27);
        let tr = i64::from(e.friction_torque.bits());
        NewtonMetres::from_raw(sat32(
            tr.saturating_mul(w2.saturating_abs()) / w.saturating_abs(),
        ))
    }

    /// What a pair produced: the scaled law (taken, then its table rescaled, by the next ticks
    /// at rest, then the interval's factors), the warning, the store request.
    fn finish_identification(&mut self, end: &MotionEnd) {
        if end.rescale {
            self.loadid.rescaling = Some(end.scale);
        } else {
            // The scale's band narrowed (a measured scale): the interval follows.
            self.loadid.interval_left = crate::ident::INTERVAL_PIECES;
        }
        let id = &mut self.loadid;
        if end.store.is_some() {
            id.store = end.store;
        }
        if end.lubrication && self.live.pending_event.is_none() {
            self.live.pending_event = Some(Event::ThreadDry(id.ident.report()));
        }
    }

    /// The friction scale to write to the store, once (the firmware's storage task takes it).
    pub fn take_friction_store(&mut self) -> Option<Ratio> {
        self.loadid.store.take()
    }

    /// The load limit: `(1 + protect.overload_margin)` × the rated load.
    pub(super) fn overload_limit(cfg: &ControlConfig) -> Kilograms {
        cfg.rated_load
            .sat_add(qmul(cfg.rated_load, cfg.protection.overload_margin))
    }

    /// The profile's speed reference of the last tick, screw rad/s (signed).
    pub fn reference(&self) -> crate::units::RadiansPerSecond {
        self.reference_speed()
    }

    /// A lift's and a lowering's means kept and their pair solve under way, as at the end of a
    /// lowering that followed a lift (the QEMU harness counts the ticks at rest that run it).
    #[cfg(feature = "bench-hooks")]
    pub fn bench_pair(
        &mut self,
        up: crate::ident::pair::MotionMeans,
        down: crate::ident::pair::MotionMeans,
    ) {
        self.loadid.ident.bench_pair(self.est.screw(), up, down);
        self.loadid.rest_work = true;
    }

    /// The identification's state (tests, host-sim).
    pub fn load_ident(&self) -> &LoadIdent {
        &self.loadid.ident
    }
}
