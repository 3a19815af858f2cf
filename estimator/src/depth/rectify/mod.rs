//! Stereo rectification of a verged, distorted rig (Bouguet): the shared rectified camera,
//! the canvas that holds the work volume, the remap tables that resample raw images onto
//! it, and the disparity search range. Matching itself lives in `stereo`.

mod camera;
mod resample;

pub use camera::RectifiedCamera;

use camplace_config::WorkVolume;
use nalgebra::{Isometry3, Matrix3, Point3, Rotation3, Translation3, UnitQuaternion, Vector3};
use rayon::prelude::*;

use crate::camera::Camera;
use crate::error::{Error, ErrorKind, Result};
use crate::rig::Rig;
use camplace_config::AsImageView;

use crate::{FloatImage, GrayImage};

/// Fixed-point resolution of the bilinear weights: 1/256 px is far below the matcher's
/// sub-pixel noise and keeps the blend in 32-bit integers.
const FRAC_BITS: u32 = 8;
const FRAC_ONE: u32 = 1 << FRAC_BITS;
/// Marks a rectified pixel whose source lies outside the raw image.
const OUTSIDE: u32 = u32::MAX;
/// Raw-image sampling step (px) when measuring what part of the work volume both cameras see.
const COVERAGE_STEP: usize = 4;
/// Depth samples per raw ray through the work volume.
const COVERAGE_DEPTHS: usize = 12;
/// Extra canvas around the seen work volume: covers the coverage sampling step and the
/// descriptor window of the matcher.
const CANVAS_MARGIN_PX: f64 = 8.0;
/// Extra disparity searched either side of the work volume's range, px.
const DISPARITY_MARGIN_PX: f64 = 3.0;
/// The canvas never grows beyond this multiple of the raw image size.
const MAX_CANVAS_SCALE: f64 = 2.0;

/// One rectified pixel's source: the top-left raw pixel and the bilinear fractions. Laid
/// out as written (the vector resampler reads the index as dword 0 and both fractions as
/// dword 1).
#[derive(Debug, Clone, Copy, PartialEq)]
#[repr(C)]
struct RemapEntry {
    index: u32,
    frac_x: u16,
    frac_y: u16,
}

/// Precomputed rectification of one rig for one work volume.
#[derive(Clone)]
pub struct Rectification {
    /// The shared rectified camera (rectified-left frame in the world).
    pub camera: RectifiedCamera,
    left: Camera,
    right: Camera,
    /// Raw-left camera frame <- rectified frame (rotation only: same centre).
    r_left_rect: Rotation3<f64>,
    /// Raw-right camera frame <- rectified frame.
    r_right_rect: Rotation3<f64>,
    map_left: Vec<RemapEntry>,
    map_right: Vec<RemapEntry>,
    disparity_range: (f32, f32),
}

impl std::fmt::Debug for Rectification {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        // The remap tables are a pixel each: leave them out.
        f.debug_struct("Rectification")
            .field("camera", &self.camera)
            .field("disparity_range", &self.disparity_range)
            .finish_non_exhaustive()
    }
}

