//! The simulated sensor: a stereo camera and a projector at one placement, rendering a
//! scene into the frames the estimator reads (one image per camera for the one-shot
//! method, twelve for the phase-shift method) with ground-truth depth and object ids.
//!
//! Per frame the geometry (scene triangles, the projector's and the lamp's shadow maps,
//! each camera's G-buffer and pattern-independent shading terms, and with defocus each
//! pixel's blur) is computed once; each shot then costs one pass of pattern sampling, the
//! camera's defocus and the noise. A defocused camera's fringe shots come in complementary
//! pairs, so it samples and blurs 7 images for its 12 shots (see `fringes_defocused`). Every buffer is allocated
//! in `Simulator::new` or on the first frame, and reused after.

use camplace_config::{Cell, Effect, Focus, Placement};
use camplace_config::{FloatImage, Frames, GrayImage};
pub use camplace_estimator::depth::Method;
use camplace_estimator::{
    depth::fringe_set, depth::one_shot, depth::PHASE_STEPS, geometry::look_at, geometry::sensor_rig, geometry::Camera,
    Rig,
};
use nalgebra::Point3;

use crate::render::defocus::{blur_levels, defocus_image, top_level, BlurStack, ThinLens, LEVELS};
use crate::render::lens::LensWarp;
use crate::render::noise::{add_noise, mean_filter_to_u8, sense};
use crate::render::pattern::{white, ProjectorImage};
use crate::render::raster::{View, ZBuffer};
use crate::render::shade::{Lights, ShadingTerms};
use crate::scene::{Objects, SceneSpec, SceneTriangle, ID_TABLE};
use crate::seeds::image_key;
use crate::{Error, Result};

/// Side of the lamp's square shadow map, pixels (about 0.5 mm per pixel on a tray seen
/// from the default 1.5 m).
pub const LAMP_MAP_SIZE: usize = 512;

/// One captured frame: the shots of both cameras, as every frame source hands them on, and
/// their ground truth.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Frame {
    /// The cameras' images, one per shot: what a camera would capture, passed as they are
    /// to the estimator, the dataset writer or anything else that takes [`Frames`].
    pub shots: Frames,
    /// Ground-truth depth along the left camera's z axis, mm; +inf where nothing is seen.
    pub depth_left: FloatImage,
    /// Ground-truth depth along the right camera's z axis, mm; +inf where nothing is seen.
    pub depth_right: FloatImage,
    /// Object ids seen by the left camera (0 table or nothing, 1 tray, 2 + n item n).
    pub ids_left: GrayImage,
    /// Object ids seen by the right camera.
    pub ids_right: GrayImage,
}

/// The simulated stereo camera and projector of one placement, with all its buffers.
#[derive(Debug, Clone)]
pub struct Simulator {
    rig: Rig,
    objects: Objects,
    /// What each camera's rasterizer draws: the camera itself, or for a camera with lens
    /// distortion its distortion-free canvas.
    cameras: [View; 2],
    /// Per camera with lens distortion, the warp from its canvas to its image.
    lenses: [Option<LensWarp>; 2],
    projector: View,
    projector_gain: f64,
    noise_amplitude: u32,
    blur: usize,
    one_shot_images: Vec<GrayImage>,
    fringe_images: Vec<GrayImage>,
    one_shot: Vec<ProjectorImage>,
    fringes: Vec<ProjectorImage>,
    /// A white projector image, prepared as the fringes are.
    white: ProjectorImage,
    /// The blurred light of a complementary pair's sum and of a period's first two steps.
    basis: [Vec<f32>; 3],
    triangles: Vec<SceneTriangle>,
    zbuffers: [ZBuffer; 2],
    terms: [ShadingTerms; 2],
    projector_map: ZBuffer,
    lamp_map: ZBuffer,
    clean: Vec<f32>,
    scratch: Vec<f32>,
    /// A canvas's shaded grey levels, depth and ids before the lens warp (empty without one).
    canvas_grey: Vec<f32>,
    canvas_depth: FloatImage,
    canvas_ids: GrayImage,
    /// Per camera, its lens when defocus is rendered.
    camera_lenses: [Option<ThinLens>; 2],
    /// The projector's lens when defocus is rendered.
    projector_lens: Option<ThinLens>,
    /// The top level of the patterns' blur stacks.
    projector_top: usize,
    /// Per camera, each pixel's defocus blur this frame as a blur level and weight, and
    /// the top level the frame needs.
    camera_levels: [Vec<(u32, f32)>; 2],
    camera_top: [usize; 2],
    blur_stack: BlurStack,
    /// The box filter and the largest defocus blur the projector images were prepared with.
    #[cfg(test)]
    pattern_prep: (usize, f32),
    /// Renders every fringe shot on its own, the obvious way the pairs are checked against.
    #[cfg(test)]
    fringes_one_by_one: bool,
    /// Computes the shading terms one pixel at a time, the obvious way the runs are
    /// checked against.
    #[cfg(test)]
    terms_one_by_one: bool,
}

