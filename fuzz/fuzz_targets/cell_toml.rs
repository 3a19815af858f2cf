//! Cell file text (TOML): an error or a checked cell, never a panic, an abort or a hang.
//! Mesh paths in it point into an empty folder, so a tray mesh is a missing file.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    if let Ok(text) = std::str::from_utf8(data) {
        let _ = camplace_config::Cell::from_toml_str(text, std::path::Path::new("/nonexistent-camplace-fuzz"));
    }
});
