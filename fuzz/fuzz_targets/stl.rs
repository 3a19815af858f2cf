//! STL bytes (a tray mesh, ASCII or binary): an error or a mesh, never a panic, an abort or
//! a hang.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let _ = camplace_config::decode_stl(data);
});
