//! The mounting check: a rig's placement as built (read back from its calibration by
//! [`as_built`](super::as_built::as_built)) against the planned placement, parameter by
//! parameter, and with measured tolerances whether each difference lies within them. The
//! azimuth's difference is taken the short way round. How it is printed is the caller's.

use camplace_config::{Placement, PlacementParam, ToleranceReport};

use crate::as_built::{azimuth_difference, AsBuilt};

/// The slack a difference may pass a tolerance's edge by and still be within it: the
/// rounding of a tolerance written to a file.
const EDGE_SLACK: f64 = 1e-9;

/// Whether one parameter is mounted within its tolerance.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MountingVerdict {
    /// The difference lies within the tolerance on its side.
    Within,
    /// The difference lies beyond the tolerance on its side.
    Outside,
    /// No tolerance was measured for the parameter.
    NotMeasured,
}

/// How far one parameter may be off the plan, mm or deg (both 0 or more).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MountingLimit {
    /// Below the planned value.
    pub minus: f64,
    /// Above the planned value.
    pub plus: f64,
}

/// One parameter of the mounting check.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ParamCheck {
    /// The parameter (its name and unit).
    pub param: PlacementParam,
    /// Its value as built (the vergence as the mean toe-in, deg).
    pub as_built: f64,
    /// Its planned value.
    pub planned: f64,
    /// As built less planned; the azimuth's in (-180, 180].
    pub difference: f64,
    /// The measured tolerance, if any.
    pub limit: Option<MountingLimit>,
    /// Whether the difference lies within it.
    pub verdict: MountingVerdict,
}

/// Every placement parameter of a rig as built against its plan.
#[derive(Debug, Clone, PartialEq)]
pub struct MountingCheck {
    /// One check per parameter, in the order placements are written ([`PlacementParam::ALL`]).
    pub params: Vec<ParamCheck>,
}

impl MountingCheck {
    /// The parameters mounted outside their tolerance, in order.
    pub fn outside(&self) -> Vec<PlacementParam> {
        self.params.iter().filter(|c| c.verdict == MountingVerdict::Outside).map(|c| c.param).collect()
    }

    /// Whether no parameter is outside its tolerance (a parameter not measured is not).
    pub fn within(&self) -> bool {
        self.params.iter().all(|c| c.verdict != MountingVerdict::Outside)
    }
}