impl Rectification {
    /// Rectifies `rig` so the part of `work_volume` both cameras see fits the canvas.
    pub fn new(rig: &Rig, work_volume: &WorkVolume) -> Result<Rectification> {
        let (left, right) = (&rig.left, &rig.right);
        for (name, cam) in [("left", left), ("right", right)] {
            let k = &cam.k;
            let finite = k.iter().all(|v| v.is_finite()) && cam.dist.iter().all(|v| v.is_finite());
            if cam.width < 2 || cam.height < 2 || !finite || k[(0, 0)] <= 0.0 || k[(1, 1)] <= 0.0 {
                return Err(Error::new(
                    ErrorKind::Rig,
                    format!("{name} camera: expected a size of at least 2x2 and positive focal lengths"),
                ));
            }
        }
        let baseline_vec = right.centre() - left.centre();
        let baseline = baseline_vec.norm();
        if !(baseline.is_finite() && baseline > 1e-6) {
            return Err(Error::new(
                ErrorKind::Rig,
                "right.T_world_camera: expected a camera centre apart from the left camera's",
            ));
        }
        let r_wl = left.t_world_camera.rotation.to_rotation_matrix();
        let r_wr = right.t_world_camera.rotation.to_rotation_matrix();
        // Split the relative rotation evenly so both views are resampled by the same small
        // angle: each side loses the least resolution and both land in one middle frame.
        let r_lr = r_wl.inverse() * r_wr;
        let half = Rotation3::new(r_lr.scaled_axis() * 0.5);
        let r_wm = r_wl * half;
        let t = r_wm.inverse() * baseline_vec;
        let e1 = t / t.norm();
        let e2 = Vector3::new(-e1.y, e1.x, 0.0);
        if e2.norm() < 1e-6 {
            return Err(Error::new(ErrorKind::Rig, "rig: the baseline runs along the viewing direction"));
        }
        let e2 = e2.normalize();
        let e3 = e1.cross(&e2);
        let r_m_rect = Rotation3::from_matrix_unchecked(Matrix3::from_columns(&[e1, e2, e3]));
        let r_w_rect = r_wm * r_m_rect;
        let focal = 0.25 * (left.k[(0, 0)] + left.k[(1, 1)] + right.k[(0, 0)] + right.k[(1, 1)]);
        let t_world_rectified = Isometry3::from_parts(
            Translation3::from(left.centre().coords),
            UnitQuaternion::from_rotation_matrix(&r_w_rect),
        );
        let r_left_rect = r_wl.inverse() * r_w_rect;
        let r_right_rect = r_wr.inverse() * r_w_rect;

        let seen =
            seen_work_volume(left, right, &t_world_rectified, focal, baseline, work_volume).ok_or_else(|| {
                Error::new(
                    ErrorKind::Rig,
                    "left.T_world_camera, right.T_world_camera: no part of the work volume (the table and the space \
                 above it) is seen by both cameras; expected cameras that look down at the table",
                )
            })?;
        let max_w = MAX_CANVAS_SCALE * left.width.max(right.width) as f64;
        let max_h = MAX_CANVAS_SCALE * left.height.max(right.height) as f64;
        let (x0, x1) = clamp_span(seen.x_min - CANVAS_MARGIN_PX, seen.x_max + CANVAS_MARGIN_PX, max_w);
        let (y0, y1) = clamp_span(seen.y_min - CANVAS_MARGIN_PX, seen.y_max + CANVAS_MARGIN_PX, max_h);
        let width = (x1.ceil() - x0.floor()) as usize + 1;
        let height = (y1.ceil() - y0.floor()) as usize + 1;
        // Canvas pixel (0, 0) sits at the seen region's corner: cx, cy are minus that corner.
        let k = Matrix3::new(focal, 0.0, -x0.floor(), 0.0, focal, -y0.floor(), 0.0, 0.0, 1.0);
        let camera = RectifiedCamera { width, height, k, baseline, t_world_rectified };
        let map_left = remap_table(&camera, left, &r_left_rect);
        let map_right = remap_table(&camera, right, &r_right_rect);
        let d_min = (seen.d_min - DISPARITY_MARGIN_PX).max(0.0);
        let d_max = seen.d_max + DISPARITY_MARGIN_PX;
        Ok(Rectification {
            camera,
            left: left.clone(),
            right: right.clone(),
            r_left_rect,
            r_right_rect,
            map_left,
            map_right,
            disparity_range: (d_min as f32, d_max as f32),
        })
    }

    /// Resamples a raw left image onto the rectified canvas (0 where the raw image ends).
    /// A raw image of the wrong size yields an all-black canvas.
    pub fn rectify_left(&self, raw: &GrayImage, out: &mut GrayImage) {
        self.rectify_left_shots(std::slice::from_ref(raw), std::slice::from_mut(out));
    }

    /// Resamples a raw right image onto the rectified canvas (0 where the raw image ends).
    /// A raw image of the wrong size yields an all-black canvas.
    pub fn rectify_right(&self, raw: &GrayImage, out: &mut GrayImage) {
        self.rectify_right_shots(std::slice::from_ref(raw), std::slice::from_mut(out));
    }

    /// [`Rectification::rectify_left`] of every shot of a frame, `raws[i]` into `outs[i]`,
    /// in one pass over the remap table.
    pub fn rectify_left_shots<S: AsImageView<u8>>(&self, raws: &[S], outs: &mut [GrayImage]) {
        self.resample(&self.map_left, &self.left, raws, outs);
    }

    /// [`Rectification::rectify_right`] of every shot of a frame, `raws[i]` into `outs[i]`,
    /// in one pass over the remap table.
    pub fn rectify_right_shots<S: AsImageView<u8>>(&self, raws: &[S], outs: &mut [GrayImage]) {
        self.resample(&self.map_right, &self.right, raws, outs);
    }

    /// The shots of one raw camera through its remap table onto the canvas.
    fn resample<S: AsImageView<u8>>(&self, map: &[RemapEntry], raw: &Camera, raws: &[S], outs: &mut [GrayImage]) {
        let canvas = (self.camera.width, self.camera.height);
        resample::remap_shots(map, (raw.width, raw.height), canvas, raws, outs);
    }

    /// The disparities (px) the seen work volume spans at this placement, with a margin:
    /// the matcher's search range.
    pub fn disparity_range(&self) -> (f32, f32) {
        self.disparity_range
    }

    /// Rectified pixel of raw pixel (u, v) of the left (`left = true`) or right camera.
    pub fn raw_to_rectified(&self, left: bool, u: f64, v: f64) -> (f64, f64) {
        let (cam, r) = if left { (&self.left, &self.r_left_rect) } else { (&self.right, &self.r_right_rect) };
        let ray = r.inverse() * cam.ray(u, v);
        let k = &self.camera.k;
        (k[(0, 0)] * ray.x / ray.z + k[(0, 2)], k[(1, 1)] * ray.y / ray.z + k[(1, 2)])
    }

