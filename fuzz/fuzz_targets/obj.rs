//! Wavefront OBJ bytes (a tray mesh): an error or a mesh, never a panic, an abort or a hang.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let _ = camplace_config::decode_obj(data);
});
