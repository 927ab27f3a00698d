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

/// (kind, output offset, output length, input offset) of every record, in file order.
fn records(f: &[u8]) -> Vec<(u8, usize, usize, usize)> {
    let mut at = 6;
    let mut out = Vec::new();
    while at < f.len() {
        let kind = f[at];
        let in_len = u32::from_le_bytes(f[at + 1..at + 5].try_into().unwrap()) as usize;
        let out_len = u32::from_le_bytes(f[at + 5..at + 9].try_into().unwrap()) as usize;
        out.push((kind, at + 9 + in_len, out_len, at + 9));
        at += 9 + in_len + out_len;
    }
    out
}

#[test]
fn every_kind_is_generated_and_a_flipped_byte_in_any_kind_is_reported() {
    let f = file();
    let recs = records(&f);
    for (k, kind) in Kind::ALL.iter().enumerate() {
        let (i, &(_, out_at, out_len, _)) = recs
            .iter()
            .enumerate()
            .find(|(_, r)| r.0 == *kind as u8)
            .unwrap_or_else(|| panic!("no {} record", kind.name()));
        assert!(out_len > 0, "{}", kind.name());
        // The last output byte: the end of the record's last operation.
        let mut bad = f.clone();
        bad[out_at + out_len - 1] ^= 0x80;
        let r = verify(&bad).unwrap();
        assert_eq!(r.mismatches.iter().sum::<u32>(), 1, "{}", kind.name());
        assert_eq!(r.mismatches[k], 1, "{}", kind.name());
        assert_eq!(
            r.first_mismatch,
            Some((i as u32, *kind as u8, out_len as u32 - 1)),
            "{}",
            kind.name()
        );
    }
}

#[test]
fn profile_scripts_cover_moves_to_rest_and_the_far_path() {
    use liftfw_golden::{OP_RUN, OP_STEPS, OP_TARGET};
    let f = file();
    let (mut scripts, mut rested, mut far, mut s_curve) = (0, 0, 0, 0);
    for (kind, out_at, _, in_at) in records(&f) {
        if kind != Kind::ProfileSequence as u8 {
            continue;
        }
        scripts += 1;
        // Walk the script (input) and its outputs side by side.
        let input = &f[in_at..out_at];
        let start = i32::from_le_bytes(input[0..4].try_into().unwrap());
        s_curve += usize::from(input[16] == 1);
        let n = u16::from_le_bytes(input[17..19].try_into().unwrap()) as usize;
        let mut o = out_at;
        let mut is_far = start.unsigned_abs() > 1 << 29;
        let mut rests = false;
        for op in input[19..].chunks(9).take(n) {
            let arg = i64::from_le_bytes(op[1..9].try_into().unwrap());
            match op[0] {
                OP_STEPS => o += 17 * arg as usize,
                OP_RUN => {
                    let at = u32::from_le_bytes(f[o + 25..o + 29].try_into().unwrap());
                    rests |= at != u32::MAX;
                    o += 29;
                }
                OP_TARGET => is_far |= arg.unsigned_abs() > 1 << 29,
                _ => {}
            }
            o += 4; // the target after each operation
        }
        rested += usize::from(rests);
        far += usize::from(is_far);
    }
    assert_eq!(scripts, 128);
    assert_eq!(s_curve, 64);
    // Most scripts bring the reference to rest at least once; a good share runs the far path.
    assert!(rested >= 80, "{rested} of {scripts} scripts rest");
    assert!(far >= 16, "{far} of {scripts} scripts go past 2^29 counts");
}

#[test]
fn console_lines_reach_every_outcome() {
    let f = file();
    let mut outcomes = std::collections::BTreeMap::<String, usize>::new();
    for (kind, out_at, out_len, _) in records(&f) {
        if kind == Kind::ConsoleParse as u8 {
            let text = String::from_utf8_lossy(&f[out_at..out_at + out_len]);
            let head: String = text
                .chars()
                .take_while(|c| c.is_alphanumeric() || "(".contains(*c))
                .collect();
            let head = head.split('(').take(3).collect::<Vec<_>>().join("(");
            *outcomes.entry(head).or_default() += 1;
        }
    }
    assert_eq!(outcomes.values().sum::<usize>(), 2400);
    for o in [
        "Ok(None",
        "Ok(Some(Status",
        "Ok(Some(Get",
        "Ok(Some(Set",
        "Ok(Some(Save",
        "Ok(Some(Limits",
        "Ok(Some(Up",
        "Ok(Some(Down",
        "Ok(Some(Stop",
        "Ok(Some(Goto",
        "Ok(Some(Fault",
        "Ok(Some(FaultClear",
        "Ok(Some(Help",
        "Ok(Some(Version",
        "Err(NotText",
        "Err(TooLong",
        "Err(UnknownCommand",
        "Err(MissingKey",
        "Err(UnknownKey",
        "Err(MissingValue",
        "Err(BadValue",
        "Err(BadHeight",
        "Err(Trailing",
    ] {
        let n: usize = outcomes
            .iter()
            .filter(|(h, _)| *h == o || h.starts_with(&format!("{o}(")))
            .map(|(_, n)| n)
            .sum();
        assert!(n >= 3, "{o}: {outcomes:?}");
    }
}

#[test]
fn detector_traces_slip_raise_episodes_and_stay_quiet() {
    let f = file();
    let (mut traces, mut with_onset, mut quiet, mut slips) = (0, 0, 0, 0);
    for (kind, out_at, _, _) in records(&f) {
        if kind != Kind::DetectorSequence as u8 {
            continue;
        }
        traces += 1;
        // Run-length coded reports: tick u32, flags u8, amplitude i32, episodes u32, branch u8.
        let (mut o, mut onset, mut any) = (out_at, false, false);
        loop {
            let t = u32::from_le_bytes(f[o..o + 4].try_into().unwrap());
            o += 4;
            if t == u32::MAX {
                break;
            }
            onset |= f[o] & 2 != 0;
            any |= f[o] & 4 != 0;
            slips += usize::from(f[o] & 4 != 0);
            o += 10;
        }
        with_onset += usize::from(onset);
        quiet += usize::from(!any);
    }
    assert_eq!(traces, 96);
    assert!(with_onset >= 25, "{with_onset} traces with an episode");
    assert!(quiet >= 25, "{quiet} traces without a slip");
    assert!(slips >= 500, "{slips} slips");
}

#[test]
fn control_runs_reach_motion_states_faults_and_refusals() {
    let f = file();
    let (mut runs, mut states, mut faults, mut refusals) = (0, [false; 5], 0, 0);
    for (kind, out_at, _, _) in records(&f) {
        if kind != Kind::ControlTick as u8 {
            continue;
        }
        runs += 1;
        let mut o = out_at;
        loop {
            let t = u32::from_le_bytes(f[o..o + 4].try_into().unwrap());
            o += 4;
            if t == u32::MAX {
                break;
            }
            if f[o] == 0xfe {
                refusals += usize::from(!matches!(f[o + 1], 0 | 0xff));
                o += 2;
                continue;
            }
            states[usize::from(f[o + 4])] = true;
            let len = u16::from_le_bytes(f[o + 5..o + 7].try_into().unwrap()) as usize;
            o += 7;
            faults += usize::from(f[o..o + len].starts_with(b"Fault("));
            o += len;
        }
    }
    assert_eq!(runs, 24);
    assert_eq!(states, [true; 5], "idle, lifting, lowering, holding, fault");
    assert!(faults >= 20, "{faults} faults");
    assert!(refusals >= 10, "{refusals} refused commands");
}
