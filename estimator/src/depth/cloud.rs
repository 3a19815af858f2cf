//! The point-cloud stage: a rectified-left disparity map becomes points in the world frame
//! (mm), cropped to the work volume and with the background removed, plus the depth maps.
//! Down-sampling and normals belong to the next stage.
//!
//! Pixel (x, y) of the disparity map is taken at its centre, image coordinates (x, y), as
//! OpenCV does; depth is `z = fx * baseline / d` along the rectified z axis.

use camplace_config::{ReconstructionParams, WorkVolume};
use nalgebra::{Matrix3, Point3, Vector3};

use crate::{Background, Error, ErrorKind, FloatImage, RectifiedCamera, Result};

/// The caller-owned output of [`CloudBuilder::build`], reused frame after frame.
#[derive(Debug, Clone, Default)]
pub struct Cloud {
    /// Kept points in the world frame, mm, in row-major pixel order.
    pub points: Vec<Point3<f32>>,
    /// Rectified-left pixel index (`y * width + x`) of each point.
    pub pixels: Vec<u32>,
    /// Rectified-left depth of the kept points, mm; +inf elsewhere.
    pub depth: FloatImage,
}

impl Cloud {
    /// An output with room for every pixel of a `width` x `height` map, so that building
    /// into it never allocates.
    pub fn with_capacity(width: usize, height: usize) -> Self {
        Cloud {
            points: Vec::with_capacity(width * height),
            pixels: Vec::with_capacity(width * height),
            depth: FloatImage::new(width, height, f32::INFINITY),
        }
    }
}

/// Disparity -> world points for one rectified camera, work volume and background margin.
#[derive(Debug, Clone)]
pub struct CloudBuilder {
    camera: RectifiedCamera,
    focal_baseline: f32,
    cx: f32,
    cy: f32,
    inv_fx: f32,
    inv_fy: f32,
    rotation: Matrix3<f32>,
    translation: Vector3<f32>,
    lower: Vector3<f32>,
    upper: Vector3<f32>,
    background_margin: f32,
}

impl CloudBuilder {
    /// A builder for `camera`, keeping points inside `work_volume` (world box, mm) and at
    /// least `params.background_margin` mm in front of the background.
    pub fn new(camera: &RectifiedCamera, work_volume: &WorkVolume, params: &ReconstructionParams) -> Self {
        let k = &camera.k;
        let iso = camera.t_world_rectified;
        let wv = |r: [f64; 2]| (r[0] as f32, r[1] as f32);
        let (x, y, z) = (wv(work_volume.x), wv(work_volume.y), wv(work_volume.z));
        CloudBuilder {
            camera: camera.clone(),
            focal_baseline: (camera.focal() * camera.baseline) as f32,
            cx: k[(0, 2)] as f32,
            cy: k[(1, 2)] as f32,
            inv_fx: (1.0 / k[(0, 0)]) as f32,
            inv_fy: (1.0 / k[(1, 1)]) as f32,
            rotation: iso.rotation.to_rotation_matrix().matrix().cast(),
            translation: iso.translation.vector.cast(),
            lower: Vector3::new(x.0, y.0, z.0),
            upper: Vector3::new(x.1, y.1, z.1),
            background_margin: params.background_margin as f32,
        }
    }

    /// The rectified camera the builder back-projects with.
    pub fn camera(&self) -> &RectifiedCamera {
        &self.camera
    }

