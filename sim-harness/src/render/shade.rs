//! Shading of one camera's pixels: from its G-buffer and the lights (ambient, the lamp
//! with its shadow map, the projector with its shadow map) to the pattern-independent
//! terms of every pixel, computed once per scene, and from those terms and a projector
//! image to the clean grey image of one shot:
//!
//! grey = 255 albedo ambient
//!        + 255 (albedo + gloss(n.h_lamp)) lamp_strength lamp_visible max(0, n.l_lamp)
//!        + 255 (albedo + gloss(n.h_projector)) projector_gain pattern(projector uv)
//!          projector_visible max(0, n.l_projector)
//!
//! clamped to 0..255 as the sensor saturates (after the lens's blur, when the camera's
//! defocus is rendered: then this module hands on the light unclamped); gloss is the
//! material's glossy lobe (see `Gloss`), h the half-way vector between the light and the
//! camera, so a glossy face throws a light's highlight where the law of reflection sends
//! it into the camera. With
//! the projector's defocus, each pixel also keeps the blur its surface point's distance
//! from the projector gives the pattern, as a level and weight of the pattern's blur stack,
//! and reads the pattern at that blur. The lamp is a point light without fall-off (it hangs
//! far away compared with the tray). A camera pixel spans about two projector
//! pixels; the pattern is pre-filtered over that footprint (see `ProjectorImage`) and
//! sampled once, bilinearly, at the pixel centre's projector coordinates, which keeps the
//! dots from aliasing at a quarter of the cost of four sub-samples.

use camplace_config::{FloatImage, GrayImage};
use nalgebra::{Matrix3, Point3, Vector3};
use rayon::prelude::*;

use crate::render::defocus::{level_weight, ThinLens};
use crate::render::noise::read_out;
use crate::render::pattern::ProjectorImage;
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

/// Per pixel of one camera, the parts of its grey level that do not depend on the pattern.
#[derive(Debug, Clone, Default)]
pub struct ShadingTerms {
    /// Image width, pixels.
    pub width: usize,
    /// Image height, pixels.
    pub height: usize,
    /// 255 albedo (ambient + lamp term), grey levels.
    pub base: Vec<f32>,
    /// 255 albedo gain n.l where the projector lights the pixel, else 0, grey levels.
    pub projector: Vec<f32>,
    /// Projector coordinates (u, v) of the pixel centre.
    pub projector_uv: Vec<[f32; 2]>,
    /// The projector's defocus blur at the pixel's surface point, as the level and weight
    /// ([`level_weight`]) of the patterns' blur stacks that give it (kept only with defocus).
    pub projector_blur: Vec<(u32, f32)>,
    /// Whether the projector's defocus is rendered.
    defocused: bool,
    triangles: Vec<TriangleTerms>,
}

impl ShadingTerms {
    /// Terms for a `width` x `height` camera, buffers allocated here once.
    pub fn new(width: usize, height: usize) -> ShadingTerms {
        let n = width * height;
        ShadingTerms {
            width,
            height,
            base: vec![0.0; n],
            projector: vec![0.0; n],
            projector_uv: vec![[0.0; 2]; n],
            projector_blur: vec![(0, 0.0); n],
            defocused: false,
            triangles: Vec::new(),
        }
    }