    /// Raw pixel of rectified pixel (x, y) of the left or right camera; `None` behind it.
    pub fn rectified_to_raw(&self, left: bool, x: f64, y: f64) -> Option<(f64, f64)> {
        let (cam, r) = if left { (&self.left, &self.r_left_rect) } else { (&self.right, &self.r_right_rect) };
        raw_of_rectified(&self.camera, cam, r, x, y)
    }

    /// Ground-truth disparity in rectified-left pixels from a depth image of the raw left
    /// camera (mm along its z axis, +inf where nothing). Inverse mapping: each rectified
    /// pixel takes the inverse depth interpolated at its raw source when the four raw
    /// neighbours agree (a surface), the nearest one otherwise (an edge); +inf where unknown.
    pub fn disparity_truth(&self, raw_left: &Camera, depth_left: &FloatImage, out: &mut FloatImage) {
        let cam = &self.camera;
        out.reset(cam.width, cam.height, f32::INFINITY);
        if depth_left.width != raw_left.width
            || depth_left.height != raw_left.height
            || raw_left.width < 2
            || raw_left.height < 2
        {
            return;
        }
        let r_raw_rect = raw_left.t_world_camera.rotation.to_rotation_matrix().inverse()
            * self.camera.t_world_rectified.rotation.to_rotation_matrix();
        let fb = cam.focal() * cam.baseline;
        let (w, h) = (depth_left.width, depth_left.height);
        for y in 0..cam.height {
            for x in 0..cam.width {
                let Some((u, v)) = raw_of_rectified(cam, raw_left, &r_raw_rect, x as f64, y as f64) else {
                    continue;
                };
                if !(u > -0.5 && v > -0.5 && u < w as f64 - 0.5 && v < h as f64 - 0.5) {
                    continue;
                }
                let ray = r_raw_rect * rectified_ray(cam, x as f64, y as f64);
                let n = (ray.x / ray.z, ray.y / ray.z);
                let Some(inv_z) = inverse_depth_at(raw_left, depth_left, u, v, n) else { continue };
                // The rectified ray scaled to raw depth z has rectified depth z / ray.z.
                let d = fb * ray.z * inv_z;
                if d.is_finite() && d > 0.0 {
                    out.set(x, y, d as f32);
                }
            }
        }
    }
}

/// Inverse depth at raw position (u, v), whose undistorted normalised coordinates are `n`.
/// When the raw pixel triangle around it (half of the 2x2 cell) holds depths within 2 % of
/// each other, the inverse depth is the affine function of normalised coordinates through
/// its corners, exact for planes even under distortion; otherwise the nearest pixel's.
fn inverse_depth_at(cam: &Camera, depth: &FloatImage, u: f64, v: f64, n: (f64, f64)) -> Option<f64> {
    let (w, h) = (depth.width, depth.height);
    let valid = |z: f32| z.is_finite() && z > 0.0;
    let x0 = (u.floor().max(0.0) as usize).min(w - 2);
    let y0 = (v.floor().max(0.0) as usize).min(h - 2);
    let (fx, fy) = (u - x0 as f64, v - y0 as f64);
    let corners = if fx + fy <= 1.0 {
        [(x0, y0), (x0 + 1, y0), (x0, y0 + 1)]
    } else {
        [(x0 + 1, y0 + 1), (x0 + 1, y0), (x0, y0 + 1)]
    };
    let z = corners.map(|(x, y)| depth.get(x, y));
    if z.iter().all(|&z| valid(z)) {
        let lo = z.iter().cloned().fold(f32::INFINITY, f32::min) as f64;
        let hi = z.iter().cloned().fold(0.0, f32::max) as f64;
        if hi - lo <= 0.02 * lo {
            let p = corners.map(|(x, y)| cam.ray(x as f64, y as f64));
            let (e1, e2) = ((p[1].x - p[0].x, p[1].y - p[0].y), (p[2].x - p[0].x, p[2].y - p[0].y));
            let det = e1.0 * e2.1 - e1.1 * e2.0;
            if det.abs() > 1e-15 {
                let (qx, qy) = (n.0 - p[0].x, n.1 - p[0].y);
                let b1 = (qx * e2.1 - qy * e2.0) / det;
                let b2 = (e1.0 * qy - e1.1 * qx) / det;
                let inv = z.map(|z| 1.0 / z as f64);
                return Some(inv[0] + b1 * (inv[1] - inv[0]) + b2 * (inv[2] - inv[0]));
            }
        }
    }
    let xn = (u.round().max(0.0) as usize).min(w - 1);
    let yn = (v.round().max(0.0) as usize).min(h - 1);
    let zn = depth.get(xn, yn);
    valid(zn).then(|| 1.0 / zn as f64)
}

