//! One module per record kind: its input codec, its evaluation (the core call and its outputs,
//! field by field) and its case generator.

pub(crate) mod console;
pub(crate) mod control;
pub(crate) mod detector;
pub(crate) mod estimator;
pub(crate) mod profile;
