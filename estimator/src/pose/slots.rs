//! The tray's slots: their layout as the model carries it (each slot's pose in the tray
//! frame, the footprint an item stands on and the height profile of an upright item over
//! it), and the judge that reads, from a frame's scene cloud and the tray's verified pose,
//! whether each slot holds an item, is empty, or was not seen well enough to tell. Building
//! the layout from a cell's tray and item is the simulator's job.
//!
//! Allocation policy: [`SlotJudge::new`] sizes every buffer for the layout; `judge`
//! allocates nothing.

use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};

use crate::error::{Error, ErrorKind, Result};

/// A footprint cell's profile value marking a cell the item's outline crosses: its top there
/// depends on where exactly the item stands, so it is not compared.
pub const EDGE_CELL: f32 = -1.0;

/// The share of a slot's footprint that must be measured before an empty slot is called
/// empty: an item, or a foreign object a quarter of the footprint's size, shows its top in
/// any half of the footprint it covers.
pub const MIN_SEEN_SHARE: f32 = 0.5;

/// The share of the compared cells whose top may differ from an upright item's before a
/// filled slot is flagged askew: an item off by a pose error of a millimetre or two differs
/// only at its outline, which is not compared. An upright item beside one tilted 20° showed
/// 31 % in a rendered scene (a quarter flagged it); a 34 mm box tilted 20° differs over about
/// 65 % of its cells, a box of another size over nearly all.
pub const MAX_MISMATCH_SHARE: f32 = 0.4;

/// The points above the raise height a footprint cell must hold to count as raised. An
/// item's top, sampled at the surface resolution, puts several in each cell it covers; the
/// stereo matcher's stray points beside a neighbour's edge lie one to a cell (on 300
/// rendered one-shot tray-8 scenes at r=705.1, alpha=8.68, 13 to 69 of them over about half
/// a slot's footprint made 6 empty slots read filled).
pub const RAISED_CELL_POINTS: u16 = 2;

/// How far below the floor a measured point may lie and still count as the floor, mm (the
/// depth noise at the study's distances, and a tray resting a little tilted).
pub const FLOOR_TOLERANCE_MM: f32 = 4.0;

/// The most slots a tray's layout may hold (`SLOT n` names them in the robot protocol).
pub const MAX_SLOTS: usize = 1 << 12;
/// The most cells one slot's footprint may hold.
pub const MAX_FOOTPRINT_CELLS: usize = 1 << 16;
/// The most footprint cells over all slots: each frame fills and reads every one, so a
/// model file cannot ask for more than about 4 MB of them whatever its counts say.
pub const MAX_SLOT_CELLS: usize = 1 << 20;

/// The slots of a tray and the item they hold, as the model file carries them.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct SlotLayout {
    /// Each slot's pose `[x, y, z, yaw]` in the tray frame (mm, deg): where an item's bottom
    /// centre sits, z being the slot's floor height.
    pub slots: Vec<[f64; 4]>,
    /// The footprint's lowest corner `[x, y]` in the slot frame, mm: the item's outline
    /// shrunk by a margin, so its side faces and a millimetre of pose error stay outside.
    pub footprint_min_mm: [f32; 2],
    /// The size of one footprint cell `[x, y]`, mm.
    pub cell_mm: [f32; 2],
    /// Footprint cells along the slot's x axis.
    pub cols: u32,
    /// Footprint cells along the slot's y axis.
    pub rows: u32,
    /// Per cell (x fastest), the top of an upright item above the slot floor, mm; 0 where
    /// the item does not reach, [`EDGE_CELL`] where its outline crosses the cell.
    pub top_mm: Vec<f32>,
}

impl SlotLayout {
    /// Slot `n`'s frame in the tray frame (slot frame -> tray frame); `None` past the end.
    pub fn slot_pose(&self, n: usize) -> Option<Isometry3<f64>> {
        let [x, y, z, yaw] = *self.slots.get(n)?;
        Some(Isometry3::from_parts(
            Translation3::new(x, y, z),
            UnitQuaternion::from_axis_angle(&Vector3::z_axis(), yaw.to_radians()),
        ))
    }

