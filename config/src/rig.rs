//! `rig.json`: the calibration of the two cameras and the projector
//! (docs/design/interchange-formats.md), plus the optional `rectified` section that reconstruction
//! adds.

use serde::{Deserialize, Serialize};
use std::path::Path;

use crate::camera_checks::{
    check_distortion, check_focal_px, check_image_size, check_mounting, BYTES_PER_CAMERA_PIXEL,
    BYTES_PER_PROJECTOR_PIXEL, MEMORY_BUDGET_BYTES,
};
use crate::Error;

/// A rectified canvas's buffers (per canvas pixel, the same cost as a camera pixel) within
/// the memory budget.
fn check_image_size_any(key: &str, width: u32, height: u32) -> Result<(), Error> {
    let estimate = u64::from(width) * u64::from(height) * BYTES_PER_CAMERA_PIXEL;
    if estimate > MEMORY_BUDGET_BYTES {
        return Err(Error::value(
            key,
            format!(
                "a {width} x {height} canvas would need about {:.1} GB of buffers, past the memory budget of {:.1} GB",
                estimate as f64 / 1e9,
                MEMORY_BUDGET_BYTES as f64 / 1e9
            ),
        ));
    }
    Ok(())
}

/// One camera (or the projector): intrinsics, distortion and pose in the world.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraFile {
    pub width: u32,
    pub height: u32,
    #[serde(rename = "K")]
    pub k: [[f64; 3]; 3],
    /// k1 k2 p1 p2 k3 (OpenCV order).
    pub dist: [f64; 5],
    #[serde(rename = "T_world_camera")]
    pub t_world_camera: [[f64; 4]; 4],
}

/// The common rectified camera of a stereo pair.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RectifiedFile {
    pub width: u32,
    pub height: u32,
    #[serde(rename = "K")]
    pub k: [[f64; 3]; 3],
    /// Distance between the rectified camera centres, mm.
    pub baseline: f64,
    #[serde(rename = "T_world_rectified")]
    pub t_world_rectified: [[f64; 4]; 4],
}

/// A whole `rig.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RigFile {
    pub left: CameraFile,
    pub right: CameraFile,
    pub projector: Option<CameraFile>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rectified: Option<RectifiedFile>,
}

impl RigFile {
    /// Reads and checks a `rig.json`.
    pub fn load(path: &Path) -> Result<RigFile, Error> {
        let text = crate::formats::read::read_text(path)?;
        Self::from_json(&text).map_err(|e| e.in_file(path))
    }

    /// Parses and checks rig JSON text.
    pub fn from_json(text: &str) -> Result<RigFile, Error> {
        let rig: RigFile = crate::formats::json::decode(text)?;
        rig.check()?;
        Ok(rig)
    }

    /// Checks every camera (size, K, distortion, pose) and the baseline.
    pub fn check(&self) -> Result<(), Error> {
        self.left.check("left", BYTES_PER_CAMERA_PIXEL)?;
        self.right.check("right", BYTES_PER_CAMERA_PIXEL)?;
        let baseline = (0..3)
            .map(|r| self.right.t_world_camera[r][3] - self.left.t_world_camera[r][3])
            .map(|d| d * d)
            .sum::<f64>()
            .sqrt();
        if baseline < MIN_BASELINE_MM {
            return Err(Error::value(
                "right.T_world_camera",
                format!(
                    "expected a camera centre at least {MIN_BASELINE_MM} mm from left's (the baseline), got {baseline} mm"
                ),
            ));
        }
        if let Some(p) = &self.projector {
            p.check("projector", BYTES_PER_PROJECTOR_PIXEL)?;
        }
        if let Some(r) = &self.rectified {
            r.check()?;
        }
        Ok(())
    }

    /// The rig as pretty JSON.
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).expect("a rig always serialises")
    }

    /// Writes the rig atomically.
    pub fn save(&self, path: &Path) -> Result<(), Error> {
        crate::formats::write_atomic(path, self.to_json().as_bytes())
    }
}

/// The shortest baseline a `rig.json` may give, mm: with cameras closer than this no depth
/// can be triangulated (stereo rigs are tens of millimetres apart and more).
pub const MIN_BASELINE_MM: f64 = 1.0;

pub use crate::camera_checks::MAX_IMAGE_SIDE;

fn check_k(key: &str, k: &[[f64; 3]; 3], width: u32, height: u32) -> Result<(), Error> {
    if !(k.iter().flatten().all(|v| v.is_finite()) && k[1][0] == 0.0 && k[2] == [0.0, 0.0, 1.0]) {
        return Err(Error::value(
            format!("{key}.K"),
            "expected [[fx, s, cx], [0, fy, cy], [0, 0, 1]] of finite numbers with fx, fy > 0",
        ));
    }
    check_focal_px(&format!("{key}.K"), "fx", k[0][0], width)?;
    check_focal_px(&format!("{key}.K"), "fy", k[1][1], height)
}

impl CameraFile {
    /// The physical checks of the cell's sensor, the same functions: the size within the
    /// memory budget, the focal lengths, a distortion one-to-one over the image, a rigid
    /// pose whose centre is within the cell's reach, above the table, looking down.
    fn check(&self, key: &str, bytes_per_pixel: u64) -> Result<(), Error> {
        check_image_size(&format!("{key}.width"), self.width, self.height, bytes_per_pixel, 1)?;
        check_k(key, &self.k, self.width, self.height)?;
        check_distortion(&format!("{key}.dist"), &self.dist, self.width, self.height, &self.k)?;
        let pose = format!("{key}.T_world_camera");
        crate::pose::check_rigid(&self.t_world_camera).map_err(|m| Error::value(&pose, m))?;
        check_mounting(&pose, &self.t_world_camera)
    }
}

