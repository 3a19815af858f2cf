//! `tolerance.json` (`camplace placement --tolerance`, `--study`): an error or a checked
//! measurement, never a panic; what is accepted written back reads back the same.
#![no_main]

use camplace_config::ToleranceReport;

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let Ok(report) = ToleranceReport::from_json(data) else { return };
    let written = serde_json::to_vec(&report).expect("plain data");
    let back = ToleranceReport::from_json(&written).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(back, report);
});
