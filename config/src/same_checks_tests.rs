//! A value refused in one file is refused in every other file that can carry it: the
//! cell's `[sensor]` against `rig.json` (on its own and as the cell's `rig`), the cell's
//! `[tray]` and `[items]` against each `[[trays]]` entry. Seeded random values, valid and
//! not, each judged in every place; the verdicts must agree.

use crate::test_draw::Draw;
use crate::{Cell, RigFile, TrayEntry};

/// Draws beyond the shared stream's.
trait Wild {
    fn wild(&mut self) -> f64;
}

impl Wild for Draw {
    /// A number of any sign and scale, now and then not finite.
    fn wild(&mut self) -> f64 {
        match self.next() % 16 {
            0 => f64::NAN,
            1 => f64::INFINITY,
            2 => -f64::INFINITY,
            3 => 0.0,
            _ => {
                let sign = if self.next().is_multiple_of(2) { 1.0 } else { -1.0 };
                sign * 10f64.powf(self.uniform(-6.0, 6.0))
            }
        }
    }
}

/// A rig matching the default cell's cameras: 640 x 480, looking down from 600 mm.
fn rig(fx: f64, fy: f64, (w, h): (u32, u32), dist: [f64; 5]) -> RigFile {
    let mut left = crate::CameraFile {
        width: w,
        height: h,
        k: [[fx, 0.0, f64::from(w) / 2.0], [0.0, fy, f64::from(h) / 2.0], [0.0, 0.0, 1.0]],
        dist,
        t_world_camera: [[1.0, 0.0, 0.0, -40.0], [0.0, -1.0, 0.0, 0.0], [0.0, 0.0, -1.0, 600.0], [0.0, 0.0, 0.0, 1.0]],
    };
    let mut right = left.clone();
    right.t_world_camera[0][3] = 40.0;
    left.dist = dist;
    RigFile { left, right, projector: None, rectified: None }
}

/// The verdicts on one set of camera values: in the cell's `[sensor]`, in `rig.json`, and
/// in the cell's `[rig]`.
fn camera_verdicts(fx: f64, fy: f64, size: (u32, u32), dist: [f64; 5]) -> [bool; 3] {
    let mut cell = Cell::default();
    cell.sensor.camera_resolution = [size.0, size.1];
    cell.sensor.camera_k =
        vec![[fx, 0.0, f64::from(size.0) / 2.0], [0.0, fy, f64::from(size.1) / 2.0], [0.0, 0.0, 1.0]];
    cell.sensor.camera_dist = dist;
    let in_sensor = cell.validate().is_ok();
    let file = rig(fx, fy, size, dist);
    let in_rig = RigFile::from_json(&file.to_json()).is_ok();
    let with_rig = Cell { rig: Some(file), ..Cell::default() };
    [in_sensor, in_rig, with_rig.validate().is_ok()]
}

#[test]
fn a_camera_value_refused_in_the_cell_is_refused_in_rig_json_and_the_other_way_round() {
    let mut d = Draw::new(40);
    let (mut refused, mut accepted) = (0, 0);
    for case in 0..600 {
        let (mut fx, mut size, mut dist) = (800.0, (640u32, 480u32), [0.0; 5]);
        match case % 3 {
            0 => fx = if d.next().is_multiple_of(2) { d.wild() } else { d.uniform(1.0, 40_000.0) },
            1 => {
                let side = |d: &mut Draw| match d.next() % 3 {
                    0 => d.next() as u32 % 20,
                    1 => 16 + d.next() as u32 % 9000,
                    _ => 8000 + d.next() as u32 % 400,
                };
                size = (side(&mut d), side(&mut d));
                // A lens of about 50 degrees over any width, so the size alone decides.
                fx = f64::from(size.0.max(1));
            }
            _ => {
                // Radial terms of any lens and past it; tangential ones as real lenses have
                // them (a p1 of 1 folds any image, which would leave few lenses accepted).
                for (i, v) in dist.iter_mut().enumerate() {
                    let span = if i == 2 || i == 3 { 0.01 } else { 1.5 };
                    *v = if d.next().is_multiple_of(8) { d.wild() } else { d.uniform(-span, span) };
                }
            }
        }
        let v = camera_verdicts(fx, fx, size, dist);
        assert!(v.iter().all(|&ok| ok == v[0]), "fx {fx}, size {size:?}, dist {dist:?}: sensor, rig.json, [rig] {v:?}");
        if v[0] {
            accepted += 1;
        } else {
            refused += 1;
        }
    }
    // Both sides of every check were reached.
    assert!(refused > 100 && accepted > 100, "refused {refused}, accepted {accepted}");
}

#[test]
fn a_tray_or_items_value_refused_in_the_cell_is_refused_in_each_listed_tray() {
    let mut d = Draw::new(41);
    let (mut refused, mut accepted) = (0, 0);
    for case in 0..400 {
        let mut one = Cell::default();
        let value = if d.next().is_multiple_of(2) { d.wild() } else { d.uniform(-0.5, 1.5) };
        match case % 6 {
            0 => one.tray.albedo = value,
            1 => one.tray.specular = value,
            2 => one.tray.roughness = value,
            3 => one.items.albedo = value,
            4 => one.items.specular = value,
            _ => one.items.roughness = value,
        }
        let in_cell = one.validate().is_ok();
        // The same tray and items as the second of two listed trays.
        let mut listed = Cell::default();
        let plain = TrayEntry { name: "plain".into(), tray: Cell::default().tray, items: Cell::default().items };
        let entry = TrayEntry { name: "other".into(), tray: one.tray.clone(), items: one.items.clone() };
        listed.trays = vec![plain, entry];
        let in_list = listed.validate();
        assert_eq!(
            in_cell,
            in_list.is_ok(),
            "case {case}, value {value}: [tray]/[items] {in_cell}, [[trays]] {in_list:?}"
        );
        if let Err(e) = in_list {
            assert!(e.key().starts_with("trays[1]"), "the entry is named: {e}");
            refused += 1;
        } else {
            accepted += 1;
        }
    }
    assert!(refused > 50 && accepted > 50, "refused {refused}, accepted {accepted}");
}
