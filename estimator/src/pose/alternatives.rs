//! The poses a tray can be mistaken for, in its own frame: its three quarter turns about its
//! centre, and the turns that lay most of its slot grid onto itself once shifted (a 3 × 2
//! tray of slots 80 mm apart both ways, turned a quarter turn and moved 40 mm along each
//! axis, puts four of its six slots, and the items in them, where four of the right pose's
//! stand). A frame that shows only the slots the two share cannot tell them apart by the
//! points it explains; the parts where they differ can (`Icp::explained_near_and_apart`,
//! `TurnParts`). Found once per model, from its slots.

use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};

use crate::Model;

/// Alternatives weighed at most: the three quarter turns and [`MAX_LATTICE`] more.
pub const MAX_ALTERNATIVES: usize = 3 + MAX_LATTICE;
/// Turned-and-shifted alternatives kept at most, those laying the most slots onto slots
/// first (nearest first among equals).
pub const MAX_LATTICE: usize = 12;
/// 0, 1, 2 … : the indices [`Alternatives::every`] hands out.
const EVERY: [usize; MAX_ALTERNATIVES] = {
    let mut every = [0; MAX_ALTERNATIVES];
    let mut k = 0;
    while k < MAX_ALTERNATIVES {
        every[k] = k;
        k += 1;
    }
    every
};
/// Slots read at most when looking for the grid's alternatives.
const MAX_SLOTS: usize = 64;
/// A slot centre moved by an alternative lies on another when within this share of the
/// shortest slot-to-slot distance.
const ALIGN_SHARE: f64 = 0.1;

/// A pose of the tray in the tray's own frame: `x -> turn(x) + shift`, the turn being
/// `quarters` quarter turns about the tray's z axis and the shift along its x and y, mm.
/// The tray at `pose * alternative.transform()` is the alternative to the tray at `pose`.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Alternative {
    /// Quarter turns about the tray's z axis, 1 to 3.
    pub quarters: u32,
    /// The shift after the turn (tray frame, z = 0), mm; zero for a turn about the centre.
    pub shift: Vector3<f64>,
}

impl Alternative {
    /// The turn by `quarters` quarter turns about the tray's centre.
    pub fn turn(quarters: u32) -> Alternative {
        Alternative { quarters, shift: Vector3::zeros() }
    }

    /// The alternative as a transform of the tray frame (alternative's frame -> tray frame).
    pub fn transform(&self) -> Isometry3<f64> {
        Isometry3::from_parts(Translation3::from(self.shift), quarter_turns(self.quarters))
    }

    /// Whether it is a turn about the centre.
    pub fn about_centre(&self) -> bool {
        self.shift.norm() < 1e-9
    }

    /// `p` (tray frame) taken back by the alternative: the point of the alternative's tray
    /// that lands on `p`.
    pub fn back(&self, p: &Point3<f32>) -> Point3<f32> {
        let s = self.shift.cast::<f32>();
        turned_back(&Point3::new(p.x - s.x, p.y - s.y, p.z), self.quarters)
    }

    /// Whether `model`'s listed symmetries make the alternative the same tray: a listed turn
    /// about the centre. (A listed turn with a shift is a shift, not weighed here.)
    pub fn listed(&self, model: &Model) -> bool {
        self.about_centre() && listed_turn(model, self.quarters)
    }
}

/// The alternatives of one tray: the quarter turns 1, 2 and 3 at 0, 1 and 2, then the
/// turned-and-shifted ones, each with its inverse in the list.
#[derive(Debug, Clone, PartialEq)]
pub struct Alternatives {
    list: Vec<Alternative>,
    /// Per alternative, the index of its inverse.
    inverse: Vec<usize>,
}

impl Default for Alternatives {
    fn default() -> Self {
        Alternatives { list: (1..4).map(Alternative::turn).collect(), inverse: vec![2, 1, 0] }
    }
}

