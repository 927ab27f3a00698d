//! A spring-applied holding brake on the screw (`drive.brake = spring`, for a ball screw that
//! is not self-locking): engaged when its coil is off. Its holding torque acts on the screw
//! like the support friction T₀ (a Coulomb torque, so the stuck phase holds it exactly,
//! without creep): the run loop adds `level · holding_torque` to the support torque, where the
//! level moves linearly from 0 (released) to 1 (engaged) in `engage_s` once the coil is off
//! and back in `release_s` once it is powered.

/// The brake's parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BrakeParams {
    /// Holding torque fully engaged, N·m at the screw.
    pub holding_torque: f64,
    /// Time from coil off to fully engaged, s.
    pub engage_s: f64,
    /// Time from coil on to fully released, s.
    pub release_s: f64,
}

impl BrakeParams {
    /// A brake for the 4008 ball screw at rated load: 100 N·m at the screw, over twice the
    /// rated load's torque at α₀ = 16° (R·l/2π ≈ 43 N·m), 40 ms to engage or release.
    pub const SCREW_100NM: BrakeParams = BrakeParams {
        holding_torque: 100.0,
        engage_s: 0.04,
        release_s: 0.04,
    };

    /// The engagement level after `dt` seconds with the coil `powered`, from `level`.
    pub fn step(&self, level: f64, powered: bool, dt: f64) -> f64 {
        if powered {
            (level - dt / self.release_s.max(1e-9)).max(0.0)
        } else {
            (level + dt / self.engage_s.max(1e-9)).min(1.0)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn engages_and_releases_in_its_times() {
        let b = BrakeParams::SCREW_100NM;
        let mut level = 0.0;
        for _ in 0..39 {
            level = b.step(level, false, 1e-3);
        }
        assert!(level < 1.0 && level > 0.9, "{level}");
        level = b.step(level, false, 1e-3);
        assert!((level - 1.0).abs() < 1e-9);
        for _ in 0..20 {
            level = b.step(level, true, 1e-3);
        }
        assert!((level - 0.5).abs() < 1e-9, "{level}");
    }
}