/// Compares `built` with `plan`, each parameter against its tolerance in `limits` when it
/// was measured there.
pub fn mounting_check(built: &AsBuilt, plan: &Placement, limits: Option<&ToleranceReport>) -> MountingCheck {
    let params = PlacementParam::ALL
        .into_iter()
        .map(|param| {
            let (as_built, planned) = (param.get(&built.placement), param.get(plan));
            let difference = match param {
                PlacementParam::Azimuth => azimuth_difference(as_built, planned),
                _ => as_built - planned,
            };
            let limit = limits.and_then(|t| t.axis(param)).map(|a| MountingLimit { minus: a.minus, plus: a.plus });
            let verdict = match limit {
                Some(l) if difference < -l.minus - EDGE_SLACK || difference > l.plus + EDGE_SLACK => {
                    MountingVerdict::Outside
                }
                Some(_) => MountingVerdict::Within,
                None => MountingVerdict::NotMeasured,
            };
            ParamCheck { param, as_built, planned, difference, limit, verdict }
        })
        .collect();
    MountingCheck { params }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::placement_rig::rig_for;
    use camplace_config::{Cell, Vergence};

    fn plan() -> Placement {
        Placement { r: 605.0, alpha: 32.0, baseline: 81.0, vergence: Vergence::Degrees(3.5), azimuth: 0.0 }
    }

    /// The rig rendered at `p`, read back: what a calibration of it gives.
    fn built_at(p: &Placement) -> AsBuilt {
        crate::as_built(&rig_for(p, &Cell::default().sensor)).unwrap()
    }

    /// A tolerance report with `(parameter, minus, plus)` measured.
    fn limits(axes: &[(PlacementParam, f64, f64)]) -> ToleranceReport {
        crate::testing::tolerance_report(&plan().to_string(), axes)
    }

    fn verdicts(c: &MountingCheck) -> Vec<MountingVerdict> {
        c.params.iter().map(|p| p.verdict).collect()
    }

    use MountingVerdict::{NotMeasured, Outside, Within};

    #[test]
    fn a_rig_mounted_inside_every_tolerance_is_within() {
        let t = limits(&[
            (PlacementParam::R, 20.0, 30.0),
            (PlacementParam::Alpha, 3.0, 4.0),
            (PlacementParam::Baseline, 10.0, 10.0),
            (PlacementParam::Vergence, 0.5, 0.75),
            (PlacementParam::Azimuth, 5.0, 5.0),
        ]);
        let moved = Placement { r: 625.0, alpha: 30.0, baseline: 85.0, vergence: Vergence::Degrees(3.0), azimuth: 4.0 };
        let c = mounting_check(&built_at(&moved), &plan(), Some(&t));
        assert_eq!(verdicts(&c), [Within; 5], "{c:?}");
        assert!(c.within() && c.outside().is_empty());
        let order: Vec<PlacementParam> = c.params.iter().map(|p| p.param).collect();
        assert_eq!(order, PlacementParam::ALL);
        // The differences against the truth the rig was rendered from.
        for (check, want) in c.params.iter().zip([20.0, -2.0, 4.0, -0.5, 4.0]) {
            assert!((check.difference - want).abs() < 1e-6, "{check:?}");
            assert!((check.as_built - check.planned - want).abs() < 1e-6, "{check:?}");
        }
        assert_eq!(c.params[0].limit, Some(MountingLimit { minus: 20.0, plus: 30.0 }));
        // At the edge exactly: within.
        let edge = Placement { r: 585.0, ..plan() };
        assert!(mounting_check(&built_at(&edge), &plan(), Some(&t)).within());
    }

    #[test]
    fn a_rig_off_on_either_side_is_outside_on_that_side_only() {
        let t = limits(&[(PlacementParam::R, 20.0, 30.0), (PlacementParam::Alpha, 3.0, 4.0)]);
        // r: 25 below (beyond its 20) and 25 above (within its 30); alpha: 5 above (beyond
        // its 4) and 3.5 below (beyond its 3).
        for (moved, outside) in [
            (Placement { r: 580.0, ..plan() }, vec![PlacementParam::R]),
            (Placement { r: 630.0, ..plan() }, vec![]),
            (Placement { r: 640.0, ..plan() }, vec![PlacementParam::R]),
            (Placement { alpha: 37.0, ..plan() }, vec![PlacementParam::Alpha]),
            (Placement { alpha: 28.5, ..plan() }, vec![PlacementParam::Alpha]),
            (Placement { r: 580.0, alpha: 37.0, ..plan() }, vec![PlacementParam::R, PlacementParam::Alpha]),
        ] {
            let c = mounting_check(&built_at(&moved), &plan(), Some(&t));
            assert_eq!(c.outside(), outside, "{moved}: {c:?}");
            assert_eq!(c.within(), outside.is_empty());
            // Baseline, vergence and azimuth were not walked.
            assert_eq!(verdicts(&c)[2..], [NotMeasured; 3]);
        }
    }

    #[test]
    fn the_azimuth_differs_the_short_way_round_across_180() {
        let t = limits(&[(PlacementParam::Azimuth, 5.0, 5.0)]);
        let plan = Placement { azimuth: 178.0, ..plan() };
        // Mounted at -178° (182°): 4° on, not 356° back.
        let c = mounting_check(&built_at(&Placement { azimuth: -178.0, ..plan }), &plan, Some(&t));
        let azimuth = c.params[4];
        assert_eq!(azimuth.param, PlacementParam::Azimuth);
        assert!((azimuth.difference - 4.0).abs() < 1e-6, "{azimuth:?}");
        assert_eq!(azimuth.verdict, Within);
        // Mounted at -170°: 12° on, outside.
        let c = mounting_check(&built_at(&Placement { azimuth: -170.0, ..plan }), &plan, Some(&t));
        assert!((c.params[4].difference - 12.0).abs() < 1e-6 && c.outside() == [PlacementParam::Azimuth]);
        // Planned at -178°, mounted at 176°: 6° back, outside on the minus side.
        let plan = Placement { azimuth: -178.0, ..plan };
        let c = mounting_check(&built_at(&Placement { azimuth: 176.0, ..plan }), &plan, Some(&t));
        assert!((c.params[4].difference + 6.0).abs() < 1e-6 && c.params[4].verdict == Outside, "{c:?}");
    }

    #[test]
    fn without_tolerances_nothing_is_measured_or_outside() {
        let moved = Placement { r: 900.0, alpha: 50.0, ..plan() };
        let c = mounting_check(&built_at(&moved), &plan(), None);
        assert_eq!(verdicts(&c), [NotMeasured; 5]);
        assert!(c.within() && c.params.iter().all(|p| p.limit.is_none()));
        assert!((c.params[0].difference - 295.0).abs() < 1e-6 && (c.params[1].difference - 18.0).abs() < 1e-6);
    }
}
