//! The physical checks of a camera or projector, one function per quantity, used wherever
//! that quantity can come from: the cell's `[sensor]` and `rig.json` (on its own or as a
//! cell's `rig`). An image size whose buffers would pass the memory budget, a focal length
//! no lens has, a distortion that folds back over the image, a centre out of the cell's
//! reach or below the table are refused naming the key, not met later as a symptom.

use crate::{Error, MAX_DISTANCE_MM};

/// The smallest and largest image side, pixels.
pub const MIN_IMAGE_SIDE: u32 = 16;

/// The largest image side, pixels, of a camera or projector.
pub const MAX_IMAGE_SIDE: u32 = 8192;

/// What a run may hold in memory, bytes: the study, the model build and the deployed loop
/// size their buffers from the cameras' and projector's images, and a size whose estimate
/// passes this is refused before anything is allocated. 16 GiB lets 12-megapixel cameras
/// through (4096 x 3072: 15 GB by the estimate) and refuses 8192 x 8192 (80 GB).
pub const MEMORY_BUDGET_BYTES: u64 = 16 << 30;

/// What one camera pixel costs a run, bytes: the rendered shots and their terms, the
/// rectified canvas, the stereo descriptors, costs and disparities, the depth map and the
/// cloud. Measured with `evaluate --method phase-12` (the dearer method) on two workers:
/// peak resident memory 458 MB at 640 x 480 and 1231 MB at 1280 x 960, 840 bytes a pixel
/// more; rounded up for a third worker's share.
pub const BYTES_PER_CAMERA_PIXEL: u64 = 1200;

/// What one projector pixel costs a run, bytes: an estimate from the buffers it feeds (the
/// pattern images and their blur levels at float precision), not a measurement.
pub const BYTES_PER_PROJECTOR_PIXEL: u64 = 200;

/// The narrowest and widest horizontal field of view a lens may give, degrees.
pub const FIELD_OF_VIEW_DEG: (f64, f64) = (1.0, 170.0);

/// Checks an image size: `width` and `height` from [`MIN_IMAGE_SIDE`] to [`MAX_IMAGE_SIDE`],
/// and `count` images of it at `bytes_per_pixel` within [`MEMORY_BUDGET_BYTES`].
pub fn check_image_size(key: &str, width: u32, height: u32, bytes_per_pixel: u64, count: u64) -> Result<(), Error> {
    let sides = MIN_IMAGE_SIDE..=MAX_IMAGE_SIDE;
    if !(sides.contains(&width) && sides.contains(&height)) {
        return Err(Error::value(
            key,
            format!("expected [width, height] from {MIN_IMAGE_SIDE} to {MAX_IMAGE_SIDE} pixels a side, got {width} x {height}"),
        ));
    }
    let estimate = u64::from(width) * u64::from(height) * bytes_per_pixel * count;
    if estimate > MEMORY_BUDGET_BYTES {
        return Err(Error::value(
            key,
            format!(
                "{width} x {height} pixels would need about {:.1} GB of buffers ({bytes_per_pixel} bytes a pixel{}), past the memory budget of {:.1} GB; use a smaller image",
                estimate as f64 / 1e9,
                if count > 1 { format!(", {count} images") } else { String::new() },
                MEMORY_BUDGET_BYTES as f64 / 1e9
            ),
        ));
    }
    Ok(())
}

/// Checks a focal length in pixels (`name` is `fx` or `fy`) over an image side of `side_px`:
/// finite, and giving a field of view within [`FIELD_OF_VIEW_DEG`].
pub fn check_focal_px(key: &str, name: &str, focal_px: f64, side_px: u32) -> Result<(), Error> {
    let side = f64::from(side_px);
    let (lo, hi) = FIELD_OF_VIEW_DEG;
    // The focal lengths that give the widest and the narrowest view across the side.
    let shortest = (side / 2.0) / (hi.to_radians() / 2.0).tan();
    let longest = (side / 2.0) / (lo.to_radians() / 2.0).tan();
    if !(focal_px.is_finite() && (shortest..=longest).contains(&focal_px)) {
        return Err(Error::value(
            key,
            format!(
                "{name} = {focal_px:?} px: expected a focal length giving a field of view of {lo} to {hi} degrees across {side_px} px ({shortest:.1} to {longest:.0} px)"
            ),
        ));
    }
    Ok(())
}

