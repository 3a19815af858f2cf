//! Lens distortion in rendering. The rasterizer draws pinhole views only (straight edges
//! stay straight), so a camera with distortion is drawn as a distortion-free canvas: the
//! same focal lengths, wide enough to hold every ray the real image sees, and each pixel of
//! the real image then takes its value from where its undistorted ray meets the canvas.
//! Grey levels are sampled bilinearly (a lens integrates light continuously); depth and
//! object ids take the nearest canvas pixel, since averaging them would invent surfaces.
//! The map from image pixels to canvas positions is built once per camera.

use camplace_estimator::geometry::Camera;
use rayon::prelude::*;

/// Pixels the canvas reaches beyond the outermost ray, so bilinear samples stay inside.
const CANVAS_MARGIN: f64 = 2.0;
/// The widest canvas side as a multiple of the image's: a lens that bends rays further out
/// than this is refused by the cell's check of `camera_dist` long before.
const MAX_CANVAS_SCALE: f64 = 4.0;
/// Rows per task of parallel work.
const ROWS_PER_TASK: usize = 16;

/// Where each pixel of a distorted image lies on its distortion-free canvas.
#[derive(Debug, Clone, PartialEq)]
pub struct LensWarp {
    width: usize,
    height: usize,
    canvas_width: usize,
    canvas_height: usize,
    /// Per image pixel: the canvas pixel at the top left of its bilinear cell and the
    /// weights of the right and lower neighbours; `u32::MAX` when the ray misses the canvas.
    cells: Vec<(u32, [f32; 2])>,
}

