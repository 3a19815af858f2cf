//! PFM bytes (a disparity or depth map): an error or an image, never a panic, an abort or
//! a hang.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let _ = camplace_config::decode_pfm(data);
});
