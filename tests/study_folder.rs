//! A study folder's outputs in a form two runs can be compared in: `summary.json` and
//! `results.jsonl` without the timings, which differ run to run.

use std::path::Path;

use serde_json::Value;

/// summary.json without the timings.
pub fn summary_without_timings(path: &Path) -> Value {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut v: Value = serde_json::from_str(&text).unwrap();
    for row in v.as_array_mut().unwrap() {
        let row = row.as_object_mut().unwrap();
        row.remove("median_timings_ms");
        row.remove("median_ms");
    }
    v
}

/// Result lines keyed by (placement, scenario) and sorted by key, without the timings.
pub fn results_without_timings(path: &Path) -> Vec<((String, u64), Value)> {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut v: Vec<((String, u64), Value)> = text
        .lines()
        .map(|l| {
            let mut v: Value = serde_json::from_str(l).unwrap();
            let o = v.as_object_mut().unwrap();
            o.remove("timings_ms");
            o.remove("ms");
            let key = (o["placement"].as_str().unwrap().to_string(), o["scenario"].as_u64().unwrap());
            (key, v)
        })
        .collect();
    v.sort_by(|a, b| a.0.cmp(&b.0));
    v
}
