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
use rayon::prelude::*;

use crate::render::noise::read_out;
use crate::render::pattern::{LightRun, ProjectorImage};
use crate::render::raster::{View, ZBuffer};
pub use crate::render::terms::Lights;
use crate::render::terms::{terms_row, Context, Homographies, Row, TriangleTerms};
use crate::scene::{SceneTriangle, ID_TABLE};

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
    /// Projector coordinates (u, v) of the pixel centre; meaningful where the projector
    /// lights the pixel (`projector` > 0), and all that is read.
    pub projector_uv: Vec<[f32; 2]>,
    /// The projector's defocus blur at the pixel's surface point, as the level and weight
    /// ([`level_weight`]) of the patterns' blur stacks that give it (kept only with defocus;
    /// meaningful where the projector lights the pixel).
    pub projector_blur: Vec<(u32, f32)>,
    /// Whether the projector's defocus is rendered.
    pub(crate) defocused: bool,
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
        self.compute_with(camera, zbuffer, triangles, lights, (depth, ids), terms_row);
    }

    /// [`ShadingTerms::compute`] one pixel at a time, the obvious way.
    #[cfg(test)]
    pub(crate) fn compute_per_pixel(
        &mut self,
        camera: &View,
        zbuffer: &ZBuffer,
        triangles: &[SceneTriangle],
        lights: &Lights<'_>,
        depth: &mut FloatImage,
        ids: &mut GrayImage,
    ) {
        self.compute_with(camera, zbuffer, triangles, lights, (depth, ids), |ctx, fy, row| ctx.row_per_pixel(fy, row));
    }

    /// [`ShadingTerms::compute`] with `row` doing each row's pixels.
    fn compute_with(
        &mut self,
        camera: &View,
        zbuffer: &ZBuffer,
        triangles: &[SceneTriangle],
        lights: &Lights<'_>,
        (depth, ids): (&mut FloatImage, &mut GrayImage),
        row_terms: fn(&Context<'_>, f64, Row<'_>),
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
                    row_terms(&ctx, y as f64, row);
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
                let terms = BandTerms { width: self.width, base, proj, uv, blur };
                shade_band(pattern, exposure, (chunk * band) as u64, terms, out);
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

/// One band's pattern-independent terms (`blur` empty without the projector's defocus), in
/// rows of `width` pixels.
struct BandTerms<'a> {
    width: usize,
    base: &'a [f32],
    proj: &'a [f32],
    uv: &'a [[f32; 2]],
    blur: &'a [(u32, f32)],
}

#[inline(always)]
fn shade_band_body(pattern: &ProjectorImage, exposure: Exposure, first: u64, terms: BandTerms<'_>, out: &mut [f32]) {
    let n = out.len();
    let BandTerms { width, base, proj, uv, blur } = terms;
    let (base, proj, uv) = (&base[..n], &proj[..n], &uv[..n]);
    let scale = match exposure {
        Exposure::Light(scale) => scale,
        Exposure::Sensed(_) => 1.0,
    };
    let band = LightRun { base, proj, uv, blur };
    // Row by row, each row's pattern values asked of the cache while the row before is lit.
    let width = width.clamp(1, n.max(1));
    for start in (0..n).step_by(width) {
        let end = (start + width).min(n);
        if end < n {
            pattern.prefetch(band.span(end..(end + width).min(n)));
        }
        let row = band.span(start..end);
        let done = pattern.add_light_wide(scale, row, &mut out[start..end]);
        pattern.add_light(scale, row.from(done), &mut out[start + done..end]);
    }
    if let Exposure::Sensed(noise) = exposure {
        read_out(out, first, noise);
    }
}

/// Rows of pixels per task of parallel work: enough to pay for a task, few enough to share
/// 480 rows between a handful of threads.
const ROWS_PER_TASK: usize = 16;
