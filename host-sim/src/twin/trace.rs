//! Ground truth recorded for every run, and its CSV export.

use crate::twin::plant::{Flank, Phase};
use std::io::{self, Write};

/// One sample of the plant's true state (SI units; angles in rad, α in degrees for reading).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Record {
    /// Time, s.
    pub t: f64,
    /// Coupling input angle θ_i (gear output), rad.
    pub theta_i: f64,
    /// Screw angle θ, rad (0 with the arms at α₀).
    pub theta: f64,
    /// Screw rate θ̇, rad/s.
    pub theta_dot: f64,
    /// Coupling twist θ − θ_i, rad (0 at the start).
    pub twist: f64,
    /// Arm angle α, degrees.
    pub alpha_deg: f64,
    /// Head height, m.
    pub height: f64,
    /// Axial load R, N.
    pub r: f64,
    /// Pin friction F₀, N.
    pub f0: f64,
    /// Structure damping c_x, kg/s.
    pub c_x: f64,
    /// Friction coefficient in use μ (while stuck: the mobilised static coefficient).
    pub mu: f64,
    /// Signed coefficient μ_s.
    pub mu_s: f64,
    /// Thread normal force N, N (negative: reversed flank).
    pub normal: f64,
    /// Thread friction torque T_r, N·m.
    pub friction_torque: f64,
    /// Coupling torque k(θ_i − θ), N·m.
    pub coupling_torque: f64,
    /// Stick/slip phase.
    pub phase: Phase,
    /// Carrying flank.
    pub flank: Flank,
    /// Motor current, A (closed loop; 0 in paper mode).
    pub current: f64,
    /// Armature voltage, V.
    pub armature_voltage: f64,
    /// Bridge supply voltage, V.
    pub bus_voltage: f64,
    /// Signed bridge duty (0 when coasting or braking).
    pub duty: f64,
    /// Motor speed, rad/s.
    pub motor_speed: f64,
    /// Energy terms, J.
    pub energy: Energy,
}

/// Energy bookkeeping since the start of the run, J.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Energy {
    /// Work the gear output did on the coupling, ∫ T_c·θ̇_i dt.
    pub input: f64,
    /// Work the coupling did on the screw, ∫ T_c·θ̇ dt.
    pub screw_input: f64,
    /// Thread friction ∫ μ|N||v_s| dt.
    pub thread: f64,
    /// Supports ∫ (T₀|θ̇| + c·θ̇²) dt.
    pub support: f64,
    /// Pins ∫ F₀|ẋ| dt.
    pub pins: f64,
    /// Structure damping ∫ c_x·ẋ² dt.
    pub structure: f64,
    /// Change of the load's potential energy M·g·Δh (the nut moves horizontally: none for it).
    pub potential: f64,
    /// Change of screw + nut kinetic energy.
    pub kinetic: f64,
    /// Change of coupling spring energy.
    pub spring: f64,
    /// Closed loop: energy drawn from the battery's source V_oc·∫i_b dt.
    pub source: f64,
    /// Closed loop: ohmic (battery, bridge, armature) + diode losses.
    pub electrical_loss: f64,
    /// Closed loop: motor friction + gear mesh losses.
    pub drive_loss: f64,
    /// Closed loop: change of motor-side kinetic energy plus inductor energy.
    pub drive_stored: f64,
}

impl Energy {
    /// Screw-side losses: thread, supports, pins, structure.
    pub fn mechanical_losses(&self) -> f64 {
        self.thread + self.support + self.pins + self.structure
    }

    /// Relative error of the coupling-side balance
    /// `input = losses + ΔPE + ΔKE + Δspring`, against |input|.
    pub fn balance_error(&self) -> f64 {
        let out = self.mechanical_losses() + self.potential + self.kinetic + self.spring;
        (self.input - out).abs() / self.input.abs().max(1e-12)
    }

    /// Relative error of the whole-drive balance `source = electrical + drive losses + stored +
    /// coupling input`, against |source| (closed loop).
    pub fn drive_balance_error(&self) -> f64 {
        let out = self.electrical_loss + self.drive_loss + self.drive_stored + self.input;
        (self.source - out).abs() / self.source.abs().max(1e-12)
    }
}

/// A change of the contact's stick/slip phase, located by the solver's event search (to
/// 10⁻⁶ of a step): the ground truth the stick-slip labels are built from (`crate::twin::truth`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PhaseChange {
    /// Time of the event, s.
    pub t: f64,
    /// The phase entered.
    pub phase: Phase,
    /// Coupling twist θ − θ_i at the event, rad.
    pub twist: f64,
}

/// The recorded samples of a run.
#[derive(Clone, Debug, Default)]
pub struct Trace {
    /// Samples in time order.
    pub records: Vec<Record>,
    /// Every phase change of the run in time order, the initial phase at t = 0 first
    /// (recorded whatever the sampling rate).
    pub phases: Vec<PhaseChange>,
}

fn flank_label(f: Flank) -> &'static str {
    match f {
        Flank::Loaded => "loaded",
        Flank::Reversed => "reversed",
    }
}

impl Trace {
    /// CSV header line.
    pub const HEADER: &'static str = "t_s,theta_i_rad,theta_rad,theta_dot_rad_s,twist_rad,alpha_deg,height_m,\
R_N,F0_N,c_x_kg_s,mu,mu_s,N_N,T_r_Nm,T_c_Nm,phase,flank,current_A,armature_V,bus_V,duty,motor_speed_rad_s,\
E_input_J,E_screw_input_J,E_thread_J,E_support_J,E_pins_J,E_structure_J,dPE_J,dKE_J,dE_spring_J,\
E_source_J,E_electrical_loss_J,E_drive_loss_J,dE_drive_stored_J";

    /// Writes the trace as CSV (header + one line per record).
    pub fn write_csv(&self, mut w: impl Write) -> io::Result<()> {
        writeln!(w, "{}", Self::HEADER)?;
        for r in &self.records {
            let e = &r.energy;
            writeln!(
                w,
                "{:.7},{:.9},{:.9},{:.6},{:.9},{:.6},{:.7},{:.3},{:.3},{:.1},{:.6},{:.6},{:.3},{:.6},{:.6},{},{},{:.4},{:.4},{:.4},{:.5},{:.4},{:.6},{:.6},{:.6},{:.6},{:.6},{:.6},{:.6},{:.9},{:.6},{:.6},{:.6},{:.6},{:.6}",
                r.t, r.theta_i, r.theta, r.theta_dot, r.twist, r.alpha_deg, r.height, r.r, r.f0, r.c_x, r.mu,
                r.mu_s, r.normal, r.friction_torque, r.coupling_torque, r.phase.label(), flank_label(r.flank),
                r.current, r.armature_voltage, r.bus_voltage, r.duty, r.motor_speed, e.input, e.screw_input,
                e.thread, e.support, e.pins, e.structure, e.potential, e.kinetic, e.spring, e.source,
                e.electrical_loss, e.drive_loss, e.drive_stored
            )?;
        }
        Ok(())
    }
}