impl LensWarp {
    /// For a camera with distortion, its distortion-free canvas camera (same pose) and the
    /// warp from canvas to image; `None` for a distortion-free camera, drawn directly.
    pub fn new(camera: &Camera) -> Option<(Camera, LensWarp)> {
        if camera.is_ideal() {
            return None;
        }
        let (w, h) = (camera.width, camera.height);
        let ideal = |u: f64, v: f64| -> (f64, f64) {
            let r = camera.ray(u, v);
            let k = &camera.k;
            (k[(0, 0)] * r.x + k[(0, 1)] * r.y + k[(0, 2)], k[(1, 1)] * r.y + k[(1, 2)])
        };
        // The image's border bounds the canvas (the distortion is one-to-one over the image).
        let (mut lo, mut hi) = ((0.0f64, 0.0f64), ((w - 1) as f64, (h - 1) as f64));
        let border = (0..w).flat_map(|x| [(x, 0), (x, h - 1)]).chain((0..h).flat_map(|y| [(0, y), (w - 1, y)]));
        for (x, y) in border {
            let (u, v) = ideal(x as f64, y as f64);
            lo = (lo.0.min(u), lo.1.min(v));
            hi = (hi.0.max(u), hi.1.max(v));
        }
        let limit = |n: usize| (MAX_CANVAS_SCALE - 1.0) / 2.0 * n as f64;
        let left = (-lo.0 + CANVAS_MARGIN).clamp(0.0, limit(w)).ceil();
        let top = (-lo.1 + CANVAS_MARGIN).clamp(0.0, limit(h)).ceil();
        let right = (hi.0 - (w - 1) as f64 + CANVAS_MARGIN).clamp(0.0, limit(w)).ceil();
        let bottom = (hi.1 - (h - 1) as f64 + CANVAS_MARGIN).clamp(0.0, limit(h)).ceil();
        let (cw, ch) = (w + (left + right) as usize, h + (top + bottom) as usize);
        let mut k = camera.k;
        k[(0, 2)] += left;
        k[(1, 2)] += top;
        let canvas = Camera { width: cw, height: ch, k, dist: [0.0; 5], t_world_camera: camera.t_world_camera };
        let mut cells = vec![(u32::MAX, [0.0f32; 2]); w * h];
        cells.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
            for (x, cell) in row.iter_mut().enumerate() {
                let (u, v) = ideal(x as f64, y as f64);
                let (cu, cv) = (u + left, v + top);
                let (fu, fv) = (cu.floor(), cv.floor());
                if fu >= 0.0 && fv >= 0.0 && fu + 1.0 < cw as f64 && fv + 1.0 < ch as f64 {
                    *cell = ((fv as usize * cw + fu as usize) as u32, [(cu - fu) as f32, (cv - fv) as f32]);
                }
            }
        });
        Some((canvas, LensWarp { width: w, height: h, canvas_width: cw, canvas_height: ch, cells }))
    }

    /// The canvas's width and height, pixels.
    #[cfg(test)]
    pub fn canvas_size(&self) -> (usize, usize) {
        (self.canvas_width, self.canvas_height)
    }

    /// The image's grey levels from the canvas's, bilinearly; 0 where a ray misses it.
    pub fn warp_linear(&self, canvas: &[f32], image: &mut [f32]) {
        let cw = self.canvas_width;
        image
            .par_chunks_mut(self.width * ROWS_PER_TASK)
            .zip(self.cells.par_chunks(self.width * ROWS_PER_TASK))
            .for_each(|(out, cells)| {
                for (o, &(i, [a, b])) in out.iter_mut().zip(cells) {
                    *o = if i == u32::MAX {
                        0.0
                    } else {
                        let i = i as usize;
                        let top = canvas[i] + a * (canvas[i + 1] - canvas[i]);
                        let bottom = canvas[i + cw] + a * (canvas[i + cw + 1] - canvas[i + cw]);
                        top + b * (bottom - top)
                    };
                }
            });
    }

    /// The image's values from the canvas's nearest pixel; `missed` where a ray misses it.
    pub fn warp_nearest<T: Copy + Send + Sync>(&self, canvas: &[T], image: &mut [T], missed: T) {
        let cw = self.canvas_width;
        image
            .par_chunks_mut(self.width * ROWS_PER_TASK)
            .zip(self.cells.par_chunks(self.width * ROWS_PER_TASK))
            .for_each(|(out, cells)| {
                for (o, &(i, [a, b])) in out.iter_mut().zip(cells) {
                    *o = if i == u32::MAX {
                        missed
                    } else {
                        canvas[i as usize + (a >= 0.5) as usize + if b >= 0.5 { cw } else { 0 }]
                    };
                }
            });
    }

    /// Image width and height, pixels.
    pub fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Isometry3, Matrix3, Point3};

    /// A camera matrix with its principal point moved by `(dx, dy)` pixels.
    fn shifted(k: &Matrix3<f64>, dx: f64, dy: f64) -> Matrix3<f64> {
        let mut k = *k;
        k[(0, 2)] += dx;
        k[(1, 2)] += dy;
        k
    }

    fn camera(dist: [f64; 5]) -> Camera {
        let mut c = Camera::ideal(320, 240, 300.0, Isometry3::identity());
        c.k[(0, 2)] += 3.5;
        c.k[(1, 2)] -= 2.0;
        c.dist = dist;
        c
    }

    #[test]
    fn an_ideal_camera_needs_no_warp() {
        assert!(LensWarp::new(&camera([0.0; 5])).is_none());
    }

    #[test]
    fn the_canvas_holds_every_ray_and_keeps_the_focal_lengths() {
        for dist in [[-0.3, 0.1, 0.001, -0.002, 0.0], [0.2, 0.05, 0.0, 0.0, 0.0]] {
            let cam = camera(dist);
            let (canvas, warp) = LensWarp::new(&cam).unwrap();
            assert_eq!(canvas.k[(0, 0)], cam.k[(0, 0)]);
            assert!(canvas.is_ideal());
            assert!(warp.cells.iter().all(|c| c.0 != u32::MAX), "{dist:?}: a ray misses the canvas");
            let (cw, ch) = warp.canvas_size();
            assert_eq!((cw, ch), (canvas.width, canvas.height));
            let dx = canvas.k[(0, 2)] - cam.k[(0, 2)];
            let dy = canvas.k[(1, 2)] - cam.k[(1, 2)];
            assert_eq!(canvas.k, shifted(&cam.k, dx, dy));
        }
    }

    /// A world point seen by the distorted camera at pixel p is drawn on the canvas where
    /// the canvas camera projects it, so the warp must bring it back to p.
    #[test]
    fn warping_a_canvas_puts_each_point_where_the_distorted_camera_sees_it() {
        let cam = camera([-0.25, 0.08, 0.0015, -0.001, 0.0]);
        let (canvas, warp) = LensWarp::new(&cam).unwrap();
        // The canvas shows a smooth function of the world point on the plane z = 1000 mm.
        let f = |p: &Point3<f64>| (p.x * 0.01).sin() * 50.0 + p.y * 0.05 + 100.0;
        let mut values = vec![0.0f32; canvas.width * canvas.height];
        for y in 0..canvas.height {
            for x in 0..canvas.width {
                values[y * canvas.width + x] = f(&canvas.back_project(x as f64, y as f64, 1000.0)) as f32;
            }
        }
        let mut image = vec![0.0f32; cam.width * cam.height];
        warp.warp_linear(&values, &mut image);
        let mut worst = 0.0f64;
        for y in (0..cam.height).step_by(7) {
            for x in (0..cam.width).step_by(7) {
                let want = f(&cam.back_project(x as f64, y as f64, 1000.0));
                worst = worst.max((image[y * cam.width + x] as f64 - want).abs());
            }
        }
        // Bilinear interpolation of a function that changes by at most ~2 per canvas pixel.
        assert!(worst < 0.05, "largest difference {worst}");
        let ids: Vec<u32> = (0..values.len() as u32).collect();
        let mut nearest = vec![0u32; image.len()];
        warp.warp_nearest(&ids, &mut nearest, u32::MAX);
        for y in (0..cam.height).step_by(11) {
            for x in (0..cam.width).step_by(11) {
                let i = nearest[y * cam.width + x] as usize;
                let (cx, cy) = ((i % canvas.width) as f64, (i / canvas.width) as f64);
                let p = canvas.back_project(cx, cy, 1000.0);
                let q = cam.project(&p).unwrap();
                assert!((q.x - x as f64).hypot(q.y - y as f64) < 0.75, "({x}, {y}) takes ({cx}, {cy}) seen at {q}");
            }
        }
    }
}