    /// The item's height above the slot floor, mm (its highest profile cell).
    pub fn item_height_mm(&self) -> f32 {
        self.top_mm.iter().copied().fold(0.0, f32::max)
    }

    /// How far above the floor a cell's highest point must stand to count as raised, mm:
    /// a third of the item, at least 4 mm above the floor's noise.
    pub fn raise_mm(&self) -> f32 {
        (0.3 * self.item_height_mm()).max(4.0)
    }

    /// How far a cell's top may differ from an upright item's and still match, mm.
    pub fn match_tolerance_mm(&self) -> f32 {
        (0.15 * self.item_height_mm()).max(4.0)
    }

    /// Checks the grid and every number.
    pub fn validate(&self) -> Result<()> {
        let bad = |msg: String| Err(Error::new(ErrorKind::Model, format!("model: slots: {msg}")));
        if let Some(i) = self.slots.iter().position(|s| !s.iter().all(|v| v.is_finite())) {
            return bad(format!("expected finite slot poses, slot {i} is not"));
        }
        if self.slots.len() > MAX_SLOTS {
            return bad(format!("expected at most {MAX_SLOTS} slots, found {}", self.slots.len()));
        }
        let cells = (self.cols as usize).checked_mul(self.rows as usize);
        if cells.is_none_or(|c| c > MAX_FOOTPRINT_CELLS) {
            return bad(format!(
                "expected at most {MAX_FOOTPRINT_CELLS} footprint cells, found {} x {}",
                self.cols, self.rows
            ));
        }
        // Every frame fills and reads a cell of each slot's footprint: bounded as a whole.
        if cells.and_then(|c| c.checked_mul(self.slots.len())).is_none_or(|n| n > MAX_SLOT_CELLS) {
            return bad(format!(
                "expected at most {MAX_SLOT_CELLS} cells over all slots, found {} slots of {} x {}",
                self.slots.len(),
                self.cols,
                self.rows
            ));
        }
        if self.cols == 0 || self.rows == 0 || cells != Some(self.top_mm.len()) {
            return bad(format!(
                "expected cols x rows ({} x {}) footprint cells, found {} profile values",
                self.cols,
                self.rows,
                self.top_mm.len()
            ));
        }
        if !self.cell_mm.iter().all(|c| c.is_finite() && *c > 0.0)
            || !self.footprint_min_mm.iter().all(|c| c.is_finite())
        {
            return bad(format!(
                "expected a positive cell size and a finite footprint corner, found {:?} and {:?}",
                self.cell_mm, self.footprint_min_mm
            ));
        }
        if let Some(t) = self.top_mm.iter().find(|t| !(t.is_finite() && (**t >= 0.0 || **t == EDGE_CELL))) {
            return bad(format!("expected profile heights >= 0 mm (or {EDGE_CELL} for an edge cell), found {t}"));
        }
        if self.item_height_mm() <= 0.0 {
            return bad("expected an item higher than the slot floor somewhere in the footprint".to_string());
        }
        Ok(())
    }
}

/// What a slot holds, as the measured depth shows it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum SlotState {
    /// Something stands in the slot.
    Filled,
    /// The slot's floor is seen and nothing stands on it.
    Empty,
    /// Too little of the slot was measured to tell (occluded, out of view, in shadow).
    #[default]
    Unseen,
}

impl SlotState {
    /// `filled`, `empty` or `unseen`.
    pub fn as_str(self) -> &'static str {
        match self {
            SlotState::Filled => "filled",
            SlotState::Empty => "empty",
            SlotState::Unseen => "unseen",
        }
    }

    /// The state a name from [`SlotState::as_str`] stands for.
    pub fn from_name(name: &str) -> Option<SlotState> {
        match name {
            "filled" => Some(SlotState::Filled),
            "empty" => Some(SlotState::Empty),
            "unseen" => Some(SlotState::Unseen),
            _ => None,
        }
    }
}

