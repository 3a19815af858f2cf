//! `tolerance.json`: what a tolerance measurement found (each parameter's edge on both
//! sides with the points just inside and just outside it, the corners of the box), its
//! table for a terminal, and reading it back checked, since `camplace placement` judges an
//! installed rig by it and `camplace serve` takes its drift limits from it. The measurement
//! itself is the simulator's.

use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::{pct, Error, Placement, PlacementParam, Vergence, MAX_DISTANCE_MM};

type Result<T> = std::result::Result<T, Error>;

/// Why a walk in one direction stopped.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum WalkEnd {
    /// A point was judged outside: the edge lies between the last point inside and it.
    Drop,
    /// The parameter's range ended with every point inside: the tolerance is at least that.
    RangeEnd,
}

/// One evaluated placement, paired by scene against the nominal.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TolerancePoint {
    /// Offset from the nominal value, mm or deg.
    pub offset: f64,
    /// Success rate there (the lowest tray's).
    pub success_rate: f64,
    /// Its Wilson 95 % interval.
    pub success_interval: [f64; 2],
    /// Scenes scored there.
    pub scenes: usize,
    /// Scenes the nominal succeeded on and this point did not (the tray of the smallest p).
    pub lost: usize,
    /// Scenes this point succeeded on and the nominal did not (the same tray).
    pub gained: usize,
    /// One-sided exact McNemar p-value that this point succeeds less often than the nominal
    /// (the smallest over the trays); the point is outside when it is below the level.
    pub p_lower: f64,
}

/// One parameter's tolerance on both sides.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AxisTolerance {
    /// The parameter's name.
    pub parameter: String,
    /// mm or deg.
    pub unit: String,
    /// The resolution the edge is found to (offsets are whole numbers of it).
    pub resolution: f64,
    /// The furthest offset walked on either side (more than a bracket is ever off by); a
    /// side ending at it without a drop is at least this far (0 in files that predate it).
    #[serde(default)]
    pub limit: f64,
    /// How far below the nominal value it may be (0 or more): the furthest point inside.
    pub minus: f64,
    /// Why the walk downwards stopped.
    pub minus_end: WalkEnd,
    /// The point just inside the lower edge (the nominal when none further was).
    pub minus_inside: TolerancePoint,
    /// The point just outside it, one resolution further (none when the range ended).
    pub minus_outside: Option<TolerancePoint>,
    /// The furthest valid offset downwards (the range's end), negative or 0.
    pub minus_range: f64,
    /// How far above the nominal value it may be.
    pub plus: f64,
    /// Why the walk upwards stopped.
    pub plus_end: WalkEnd,
    /// The point just inside the upper edge.
    pub plus_inside: TolerancePoint,
    /// The point just outside it.
    pub plus_outside: Option<TolerancePoint>,
    /// The furthest valid offset upwards, positive or 0.
    pub plus_range: f64,
    /// Every evaluated offset, ascending, the nominal (0) included.
    pub points: Vec<TolerancePoint>,
}

/// One corner of the tolerance box.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ToleranceCorner {
    /// The placement there.
    pub placement: String,
    /// Each parameter's offset, in the order of the tolerance parameters.
    pub offsets: [f64; 5],
    /// Success there, paired against the nominal.
    pub point: TolerancePoint,
}

/// The whole measurement (`tolerance.json`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ToleranceReport {
    /// The nominal placement (toe-in in degrees).
    pub placement: String,
    /// Sensor method.
    pub method: String,
    /// Seed of the scenarios.
    pub seed: u64,
    /// Scenarios per placement (the same scenes everywhere).
    pub scenarios: u64,
    /// The drop of success the scene count is to detect (0.1: 10 points).
    pub margin: f64,
    /// The level of the one-sided paired test that puts a point outside (0.05).
    pub level: f64,
    /// The chance that a point whose true success is `margin` below the nominal's is put
    /// outside (it loses that share of the scenes and gains none).
    pub power: f64,
    /// Success at the nominal placement.
    pub nominal: TolerancePoint,
    /// Each walked parameter's tolerance, in the order of the tolerance parameters.
    pub axes: Vec<AxisTolerance>,
    /// The share of each found tolerance the corners are placed at (1: the edges).
    pub corner_fraction: f64,
    /// The distinct corners of the box.
    pub corners: Vec<ToleranceCorner>,
    /// Scenes every corner was screened on before the lowest ran on to their verdict (0:
    /// every corner ran to its verdict; absent in files written before it).
    #[serde(default)]
    pub corner_screen: u64,
}