impl Simulator {
    /// The sensor of `cell` at `placement` (or the cell's installed rig, which then fixes
    /// the cameras), its one-shot dots drawn from `pattern_seed`.
    pub fn new(cell: &Cell, placement: &Placement, pattern_seed: u64) -> Result<Simulator> {
        let sensor = &cell.sensor;
        if sensor.blur.is_multiple_of(2) || sensor.blur > 15 {
            return Err(Error::Other(format!(
                "sensor.blur: expected an odd filter side up to 15, got {}",
                sensor.blur
            )));
        }
        let rig = sensor_rig(cell, placement);
        let lenses = [LensWarp::new(&rig.left), LensWarp::new(&rig.right)];
        let drawn =
            |camera: &Camera, lens: &Option<(Camera, LensWarp)>| View::new(lens.as_ref().map_or(camera, |l| &l.0));
        let cameras = [drawn(&rig.left, &lenses[0])?, drawn(&rig.right, &lenses[1])?];
        let lenses = lenses.map(|l| l.map(|(_, warp)| warp));
        let projector_camera =
            rig.projector.as_ref().ok_or_else(|| Error::Other("the sensor has no projector".to_string()))?;
        let projector = View::new(projector_camera)?;
        let one_shot_images = vec![one_shot(sensor, pattern_seed)];
        let fringe_images = fringe_set(sensor);
        let (w, h) = (rig.left.width, rig.left.height);
        let footprint = footprint(&rig.left, projector_camera);
        let defocus = cell.effect_active(Effect::Defocus);
        let o = &cell.optics;
        let lens_of = |view: &View, focal_length: f64, f_number: f64, focus: Focus| {
            let focus = match focus {
                Focus::Distance(d) => d,
                Focus::Table => view.t_view_world.translation.vector.z,
            };
            // A lens focused nearer than its focal length is not a lens (the table behind
            // the camera, say): such a view is drawn sharp.
            (defocus && focus > focal_length).then(|| ThinLens::new(focal_length, f_number, focus, view.k[(0, 0)]))
        };
        let camera_lenses =
            [0, 1].map(|c| lens_of(&cameras[c], o.camera_focal_length, o.camera_f_number, o.camera_focus));
        let projector_lens = lens_of(&projector, o.projector_focal_length, o.projector_f_number, o.projector_focus);
        let max_sigma = projector_lens.map_or(0.0, |lens| largest_blur(&lens, &projector, cell));
        Ok(Simulator {
            objects: Objects::from_cell(cell)?,
            one_shot: one_shot_images.iter().map(|i| ProjectorImage::new(i, footprint, max_sigma)).collect(),
            fringes: fringe_images.iter().map(|i| ProjectorImage::new(i, footprint, max_sigma)).collect(),
            white: ProjectorImage::new(&white(sensor), footprint, max_sigma),
            basis: Default::default(),
            one_shot_images,
            fringe_images,
            zbuffers: [0, 1].map(|c| ZBuffer::new(cameras[c].width, cameras[c].height)),
            terms: [0, 1].map(|c| ShadingTerms::new(cameras[c].width, cameras[c].height)),
            projector_map: ZBuffer::new(projector.width, projector.height),
            lamp_map: ZBuffer::new(LAMP_MAP_SIZE, LAMP_MAP_SIZE),
            clean: vec![0.0; w * h],
            scratch: vec![0.0; w * h],
            canvas_grey: Vec::new(),
            canvas_depth: FloatImage::default(),
            canvas_ids: GrayImage::default(),
            camera_lenses,
            projector_lens,
            projector_top: top_level(max_sigma),
            camera_levels: [Vec::new(), Vec::new()],
            camera_top: [0; 2],
            blur_stack: BlurStack::default(),
            #[cfg(test)]
            pattern_prep: (footprint, max_sigma),
            #[cfg(test)]
            fringes_one_by_one: false,
            #[cfg(test)]
            terms_one_by_one: false,
            triangles: Vec::new(),
            projector_gain: sensor.projector_gain,
            noise_amplitude: sensor.noise_amplitude,
            blur: sensor.blur as usize,
            cameras,
            lenses,
            projector,
            rig,
        })
    }

    /// Sets the sensor's levels that leave the patterns as they are: the projector's gain,
    /// the camera noise's amplitude and the mean filter's side (odd, at most 15, as
    /// [`Simulator::new`] checks it).
    pub(crate) fn set_levels(&mut self, projector_gain: f64, noise_amplitude: u32, blur: u32) {
        debug_assert!(blur % 2 == 1 && blur <= 15);
        self.projector_gain = projector_gain;
        self.noise_amplitude = noise_amplitude;
        self.blur = blur as usize;
    }

    /// The calibrated rig (cameras and projector) this sensor renders with.
    pub fn rig(&self) -> &Rig {
        &self.rig
    }

    /// The table, tray and item it places in scenes.
    pub fn objects(&self) -> &Objects {
        &self.objects
    }

    /// The objects, to stand something else in a slot (`Objects::odd_items`) for a test of
    /// what the slot judge makes of it.
    pub fn objects_mut(&mut self) -> &mut Objects {
        &mut self.objects
    }

    /// Shows `image` as the one-shot pattern from now on (prepared as the seeded one was).
    #[cfg(test)]
    pub(crate) fn set_one_shot_pattern(&mut self, image: GrayImage) {
        let (footprint, max_sigma) = self.pattern_prep;
        self.one_shot = vec![ProjectorImage::new(&image, footprint, max_sigma)];
        self.one_shot_images = vec![image];
    }

    /// The projector's lens and the left camera's, when defocus is rendered.
    #[cfg(test)]
    pub(crate) fn thin_lenses(&self) -> (Option<ThinLens>, Option<ThinLens>) {
        (self.projector_lens, self.camera_lenses[0])
    }