/// One slot as judged in one frame, with the evidence.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SlotReading {
    /// Filled, empty or unseen.
    pub state: SlotState,
    /// Filled with something that is not an upright item (tilted, another size).
    pub askew: bool,
    /// Measured points within the footprint standing above the floor by more than the
    /// layout's raise height.
    pub points_above: u32,
    /// Footprint cells holding at least [`RAISED_CELL_POINTS`] of those points.
    pub raised_cells: u32,
    /// The share of the footprint's cells holding any measured point, in [0, 1].
    pub seen_share: f32,
    /// Of the seen cells an upright item's profile covers evenly, the share whose top
    /// differs from the profile by more than the match tolerance.
    pub mismatch_share: f32,
    /// The slot's frame in the world (slot frame -> world), the tray's pose composed with
    /// the slot's pose in the tray frame: the grasp frame of its item.
    pub t_world_slot: Isometry3<f64>,
}

impl Default for SlotReading {
    fn default() -> Self {
        SlotReading {
            state: SlotState::Unseen,
            askew: false,
            points_above: 0,
            raised_cells: 0,
            seen_share: 0.0,
            mismatch_share: 0.0,
            t_world_slot: Isometry3::identity(),
        }
    }
}

/// Judges every slot of one layout from scene clouds, with its buffers.
#[derive(Debug, Clone)]
pub struct SlotJudge {
    layout: SlotLayout,
    /// Each slot's tray frame -> slot frame.
    t_slot_tray: Vec<Isometry3<f32>>,
    /// The tray-frame box `(min, max)` holding every footprint, for a cheap rejection.
    bounds: ([f32; 2], [f32; 2]),
    /// Per slot and cell, the highest measured point above the floor (NEG_INFINITY: none).
    cell_top: Vec<f32>,
    /// Per slot and cell, the points standing above the raise height (saturating).
    cell_above: Vec<u16>,
    /// Per slot, the points standing above the raise height.
    points_above: Vec<u32>,
    readings: Vec<SlotReading>,
}

impl SlotJudge {
    /// The judge of `layout`, every buffer allocated.
    pub fn new(layout: SlotLayout) -> Result<SlotJudge> {
        layout.validate()?;
        let t_slot_tray: Vec<Isometry3<f32>> =
            (0..layout.slots.len()).filter_map(|n| layout.slot_pose(n)).map(|p| p.inverse().cast::<f32>()).collect();
        let [x0, y0] = layout.footprint_min_mm;
        let (x1, y1) = (x0 + layout.cols as f32 * layout.cell_mm[0], y0 + layout.rows as f32 * layout.cell_mm[1]);
        let mut lo = [f32::INFINITY; 2];
        let mut hi = [f32::NEG_INFINITY; 2];
        for n in 0..layout.slots.len() {
            let pose = layout.slot_pose(n).expect("n < slots").cast::<f32>();
            for (x, y) in [(x0, y0), (x1, y0), (x0, y1), (x1, y1)] {
                let p = pose * Point3::new(x, y, 0.0);
                for a in 0..2 {
                    lo[a] = lo[a].min(p[a]);
                    hi[a] = hi[a].max(p[a]);
                }
            }
        }
        let cells = layout.top_mm.len() * layout.slots.len();
        let slots = layout.slots.len();
        Ok(SlotJudge {
            t_slot_tray,
            bounds: (lo, hi),
            cell_top: vec![f32::NEG_INFINITY; cells],
            cell_above: vec![0; cells],
            points_above: vec![0; slots],
            readings: vec![SlotReading::default(); slots],
            layout,
        })
    }

    /// The layout judged.
    pub fn layout(&self) -> &SlotLayout {
        &self.layout
    }

