//! The estimator configurations the vectors run under.

use crate::corners;
use crate::format::Error;
use fixed::types::I32F32;
use liftfw::estimator::{Estimator, EstimatorConfig};
use liftfw::model::friction::FrictionLaw;

/// Number of configurations in [`config`].
pub const CONFIGS: u8 = 6;

/// The estimator configurations the vectors run under: the presets and both corners of every
/// validated range (so configuration-time quantisation is proven bit-exact too).
pub fn config(id: u8) -> Option<EstimatorConfig> {
    let d = EstimatorConfig::DEFAULT;
    Some(match id {
        0 => d,
        1 => EstimatorConfig {
            law: FrictionLaw::PTFE,
            ..d
        },
        2 => EstimatorConfig {
            law: FrictionLaw::LITHIUM,
            ..d
        },
        3 => EstimatorConfig {
            law: FrictionLaw::BALL_SCREW,
            ..d
        },
        // The upper corner of every range, its law capped at s = 0.5 (inside the range) so
        // that the vectors exercise `min(s, s_max)`: the envelope tests' `high_law` has no cap.
        4 => EstimatorConfig {
            law: FrictionLaw {
                s_max: I32F32::lit("0.5"),
                ..corners::high_law()
            },
            ..corners::upper()
        },
        5 => corners::lower(),
        _ => return None,
    })
}

/// A fresh estimator under configuration `cfg_id`.
pub(crate) fn estimator(cfg_id: u8) -> Result<Estimator, Error> {
    let cfg = config(cfg_id).ok_or(Error::UnknownConfig(cfg_id))?;
    Estimator::new(&cfg).map_err(|_| Error::UnknownConfig(cfg_id))
}