/// The largest size of a distortion coefficient: real lenses stay well below it.
pub const MAX_DISTORTION_COEFFICIENT: f64 = 10.0;

/// How far past the image's farthest corner a distortion must stay one-to-one, as a fraction
/// of the principal point's distance to that corner: a corner pixel's ray is then on the
/// lens model's rising branch with a little room for the corner's sub-pixel neighbours.
pub const DISTORTION_MARGIN: f64 = 1.05;

/// Where a distortion first folds back: how far out, as a fraction of the principal point's
/// distance to the image's farthest corner (normalised coordinates, distorted side), and the
/// image corner nearest the ray it folds on.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DistortionFold {
    /// The distorted radius at the fold over the farthest corner's; below 1 the fold is in
    /// the image.
    pub fraction_of_corner: f64,
    /// `top-left`, `top-right`, `bottom-left` or `bottom-right`.
    pub corner: &'static str,
}

/// The rays' directions searched for a fold: one every 2 degrees (tangential terms make the
/// fold depend on the direction, and they are small beside the radial ones).
const FOLD_RAYS: usize = 180;

/// Steps along each ray per farthest-corner radius: a fold's position is found within 0.5 %.
const FOLD_STEPS_PER_CORNER: f64 = 200.0;

/// Where the distortion `[k1, k2, p1, p2, k3]` of a camera with intrinsics `k` over a
/// `width` x `height` image first folds back, looking out to `horizon` times the principal
/// point's distance to the farthest image corner; `None` when it does not fold that far.
///
/// Along every ray out of the principal point the undistorted radius grows in small steps;
/// the map folds where its Jacobian determinant falls to 5 % of the radial factor (for a
/// purely radial lens, where d/dr of r (1 + k1 r² + k2 r⁴ + k3 r⁶) falls to 0.05), and a ray
/// is done once its distorted point is `horizon` corner radii out. Judging the distorted
/// side is what matters: a barrel lens's corner pixel comes from a ray farther out than the
/// corner's own radius, a pincushion's from one nearer in.
pub fn distortion_fold(
    dist: &[f64; 5],
    width: u32,
    height: u32,
    k: &[[f64; 3]; 3],
    horizon: f64,
) -> Option<DistortionFold> {
    let (fx, fy, cx, cy) = (k[0][0], k[1][1], k[0][2], k[1][2]);
    let (w, h) = (f64::from(width), f64::from(height));
    let (mut corner_radius, mut corner_theta) = (0.0f64, 0.0f64);
    for (u, v) in [(0.0, 0.0), (w, 0.0), (0.0, h), (w, h)] {
        let (x, y) = ((u - cx) / fx, (v - cy) / fy);
        if x.hypot(y) > corner_radius {
            (corner_radius, corner_theta) = (x.hypot(y), y.atan2(x));
        }
    }
    if !(corner_radius.is_finite() && corner_radius > 0.0) {
        return None;
    }
    let [k1, k2, p1, p2, k3] = *dist;
    let limit = horizon * corner_radius;
    let step = corner_radius / FOLD_STEPS_PER_CORNER;
    // A ray whose slope stays above the threshold gains 0.05 step a step at least, so it
    // passes the limit within this many steps; the bound only guards the loop.
    let max_steps = (horizon * FOLD_STEPS_PER_CORNER / 0.05).ceil() as usize + 1;
    let mut first: Option<DistortionFold> = None;
    // The first ray points at the farthest corner, so a fold at the same radius all round (a
    // radial lens) is named by the corner where it cuts into the image first.
    for ray in 0..FOLD_RAYS {
        let theta = corner_theta + std::f64::consts::TAU * ray as f64 / FOLD_RAYS as f64;
        let (dx, dy) = (theta.cos(), theta.sin());
        for i in 1..=max_steps {
            let r = step * i as f64;
            let (x, y) = (r * dx, r * dy);
            let r2 = r * r;
            let radial = 1.0 + k1 * r2 + k2 * r2 * r2 + k3 * r2 * r2 * r2;
            // d(radial)/d(r²), for the Jacobian's radial part.
            let radial_d = k1 + 2.0 * k2 * r2 + 3.0 * k3 * r2 * r2;
            let xd = x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x);
            let yd = y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y;
            let j11 = radial + 2.0 * x * x * radial_d + 2.0 * p1 * y + 6.0 * p2 * x;
            let j12 = 2.0 * x * y * radial_d + 2.0 * p1 * x + 2.0 * p2 * y;
            let j21 = 2.0 * x * y * radial_d + 2.0 * p1 * x + 2.0 * p2 * y;
            let j22 = radial + 2.0 * y * y * radial_d + 6.0 * p1 * y + 2.0 * p2 * x;
            let det = j11 * j22 - j12 * j21;
            let out = xd.hypot(yd);
            if radial <= 0.0 || det <= 0.05 * radial {
                let fraction_of_corner = out / corner_radius;
                // Rounding alone must not move a tie off the farthest corner's ray.
                if first.is_none_or(|f| fraction_of_corner < f.fraction_of_corner - 1e-9) {
                    let corner = match (xd < 0.0, yd < 0.0) {
                        (true, true) => "top-left",
                        (false, true) => "top-right",
                        (true, false) => "bottom-left",
                        (false, false) => "bottom-right",
                    };
                    first = Some(DistortionFold { fraction_of_corner, corner });
                }
                break;
            }
            if out >= limit {
                break;
            }
        }
    }
    first
}