    /// Back-projects every finite positive disparity, keeps the points inside the work
    /// volume and in front of `background` (when given), and writes them, their pixels and
    /// their depths into `cloud` (cleared first; no allocation when it has the capacity).
    pub fn build(&self, disparity: &FloatImage, background: Option<&Background>, cloud: &mut Cloud) -> Result<()> {
        self.check_size(disparity)?;
        if let Some(bg) = background {
            if !bg.depth().same_size(disparity) {
                return Err(Error::new(ErrorKind::Input, "cloud: the background is not the disparity map's size"));
            }
        }
        cloud.points.clear();
        cloud.pixels.clear();
        cloud.depth.reset(disparity.width, disparity.height, f32::INFINITY);
        let w = disparity.width;
        // Row by row: a pixel's coordinates without a division.
        let pixels = disparity
            .data
            .chunks_exact(w.max(1))
            .enumerate()
            .flat_map(|(y, row)| row.iter().enumerate().map(move |(x, &d)| (x, y, d)));
        for (i, (x, y, d)) in pixels.enumerate() {
            // NaN and +inf fail `d < INFINITY`; zero and negative disparities lie at or
            // beyond infinity.
            if !(d > 0.0 && d < f32::INFINITY) {
                continue;
            }
            let z = self.focal_baseline / d;
            if let Some(bg) = background {
                if bg.is_background(x, y, z, self.background_margin) {
                    continue;
                }
            }
            let p = Vector3::new((x as f32 - self.cx) * z * self.inv_fx, (y as f32 - self.cy) * z * self.inv_fy, z);
            let q = self.rotation * p + self.translation;
            if q.x < self.lower.x
                || q.x > self.upper.x
                || q.y < self.lower.y
                || q.y > self.upper.y
                || q.z < self.lower.z
                || q.z > self.upper.z
            {
                continue;
            }
            cloud.points.push(Point3::from(q));
            cloud.pixels.push(i as u32);
            cloud.depth.data[i] = z;
        }
        Ok(())
    }

    /// Depth (mm along the rectified z axis) of every pixel of `disparity`, +inf where it
    /// is not a finite positive disparity; no crop, no background removal.
    pub fn depth(&self, disparity: &FloatImage, depth: &mut FloatImage) -> Result<()> {
        self.check_size(disparity)?;
        depth.reset(disparity.width, disparity.height, f32::INFINITY);
        for (o, &d) in depth.data.iter_mut().zip(&disparity.data) {
            if d > 0.0 && d < f32::INFINITY {
                *o = self.focal_baseline / d;
            }
        }
        Ok(())
    }

