//! Motion control: the working state built with the configuration ([`Motion`]) and the tick's
//! motion phases: profile → speed loop → bridge and the arrival check, the bridge at rest, the
//! back-EMF speed, and the detectors that watch a motion (stick-slip, and on a ball screw the
//! friction identification).

use super::clip::{ClipTick, ClipTracker};
use super::derived::{Derived, ARRIVED_COUNTS};
use super::edges::EdgeInterpolator;
#[cfg(feature = "ball-screw")]
use super::lube;
use super::profile::Profile;
use super::protect::Monitors;
use super::sense::Debouncer;
use super::speed::{duty_q15, SpeedInputs, SpeedLoop};
use super::{hold, Bridge, Controller, Event, Reading, State};
use crate::detect::stickslip::{DetectorInputs, Reaction, StickSlipDetector};
use crate::units::{qmul, sat32, NewtonMetres, Radians, RadiansPerSecond, Volts, Q};

/// The working state of motion control, built with the configuration: a new configuration
/// (at rest) starts it afresh, but for the parts [`Controller::reconfigure`] names.
#[derive(Clone, Debug)]
pub(super) struct Motion {
    /// Sub-count position from the encoder's edge times, for the speed filter.
    pub(super) edges: EdgeInterpolator,
    pub(super) debounce: Debouncer,
    pub(super) profile: Profile,
    pub(super) speed: SpeedLoop,
    pub(super) monitors: Monitors,
    /// Ticks since the reference arrived (settling) and since the motion started.
    pub(super) settle_ticks: u32,
    pub(super) motion_ticks: u32,
    /// Where a ball screw is held at rest (set when the rest begins; see `hold`).
    pub(super) hold_target: i32,
    /// The profile's speed of the last tick in screw rad/s (`reference_speed`), converted
    /// once when the profile steps: the tick reads it up to four times.
    pub(super) last_ref_rad: RadiansPerSecond,
    /// The profile's position of the last tick, counts.
    pub(super) last_ref_counts: i32,
    /// Measured screw torque, low-passed (1/8 per tick: 20 Hz at 1 kHz), for the twist.
    pub(super) torque_lp: NewtonMetres,
    pub(super) last_duty: i16,
    pub(super) last_bridge: Bridge,
    /// Stick-slip detector (`crate::detect::stickslip`).
    pub(super) stick_slip: StickSlipDetector,
    /// Its breakaways the current limit clipped (`clip`).
    pub(super) clip: ClipTracker,
    /// The cruise speed of the motion under way when the motor cannot reach the configured one
    /// (`limit_cruise`).
    pub(super) cruise_limit: Option<RadiansPerSecond>,
    /// The motion's [`Event::CruiseLimited`] was reported.
    pub(super) cruise_reported: bool,
    /// The last driving tick found the screw lagging (the planner waited): a stall sign.
    pub(super) lagging: bool,
    /// A motion from rest has not driven yet: if the screw still turns the other way (a
    /// command on the tick after a switch stop or homing, the coupling unwinding), the bridge
    /// brakes or coasts (`rest_bridge`) and the profile waits until it turns slower than
    /// `estimator.rest_speed`. Driving against the back-EMF would plug the motor: at 1 rad/s
    /// of screw speed the current tripped the over-current limit.
    pub(super) reversing: bool,
    /// Ticks of regenerative braking left in this rest (`rest_bridge`).
    pub(super) regen_left: u16,
    /// The identification of the ball screw's friction.
    #[cfg(feature = "ball-screw")]
    pub(super) lube: lube::LubeMonitor,
    /// A lubrication warning (of `lube`'s latest report) waits for a tick without another event.
    #[cfg(feature = "ball-screw")]
    pub(super) lube_notice: bool,
    /// The holding brake (`hold.rs`).
    pub(super) brake: hold::BrakeState,
}

