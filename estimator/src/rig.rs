//! The stereo rig: two cameras and, optionally, the projector.

use camplace_config::RigFile;

use crate::camera::Camera;

/// A calibrated stereo pair with its projector.
#[derive(Debug, Clone, PartialEq)]
pub struct Rig {
    pub left: Camera,
    pub right: Camera,
    pub projector: Option<Camera>,
}

impl Rig {
    /// The rig of a `rig.json`.
    pub fn from_file(f: &RigFile) -> Self {
        Rig {
            left: Camera::from_file(&f.left),
            right: Camera::from_file(&f.right),
            projector: f.projector.as_ref().map(Camera::from_file),
        }
    }

    /// The `rig.json` of this rig (without a rectified section).
    pub fn to_file(&self) -> RigFile {
        RigFile {
            left: self.left.to_file(),
            right: self.right.to_file(),
            projector: self.projector.as_ref().map(Camera::to_file),
            rectified: None,
        }
    }

    /// Distance between the camera centres, mm.
    pub fn baseline(&self) -> f64 {
        (self.right.centre() - self.left.centre()).norm()
    }
}
