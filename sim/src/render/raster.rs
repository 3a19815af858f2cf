//! The z-buffer rasterizer: scene triangles into a pinhole view's per-pixel nearest
//! triangle and inverse depth, for the cameras (their G-buffers) and for the projector and
//! the lamp (their shadow maps). It owns the view geometry (inverse-depth planes,
//! plane-induced homographies to other views); how a pixel is lit is shade.rs's business.
//!
//! Pixel centres sit at integer coordinates (the convention of `Camera`). A pixel belongs
//! to a triangle when its centre is inside, or on a top or left edge (the top-left rule),
//! so two triangles sharing an edge never both claim a pixel. Inverse depth 1/z is affine
//! over the image of a planar triangle, which makes the interpolated depth exact under
//! perspective. Triangles are clipped at a near plane. Rows are cut into bands drawn in
//! parallel; every band visits the triangles in scene order and a nearer triangle must be
//! strictly nearer to win, so the result does not depend on the thread count.

use camplace_estimator::{geometry::Camera, Error as EstimatorError, ErrorKind};
use nalgebra::{Isometry3, Matrix3, Point3, Vector3};
use rayon::prelude::*;

use crate::scene::{SceneTriangle, ID_TABLE};
use crate::Result;

/// The triangle index of a pixel that sees nothing.
pub const NO_TRIANGLE: u32 = u32::MAX;
/// Near clipping distance along the view's z axis, mm.
pub const NEAR_MM: f64 = 1.0;
/// Rows per band of parallel work: a few dozen bands keep two to eight threads busy.
const BAND_ROWS: usize = 16;
/// log2 of the side of the square tiles whose occupancy `ZBuffer::lookup` checks first.
const TILE_SHIFT: usize = 3;

/// A distortion-free pinhole view (camera, projector or lamp) that triangles are drawn into.
#[derive(Debug, Clone, PartialEq)]
pub struct View {
    /// Image width, pixels.
    pub width: usize,
    /// Image height, pixels.
    pub height: usize,
    /// Intrinsic matrix.
    pub k: Matrix3<f64>,
    /// Its inverse.
    pub k_inv: Matrix3<f64>,
    /// View frame -> world.
    pub t_world_view: Isometry3<f64>,
    /// World -> view frame.
    pub t_view_world: Isometry3<f64>,
}

impl View {
    /// The view of a camera; a camera with lens distortion is refused, because straight
    /// edges would no longer project to straight lines.
    pub fn new(camera: &Camera) -> Result<View> {
        if !camera.is_ideal() {
            return Err(
                EstimatorError::new(ErrorKind::Rig, "the renderer needs cameras without lens distortion").into()
            );
        }
        let k_inv = camera
            .k
            .try_inverse()
            .filter(|m| m.iter().all(|v| v.is_finite()))
            .ok_or_else(|| EstimatorError::new(ErrorKind::Rig, "camera matrix K is not invertible"))?;
        if camera.width == 0 || camera.height == 0 {
            return Err(EstimatorError::new(ErrorKind::Rig, "camera image is empty").into());
        }
        Ok(View {
            width: camera.width,
            height: camera.height,
            k: camera.k,
            k_inv,
            t_world_view: camera.t_world_camera,
            t_view_world: camera.t_world_camera.inverse(),
        })
    }

    /// Centre of projection, world mm.
    pub fn centre(&self) -> Point3<f64> {
        Point3::from(self.t_world_view.translation.vector)
    }

    /// World direction of the unit-depth ray through pixel (x, y) is `r[0] x + r[1] y + r[2]`.
    pub fn world_ray_coefficients(&self) -> [Vector3<f64>; 3] {
        let m = self.t_world_view.rotation.to_rotation_matrix().matrix() * self.k_inv;
        [m.column(0).into_owned(), m.column(1).into_owned(), m.column(2).into_owned()]
    }
}

fn inverse_depth_plane(k_inv: &Matrix3<f64>, p: &[Point3<f64>; 3]) -> Option<[f64; 3]> {
    let n = (p[1] - p[0]).cross(&(p[2] - p[0]));
    let d = n.dot(&p[0].coords);
    let scale = n.norm() * p.iter().map(|q| q.coords.norm()).fold(0.0, f64::max);
    let through_centre = d.abs().partial_cmp(&(1e-9 * scale)) != Some(std::cmp::Ordering::Greater);
    if through_centre {
        return None;
    }
    // A point X = z K^-1 (x, y, 1) on the plane n.X = d has 1/z = n.K^-1 (x, y, 1) / d.
    let c = k_inv.transpose() * n / d;
    Some([c.x, c.y, c.z])
}