impl ToleranceReport {
    /// The tolerance measured for `param`, if it was walked.
    pub fn axis(&self, param: PlacementParam) -> Option<&AxisTolerance> {
        self.axes.iter().find(|a| a.parameter == param.name())
    }

    /// The corner with the lowest success rate (the first of equals), if any.
    pub fn worst_corner(&self) -> Option<&ToleranceCorner> {
        self.corners.iter().fold(None, |worst: Option<&ToleranceCorner>, c| match worst {
            Some(w) if w.point.success_rate <= c.point.success_rate => Some(w),
            _ => Some(c),
        })
    }

    /// How the points were judged, in one sentence.
    pub fn test_text(&self) -> String {
        format!(
            "a point is outside when the one-sided exact McNemar test, paired by scene against the nominal on the \
             same {} scenes, shows its success lower at the {:.0} % level; a true drop of {:.0} points is caught \
             with {:.0} % power",
            self.scenarios,
            100.0 * self.level,
            100.0 * self.margin,
            100.0 * self.power
        )
    }

    /// A table for a terminal: one row per parameter and side, then the worst corner.
    pub fn table(&self) -> String {
        let mut text = format!(
            "tolerance of {} ({}, seed {}, {} scenarios; nominal success {})\n  {}\n",
            self.placement,
            self.method,
            self.seed,
            self.scenarios,
            pct(self.nominal.success_rate),
            self.test_text()
        );
        if let Some(limits) = self.limits_text() {
            text.push_str(&format!("  each side walked at most {limits}\n"));
        }
        for a in &self.axes {
            for side in a.sides() {
                text.push_str(&format!("  {:<9} {}\n", a.parameter, side.text(&a.parameter, &a.unit)));
            }
        }
        if self.nominal.success_rate < 0.5 {
            text.push_str(
                "  note: the nominal placement itself fails on most scenes, so little can be lost; measure around a placement that works\n",
            );
        }
        if let Some(w) = self.worst_corner() {
            text.push_str(&format!(
                "  worst of {} corners ({}{}): {} at {} (95 % interval {}–{}; {} scenes lost, {} gained)",
                self.corners.len(),
                self.corner_text(),
                self.screen_text(),
                pct(w.point.success_rate),
                w.placement,
                pct(w.point.success_interval[0]),
                pct(w.point.success_interval[1]),
                w.point.lost,
                w.point.gained
            ));
        }
        text
    }

    /// How far each side was walked at most, in words ("±400 mm (r), ±30 deg (alpha)"), or
    /// `None` for a file that predates the limits.
    pub fn limits_text(&self) -> Option<String> {
        if self.axes.iter().any(|a| a.limit <= 0.0) {
            return None;
        }
        let each: Vec<String> =
            self.axes.iter().map(|a| format!("±{} {} ({})", num(a.limit), a.unit, a.parameter)).collect();
        Some(each.join(", "))
    }

    /// How the corners were screened, in words after a "; " (empty when every corner ran
    /// to its verdict).
    pub fn screen_text(&self) -> String {
        if self.corner_screen == 0 {
            return String::new();
        }
        format!("; each screened on {} scenes, the lowest run on until their verdict settled", self.corner_screen)
    }

    /// Where the corners are, in words.
    pub fn corner_text(&self) -> String {
        if self.corner_fraction == 1.0 {
            "every parameter at its edge at once".to_string()
        } else {
            format!("every parameter at {:.0} % of its tolerance at once", 100.0 * self.corner_fraction)
        }
    }

