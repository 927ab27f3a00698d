//! The electric drive upstream of the coupling: battery → H-bridge (PWM averaged) → 12 V
//! permanent-magnet DC motor → gearbox → gear output θ_i.
//!
//! Sizing (docs/plant.md): the screw needs ≈ 75 N·m to lift 1000 kg from α₀ = 15° with dry
//! friction and μ_b = 0.3. With ratio 60, efficiency 0.85 and k_t = 0.04 N·m/A the motor needs
//! 75/(60·0.85·0.04) ≈ 37 A there, within a 40 A budget, and the screw then turns at ≈ 4 rad/s
//! (a 12 V supply at 40 A cannot deliver the paper-mode cruise power of 75 N·m × 15 rad/s).

use liftfw::control::Bridge;

/// Motor, gearbox, bridge and battery parameters (SI units).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DriveParams {
    /// Battery open-circuit voltage, V.
    pub battery_voltage: f64,
    /// Battery internal resistance (incl. leads), Ω.
    pub battery_resistance: f64,
    /// Bridge on-resistance in the motor loop (high side + low side), Ω (BTS7960: ≈ 16 mΩ).
    pub bridge_resistance: f64,
    /// Body-diode forward drop, V (two conduct while the bridge coasts).
    pub diode_drop: f64,
    /// Armature resistance, Ω.
    pub armature_resistance: f64,
    /// Armature inductance, H.
    pub armature_inductance: f64,
    /// Torque constant k_t = back-EMF constant k_e, N·m/A = V·s/rad.
    pub torque_constant: f64,
    /// Rotor inertia, kg·m².
    pub rotor_inertia: f64,
    /// Gearbox inertia referred to the motor shaft, kg·m².
    pub gear_inertia: f64,
    /// Motor viscous friction, N·m·s/rad.
    pub motor_viscous: f64,
    /// Motor + gearbox no-load (Coulomb) torque at the motor shaft, N·m.
    pub motor_coulomb: f64,
    /// Gear ratio n (motor turns per output turn).
    pub ratio: f64,
    /// Gearbox efficiency η (mesh losses in either power-flow direction).
    pub efficiency: f64,
}

impl Default for DriveParams {
    fn default() -> Self {
        Self {
            battery_voltage: 12.6,
            battery_resistance: 0.015,
            bridge_resistance: 0.016,
            diode_drop: 0.8,
            armature_resistance: 0.06,
            armature_inductance: 80e-6,
            torque_constant: 0.04,
            rotor_inertia: 5e-5,
            gear_inertia: 1e-5,
            motor_viscous: 2e-5,
            motor_coulomb: 0.02,
            ratio: 60.0,
            efficiency: 0.85,
        }
    }
}

/// The averaged bridge state for one control period.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum BridgeState {
    /// All four switches off: current, if any, decays through the body diodes into the battery.
    Coast,
    /// Both low sides on: the armature is short-circuited through the bridge.
    Brake,
    /// Averaged drive with duty in [−1, 1] (synchronous PWM: the current may flow either way).
    Drive(f64),
}

impl BridgeState {
    /// From the core's command.
    pub fn from_command(b: Bridge) -> Self {
        match b {
            Bridge::Coast => BridgeState::Coast,
            Bridge::Brake => BridgeState::Brake,
            Bridge::Drive(q) => {
                BridgeState::Drive((f64::from(q) / f64::from(i16::MAX)).clamp(-1.0, 1.0))
            }
        }
    }

    /// Signed duty (0 for coast and brake).
    pub fn duty(self) -> f64 {
        match self {
            BridgeState::Drive(d) => d,
            _ => 0.0,
        }
    }
}

/// Electrical and mechanical rates of the drive at one instant.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct DriveRates {
    /// di/dt, A/s.
    pub di: f64,
    /// dω_m/dt, rad/s².
    pub dw: f64,
    /// Armature terminal voltage, V.
    pub armature_voltage: f64,
    /// Bridge supply (battery terminal) voltage, V.
    pub bus_voltage: f64,
    /// Battery current (positive: discharging), A.
    pub battery_current: f64,
    /// Power drawn from the battery's open-circuit source V_oc·i_b, W.
    pub source_power: f64,
    /// Ohmic losses: battery, bridge, armature, W.
    pub ohmic_loss: f64,
    /// Diode losses, W.
    pub diode_loss: f64,
    /// Motor friction losses, W.
    pub motor_friction_loss: f64,
    /// Gear mesh losses, W.
    pub gear_loss: f64,
}

