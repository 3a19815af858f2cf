//! Where the one-shot matcher computes depth: the box of the rectified left image that
//! differs from the background capture. On rendered scenes it must hold every pixel where
//! the truth sees the tray or an item (the ids the renderer writes), on built-in and mesh
//! trays, near and far placements, with an occluder over the tray in half the scenes; and
//! it must be smaller than the image, or it saves nothing.

use camplace_config::Cell;
use camplace_estimator::{depth::Method, depth::Reconstruction, depth::Reconstructor, EstimatorConfig};
use camplace_sim::{background_scene, draw_scenario, noise_key, Frame, Simulator};

use crate::meshes::tray_stl;

/// Ids the renderer gives the tray and the items (the table is 0, the occluder 255).
fn tray_or_item(id: u8) -> bool {
    id != 0 && id != 255
}

/// Renders scenarios `0..n` of `cell` at `placement`, one shot, and checks each frame's
/// region; returns the regions' mean share of the image.
fn regions_hold_the_tray(cell: &Cell, placement: &str, n: u64) -> f64 {
    let p = cell.placement.with_overrides(placement).unwrap();
    let seed = 3;
    let mut sim = Simulator::new(cell, &p, seed).unwrap();
    let rig = sim.rig().clone();
    let mut rec = Reconstructor::new(&EstimatorConfig::from(cell), &rig, Method::OneShot).unwrap();
    let mut frame = Frame::default();
    sim.render(&background_scene(cell, seed), Method::OneShot, noise_key(seed, 0, true), &mut frame);
    rec.set_background(&frame.shots.left, &frame.shots.right).unwrap();
    let mut out = Reconstruction::default();
    let mut share = 0.0;
    for i in 0..n {
        let scenario = draw_scenario(cell, seed, i);
        sim.render(&scenario.scene(), Method::OneShot, noise_key(seed, i, false), &mut frame);
        rec.process(&frame.shots.left, &frame.shots.right, &mut out).unwrap();
        let region = rec.last_region();
        let rect = rec.rectification();
        let (w, h) = (rect.camera.width, rect.camera.height);
        let mut seen = 0;
        for y in 0..h {
            for x in 0..w {
                let Some((u, v)) = rect.rectified_to_raw(true, x as f64, y as f64) else { continue };
                let (u, v) = (u.round(), v.round());
                if u < 0.0 || v < 0.0 || u >= rig.left.width as f64 || v >= rig.left.height as f64 {
                    continue;
                }
                if tray_or_item(frame.ids_left.get(u as usize, v as usize)) {
                    seen += 1;
                    assert!(
                        region.contains(x, y),
                        "{placement}, scenario {i}: tray pixel ({x}, {y}) outside the region {region:?}"
                    );
                }
            }
        }
        assert!(seen > 1000, "{placement}, scenario {i}: only {seen} tray pixels in view");
        share += region.area() as f64 / (w * h) as f64;
    }
    share / n as f64
}

#[test]
fn the_region_holds_the_tray_at_near_and_far_placements() {
    let cell = Cell::default();
    for (placement, at_most) in
        [("r=605,alpha=32", 0.45), ("r=450,alpha=10,baseline=120", 0.6), ("r=1000,alpha=60", 0.3)]
    {
        let share = regions_hold_the_tray(&cell, placement, 8);
        eprintln!("{placement}: the region is {:.1} % of the image on average", 100.0 * share);
        assert!(share < at_most, "{placement}: the region is {:.1} % of the image", 100.0 * share);
    }
}

#[test]
fn the_region_holds_a_mesh_tray_and_its_items_under_an_occluder() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("own.stl"), tray_stl(200.0, 140.0, 6.0, 8.0, 28.0)).unwrap();
    let text = "[tray]\nkind = \"mesh\"\nmesh = \"own.stl\"\n\
                slots = [[-45.0, -30.0, 6.0, 0.0], [45.0, -30.0, 6.0, 0.0], [-45.0, 30.0, 6.0, 0.0], [45.0, 30.0, 6.0, 0.0]]\n\
                [occluder]\nprobability = 0.5\n";
    let cell = Cell::from_toml_str(text, dir.path()).unwrap();
    let share = regions_hold_the_tray(&cell, "r=605,alpha=32", 8);
    eprintln!("mesh tray with an occluder: the region is {:.1} % of the image on average", 100.0 * share);
    assert!(share < 0.6, "the region is {:.1} % of the image", 100.0 * share);
}