impl RectifiedFile {
    fn check(&self) -> Result<(), Error> {
        // The canvas may be up to twice the camera image a side.
        let sides = 1..=2 * MAX_IMAGE_SIDE;
        if !(sides.contains(&self.width) && sides.contains(&self.height)) {
            return Err(Error::value(
                "rectified.width",
                format!(
                    "expected a canvas from 1 to {} pixels a side, got {} x {}",
                    2 * MAX_IMAGE_SIDE,
                    self.width,
                    self.height
                ),
            ));
        }
        check_image_size_any("rectified.width", self.width, self.height)?;
        check_k("rectified", &self.k, self.width, self.height)?;
        if !(self.baseline.is_finite() && self.baseline > 0.0) {
            return Err(Error::value("rectified.baseline", "expected a positive distance in mm"));
        }
        crate::pose::check_rigid(&self.t_world_rectified).map_err(|m| Error::value("rectified.T_world_rectified", m))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cam() -> CameraFile {
        CameraFile {
            width: 640,
            height: 480,
            k: [[800.0, 0.0, 319.5], [0.0, 800.0, 239.5], [0.0, 0.0, 1.0]],
            dist: [0.0; 5],
            // 600 mm above the table, looking straight down.
            t_world_camera: [
                [1.0, 0.0, 0.0, 0.0],
                [0.0, -1.0, 0.0, 0.0],
                [0.0, 0.0, -1.0, 600.0],
                [0.0, 0.0, 0.0, 1.0],
            ],
        }
    }

    /// The right camera of a rig, 80 mm to the left camera's right.
    fn right() -> CameraFile {
        let mut c = cam();
        c.t_world_camera[0][3] = 80.0;
        c
    }

    #[test]
    fn round_trip() {
        let rig = RigFile { left: cam(), right: right(), projector: Some(cam()), rectified: None };
        assert_eq!(RigFile::from_json(&rig.to_json()).unwrap(), rig);
    }

    #[test]
    fn missing_right_camera_is_named() {
        let rig = RigFile { left: cam(), right: right(), projector: None, rectified: None };
        let mut v: serde_json::Value = serde_json::from_str(&rig.to_json()).unwrap();
        v.as_object_mut().unwrap().remove("right");
        let e = RigFile::from_json(&v.to_string()).unwrap_err();
        assert!(e.to_string().contains("right"), "{e}");
    }

    fn with_left(f: impl FnOnce(&mut CameraFile)) -> String {
        let mut rig = RigFile { left: cam(), right: right(), projector: None, rectified: None };
        f(&mut rig.left);
        RigFile::from_json(&rig.to_json()).unwrap_err().to_string()
    }

    #[test]
    fn a_reflected_camera_pose_is_refused() {
        let e = with_left(|c| {
            for row in c.t_world_camera.iter_mut().take(3) {
                row[0] = -row[0];
            }
        });
        assert!(e.starts_with("left.T_world_camera: ") && e.contains("determinant"), "{e}");
    }

    #[test]
    fn sizes_and_intrinsics_out_of_range_are_named() {
        assert!(with_left(|c| c.width = 1 << 20).starts_with("left.width: "));
        assert!(with_left(|c| c.k[0][2] = f64::INFINITY).contains("left.K"));
        assert!(with_left(|c| c.dist[4] = f64::NAN).contains("left.dist"));
    }

    #[test]
    fn the_sensors_physical_checks_apply_naming_the_key() {
        let e = with_left(|c| c.k[0][0] = 1e-300);
        assert!(e.starts_with("left.K: fx = ") && e.contains("field of view"), "{e}");
        let e = with_left(|c| c.k[1][1] = -3.0);
        assert!(e.starts_with("left.K: fy = "), "{e}");
        let e = with_left(|c| c.t_world_camera[2][3] = -513.0);
        assert!(e.starts_with("left.T_world_camera: ") && e.contains("above the table"), "{e}");
        let e = with_left(|c| c.t_world_camera[0][3] = 1e200);
        assert!(e.starts_with("left.T_world_camera: ") && e.contains("within"), "{e}");
        let e = with_left(|c| c.dist = [-3.0, 0.0, 0.0, 0.0, 0.0]);
        assert!(e.starts_with("left.dist: ") && e.contains("one-to-one"), "{e}");
        let e = with_left(|c| (c.width, c.height) = (8192, 8192));
        assert!(e.starts_with("left.width: 8192 x 8192") && e.contains("budget"), "{e}");
        let e = with_left(|c| {
            // Turned half way round about x: looking up from above the table.
            c.t_world_camera[1][1] = 1.0;
            c.t_world_camera[2][2] = 1.0;
        });
        assert!(e.contains("point down"), "{e}");
    }

    #[test]
    fn cameras_at_one_centre_are_refused_naming_the_key() {
        let mut rig = RigFile { left: cam(), right: right(), projector: None, rectified: None };
        rig.right.t_world_camera[0][3] = 0.5;
        let e = RigFile::from_json(&rig.to_json()).unwrap_err();
        assert!(e.to_string().contains("right.T_world_camera") && e.to_string().contains("baseline"), "{e}");
        rig.right.t_world_camera[0][3] = 1.0;
        assert!(RigFile::from_json(&rig.to_json()).is_ok());
    }
}