    fn check_size(&self, disparity: &FloatImage) -> Result<()> {
        if disparity.width != self.camera.width || disparity.height != self.camera.height {
            return Err(Error::new(
                ErrorKind::Input,
                format!(
                    "cloud: expected a {} x {} disparity map, got {} x {}",
                    self.camera.width, self.camera.height, disparity.width, disparity.height
                ),
            ));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Isometry3, Translation3, UnitQuaternion};
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn camera() -> RectifiedCamera {
        let rotation = UnitQuaternion::from_euler_angles(2.6, 0.3, -0.4);
        RectifiedCamera {
            width: 160,
            height: 120,
            k: Matrix3::new(200.0, 0.0, 82.5, 0.0, 200.0, 57.0, 0.0, 0.0, 1.0),
            baseline: 110.0,
            t_world_rectified: Isometry3::from_parts(Translation3::new(40.0, -300.0, 520.0), rotation),
        }
    }

    fn everywhere() -> WorkVolume {
        WorkVolume { x: [-1e5, 1e5], y: [-1e5, 1e5], z: [-1e5, 1e5] }
    }

    fn params(margin: f64) -> ReconstructionParams {
        ReconstructionParams { background_margin: margin, background_dilation: 0 }
    }

    /// Random disparities with a share of invalid ones of every kind.
    fn random_disparity(cam: &RectifiedCamera, seed: u64) -> FloatImage {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let data = (0..cam.width * cam.height)
            .map(|_| match rng.random_range(0..10) {
                0 => f32::INFINITY,
                1 => f32::NAN,
                2 => [0.0, -3.0][rng.random_range(0..2)],
                _ => rng.random_range(20.0..80.0f32),
            })
            .collect();
        FloatImage::from_vec(cam.width, cam.height, data).unwrap()
    }

    #[test]
    fn points_project_back_to_their_pixel_and_disparity() {
        let cam = camera();
        let disp = random_disparity(&cam, 11);
        let builder = CloudBuilder::new(&cam, &everywhere(), &params(4.0));
        let mut cloud = Cloud::with_capacity(cam.width, cam.height);
        builder.build(&disp, None, &mut cloud).unwrap();
        let valid = disp.data.iter().filter(|d| d.is_finite() && **d > 0.0).count();
        assert_eq!(cloud.points.len(), valid);
        for (p, &i) in cloud.points.iter().zip(&cloud.pixels) {
            let (x, y) = (i as usize % cam.width, i as usize / cam.width);
            let (u, v, d) = cam.project(&p.cast()).unwrap();
            assert!((u - x as f64).abs() < 1e-3 && (v - y as f64).abs() < 1e-3, "pixel ({x}, {y}) -> ({u}, {v})");
            let want = disp.data[i as usize] as f64;
            assert!((d - want).abs() < 1e-4 * want, "disparity {want} -> {d}");
            let z = cam.depth_from_disparity(want as f32);
            assert!((cloud.depth.data[i as usize] - z).abs() < 1e-3 * z);
        }
        let mut depth = FloatImage::default();
        builder.depth(&disp, &mut depth).unwrap();
        for (z, d) in depth.data.iter().zip(&disp.data) {
            if d.is_finite() && *d > 0.0 {
                assert!((z - cam.depth_from_disparity(*d)).abs() < 1e-3);
            } else {
                assert_eq!(*z, f32::INFINITY);
            }
        }
    }

    #[test]
    fn crop_and_background_agree_with_a_plain_loop() {
        let cam = camera();
        let disp = random_disparity(&cam, 12);
        // A box around the middle of the cloud, so that every face crops some points.
        let mut all = Cloud::with_capacity(cam.width, cam.height);
        CloudBuilder::new(&cam, &everywhere(), &params(4.0)).build(&disp, None, &mut all).unwrap();
        let quantiles = |axis: usize| {
            let mut v: Vec<f64> = all.points.iter().map(|p| p[axis] as f64).collect();
            v.sort_by(|a, b| a.partial_cmp(b).unwrap());
            [v[v.len() / 5], v[4 * v.len() / 5]]
        };
        let wv = WorkVolume { x: quantiles(0), y: quantiles(1), z: quantiles(2) };
        let bg_disp = random_disparity(&cam, 13);
        let background = Background::from_disparity(&cam, &bg_disp, &params(4.0)).unwrap();
        let builder = CloudBuilder::new(&cam, &wv, &params(4.0));
        let mut cloud = Cloud::with_capacity(cam.width, cam.height);
        builder.build(&disp, Some(&background), &mut cloud).unwrap();
        let mut want = Vec::new();
        for y in 0..cam.height {
            for x in 0..cam.width {
                let d = disp.get(x, y) as f64;
                if !(d.is_finite() && d > 0.0) {
                    continue;
                }
                let pc = cam.point_in_camera(x as f64, y as f64, d);
                if pc.z >= background.depth().get(x, y) as f64 - 4.0 {
                    continue;
                }
                let p = cam.t_world_rectified.transform_point(&pc);
                let inside = |v: f64, r: [f64; 2]| v >= r[0] && v <= r[1];
                if inside(p.x, wv.x) && inside(p.y, wv.y) && inside(p.z, wv.z) {
                    want.push((y * cam.width + x) as u32);
                }
            }
        }
        // Points within float rounding of a box face may fall either way.
        let near_face = cloud
            .pixels
            .iter()
            .filter(|i| !want.contains(i))
            .chain(want.iter().filter(|i| !cloud.pixels.contains(i)))
            .count();
        assert!(want.len() > 100, "the test keeps too few points to say anything");
        assert!(near_face <= 2, "{near_face} points differ from the plain loop");
        let within = |v: f32, r: [f64; 2]| v >= r[0] as f32 && v <= r[1] as f32;
        assert!(cloud.points.iter().all(|p| within(p.x, wv.x) && within(p.y, wv.y) && within(p.z, wv.z)));
    }

    #[test]
    fn rebuilding_keeps_the_buffers() {
        let cam = camera();
        let builder = CloudBuilder::new(&cam, &everywhere(), &params(4.0));
        let mut cloud = Cloud::with_capacity(cam.width, cam.height);
        let ptr = cloud.points.as_ptr();
        for seed in 0..3 {
            builder.build(&random_disparity(&cam, seed), None, &mut cloud).unwrap();
        }
        assert_eq!(ptr, cloud.points.as_ptr());
        let wrong = FloatImage::new(10, 10, 50.0);
        assert!(builder.build(&wrong, None, &mut cloud).is_err());
    }

    #[test]
    fn background_removal_keeps_the_box_and_drops_the_table() {
        use crate::depth::fixture::{params as phase_params, Scene, Surface, PERIODS, RANGE};
        use crate::PhaseDecoder;
        let cam = crate::depth::fixture::camera();
        let (w, h) = (cam.width, cam.height);
        let mut decoder = PhaseDecoder::new(&phase_params(), &PERIODS, w, h).unwrap();
        let empty = Scene { with_box: false, mirrored: false }.render(&PERIODS, 21);
        let mut bg_disp = FloatImage::default();
        decoder.decode(&empty.left, &empty.right, RANGE, &mut bg_disp).unwrap();
        let recon = ReconstructionParams { background_margin: 4.0, background_dilation: 2 };
        let background = Background::from_disparity(&cam, &bg_disp, &recon).unwrap();

        let scene = Scene { with_box: true, mirrored: false }.render(&PERIODS, 22);
        let mut disp = FloatImage::default();
        decoder.decode(&scene.left, &scene.right, RANGE, &mut disp).unwrap();
        // The scene's table frame has z = 0 on the table: a work volume that keeps all.
        let wv = WorkVolume { x: [-1e4, 1e4], y: [-1e4, 1e4], z: [-50.0, 200.0] };
        let builder = CloudBuilder::new(&cam, &wv, &recon);
        let mut cloud = Cloud::with_capacity(w, h);
        builder.build(&disp, Some(&background), &mut cloud).unwrap();

        let (mut table, mut table_kept, mut boxed, mut box_kept) = (0, 0, 0, 0);
        let kept: std::collections::HashSet<u32> = cloud.pixels.iter().copied().collect();
        for i in 0..w * h {
            // Wrong matches are the decoder's errors, not the background's.
            let error = (disp.data[i] as f64 - scene.disparity[i]).abs();
            if !error.is_finite() || error > 1.0 {
                continue;
            }
            let k = kept.contains(&(i as u32)) as usize;
            match scene.surface[i] {
                Some(Surface::Table) => {
                    table += 1;
                    table_kept += k;
                }
                Some(Surface::Box) => {
                    boxed += 1;
                    box_kept += k;
                }
                None => {}
            }
        }
        eprintln!("table {table_kept}/{table} box {box_kept}/{boxed}");
        assert!(table > 50_000 && boxed > 5_000, "{table} table and {boxed} box pixels decoded");
        assert!((table_kept as f64) < 0.002 * table as f64, "{table_kept} of {table} table points kept");
        assert!(box_kept as f64 > 0.99 * boxed as f64, "{box_kept} of {boxed} box points kept");
        // Kept box points lie on the box's front face (z = 590 mm in the camera frame).
        let to_camera = cam.t_world_rectified.inverse();
        let mut off: Vec<f64> =
            cloud.points.iter().map(|p| (to_camera.transform_point(&p.cast()).z - 590.0).abs()).collect();
        off.sort_by(|a, b| a.partial_cmp(b).unwrap());
        assert!(off[off.len() / 2] < 0.5, "median distance to the box face {} mm", off[off.len() / 2]);
    }
}