    /// The projector images of a method, in shot order.
    pub fn patterns(&self, method: Method) -> &[GrayImage] {
        match method {
            Method::OneShot => &self.one_shot_images,
            Method::Phase12 => &self.fringe_images,
        }
    }

    /// Renders `scene` into `frame` (reusing its buffers) with the camera noise of
    /// `noise_key`: the same key gives the same images, on any number of threads.
    pub fn render(&mut self, scene: &SceneSpec, method: Method, noise_key: u64, frame: &mut Frame) {
        self.render_with(scene, method, Some(noise_key), frame);
    }

    /// Renders `scene` without noise and without the mean filter: the clean images.
    pub fn render_clean(&mut self, scene: &SceneSpec, method: Method, frame: &mut Frame) {
        self.render_with(scene, method, None, frame);
    }

    fn render_with(&mut self, scene: &SceneSpec, method: Method, noise_key: Option<u64>, frame: &mut Frame) {
        self.geometry(scene, frame);
        for (cam, images) in [&mut frame.shots.left, &mut frame.shots.right].into_iter().enumerate() {
            let (w, h) = if cam == 0 {
                (self.rig.left.width, self.rig.left.height)
            } else {
                (self.rig.right.width, self.rig.right.height)
            };
            self.clean.resize(w * h, 0.0);
            let shots = self.patterns(method).len();
            images.truncate(shots);
            images.resize_with(shots, GrayImage::default);
            for image in images.iter_mut() {
                if !(image.width == w && image.height == h && image.data.len() == w * h) {
                    image.reset(w, h, 0);
                }
            }
            let amplitude = self.noise_amplitude;
            let noise = |shot: usize| noise_key.map(|key| (image_key(key, cam as u64, shot as u64), amplitude));
            let blur = if noise_key.is_some() { self.blur } else { 1 };
            if method == Method::Phase12 && self.camera_lenses[cam].is_some() && self.draws_pairs() {
                self.fringes_defocused(cam, &noise, blur, images);
                continue;
            }
            let patterns = match method {
                Method::OneShot => &self.one_shot,
                Method::Phase12 => &self.fringes,
            };
            for (shot, (pattern, image)) in patterns.iter().zip(images.iter_mut()).enumerate() {
                let noise = noise(shot);
                match (&self.lenses[cam], self.camera_lenses[cam].is_some()) {
                    (None, false) => self.terms[cam].shade(pattern, noise, &mut self.clean),
                    (None, true) => self.terms[cam].light(pattern, 1.0, &mut self.clean),
                    (Some(lens), defocused) => {
                        self.canvas_grey.resize(self.cameras[cam].width * self.cameras[cam].height, 0.0);
                        if defocused {
                            self.terms[cam].light(pattern, 1.0, &mut self.canvas_grey);
                        } else {
                            self.terms[cam].shade(pattern, None, &mut self.canvas_grey);
                        }
                        lens.warp_linear(&self.canvas_grey, &mut self.clean);
                    }
                }
                // The lens blurs the light before the sensor saturates and adds its noise.
                if self.camera_lenses[cam].is_some() {
                    let (levels, top) = (&self.camera_levels[cam], self.camera_top[cam]);
                    defocus_image(&mut self.clean, w, levels, top, &mut self.blur_stack, Some(noise));
                } else if self.lenses[cam].is_some() {
                    if let Some((key, amplitude)) = noise {
                        add_noise(&mut self.clean, key, amplitude);
                    }
                }
                mean_filter_to_u8(&self.clean, w, blur, &mut self.scratch, &mut image.data);
            }
        }
    }

    /// Whether fringe shots under complementary patterns are drawn from their pair's sum.
    fn draws_pairs(&self) -> bool {
        #[cfg(test)]
        if self.fringes_one_by_one {
            return false;
        }
        true
    }

    /// The 12 shots of camera `cam` through its defocused lens. Light, the lens's blur and
    /// the projector's are linear up to the sensor, and steps 2 and 3 of a fringe period
    /// show the complements of steps 0 and 1; so the light of step k + 2 is the light under
    /// a white pattern with the pattern-independent light counted twice, less the light of
    /// step k. Per camera that blurs 7 images instead of 12; the sensor then saturates,
    /// adds the noise and filters every shot as it would each alone.
    fn fringes_defocused(
        &mut self,
        cam: usize,
        noise: &dyn Fn(usize) -> Option<(u64, u32)>,
        blur: usize,
        images: &mut [GrayImage],
    ) {
        let (w, pixels) = images.first().map_or((0, 0), |i| (i.width, i.data.len()));
        let Simulator {
            terms,
            lenses,
            cameras,
            canvas_grey,
            camera_levels,
            camera_top,
            blur_stack,
            basis,
            white,
            fringes,
            clean,
            scratch,
            ..
        } = self;
        let (levels, top) = (&camera_levels[cam], camera_top[cam]);
        let mut blurred_light = |pattern: &ProjectorImage, base_scale: f32, out: &mut Vec<f32>| {
            out.resize(pixels, 0.0);
            match &lenses[cam] {
                None => terms[cam].light(pattern, base_scale, out),
                Some(lens) => {
                    canvas_grey.resize(cameras[cam].width * cameras[cam].height, 0.0);
                    terms[cam].light(pattern, base_scale, canvas_grey);
                    lens.warp_linear(canvas_grey, out);
                }
            }
            defocus_image(out, w, levels, top, blur_stack, None);
        };
        let [pair_sum, first, second] = basis;
        blurred_light(white, 2.0, pair_sum);
        for (period, shots) in images.chunks_mut(PHASE_STEPS).enumerate() {
            let steps = &fringes[period * PHASE_STEPS..][..PHASE_STEPS];
            blurred_light(&steps[0], 1.0, first);
            blurred_light(&steps[1], 1.0, second);
            for (k, image) in shots.iter_mut().enumerate() {
                let (light, less) = match k {
                    0 => (&first[..], None),
                    1 => (&second[..], None),
                    2 => (&pair_sum[..], Some(&first[..])),
                    _ => (&pair_sum[..], Some(&second[..])),
                };
                sense(light, less, noise(period * PHASE_STEPS + k), clean);
                mean_filter_to_u8(clean, w, blur, scratch, &mut image.data);
            }
        }
    }

