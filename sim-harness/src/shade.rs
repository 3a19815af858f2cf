//! Shading of one camera's pixels: from its G-buffer and the lights (ambient, the lamp
//! with its shadow map, the projector with its shadow map) to the pattern-independent
//! terms of every pixel, computed once per scene, and from those terms and a projector
//! image to the clean grey image of one shot:
//!
//! grey = 255 albedo (ambient + lamp_strength lamp_visible max(0, n.l_lamp)
//!        + projector_gain pattern(projector uv) projector_visible max(0, n.l_projector))
//!
//! clamped to 0..255 as the sensor saturates. The lamp is a point light without fall-off
//! (it hangs far away compared with the tray). A camera pixel spans about two projector
//! pixels; the pattern is pre-filtered over that footprint (see `ProjectorImage`) and
//! sampled once, bilinearly, at the pixel centre's projector coordinates, which keeps the
//! dots from aliasing at a quarter of the cost of four sub-samples.

use camplace_estimator::{FloatImage, GrayImage};
use nalgebra::{Matrix3, Point3, Vector3};
use rayon::prelude::*;

use crate::noise::pixel_noise;
use crate::pattern::ProjectorImage;
use crate::raster::{View, ZBuffer, NO_TRIANGLE};
use crate::scene::{SceneTriangle, ID_TABLE};

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
    h_projector: Vec<Matrix3<f64>>,
    h_lamp: Vec<Matrix3<f64>>,
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
            h_projector: Vec::new(),
            h_lamp: Vec::new(),
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
        self.h_projector.clear();
        self.h_lamp.clear();
        for plane in &zbuffer.planes {
            self.h_projector.push(camera.homography_to(lights.projector, *plane));
            if let Some((lamp, _)) = lights.lamp_shadow {
                self.h_lamp.push(camera.homography_to(lamp, *plane));
            }
        }
        let ctx = Context {
            rays: camera.world_ray_coefficients(),
            centre: camera.centre(),
            projector_centre: lights.projector.centre(),
            zbuffer,
            triangles,
            lights,
            h_projector: &self.h_projector,
            h_lamp: &self.h_lamp,
        };
        self.base
            .par_chunks_mut(w)
            .zip(self.projector.par_chunks_mut(w))
            .zip(self.projector_uv.par_chunks_mut(w))
            .zip(depth.data.par_chunks_mut(w))
            .zip(ids.data.par_chunks_mut(w))
            .enumerate()
            .for_each(|(y, ((((base, proj), uv), depth), ids))| {
                let tri_row = &zbuffer.triangle[y * w..(y + 1) * w];
                for x in 0..w {
                    let t = tri_row[x];
                    if t == NO_TRIANGLE {
                        base[x] = 0.0;
                        proj[x] = 0.0;
                        depth[x] = f32::INFINITY;
                        ids[x] = ID_TABLE;
                        continue;
                    }
                    let px = ctx.pixel(x as f64, y as f64, t as usize, &mut uv[x]);
                    base[x] = px.base;
                    proj[x] = px.projector;
                    depth[x] = px.depth;
                    ids[x] = triangles[t as usize].id;
                }
            });
    }

    /// The grey image of one shot under `pattern`, clamped to 0..255 as the sensor
    /// saturates, plus the noise of image key `noise.0` at amplitude `noise.1` if given.
    pub fn shade(&self, pattern: &ProjectorImage, noise: Option<(u64, u32)>, out: &mut [f32]) {
        let w = self.width;
        out.par_chunks_mut(w)
            .zip(self.base.par_chunks(w))
            .zip(self.projector.par_chunks(w))
            .zip(self.projector_uv.par_chunks(w))
            .enumerate()
            .for_each(|(y, (((out, base), proj), uv))| {
                for x in 0..out.len() {
                    let mut g = base[x];
                    let p = proj[x];
                    if p > 0.0 {
                        g += p * pattern.sample(uv[x][0], uv[x][1]);
                    }
                    out[x] = g.clamp(0.0, 255.0);
                }
                if let Some((key, amplitude)) = noise.filter(|n| n.1 > 0) {
                    let first = (y * w) as u64;
                    for (x, o) in out.iter_mut().enumerate() {
                        *o += pixel_noise(key, first + x as u64, amplitude) as f32;
                    }
                }
            });
    }

    /// Whether the projector lights pixel `i` (the complement is its projector shadow,
    /// its back-facing surfaces and what lies outside the projector's image).
    pub fn projector_lit(&self, i: usize) -> bool {
        self.projector[i] > 0.0
    }
}