/// One clipped, projected triangle ready to be filled.
#[derive(Debug, Clone, Copy)]
struct ScreenTriangle {
    /// Per edge: the start vertex (x, y) and the inward gradient (a, b) of the edge function
    /// E = a (x - x0) + b (y - y0), positive inside.
    edges: [[f64; 4]; 3],
    top_left: [bool; 3],
    /// Inclusive pixel bounds, clamped to the image.
    x0: usize,
    x1: usize,
    y0: usize,
    y1: usize,
    plane: [f64; 3],
    source: u32,
}

/// Per pixel, the nearest triangle and its inverse depth, with each drawn triangle's
/// inverse-depth plane; buffers are sized once and reused scene after scene.
#[derive(Debug, Clone, Default)]
pub struct ZBuffer {
    /// Image width, pixels.
    pub width: usize,
    /// Image height, pixels.
    pub height: usize,
    /// 1/z per pixel, 1/mm; 0 where nothing is seen.
    pub inverse_depth: Vec<f32>,
    /// Index of the scene triangle seen at each pixel, `NO_TRIANGLE` where nothing is.
    pub triangle: Vec<u32>,
    /// Inverse-depth plane of every scene triangle in this view (zeros when not drawn).
    pub planes: Vec<[f64; 3]>,
    screen: Vec<ScreenTriangle>,
    /// Per band, whether it holds anything; clean bands that stay empty are not touched,
    /// which makes shadow maps (mostly empty) cheap.
    dirty: Vec<bool>,
    /// Per tile, whether some drawn triangle's bounds reach it: a shadow test at a pixel
    /// of an empty tile need not touch the (large, cache-missing) per-pixel arrays.
    occupied: Vec<bool>,
    /// Tiles per row.
    tiles_x: usize,
}

/// What a light's shadow map holds at a point: `ZBuffer::lookup`'s answer.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MapPixel {
    /// The point falls outside the map.
    Outside,
    /// Nothing is drawn there.
    Empty,
    /// The index of the nearest pixel, which may hold a triangle.
    Pixel(usize),
}

impl ZBuffer {
    /// An empty buffer for a `width` x `height` view.
    pub fn new(width: usize, height: usize) -> ZBuffer {
        ZBuffer {
            width,
            height,
            inverse_depth: vec![0.0; width * height],
            triangle: vec![NO_TRIANGLE; width * height],
            planes: Vec::new(),
            screen: Vec::new(),
            dirty: vec![true; height.div_ceil(BAND_ROWS)],
            occupied: vec![false; (width.div_ceil(1 << TILE_SHIFT)) * height.div_ceil(1 << TILE_SHIFT)],
            tiles_x: width.div_ceil(1 << TILE_SHIFT),
        }
    }

    /// Draws `triangles` seen from `view` (whose size must be this buffer's); with
    /// `occluders_only` the table is left out, as nothing lies below it to be shadowed.
    pub fn rasterize(&mut self, view: &View, triangles: &[SceneTriangle], occluders_only: bool) {
        debug_assert!(view.width == self.width && view.height == self.height);
        self.planes.clear();
        self.planes.resize(triangles.len(), [0.0; 3]);
        self.screen.clear();
        for (index, tri) in triangles.iter().enumerate() {
            if occluders_only && tri.id == ID_TABLE {
                continue;
            }
            let p = tri.vertices.map(|v| view.t_view_world * v);
            let Some(plane) = inverse_depth_plane(&view.k_inv, &p) else { continue };
            self.planes[index] = plane;
            let (clipped, n) = clip_near(&p);
            if n < 3 {
                continue;
            }
            let s = clipped.map(|q| {
                let k = &view.k;
                let (x, y) = (q.x / q.z, q.y / q.z);
                [k[(0, 0)] * x + k[(0, 1)] * y + k[(0, 2)], k[(1, 1)] * y + k[(1, 2)]]
            });
            for j in 1..n - 1 {
                if let Some(st) = setup([s[0], s[j], s[j + 1]], plane, index as u32, self.width, self.height) {
                    self.screen.push(st);
                }
            }
        }
        self.occupied.fill(false);
        for st in &self.screen {
            if st.x0 > st.x1 {
                continue;
            }
            for ty in st.y0 >> TILE_SHIFT..=st.y1 >> TILE_SHIFT {
                let row = ty * self.tiles_x;
                self.occupied[row + (st.x0 >> TILE_SHIFT)..=row + (st.x1 >> TILE_SHIFT)].fill(true);
            }
        }
        let w = self.width;
        let screen = &self.screen;
        self.inverse_depth
            .par_chunks_mut(w * BAND_ROWS)
            .zip(self.triangle.par_chunks_mut(w * BAND_ROWS))
            .zip(self.dirty.par_iter_mut())
            .enumerate()
            .for_each(|(band, ((z, t), dirty))| {
                let y0 = band * BAND_ROWS;
                let y1 = y0 + z.len() / w;
                let touched = screen.iter().any(|st| st.y0 < y1 && st.y1 >= y0);
                if *dirty || touched {
                    z.fill(0.0);
                    t.fill(NO_TRIANGLE);
                }
                if touched {
                    fill_band(screen, w, y0, y1, z, t);
                }
                *dirty = touched;
            });
    }

