//! Robot pose files (`calibrate --hand-eye --robot-poses`, `render --robot-poses`), with or
//! without their `format` header: an error or finite rigid poses, never a panic; a decoded
//! file written back with its format reads back to the same poses.
#![no_main]

use camplace_config::{parse_robot_poses, robot_poses_text};

mod common;

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    // The first byte picks the format the flags give (or none), the rest is the file.
    let Some((&pick, rest)) = data.split_first() else { return };
    let Ok(text) = std::str::from_utf8(rest) else { return };
    let given = common::format(pick);
    let Ok(read) = parse_robot_poses(text, given) else { return };
    assert_eq!(read.poses.len(), read.lines.len());
    for p in &read.poses {
        common::assert_rigid(p);
    }
    let written = robot_poses_text(&read.poses, read.format, "read back");
    let back = parse_robot_poses(&written, None).unwrap_or_else(|e| panic!("{e}\n{written}"));
    assert_eq!(back.format, read.format);
    assert_eq!(back.poses.len(), read.poses.len());
    for (a, b) in read.poses.iter().zip(&back.poses) {
        common::assert_close(a, b);
    }
});