/// Coulomb friction is regularised over this motor speed, rad/s (the thread's stick-slip is the
/// one modelled exactly; the motor's no-load friction is not the subject of this twin).
const COULOMB_BAND: f64 = 1.0;

impl DriveParams {
    /// Total inertia at the motor shaft, kg·m².
    pub fn inertia(&self) -> f64 {
        self.rotor_inertia + self.gear_inertia
    }

    /// Rates for current `i`, motor speed `w` (rad/s), bridge state and coupling torque `t_c`
    /// (N·m at the gear output, positive when it resists lifting).
    ///
    /// The gearbox loses (1 − η) of the power flowing through it in either direction: motoring
    /// (power to the screw) the motor supplies T_c/(n·η); back-driven (the screw feeds power
    /// into the motor) it receives only η·T_c/n. The direction is sgn(T_c·ω), blended over the
    /// Coulomb band so that the right-hand side stays continuous through ω = 0.
    pub fn rates(&self, i: f64, w: f64, bridge: BridgeState, t_c: f64) -> DriveRates {
        let e = self.torque_constant * w;
        let (ra, l) = (self.armature_resistance, self.armature_inductance);
        let (voc, rb) = (self.battery_voltage, self.battery_resistance);
        let mut r = DriveRates::default();
        match bridge {
            BridgeState::Drive(d) => {
                // Averaged: V_a = d·V_bus, i_b = d·i, V_bus = V_oc − R_b·i_b.
                let vbus = voc - rb * d * i;
                r.armature_voltage = d * vbus;
                r.bus_voltage = vbus;
                r.battery_current = d * i;
                r.di = (r.armature_voltage - (ra + self.bridge_resistance) * i - e) / l;
                r.ohmic_loss = rb * (d * i).powi(2) + (ra + self.bridge_resistance) * i * i;
            }
            BridgeState::Brake => {
                r.bus_voltage = voc;
                r.di = (-(ra + self.bridge_resistance) * i - e) / l;
                r.ohmic_loss = (ra + self.bridge_resistance) * i * i;
            }
            BridgeState::Coast => {
                // Diodes conduct while current flows, or when the back-EMF exceeds the bus plus
                // two drops (generator); they block otherwise. A sign change of i inside a step
                // is clamped to 0 by the caller (`coast_clamp`).
                let s = if i != 0.0 {
                    i.signum()
                } else if e.abs() > voc + 2.0 * self.diode_drop {
                    -e.signum()
                } else {
                    0.0
                };
                let vbus = voc + rb * s.abs() * i.abs();
                r.bus_voltage = vbus;
                r.armature_voltage = -s * (vbus + 2.0 * self.diode_drop);
                r.battery_current = -i.abs();
                r.di = if s == 0.0 {
                    0.0
                } else {
                    (r.armature_voltage - ra * i - e) / l
                };
                r.ohmic_loss = rb * i * i + ra * i * i;
                r.diode_loss = 2.0 * self.diode_drop * i.abs();
            }
        }
        r.source_power = voc * r.battery_current;
        // tanh is odd (glibc's and any correctly rounded one): sgn(T_c)·tanh(ω/band) is
        // tanh(sgn(T_c)·ω/band) to the bit, one call for both terms.
        let band = tanh_saturating(w / COULOMB_BAND);
        let blend = t_c.signum() * band;
        // Torque factor at the motor: 1/η motoring (blend = +1), η back-driven (blend = −1),
        // and exactly 1 where the flow reverses, so the mesh loss is never negative.
        let factor = gear_factor(self.efficiency, blend);
        let t_load = t_c / self.ratio * factor;
        let t_fric = self.motor_viscous * w + self.motor_coulomb * band;
        r.dw = (self.torque_constant * i - t_fric - t_load) / self.inertia();
        r.motor_friction_loss = t_fric * w;
        r.gear_loss = t_load * w - t_c * w / self.ratio;
        r
    }
}