impl Alternatives {
    /// The quarter turns of `model`'s tray and, from its slots, each turn that a shift
    /// makes lay more than half of the slot centres onto slot centres (the tray's listed
    /// turns excepted: shifted, they are shifts, which the see-through test weighs).
    pub fn of(model: &Model) -> Alternatives {
        let mut out = Alternatives::default();
        let Some(layout) = &model.slots else { return out };
        let centres: Vec<Vector3<f64>> =
            layout.slots.iter().take(MAX_SLOTS).map(|s| Vector3::new(s[0], s[1], 0.0)).collect();
        let n = centres.len();
        let shortest = centres
            .iter()
            .enumerate()
            .flat_map(|(i, a)| centres[i + 1..].iter().map(move |b| (b - a).norm()))
            .filter(|d| *d > 1e-6)
            .fold(f64::INFINITY, f64::min);
        if n < 2 || !shortest.is_finite() {
            return out;
        }
        let tolerance = ALIGN_SHARE * shortest;
        let aligned = |a: &Alternative| {
            let t = a.transform();
            centres
                .iter()
                .filter(|c| centres.iter().any(|d| (t * Point3::from(**c) - Point3::from(*d)).norm() <= tolerance))
                .count()
        };
        let mut candidates: Vec<(usize, Alternative)> = Vec::new();
        for quarters in (1..4).filter(|&q| !listed_turn(model, q)) {
            let turn = quarter_turns(quarters);
            for c in &centres {
                for d in &centres {
                    let shift = d - turn * c;
                    let a = Alternative { quarters, shift };
                    if shift.norm() <= tolerance
                        || candidates
                            .iter()
                            .any(|(_, b)| b.quarters == quarters && (b.shift - shift).norm() <= tolerance)
                    {
                        continue;
                    }
                    let count = aligned(&a);
                    if 2 * count > n && count >= 2 {
                        candidates.push((count, a));
                    }
                }
            }
        }
        // The most slots laid onto slots first, then the nearest, then by turn and shift: the
        // same list whatever order the slots are listed in.
        candidates.sort_by(|(ca, a), (cb, b)| {
            cb.cmp(ca)
                .then(a.shift.norm().total_cmp(&b.shift.norm()))
                .then(a.quarters.cmp(&b.quarters))
                .then(a.shift.x.total_cmp(&b.shift.x))
                .then(a.shift.y.total_cmp(&b.shift.y))
        });
        for (_, a) in &candidates {
            if out.index_of(a, tolerance).is_some() {
                continue;
            }
            let inverse = a.inverse();
            let own_inverse = (inverse.shift - a.shift).norm() <= tolerance && inverse.quarters == a.quarters;
            let room = MAX_ALTERNATIVES - out.list.len();
            if room < if own_inverse { 1 } else { 2 } {
                break;
            }
            let at = out.list.len();
            out.list.push(*a);
            if own_inverse {
                out.inverse.push(at);
            } else {
                out.list.push(inverse);
                out.inverse.extend([at + 1, at]);
            }
        }
        out
    }

    /// Every alternative, the quarter turns first.
    pub fn list(&self) -> &[Alternative] {
        &self.list
    }

    /// Every alternative's index, for [`crate::Icp::explained_near_and_apart`].
    pub fn every(&self) -> &'static [usize] {
        &EVERY[..self.list.len()]
    }

    /// The index of alternative `k`'s inverse.
    pub fn inverse_of(&self, k: usize) -> usize {
        self.inverse[k]
    }

    fn index_of(&self, a: &Alternative, tolerance: f64) -> Option<usize> {
        self.list.iter().position(|b| b.quarters == a.quarters && (b.shift - a.shift).norm() <= tolerance)
    }
}

impl Alternative {
    /// The alternative that undoes this one: `x -> turn⁻¹(x − shift)`.
    pub fn inverse(&self) -> Alternative {
        let quarters = (4 - self.quarters % 4) % 4;
        Alternative { quarters, shift: -(quarter_turns(quarters) * self.shift) }
    }
}

/// Whether `model`'s symmetries list the turn by `quarters` quarter turns about its z axis.
pub(crate) fn listed_turn(model: &Model, quarters: u32) -> bool {
    model.symmetries_deg.iter().any(|s| (s.rem_euclid(360.0) - 90.0 * quarters as f32).abs() < 1.0)
}

/// A turn by `quarters` quarter turns about the tray's z axis.
pub(crate) fn quarter_turns(quarters: u32) -> UnitQuaternion<f64> {
    UnitQuaternion::from_axis_angle(&Vector3::z_axis(), f64::from(quarters) * std::f64::consts::FRAC_PI_2)
}

