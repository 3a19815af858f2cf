//! Placement strings (`--placement`, `recommended.json`'s `placement`): an error or a checked
//! placement, never a panic.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    if let Ok(text) = std::str::from_utf8(data) {
        let base = camplace_config::Cell::default().placement;
        if let Ok(p) = base.with_overrides(text) {
            // A placement read back from its own text is the same one.
            assert_eq!(base.with_overrides(&p.to_string()).ok(), Some(p));
        }
    }
});
