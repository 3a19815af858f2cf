//! The simulation's optics against their analytic forms: the thin lens's circle of
//! confusion (camera and projector), the law of reflection for a glossy highlight, and the
//! new effects' determinism across thread counts.

use camplace_config::{Cell, Focus, GrayImage, Placement, Vergence};
use nalgebra::{Isometry3, Point3};

use super::{Frame, Method, Simulator};
use crate::scene::{OccluderBox, SceneSpec};

/// A flat scene: the table alone (or with a thin box lying on it), lit as given.
fn flat(ambient: f64, lamp_strength: f64, lamp_position: Point3<f64>, occluder: Option<OccluderBox>) -> SceneSpec {
    SceneSpec {
        t_world_tray: Isometry3::identity(),
        filled: Vec::new(),
        table: true,
        tray: false,
        ambient,
        lamp_strength,
        lamp_position,
        occluder,
    }
}

/// The rig straight above the table at distance `r`, cameras parallel (so the table is
/// square to the left camera's axis, at depth `r`).
fn above(r: f64) -> Placement {
    Placement { r, alpha: 0.0, baseline: 60.0, vergence: Vergence::Degrees(0.0), azimuth: 0.0 }
}

/// The spread of a straight step edge through the image's centre (within the projector's
/// light): 4 times the standard deviation of the line spread function, the derivative of
/// the grey level across the edge averaged over 200 lines (which averages out the 8-bit
/// rounding), taken within `reach` pixels of the edge; a disc of diameter c gives c. The
/// edge may run along the rows or the columns.
fn edge_width(image: &GrayImage, reach: usize) -> f64 {
    let (w, h) = (image.width, image.height);
    let mean_line = |lines: &mut dyn Iterator<Item = Vec<f64>>| {
        let all: Vec<Vec<f64>> = lines.collect();
        let n = all.len() as f64;
        (0..all[0].len()).map(|i| all.iter().map(|l| l[i]).sum::<f64>() / n).collect::<Vec<f64>>()
    };
    let across_rows = mean_line(
        &mut (w / 2 - 100..w / 2 + 100).map(|x| (h / 2 - 150..h / 2 + 150).map(|y| image.get(x, y) as f64).collect()),
    );
    let across_columns = mean_line(
        &mut (h / 2 - 100..h / 2 + 100).map(|y| (w / 2 - 200..w / 2 + 200).map(|x| image.get(x, y) as f64).collect()),
    );
    let rise = |l: &[f64]| (l[l.len() - 1] - l[0]).abs();
    let line = if rise(&across_rows) > rise(&across_columns) { across_rows } else { across_columns };
    let d: Vec<f64> = line.windows(2).map(|p| p[1] - p[0]).collect();
    let peak = (0..d.len()).max_by(|&a, &b| d[a].abs().total_cmp(&d[b].abs())).unwrap();
    let window = peak.saturating_sub(reach)..(peak + reach + 1).min(d.len());
    let total: f64 = d[window.clone()].iter().sum();
    assert!(total.abs() > 50.0, "no edge across the image's centre");
    let mean = window.clone().map(|i| i as f64 * d[i]).sum::<f64>() / total;
    let var = window.map(|i| (i as f64 - mean).powi(2) * d[i]).sum::<f64>() / total;
    4.0 * var.sqrt()
}

/// The thin lens's circle of confusion, pixels, written out: aperture f/N, sensor pixels of
/// f / fx mm, a point at z seen with the focus at s.
fn circle(focal: f64, f_number: f64, fx: f64, s: f64, z: f64) -> f64 {
    let image_distance = |d: f64| 1.0 / (1.0 / focal - 1.0 / d);
    let (vs, vz) = (image_distance(s), image_distance(z));
    (focal / f_number) * (vz - vs).abs() / vz * fx / focal
}

#[test]
fn a_step_edge_is_blurred_by_the_cameras_circle_of_confusion() {
    let mut cell = Cell::default();
    cell.optics.camera_f_number = 1.0;
    cell.optics.camera_focus = Focus::Distance(600.0);
    // The projector is off: the edge is an albedo step lit by ambient light alone.
    cell.sensor.projector_gain = 0.0;
    cell.table.albedo = 0.1;
    cell.occluder.albedo = 0.9;
    // A box 0.01 mm thin lying on one half of the table: a step at one depth.
    let half = Some(OccluderBox { min: [0.0, -500.0, 0.0], max: [500.0, 500.0, 0.01] });
    for r in [350.0, 450.0, 1000.0] {
        let mut sim = Simulator::new(&cell, &above(r), 1).unwrap();
        let mut frame = Frame::default();
        sim.render_clean(&flat(1.0, 0.0, Point3::new(0.0, 0.0, 1500.0), half), Method::OneShot, &mut frame);
        let fx = sim.rig().left.k[(0, 0)];
        let want = circle(cell.optics.camera_focal_length, 1.0, fx, 600.0, r);
        let got = edge_width(&frame.shots.left[0], want.ceil() as usize + 4);
        eprintln!("camera, r {r}: edge {got:.2} px, circle of confusion {want:.2} px");
        assert!((got / want - 1.0).abs() < 0.1, "r {r}: edge {got:.2} px, circle of confusion {want:.2} px");
    }
}

