//! The shading terms of one camera row: per pixel, from the triangle the z-buffer holds
//! there and the lights, the pattern-independent grey level, the projector's gain, its
//! image coordinates and blur, and the ground-truth depth and id (the formula is
//! `shade`'s).
//!
//! A row is taken in runs of pixels that see one triangle, at most [`RUN`] long, so every
//! per-triangle value is a constant of the run. Each run goes in passes: the geometry
//! (depth, surface point, the projector's and the lamp's image coordinates) and the light
//! (distances, cosines, glossy lobes) are straight-line f64 arithmetic the compiler runs in
//! vector lanes, the projector's blur levels too; only the shadow-map lookups and the rare
//! powers of a glossy lobe near its mirror direction go pixel by pixel (a lookup's tile
//! check skips the empty parts of a map without reading the map). Every pass does the IEEE
//! operations of the per-pixel formula in its order, so the terms are bit for bit those of
//! the one-pixel-at-a-time version kept for the tests.

// The passes index several fixed-size arrays by pixel: the shape the vectoriser turns into lanes.
#![allow(clippy::needless_range_loop)]

use nalgebra::{Matrix3, Point3, Vector3};

use crate::render::defocus::{level_weight, ThinLens, LEVELS};
use crate::render::raster::{MapPixel, View, ZBuffer, NO_TRIANGLE};
use crate::scene::{Gloss, SceneTriangle, ID_TABLE};

/// A point is in shadow only when the occluder is nearer to the light than this, mm.
pub const SHADOW_BIAS_MM: f64 = 1.0;

/// The lights of a scene as the shader sees them.
#[derive(Debug, Clone, Copy)]
pub struct Lights<'a> {
    /// Ambient light, units of full white.
    pub ambient: f64,
    /// Lamp strength, units of full white on a surface facing it.
    pub lamp_strength: f64,
    /// Lamp position, world mm.
    pub lamp_position: Point3<f64>,
    /// The lamp's view and shadow map; `None` when nothing can cast a lamp shadow.
    pub lamp_shadow: Option<(&'a View, &'a ZBuffer)>,
    /// The projector's view.
    pub projector: &'a View,
    /// The projector's shadow map.
    pub projector_shadow: &'a ZBuffer,
    /// Projector brightness on a surface facing it, units of full white.
    pub projector_gain: f64,
    /// The projector's lens, when its defocus is rendered, and the top level of the
    /// patterns' blur stacks.
    pub projector_lens: Option<(ThinLens, usize)>,
}

/// Longest run of pixels taken in one set of passes (their buffers, one set per row, live on
/// the stack).
const RUN: usize = 32;

/// 0, 1, 2, ... as f64: a run's pixel x is its first x plus these, exactly.
const OFFSETS: [f64; RUN] = {
    let mut offsets = [0.0; RUN];
    let mut i = 0;
    while i < RUN {
        offsets[i] = i as f64;
        i += 1;
    }
    offsets
};

/// `other.k (R k_inv + t plane)`, split so that one triangle's homography costs a rank-one
/// update instead of the products of rotation and intrinsic matrices.
pub(super) struct Homographies {
    /// `other.k R k_inv`.
    rotation: Matrix3<f64>,
    /// `other.k t`.
    translation: Vector3<f64>,
}

impl Homographies {
    pub(super) fn new(from: &View, to: &View) -> Homographies {
        let t = to.t_view_world * from.t_world_view;
        let r = t.rotation.to_rotation_matrix().into_inner();
        Homographies { rotation: to.k * r * from.k_inv, translation: to.k * t.translation.vector }
    }

    /// The rows of the homography of a surface with inverse-depth plane `plane`, as
    /// `View::homography_to` defines it.
    pub(super) fn for_plane(&self, plane: [f64; 3]) -> [[f64; 3]; 3] {
        let (m, t) = (&self.rotation, &self.translation);
        std::array::from_fn(|i| std::array::from_fn(|j| m[(i, j)] + t[i] * plane[j]))
    }
}