    /// Depth along the view's z axis at pixel (x, y), mm; +inf where nothing is seen.
    #[cfg(test)]
    pub fn depth(&self, x: usize, y: usize) -> f64 {
        let t = self.triangle[y * self.width + x];
        if t == NO_TRIANGLE {
            return f64::INFINITY;
        }
        let [a, b, c] = self.planes[t as usize];
        1.0 / (a * x as f64 + b * y as f64 + c)
    }

    /// What the buffer holds at the pixel nearest to (u, v).
    #[inline]
    pub fn lookup(&self, u: f64, v: f64) -> MapPixel {
        let (x, y) = (u + 0.5, v + 0.5);
        if !(x >= 0.0 && y >= 0.0 && x < self.width as f64 && y < self.height as f64) {
            return MapPixel::Outside;
        }
        let (x, y) = (x as usize, y as usize);
        if self.occupied[(y >> TILE_SHIFT) * self.tiles_x + (x >> TILE_SHIFT)] {
            MapPixel::Pixel(y * self.width + x)
        } else {
            MapPixel::Empty
        }
    }

    /// The pixel index nearest to (u, v), `None` outside the image.
    #[cfg(test)]
    #[inline]
    pub fn nearest(&self, u: f64, v: f64) -> Option<usize> {
        // For the non-negative values let through, truncation is the floor (and cheaper,
        // as `floor` is a library call without SSE4.1); x < width iff floor(x) < width.
        let (x, y) = (u + 0.5, v + 0.5);
        if x >= 0.0 && y >= 0.0 && x < self.width as f64 && y < self.height as f64 {
            Some(y as usize * self.width + x as usize)
        } else {
            None
        }
    }
}

/// Clips a view-frame triangle to z >= NEAR_MM; returns the polygon (up to 4 corners).
fn clip_near(p: &[Point3<f64>; 3]) -> ([Point3<f64>; 4], usize) {
    let mut out = [Point3::origin(); 4];
    let mut n = 0;
    for i in 0..3 {
        let (a, b) = (p[i], p[(i + 1) % 3]);
        let (ina, inb) = (a.z >= NEAR_MM, b.z >= NEAR_MM);
        if ina {
            out[n] = a;
            n += 1;
        }
        if ina != inb {
            let t = (NEAR_MM - a.z) / (b.z - a.z);
            let mut q = a + (b - a) * t;
            q.z = NEAR_MM;
            out[n] = q;
            n += 1;
        }
    }
    (out, n)
}

fn setup(v: [[f64; 2]; 3], plane: [f64; 3], source: u32, w: usize, h: usize) -> Option<ScreenTriangle> {
    let [a, mut b, mut c] = v;
    let area = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
    let degenerate = area.abs().partial_cmp(&1e-12) != Some(std::cmp::Ordering::Greater);
    if degenerate {
        return None;
    }
    if area < 0.0 {
        std::mem::swap(&mut b, &mut c);
    }
    let corners = [a, b, c];
    let mut edges = [[0.0; 4]; 3];
    let mut top_left = [false; 3];
    for i in 0..3 {
        let (p, q) = (corners[i], corners[(i + 1) % 3]);
        let (ga, gb) = (-(q[1] - p[1]), q[0] - p[0]);
        edges[i] = [p[0], p[1], ga, gb];
        top_left[i] = ga > 0.0 || (ga == 0.0 && gb > 0.0);
    }
    let (min_x, max_x) = (a[0].min(b[0]).min(c[0]), a[0].max(b[0]).max(c[0]));
    let (min_y, max_y) = (a[1].min(b[1]).min(c[1]), a[1].max(b[1]).max(c[1]));
    let (wf, hf) = (w as f64 - 1.0, h as f64 - 1.0);
    if max_x < 0.0 || max_y < 0.0 || min_x > wf || min_y > hf {
        return None;
    }
    Some(ScreenTriangle {
        edges,
        top_left,
        x0: min_x.ceil().max(0.0) as usize,
        x1: max_x.floor().min(wf) as usize,
        y0: min_y.ceil().max(0.0) as usize,
        y1: max_y.floor().min(hf) as usize,
        plane,
        source,
    })
}