/// Unit-depth ray of rectified pixel (x, y) in the rectified frame.
fn rectified_ray(cam: &RectifiedCamera, x: f64, y: f64) -> Vector3<f64> {
    let k = &cam.k;
    Vector3::new((x - k[(0, 2)]) / k[(0, 0)], (y - k[(1, 2)]) / k[(1, 1)], 1.0)
}

fn raw_of_rectified(
    cam: &RectifiedCamera,
    raw: &Camera,
    r_raw_rect: &Rotation3<f64>,
    x: f64,
    y: f64,
) -> Option<(f64, f64)> {
    let p = r_raw_rect * rectified_ray(cam, x, y);
    raw.project_camera(&Point3::from(p)).map(|p| (p.x, p.y))
}

/// The remap table of one raw camera: each rectified pixel's raw source, row by row in
/// [`remap_row`] (the arithmetic of [`raw_of_rectified`], step for step,
/// so the table is the same to the bit).
fn remap_table(cam: &RectifiedCamera, raw: &Camera, r_raw_rect: &Rotation3<f64>) -> Vec<RemapEntry> {
    let projection = RowProjection::new(cam, raw, r_raw_rect);
    let mut map = vec![RemapEntry { index: 0, frac_x: 0, frac_y: 0 }; cam.width * cam.height];
    map.par_chunks_mut(cam.width).enumerate().for_each(|(y, row)| remap_row(&projection, y as f64, row));
    map
}

/// What [`remap_row`] needs of a rectified and a raw camera, as plain numbers.
struct RowProjection {
    /// Rectified focal lengths and principal point: fx, fy, cx, cy.
    rectified: [f64; 4],
    /// Raw camera <- rectified frame, row-major.
    rotation: [[f64; 3]; 3],
    /// Raw camera matrix entries k00, k01, k02, k11, k12.
    k: [f64; 5],
    /// Raw distortion k1, k2, p1, p2, k3.
    dist: [f64; 5],
    /// Raw image width and height.
    size: (usize, usize),
}

impl RowProjection {
    fn new(cam: &RectifiedCamera, raw: &Camera, r_raw_rect: &Rotation3<f64>) -> RowProjection {
        let (c, k, m) = (&cam.k, &raw.k, r_raw_rect.matrix());
        RowProjection {
            rectified: [c[(0, 0)], c[(1, 1)], c[(0, 2)], c[(1, 2)]],
            rotation: std::array::from_fn(|r| std::array::from_fn(|col| m[(r, col)])),
            k: [k[(0, 0)], k[(0, 1)], k[(0, 2)], k[(1, 1)], k[(1, 2)]],
            dist: raw.dist,
            size: (raw.width, raw.height),
        }
    }
}

multiversion! {
    /// The entries of the rectified pixels (x, y) of row `y`, x = 0, 1, …; `OUTSIDE` where
    /// the source lies behind the raw camera or outside its image.
    fn remap_row(p: &RowProjection, y: f64, row: &mut [RemapEntry]) => remap_row_with
}

/// Pixels [`remap_row`] takes at a time, in arrays on the stack the compiler can vectorise.
const REMAP_LANES: usize = 32;

#[inline(always)]
fn remap_row_with(p: &RowProjection, y: f64, row: &mut [RemapEntry]) {
    let [fx, fy, cx, cy] = p.rectified;
    let [m0, m1, m2] = p.rotation;
    let [k00, k01, k02, k11, k12] = p.k;
    let [k1, k2, p1, p2, k3] = p.dist;
    let (width, height) = p.size;
    let (last_x, last_y) = ((width - 1) as f64, (height - 1) as f64);
    let ry = (y - cy) / fy;
    for (c, chunk) in row.chunks_mut(REMAP_LANES).enumerate() {
        let (mut us, mut vs) = ([0.0f64; REMAP_LANES], [0.0f64; REMAP_LANES]);
        for (i, (u, v)) in us.iter_mut().zip(vs.iter_mut()).enumerate() {
            // The ray of `rectified_ray`, turned by the rotation as nalgebra's product sums
            // it (column by column), then projected and distorted as
            // `Camera::project_camera` and `Camera::distort` do; NaN behind the camera.
            let rx = ((c * REMAP_LANES + i) as f64 - cx) / fx;
            let (px, py, pz) = (
                m0[0] * rx + m0[1] * ry + m0[2] * 1.0,
                m1[0] * rx + m1[1] * ry + m1[2] * 1.0,
                m2[0] * rx + m2[1] * ry + m2[2] * 1.0,
            );
            let (xn, yn) = (px / pz, py / pz);
            let r2 = xn * xn + yn * yn;
            let radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3));
            let xd = xn * radial + 2.0 * p1 * xn * yn + p2 * (r2 + 2.0 * xn * xn);
            let yd = yn * radial + p1 * (r2 + 2.0 * yn * yn) + 2.0 * p2 * xn * yn;
            let behind = pz <= 1e-9;
            *u = if behind { f64::NAN } else { k00 * xd + k01 * yd + k02 };
            *v = if behind { f64::NAN } else { k11 * yd + k12 };
        }
        // The entry without branches: the numbers of the obvious branching version (the
        // tests' `remap_entry`, the oracle), chosen by masks.
        let (mut index, mut frac_x, mut frac_y) = ([OUTSIDE; REMAP_LANES], [0u16; REMAP_LANES], [0u16; REMAP_LANES]);
        for i in 0..REMAP_LANES {
            let (u, v) = (us[i], vs[i]);
            let inside = u >= 0.0 && v >= 0.0 && u <= last_x && v <= last_y;
            let (fu, fv) = (u.floor(), v.floor());
            // x0 + 1 >= width, for x0 = floor(u) >= 0.
            let (edge_x, edge_y) = (fu >= last_x, fv >= last_y);
            let x0 = if edge_x { last_x - 1.0 } else { fu };
            let y0 = if edge_y { last_y - 1.0 } else { fv };
            let wx = if edge_x { 1.0 } else { u - fu } * FRAC_ONE as f64;
            let wy = if edge_y { 1.0 } else { v - fv } * FRAC_ONE as f64;
            index[i] = if inside { (y0 * width as f64 + x0) as u32 } else { OUTSIDE };
            frac_x[i] = if inside { round_non_negative(wx) as u16 } else { 0 };
            frac_y[i] = if inside { round_non_negative(wy) as u16 } else { 0 };
        }
        for (i, entry) in chunk.iter_mut().enumerate() {
            *entry = RemapEntry { index: index[i], frac_x: frac_x[i], frac_y: frac_y[i] };
        }
    }
}