/// What the per-pixel work needs of one triangle, in one camera's pixel coordinates.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct TriangleTerms {
    /// Inverse-depth plane: 1/z = a x + b y + c.
    pub(super) plane: [f64; 3],
    /// Rows of the homography to the projector's homogeneous pixel.
    pub(super) h_projector: [[f64; 3]; 3],
    /// Rows of the homography to the lamp's shadow-map pixel (zeros without the map).
    pub(super) h_lamp: [[f64; 3]; 3],
    /// 255 albedo, grey levels.
    pub(super) albedo: f64,
    /// Unit normal turned towards the camera.
    pub(super) normal: [f64; 3],
    /// Glossy lobe.
    pub(super) gloss: Gloss,
    /// n.(lamp - p) with n turned towards the camera: the lamp lights the face only when
    /// positive (0 when the lamp is off).
    pub(super) lamp_facing: f64,
    /// n.(projector - p), likewise.
    pub(super) projector_facing: f64,
    /// Object id.
    pub(super) id: u8,
}

/// One image row of the outputs and the z-buffer's triangles.
pub(super) struct Row<'r> {
    pub(super) tri: &'r [u32],
    pub(super) base: &'r mut [f32],
    pub(super) projector: &'r mut [f32],
    pub(super) uv: &'r mut [[f32; 2]],
    pub(super) blur: &'r mut [(u32, f32)],
    pub(super) depth: &'r mut [f32],
    pub(super) ids: &'r mut [u8],
}

/// Everything the per-pixel work reads, shared by the threads.
pub(super) struct Context<'a> {
    pub(super) rays: [[f64; 3]; 3],
    pub(super) centre: [f64; 3],
    pub(super) lamp_position: [f64; 3],
    pub(super) projector_centre: [f64; 3],
    pub(super) terms: &'a [TriangleTerms],
    pub(super) triangles: &'a [SceneTriangle],
    pub(super) lights: &'a Lights<'a>,
}

camplace_estimator::multiversion! {
    /// [`Context::row`].
    pub(super) fn terms_row(ctx: &Context<'_>, fy: f64, row: Row<'_>) => terms_row_body
}

#[inline(always)]
fn terms_row_body(ctx: &Context<'_>, fy: f64, row: Row<'_>) {
    ctx.row(fy, row);
}