/// tanh(x), without the call where it is ±1 to the last bit: for |x| ≥ 19.1,
/// 1 − tanh|x| = 2/(e^(2|x|) + 1) < 5.1·10⁻¹⁷, under half an ulp below 1 (5.55·10⁻¹⁷), so tanh
/// rounds to ±1 exactly (glibc's tanh computes 1 − 2/(expm1(2|x|) + 2) there, or returns
/// 1 − tiny from 22). The motor turns faster than 19.1 rad/s (0.32 rad/s at the screw) in most
/// runs, and this is the plant's hottest transcendental call.
#[inline]
pub fn tanh_saturating(x: f64) -> f64 {
    if x.abs() >= 19.1 {
        1f64.copysign(x)
    } else {
        x.tanh()
    }
}

/// η^(−blend), remembered for the last (η, blend) on this thread: saturated (blend = ±1 in
/// steady motion) the same power is asked for at every evaluation. The same `powf` call makes
/// every value, so the result is the same to the bit.
#[inline]
fn gear_factor(efficiency: f64, blend: f64) -> f64 {
    use std::cell::Cell;
    thread_local! {
        static LAST: Cell<(u64, u64, f64)> = const { Cell::new((u64::MAX, u64::MAX, f64::NAN)) };
    }
    let key = (efficiency.to_bits(), blend.to_bits());
    LAST.with(|c| {
        let (e, b, f) = c.get();
        if (e, b) == key {
            f
        } else {
            let f = efficiency.powf(-blend);
            c.set((key.0, key.1, f));
            f
        }
    })
}

/// The coast diodes block reverse current: if i changed sign over a step while coasting, it
/// stopped at 0.
pub fn coast_clamp(bridge: BridgeState, i_before: f64, i_after: f64) -> f64 {
    if matches!(bridge, BridgeState::Coast) && i_before * i_after < 0.0 {
        0.0
    } else {
        i_after
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_saturated_tanh_and_the_remembered_power_are_the_library_calls_to_the_bit() {
        let mut x = 0.0f64;
        while x < 40.0 {
            for v in [x, -x] {
                assert_eq!(tanh_saturating(v).to_bits(), v.tanh().to_bits(), "{v}");
                let b = 0.3f64.signum() * tanh_saturating(v);
                assert_eq!(b.to_bits(), (0.3f64.signum() * v).tanh().to_bits(), "{v}");
                let b = (-0.3f64).signum() * tanh_saturating(v);
                assert_eq!(
                    b.to_bits(),
                    ((-0.3f64).signum() * v).tanh().to_bits(),
                    "{v}"
                );
                for eff in [0.7f64, 0.85] {
                    let want = eff.powf(-b);
                    // Twice: the second is the remembered value.
                    assert_eq!(gear_factor(eff, b).to_bits(), want.to_bits());
                    assert_eq!(gear_factor(eff, b).to_bits(), want.to_bits());
                }
            }
            x += 0.000_37;
        }
        assert!(tanh_saturating(f64::NAN).is_nan());
    }

    #[test]
    fn rated_lift_needs_less_than_forty_amps() {
        // Steady state at the rated screw torque: k_t·i = T/(n·η) + friction.
        let p = DriveParams::default();
        let t_screw = 76.0;
        let i = (t_screw / (p.ratio * p.efficiency) + p.motor_coulomb) / p.torque_constant;
        assert!(i < 40.0, "{i}");
    }

    #[test]
    fn gear_loss_is_never_negative() {
        let p = DriveParams::default();
        for (tc, w) in [
            (50.0, 100.0),
            (50.0, -100.0),
            (-50.0, 100.0),
            (-50.0, -100.0),
            (10.0, 0.3),
            (50.0, -0.05),
            (-50.0, 0.01),
        ] {
            let r = p.rates(0.0, w, BridgeState::Brake, tc);
            assert!(r.gear_loss >= -1e-12, "{tc} {w}: {}", r.gear_loss);
        }
    }

    #[test]
    fn coasting_current_decays_against_the_bus() {
        let p = DriveParams::default();
        let r = p.rates(10.0, 0.0, BridgeState::Coast, 0.0);
        assert!(r.di < 0.0 && r.armature_voltage < -p.battery_voltage);
        assert!(
            r.battery_current < 0.0,
            "coast returns the inductor's energy to the battery"
        );
        let r0 = p.rates(0.0, 50.0, BridgeState::Coast, 0.0);
        assert_eq!(r0.di, 0.0, "diodes block below the bus voltage");
    }
}