camplace_estimator::multiversion! {
    /// Fills rows `y_begin..y_end` (the band held by `z` and `t`).
    fn fill_band(
        screen: &[ScreenTriangle],
        w: usize,
        y_begin: usize,
        y_end: usize,
        z: &mut [f32],
        t: &mut [u32],
    ) => fill_band_body
}

#[inline(always)]
fn fill_band_body(screen: &[ScreenTriangle], w: usize, y_begin: usize, y_end: usize, z: &mut [f32], t: &mut [u32]) {
    for st in screen {
        if st.y1 < y_begin || st.y0 >= y_end || st.x0 > st.x1 {
            continue;
        }
        let [pa, pb, pc] = st.plane;
        for y in st.y0.max(y_begin)..=st.y1.min(y_end - 1) {
            let fy = y as f64;
            // The span where every edge function is >= 0, widened by a pixel each side
            // so the exact test below decides the border pixels.
            let (mut lo, mut hi) = (st.x0 as f64, st.x1 as f64);
            let mut empty = false;
            // A row lying exactly on a horizontal edge needs the fill rule at every pixel.
            let mut on_edge = false;
            for &[ex, ey, ga, gb] in &st.edges {
                let r = gb * (fy - ey);
                if ga > 0.0 {
                    lo = lo.max(ex - r / ga);
                } else if ga < 0.0 {
                    hi = hi.min(ex - r / ga);
                } else if r < 0.0 {
                    empty = true;
                } else if r == 0.0 {
                    on_edge = true;
                }
            }
            if empty || lo > hi + 1.0 {
                continue;
            }
            let xs = ((lo.floor() - 1.0).max(st.x0 as f64)) as usize;
            let xe = ((hi.ceil() + 1.0).min(st.x1 as f64)) as usize;
            // Pixels a whole pixel inside the span are inside whatever the rounding.
            let (sure_lo, sure_hi) = if on_edge { (1.0, 0.0) } else { (lo + 1.0, hi - 1.0) };
            let row = (y - y_begin) * w;
            let plane = [pa, pb * fy, pc];
            let edge_pixel = |x: usize, z: &mut [f32], t: &mut [u32]| {
                let fx = x as f64;
                let inside = st.edges.iter().zip(st.top_left).all(|(&[ex, ey, ga, gb], tl)| {
                    let e = ga * (fx - ex) + gb * (fy - ey);
                    e > 0.0 || (e == 0.0 && tl)
                });
                if inside {
                    depth_run(plane, x, st.source, &mut z[row + x..=row + x], &mut t[row + x..=row + x]);
                }
            };
            // The pixels sure to be inside form one run (x >= sure_lo and x <= sure_hi); the
            // others on either side take the exact edge test.
            let first_sure = if sure_lo <= xs as f64 { xs } else { (sure_lo.ceil() as usize).min(xe + 1) };
            let end_sure =
                if sure_hi < first_sure as f64 { first_sure } else { (sure_hi.floor() as usize + 1).min(xe + 1) };
            for x in xs..first_sure {
                edge_pixel(x, z, t);
            }
            if end_sure > first_sure {
                let span = row + first_sure..row + end_sure;
                depth_run(plane, first_sure, st.source, &mut z[span.clone()], &mut t[span]);
            }
            for x in end_sure..=xe {
                edge_pixel(x, z, t);
            }
        }
    }
}

/// The depth test of the pixels `x0..` of one row over `z` and `t`: a pixel takes the
/// triangle `source` where its inverse depth, `pa x + pb_y + pc` from `[pa, pb_y, pc]`
/// (summed in that order, as every pixel's), is nearer. Without branches, so the run
/// fills in vector lanes.
#[inline(always)]
fn depth_run([pa, pb_y, pc]: [f64; 3], x0: usize, source: u32, z: &mut [f32], t: &mut [u32]) {
    for (j, (z, t)) in z.iter_mut().zip(t.iter_mut()).enumerate() {
        let iz = (pa * (x0 + j) as f64 + pb_y + pc) as f32;
        let nearer = iz > *z;
        *z = if nearer { iz } else { *z };
        *t = if nearer { source } else { *t };
    }
}