/// `p` turned back by `quarters` (1 to 3) quarter turns about z: (x, y) -> (y, -x) per
/// quarter.
pub(crate) fn turned_back(p: &Point3<f32>, quarters: u32) -> Point3<f32> {
    match quarters {
        1 => Point3::new(p.y, -p.x, p.z),
        2 => Point3::new(-p.x, -p.y, p.z),
        _ => Point3::new(-p.y, p.x, p.z),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pose::SlotLayout;

    fn model_with(slots: Vec<[f64; 4]>, symmetries_deg: Vec<f32>) -> Model {
        let mut model = crate::testing::tray(false, 1);
        model.slots = Some(SlotLayout {
            slots,
            footprint_min_mm: [-5.0, -5.0],
            cell_mm: [5.0, 5.0],
            cols: 2,
            rows: 2,
            top_mm: vec![10.0; 4],
        });
        model.symmetries_deg = symmetries_deg;
        model
    }

    fn grid(cols: usize, rows: usize, px: f64, py: f64) -> Vec<[f64; 4]> {
        let (x0, y0) = (-(cols as f64 - 1.0) * px / 2.0, -(rows as f64 - 1.0) * py / 2.0);
        (0..rows).flat_map(|j| (0..cols).map(move |i| [x0 + i as f64 * px, y0 + j as f64 * py, 6.0, 0.0])).collect()
    }

    /// Against a count over every turn and every shift on a 1 mm lattice: the alternatives
    /// found are exactly the turned-and-shifted poses laying more than half of the slots
    /// onto slots, each with its inverse, and none for a listed turn.
    #[test]
    fn the_grid_alternatives_are_the_shifts_that_lay_most_slots_on_slots() {
        for (slots, symmetries, expected) in [
            // 3 × 2 at 80 mm both ways: quarter turns with (±40, ±40), half turns with (±80, 0).
            (grid(3, 2, 80.0, 80.0), vec![], 10),
            // The same with its half turn listed: the quarter turns' alone.
            (grid(3, 2, 80.0, 80.0), vec![180.0], 8),
            // 4 × 2 at 47.5 × 55 mm: the half turn moved by one pitch along x.
            (grid(4, 2, 47.5, 55.0), vec![], 2),
            // 2 × 2, square: every turn lays all four on themselves, shifted at most two.
            (grid(2, 2, 60.0, 60.0), vec![], 0),
        ] {
            let model = model_with(slots.clone(), symmetries.clone());
            let found = Alternatives::of(&model);
            assert_eq!(&found.list()[..3], Alternatives::default().list());
            let lattice = &found.list()[3..];
            assert_eq!(lattice.len(), expected, "{slots:?}: {lattice:?}");
            // The brute force: every turn, every shift on a 1 mm lattice within ±300 mm.
            let centres: Vec<Point3<f64>> = slots.iter().map(|s| Point3::new(s[0], s[1], 0.0)).collect();
            let mut brute = 0;
            for q in 1..4u32 {
                if symmetries.iter().any(|s| (s - 90.0 * q as f32).abs() < 1.0) {
                    continue;
                }
                for sx in -300..=300 {
                    for sy in -300..=300 {
                        let shift = Vector3::new(f64::from(sx) / 2.0, f64::from(sy) / 2.0, 0.0);
                        if shift.norm() < 1e-9 {
                            continue;
                        }
                        let t = Alternative { quarters: q, shift }.transform();
                        let on = centres.iter().filter(|c| centres.iter().any(|d| (t * **c - d).norm() < 1e-6)).count();
                        if 2 * on > centres.len() {
                            brute += 1;
                            assert!(
                                lattice.iter().any(|a| a.quarters == q && (a.shift - shift).norm() < 1e-6),
                                "missing q {q} {shift:?}"
                            );
                        }
                    }
                }
            }
            assert_eq!(brute, lattice.len());
            for (k, a) in found.list().iter().enumerate() {
                let undo = a.transform() * found.list()[found.inverse_of(k)].transform();
                assert!(undo.translation.vector.norm() < 1e-9 && undo.rotation.angle() < 1e-9, "{a:?}");
                // `back` undoes the transform.
                let p = Point3::new(12.5f32, -31.0, 7.0);
                let moved = a.transform().cast::<f32>() * p;
                assert!((a.back(&moved) - p).norm() < 1e-3);
            }
        }
    }
}