impl Context<'_> {
    /// The terms of every pixel of row `fy`, run by run.
    #[inline(always)]
    fn row(&self, fy: f64, row: Row<'_>) {
        let w = row.tri.len();
        let Row { tri, base, projector, uv, blur, depth, ids } = row;
        let (base, projector, uv, depth, ids) =
            (&mut base[..w], &mut projector[..w], &mut uv[..w], &mut depth[..w], &mut ids[..w]);
        let mut scratch = RunScratch::default();
        let mut x0 = 0;
        while x0 < w {
            let t = tri[x0];
            let end = (x0 + RUN).min(w);
            let x1 = x0 + 1 + tri[x0 + 1..end].iter().take_while(|&&u| u == t).count();
            let span = x0..x1;
            match self.terms.get(t as usize) {
                None => {
                    base[span.clone()].fill(0.0);
                    projector[span.clone()].fill(0.0);
                    depth[span.clone()].fill(f32::INFINITY);
                    ids[span].fill(ID_TABLE);
                }
                Some(tt) => {
                    let out = RunOut {
                        base: &mut base[span.clone()],
                        projector: &mut projector[span.clone()],
                        uv: &mut uv[span.clone()],
                        blur: if blur.is_empty() { &mut [] } else { &mut blur[span.clone()] },
                        depth: &mut depth[span.clone()],
                        ids: &mut ids[span],
                    };
                    self.run(fy, x0, t as usize, tt, out, &mut scratch);
                }
            }
            x0 = x1;
        }
    }

    /// The terms of a run of pixels from (`x0`, `fy`) that all see triangle `t`, its
    /// passes' values in `s` (each pass writes the lanes it reads later).
    #[inline(always)]
    fn run(&self, fy: f64, x0: usize, t: usize, tt: &TriangleTerms, out: RunOut<'_>, s: &mut RunScratch) {
        // Bounded by RUN in the compiler's eyes too, so that the passes carry no index checks.
        let n = out.base.len().min(RUN);
        let RunOut { base, projector, uv, blur, depth, ids } = out;
        let (base, projector, uv, depth, ids) =
            (&mut base[..n], &mut projector[..n], &mut uv[..n], &mut depth[..n], &mut ids[..n]);
        let RunScratch { geometry, to_camera, light, highlight, mask, cos, gain, q, reach, lobe, half, level } = s;
        let fx0 = x0 as f64;
        let l = self.lights;
        let [rx, ry, r0] = self.rays;
        // The unit-depth ray of pixel (x, fy) is ray_row + rx x.
        let ray_row: [f64; 3] = std::array::from_fn(|i| ry[i] * fy + r0[i]);
        let [a, b, c] = tt.plane;
        let b_fy = b * fy;
        for i in 0..n {
            let fx = fx0 + OFFSETS[i];
            let inv_z = a * fx + b_fy + c;
            let z = 1.0 / inv_z;
            geometry.inv_z[i] = inv_z;
            geometry.z[i] = z;
            for k in 0..3 {
                geometry.pos[k][i] = self.centre[k] + (ray_row[k] + rx[k] * fx) * z;
            }
        }
        let glossy = tt.gloss.specular > 0.0;
        if glossy {
            for i in 0..n {
                let v = unit(sub(&self.centre, &geometry.at(i)));
                for k in 0..3 {
                    to_camera[k][i] = v[k];
                }
            }
        }
        light[..n].fill(l.ambient);
        highlight[..n].fill(0.0);
        if tt.lamp_facing > 0.0 {
            let visible = &mut *mask;
            visible[..n].fill(true);
            if let Some((_, map)) = l.lamp_shadow {
                // Outside the lamp's map there is nothing that could shadow.
                image_coordinates(&tt.h_lamp, fx0, fy, n, q);
                for i in 0..n {
                    let qz = q.qz[i];
                    visible[i] = qz <= 0.0
                        || match map.lookup(q.u[i], q.v[i]) {
                            MapPixel::Outside | MapPixel::Empty => true,
                            MapPixel::Pixel(p) => self.unshadowed(map, p, t, qz * geometry.z[i]),
                        };
                }
            }
            distances(&self.lamp_position, geometry, n, reach);
            for i in 0..n {
                cos[i] = tt.lamp_facing / reach[i];
                let lit = l.ambient + l.lamp_strength * cos[i];
                light[i] = if visible[i] { lit } else { l.ambient };
            }
            if glossy {
                lobes(&tt.gloss, &tt.normal, &self.lamp_position, reach, geometry, to_camera, n, half, lobe);
                for i in 0..n {
                    let h = 0.0 + 255.0 * lobe[i] * l.lamp_strength * cos[i];
                    highlight[i] = if visible[i] { h } else { 0.0 };
                }
            }
        }
        gain[..n].fill(0.0);
        if l.projector_gain > 0.0 && tt.projector_facing > 0.0 {
            image_coordinates(&tt.h_projector, fx0, fy, n, q);
            let map = l.projector_shadow;
            let lit = &mut *mask;
            for i in 0..n {
                let qz = q.qz[i];
                lit[i] = qz > 0.0
                    && match map.lookup(q.u[i], q.v[i]) {
                        MapPixel::Outside => false,
                        MapPixel::Empty => true,
                        MapPixel::Pixel(p) => self.unshadowed(map, p, t, qz * geometry.z[i]),
                    };
            }
            distances(&self.projector_centre, geometry, n, reach);
            if glossy {
                lobes(&tt.gloss, &tt.normal, &self.projector_centre, reach, geometry, to_camera, n, half, lobe);
            } else {
                lobe[..n].fill(0.0);
            }
            // Each pass apart, so that the arithmetic runs in lanes. The coordinates and
            // blurs are stored for every pixel of the run, lit or not: only a lit pixel's
            // are ever read, and plain stores run in lanes where masked ones of pairs would
            // be scattered.
            for i in 0..n {
                let cos = tt.projector_facing / reach[i];
                let g = (tt.albedo + 255.0 * lobe[i]) * l.projector_gain * cos;
                gain[i] = if lit[i] { g } else { 0.0 };
            }
            for i in 0..n {
                uv[i] = [q.u[i] as f32, q.v[i] as f32];
            }
            if let Some((lens, top)) = &l.projector_lens {
                let blur = &mut blur[..n];
                let (ks, ws) = level;
                // A stack's top level is one of its levels; bounded here, the loop below
                // carries no index check.
                let top = (*top).min(LEVELS.len() - 1);
                for i in 0..n {
                    // The point lies qz z from the projector along its axis.
                    let (k, w) = level_weight(lens.sigma_px_at_inverse(q.inv_qz[i] * geometry.inv_z[i]), top);
                    ks[i] = k as u32;
                    ws[i] = w;
                }
                for i in 0..n {
                    blur[i] = (ks[i], ws[i]);
                }
            }
        }
        for i in 0..n {
            base[i] = (tt.albedo * light[i] + highlight[i]) as f32;
            projector[i] = gain[i] as f32;
            depth[i] = geometry.z[i] as f32;
        }
        ids.fill(tt.id);
    }

    /// The terms of every pixel of row `fy`, one pixel at a time: the obvious version the
    /// runs are checked against.
    #[cfg(test)]
    pub(super) fn row_per_pixel(&self, fy: f64, row: Row<'_>) {
        let w = row.tri.len();
        let (base, proj, uvs, depth, ids) =
            (&mut row.base[..w], &mut row.projector[..w], &mut row.uv[..w], &mut row.depth[..w], &mut row.ids[..w]);
        let blur = row.blur;
        let [rx, ry, r0] = self.rays;
        // The unit-depth ray of pixel (x, fy) is ray_row + rx x.
        let ray_row: [f64; 3] = std::array::from_fn(|i| ry[i] * fy + r0[i]);
        let l = self.lights;
        let lamp_map = l.lamp_shadow.map(|(_, map)| map);
        let projector_on = l.projector_gain > 0.0;
        for (x, &t) in row.tri.iter().enumerate() {
            let Some(tt) = self.terms.get(t as usize) else {
                base[x] = 0.0;
                proj[x] = 0.0;
                depth[x] = f32::INFINITY;
                ids[x] = ID_TABLE;
                continue;
            };
            let t = t as usize;
            let fx = x as f64;
            let [a, b, c] = tt.plane;
            let inv_z = a * fx + b * fy + c;
            let z = 1.0 / inv_z;
            let pos: [f64; 3] = std::array::from_fn(|i| self.centre[i] + (ray_row[i] + rx[i] * fx) * z);
            let mut light = l.ambient;
            let mut highlight = 0.0;
            let glossy = tt.gloss.specular > 0.0;
            let to_camera = if glossy { unit(sub(&self.centre, &pos)) } else { [0.0; 3] };
            if tt.lamp_facing > 0.0 {
                let visible = match lamp_map {
                    None => true,
                    Some(map) => {
                        let h = &tt.h_lamp;
                        let qz = h[2][0] * fx + h[2][1] * fy + h[2][2];
                        // Outside the lamp's map there is nothing that could shadow.
                        qz <= 0.0 || {
                            let inv = 1.0 / qz;
                            let u = (h[0][0] * fx + h[0][1] * fy + h[0][2]) * inv;
                            let v = (h[1][0] * fx + h[1][1] * fy + h[1][2]) * inv;
                            match map.lookup(u, v) {
                                MapPixel::Outside | MapPixel::Empty => true,
                                MapPixel::Pixel(i) => self.unshadowed(map, i, t, qz * z),
                            }
                        }
                    }
                };
                if visible {
                    let cos = tt.lamp_facing / distance(&self.lamp_position, &pos);
                    light += l.lamp_strength * cos;
                    if glossy {
                        let lobe =
                            tt.gloss.reflectance_half_way(&tt.normal, &half_way(&self.lamp_position, &pos, &to_camera));
                        highlight += 255.0 * lobe * l.lamp_strength * cos;
                    }
                }
            }
            let mut projector = 0.0;
            if projector_on && tt.projector_facing > 0.0 {
                let h = &tt.h_projector;
                let qz = h[2][0] * fx + h[2][1] * fy + h[2][2];
                if qz > 0.0 {
                    let map = l.projector_shadow;
                    let inv = 1.0 / qz;
                    let u = (h[0][0] * fx + h[0][1] * fy + h[0][2]) * inv;
                    let v = (h[1][0] * fx + h[1][1] * fy + h[1][2]) * inv;
                    let lit = match map.lookup(u, v) {
                        MapPixel::Outside => false,
                        MapPixel::Empty => true,
                        MapPixel::Pixel(i) => self.unshadowed(map, i, t, qz * z),
                    };
                    if lit {
                        let cos = tt.projector_facing / distance(&self.projector_centre, &pos);
                        let lobe = if glossy {
                            255.0
                                * tt.gloss.reflectance_half_way(
                                    &tt.normal,
                                    &half_way(&self.projector_centre, &pos, &to_camera),
                                )
                        } else {
                            0.0
                        };
                        projector = (tt.albedo + lobe) * l.projector_gain * cos;
                        uvs[x] = [u as f32, v as f32];
                        if let Some((lens, top)) = &l.projector_lens {
                            // The point lies qz z from the projector along its axis.
                            let (k, w) = level_weight(lens.sigma_px_at_inverse(inv * inv_z), *top);
                            blur[x] = (k as u32, w);
                        }
                    }
                }
            }
            base[x] = (tt.albedo * light + highlight) as f32;
            proj[x] = projector as f32;
            depth[x] = z as f32;
            ids[x] = tt.id;
        }
    }

    /// Whether a point of triangle `t` at depth `z_light` from a light is not hidden by
    /// what the light's shadow map holds at pixel `i`. The point's own surface never
    /// shadows it, which avoids acne on faces the light grazes.
    #[inline(always)]
    fn unshadowed(&self, map: &ZBuffer, i: usize, t: usize, z_light: f64) -> bool {
        let o = map.triangle[i];
        if o == NO_TRIANGLE || o as usize == t {
            return true;
        }
        let inverse_depth = map.inverse_depth[i] as f64;
        // The plane test is the dearer one, so it runs only where the depths say shadow.
        z_light * inverse_depth <= 1.0 + SHADOW_BIAS_MM * inverse_depth
            || same_surface(&self.triangles[o as usize], &self.triangles[t])
    }
}