    /// Everything that depends only on the poses: triangles, shadow maps, G-buffers,
    /// shading terms, ground-truth depth and ids.
    fn geometry(&mut self, scene: &SceneSpec, frame: &mut Frame) {
        let Simulator {
            objects,
            triangles,
            projector,
            projector_map,
            lamp_map,
            cameras,
            lenses,
            zbuffers,
            terms,
            canvas_depth,
            canvas_ids,
            camera_lenses,
            projector_lens,
            projector_top,
            camera_levels,
            camera_top,
            ..
        } = self;
        objects.triangles(scene, triangles);
        projector_map.rasterize(projector, triangles, true);
        let lamp_view = lamp_view(scene, triangles);
        if let Some(view) = &lamp_view {
            lamp_map.rasterize(view, triangles, true);
        }
        let lights = Lights {
            ambient: scene.ambient,
            lamp_strength: scene.lamp_strength,
            lamp_position: scene.lamp_position,
            lamp_shadow: lamp_view.as_ref().map(|v| (v, &*lamp_map)),
            projector,
            projector_shadow: projector_map,
            projector_gain: self.projector_gain,
            projector_lens: projector_lens.map(|lens| (lens, *projector_top)),
        };
        let outputs = [(&mut frame.depth_left, &mut frame.ids_left), (&mut frame.depth_right, &mut frame.ids_right)];
        for (c, (depth, ids)) in outputs.into_iter().enumerate() {
            zbuffers[c].rasterize(&cameras[c], triangles, false);
            #[cfg(test)]
            let compute = if self.terms_one_by_one { ShadingTerms::compute_per_pixel } else { ShadingTerms::compute };
            #[cfg(not(test))]
            let compute = ShadingTerms::compute;
            match &lenses[c] {
                None => compute(&mut terms[c], &cameras[c], &zbuffers[c], triangles, &lights, depth, ids),
                Some(lens) => {
                    compute(&mut terms[c], &cameras[c], &zbuffers[c], triangles, &lights, canvas_depth, canvas_ids);
                    let (w, h) = lens.size();
                    if !(depth.width == w && depth.height == h && depth.data.len() == w * h) {
                        depth.reset(w, h, f32::INFINITY);
                    }
                    if !(ids.width == w && ids.height == h && ids.data.len() == w * h) {
                        ids.reset(w, h, ID_TABLE);
                    }
                    lens.warp_nearest(&canvas_depth.data, &mut depth.data, f32::INFINITY);
                    lens.warp_nearest(&canvas_ids.data, &mut ids.data, ID_TABLE);
                }
            }
            if let Some(lens) = &camera_lenses[c] {
                camera_top[c] = blur_levels(lens, &depth.data, &mut camera_levels[c]);
            }
        }
    }
}

/// The largest blur, projector pixels, that `lens` gives anything the projector can light
/// in `cell`: the depths of the work volume's and the table's corners bound it (the blur
/// grows away from the focus distance on either side).
fn largest_blur(lens: &ThinLens, projector: &View, cell: &Cell) -> f32 {
    let w = &cell.work_volume;
    let [tx, ty] = cell.table.size.map(|s| s / 2.0);
    let corners = (0..8)
        .map(|i| Point3::new(w.x[i & 1], w.y[(i >> 1) & 1], w.z[(i >> 2) & 1]))
        .chain((0..4).map(|i| Point3::new([-tx, tx][i & 1], [-ty, ty][i >> 1], 0.0)));
    corners
        .map(|p| (projector.t_view_world * p).z)
        .filter(|&z| z > 0.0)
        .map(|z| lens.sigma_px(z))
        .fold(0.0, f32::max)
        .min(LEVELS[LEVELS.len() - 1])
}

/// Projector pixels that one camera pixel spans where the optical axes meet the table,
/// rounded to a whole box-filter width.
fn footprint(camera: &Camera, projector: &Camera) -> usize {
    let mm_per_camera_px = camera.centre().coords.norm() / camera.k[(0, 0)];
    let projector_px_per_mm = projector.k[(0, 0)] / projector.centre().coords.norm();
    let span = mm_per_camera_px * projector_px_per_mm;
    if span.is_finite() {
        span.round().clamp(1.0, 16.0) as usize
    } else {
        1
    }
}

