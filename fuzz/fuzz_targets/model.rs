//! Tray model files (`camplace model`): an error or a model, never a panic, an abort or a
//! hang.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let _ = camplace_estimator::Model::from_bytes(data);
});
