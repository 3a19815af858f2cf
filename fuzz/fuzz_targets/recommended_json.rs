//! `recommended.json` (`placement --study`, `ablate --study`): an error or a checked
//! placement and method, never a panic; what is accepted written back reads back the same.
#![no_main]

use camplace_sim::Recommended;

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let Ok(r) = Recommended::from_json(data) else { return };
    let back = Recommended::from_json(r.to_json().as_bytes()).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(back, r);
});