/// What `Context::pixel` finds at one pixel.
struct PixelTerms {
    base: f32,
    projector: f32,
    depth: f32,
}

/// Everything the per-pixel work reads, shared by the threads.
struct Context<'a> {
    rays: [Vector3<f64>; 3],
    centre: Point3<f64>,
    projector_centre: Point3<f64>,
    zbuffer: &'a ZBuffer,
    triangles: &'a [SceneTriangle],
    lights: &'a Lights<'a>,
    h_projector: &'a [Matrix3<f64>],
    h_lamp: &'a [Matrix3<f64>],
}

impl Context<'_> {
    #[inline]
    fn pixel(&self, fx: f64, fy: f64, t: usize, uv: &mut [f32; 2]) -> PixelTerms {
        let tri = &self.triangles[t];
        let [a, b, c] = self.zbuffer.planes[t];
        let z = 1.0 / (a * fx + b * fy + c);
        let [rx, ry, r0] = self.rays;
        let pos = self.centre + (rx * fx + ry * fy + r0) * z;
        let normal = if tri.normal.dot(&(self.centre - pos)) < 0.0 { -tri.normal } else { tri.normal };
        let l = self.lights;
        let mut light = l.ambient;
        if l.lamp_strength > 0.0 {
            let to_lamp = l.lamp_position - pos;
            let facing = normal.dot(&to_lamp);
            if facing > 0.0 {
                let visible = match l.lamp_shadow {
                    None => true,
                    Some((_, map)) => {
                        let q = self.h_lamp[t] * Vector3::new(fx, fy, 1.0);
                        let inv = 1.0 / q.z;
                        // Outside the lamp's map there is nothing that could shadow.
                        q.z <= 0.0
                            || map.nearest(q.x * inv, q.y * inv).is_none_or(|i| self.unshadowed(map, i, t, q.z * z))
                    }
                };
                if visible {
                    light += l.lamp_strength * facing / to_lamp.norm();
                }
            }
        }
        let albedo = 255.0 * tri.albedo;
        let mut projector = 0.0;
        if l.projector_gain > 0.0 {
            let to_proj = self.projector_centre - pos;
            let facing = normal.dot(&to_proj);
            let q = self.h_projector[t] * Vector3::new(fx, fy, 1.0);
            if facing > 0.0 && q.z > 0.0 {
                let map = l.projector_shadow;
                let inv = 1.0 / q.z;
                let (u, v) = (q.x * inv, q.y * inv);
                if map.nearest(u, v).is_some_and(|i| self.unshadowed(map, i, t, q.z * z)) {
                    projector = albedo * l.projector_gain * facing / to_proj.norm();
                    *uv = [u as f32, v as f32];
                }
            }
        }
        PixelTerms { base: (albedo * light) as f32, projector: projector as f32, depth: z as f32 }
    }

    /// Whether a point of triangle `t` at depth `z_light` from a light is not hidden by
    /// what the light's shadow map holds at pixel `i`. The point's own surface never
    /// shadows it, which avoids acne on faces the light grazes.
    #[inline]
    fn unshadowed(&self, map: &ZBuffer, i: usize, t: usize, z_light: f64) -> bool {
        let o = map.triangle[i];
        if o == NO_TRIANGLE || o as usize == t || same_surface(&self.triangles[o as usize], &self.triangles[t]) {
            return true;
        }
        z_light * map.inverse_depth[i] as f64 <= 1.0 + SHADOW_BIAS_MM * map.inverse_depth[i] as f64
    }
}

/// Whether two triangles lie in one plane (the two halves of a box face, say).
fn same_surface(a: &SceneTriangle, b: &SceneTriangle) -> bool {
    let cos = a.normal.dot(&b.normal);
    if cos.abs() < 1.0 - 1e-9 {
        return false;
    }
    (b.vertices[0] - a.vertices[0]).dot(&a.normal).abs() < 1e-3
}