/// What one camera pixel sees, read from its z-buffer: the G-buffer of that camera (the
/// tests' view of a rendered frame).
#[cfg(test)]
#[derive(Debug, Clone, Copy)]
pub struct GBuffer<'a> {
    /// Its z-buffer, drawn from `triangles`.
    pub zbuffer: &'a ZBuffer,
    /// The scene's triangles.
    pub triangles: &'a [SceneTriangle],
}

#[cfg(test)]
impl GBuffer<'_> {
    /// The scene triangle seen at pixel (x, y).
    pub fn triangle(&self, x: usize, y: usize) -> Option<&SceneTriangle> {
        let t = self.zbuffer.triangle[y * self.zbuffer.width + x];
        self.triangles.get(t as usize)
    }

    /// Depth along the camera's z axis, mm; +inf where nothing is seen.
    pub fn depth(&self, x: usize, y: usize) -> f64 {
        self.zbuffer.depth(x, y)
    }

    /// Object id seen at (x, y); the table's id where nothing is seen.
    pub fn id(&self, x: usize, y: usize) -> u8 {
        self.triangle(x, y).map_or(ID_TABLE, |t| t.id)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::scenario::draw_scenario;
    use crate::scene::Objects;
    use camplace_config::{Cell, Vergence};
    use camplace_estimator::geometry::rig_for;
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// Distance along the unit-depth ray `dir` from `o` to triangle `t` (Moller-Trumbore).
    fn ray_hit(o: &Point3<f64>, dir: &Vector3<f64>, t: &[Point3<f64>; 3]) -> Option<f64> {
        let (e1, e2) = (t[1] - t[0], t[2] - t[0]);
        let p = dir.cross(&e2);
        let det = e1.dot(&p);
        if det.abs() < 1e-12 {
            return None;
        }
        let s = o - t[0];
        let u = s.dot(&p) / det;
        let q = s.cross(&e1);
        let v = dir.dot(&q) / det;
        let d = e2.dot(&q) / det;
        (u >= 0.0 && v >= 0.0 && u + v <= 1.0 && d > 0.0).then_some(d)
    }

    #[test]
    fn rasterizer_matches_a_ray_cast() {
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        for (k, verg) in [Vergence::Auto, Vergence::Degrees(0.0), Vergence::Degrees(3.5)].into_iter().enumerate() {
            let mut cell = Cell::default();
            cell.placement.vergence = verg;
            cell.placement.alpha = [32.0, 0.0, 50.0][k];
            let objects = Objects::from_cell(&cell).unwrap();
            let scene = draw_scenario(&cell, 2, k as u64).scene();
            let mut tris = Vec::new();
            objects.triangles(&scene, &mut tris);
            let rig = rig_for(&cell.placement, &cell.sensor);
            for cam in [&rig.left, &rig.right, rig.projector.as_ref().unwrap()] {
                let view = View::new(cam).unwrap();
                let mut zb = ZBuffer::new(view.width, view.height);
                zb.rasterize(&view, &tris, false);
                let (mut hits, mut checked) = (0, 0);
                while checked < 300 {
                    let x = rng.random_range(0..view.width);
                    let y = rng.random_range(0..view.height);
                    let dir = cam.t_world_camera.rotation * cam.ray(x as f64, y as f64);
                    let mut best: Option<(f64, u8)> = None;
                    for t in &tris {
                        if let Some(d) = ray_hit(&cam.centre(), &dir, &t.vertices) {
                            if best.is_none_or(|(b, _)| d < b) {
                                best = Some((d, t.id));
                            }
                        }
                    }
                    checked += 1;
                    let g = GBuffer { zbuffer: &zb, triangles: &tris };
                    match best {
                        None => assert!(g.depth(x, y).is_infinite(), "({x}, {y}) should see nothing"),
                        Some((d, id)) => {
                            hits += 1;
                            assert!((g.depth(x, y) - d).abs() < 0.01, "({x}, {y}): {} vs {d}", g.depth(x, y));
                            assert_eq!(g.id(x, y), id, "({x}, {y})");
                        }
                    }
                }
                assert!(hits > 200);
            }
        }
    }

    #[test]
    fn lookup_agrees_with_the_pixels() {
        let mut rng = ChaCha8Rng::seed_from_u64(6);
        let cell = Cell::default();
        let objects = Objects::from_cell(&cell).unwrap();
        let scene = draw_scenario(&cell, 3, 1).scene();
        let mut tris = Vec::new();
        objects.triangles(&scene, &mut tris);
        let rig = rig_for(&cell.placement, &cell.sensor);
        let view = View::new(rig.projector.as_ref().unwrap()).unwrap();
        let mut zb = ZBuffer::new(view.width, view.height);
        zb.rasterize(&view, &tris, true);
        let (mut empty, mut pixel) = (0, 0);
        for _ in 0..20_000 {
            let u = rng.random_range(-10.0..view.width as f64 + 10.0);
            let v = rng.random_range(-10.0..view.height as f64 + 10.0);
            match (zb.lookup(u, v), zb.nearest(u, v)) {
                (MapPixel::Outside, None) => {}
                (MapPixel::Empty, Some(i)) => {
                    assert_eq!(zb.triangle[i], NO_TRIANGLE, "({u}, {v})");
                    empty += 1;
                }
                (MapPixel::Pixel(i), Some(j)) => {
                    assert_eq!(i, j);
                    pixel += 1;
                }
                (a, b) => panic!("({u}, {v}): {a:?} vs {b:?}"),
            }
        }
        assert!(empty > 1000 && pixel > 100, "{empty} {pixel}");
    }

    #[test]
    fn near_clipping_keeps_the_part_in_front() {
        // One big floor triangle that reaches behind a low, tilted camera.
        let cam = Camera::ideal(
            64,
            48,
            50.0,
            camplace_estimator::geometry::look_at(Point3::new(0.0, 0.0, 10.0), Point3::new(100.0, 0.0, 0.0), 0.0),
        );
        let view = View::new(&cam).unwrap();
        let tri = crate::scene::SceneTriangle {
            vertices: [
                Point3::new(-1000.0, -1000.0, 0.0),
                Point3::new(1000.0, -1000.0, 0.0),
                Point3::new(0.0, 1000.0, 0.0),
            ],
            normal: Vector3::z(),
            albedo: 0.5,
            gloss: crate::scene::Gloss::MATTE,
            id: 0,
        };
        let mut zb = ZBuffer::new(64, 48);
        zb.rasterize(&view, &[tri], false);
        for y in 0..48 {
            for x in 0..64 {
                let dir = cam.t_world_camera.rotation * cam.ray(x as f64, y as f64);
                let want = ray_hit(&cam.centre(), &dir, &tri.vertices).unwrap_or(f64::INFINITY);
                let got = zb.depth(x, y);
                assert!(got == want || (got - want).abs() < 1e-6 * want, "({x}, {y}): {got} vs {want}");
            }
        }
    }

    #[test]
    fn shared_edges_are_drawn_once() {
        // A fan of triangles around a centre tiles a square; every pixel centre inside
        // belongs to exactly one of them.
        let cam = Camera::ideal(40, 40, 40.0, Isometry3::translation(0.0, 0.0, -100.0));
        let view = View::new(&cam).unwrap();
        let c = Point3::new(0.0, 0.0, 0.0);
        let ring = [(-30.0, -30.0), (30.0, -30.0), (30.0, 30.0), (-30.0, 30.0), (-30.0, -30.0)];
        let mut count = vec![0u32; 40 * 40];
        for i in 0..4 {
            let (a, b) = (ring[i], ring[i + 1]);
            let tri = crate::scene::SceneTriangle {
                vertices: [c, Point3::new(a.0, a.1, 0.0), Point3::new(b.0, b.1, 0.0)],
                normal: Vector3::z(),
                albedo: 0.5,
                gloss: crate::scene::Gloss::MATTE,
                id: 0,
            };
            let mut zb = ZBuffer::new(40, 40);
            zb.rasterize(&view, &[tri], false);
            for (n, t) in count.iter_mut().zip(&zb.triangle) {
                *n += (*t != NO_TRIANGLE) as u32;
            }
        }
        // The square spans pixels 8 ..= 31 (x = 19.5 + 0.4 X); its diagonals pass through
        // pixel centres, which the fill rule gives to one triangle only.
        for y in 0..40 {
            for x in 0..40 {
                let want = (8..=31).contains(&x) && (8..=31).contains(&y);
                assert_eq!(count[y * 40 + x], want as u32, "({x}, {y})");
            }
        }
    }
}
