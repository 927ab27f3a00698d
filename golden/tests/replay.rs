//! The golden-vector machinery on the host: what the QEMU harness relies on.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use liftfw_golden::{config, generate, verify, Error, Kind, Sink, CONFIGS};

struct VecSink(Vec<u8>);

impl Sink for VecSink {
    fn put(&mut self, b: &[u8]) {
        self.0.extend_from_slice(b);
    }
}

fn file() -> Vec<u8> {
    let mut s = VecSink(Vec::new());
    generate(&mut s).unwrap();
    s.0
}

#[test]
fn every_configuration_is_accepted_by_the_core() {
    for id in 0..CONFIGS {
        let c = config(id).unwrap();
        liftfw::estimator::Estimator::new(&c).unwrap_or_else(|e| panic!("config {id}: {e}"));
    }
    assert!(config(CONFIGS).is_none());
}

#[test]
fn generated_vectors_replay_without_mismatch_and_cover_thousands_of_inputs() {
    let f = file();
    let r = verify(&f).unwrap();
    assert!(r.passed(), "{r:?}");
    assert_eq!(r.records[0], 3000);
    assert!(r.records[1] * 50 >= 1800, "{r:?}");
}

#[test]
fn generation_is_deterministic() {
    assert_eq!(file(), file());
}

#[test]
fn a_flipped_output_bit_is_reported_with_its_record() {
    let mut f = file();
    // Record 0 starts after the 6-byte header: kind, in_len, out_len, input, output.
    let in_len = u32::from_le_bytes(f[7..11].try_into().unwrap()) as usize;
    let out_at = 6 + 9 + in_len;
    f[out_at + 5] ^= 1;
    let r = verify(&f).unwrap();
    assert!(!r.passed());
    assert_eq!(r.mismatches[0], 1);
    assert_eq!(
        r.first_mismatch,
        Some((0, Kind::EstimatorEstimate as u8, 5))
    );
}

#[test]
fn malformed_files_are_errors_not_panics() {
    let f = file();
    assert_eq!(verify(b"nope").unwrap_err(), Error::BadMagic);
    assert_eq!(verify(&f[..f.len() - 1]).unwrap_err(), Error::Truncated);
    let mut bad_kind = f.clone();
    bad_kind[6] = 99;
    assert_eq!(verify(&bad_kind).unwrap_err(), Error::UnknownKind(99));
    let mut bad_cfg = f.clone();
    bad_cfg[15] = 200; // first input byte: the configuration index
    assert_eq!(verify(&bad_cfg).unwrap_err(), Error::UnknownConfig(200));
    // Any prefix: an error or a clean (shorter) report, never a panic.
    for n in (0..4000).step_by(7) {
        let _ = verify(&f[..n]);
    }
}
