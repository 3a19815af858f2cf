//! Image bytes (dataset frames, calibration views): an error or a grey image within the
//! pixel budget, never a panic, an abort or an allocation past the budget.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    if let Ok(g) = camplace_config::decode_gray(data) {
        assert!((g.width * g.height) as u64 <= camplace_config::MAX_IMAGE_PIXELS);
        assert_eq!(g.data.len(), g.width * g.height);
    }
});