/// A run's outputs (`blur` empty without the projector's defocus).
struct RunOut<'r> {
    base: &'r mut [f32],
    projector: &'r mut [f32],
    uv: &'r mut [[f32; 2]],
    blur: &'r mut [(u32, f32)],
    depth: &'r mut [f32],
    ids: &'r mut [u8],
}

/// The values a run's passes hand on to later ones, made once per row and reused run after
/// run: a pass writes the first `n` lanes of what it fills before any later pass reads them,
/// so nothing is cleared between runs.
struct RunScratch {
    geometry: Geometry,
    /// Unit vectors from the surface to the camera (glossy surfaces only).
    to_camera: [[f64; RUN]; 3],
    /// Base light, and the lamp's highlight.
    light: [f64; RUN],
    highlight: [f64; RUN],
    /// A shadow test's verdicts: visible from the lamp, then lit by the projector.
    mask: [bool; RUN],
    /// The lamp's cosine over distance.
    cos: [f64; RUN],
    /// The projector's gain.
    gain: [f64; RUN],
    /// Image coordinates in the lamp's view, then in the projector's.
    q: ImageCoordinates,
    /// Distances to the lamp, then to the projector.
    reach: [f64; RUN],
    /// A glossy lobe towards the camera, and its half-way vectors.
    lobe: [f64; RUN],
    half: HalfWays,
    /// The projector's blur level and weight.
    level: ([u32; RUN], [f32; RUN]),
}