/// Checks a distortion `[k1, k2, p1, p2, k3]` of a camera with intrinsics `k` over a
/// `width` x `height` image: finite, within ±[`MAX_DISTORTION_COEFFICIENT`], and one-to-one
/// over the image: out to [`DISTORTION_MARGIN`] times the farthest corner's distance from
/// the principal point the map does not fold back ([`distortion_fold`]), or pixels could not
/// be mapped back to rays. Beyond that a real lens's polynomial may fold harmlessly.
pub fn check_distortion(key: &str, dist: &[f64; 5], width: u32, height: u32, k: &[[f64; 3]; 3]) -> Result<(), Error> {
    if !dist.iter().all(|v| v.is_finite() && v.abs() <= MAX_DISTORTION_COEFFICIENT) {
        return Err(Error::value(
            key,
            format!("expected [k1, k2, p1, p2, k3], finite numbers within ±{MAX_DISTORTION_COEFFICIENT}, got {dist:?}"),
        ));
    }
    if dist.iter().all(|&d| d == 0.0) {
        return Ok(());
    }
    if let Some(fold) = distortion_fold(dist, width, height, k, DISTORTION_MARGIN) {
        return Err(Error::value(
            key,
            format!(
                "expected a distortion that is one-to-one over the image, but it folds back at {:.0} % of the way from the principal point to the farthest image corner, towards the {} corner",
                100.0 * fold.fraction_of_corner,
                fold.corner
            ),
        ));
    }
    Ok(())
}