    /// Reads `path` and checks every field a rig is judged by: refused when it is not a
    /// regular text file within the text budget, holds anything after its JSON value, or a
    /// tolerance that is not a finite, non-negative number within its unit's bounds.
    pub fn load(path: &Path) -> Result<ToleranceReport> {
        let bytes = crate::read_bounded(path, crate::FileKind::Text)?;
        Self::from_json(&bytes).map_err(|what| Error::format(what).in_file(path))
    }

    /// Decodes and checks the bytes of a `tolerance.json` (see [`ToleranceReport::load`]);
    /// the error names the field, without the file.
    pub fn from_json(bytes: &[u8]) -> std::result::Result<ToleranceReport, String> {
        // serde_json refuses anything but white space after the value.
        let report: ToleranceReport = serde_json::from_slice(bytes).map_err(|e| {
            format!("expected the tolerance.json camplace tolerance or study writes (one JSON object): {e}")
        })?;
        report.check()?;
        Ok(report)
    }

    /// The checks of [`ToleranceReport::load`], naming the field.
    pub fn check(&self) -> std::result::Result<(), String> {
        // Every parameter is written out, so the base's values never show through.
        let base = Placement { r: 1.0, alpha: 0.0, baseline: 1.0, vergence: Vergence::Degrees(0.0), azimuth: 0.0 };
        base.with_overrides(&self.placement).ok().filter(|p| p.validate("").is_ok()).ok_or_else(|| {
            format!(
                "placement: expected a valid placement such as r=605,alpha=32,baseline=81,vergence=3.5, got \"{}\"",
                self.placement
            )
        })?;
        let share = |name: &str, v: f64| {
            if v.is_finite() && (0.0..=1.0).contains(&v) {
                Ok(())
            } else {
                Err(format!("{name}: expected a share from 0 to 1, got {v}"))
            }
        };
        share("margin", self.margin)?;
        share("level", self.level)?;
        share("power", self.power)?;
        share("corner_fraction", self.corner_fraction)?;
        share("nominal.success_rate", self.nominal.success_rate)?;
        let mut seen: Vec<&str> = Vec::new();
        for (i, a) in self.axes.iter().enumerate() {
            let key = |field: &str| format!("axes[{i}].{field}");
            let Some(bound) = unit_bound(&a.parameter, &a.unit) else {
                return Err(format!(
                    "{}: expected r or baseline in mm, or alpha, vergence or azimuth in deg; got {} in {}",
                    key("parameter"),
                    a.parameter,
                    a.unit
                ));
            };
            if seen.contains(&a.parameter.as_str()) {
                return Err(format!("{}: {} is given twice", key("parameter"), a.parameter));
            }
            seen.push(&a.parameter);
            for (field, v) in [("minus", a.minus), ("plus", a.plus), ("resolution", a.resolution), ("limit", a.limit)] {
                if !(v.is_finite() && (0.0..=bound).contains(&v)) {
                    return Err(format!(
                        "{}: expected a finite tolerance from 0 to {bound} {}, got {v}",
                        key(field),
                        a.unit
                    ));
                }
            }
            for (field, p) in [("minus_inside", &a.minus_inside), ("plus_inside", &a.plus_inside)] {
                share(&key(&format!("{field}.success_rate")), p.success_rate)?;
            }
        }
        Ok(())
    }
}

/// The largest tolerance a parameter can have in its unit, or `None` for an unknown pair.
fn unit_bound(parameter: &str, unit: &str) -> Option<f64> {
    let param = PlacementParam::from_name(parameter).filter(|p| p.unit() == unit)?;
    Some(match param {
        PlacementParam::R | PlacementParam::Baseline => MAX_DISTANCE_MM,
        PlacementParam::Alpha | PlacementParam::Vergence => 90.0,
        PlacementParam::Azimuth => 360.0,
    })
}