#[test]
fn a_projected_step_is_blurred_by_the_projectors_circle_of_confusion() {
    let mut cell = Cell::default();
    // The cameras' blur made negligible (a pinhole), the projector's large.
    cell.optics.camera_f_number = 64.0;
    cell.optics.projector_f_number = 1.0;
    cell.optics.projector_focus = Focus::Distance(600.0);
    cell.sensor.projector_gain = 1.0;
    cell.table.albedo = 0.8;
    cell.effects.specular = false;
    for r in [350.0, 450.0, 1000.0] {
        let mut sim = Simulator::new(&cell, &above(r), 1).unwrap();
        let [pw, ph] = cell.sensor.projector_resolution.map(|v| v as usize);
        // Dark in the top half of the projector's image, bright in the bottom half.
        let mut step = GrayImage::new(pw, ph, 0);
        for y in ph / 2..ph {
            step.row_mut(y).fill(255);
        }
        sim.set_one_shot_pattern(step);
        let mut frame = Frame::default();
        sim.render_clean(&flat(0.0, 0.0, Point3::new(0.0, 0.0, 1500.0), None), Method::OneShot, &mut frame);
        let (projector, camera) = sim.thin_lenses();
        let (projector, camera) = (projector.unwrap(), camera.unwrap());
        let fx_p = sim.rig().projector.as_ref().unwrap().k[(0, 0)];
        let fx_c = sim.rig().left.k[(0, 0)];
        // The projector's circle in its own pixels, seen in camera pixels (both at depth r).
        let c_p = circle(cell.optics.projector_focal_length, 1.0, fx_p, 600.0, r);
        assert!((projector.circle_px(r) / c_p - 1.0).abs() < 1e-9);
        // Beside the defocus, the pattern's box filter over the camera's footprint (b = 2:
        // variance (b² - 1) / 12) and the bilinear reading (1 / 6) spread it, as does the
        // camera's near-pinhole lens.
        let var_p = (c_p / 4.0).powi(2) + 0.25 + 1.0 / 6.0;
        let want = 4.0 * (var_p * (fx_c / fx_p).powi(2) + (camera.circle_px(r) / 4.0).powi(2)).sqrt();
        let img = &frame.shots.left[0];
        let got = edge_width(img, want.ceil() as usize + 4);
        assert!(c_p * fx_c / fx_p > 1.5, "r {r}: the blur is too small to test");
        eprintln!("projector, r {r}: edge {got:.2} px, expected {want:.2} px");
        assert!((got / want - 1.0).abs() < 0.1, "r {r}: edge {got:.2} px, expected {want:.2} px");
    }
}

#[test]
fn a_glossy_highlight_lands_where_the_law_of_reflection_puts_it_and_saturates() {
    let mut cell = Cell::default();
    cell.sensor.projector_gain = 0.0;
    cell.effects.defocus = false;
    cell.table.albedo = 0.2;
    cell.table.specular = 0.2;
    cell.table.roughness = 0.05;
    let placement = above(600.0);
    for lamp in [Point3::new(150.0, 100.0, 900.0), Point3::new(-200.0, 40.0, 700.0), Point3::new(60.0, -120.0, 1200.0)]
    {
        let scene = flat(0.1, 1.0, lamp, None);
        let mut sim = Simulator::new(&cell, &placement, 1).unwrap();
        let mut frame = Frame::default();
        sim.render_clean(&scene, Method::OneShot, &mut frame);
        let cam = sim.rig().left.clone();
        // The mirror point: where the line from the camera to the lamp's mirror image below
        // the table meets the table.
        let c = cam.centre();
        let t = c.z / (c.z + lamp.z);
        let m = c + (Point3::new(lamp.x, lamp.y, -lamp.z) - c) * t;
        let want = cam.project(&m).unwrap();
        let img = &frame.shots.left[0];
        let (mut n, mut sx, mut sy) = (0.0, 0.0, 0.0);
        for y in 0..img.height {
            for x in 0..img.width {
                if img.get(x, y) == 255 {
                    n += 1.0;
                    sx += x as f64;
                    sy += y as f64;
                }
            }
        }
        assert!(n >= 5.0, "lamp at {lamp}: the highlight does not saturate");
        let got = nalgebra::Point2::new(sx / n, sy / n);
        eprintln!("lamp at {lamp}: highlight at {got} ({n} px saturated), mirror point at {want}");
        assert!((got - want).norm() < 1.0, "lamp at {lamp}: highlight at {got}, mirror point at {want}");
        // Matte, the same scene has no saturated pixel.
        let mut matte = cell.clone();
        matte.effects.specular = false;
        let mut sim = Simulator::new(&matte, &placement, 1).unwrap();
        sim.render_clean(&scene, Method::OneShot, &mut frame);
        assert!(frame.shots.left[0].data.iter().all(|&g| g < 255));
    }
}

#[test]
fn realism_renders_the_same_whatever_the_thread_count() {
    let mut cell = Cell::default();
    cell.occluder.probability = 1.0;
    let scenario = crate::scene::scenario::draw_scenario(&cell, 5, 2);
    assert!(scenario.occluder.is_some());
    let render = |threads: usize, method: Method| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| {
            let mut sim = Simulator::new(&cell, &cell.placement, 3).unwrap();
            let mut frame = Frame::default();
            sim.render(&scenario.scene(), method, 9, &mut frame);
            frame
        })
    };
    for method in [Method::OneShot, Method::Phase12] {
        let one = render(1, method);
        assert_eq!(one, render(2, method));
        assert_eq!(one, render(3, method));
        // The occluder is in the picture.
        assert!(one.ids_left.data.contains(&crate::scene::ID_OCCLUDER));
    }
}
