//! Command-line value types shared by host-sim's subcommands.

use crate::twin::physics::Lubricant;
use clap::ValueEnum;
use serde::Deserialize;

/// Thread lubricant as typed on the command line or in a scenario file.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Lube {
    /// Dry/boundary friction (Eq 13).
    Dry,
    /// PTFE dry spray (Eq 14).
    Ptfe,
    /// Lithium grease (Eq 11, our reading).
    Lithium,
}

impl From<Lube> for Lubricant {
    fn from(l: Lube) -> Self {
        match l {
            Lube::Dry => Lubricant::Dry,
            Lube::Ptfe => Lubricant::Ptfe,
            Lube::Lithium => Lubricant::Lithium,
        }
    }
}
