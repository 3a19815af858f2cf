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

/// Checks a distortion `[k1, k2, p1, p2, k3]` of a camera with focal lengths `fx`, `fy` over
/// a `width` x `height` image: finite, within ±[`MAX_DISTORTION_COEFFICIENT`], and
/// one-to-one over the image: along every ray out to the image's corners the distorted
/// radius keeps growing, or pixels could not be mapped back to rays.
pub fn check_distortion(key: &str, dist: &[f64; 5], width: u32, height: u32, fx: f64, fy: f64) -> Result<(), Error> {
    if !dist.iter().all(|v| v.is_finite() && v.abs() <= MAX_DISTORTION_COEFFICIENT) {
        return Err(Error::value(
            key,
            format!("expected [k1, k2, p1, p2, k3], finite numbers within ±{MAX_DISTORTION_COEFFICIENT}, got {dist:?}"),
        ));
    }
    if dist.iter().all(|&d| d == 0.0) {
        return Ok(());
    }
    // The half diagonal of the image in normalised coordinates, with a margin for the
    // principal point and the tangential terms.
    let (w, h) = (f64::from(width), f64::from(height));
    let r_max = 1.5 * ((w / fx).powi(2) + (h / fy).powi(2)).sqrt() / 2.0;
    let [k1, k2, _, _, k3] = *dist;
    let steps = 200;
    for i in 0..=steps {
        let r = r_max * i as f64 / steps as f64;
        let r2 = r * r;
        // d/dr of r (1 + k1 r^2 + k2 r^4 + k3 r^6).
        let slope = 1.0 + 3.0 * k1 * r2 + 5.0 * k2 * r2 * r2 + 7.0 * k3 * r2 * r2 * r2;
        if slope <= 0.05 {
            return Err(Error::value(
                key,
                format!(
                    "expected a distortion that is one-to-one over the image, but its radial part folds back at {:.0} % of the image's half diagonal",
                    100.0 * r / (r_max / 1.5)
                ),
            ));
        }
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

    #[test]
    fn a_distortion_folding_back_is_refused() {
        assert!(check_distortion("d", &[-0.2, 0.05, 0.0, 0.0, 0.0], 640, 480, 800.0, 800.0).is_ok());
        let e = check_distortion("d", &[-2.0, 0.0, 0.0, 0.0, 0.0], 640, 480, 800.0, 800.0).unwrap_err();
        assert!(e.to_string().contains("one-to-one"), "{e}");
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
