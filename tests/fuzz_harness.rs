//! The cargo-fuzz targets' bodies (`fuzz/harness/mod.rs`) under proptest, so that CI runs them
//! on every test run for a bounded number of cases: arbitrary bytes, and lines assembled from
//! the console's own words, units and control bytes (which reach deeper than random bytes in
//! the few thousand cases a test run affords; libFuzzer's coverage search stays the tool for
//! long runs, docs/console.md "Fuzzing").
#![allow(clippy::unwrap_used, clippy::expect_used)]

#[path = "../fuzz/harness/mod.rs"]
mod harness;

use proptest::prelude::*;

/// Pieces a hostile line is made of: commands, keys, values with units, separators and the
/// control bytes that used to split or echo (CR, LF, NUL, ESC, BEL, backspace, DEL).
const PIECES: &[&str] = &[
    "set ",
    "get ",
    "goto ",
    "up",
    "down",
    "stop",
    "save",
    "limits",
    "status",
    "fault",
    "clear",
    "help ",
    "keys",
    "version",
    "limits.upper ",
    "limits.lower ",
    "motion.cruise_speed ",
    "sense.current_ua_per_code ",
    "friction.law ",
    "drive.gear_ratio ",
    "geometry.length ",
    "300mm",
    "0.3 m",
    "20",
    "1e30",
    "-0",
    "nan",
    "32",
    "mA",
    "ptfe",
    "ball",
    "none",
    "1_000",
    " ",
    "\t",
    "\r",
    "\n",
    "\r\n",
    "\0",
    "\x1b[2J",
    "\x07",
    "\x08",
    "\x7f",
    "#",
    "é",
    "\u{85}",
];

fn assembled() -> impl Strategy<Value = Vec<u8>> {
    proptest::collection::vec(proptest::sample::select(PIECES), 0..40)
        .prop_map(|p| p.concat().into_bytes())
}

proptest! {
    // ≈ 1 s each on an idle core (debug build of the test, optimised dependencies).
    #![proptest_config(ProptestConfig { cases: 4000, ..ProptestConfig::default() })]

    #[test]
    fn console_line_on_random_bytes(data in proptest::collection::vec(any::<u8>(), 0..512)) {
        harness::console_line(&data);
    }

    #[test]
    fn console_line_on_assembled_lines(data in assembled()) {
        harness::console_line(&data);
    }

    #[test]
    fn config_record_on_random_bytes(data in proptest::collection::vec(any::<u8>(), 0..1024)) {
        harness::config_record(&data);
    }

    #[test]
    fn config_record_on_masked_records(
        mode in 0u8..4,
        mask in proptest::collection::vec(prop_oneof![9 => Just(0u8), 1 => any::<u8>()], 0..600),
    ) {
        let mut input = vec![mode | 1];
        input.extend(mask);
        harness::config_record(&input);
    }
}
