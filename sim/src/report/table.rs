//! `summary.csv`: one row per placement with its success rate, interval, errors, correct
//! matches and median time.

use std::path::Path;

use camplace_config::write_atomic;

use serde::{Deserialize, Serialize};

use crate::Result;
use camplace_estimator::scoring::Summary;

/// One row: a placement, the method and seed, and its summary (a `summary.json` entry).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SummaryRow {
    /// The placement text.
    pub placement: String,
    /// The method's name.
    pub method: String,
    /// The study seed.
    pub seed: u64,
    /// The summary.
    #[serde(flatten)]
    pub summary: Summary,
}

/// The CSV header.
pub const HEADER: &str = "placement,method,seed,scenes,successes,success_rate,success_low,success_high,\
mean_position_error_mm,median_position_error_mm,mean_rotation_error_deg,median_rotation_error_deg,\
mean_correct_matches,median_ms";

/// Writes `rows` to `path` atomically (the placement is quoted: it holds commas).
pub fn write_summary_csv(path: &Path, rows: &[SummaryRow]) -> Result<()> {
    let opt = |v: Option<f64>| v.map_or(String::new(), |v| format!("{v:.4}"));
    let mut text = String::from(HEADER);
    text.push('\n');
    for r in rows {
        let s = &r.summary;
        text.push_str(&format!(
            "\"{}\",{},{},{},{},{:.4},{:.4},{:.4},{},{},{},{},{},{:.1}\n",
            r.placement,
            r.method,
            r.seed,
            s.scored,
            s.successes,
            s.success_rate,
            s.success_interval[0],
            s.success_interval[1],
            opt(s.mean_position_error_mm),
            opt(s.median_position_error_mm),
            opt(s.mean_rotation_error_deg),
            opt(s.median_rotation_error_deg),
            opt(s.mean_correct_matches),
            s.median_ms
        ));
    }
    Ok(write_atomic(path, text.as_bytes())?)
}

/// Writes `rows` as `summary.json` (an array, one entry per placement), atomically.
pub fn write_summary_json(path: &Path, rows: &[SummaryRow]) -> Result<()> {
    let text = serde_json::to_string_pretty(rows).expect("summaries are plain data");
    Ok(write_atomic(path, text.as_bytes())?)
}
