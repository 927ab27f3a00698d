//! Bytes as a stored configuration record: decode and validation never panic, and a record
//! that decodes re-encodes to the same bytes. Inputs are either raw bytes or a bit mask over a
//! valid record (first byte odd), optionally with the CRC patched in afterwards (bit 1 of the
//! first byte), so the fuzzer reaches the checks behind the magic and the CRC.
#![no_main]

use libfuzzer_sys::fuzz_target;
use liftfw::config::record;
use liftfw::config::ValidatedConfig;
use liftfw::control::config::ControlConfig;

fuzz_target!(|input: &[u8]| {
    let Some((&mode, rest)) = input.split_first() else {
        return;
    };
    let mut data = if mode & 1 == 1 {
        let mut buf = [0u8; record::MAX_RECORD_LEN];
        let n = record::encode(&ControlConfig::DEFAULT, 1, &mut buf).unwrap();
        let mut v = buf[..n].to_vec();
        for (i, b) in rest.iter().enumerate() {
            v[i % n] ^= b;
        }
        v
    } else {
        rest.to_vec()
    };
    let n = data.len();
    if mode & 2 == 2 && n >= record::HEADER_LEN + 4 {
        let crc = record::crc32(&data[..n - 4]);
        data[n - 4..].copy_from_slice(&crc.to_le_bytes());
    }
    if let Ok((cfg, seq)) = record::decode(&data) {
        let mut buf = [0u8; record::MAX_RECORD_LEN];
        let len = record::encode(&cfg, seq, &mut buf).unwrap();
        assert_eq!(&buf[..len], &data[..]);
        let _ = ValidatedConfig::new(cfg);
    }
});
