//! A dataset's `labels.jsonl` (the review page's marks, a user may edit it): an error naming
//! the file and line or marks that each name a frame of the dataset, never a panic; what is
//! accepted written back reads back the same.
#![no_main]

use std::path::Path;

use camplace_sim::parse_labels;

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else { return };
    let frames: Vec<String> = (0..4).map(|i| format!("{i:04}")).collect();
    let Ok(labels) = parse_labels(text, &frames, Path::new("labels.jsonl")) else { return };
    assert!(labels.iter().all(|l| frames.contains(&l.frame)));
    let written: String = labels.iter().map(|l| serde_json::to_string(l).expect("plain data") + "\n").collect();
    let back = parse_labels(&written, &frames, Path::new("labels.jsonl")).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(back, labels);
});