impl Motion {
    /// At rest at `position`.
    pub(super) fn new(d: &Derived, position: i32) -> Motion {
        let cfg = &d.cfg;
        let tick_us = cfg.estimator.tick_us;
        Motion {
            edges: EdgeInterpolator::new(),
            debounce: Debouncer::new(d.ticks.debounce),
            profile: Profile::new(position, d.cruise_q32, d.ticks.ramp, cfg.motion.ramp_shape),
            speed: SpeedLoop::default(),
            monitors: Monitors::default(),
            settle_ticks: 0,
            motion_ticks: 0,
            hold_target: position,
            last_ref_rad: RadiansPerSecond::ZERO,
            last_ref_counts: position,
            torque_lp: NewtonMetres::ZERO,
            last_duty: 0,
            last_bridge: Bridge::Coast,
            stick_slip: StickSlipDetector::new(&cfg.stick_slip, tick_us),
            clip: ClipTracker::default(),
            cruise_limit: None,
            cruise_reported: false,
            reversing: false,
            regen_left: 0,
            lagging: false,
            #[cfg(feature = "ball-screw")]
            lube: lube::LubeMonitor::new(
                &cfg.lube,
                &cfg.estimator.motor,
                cfg.estimator.drive.gear_ratio,
                tick_us,
            ),
            #[cfg(feature = "ball-screw")]
            lube_notice: false,
            brake: hold::BrakeState::new(&cfg.brake, tick_us),
        }
    }
}

impl Controller {
    /// Stick-slip detector step on this tick's measured torque (the current answers the bridge
    /// command of the previous tick, so "driving" is that command) and the reaction.
    pub(super) fn detect_stick_slip(&mut self, x: &Reading) {
        let state = self.live.state;
        let measured = x.estimate.measured_screw_torque;
        let d = DetectorInputs {
            driving: self.drives(),
            direction: if state == State::Lowering { -1 } else { 1 },
            reference: self.reference_speed(),
            // Lifting, the torque at the screw less the drive's acceleration torque
            // (J·n²·η·θ̈): the speed loop answers each slip, and with cycles of 23…27 ms the
            // rotor still slowed at the next breakaway, whose peak then read 1.1…1.3 N·m under
            // the coupling's where 45…62 ms cycles read it within 0.2 N·m (host-sim, dry
            // 500 kg from 200 mm, 700 kg from 260 mm: the breakaway load 6 % light; with it
            // taken out the peaks agree at both). Not lowering: the weighing creep's breakaways
            // were read without it (its own gate on that torque, `creep`), and at the creep's
            // end the tracking filter's θ̈ lags the current by a few ticks, swinging the
            // difference by ±6 N·m (every dry lowering of `host-sim estimate` misread).
            // In i32: |θ̈| ≤ ACCEL_MAX and J ≤ `derived::DETECTOR_INERTIA_MAX`.
            measured_torque: if state == State::Lowering {
                measured
            } else {
                let a = ((i64::from(x.estimate.screw_accel.bits())
                    * i64::from(self.derived.detector_inertia))
                    >> 8) as i32;
                // At most ±2 N·m (one `SSAT`): a breakaway's is ≈ 1 N·m; beyond, the slips'
                // own acceleration (the detector sees their falls either way) or a mis-set
                // `motor.inertia`, whose speed loop then swings the rotor by ±250 rad/s²
                // (10 000 µkg·m²: its stick-slip false alarm slowed a PTFE lift, and the
                // samples' acceleration torque at that inertia tripped the overload).
                let a = a.clamp(-(1 << 17), (1 << 17) - 1);
                NewtonMetres::from_raw(measured.bits().saturating_sub(a))
            },
        };
        let out = self.motion.stick_slip.step(&d, self.est.law());
        if out.onset {
            self.stick_slip_onset();
        }
        // One add and one compare on most ticks (|i| > c as (i + c) > 2c unsigned; the ADC's
        // current is far inside i32): the plateau's work only near the current limit.
        let c = self.derived.clip_current.bits();
        let near = (x.current.bits().wrapping_add(c) as u32) > (c as u32).wrapping_mul(2);
        if near || self.motion.clip.busy() {
            self.track_clip(x, near);
        }
    }

    /// A motion whose bridge drove on the last tick (this tick's current answers that command).
    #[inline(always)]
    fn drives(&self) -> bool {
        self.live.moving() && matches!(self.motion.last_bridge, Bridge::Drive(_))
    }

    /// A tick near the current limit, or after one (`clip`). Out of line and cold.
    #[cold]
    #[inline(never)]
    fn track_clip(&mut self, x: &Reading, near: bool) {
        let driving = self.drives();
        let (t, p) = (x.estimate.measured_screw_torque, self.live.enc.position());
        let lowering = self.live.state == State::Lowering;
        let tick = ClipTick {
            at_limit: near && driving,
            torque: if lowering { t.sat_neg() } else { t }.bits(),
            position: if lowering { p.saturating_neg() } else { p },
            breakaways: self.motion.stick_slip.breakaways(),
            slip: self.motion.stick_slip.output().slip,
        };
        self.motion.clip.step(&tick, self.derived.torque_per_count);
    }

