//! `rig.json` text: an error or a checked calibration, never a panic, an abort or a hang.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    if let Ok(text) = std::str::from_utf8(data) {
        let _ = camplace_config::RigFile::from_json(text);
    }
});
