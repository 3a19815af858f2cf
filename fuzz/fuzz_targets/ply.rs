//! PLY bytes (a cloud or a tray mesh): an error or a decoded file, never a panic, an abort
//! or a hang.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let _ = camplace_config::decode_ply(data);
});