/// Checks where a camera or projector is mounted (`t` its pose in the world, rows): its
/// centre within ±[`MAX_DISTANCE_MM`] of the world origin on every axis and above the table
/// top (z > 0), and its optical axis pointing down towards the table.
pub fn check_mounting(key: &str, t: &[[f64; 4]; 4]) -> Result<(), Error> {
    let centre = [t[0][3], t[1][3], t[2][3]];
    if centre.iter().any(|v| !(v.is_finite() && v.abs() <= MAX_DISTANCE_MM)) {
        return Err(Error::value(
            key,
            format!("expected a centre within ±{MAX_DISTANCE_MM} mm of the world origin, got {centre:?} mm"),
        ));
    }
    if centre[2] <= 0.0 {
        return Err(Error::value(
            key,
            format!("expected a centre above the table top (z > 0), got z = {} mm", centre[2]),
        ));
    }
    // The optical axis is the pose's third column; it must have a downward part.
    if t[2][2] >= 0.0 {
        return Err(Error::value(
            key,
            format!(
                "expected the optical axis to point down towards the table, it points {} (its z is {:.3})",
                if t[2][2] > 0.0 { "up" } else { "level" },
                t[2][2]
            ),
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_past_the_budget_are_refused_with_the_estimate() {
        assert!(check_image_size("left", 640, 480, BYTES_PER_CAMERA_PIXEL, 1).is_ok());
        let e = check_image_size("left", 8192, 8192, BYTES_PER_CAMERA_PIXEL, 1).unwrap_err().to_string();
        assert!(e.starts_with("left: 8192 x 8192") && e.contains("GB") && e.contains("budget"), "{e}");
        assert!(check_image_size("left", 8, 480, 1, 1).is_err());
        assert!(check_image_size("left", 640, 9000, 1, 1).is_err());
    }

    #[test]
    fn focal_lengths_no_lens_has_are_refused() {
        assert!(check_focal_px("left.K", "fx", 800.0, 640).is_ok());
        for f in [1e-300, 0.0, -800.0, f64::NAN, f64::INFINITY, 1e9] {
            let e = check_focal_px("left.K", "fx", f, 640).unwrap_err().to_string();
            assert!(e.starts_with("left.K: fx = ") && e.contains("field of view"), "{e}");
        }
    }

    fn k(fx: f64, fy: f64, cx: f64, cy: f64) -> [[f64; 3]; 3] {
        [[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]]
    }

    /// The fold of a purely radial lens the slow way: the distorted radius at the first
    /// undistorted radius where d/dr of r (1 + k1 r² + k2 r⁴ + k3 r⁶) falls to 0.05.
    fn radial_fold(k1: f64, k2: f64, k3: f64) -> f64 {
        let mut r = 0.0f64;
        loop {
            let r2 = r * r;
            if 1.0 + 3.0 * k1 * r2 + 5.0 * k2 * r2 * r2 + 7.0 * k3 * r2 * r2 * r2 <= 0.05 {
                return r * (1.0 + k1 * r2 + k2 * r2 * r2 + k3 * r2 * r2 * r2);
            }
            r += 1e-6;
        }
    }

    #[test]
    fn a_distortion_folding_back_is_refused() {
        let k0 = k(800.0, 800.0, 320.0, 240.0);
        assert!(check_distortion("d", &[-0.2, 0.05, 0.0, 0.0, 0.0], 640, 480, &k0).is_ok());
        let e = check_distortion("d", &[-2.0, 0.0, 0.0, 0.0, 0.0], 640, 480, &k0).unwrap_err().to_string();
        assert!(e.starts_with("d: ") && e.contains("one-to-one") && e.contains("farthest image corner"), "{e}");
    }

    #[test]
    fn a_fold_is_refused_inside_the_image_and_let_through_outside() {
        // 640 x 480 at f = 400 with the principal point at the centre: the corners lie 1.0
        // from it in normalised coordinates. A barrel lens k1 < 0 folds where 1 + 3 k1 r² =
        // 0.05, at a distorted radius of (2.05/3)·sqrt(0.95/(-3 k1)); k1 = -0.2 puts it at
        // 0.86 (inside), k1 = -0.1 at 1.22 (outside, within the old 1.5 horizon).
        let k0 = k(400.0, 400.0, 320.0, 240.0);
        for (k1, inside) in [(-0.2, true), (-0.1, false)] {
            let dist = [k1, 0.0, 0.0, 0.0, 0.0];
            let want = radial_fold(k1, 0.0, 0.0);
            let fold = distortion_fold(&dist, 640, 480, &k0, 1.5).unwrap();
            assert!((fold.fraction_of_corner - want).abs() < 0.01, "{k1}: {fold:?}, want {want}");
            assert_eq!(check_distortion("right.dist", &dist, 640, 480, &k0).is_err(), inside, "{k1}: {fold:?}");
        }
        // A fold just inside the corner, and one just outside it (k1 solved for a fold at
        // 0.98 and at 1.08 of the corner's radius).
        let k1_folding_at = |rd: f64| -(0.95 / 3.0) * (2.05 / (3.0 * rd)).powi(2);
        let just_inside = [k1_folding_at(0.98), 0.0, 0.0, 0.0, 0.0];
        let e = check_distortion("right.dist", &just_inside, 640, 480, &k0).unwrap_err().to_string();
        assert!(e.starts_with("right.dist: ") && e.contains("folds back at 98 %"), "{e}");
        let just_outside = [k1_folding_at(1.08), 0.0, 0.0, 0.0, 0.0];
        assert!(check_distortion("right.dist", &just_outside, 640, 480, &k0).is_ok());
        let fold = distortion_fold(&just_outside, 640, 480, &k0, 1.5).unwrap();
        assert!((fold.fraction_of_corner - 1.08).abs() < 0.01, "{fold:?}");
    }

    #[test]
    fn the_farthest_corner_is_measured_from_the_principal_point() {
        // The fold at 1.08 of a centred principal point's corner radius: moving the principal
        // point 60 px right puts the left corners farther out (1.0 -> 1.12), so the same lens
        // folds inside the image, towards a left corner.
        let k1 = -(0.95 / 3.0) * (2.05f64 / (3.0 * 1.08)).powi(2);
        let dist = [k1, 0.0, 0.0, 0.0, 0.0];
        assert!(check_distortion("d", &dist, 640, 480, &k(400.0, 400.0, 320.0, 240.0)).is_ok());
        let e = check_distortion("d", &dist, 640, 480, &k(400.0, 400.0, 380.0, 240.0)).unwrap_err().to_string();
        assert!(e.contains("left corner"), "{e}");
    }

    #[test]
    fn tangential_terms_move_the_fold() {
        // A radial lens folding at 1.08 corner radii passes; a strong p1 tilts the map so it
        // folds sooner on one side, inside the image.
        let k0 = k(400.0, 400.0, 320.0, 240.0);
        let k1 = -(0.95 / 3.0) * (2.05f64 / (3.0 * 1.08)).powi(2);
        assert!(check_distortion("d", &[k1, 0.0, 0.0, 0.0, 0.0], 640, 480, &k0).is_ok());
        let e = check_distortion("d", &[k1, 0.0, 0.05, 0.0, 0.0], 640, 480, &k0).unwrap_err().to_string();
        assert!(e.contains("one-to-one"), "{e}");
    }

    #[test]
    fn a_camera_below_the_table_or_looking_up_is_refused() {
        let down = |z: f64| [[1.0, 0.0, 0.0, 0.0], [0.0, -1.0, 0.0, 0.0], [0.0, 0.0, -1.0, z], [0.0, 0.0, 0.0, 1.0]];
        assert!(check_mounting("left.T_world_camera", &down(600.0)).is_ok());
        assert!(check_mounting("left.T_world_camera", &down(-513.0))
            .unwrap_err()
            .to_string()
            .contains("above the table"));
        assert!(check_mounting("left.T_world_camera", &down(1e200)).unwrap_err().to_string().contains("within"));
        let up = [[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 600.0], [0.0, 0.0, 0.0, 1.0]];
        assert!(check_mounting("left.T_world_camera", &up).unwrap_err().to_string().contains("point down"));
    }
}