    /// Computes every pixel's terms from the camera's z-buffer (drawn from `triangles`),
    /// and writes the ground-truth depth (mm along the camera's z, +inf where nothing is
    /// seen) and object ids (the table's where nothing is seen).
    pub fn compute(
        &mut self,
        camera: &View,
        zbuffer: &ZBuffer,
        triangles: &[SceneTriangle],
        lights: &Lights<'_>,
        depth: &mut FloatImage,
        ids: &mut GrayImage,
    ) {
        let (w, h) = (self.width, self.height);
        debug_assert!(camera.width == w && camera.height == h && zbuffer.width == w);
        if !(depth.width == w && depth.height == h && depth.data.len() == w * h) {
            depth.reset(w, h, f32::INFINITY);
        }
        if !(ids.width == w && ids.height == h && ids.data.len() == w * h) {
            ids.reset(w, h, ID_TABLE);
        }
        let centre = camera.centre();
        let lamp_on = lights.lamp_strength > 0.0;
        let to_projector = Homographies::new(camera, lights.projector);
        let to_lamp = lights.lamp_shadow.map(|(lamp, _)| Homographies::new(camera, lamp));
        self.triangles.clear();
        self.triangles.extend(zbuffer.planes.iter().zip(triangles).map(|(&plane, tri)| {
            // Every point of a planar face gives the same n.(light - p), so which side the
            // camera and the lights are on is settled once per triangle.
            let v0 = tri.vertices[0];
            let normal = if tri.normal.dot(&(centre - v0)) < 0.0 { -tri.normal } else { tri.normal };
            TriangleTerms {
                plane,
                h_projector: to_projector.for_plane(plane),
                h_lamp: to_lamp.as_ref().map_or([[0.0; 3]; 3], |m| m.for_plane(plane)),
                albedo: 255.0 * tri.albedo,
                normal: normal.into(),
                gloss: tri.gloss,
                lamp_facing: if lamp_on { normal.dot(&(lights.lamp_position - v0)) } else { 0.0 },
                projector_facing: normal.dot(&(lights.projector.centre() - v0)),
                id: tri.id,
            }
        }));
        let ctx = Context {
            rays: camera.world_ray_coefficients().map(|r| [r.x, r.y, r.z]),
            centre: centre.coords.into(),
            lamp_position: lights.lamp_position.coords.into(),
            projector_centre: lights.projector.centre().coords.into(),
            terms: &self.triangles,
            triangles,
            lights,
        };
        let band = w * ROWS_PER_TASK;
        self.defocused = lights.projector_lens.is_some();
        self.base
            .par_chunks_mut(band)
            .zip(self.projector.par_chunks_mut(band))
            .zip(self.projector_uv.par_chunks_mut(band))
            .zip(depth.data.par_chunks_mut(band))
            .zip(ids.data.par_chunks_mut(band))
            .zip(self.projector_blur.par_chunks_mut(band))
            .enumerate()
            .for_each(|(chunk, (((((base, proj), uv), depth), ids), blur))| {
                let y0 = chunk * ROWS_PER_TASK;
                let rows = base.len() / w;
                for r in 0..rows {
                    let y = y0 + r;
                    let span = r * w..(r + 1) * w;
                    let row = Row {
                        tri: &zbuffer.triangle[y * w..(y + 1) * w],
                        base: &mut base[span.clone()],
                        projector: &mut proj[span.clone()],
                        uv: &mut uv[span.clone()],
                        blur: &mut blur[span.clone()],
                        depth: &mut depth[span.clone()],
                        ids: &mut ids[span],
                    };
                    terms_row(&ctx, y as f64, row);
                }
            });
    }

    /// The grey image of one shot under `pattern`, clamped to 0..255 as the sensor
    /// saturates, plus the noise of image key `noise.0` at amplitude `noise.1` if given.
    pub fn shade(&self, pattern: &ProjectorImage, noise: Option<(u64, u32)>, out: &mut [f32]) {
        self.shade_with(pattern, Exposure::Sensed(noise), out);
    }

    /// The light that reaches the lens under `pattern`, grey levels, not yet saturated: what
    /// the lens's blur acts on. With `base_scale` 2 the pattern-independent light counts
    /// twice (the sum of two shots under complementary patterns, when `pattern` is white).
    pub fn light(&self, pattern: &ProjectorImage, base_scale: f32, out: &mut [f32]) {
        self.shade_with(pattern, Exposure::Light(base_scale), out);
    }

    fn shade_with(&self, pattern: &ProjectorImage, exposure: Exposure, out: &mut [f32]) {
        let band = self.width * ROWS_PER_TASK;
        out.par_chunks_mut(band)
            .zip(self.base.par_chunks(band))
            .zip(self.projector.par_chunks(band))
            .zip(self.projector_uv.par_chunks(band))
            .enumerate()
            .for_each(|(chunk, (((out, base), proj), uv))| {
                let span = chunk * band..chunk * band + out.len();
                let blur = if self.defocused { &self.projector_blur[span] } else { &[] };
                shade_band(pattern, exposure, (chunk * band) as u64, BandTerms { base, proj, uv, blur }, out);
            });
    }

    /// Whether the projector lights pixel `i` (the complement is its projector shadow,
    /// its back-facing surfaces and what lies outside the projector's image).
    #[cfg(test)]
    pub fn projector_lit(&self, i: usize) -> bool {
        self.projector[i] > 0.0
    }
}

/// What one shading pass makes of the light.
#[derive(Debug, Clone, Copy)]
enum Exposure {
    /// The light as it is, its pattern-independent part scaled by the factor given.
    Light(f32),
    /// Saturated to 0..255 and with the noise of an image key at an amplitude, if given.
    Sensed(Option<(u64, u32)>),
}

camplace_estimator::multiversion! {
    /// [`ShadingTerms::shade`] of one band of pixels, the first of which is pixel `first`
    /// of the image.
    fn shade_band(
        pattern: &ProjectorImage,
        exposure: Exposure,
        first: u64,
        terms: BandTerms<'_>,
        out: &mut [f32],
    ) => shade_band_body
}