/// `a.round()` for `a >= 0` (halves away from zero), in operations that vectorise:
/// `a - floor(a)` is exact.
#[inline(always)]
fn round_non_negative(a: f64) -> f64 {
    let f = a.floor();
    if a - f >= 0.5 {
        f + 1.0
    } else {
        f
    }
}

/// The rectified-left extent and disparities of the work volume where both cameras see it.
struct SeenRegion {
    x_min: f64,
    x_max: f64,
    y_min: f64,
    y_max: f64,
    d_min: f64,
    d_max: f64,
}

/// Walks raw-left rays through the work volume and keeps the points the right camera sees
/// too: their rectified-left and rectified-right columns, rows and disparities. Rays, not
/// the box's corners, because the box is usually wider than the field of view.
fn seen_work_volume(
    left: &Camera,
    right: &Camera,
    t_world_rect: &Isometry3<f64>,
    focal: f64,
    baseline: f64,
    wv: &WorkVolume,
) -> Option<SeenRegion> {
    let lo = Vector3::new(wv.x[0], wv.y[0], wv.z[0]);
    let hi = Vector3::new(wv.x[1], wv.y[1], wv.z[1]);
    let centre = left.centre();
    let mut seen = SeenRegion {
        x_min: f64::INFINITY,
        x_max: f64::NEG_INFINITY,
        y_min: f64::INFINITY,
        y_max: f64::NEG_INFINITY,
        d_min: f64::INFINITY,
        d_max: f64::NEG_INFINITY,
    };
    let samples = |n: usize| (0..n.div_ceil(COVERAGE_STEP) + 1).map(move |i| (i * COVERAGE_STEP).min(n - 1));
    for v in samples(left.height) {
        for u in samples(left.width) {
            let dir = left.t_world_camera.rotation * left.ray(u as f64, v as f64);
            let Some((t0, t1)) = ray_box(&centre, &dir, &lo, &hi) else { continue };
            for s in 0..COVERAGE_DEPTHS {
                let t = t0 + (t1 - t0) * s as f64 / (COVERAGE_DEPTHS - 1) as f64;
                let p = centre + dir * t;
                let Some(pr) = right.project(&p) else { continue };
                if !(pr.x >= 0.0
                    && pr.y >= 0.0
                    && pr.x <= (right.width - 1) as f64
                    && pr.y <= (right.height - 1) as f64)
                {
                    continue;
                }
                let q = t_world_rect.inverse_transform_point(&p);
                if q.z <= 1e-9 {
                    continue;
                }
                let (x, y) = (focal * q.x / q.z, focal * q.y / q.z);
                let d = focal * baseline / q.z;
                seen.x_min = seen.x_min.min(x - d);
                seen.x_max = seen.x_max.max(x);
                seen.y_min = seen.y_min.min(y);
                seen.y_max = seen.y_max.max(y);
                seen.d_min = seen.d_min.min(d);
                seen.d_max = seen.d_max.max(d);
            }
        }
    }
    seen.x_min.is_finite().then_some(seen)
}

/// Parameter interval [t0, t1] (t0 >= 0) where `origin + t dir` lies inside the box.
fn ray_box(origin: &Point3<f64>, dir: &Vector3<f64>, lo: &Vector3<f64>, hi: &Vector3<f64>) -> Option<(f64, f64)> {
    let (mut t0, mut t1) = (0.0f64, f64::INFINITY);
    for i in 0..3 {
        if dir[i].abs() < 1e-12 {
            if origin[i] < lo[i] || origin[i] > hi[i] {
                return None;
            }
            continue;
        }
        let a = (lo[i] - origin[i]) / dir[i];
        let b = (hi[i] - origin[i]) / dir[i];
        t0 = t0.max(a.min(b));
        t1 = t1.min(a.max(b));
    }
    (t0 <= t1 && t1.is_finite()).then_some((t0, t1))
}