    /// Judges every slot from `cloud` (world mm, background removed) with the tray at
    /// `t_world_tray`; the readings are [`SlotJudge::readings`] until the next call.
    pub fn judge(&mut self, cloud: &[Point3<f32>], t_world_tray: &Isometry3<f64>) -> &[SlotReading] {
        let l = &self.layout;
        let cells = l.top_mm.len();
        let (cols, rows) = (l.cols as usize, l.rows as usize);
        let [x0, y0] = l.footprint_min_mm;
        let [cx, cy] = l.cell_mm;
        let raise = l.raise_mm();
        // Anything far above the tallest item is not standing in a slot (a gripper, the
        // occluder); a foreign object twice the item's height still counts.
        let ceiling = 2.0 * l.item_height_mm() + 20.0;
        self.cell_top.fill(f32::NEG_INFINITY);
        self.cell_above.fill(0);
        self.points_above.fill(0);
        let t_tray_world = t_world_tray.inverse().cast::<f32>();
        let (lo, hi) = self.bounds;
        for p in cloud {
            let q = t_tray_world * p;
            if q.x < lo[0] || q.x > hi[0] || q.y < lo[1] || q.y > hi[1] {
                continue;
            }
            for (s, t) in self.t_slot_tray.iter().enumerate() {
                let r = t * q;
                let (u, v) = ((r.x - x0) / cx, (r.y - y0) / cy);
                if !(u >= 0.0 && v >= 0.0 && r.z >= -FLOOR_TOLERANCE_MM && r.z <= ceiling) {
                    continue;
                }
                let (i, j) = (u as usize, v as usize);
                if i >= cols || j >= rows {
                    continue;
                }
                let at = s * cells + j * cols + i;
                self.cell_top[at] = self.cell_top[at].max(r.z);
                if r.z > raise {
                    self.cell_above[at] = self.cell_above[at].saturating_add(1);
                    self.points_above[s] += 1;
                }
            }
        }
        let tolerance = l.match_tolerance_mm();
        let expected_raised = l.top_mm.iter().filter(|&&t| t > raise).count() as f32;
        for (s, reading) in self.readings.iter_mut().enumerate() {
            let tops = &self.cell_top[s * cells..(s + 1) * cells];
            let above = &self.cell_above[s * cells..(s + 1) * cells];
            let (mut seen, mut raised, mut compared, mut mismatched) = (0u32, 0u32, 0u32, 0u32);
            for ((&top, &want), &above) in tops.iter().zip(&l.top_mm).zip(above) {
                if top == f32::NEG_INFINITY {
                    continue;
                }
                seen += 1;
                raised += u32::from(above >= RAISED_CELL_POINTS);
                if want != EDGE_CELL {
                    compared += 1;
                    mismatched += u32::from((top - want).abs() > tolerance);
                }
            }
            let seen_share = seen as f32 / cells as f32;
            // A few raised cells are a stray streak of the stereo matcher at a neighbour's
            // edge (its single points raise none); an item, or a foreign object a tenth of
            // the footprint, raises more.
            let filled = raised >= 3 && raised as f32 >= 0.1 * expected_raised;
            let mismatch_share = if compared > 0 { mismatched as f32 / compared as f32 } else { 0.0 };
            let state = if filled {
                SlotState::Filled
            } else if seen_share >= MIN_SEEN_SHARE {
                SlotState::Empty
            } else {
                SlotState::Unseen
            };
            let pose = l.slot_pose(s).expect("s < slots");
            *reading = SlotReading {
                state,
                askew: filled && compared >= 4 && mismatch_share > MAX_MISMATCH_SHARE,
                points_above: self.points_above[s],
                raised_cells: raised,
                seen_share,
                mismatch_share,
                t_world_slot: t_world_tray * pose,
            };
        }
        &self.readings
    }

    /// The last [`SlotJudge::judge`]'s readings, one per slot.
    pub fn readings(&self) -> &[SlotReading] {
        &self.readings
    }
}