/// One band's pattern-independent terms (`blur` empty without the projector's defocus).
struct BandTerms<'a> {
    base: &'a [f32],
    proj: &'a [f32],
    uv: &'a [[f32; 2]],
    blur: &'a [(u32, f32)],
}

#[inline(always)]
fn shade_band_body(pattern: &ProjectorImage, exposure: Exposure, first: u64, terms: BandTerms<'_>, out: &mut [f32]) {
    let n = out.len();
    let BandTerms { base, proj, uv, blur } = terms;
    let (base, proj, uv) = (&base[..n], &proj[..n], &uv[..n]);
    let scale = match exposure {
        Exposure::Light(scale) => scale,
        Exposure::Sensed(_) => 1.0,
    };
    if blur.len() == n {
        for x in 0..n {
            let mut g = scale * base[x];
            let p = proj[x];
            if p > 0.0 {
                g += p * pattern.sample_defocused(uv[x][0], uv[x][1], blur[x]);
            }
            out[x] = g;
        }
    } else {
        for x in 0..n {
            let mut g = scale * base[x];
            let p = proj[x];
            if p > 0.0 {
                g += p * pattern.sample(uv[x][0], uv[x][1]);
            }
            out[x] = g;
        }
    }
    if let Exposure::Sensed(noise) = exposure {
        read_out(out, first, noise);
    }
}

/// Rows of pixels per task of parallel work: enough to pay for a task, few enough to share
/// 480 rows between a handful of threads.
const ROWS_PER_TASK: usize = 16;

/// `other.k (R k_inv + t plane)`, split so that one triangle's homography costs a rank-one
/// update instead of the products of rotation and intrinsic matrices.
struct Homographies {
    /// `other.k R k_inv`.
    rotation: Matrix3<f64>,
    /// `other.k t`.
    translation: Vector3<f64>,
}

impl Homographies {
    fn new(from: &View, to: &View) -> Homographies {
        let t = to.t_view_world * from.t_world_view;
        let r = t.rotation.to_rotation_matrix().into_inner();
        Homographies { rotation: to.k * r * from.k_inv, translation: to.k * t.translation.vector }
    }

    /// The rows of the homography of a surface with inverse-depth plane `plane`, as
    /// `View::homography_to` defines it.
    fn for_plane(&self, plane: [f64; 3]) -> [[f64; 3]; 3] {
        let (m, t) = (&self.rotation, &self.translation);
        std::array::from_fn(|i| std::array::from_fn(|j| m[(i, j)] + t[i] * plane[j]))
    }
}

/// What the per-pixel work needs of one triangle, in one camera's pixel coordinates.
#[derive(Debug, Clone, Copy, Default)]
struct TriangleTerms {
    /// Inverse-depth plane: 1/z = a x + b y + c.
    plane: [f64; 3],
    /// Rows of the homography to the projector's homogeneous pixel.
    h_projector: [[f64; 3]; 3],
    /// Rows of the homography to the lamp's shadow-map pixel (zeros without the map).
    h_lamp: [[f64; 3]; 3],
    /// 255 albedo, grey levels.
    albedo: f64,
    /// Unit normal turned towards the camera.
    normal: [f64; 3],
    /// Glossy lobe.
    gloss: Gloss,
    /// n.(lamp - p) with n turned towards the camera: the lamp lights the face only when
    /// positive (0 when the lamp is off).
    lamp_facing: f64,
    /// n.(projector - p), likewise.
    projector_facing: f64,
    /// Object id.
    id: u8,
}

/// One image row of the outputs and the z-buffer's triangles.
struct Row<'r> {
    tri: &'r [u32],
    base: &'r mut [f32],
    projector: &'r mut [f32],
    uv: &'r mut [[f32; 2]],
    blur: &'r mut [(u32, f32)],
    depth: &'r mut [f32],
    ids: &'r mut [u8],
}

/// Everything the per-pixel work reads, shared by the threads.
struct Context<'a> {
    rays: [[f64; 3]; 3],
    centre: [f64; 3],
    lamp_position: [f64; 3],
    projector_centre: [f64; 3],
    terms: &'a [TriangleTerms],
    triangles: &'a [SceneTriangle],
    lights: &'a Lights<'a>,
}

camplace_estimator::multiversion! {
    /// [`Context::row`].
    fn terms_row(ctx: &Context<'_>, fy: f64, row: Row<'_>) => terms_row_body
}

#[inline(always)]
fn terms_row_body(ctx: &Context<'_>, fy: f64, row: Row<'_>) {
    ctx.row(fy, row);
}

impl Context<'_> {
    /// The terms of every pixel of row `fy`.
    #[inline(always)]
    fn row(&self, fy: f64, row: Row<'_>) {
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