/// Shrinks [a, b] about its middle to at most `max` long.
fn clamp_span(a: f64, b: f64, max: f64) -> (f64, f64) {
    if b - a <= max {
        (a, b)
    } else {
        let mid = 0.5 * (a + b);
        (mid - 0.5 * max, mid + 0.5 * max)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// A rig built by hand: rig origin `r` mm from W's origin at 30 deg polar angle, looking
    /// at it; cameras `baseline` apart, each toed in by `toe_in_deg` about its own y axis,
    /// with different intrinsics and distortion.
    fn rig(baseline: f64, toe_in_deg: f64, r: f64) -> Rig {
        let a = 30f64.to_radians();
        let eye = Point3::new(r * a.sin(), 0.0, r * a.cos());
        let z = -eye.coords.normalize();
        let x = Vector3::new(0.0, 1.0, 0.0);
        let y = z.cross(&x);
        let t_world_rig = Isometry3::from_parts(
            Translation3::from(eye.coords),
            UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(Matrix3::from_columns(&[x, y, z]))),
        );
        let camera = |side: f64, k: Matrix3<f64>, dist: [f64; 5]| {
            let t_rig_cam = Isometry3::from_parts(
                Translation3::new(side * baseline / 2.0, 0.0, 0.0),
                UnitQuaternion::from_axis_angle(&Vector3::y_axis(), -side * toe_in_deg.to_radians()),
            );
            Camera { width: 640, height: 480, k, dist, t_world_camera: t_world_rig * t_rig_cam }
        };
        Rig {
            left: camera(
                -1.0,
                Matrix3::new(812.0, 0.0, 322.0, 0.0, 809.0, 236.0, 0.0, 0.0, 1.0),
                [-0.12, 0.06, 0.001, -0.0006, 0.0],
            ),
            right: camera(
                1.0,
                Matrix3::new(815.0, 0.0, 317.5, 0.0, 813.0, 243.0, 0.0, 0.0, 1.0),
                [-0.09, 0.03, -0.0008, 0.0004, 0.01],
            ),
            projector: None,
        }
    }

    fn work_volume() -> WorkVolume {
        WorkVolume { x: [-260.0, 260.0], y: [-210.0, 210.0], z: [-5.0, 80.0] }
    }

    fn rigs() -> impl Iterator<Item = Rig> {
        [81.0, 120.0].into_iter().flat_map(|b| [0.0, 3.5, 8.0].into_iter().map(move |v| rig(b, v, 600.0)))
    }

    fn inside(cam: &Camera, p: &nalgebra::Point2<f64>) -> bool {
        p.x >= 0.0 && p.y >= 0.0 && p.x <= (cam.width - 1) as f64 && p.y <= (cam.height - 1) as f64
    }

    #[test]
    fn seen_points_share_a_row_and_give_back_their_depth() {
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        for rig in rigs() {
            let rect = Rectification::new(&rig, &work_volume()).unwrap();
            let cam = &rect.camera;
            let (d_lo, d_hi) = rect.disparity_range();
            let mut n = 0;
            while n < 300 {
                let p = Point3::new(
                    rng.random_range(-260.0..260.0),
                    rng.random_range(-210.0..210.0),
                    rng.random_range(-5.0..80.0),
                );
                let (Some(pl), Some(pr)) = (rig.left.project(&p), rig.right.project(&p)) else { continue };
                if !(inside(&rig.left, &pl) && inside(&rig.right, &pr)) {
                    continue;
                }
                n += 1;
                let (ul, vl) = rect.raw_to_rectified(true, pl.x, pl.y);
                let (ur, vr) = rect.raw_to_rectified(false, pr.x, pr.y);
                assert!((vl - vr).abs() < 0.05, "rows differ by {}", vl - vr);
                let z = cam.t_world_rectified.inverse_transform_point(&p).z;
                let d = ul - ur;
                let z_est = cam.focal() * cam.baseline / d;
                assert!(((z_est - z) / z).abs() < 1e-3, "depth {z_est} vs {z}");
                let (u, v, _) = cam.project(&p).unwrap();
                assert!((u - ul).abs() < 0.01 && (v - vl).abs() < 0.01);
                // The canvas holds the point in both views and the range holds its disparity.
                assert!(
                    ul >= 0.0
                        && ur >= 0.0
                        && ul <= (cam.width - 1) as f64
                        && vl >= 0.0
                        && vl <= (cam.height - 1) as f64
                );
                assert!(d >= d_lo as f64 && d <= d_hi as f64, "disparity {d} outside {d_lo}..{d_hi}");
                let back = rect.rectified_to_raw(true, ul, vl).unwrap();
                assert!((back.0 - pl.x).abs() < 1e-3 && (back.1 - pl.y).abs() < 1e-3);
            }
            assert!(cam.width < 2 * 640 && cam.height < 2 * 480, "{}x{}", cam.width, cam.height);
        }
    }

    /// Grey level of a smooth texture on the table plane z = 0 (periods of ~10-20 px).
    fn texture(p: &Point3<f64>) -> f64 {
        128.0 + 50.0 * (0.35 * p.x + 0.1 * p.y).sin() + 40.0 * (0.27 * p.y - 0.12 * p.x + 1.0).sin()
    }

    fn on_table(origin: Point3<f64>, dir: Vector3<f64>) -> Option<Point3<f64>> {
        let t = -origin.z / dir.z;
        (t > 0.0).then(|| origin + dir * t)
    }

    #[test]
    fn rectified_images_agree_with_direct_projection() {
        for rig in [rig(81.0, 3.5, 600.0), rig(120.0, 8.0, 600.0)] {
            let rect = Rectification::new(&rig, &work_volume()).unwrap();
            let cam = &rect.camera;
            for (is_left, raw_cam) in [(true, &rig.left), (false, &rig.right)] {
                let mut raw = GrayImage::new(raw_cam.width, raw_cam.height, 0);
                for v in 0..raw.height {
                    for u in 0..raw.width {
                        let dir = raw_cam.t_world_camera.rotation * raw_cam.ray(u as f64, v as f64);
                        let p = on_table(raw_cam.centre(), dir).unwrap();
                        raw.set(u, v, texture(&p).round() as u8);
                    }
                }
                let mut out = GrayImage::default();
                if is_left {
                    rect.rectify_left(&raw, &mut out);
                } else {
                    rect.rectify_right(&raw, &mut out);
                }
                assert_eq!((out.width, out.height), (cam.width, cam.height));
                let (mut sum, mut n, mut worst) = (0.0, 0usize, 0.0f64);
                for y in 0..cam.height {
                    for x in 0..cam.width {
                        let Some((u, v)) = rect.rectified_to_raw(is_left, x as f64, y as f64) else { continue };
                        if !(u >= 1.0 && v >= 1.0 && u <= raw.width as f64 - 2.0 && v <= raw.height as f64 - 2.0) {
                            continue;
                        }
                        let ray = rect.camera.t_world_rectified.rotation * rectified_ray(cam, x as f64, y as f64);
                        let centre = if is_left { raw_cam.centre() } else { rig.right.centre() };
                        let p = on_table(centre, ray).unwrap();
                        let e = (out.get(x, y) as f64 - texture(&p)).abs();
                        sum += e;
                        worst = worst.max(e);
                        n += 1;
                    }
                }
                assert!(n > cam.width * cam.height / 2, "only {n} pixels inside");
                assert!(sum / (n as f64) < 1.0 && worst < 6.0, "mean {} worst {worst}", sum / n as f64);
                // Beyond the raw image the canvas is black.
                let outside = (0..cam.height).flat_map(|y| (0..cam.width).map(move |x| (x, y))).filter(|&(x, y)| {
                    rect.rectified_to_raw(is_left, x as f64, y as f64)
                        .is_none_or(|(u, v)| u < -1.0 || v < -1.0 || u > raw.width as f64 || v > raw.height as f64)
                });
                for (x, y) in outside {
                    assert_eq!(out.get(x, y), 0);
                }
            }
        }
    }

    #[test]
    fn disparity_truth_matches_the_plane() {
        let rig = rig(81.0, 3.5, 600.0);
        let rect = Rectification::new(&rig, &work_volume()).unwrap();
        let cam = &rect.camera;
        let left = &rig.left;
        let mut depth = FloatImage::new(left.width, left.height, f32::INFINITY);
        for v in 0..left.height {
            for u in 0..left.width {
                // A tilted plane through the table centre, raised 20 mm.
                let ray = left.ray(u as f64, v as f64);
                let n = Vector3::new(0.1, -0.05, 1.0).normalize();
                let o = left.t_world_camera.inverse_transform_point(&Point3::new(0.0, 0.0, 20.0));
                let n_cam = left.t_world_camera.rotation.inverse() * n;
                let t = o.coords.dot(&n_cam) / ray.dot(&n_cam);
                depth.set(u, v, t as f32);
            }
        }
        let mut truth = FloatImage::default();
        rect.disparity_truth(left, &depth, &mut truth);
        let (mut n, mut worst) = (0, 0.0f64);
        for y in 0..cam.height {
            for x in 0..cam.width {
                let d = truth.get(x, y);
                if !d.is_finite() {
                    continue;
                }
                let ray = cam.t_world_rectified.rotation * rectified_ray(cam, x as f64, y as f64);
                let o = cam.t_world_rectified.translation.vector;
                let n_w = Vector3::new(0.1, -0.05, 1.0).normalize();
                let t = (Vector3::new(0.0, 0.0, 20.0) - o).dot(&n_w) / ray.dot(&n_w);
                let expect = cam.focal() * cam.baseline / t;
                worst = worst.max((d as f64 - expect).abs());
                n += 1;
            }
        }
        assert!(n > 640 * 480 * 8 / 10, "only {n} truth pixels");
        assert!(worst < 0.01, "worst truth error {worst} px");
    }

    /// The entry of raw position (u, v) in a raw image of `(width, height)`, `None` outside it.
    fn remap_entry((width, height): (usize, usize), u: f64, v: f64) -> Option<RemapEntry> {
        let inside = u >= 0.0 && v >= 0.0 && u <= (width - 1) as f64 && v <= (height - 1) as f64;
        if !inside {
            return None;
        }
        // The last column and row sample with a zero weight on a neighbour that would be
        // outside: move one pixel in and put the weight at 1.
        let (mut x0, mut fx) = (u.floor() as usize, u - u.floor());
        let (mut y0, mut fy) = (v.floor() as usize, v - v.floor());
        if x0 + 1 >= width {
            x0 = width - 2;
            fx = 1.0;
        }
        if y0 + 1 >= height {
            y0 = height - 2;
            fy = 1.0;
        }
        Some(RemapEntry {
            index: (y0 * width + x0) as u32,
            frac_x: (fx * FRAC_ONE as f64).round() as u16,
            frac_y: (fy * FRAC_ONE as f64).round() as u16,
        })
    }

    /// The table as the obvious pixel-by-pixel projection gives it.
    fn remap_table_by_pixel(cam: &RectifiedCamera, raw: &Camera, r_raw_rect: &Rotation3<f64>) -> Vec<RemapEntry> {
        let mut map = Vec::new();
        for y in 0..cam.height {
            for x in 0..cam.width {
                let entry = raw_of_rectified(cam, raw, r_raw_rect, x as f64, y as f64)
                    .and_then(|(u, v)| remap_entry((raw.width, raw.height), u, v));
                map.push(entry.unwrap_or(RemapEntry { index: OUTSIDE, frac_x: 0, frac_y: 0 }));
            }
        }
        map
    }

    #[test]
    fn row_tables_match_the_pixel_by_pixel_projection_to_the_bit() {
        let mut behind_rig = rig(81.0, 3.5, 600.0);
        // Cameras turned so part of the canvas lies behind them: those entries are outside.
        let turn = UnitQuaternion::from_axis_angle(&Vector3::y_axis(), 80f64.to_radians());
        behind_rig.right.t_world_camera.rotation = turn * behind_rig.right.t_world_camera.rotation;
        let ideal = {
            let mut r = rig(120.0, 8.0, 600.0);
            r.left.dist = [0.0; 5];
            r.right.dist = [0.0; 5];
            r
        };
        for rig in rigs().chain([ideal]) {
            let rect = Rectification::new(&rig, &work_volume()).unwrap();
            let (l, r) = (&rect.left, &rect.right);
            assert!(rect.map_left == remap_table_by_pixel(&rect.camera, l, &rect.r_left_rect));
            assert!(rect.map_right == remap_table_by_pixel(&rect.camera, r, &rect.r_right_rect));
            assert!(
                rect.map_left.iter().any(|e| e.index == OUTSIDE) && rect.map_left.iter().any(|e| e.index != OUTSIDE)
            );
        }
        let rect = Rectification::new(&rig(81.0, 3.5, 600.0), &work_volume()).unwrap();
        let r_behind = behind_rig.right.t_world_camera.rotation.to_rotation_matrix().inverse()
            * rect.camera.t_world_rectified.rotation.to_rotation_matrix();
        let table = remap_table(&rect.camera, &behind_rig.right, &r_behind);
        assert!(table == remap_table_by_pixel(&rect.camera, &behind_rig.right, &r_behind));
        let behind = (0..rect.camera.height)
            .flat_map(|y| (0..rect.camera.width).map(move |x| (x, y)))
            .filter(|&(x, y)| {
                raw_of_rectified(&rect.camera, &behind_rig.right, &r_behind, x as f64, y as f64).is_none()
            })
            .count();
        assert!(behind > 0, "expected part of the canvas behind the turned camera");
    }

    #[test]
    fn rig_that_cannot_see_the_work_volume_is_an_error() {
        let mut rig = rig(81.0, 0.0, 600.0);
        let away = Isometry3::translation(5000.0, 0.0, 0.0);
        rig.left.t_world_camera = away * rig.left.t_world_camera;
        rig.right.t_world_camera = away * rig.right.t_world_camera;
        let err = Rectification::new(&rig, &work_volume()).unwrap_err();
        assert_eq!(err.kind(), ErrorKind::Rig);
        let mut same = rig.clone();
        same.right.t_world_camera = same.left.t_world_camera;
        assert_eq!(Rectification::new(&same, &work_volume()).unwrap_err().kind(), ErrorKind::Rig);
    }
}
