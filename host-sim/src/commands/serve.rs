//! `host-sim serve`: the simulated board, its console on loopback TCP. The arguments are the
//! app's own settings ([`ServeArgs`]: tests and liftctl's end-to-end tests start it with them).

pub use crate::apps::serve::ServeArgs as Args;
use std::error::Error;

/// Runs `host-sim serve` until it is stopped.
pub fn run(a: &Args) -> Result<(), Box<dyn Error>> {
    crate::apps::serve::main(a)
}
