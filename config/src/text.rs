//! How the numbers camplace prints are written, for every crate's summaries and reports.

/// A rate as a percentage with one decimal: `0.9712` -> `"97.1 %"`.
pub fn pct(r: f64) -> String {
    format!("{:.1} %", 100.0 * r)
}
