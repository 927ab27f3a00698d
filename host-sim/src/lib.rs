//! host-sim: the lift's digital twin.
#![warn(missing_docs)]