/// One side of one parameter, as the table states it.
pub struct SideView<'a> {
    /// -1 below the nominal, +1 above.
    pub sign: f64,
    /// The tolerance (0 or more).
    pub tolerance: f64,
    /// Why the walk stopped.
    pub end: WalkEnd,
    /// The point just inside.
    pub inside: &'a TolerancePoint,
    /// The point just outside.
    pub outside: Option<&'a TolerancePoint>,
    /// The range's end on this side (signed offset).
    pub range: f64,
    /// The furthest offset walked (0: not recorded).
    pub limit: f64,
}

impl AxisTolerance {
    /// The lower side, then the upper.
    pub fn sides(&self) -> [SideView<'_>; 2] {
        [
            SideView {
                sign: -1.0,
                tolerance: self.minus,
                end: self.minus_end,
                inside: &self.minus_inside,
                outside: self.minus_outside.as_ref(),
                range: self.minus_range,
                limit: self.limit,
            },
            SideView {
                sign: 1.0,
                tolerance: self.plus,
                end: self.plus_end,
                inside: &self.plus_inside,
                outside: self.plus_outside.as_ref(),
                range: self.plus_range,
                limit: self.limit,
            },
        ]
    }
}

impl SideView<'_> {
    /// "−35 mm: inside 95.0 % [86.3–98.6 %] at −35; outside 78.3 % [66.4–86.9 %] at −40 (…)"
    /// or "at least −32 deg: the placement's range ends there (alpha offset −32); …".
    pub fn text(&self, parameter: &str, unit: &str) -> String {
        let signed = |v: f64| if self.sign < 0.0 { format!("−{}", num(v)) } else { format!("+{}", num(v)) };
        let rate = |p: &TolerancePoint| {
            format!(
                "{} [{}–{}] at {}",
                pct(p.success_rate),
                pct(p.success_interval[0]),
                pct(p.success_interval[1]),
                offset_text(p.offset)
            )
        };
        match (self.end, self.outside) {
            (WalkEnd::Drop, Some(out)) => format!(
                "{} {unit}: inside {}; outside {} ({} scenes lost, {} gained, p {})",
                signed(self.tolerance),
                rate(self.inside),
                rate(out),
                out.lost,
                out.gained,
                p_text(out.p_lower)
            ),
            _ => format!(
                "at least {} {unit}: {}; {}",
                signed(self.tolerance),
                self.range_text(parameter, unit),
                rate(self.inside)
            ),
        }
    }

    /// Whether the walk's own limit ended this side, rather than the placement's range.
    pub fn at_walk_limit(&self) -> bool {
        self.limit > 0.0 && self.range.abs() >= self.limit - 1e-9
    }

    /// What ended the range on this side, in words: "the walk's limit (±400 mm) ends there"
    /// or "the placement's range ends there (alpha offset −32)".
    pub fn range_text(&self, parameter: &str, unit: &str) -> String {
        if self.at_walk_limit() {
            format!("the walk's limit (±{} {unit}, more than a bracket is off by) ends there", num(self.limit))
        } else {
            format!("the placement's range ends there ({parameter} offset {})", offset_text(self.range))
        }
    }
}

/// An offset with its sign and no trailing zeros ("−35", "+0.25", "0").
pub fn offset_text(v: f64) -> String {
    if v == 0.0 {
        "0".to_string()
    } else if v < 0.0 {
        format!("−{}", num(-v))
    } else {
        format!("+{}", num(v))
    }
}

/// A number with up to three decimals and no trailing zeros.
fn num(v: f64) -> String {
    let text = format!("{v:.3}");
    text.trim_end_matches('0').trim_end_matches('.').to_string()
}

/// "= 0.031", or "< 0.001".
fn p_text(p: f64) -> String {
    if p < 0.001 {
        "< 0.001".to_string()
    } else {
        format!("= {p:.3}")
    }
}

/// How a walk ended, in words.
pub fn end_text(end: WalkEnd) -> &'static str {
    match end {
        WalkEnd::Drop => "edge",
        WalkEnd::RangeEnd => "range end",
    }
}