/// The lamp's view for its shadow map: from the lamp towards the bounding sphere of what
/// can cast a shadow (all but the table), just wide enough to hold it. `None` when the
/// lamp is off, nothing can cast a shadow, or the lamp hangs inside that sphere.
fn lamp_view(scene: &SceneSpec, triangles: &[SceneTriangle]) -> Option<View> {
    if scene.lamp_strength.is_nan() || scene.lamp_strength <= 0.0 {
        return None;
    }
    let mut points = triangles.iter().filter(|t| t.id != ID_TABLE).flat_map(|t| t.vertices);
    let first = points.next()?;
    let (lo, hi) = points.fold((first, first), |(lo, hi), p| (lo.inf(&p), hi.sup(&p)));
    let centre = Point3::from((lo.coords + hi.coords) / 2.0);
    let radius = (hi - lo).norm() / 2.0;
    let distance = (scene.lamp_position - centre).norm();
    if distance.is_nan() || distance <= 1.05 * radius {
        return None;
    }
    let half_angle = (radius / distance).asin() * 1.02;
    let focal = (LAMP_MAP_SIZE as f64 / 2.0) / half_angle.tan();
    let pose = look_at(scene.lamp_position, centre, 0.0);
    View::new(&Camera::ideal(LAMP_MAP_SIZE, LAMP_MAP_SIZE, focal, pose)).ok()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::scenario::draw_scenario;
    use crate::scene::{ID_FIRST_ITEM, ID_TRAY};
    use camplace_config::Vergence;
    use nalgebra::Point2;

    fn placements() -> [Placement; 3] {
        let p = Cell::default().placement;
        [
            Placement { vergence: Vergence::Degrees(0.0), ..p },
            Placement { vergence: Vergence::Degrees(3.5), baseline: 81.0, ..p },
            Placement { vergence: Vergence::Auto, alpha: 15.0, r: 700.0, ..p },
        ]
    }

    #[test]
    fn depth_is_true_on_table_and_rim() {
        let cell = Cell::default();
        for (k, placement) in placements().into_iter().enumerate() {
            let mut sim = Simulator::new(&cell, &placement, 1).unwrap();
            let scenario = draw_scenario(&cell, 11, k as u64);
            let mut frame = Frame::default();
            sim.render(&scenario.scene(), Method::OneShot, 5, &mut frame);
            let tray_world = scenario.t_world_tray.inverse();
            for (cam, depth, ids) in [
                (&sim.rig().left, &frame.depth_left, &frame.ids_left),
                (&sim.rig().right, &frame.depth_right, &frame.ids_right),
            ] {
                let (mut table, mut rim) = (0, 0);
                for y in 0..depth.height {
                    for x in 0..depth.width {
                        let d = depth.get(x, y) as f64;
                        if !d.is_finite() {
                            continue;
                        }
                        let p = cam.back_project(x as f64, y as f64, d);
                        match ids.get(x, y) {
                            ID_TABLE => {
                                assert!(p.z.abs() < 0.1, "table pixel ({x}, {y}) at z = {}", p.z);
                                table += 1;
                            }
                            ID_TRAY => {
                                let q = tray_world * p;
                                if sim.objects().tray.on_rim_top(q.x, q.y, 0.5) {
                                    assert!((q.z - sim.objects().tray.rim_height).abs() < 0.1, "rim at {q}");
                                    rim += 1;
                                }
                            }
                            _ => {}
                        }
                    }
                }
                assert!(table > 100_000 && rim > 500, "{placement}: {table} table and {rim} rim pixels");
            }
        }
    }

    #[test]
    fn a_distorted_camera_sees_the_table_where_its_rays_meet_it() {
        let mut cell = Cell::default();
        cell.sensor.camera_dist = [-0.2, 0.06, 0.001, -0.0008, 0.0];
        let mut sim = Simulator::new(&cell, &cell.placement, 1).unwrap();
        let plain = Simulator::new(&Cell::default(), &cell.placement, 1).unwrap();
        let scenario = draw_scenario(&cell, 11, 2);
        let (mut frame, mut undistorted) = (Frame::default(), Frame::default());
        sim.render(&scenario.scene(), Method::OneShot, 5, &mut frame);
        let mut plain = plain;
        plain.render(&scenario.scene(), Method::OneShot, 5, &mut undistorted);
        assert_eq!((frame.shots.left[0].width, frame.shots.left[0].height), (640, 480));
        for (cam, depth, ids) in [
            (&sim.rig().left, &frame.depth_left, &frame.ids_left),
            (&sim.rig().right, &frame.depth_right, &frame.ids_right),
        ] {
            let mut table = 0;
            for y in 0..depth.height {
                for x in 0..depth.width {
                    let d = depth.get(x, y) as f64;
                    if d.is_finite() && ids.get(x, y) == ID_TABLE {
                        // Depth and ids come from the nearest canvas pixel, up to half a
                        // pixel away along the sloping table.
                        let p = cam.back_project(x as f64, y as f64, d);
                        assert!(p.z.abs() < 1.5, "table pixel ({x}, {y}) at z = {}", p.z);
                        table += 1;
                    }
                }
            }
            assert!(table > 100_000, "{table} table pixels");
        }
        // Barrel distortion pulls the corners in: the image differs from the pinhole one.
        let differ =
            frame.shots.left[0].data.iter().zip(&undistorted.shots.left[0].data).filter(|(a, b)| a != b).count();
        assert!(differ > frame.shots.left[0].data.len() / 2, "{differ} pixels differ");
        // The noise is the sensor's: the same key gives the same images on any thread count.
        let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
        let mut again = Frame::default();
        pool.install(|| sim.render(&scenario.scene(), Method::OneShot, 5, &mut again));
        assert!(again == frame);
    }

    /// Convex hull of points, counter-clockwise in image coordinates' maths orientation.
    fn hull(mut p: Vec<Point2<f64>>) -> Vec<Point2<f64>> {
        p.sort_by(|a, b| a.x.total_cmp(&b.x).then(a.y.total_cmp(&b.y)));
        let cross =
            |o: &Point2<f64>, a: &Point2<f64>, b: &Point2<f64>| (a.x - o.x) * (b.y - o.y) - (a.y - o.y) * (b.x - o.x);
        let mut h: Vec<Point2<f64>> = Vec::new();
        for pass in 0..2 {
            let start = h.len();
            let iter: Box<dyn Iterator<Item = &Point2<f64>>> =
                if pass == 0 { Box::new(p.iter()) } else { Box::new(p.iter().rev()) };
            for q in iter {
                while h.len() >= start + 2 && cross(&h[h.len() - 2], &h[h.len() - 1], q) <= 0.0 {
                    h.pop();
                }
                h.push(*q);
            }
            h.pop();
        }
        h
    }

    /// Smallest signed distance of `q` to the hull's edge lines, positive inside.
    fn inside_by(h: &[Point2<f64>], q: &Point2<f64>) -> f64 {
        (0..h.len())
            .map(|i| {
                let (a, b) = (h[i], h[(i + 1) % h.len()]);
                let e = b - a;
                (e.x * (q.y - a.y) - e.y * (q.x - a.x)) / e.norm()
            })
            .fold(f64::INFINITY, f64::min)
    }

    #[test]
    fn tray_outline_lands_where_the_rig_projects_it() {
        let cell = Cell::default();
        for placement in placements() {
            let mut sim = Simulator::new(&cell, &placement, 1).unwrap();
            let mut scene = draw_scenario(&cell, 4, 1).scene();
            scene.filled.clear();
            let mut frame = Frame::default();
            sim.render_clean(&scene, Method::OneShot, &mut frame);
            let tray = &sim.objects().tray;
            let corners = |x: [f64; 2], y: [f64; 2], z: [f64; 2]| {
                let mut out = Vec::new();
                for (a, b, c) in itertools_product(x, y, z) {
                    let p = scene.t_world_tray * Point3::new(a, b, c);
                    out.push(sim.rig().left.project(&p).unwrap());
                }
                hull(out)
            };
            let [hx, hy] = tray.outer.map(|v| v / 2.0);
            let body = corners([-hx, hx], [-hy, hy], [0.0, tray.rim_height]);
            let [tx, ty, tz] = crate::scene::tray::TAB_SIZE;
            let tab = corners([hx, hx + tx], [-ty / 2.0, ty / 2.0], [0.0, tz]);
            let (mut inside, mut outside) = (0, 0);
            let ids = &frame.ids_left;
            for y in 0..ids.height {
                for x in 0..ids.width {
                    let q = Point2::new(x as f64, y as f64);
                    let d = inside_by(&body, &q);
                    if d > 0.5 {
                        assert_eq!(ids.get(x, y), ID_TRAY, "({x}, {y}) is {d} px inside the outline");
                        inside += 1;
                    } else if d < -0.5 && inside_by(&tab, &q) < -0.5 {
                        assert_eq!(ids.get(x, y), ID_TABLE, "({x}, {y}) is {} px outside the outline", -d);
                        outside += 1;
                    }
                }
            }
            assert!(inside > 5_000 && outside > 100_000, "{inside} {outside}");
        }
    }

    fn itertools_product(x: [f64; 2], y: [f64; 2], z: [f64; 2]) -> impl Iterator<Item = (f64, f64, f64)> {
        x.into_iter().flat_map(move |a| y.into_iter().flat_map(move |b| z.into_iter().map(move |c| (a, b, c))))
    }

    #[test]
    fn images_do_not_depend_on_the_thread_count() {
        let cell = Cell::default();
        let scene = draw_scenario(&cell, 1, 3).scene();
        let run = |threads: usize, pattern_seed: u64, noise_key: u64, method: Method| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            let mut sim = Simulator::new(&cell, &cell.placement, pattern_seed).unwrap();
            let mut frame = Frame::default();
            pool.install(|| sim.render(&scene, method, noise_key, &mut frame));
            frame
        };
        for method in [Method::OneShot, Method::Phase12] {
            let a = run(1, 1, 9, method);
            let b = run(2, 1, 9, method);
            assert_eq!(a.shots.left.len(), if method == Method::OneShot { 1 } else { 12 });
            assert!(a == b, "{method}: one and two threads differ");
        }
        let differ = |a: &GrayImage, b: &GrayImage| a.data.iter().zip(&b.data).filter(|(p, q)| p != q).count();
        let a = run(2, 1, 9, Method::OneShot);
        let other_noise = run(2, 1, 10, Method::OneShot);
        assert!(differ(&a.shots.left[0], &other_noise.shots.left[0]) > a.shots.left[0].data.len() / 2);
        assert!(differ(&a.shots.right[0], &other_noise.shots.right[0]) > a.shots.right[0].data.len() / 2);
        // Another pattern seed moves the dots even without noise.
        let mut sim1 = Simulator::new(&cell, &cell.placement, 1).unwrap();
        let mut sim2 = Simulator::new(&cell, &cell.placement, 2).unwrap();
        let (mut f1, mut f2) = (Frame::default(), Frame::default());
        sim1.render_clean(&scene, Method::OneShot, &mut f1);
        sim2.render_clean(&scene, Method::OneShot, &mut f2);
        assert!(differ(&f1.shots.left[0], &f2.shots.left[0]) > f1.shots.left[0].data.len() / 4);
        assert_eq!(f1.depth_left, f2.depth_left);
    }

    #[test]
    fn fringe_pairs_drawn_from_their_sum_are_the_shots_rendered_alone() {
        // Defocused, with lens distortion and without, in focus and far out of it, with
        // noise and clean: only float rounding may tell the two apart.
        let mut distorted = Cell::default();
        distorted.sensor.camera_dist = [-0.1, 0.05, 0.0005, -0.0003, 0.0];
        let mut near_focus = Cell::default();
        near_focus.optics.camera_focus = camplace_config::Focus::Distance(400.0);
        near_focus.optics.camera_f_number = 1.4;
        for cell in [Cell::default(), distorted, near_focus] {
            for scenario in [2, 5] {
                let scene = draw_scenario(&cell, 1, scenario).scene();
                let mut sim = Simulator::new(&cell, &cell.placement, 1).unwrap();
                assert!(sim.camera_lenses[0].is_some());
                for noise in [Some(7), None] {
                    let mut render = |one_by_one: bool| {
                        sim.fringes_one_by_one = one_by_one;
                        let mut frame = Frame::default();
                        sim.render_with(&scene, Method::Phase12, noise, &mut frame);
                        frame
                    };
                    let (pairs, alone) = (render(false), render(true));
                    for (a, b) in pairs
                        .shots
                        .left
                        .iter()
                        .chain(&pairs.shots.right)
                        .zip(alone.shots.left.iter().chain(&alone.shots.right))
                    {
                        let off: Vec<u8> = a.data.iter().zip(&b.data).map(|(p, q)| p.abs_diff(*q)).collect();
                        assert!(off.iter().all(|&d| d <= 1), "a shot differs by more than a grey level");
                        assert!(off.iter().filter(|&&d| d > 0).count() <= a.data.len() / 1000);
                    }
                    assert_eq!(pairs.depth_left, alone.depth_left);
                }
            }
        }
    }

    #[test]
    fn runs_give_the_terms_of_one_pixel_at_a_time() {
        // Every effect on, glossy items and table too, with lens distortion and without,
        // the lamp on and off, at three placements: the terms, the truth and the images
        // are the same bits whichever way the terms were computed.
        let mut glossy = Cell::default();
        glossy.table.specular = 0.3;
        glossy.table.roughness = 0.2;
        glossy.items.specular = 0.5;
        glossy.items.roughness = 0.05;
        let mut distorted = Cell::default();
        distorted.sensor.camera_dist = [-0.1, 0.05, 0.0005, -0.0003, 0.0];
        let plain = Cell {
            effects: camplace_config::Effects {
                defocus: false,
                specular: false,
                calibration_error: false,
                occluder: false,
            },
            ..Cell::default()
        };
        let mut lit_pixels = 0;
        for (c, cell) in [Cell::default(), glossy, distorted, plain].into_iter().enumerate() {
            for (k, placement) in placements().into_iter().enumerate() {
                let mut scene = draw_scenario(&cell, 3, (c * 3 + k) as u64).scene();
                if k == 1 {
                    scene.lamp_strength = 0.0;
                }
                let mut sim = Simulator::new(&cell, &placement, 1).unwrap();
                let mut render = |one_by_one: bool| {
                    sim.terms_one_by_one = one_by_one;
                    let mut frame = Frame::default();
                    sim.render(&scene, Method::OneShot, 9, &mut frame);
                    (frame, sim.terms.clone())
                };
                let ((runs, run_terms), (pixels, pixel_terms)) = (render(false), render(true));
                assert_eq!(runs, pixels, "cell {c}, placement {k}");
                for (a, b) in run_terms.iter().zip(&pixel_terms) {
                    let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                    assert_eq!(bits(&a.base), bits(&b.base), "cell {c}, placement {k}: base");
                    assert_eq!(bits(&a.projector), bits(&b.projector), "cell {c}, placement {k}: projector");
                    for i in (0..a.projector.len()).filter(|&i| a.projector[i] > 0.0) {
                        lit_pixels += 1;
                        let uv = |t: &ShadingTerms| t.projector_uv[i].map(f32::to_bits);
                        assert_eq!(uv(a), uv(b), "cell {c}, placement {k}: uv of pixel {i}");
                        if a.defocused {
                            let blur = |t: &ShadingTerms| (t.projector_blur[i].0, t.projector_blur[i].1.to_bits());
                            assert_eq!(blur(a), blur(b), "cell {c}, placement {k}: blur of pixel {i}");
                        }
                    }
                }
            }
        }
        assert!(lit_pixels > 1_000_000, "{lit_pixels} lit pixels compared");
    }

    #[test]
    fn dots_span_one_and_a_half_to_three_camera_pixels() {
        let cell = Cell::default();
        let mut sim = Simulator::new(&cell, &cell.placement, 1).unwrap();
        let mut scene = draw_scenario(&cell, 1, 0).scene();
        scene.filled.clear();
        let mut frame = Frame::default();
        sim.render_clean(&scene, Method::OneShot, &mut frame);
        // Projector pixels per camera pixel, from neighbouring pixels on one surface.
        let t = &sim.terms[0];
        let w = t.width;
        let tri = &sim.zbuffers[0].triangle;
        let mut spans: Vec<f64> = (0..t.base.len() - w - 1)
            .filter(|&i| [i + 1, i + w].iter().all(|&j| t.projector_lit(j) && tri[j] == tri[i]) && t.projector_lit(i))
            .map(|i| {
                let (s, sx, sy) = (t.projector_uv[i], t.projector_uv[i + 1], t.projector_uv[i + w]);
                let dx = (sx[0] - s[0]).hypot(sx[1] - s[1]) as f64;
                let dy = (sy[0] - s[0]).hypot(sy[1] - s[1]) as f64;
                (dx * dy).sqrt()
            })
            .collect();
        spans.sort_by(f64::total_cmp);
        let median = spans[spans.len() / 2];
        let dot = cell.sensor.dot_size as f64 / median;
        assert!((1.5..=3.0).contains(&dot), "a dot spans {dot} camera pixels");
    }

    #[test]
    fn noise_variance_matches_the_theory() {
        let mut cell = Cell::default();
        cell.sensor.projector_gain = 0.0;
        let mut sim = Simulator::new(&cell, &cell.placement, 1).unwrap();
        let mut scene = draw_scenario(&cell, 1, 0).scene().background();
        scene.ambient = 0.8;
        scene.lamp_strength = 0.0;
        let (mut noisy, mut clean) = (Frame::default(), Frame::default());
        sim.render(&scene, Method::OneShot, 77, &mut noisy);
        sim.render_clean(&scene, Method::OneShot, &mut clean);
        let (w, h) = (noisy.shots.left[0].width, noisy.shots.left[0].height);
        let (mut n, mut sum, mut sum2) = (0.0, 0.0, 0.0);
        for img in 0..2 {
            let (a, b) = if img == 0 {
                (&noisy.shots.left[0], &clean.shots.left[0])
            } else {
                (&noisy.shots.right[0], &clean.shots.right[0])
            };
            for y in 1..h - 1 {
                for x in 1..w - 1 {
                    assert_eq!(b.get(x, y), b.get(1, 1), "the clean image is flat");
                    let d = a.get(x, y) as f64 - b.get(x, y) as f64;
                    n += 1.0;
                    sum += d;
                    sum2 += d * d;
                }
            }
        }
        let mean = sum / n;
        let var = sum2 / n - mean * mean;
        let a = cell.sensor.noise_amplitude as f64;
        let b = cell.sensor.blur as f64;
        let want = ((2.0 * a + 1.0).powi(2) - 1.0) / 12.0 / (b * b) + 1.0 / 12.0;
        assert!((var / want - 1.0).abs() < 0.04, "variance {var}, theory {want}");
        assert!(mean.abs() < 0.5, "mean {mean}");
    }

    #[test]
    fn tray_is_bright_items_dark_and_items_cast_projector_shadows() {
        let cell = Cell::default();
        let mut sim = Simulator::new(&cell, &cell.placement, 1).unwrap();
        let mut full = draw_scenario(&cell, 1, 6).scene();
        full.filled = (0..8).collect();
        let mut frame = Frame::default();
        sim.render(&full, Method::OneShot, 1, &mut frame);
        let (mut tray, mut items) = ((0.0, 0.0), (0.0, 0.0));
        for (&g, &id) in frame.shots.left[0].data.iter().zip(&frame.ids_left.data) {
            let acc = match id {
                ID_TRAY => &mut tray,
                id if id >= ID_FIRST_ITEM => &mut items,
                _ => continue,
            };
            acc.0 += g as f64;
            acc.1 += 1.0;
        }
        let (tray, items) = (tray.0 / tray.1, items.0 / items.1);
        assert!(tray > 3.0 * items && tray > 60.0, "tray {tray}, items {items}");
        let shadowed = |sim: &Simulator, ids: &GrayImage| -> Vec<bool> {
            (0..ids.data.len()).map(|i| ids.data[i] == ID_TRAY && !sim.terms[0].projector_lit(i)).collect()
        };
        let with_items = shadowed(&sim, &frame.ids_left);
        let item_pixels: Vec<usize> = (0..frame.ids_left.data.len()).filter(|&i| frame.ids_left.data[i] >= 2).collect();
        let mut empty = full.clone();
        empty.filled.clear();
        let mut frame2 = Frame::default();
        sim.render(&empty, Method::OneShot, 1, &mut frame2);
        let without = shadowed(&sim, &frame2.ids_left);
        let w = frame.ids_left.width as i64;
        let new: Vec<usize> = (0..with_items.len())
            .filter(|&i| with_items[i] && !without[i] && frame2.ids_left.data[i] == ID_TRAY)
            .collect();
        let near_item = new
            .iter()
            .filter(|&&i| {
                let (x, y) = (i as i64 % w, i as i64 / w);
                item_pixels.iter().any(|&j| {
                    let (u, v) = (j as i64 % w, j as i64 / w);
                    (u - x).abs() <= 10 && (v - y).abs() <= 10
                })
            })
            .count();
        assert!(new.len() > 100, "only {} new projector-shadow pixels on the tray", new.len());
        assert!(near_item as f64 >= 0.95 * new.len() as f64, "{near_item} of {} next to items", new.len());
    }
}
