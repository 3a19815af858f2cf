//! `camplace capture`: frames from a source saved as a dataset that the other commands read.

use crate::camplace_cmd::{assert_one_line_error, camplace, stderr};

#[test]
fn captured_frames_are_the_sources_and_make_a_dataset() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let o = camplace(d, &["render", "--dataset", "--count", "3", "--out", "src"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let o = camplace(d, &["capture", "--source", "dir:src", "--out", "cap", "--count", "2"]);
    assert!(o.status.success(), "{}", stderr(&o));
    // Run again with a skipped frame: appended as the next number, from the source's third frame.
    let o = camplace(d, &["capture", "--source", "dir:src", "--out", "cap", "--skip", "2"]);
    assert!(o.status.success(), "{}", stderr(&o));
    for (got, want) in [("0000", "0000"), ("0001", "0001"), ("0002", "0002")] {
        for side in ["left.png", "right.png"] {
            let a = camplace_config::read_gray(&d.join("cap/frames").join(got).join(side)).unwrap();
            let b = camplace_config::read_gray(&d.join("src/frames").join(want).join(side)).unwrap();
            assert_eq!((a.width, a.height, &a.data), (b.width, b.height, &b.data), "{got}/{side}");
        }
    }
    assert_eq!(std::fs::read(d.join("cap/rig.json")).unwrap(), std::fs::read(d.join("src/rig.json")).unwrap());
    let o = camplace(d, &["capture", "--source", "dir:src", "--out", "cap", "--background"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(d.join("cap/background/left.png").is_file() && d.join("cap/background/right.png").is_file());
    // The captured folder is a dataset the pipeline reads.
    let o = camplace(d, &["reconstruct", "--dataset", "cap"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(d.join("cap/frames/0002/cloud.ply").is_file());
    // A background is never replaced silently; bad counts and sources are one-line errors.
    let o = camplace(d, &["capture", "--source", "dir:src", "--out", "cap", "--background"]);
    assert_one_line_error(o.status.code().unwrap(), &stderr(&o), &["cap/background", "already"]);
    let o = camplace(d, &["capture", "--source", "dir:src", "--out", "c2", "--count", "0"]);
    assert_one_line_error(o.status.code().unwrap(), &stderr(&o), &["--count"]);
    let o = camplace(d, &["capture", "--source", "dir:src", "--out", "c2", "--every", "-1"]);
    assert_one_line_error(o.status.code().unwrap(), &stderr(&o), &["--every"]);
    let o = camplace(d, &["capture", "--source", "dir:nowhere", "--out", "c2"]);
    assert_one_line_error(o.status.code().unwrap(), &stderr(&o), &["nowhere"]);
    assert!(!d.join("c2").exists(), "nothing written for bad input");
}
