//! One robot pose line in each convention and unit (`parse_pose` / `format_pose`): an
//! error or a finite rigid transform, never a panic; what decodes encodes to a line that
//! decodes to the same pose.
#![no_main]

use camplace_config::{format_pose, parse_pose};

mod common;

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let Some((&pick, rest)) = data.split_first() else { return };
    let Ok(line) = std::str::from_utf8(rest) else { return };
    let Some(format) = common::format(pick) else { return };
    let Ok(pose) = parse_pose(line, format) else { return };
    common::assert_rigid(&pose);
    let written = format_pose(&pose, format);
    let back = parse_pose(&written, format).unwrap_or_else(|e| panic!("{e}: {written}"));
    common::assert_close(&pose, &back);
});