    /// The stick-slip detector's breakaways (Σ peak, count) since boot, with what the current
    /// limit clipped off their peaks added back (`clip`).
    pub(super) fn breakaway_totals(&self) -> (i64, u32) {
        let (sum, n) = self.motion.stick_slip.breakaways();
        (sum.saturating_add(self.motion.clip.extra()), n)
    }

    /// The reaction to a stick-slip episode's onset, and its event: out of line and cold
    /// (once per episode).
    #[cold]
    #[inline(never)]
    pub(super) fn stick_slip_onset(&mut self) {
        let out = self.motion.stick_slip.output();
        let (amplitude, episode) = (out.amplitude, out.episodes);
        let reaction = self.derived.cfg.stick_slip.reaction;
        // (A creep keeps its speed: its end takes the escape speed, `creep`.)
        if reaction == Reaction::ChangeSpeed && !self.loadid.creep.on {
            self.motion.profile.set_cruise(self.derived.escape_q32);
        }
        if self.live.pending_event.is_none() {
            self.live.pending_event = Some(Event::StickSlip {
                amplitude,
                episode,
                reaction,
            });
        }
    }

    /// Ball screw: a sample of the friction identification while moving, the pair solve and
    /// the lubrication warning once at rest (`lube`).
    #[cfg(feature = "ball-screw")]
    pub(super) fn identify_friction(&mut self, x: &Reading) {
        let cfg = &self.derived.cfg;
        if self.live.moving() {
            let e = &x.estimate;
            let not_thread = e.model_screw_torque.sat_sub(e.thread_torque);
            let sample = lube::LubeInputs {
                driving: matches!(self.motion.last_bridge, Bridge::Drive(_)),
                lifting: self.live.state == State::Lifting,
                reference: self.reference_speed(),
                speed: e.screw_speed,
                thread_torque: e.measured_screw_torque.sat_sub(not_thread),
                axial_rated: e.axial,
            };
            self.motion.lube.sample(&cfg.lube, &sample);
        } else if self.motion.lube.in_motion() && self.live.state == State::Fault {
            // A motion a fault ended (an obstruction, a jam…) says nothing about the friction.
            self.motion.lube.abort_motion();
        } else if self.motion.lube.in_motion() {
            let lower = self.derived.lower_counts;
            let at_lower = self.live.enc.position() <= lower.saturating_add(ARRIVED_COUNTS);
            let report = self.motion.lube.end_motion(
                &self.derived.ball_screw,
                &cfg.lube,
                cfg.rated_load,
                at_lower,
            );
            if report.is_some_and(|r| r.out_of_band) {
                self.motion.lube_notice = true;
            }
        }
        if self.motion.lube_notice && self.live.pending_event.is_none() {
            self.motion.lube_notice = false;
            self.live.pending_event = self.motion.lube.report().map(Event::Lubrication);
        }
    }

    /// Screw speed from the motor's voltage balance, (V_a − R·i)/(k_e·n): independent of the
    /// encoder, so a dead encoder and a jammed screw can be told apart.
    pub(super) fn emf_speed(&self, x: &Reading) -> RadiansPerSecond {
        let va = Volts::from_raw(sat32(
            i64::from(x.supply.bits()) * i64::from(self.motion.last_duty) >> 15,
        ));
        let ri: Volts = qmul(x.current, self.derived.cfg.estimator.motor.resistance);
        qmul(va.sat_sub(ri), self.derived.inv_ke_n)
    }