/// The `slots=` text of a serve reply and a record: per slot `F` (filled), `A` (filled,
/// askew), `E` (empty) or `?` (unseen), into `out` (cleared first).
pub fn slot_letters(readings: &[SlotReading], out: &mut String) {
    out.clear();
    out.extend(readings.iter().map(|r| match (r.state, r.askew) {
        (SlotState::Filled, false) => 'F',
        (SlotState::Filled, true) => 'A',
        (SlotState::Empty, _) => 'E',
        (SlotState::Unseen, _) => '?',
    }));
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// Two slots 50 mm apart, the second turned 90°, holding a 34 x 34 x 30 mm box.
    fn layout() -> SlotLayout {
        SlotLayout {
            slots: vec![[-25.0, 0.0, 5.0, 0.0], [25.0, 0.0, 5.0, 90.0]],
            footprint_min_mm: [-15.0, -15.0],
            cell_mm: [3.75, 3.75],
            cols: 8,
            rows: 8,
            top_mm: vec![30.0; 64],
        }
    }

    #[test]
    fn layouts_past_the_bounds_are_refused_before_their_cells_are_made() {
        assert!(layout().validate().is_ok());
        // 4096 slots of 256 x 256 cells: a 400 KB file that would ask for 1 GiB of cells.
        let many = SlotLayout { slots: vec![[0.0, 0.0, 5.0, 0.0]; MAX_SLOTS], cols: 256, rows: 256, ..layout() };
        assert!(many.validate().unwrap_err().to_string().contains("over all slots"), "{:?}", many.validate());
        let wide = SlotLayout { cols: 1 << 9, rows: 1 << 8, ..layout() };
        assert!(wide.validate().unwrap_err().to_string().contains("footprint cells"));
        let crowded = SlotLayout { slots: vec![[0.0, 0.0, 5.0, 0.0]; MAX_SLOTS + 1], ..layout() };
        assert!(crowded.validate().unwrap_err().to_string().contains("slots"));
        let overflow = SlotLayout { cols: u32::MAX, rows: u32::MAX, ..layout() };
        assert!(overflow.validate().is_err());
    }

    /// A surface's height above a slot's floor at slot-frame (x, y); `None` where unseen.
    type Height<'a> = dyn Fn(f64, f64) -> Option<f64> + 'a;

    /// Points every 2 mm over slot `n`'s footprint at `height(x, y)` above its floor (slot
    /// frame), posed into the world by `tray`.
    fn surface(
        l: &SlotLayout,
        n: usize,
        tray: &Isometry3<f64>,
        height: impl Fn(f64, f64) -> Option<f64>,
        rng: &mut ChaCha8Rng,
        out: &mut Vec<Point3<f32>>,
    ) {
        let slot = tray * l.slot_pose(n).unwrap();
        for i in 0..20 {
            for j in 0..20 {
                let (x, y) = (-19.0 + 2.0 * i as f64, -19.0 + 2.0 * j as f64);
                if let Some(z) = height(x, y) {
                    let p = slot * nalgebra::Point3::new(x, y, z + rng.random_range(-0.5..0.5));
                    out.push(p.cast::<f32>());
                }
            }
        }
    }

    /// Filled, empty, unseen, tilted and foreign slots built from their geometry are told
    /// apart, at a random tray pose, and the grasp frame is the tray's pose composed with
    /// the slot's.
    #[test]
    fn states_follow_the_geometry() {
        let l = layout();
        let mut judge = SlotJudge::new(l.clone()).unwrap();
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let inside = |x: f64, y: f64| x.abs() <= 17.0 && y.abs() <= 17.0;
        for _ in 0..50 {
            let tray = Isometry3::new(
                Vector3::new(rng.random_range(-200.0..200.0), rng.random_range(-200.0..200.0), 0.0),
                Vector3::z() * rng.random_range(-3.2..3.2),
            );
            let cases: [(&Height<'_>, SlotState, bool); 6] = [
                (&|x, y| Some(if inside(x, y) { 30.0 } else { 0.0 }), SlotState::Filled, false),
                (&|_, _| Some(0.0), SlotState::Empty, false),
                (&|x, _| (x < -12.0).then_some(0.0), SlotState::Unseen, false),
                // Tilted 20° about the slot's y axis, one edge on the floor.
                (
                    &|x, y| Some(if inside(x, y) { 30.0 + (x + 17.0) * 20f64.to_radians().tan() } else { 0.0 }),
                    SlotState::Filled,
                    true,
                ),
                // A 20 x 20 x 12 mm box.
                (&|x, y| Some(if x.abs() <= 10.0 && y.abs() <= 10.0 { 12.0 } else { 0.0 }), SlotState::Filled, true),
                // Half the footprint occluded, an item in the other half.
                (&|x, y| (x > 0.0).then_some(if inside(x, y) { 30.0 } else { 0.0 }), SlotState::Filled, false),
            ];
            for (height, state, askew) in cases {
                let mut cloud = Vec::new();
                surface(&l, 0, &tray, height, &mut rng, &mut cloud);
                surface(&l, 1, &tray, |_, _| Some(0.0), &mut rng, &mut cloud);
                let r = judge.judge(&cloud, &tray);
                assert_eq!((r[0].state, r[0].askew), (state, askew), "{:?}", r[0]);
                assert_eq!((r[1].state, r[1].askew), (SlotState::Empty, false), "{:?}", r[1]);
                let want = tray * l.slot_pose(0).unwrap();
                assert!((r[0].t_world_slot.to_homogeneous() - want.to_homogeneous()).amax() < 1e-12);
            }
        }
    }

    /// Single raised points in many cells of an empty slot (the stereo matcher's strays
    /// beside a neighbour's edge) leave it empty; two in each of the same cells fill it.
    #[test]
    fn single_stray_points_raise_no_cell() {
        let l = layout();
        let mut judge = SlotJudge::new(l.clone()).unwrap();
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let tray = Isometry3::new(Vector3::new(40.0, -30.0, 0.0), Vector3::z() * 0.7);
        let slot = tray * l.slot_pose(0).unwrap();
        for per_cell in [1, 2] {
            let mut cloud = Vec::new();
            surface(&l, 0, &tray, |_, _| Some(0.0), &mut rng, &mut cloud);
            surface(&l, 1, &tray, |_, _| Some(0.0), &mut rng, &mut cloud);
            // Half the footprint's cells (32 of 64), each with its stray points near the centre.
            for k in 0..32 {
                let (i, j) = (k % 8, k / 8);
                for n in 0..per_cell {
                    let x = l.footprint_min_mm[0] as f64 + (i as f64 + 0.4 + 0.2 * n as f64) * 3.75;
                    let y = l.footprint_min_mm[1] as f64 + (j as f64 + 0.5) * 3.75;
                    cloud.push((slot * nalgebra::Point3::new(x, y, 25.0)).cast::<f32>());
                }
            }
            let r = judge.judge(&cloud, &tray);
            assert_eq!(r[0].points_above, 32 * per_cell);
            let (state, raised) = if per_cell == 1 { (SlotState::Empty, 0) } else { (SlotState::Filled, 32) };
            assert_eq!((r[0].state, r[0].raised_cells), (state, raised), "{per_cell} a cell: {:?}", r[0]);
        }
    }

    #[test]
    fn letters_name_each_state() {
        let mut r = [SlotReading::default(); 4];
        r[0].state = SlotState::Filled;
        r[1] = SlotReading { state: SlotState::Filled, askew: true, ..r[1] };
        r[2].state = SlotState::Empty;
        let mut s = String::new();
        slot_letters(&r, &mut s);
        assert_eq!(s, "FAE?");
        for state in [SlotState::Filled, SlotState::Empty, SlotState::Unseen] {
            assert_eq!(SlotState::from_name(state.as_str()), Some(state));
        }
    }

    #[test]
    fn a_bad_layout_is_refused_by_name() {
        let l = SlotLayout { top_mm: vec![30.0; 63], ..layout() };
        assert!(SlotJudge::new(l).unwrap_err().to_string().contains("8 x 8"));
        let l = SlotLayout { top_mm: vec![0.0; 64], ..layout() };
        assert!(SlotJudge::new(l).unwrap_err().to_string().contains("item higher"));
        let l = SlotLayout { cell_mm: [0.0, 1.0], ..layout() };
        assert!(SlotJudge::new(l).is_err());
    }
}
