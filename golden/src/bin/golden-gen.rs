//! Writes the golden-vector file the QEMU harness replays: `golden-gen OUT.bin`.
//!
//! The vectors are a pure function of the core's source (fixed seed), so `scripts/qemu-test`
//! regenerates them before every target build instead of keeping a binary file in git.
use std::process::ExitCode;

struct VecSink(Vec<u8>);

impl liftfw_golden::Sink for VecSink {
    fn put(&mut self, b: &[u8]) {
        self.0.extend_from_slice(b);
    }
}

fn main() -> ExitCode {
    let Some(path) = std::env::args().nth(1) else {
        eprintln!("usage: golden-gen OUT.bin");
        return ExitCode::from(2);
    };
    let mut out = VecSink(Vec::new());
    if let Err(e) = liftfw_golden::generate(&mut out) {
        eprintln!("golden-gen: {e}");
        return ExitCode::FAILURE;
    }
    let report = match liftfw_golden::verify(&out.0) {
        Ok(r) => r,
        Err(e) => {
            eprintln!("golden-gen: generated file does not read back: {e}");
            return ExitCode::FAILURE;
        }
    };
    if let Err(e) = std::fs::write(&path, &out.0) {
        eprintln!("golden-gen: {path}: {e}");
        return ExitCode::FAILURE;
    }
    for (k, n) in liftfw_golden::Kind::ALL.iter().zip(report.records) {
        eprintln!("golden-gen: {n} {} records", k.name());
    }
    eprintln!("golden-gen: wrote {} bytes to {path}", out.0.len());
    ExitCode::SUCCESS
}