impl Default for RunScratch {
    fn default() -> Self {
        RunScratch {
            geometry: Geometry::default(),
            to_camera: [[0.0; RUN]; 3],
            light: [0.0; RUN],
            highlight: [0.0; RUN],
            mask: [false; RUN],
            cos: [0.0; RUN],
            gain: [0.0; RUN],
            q: ImageCoordinates { qz: [0.0; RUN], inv_qz: [0.0; RUN], u: [0.0; RUN], v: [0.0; RUN] },
            reach: [0.0; RUN],
            lobe: [0.0; RUN],
            half: HalfWays { dots: [0.0; RUN], lengths2: [0.0; RUN], near: [false; RUN] },
            level: ([0; RUN], [0.0; RUN]),
        }
    }
}

/// A run's half-way vectors between a light and the camera: their dot products with the
/// normal, their squared lengths and whether the lobe is near its mirror direction there.
struct HalfWays {
    dots: [f64; RUN],
    lengths2: [f64; RUN],
    near: [bool; RUN],
}

/// A run's inverse depths, depths (mm along the camera's z) and surface points (world mm).
struct Geometry {
    inv_z: [f64; RUN],
    z: [f64; RUN],
    pos: [[f64; RUN]; 3],
}

impl Default for Geometry {
    fn default() -> Self {
        Geometry { inv_z: [0.0; RUN], z: [0.0; RUN], pos: [[0.0; RUN]; 3] }
    }
}

impl Geometry {
    /// Surface point `i`.
    #[inline(always)]
    fn at(&self, i: usize) -> [f64; 3] {
        [self.pos[0][i], self.pos[1][i], self.pos[2][i]]
    }
}