    /// Profile → speed loop → bridge, and the arrival check.
    pub(super) fn drive(&mut self, x: &Reading) -> Bridge {
        let dir = if self.live.state == State::Lowering {
            -1
        } else {
            1
        };
        if self.motion.reversing {
            let w = x.estimate.screw_speed;
            if w.bits().signum() == -dir && w.sat_abs() > self.derived.cfg.estimator.rest_speed {
                return self.rest_bridge(x);
            }
            self.motion.reversing = false;
        }
        if let Some(releasing) = self.releasing_brake(x) {
            return releasing;
        }
        // The planner waits while the screw lags its reference by more than `lag_counts` (a
        // heavier load or a lower supply than `reachable_cruise` assumed): the reference never
        // runs ahead to the target and "arrives" with the head short of it, and lowering, its
        // ramp-down never leaves a lagging lift looking like a runaway.
        let behind = self
            .motion
            .last_ref_counts
            .saturating_sub(self.screw_position())
            .saturating_mul(dir);
        let mut done = false;
        let prev_ref = self.motion.last_ref_rad;
        // The planner holds a stuck screw's lag near `lag_counts`: past half of it, the drive
        // is pushing (the stall monitor's sign, steady while the planner steps and waits).
        let lag_counts = self.derived.lag_counts;
        self.motion.lagging = behind > lag_counts >> 1;
        if behind <= lag_counts {
            let r = self.motion.profile.step();
            let speed_scale = self.derived.speed_scale;
            self.motion.last_ref_rad =
                RadiansPerSecond::from_raw(speed_scale.apply32(sat32(r.speed >> 16)));
            self.motion.last_ref_counts = r.counts();
            done = r.done;
        } else {
            self.limit_cruise(x);
        }
        let reference = self.motion.last_ref_rad;
        let error_counts = self
            .motion
            .last_ref_counts
            .saturating_sub(self.screw_position());
        if done {
            self.motion.settle_ticks = self.motion.settle_ticks.saturating_add(1);
            let rest_speed = self.derived.cfg.estimator.rest_speed;
            let still = x.estimate.screw_speed.sat_abs() < rest_speed;
            if (error_counts.abs() <= ARRIVED_COUNTS && still)
                || self.motion.settle_ticks > self.derived.ticks.settle
            {
                self.enter_rest(State::Holding);
                return self.at_rest_bridge(x);
            }
        }
        // The rotor's and the gearbox input's acceleration torque for the reference's step this
        // tick (J·n·Δω/T at the motor shaft): the loop's feed-forward, so that the rotor follows
        // the ramp instead of lagging it until the integrator has wound up (and overshooting
        // once it has).
        let accel = (i64::from(reference.bits().wrapping_sub(prev_ref.bits()))
            * i64::from(self.derived.accel_ff))
            >> 16;
        Bridge::Drive(self.speed_duty(x, reference, error_counts, sat32(accel)))
    }

    /// The lift lags its reference by more than `lag_counts`: the motor cannot reach the
    /// profile's cruise at this load and supply (or a heavier car than the rated one). The
    /// reference waits this tick (the caller skips the planner), and the cruise steps toward
    /// the screw's measured speed + 1/16: down by at most 1/16 a lagging tick (a stick-slip
    /// stick, where the screw stands for a few ticks, barely lowers it), up to it at once (so
    /// the reference keeps leading a little and the limit finds what the motor reaches), never
    /// above `motion.cruise_speed`. The first limit of a motion is reported
    /// ([`Event::CruiseLimited`]). A profile faster than the lift ran
    /// ahead of it: the reference reached the target and the settling time ran out with the
    /// head short of it, and lowering, the reference's ramp-down made the lagging lift look
    /// like a runaway. Out of line: only on lagging ticks, which skip the planner's step.
    #[cold]
    #[inline(never)]
    fn limit_cruise(&mut self, x: &Reading) {
        let cruise = self.derived.cfg.motion.cruise_speed;
        let prev = self.motion.cruise_limit.unwrap_or(cruise);
        let step = prev.sat_sub(RadiansPerSecond::from_raw(prev.bits() >> 4));
        // Only while the reference cruises (not in its ramps: accelerating from rest the
        // screw lags and is slow for a moment whatever the motor can do).
        if self.motion.last_ref_rad.sat_abs() < step {
            return;
        }
        let w = x.estimate.screw_speed.sat_abs();
        let seen = w.sat_add(RadiansPerSecond::from_raw(w.bits() >> 4));
        let w = seen
            .max(step)
            .min(cruise)
            .max(const { RadiansPerSecond::lit("0.2") });
        if w >= cruise {
            return;
        }
        // Within 1/64 of the limit in force it is the speed estimate's jitter at the motor's top
        // speed (a few LSB), not a new speed: the limit stays. Re-set on every lagging tick, it
        // moved the reference by those LSB up to 178 times in 2 s, and the stick-slip detector,
        // which watches only a steady reference, never armed in a cruise-limited motion.
        if w.sat_sub(prev).sat_abs() > RadiansPerSecond::from_raw(prev.bits() >> 6) {
            self.motion.cruise_limit = Some(w);
            self.motion.profile.set_cruise(crate::math::mul_div_u64(
                self.derived.cruise_q32.unsigned_abs(),
                w.bits().unsigned_abs().into(),
                cruise.bits().unsigned_abs().max(1).into(),
            ) as i64);
        }
        // Reported once it has settled on what the screw does: the limit in force.
        if let Some(limit) = self.motion.cruise_limit {
            if !self.motion.cruise_reported && seen >= step && self.live.pending_event.is_none() {
                self.motion.cruise_reported = true;
                self.live.pending_event = Some(Event::CruiseLimited { speed: limit });
            }
        }
    }

