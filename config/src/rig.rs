//! `rig.json`: the calibration of the two cameras and the projector
//! (docs/architecture.md §3), plus the optional `rectified` section that reconstruction
//! adds.

use serde::{Deserialize, Serialize};
use std::path::Path;

use crate::{Error, ErrorKind};

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
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, &e))?;
        Self::from_json(&text).map_err(|e| e.in_file(path))
    }

    /// Parses and checks rig JSON text.
    pub fn from_json(text: &str) -> Result<RigFile, Error> {
        let de = &mut serde_json::Deserializer::from_str(text);
        let rig: RigFile = serde_path_to_error::deserialize(de).map_err(|e| {
            let key = e.path().to_string();
            let inner = e.into_inner();
            let kind = if inner.is_syntax() || inner.is_eof() { ErrorKind::Format } else { ErrorKind::Value };
            let key = if key == "." { String::new() } else { key };
            let msg = inner.to_string();
            let msg = msg.split(" at line").next().unwrap_or(&msg).to_string();
            Error::new(kind, key, msg).with_source(inner)
        })?;
        rig.left.check("left")?;
        rig.right.check("right")?;
        if let Some(p) = &rig.projector {
            p.check("projector")?;
        }
        Ok(rig)
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

impl CameraFile {
    fn check(&self, key: &str) -> Result<(), Error> {
        if self.width == 0 || self.height == 0 {
            return Err(Error::value(format!("{key}.width"), "expected a positive image size"));
        }
        let k = &self.k;
        if !(k[0][0] > 0.0 && k[1][1] > 0.0 && k[2] == [0.0, 0.0, 1.0]) {
            return Err(Error::value(
                format!("{key}.K"),
                "expected [[fx, s, cx], [0, fy, cy], [0, 0, 1]] with fx, fy > 0",
            ));
        }
        let t = &self.t_world_camera;
        if t[3] != [0.0, 0.0, 0.0, 1.0] || t.iter().flatten().any(|v| !v.is_finite()) {
            return Err(Error::value(
                format!("{key}.T_world_camera"),
                "expected a 4x4 rigid transform, last row [0, 0, 0, 1]",
            ));
        }
        // The rotation part must be orthonormal (to 1e-6).
        for i in 0..3 {
            for j in 0..3 {
                let dot: f64 = (0..3).map(|r| t[r][i] * t[r][j]).sum();
                let want = if i == j { 1.0 } else { 0.0 };
                if (dot - want).abs() > 1e-6 {
                    return Err(Error::value(format!("{key}.T_world_camera"), "expected an orthonormal rotation part"));
                }
            }
        }
        Ok(())
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
            t_world_camera: [[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]],
        }
    }

    #[test]
    fn round_trip() {
        let rig = RigFile { left: cam(), right: cam(), projector: Some(cam()), rectified: None };
        assert_eq!(RigFile::from_json(&rig.to_json()).unwrap(), rig);
    }

    #[test]
    fn missing_right_camera_is_named() {
        let rig = RigFile { left: cam(), right: cam(), projector: None, rectified: None };
        let mut v: serde_json::Value = serde_json::from_str(&rig.to_json()).unwrap();
        v.as_object_mut().unwrap().remove("right");
        let e = RigFile::from_json(&v.to_string()).unwrap_err();
        assert!(e.to_string().contains("right"), "{e}");
    }
}