/// A run's homogeneous image coordinates in a light's view: the depth factor `qz`, its
/// inverse and the pixel (u, v).
struct ImageCoordinates {
    qz: [f64; RUN],
    inv_qz: [f64; RUN],
    u: [f64; RUN],
    v: [f64; RUN],
}

/// The image coordinates through homography `h` of the `n` pixels from (`fx0`, `fy`), into
/// `q`'s first `n` lanes.
#[inline(always)]
fn image_coordinates(h: &[[f64; 3]; 3], fx0: f64, fy: f64, n: usize, q: &mut ImageCoordinates) {
    let n = n.min(RUN);
    let [hu, hv, hz] = h.map(|row| (row[0], row[1] * fy, row[2]));
    for i in 0..n {
        let fx = fx0 + OFFSETS[i];
        let qz = hz.0 * fx + hz.1 + hz.2;
        let inv = 1.0 / qz;
        q.qz[i] = qz;
        q.inv_qz[i] = inv;
        q.u[i] = (hu.0 * fx + hu.1 + hu.2) * inv;
        q.v[i] = (hv.0 * fx + hv.1 + hv.2) * inv;
    }
}

/// The glossy lobe of the `n` points of a run towards the camera under a light at `light`,
/// `reach` away from each: the half-way vectors in vector lanes, the root and the power only
/// where the lobe is not negligible, into `lobe`'s first `n` lanes (`half` holds the
/// half-way vectors' dot products and lengths). The direction to the light is the
/// difference over `reach`, the very root [`unit`] would take again.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn lobes(
    gloss: &Gloss,
    normal: &[f64; 3],
    light: &[f64; 3],
    reach: &[f64; RUN],
    geometry: &Geometry,
    to_camera: &[[f64; RUN]; 3],
    n: usize,
    half: &mut HalfWays,
    lobe: &mut [f64; RUN],
) {
    let n = n.min(RUN);
    let HalfWays { dots, lengths2, near } = half;
    for i in 0..n {
        let v = sub(light, &geometry.at(i));
        let inv = 1.0 / reach[i];
        let half: [f64; 3] = std::array::from_fn(|k| v[k] * inv + to_camera[k][i]);
        let dot = normal[0] * half[0] + normal[1] * half[1] + normal[2] * half[2];
        let length2 = half[0] * half[0] + half[1] * half[1] + half[2] * half[2];
        near[i] = gloss.near_mirror(dot, length2);
        dots[i] = dot;
        lengths2[i] = length2;
    }
    for i in 0..n {
        lobe[i] = if near[i] { gloss.reflectance(dots[i] / lengths2[i].sqrt()) } else { 0.0 };
    }
}

/// The distances from `light` to the `n` points of a run, into `reach`'s first `n` lanes.
#[inline(always)]
fn distances(light: &[f64; 3], geometry: &Geometry, n: usize, reach: &mut [f64; RUN]) {
    for i in 0..n.min(RUN) {
        reach[i] = distance(light, &geometry.at(i));
    }
}

/// Euclidean distance between two points.
#[inline]
fn distance(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    let (dx, dy, dz) = (a[0] - b[0], a[1] - b[1], a[2] - b[2]);
    (dx * dx + dy * dy + dz * dz).sqrt()
}

/// `a - b`.
#[inline(always)]
fn sub(a: &[f64; 3], b: &[f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

/// `v` scaled to unit length.
#[inline(always)]
fn unit(v: [f64; 3]) -> [f64; 3] {
    let inv = 1.0 / (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    [v[0] * inv, v[1] * inv, v[2] * inv]
}

/// The half-way vector, unnormalised, between the direction from `pos` to `light` and the
/// unit vector `to_camera`.
#[cfg(test)]
#[inline(always)]
fn half_way(light: &[f64; 3], pos: &[f64; 3], to_camera: &[f64; 3]) -> [f64; 3] {
    let l = unit(sub(light, pos));
    [l[0] + to_camera[0], l[1] + to_camera[1], l[2] + to_camera[2]]
}

/// Whether two triangles lie in one plane (the two halves of a box face, say).
fn same_surface(a: &SceneTriangle, b: &SceneTriangle) -> bool {
    let cos = a.normal.dot(&b.normal);
    if cos.abs() < 1.0 - 1e-9 {
        return false;
    }
    (b.vertices[0] - a.vertices[0]).dot(&a.normal).abs() < 1e-3
}