    /// One step of the speed loop toward `reference` with `error_counts` of position error:
    /// the duty for moving and, for a ball screw, for holding at rest (`hold.rs`).
    pub(super) fn speed_duty(
        &mut self,
        x: &Reading,
        reference: RadiansPerSecond,
        error_counts: i32,
        accel_torque: i32,
    ) -> i16 {
        let d = &self.derived;
        self.motion.speed.step(
            &d.gains,
            &SpeedInputs {
                reference,
                position_error: Radians::from_raw(d.rad_per_count.apply32(error_counts)),
                measured: x.estimate.screw_speed,
                model_motor_torque: x
                    .estimate
                    .model_motor_torque
                    .sat_add(NewtonMetres::from_raw(accel_torque)),
                supply: x.supply,
                current_headroom: d.current_headroom,
                current: x.current,
                resistance: d.cfg.estimator.motor.resistance,
            },
        )
    }

    /// The bridge at rest: short the motor (dynamic brake) once it turns slowly enough that the
    /// short-circuit current k_e·ω/R stays within the brake limit; faster than that, brake
    /// regeneratively at that current where `regen_bridge` may, else coast. Braking matters:
    /// when a move ends, the wound-up coupling unwinds through the motor, and a coasting rotor
    /// would overshoot and drag the screw back (host-sim shows 0.7 mm of head height lost with
    /// dry threads); the brake damps it with a time constant J·R/k² of about 3 ms.
    pub(super) fn rest_bridge(&mut self, x: &Reading) -> Bridge {
        let w = x.estimate.screw_speed;
        if w.sat_abs() <= self.derived.brake_speed {
            self.motion.regen_left = 0;
            Bridge::Brake
        } else if self.motion.regen_left > 0 && self.live.state != State::Fault {
            self.regen_bridge(w, x.supply)
        } else {
            Bridge::Coast
        }
    }

    /// A motion ended above the brake speed (a limit switch, the homing switch, a stop before
    /// the brake took the load): drive with the motion at k_e·n·(|ω| − brake speed) =
    /// e − R·I_brake, so the current is −`BRAKE_AMPS` (the bridge returns the energy to the
    /// supply) and the rotor slows as fast as the low sides allow. Coasting instead carried an
    /// empty lift 0.54 mm past the lower switch at the end of a homing run.
    ///
    /// The encoder's speed sets this duty, so a lying encoder must not be able to drive a
    /// motor at rest: it only continues the drive of the tick before (never more duty than
    /// that tick, never the other way), at most `REGEN_MS` after the motion ended (set in
    /// `enter_rest`), never in a fault, and it ends for good at the first tick below the brake
    /// speed. Out of line: only on such ticks.
    #[cold]
    #[inline(never)]
    fn regen_bridge(&mut self, w: RadiansPerSecond, supply: Volts) -> Bridge {
        self.motion.regen_left -= 1;
        let last = self.motion.last_duty;
        let forward = w >= RadiansPerSecond::ZERO;
        if last == 0 || (last > 0) != forward {
            self.motion.regen_left = 0;
            return Bridge::Coast;
        }
        let over = w.sat_abs().sat_sub(self.derived.brake_speed);
        let v: Volts = qmul(over, self.derived.gains.ke_n);
        let d = duty_q15(v, supply).min(last.saturating_abs());
        Bridge::Drive(if forward { d } else { -d })
    }

    /// The profile's speed of the last tick in screw rad/s.
    #[inline]
    pub(super) fn reference_speed(&self) -> RadiansPerSecond {
        self.motion.last_ref_rad
    }
}
