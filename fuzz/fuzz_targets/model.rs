//! Tray model files (`camplace model`): an error or a model, never a panic, an abort or a
//! hang. Half the inputs are decoded as they are; the other half get a body length and a
//! CRC-32 that fit them first, so mutations reach the section parser behind the checksum
//! (the `VRFY` verification section included, from a format-4 seed). A model that decodes
//! is written back and read again: the same bytes.
#![no_main]

/// CRC-32 (IEEE 802.3, reflected), the model file's checksum, written out bit by bit.
fn crc32(bytes: &[u8]) -> u32 {
    let mut c = !0u32;
    for &b in bytes {
        c ^= b as u32;
        for _ in 0..8 {
            c = if c & 1 != 0 { 0xEDB8_8320 ^ (c >> 1) } else { c >> 1 };
        }
    }
    !c
}

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let Some((&mode, rest)) = data.split_first() else { return };
    if mode & 1 == 0 || rest.len() < 24 {
        round_trip(rest);
        return;
    }
    // Magic (8), version (4), body length (8), body, checksum (4).
    let mut bytes = rest.to_vec();
    let body = (bytes.len() - 24) as u64;
    bytes[12..20].copy_from_slice(&body.to_le_bytes());
    let end = bytes.len() - 4;
    let crc = crc32(&bytes[..end]);
    bytes[end..].copy_from_slice(&crc.to_le_bytes());
    round_trip(&bytes);
});

/// A model that decodes encodes to bytes that decode to the same model (the file's rounding
/// applied once is applied: encoding the second decoding gives the same bytes).
fn round_trip(bytes: &[u8]) {
    let Ok(model) = camplace_estimator::Model::from_bytes(bytes) else { return };
    let written = model.to_bytes();
    let back = camplace_estimator::Model::from_bytes(&written).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(back.to_bytes(), written);
}
