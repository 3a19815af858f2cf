//! The report's section on verified poses: at each method's best placement, the verified
//! success (correct and accepted), the wrong poses accepted with their 95 % upper bound,
//! the correct poses rejected and the threshold, and the precision–recall curve of the
//! verification's score (SVG and PNG). It reads the fresh scenes' records the study kept;
//! the figures themselves are `study::verified`'s.

use std::path::Path;

use plotters::coord::Shift;
use plotters::prelude::*;

use super::html::HtmlPage;
use crate::study::optimize::recheck_seed;
use crate::study::placement_study::Combination;
use crate::Result;
use camplace_estimator::scoring::pct;
use camplace_estimator::{scoring::precision_recall, scoring::Scored, scoring::VerifiedSummary};
use camplace_plot::PLOT_FONT_FAMILY as FAMILY;
use camplace_plot::{save_plot, Plot};

/// The precision–recall curve of one method's best placement.
#[derive(Debug, Clone, PartialEq)]
struct PrecisionRecallPlot {
    title: String,
    /// (recall, precision, threshold), highest threshold first.
    curve: Vec<(f64, f64, f32)>,
    /// The chosen threshold's (recall, precision).
    chosen: (f64, f64),
}

impl Plot for PrecisionRecallPlot {
    fn size(&self) -> (u32, u32) {
        (560, 380)
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> std::result::Result<(), String> {
        let e = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
        let low = self.curve.iter().map(|p| 100.0 * p.1).fold(90.0f64, f64::min).floor();
        let mut chart = ChartBuilder::on(root)
            .caption(&self.title, (FAMILY, 18))
            .margin(12)
            .x_label_area_size(42)
            .y_label_area_size(56)
            .build_cartesian_2d(0f64..100.5f64, low..100.5f64)
            .map_err(e)?;
        let whole = |v: &f64| format!("{v:.0}");
        chart
            .configure_mesh()
            .x_label_formatter(&whole)
            .y_label_formatter(&whole)
            .x_desc("recall: correct poses accepted, %")
            .y_desc("precision: accepted poses correct, %")
            .label_style((FAMILY, 13))
            .axis_desc_style((FAMILY, 15))
            .draw()
            .map_err(e)?;
        let blue = RGBColor(31, 119, 180);
        let line = self.curve.iter().map(|p| (100.0 * p.0, 100.0 * p.1));
        chart.draw_series(LineSeries::new(line, blue.stroke_width(2))).map_err(e)?;
        let (x, y) = (100.0 * self.chosen.0, 100.0 * self.chosen.1);
        chart.draw_series([Circle::new((x, y), 5, RED.filled())]).map_err(e)?;
        Ok(())
    }
}

/// The section "Verified poses": a table per method at its best placement and the curve.
/// Methods whose records carry no score (a folder from before the verification) are left
/// out, said in a sentence.
pub fn verification_section(page: &mut HtmlPage, out: &Path, combos: &[Combination], seed: u64) -> Result<()> {
    page.heading(2, "Verified poses");
    page.paragraph(
        "After ICP every pose is verified: its score (0 to 1) is the share of the tray's surface facing the sensor \
         that the sensor saw, times the share of measured points inside the tray's box that the model explains. A \
         pose is handed on only when it rests on the table, the scene shows the parts that tell it from each \
         unlisted quarter turn (a tab) more where the pose puts them than where the turn does, by a standard \
         deviation of the counts (or shows neither's), and its score reaches the threshold. The threshold is the lowest score at which wrong poses are at \
         most the cell's estimator.verify_max_wrong of the accepted ones on these fresh scenes; a near miss (within \
         twice the success limits) counts only where the score tells near misses from correct poses beyond \
         chance, since the rig's calibration error leaves no trace in the fit, and where such near misses are more \
         than the target share of the accepted poses beyond chance, every pose is refused. camplace model measures it the same \
         way and stores it in the model file. Every wrong pose accepted counts in the share and its bound. The upper bound is the one-sided 95 % \
         Clopper–Pearson bound of the wrong share among accepted poses.",
    );
    for (k, c) in combos.iter().enumerate() {
        let Some(top) = c.candidates.first() else { continue };
        // The lowest tray's scenes, whose summary judges the placement (and is the one
        // `recommended.json` carries).
        let lowest = top.per_tray.iter().position(|t| *t == top.summary).unwrap_or(0);
        let Some(v) = top.summary.verification else {
            page.paragraph(&format!("{}: its results carry no verification score.", c.name()));
            continue;
        };
        let n = top.summary.scored as u64;
        let records = c.set.tray_records(lowest, &top.placement, recheck_seed(seed), n);
        let metrics = &c.set.trays[lowest].cell.metrics;
        let frames: Vec<Scored> = records.iter().filter_map(|r| Scored::of(r, metrics)).collect();
        page.paragraph(&format!("{} at {} ({}):", c.name(), top.placement, c.set.trays[lowest].name));
        page.keyed_table(&format!("verification-{k}"), &verified_rows(&c.method.to_string(), &v));
        let curve = precision_recall(&frames);
        let at = curve.iter().rev().find(|p| p.2 >= v.threshold).map_or((0.0, 1.0), |p| (p.0, p.1));
        let plot = PrecisionRecallPlot { title: format!("{}: precision against recall", c.name()), curve, chosen: at };
        if let Some(saved) = save_plot(&plot, out, &format!("precision_recall_{}", c.method))? {
            page.svg(&saved.svg)?;
        }
    }
    Ok(())
}

/// The threshold as the table shows it: the score, or that every pose is refused and why.
fn threshold_cell(v: &VerifiedSummary) -> String {
    v.near_misses_untold.map_or_else(|| format!("{:.3}", v.threshold), |e| e.to_string())
}

/// The keyed rows of one method's verified figures, each key `METHOD:FIELD` with the field
/// of `summary.json`'s `verification`.
fn verified_rows(method: &str, v: &VerifiedSummary) -> Vec<(String, String, String)> {
    let rows: Vec<(&str, String, String)> = vec![
        (
            "verified_success_rate",
            format!("verified success (correct and accepted) on {} fresh scenes", v.scored),
            format!("{} ({} of {})", pct(v.verified_success_rate), v.verified_successes, v.scored),
        ),
        (
            "wrong_accepted_share",
            "wrong poses among the accepted".into(),
            format!("{} ({} of {})", pct(v.wrong_accepted_share), v.wrong_accepted, v.accepted),
        ),
        ("wrong_accepted_upper", "its 95 % upper bound (Clopper–Pearson)".into(), pct(v.wrong_accepted_upper)),
        (
            "correct_rejected_share",
            "correct poses rejected".into(),
            format!("{} ({} of {})", pct(v.correct_rejected_share), v.correct_rejected, v.correct),
        ),
        ("threshold", "score threshold".into(), threshold_cell(v)),
    ];
    rows.into_iter().map(|(key, label, value)| (format!("{method}:{key}"), label, value)).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use camplace_estimator::scoring::{NearMissExcess, Scored};

    /// The threshold row shows the score, or the refusal of every pose with what the gross
    /// threshold would have accepted.
    #[test]
    fn the_threshold_row_says_when_every_pose_is_refused() {
        let frames: Vec<Scored> = (0..50)
            .map(|i| Scored { score: 0.5 + i as f32 / 100.0, eligible: true, correct: true, gross: false })
            .collect();
        let plain = VerifiedSummary::choose(&frames, &[], 0.005).unwrap();
        assert_eq!(threshold_cell(&plain), "0.500");
        let mut refused = plain;
        refused.near_misses_untold =
            Some(NearMissExcess { threshold: 0.514, accepted: 167, wrong: 26, near_misses: 26 });
        let cell = threshold_cell(&refused);
        assert!(cell.starts_with("every pose refused: at 0.514 26 of the 167"), "{cell}");
        let rows = verified_rows("one-shot", &refused);
        assert_eq!(rows.last().map(|r| (r.0.as_str(), r.2.as_str())), Some(("one-shot:threshold", cell.as_str())));
    }
}
