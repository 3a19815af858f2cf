//! The tray model the estimator loads: features with tray-frame positions for matching, and
//! one ICP cloud per viewpoint for scoring and refinement; its versioned binary encoding.
//! Building a model from rendered views is the simulator's job; the `testing` fixtures make
//! a box tray and scenes of it analytically, for tests and benches.
//!
//! Points are `f32` like every cloud; poses are `f64` like every calibrated transform.

use camplace_config::ContentHash;
use nalgebra::{Isometry3, Point3, Vector3};

use crate::error::{Error, ErrorKind, Result};
use crate::features::{quantise, QUANTISATION_STEPS};

/// Version of the binary layout written by [`Model::to_bytes`]. Version 4 added the `VRFY`
/// section (the verification threshold measured in simulation). Version 3 stores points as
/// 16-bit multiples of a power-of-two step, normals in 16-bit octahedral coordinates and
/// descriptors as the bytes the matcher compares; version 2 added the `ORIG` section.
/// Versions 1 to 3 still read (1 and 2 hold everything as `f32`, 1 has no origin); they
/// carry no verification threshold, so the cell's `estimator.verify_threshold` applies.
pub const MODEL_FORMAT_VERSION: u32 = 4;

/// First bytes of every model file.
pub const MODEL_MAGIC: [u8; 8] = *b"CPLMODEL";

/// Length of an ECSAD descriptor.
pub const DESCRIPTOR_LEN: usize = 30;

/// The tray as the estimator knows it.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Model {
    /// Voxel size the model clouds were down-sampled to, mm.
    pub surface_resolution: f32,
    /// Feature key points, tray frame, mm.
    pub feature_points: Vec<Point3<f32>>,
    /// Unit surface normal at each feature key point, tray frame.
    pub feature_normals: Vec<Vector3<f32>>,
    /// ECSAD descriptor of each feature key point.
    pub descriptors: Vec<[f32; DESCRIPTOR_LEN]>,
    /// One ICP cloud per viewpoint.
    pub views: Vec<ModelView>,
    /// Rotations about tray z (deg) that map the tray onto itself; the identity is implied.
    pub symmetries_deg: Vec<f32>,
    /// What the model was built from; `None` for a model of unknown origin (a version 1
    /// file, a test fixture).
    pub origin: Option<ModelOrigin>,
    /// The verification threshold measured in simulation for this model; `None` when it was
    /// not measured (a file older than version 4, a test fixture).
    pub verification: Option<ModelVerification>,
}

/// The verification threshold a model carries and what it was measured on, so that the
/// deployed estimator applies exactly what simulation measured.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ModelVerification {
    /// Scores at or above this are accepted, in [0, 1].
    pub threshold: f32,
    /// The largest share of wrong poses among the accepted ones it was chosen for.
    pub max_wrong: f32,
    /// Scenes simulated.
    pub scenes: u32,
    /// Of them, poses accepted at the threshold.
    pub accepted: u32,
    /// Of those, wrong ones (outside the success limits).
    pub wrong_accepted: u32,
    /// One-sided 95 % upper bound (Clopper–Pearson) of the wrong share among accepted poses.
    pub wrong_upper: f32,
}

/// What a model was built from, so that a model of another tray or cell can be refused.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct ModelOrigin {
    /// The hash of the whole cell (every setting and its mesh files' bytes).
    pub cell_hash: ContentHash,
    /// The tray as the cell names it (`tray-8`, `tray-4`, `mesh NAME`).
    pub tray: String,
    /// The hash of the tray's and its items' geometry.
    pub tray_hash: ContentHash,
    /// The capture method (`one-shot`, `phase-12`).
    pub method: String,
    /// The seed of the pattern and the camera noise.
    pub seed: u64,
    /// The placement, as `r=..,alpha=..,baseline=..,vergence=..`.
    pub placement: String,
}

/// The tray seen from one viewpoint: its fill states merged and down-sampled.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ModelView {
    /// Unit direction from the tray towards the sensor, tray frame.
    pub view_direction: Vector3<f32>,
    /// Surface points, tray frame, mm.
    pub points: Vec<Point3<f32>>,
    /// Unit surface normal at each point, tray frame.
    pub normals: Vec<Vector3<f32>>,
}

const TAG_HEAD: [u8; 4] = *b"HEAD";
const TAG_FEAT: [u8; 4] = *b"FEAT";
const TAG_VIEW: [u8; 4] = *b"VIEW";
const TAG_SYMM: [u8; 4] = *b"SYMM";
const TAG_ORIG: [u8; 4] = *b"ORIG";
const TAG_VRFY: [u8; 4] = *b"VRFY";
/// The `VRFY` payload of a measured threshold: threshold, max wrong, upper bound (f32) and
/// scenes, accepted, wrong accepted (u32).
const VERIFICATION_BYTES: usize = 6 * 4;
/// Longest text an `ORIG` section may hold in one field.
const MAX_ORIGIN_TEXT: usize = 4096;
/// Magic, version and body length.
const PREAMBLE_LEN: usize = 8 + 4 + 8;
/// A feature in versions 1 and 2: point, normal, descriptor, all f32.
const FEATURE_BYTES_F32: usize = 4 * (3 + 3 + DESCRIPTOR_LEN);
/// A view point in versions 1 and 2: point and normal, f32.
const VIEW_POINT_BYTES_F32: usize = 4 * 6;
/// A feature in version 3: point i16×3, normal i16×2, descriptor u8×30.
const FEATURE_BYTES: usize = 2 * 3 + 2 * 2 + DESCRIPTOR_LEN;
/// A view point in version 3: point i16×3, normal i16×2.
const VIEW_POINT_BYTES: usize = 2 * 3 + 2 * 2;
/// The largest magnitude a 16-bit point coordinate holds, in steps.
const MAX_STEPS: f32 = 32767.0;
/// The smallest step of the 16-bit points, as a power of two (mm).
const MIN_STEP_EXP: i32 = -20;
/// The largest step of the 16-bit points, as a power of two (mm).
const MAX_STEP_EXP: i32 = 20;

impl Model {
    /// Checks that the parallel arrays agree and every number is usable.
    pub fn validate(&self) -> Result<()> {
        let bad = |msg: String| Err(Error::new(ErrorKind::Model, format!("model: {msg}")));
        if !(self.surface_resolution.is_finite() && self.surface_resolution > 0.0) {
            return bad(format!("expected a positive surface_resolution, found {}", self.surface_resolution));
        }
        let n = self.feature_points.len();
        if self.feature_normals.len() != n || self.descriptors.len() != n {
            return bad(format!(
                "expected as many feature normals and descriptors as feature points ({n}), found {} and {}",
                self.feature_normals.len(),
                self.descriptors.len()
            ));
        }
        if let Some(i) = self.feature_points.iter().position(|p| !finite3(&p.coords)) {
            return bad(format!("expected finite feature points, point {i} is not"));
        }
        if let Some(i) = self.feature_normals.iter().position(|v| !finite3(v)) {
            return bad(format!("expected finite feature normals, normal {i} is not"));
        }
        if let Some(i) = self.descriptors.iter().position(|d| !d.iter().all(|v| v.is_finite())) {
            return bad(format!("expected finite descriptors, descriptor {i} is not"));
        }
        for (k, view) in self.views.iter().enumerate() {
            let norm = view.view_direction.norm();
            if !(norm - 1.0).abs().lt(&1e-3) {
                return bad(format!("expected a unit view direction in view {k}, found length {norm}"));
            }
            if view.normals.len() != view.points.len() {
                return bad(format!(
                    "expected as many normals as points in view {k} ({}), found {}",
                    view.points.len(),
                    view.normals.len()
                ));
            }
            if view.points.iter().any(|p| !finite3(&p.coords)) || view.normals.iter().any(|v| !finite3(v)) {
                return bad(format!("expected finite points and normals in view {k}"));
            }
        }
        if let Some(s) = self.symmetries_deg.iter().find(|s| !s.is_finite()) {
            return bad(format!("expected finite symmetry angles, found {s}"));
        }
        if let Some(v) = &self.verification {
            let share = |x: f32| (0.0..=1.0).contains(&x);
            if !(share(v.threshold) && share(v.max_wrong) && share(v.wrong_upper)) {
                return bad(format!(
                    "expected the verification's threshold, max wrong and upper bound in [0, 1], found {}, {} and {}",
                    v.threshold, v.max_wrong, v.wrong_upper
                ));
            }
            if v.accepted > v.scenes || v.wrong_accepted > v.accepted {
                return bad(format!(
                    "expected wrong accepted <= accepted <= scenes in the verification, found {} <= {} <= {}",
                    v.wrong_accepted, v.accepted, v.scenes
                ));
            }
        }
        Ok(())
    }

    /// The viewpoint whose view direction is closest to the direction from the tray, posed at
    /// `t_world_tray`, towards the sensor.
    pub fn closest_view(&self, t_world_tray: &Isometry3<f64>, sensor_position_world: &Point3<f32>) -> usize {
        let towards_sensor = t_world_tray.inverse_transform_point(&sensor_position_world.cast::<f64>()).coords;
        let mut best = (0, f64::NEG_INFINITY);
        for (k, view) in self.views.iter().enumerate() {
            let score = view.view_direction.cast::<f64>().dot(&towards_sensor);
            if score > best.1 {
                best = (k, score);
            }
        }
        best.0
    }

    /// The model in its binary file layout (little endian), format version 4:
    /// magic `CPLMODEL`, format version (u32), body length (u64), body, CRC-32 of all before.
    /// The body is tagged sections, each `tag[4] length(u64) payload`: `HEAD` (surface
    /// resolution f32, feature, view and symmetry counts u32), `FEAT` (the step s f32, then
    /// per feature: point as i16×3 in steps of s mm, normal as i16×2 octahedral coordinates,
    /// descriptor as u8×30 in steps of pi/255 rad), one `VIEW` per viewpoint (direction
    /// f32×3, point count u32, step f32, then per point i16×3 and i16×2 as in `FEAT`),
    /// `SYMM` (angles f32, deg) and `ORIG` (empty for an unknown origin, else the cell hash
    /// and the tray hash, 32 bytes each, the seed u64, then the tray, method and placement
    /// as u32 length and UTF-8 text) and `VRFY` (empty when no threshold was measured, else
    /// the threshold, the max wrong share and the upper bound as f32, then the scenes, the
    /// accepted and the wrong accepted poses as u32). Each step is the power of two that fits the section's
    /// largest coordinate into i16: 1/64 mm or finer for anything within 500 mm of the
    /// tray's origin. Versions 1 and 2 held every number as f32.
    ///
    /// Encoding rounds: points move by at most half a step, normals turn by less than
    /// 0.006 deg, and descriptors keep exactly what the matcher compares.
    pub fn to_bytes(&self) -> Vec<u8> {
        debug_assert!(self.validate().is_ok(), "a model to write must be valid");
        self.encode(MODEL_FORMAT_VERSION)
    }

    /// The layout of format `version` (1 to 4); versions 1 to 3 for tests of old files.
    fn encode(&self, version: u32) -> Vec<u8> {
        let compact = version >= 3;
        let (feature_bytes, point_bytes, step_bytes) =
            if compact { (FEATURE_BYTES, VIEW_POINT_BYTES, 4) } else { (FEATURE_BYTES_F32, VIEW_POINT_BYTES_F32, 0) };
        let view_bytes: usize = self.views.iter().map(|v| 12 + 16 + step_bytes + v.points.len() * point_bytes).sum();
        let origin = self.origin.as_ref().map(encode_origin).unwrap_or_default();
        let origin_bytes = if version >= 2 { 12 + origin.len() } else { 0 };
        let verification_len = if self.verification.is_some() { VERIFICATION_BYTES } else { 0 };
        let verification_bytes = if version >= 4 { 12 + verification_len } else { 0 };
        let body_len = (12 + 16)
            + (12 + step_bytes + self.feature_points.len() * feature_bytes)
            + view_bytes
            + (12 + 4 * self.symmetries_deg.len())
            + origin_bytes
            + verification_bytes;
        let mut out = Vec::with_capacity(PREAMBLE_LEN + body_len + 4);
        out.extend_from_slice(&MODEL_MAGIC);
        out.extend_from_slice(&version.to_le_bytes());
        out.extend_from_slice(&(body_len as u64).to_le_bytes());

        section(&mut out, TAG_HEAD, 16);
        put_f32(&mut out, self.surface_resolution);
        put_u32(&mut out, self.feature_points.len() as u32);
        put_u32(&mut out, self.views.len() as u32);
        put_u32(&mut out, self.symmetries_deg.len() as u32);

        section(&mut out, TAG_FEAT, step_bytes + self.feature_points.len() * feature_bytes);
        let step = if compact { position_step(&self.feature_points) } else { 0.0 };
        if compact {
            put_f32(&mut out, step);
        }
        for ((p, n), d) in self.feature_points.iter().zip(&self.feature_normals).zip(&self.descriptors) {
            if compact {
                put_point_i16(&mut out, p, step);
                put_normal_oct(&mut out, n);
                out.extend(quantise(d).iter().map(|&q| q as u8));
            } else {
                put_vec3(&mut out, &p.coords);
                put_vec3(&mut out, n);
                for v in d {
                    put_f32(&mut out, *v);
                }
            }
        }
        for view in &self.views {
            section(&mut out, TAG_VIEW, 16 + step_bytes + view.points.len() * point_bytes);
            put_vec3(&mut out, &view.view_direction);
            put_u32(&mut out, view.points.len() as u32);
            let step = if compact { position_step(&view.points) } else { 0.0 };
            if compact {
                put_f32(&mut out, step);
            }
            for (p, n) in view.points.iter().zip(&view.normals) {
                if compact {
                    put_point_i16(&mut out, p, step);
                    put_normal_oct(&mut out, n);
                } else {
                    put_vec3(&mut out, &p.coords);
                    put_vec3(&mut out, n);
                }
            }
        }
        section(&mut out, TAG_SYMM, 4 * self.symmetries_deg.len());
        for s in &self.symmetries_deg {
            put_f32(&mut out, *s);
        }
        if version >= 2 {
            section(&mut out, TAG_ORIG, origin.len());
            out.extend_from_slice(&origin);
        }
        if version >= 4 {
            section(&mut out, TAG_VRFY, verification_len);
            if let Some(v) = &self.verification {
                for x in [v.threshold, v.max_wrong, v.wrong_upper] {
                    put_f32(&mut out, x);
                }
                for n in [v.scenes, v.accepted, v.wrong_accepted] {
                    put_u32(&mut out, n);
                }
            }
        }
        let crc = crc32(&out);
        put_u32(&mut out, crc);
        out
    }

    /// Decodes [`Model::to_bytes`]'s layout, and versions 1 and 2 (all `f32`, version 1
    /// without `ORIG`), rounded as version 3 holds them; a wrong
    /// magic, another version, a truncated or corrupted file each give an
    /// [`ErrorKind::Model`] error saying what was expected.
    pub fn from_bytes(bytes: &[u8]) -> Result<Model> {
        let err = |msg: String| Error::new(ErrorKind::Model, format!("model: {msg}"));
        if bytes.len() < MODEL_MAGIC.len() || bytes[..MODEL_MAGIC.len()] != MODEL_MAGIC {
            let found = &bytes[..bytes.len().min(MODEL_MAGIC.len())];
            return Err(err(format!(
                "expected a camplace model starting with \"CPLMODEL\", found {:?}",
                String::from_utf8_lossy(found)
            )));
        }
        if bytes.len() < PREAMBLE_LEN {
            return Err(err(format!(
                "truncated: expected at least {} bytes of header, found {}",
                PREAMBLE_LEN + 4,
                bytes.len()
            )));
        }
        let version = u32::from_le_bytes(bytes[8..12].try_into().expect("4 bytes"));
        if !(1..=MODEL_FORMAT_VERSION).contains(&version) {
            return Err(err(format!(
                "expected format version 1 to {MODEL_FORMAT_VERSION}, found version {version} (rebuild the model with this camplace)"
            )));
        }
        let body_len = u64::from_le_bytes(bytes[12..20].try_into().expect("8 bytes"));
        let expected_total = (PREAMBLE_LEN as u64).saturating_add(body_len).saturating_add(4);
        if (bytes.len() as u64) < expected_total {
            return Err(err(format!("truncated: expected {expected_total} bytes, found {}", bytes.len())));
        }
        if (bytes.len() as u64) > expected_total {
            return Err(err(format!(
                "expected {expected_total} bytes, found {} (trailing data after the checksum)",
                bytes.len()
            )));
        }
        let end = PREAMBLE_LEN + body_len as usize;
        let stored = u32::from_le_bytes(bytes[end..end + 4].try_into().expect("4 bytes"));
        let computed = crc32(&bytes[..end]);
        if stored != computed {
            return Err(err(format!("corrupted: expected checksum {stored:#010x}, computed {computed:#010x}")));
        }

        let mut r = Reader { bytes: &bytes[..end], pos: PREAMBLE_LEN };
        let mut head = r.section(TAG_HEAD)?;
        let surface_resolution = head.f32("surface resolution")?;
        let n_features = head.u32("feature count")? as usize;
        let n_views = head.u32("view count")? as usize;
        let n_symmetries = head.u32("symmetry count")? as usize;
        head.finish()?;

        let compact = version >= 3;
        let mut feat = r.section(TAG_FEAT)?;
        let step = if compact { feat.step("the feature step")? } else { 0.0 };
        feat.expect_len(n_features, if compact { FEATURE_BYTES } else { FEATURE_BYTES_F32 }, "features")?;
        let mut feature_points = Vec::with_capacity(n_features);
        let mut feature_normals = Vec::with_capacity(n_features);
        let mut descriptors = Vec::with_capacity(n_features);
        for _ in 0..n_features {
            let mut d = [0.0; DESCRIPTOR_LEN];
            if compact {
                feature_points.push(feat.point_i16(step, "feature point")?);
                feature_normals.push(feat.normal_oct("feature normal")?);
                for (v, &q) in d.iter_mut().zip(feat.take(DESCRIPTOR_LEN, "descriptor")?) {
                    *v = f32::from(q) * (std::f32::consts::PI / QUANTISATION_STEPS);
                }
            } else {
                feature_points.push(Point3::from(feat.vec3("feature point")?));
                feature_normals.push(feat.vec3("feature normal")?);
                for v in &mut d {
                    *v = feat.f32("descriptor")?;
                }
            }
            descriptors.push(d);
        }
        feat.finish()?;

        if n_views > r.remaining() / 28 {
            return Err(err(format!("corrupted: {n_views} views cannot fit in the {} bytes left", r.remaining())));
        }
        let mut views = Vec::with_capacity(n_views);
        for _ in 0..n_views {
            let mut s = r.section(TAG_VIEW)?;
            let view_direction = s.vec3("view direction")?;
            let n = s.u32("view point count")? as usize;
            let step = if compact { s.step("the view step")? } else { 0.0 };
            s.expect_len(n, if compact { VIEW_POINT_BYTES } else { VIEW_POINT_BYTES_F32 }, "view points")?;
            let mut points = Vec::with_capacity(n);
            let mut normals = Vec::with_capacity(n);
            for _ in 0..n {
                if compact {
                    points.push(s.point_i16(step, "view point")?);
                    normals.push(s.normal_oct("view normal")?);
                } else {
                    points.push(Point3::from(s.vec3("view point")?));
                    normals.push(s.vec3("view normal")?);
                }
            }
            s.finish()?;
            views.push(ModelView { view_direction, points, normals });
        }

        let mut symm = r.section(TAG_SYMM)?;
        symm.expect_len(n_symmetries, 4, "symmetries")?;
        let symmetries_deg = (0..n_symmetries).map(|_| symm.f32("symmetry")).collect::<Result<Vec<_>>>()?;
        symm.finish()?;
        let origin = if version >= 2 { decode_origin(r.section(TAG_ORIG)?)? } else { None };
        let verification = if version >= 4 { decode_verification(r.section(TAG_VRFY)?)? } else { None };
        if r.remaining() != 0 {
            let last = match version {
                4.. => "VRFY",
                2 | 3 => "ORIG",
                _ => "SYMM",
            };
            return Err(err(format!(
                "expected the body to end after section {last}, found {} more bytes",
                r.remaining()
            )));
        }

        let model = Model {
            surface_resolution,
            feature_points,
            feature_normals,
            descriptors,
            views,
            symmetries_deg,
            origin,
            verification,
        };
        model.validate()?;
        // A model is what the current format holds, whichever version it was read from: an
        // older file's points and normals are rounded as version 3 rounds them, so it gives
        // the poses a model built now gives.
        let model = if compact { model } else { Model::from_bytes(&model.to_bytes())? };
        // A file from `camplace model` always has both; an estimator cannot run without.
        if model.feature_points.is_empty() || model.views.is_empty() {
            return Err(err(format!(
                "expected at least one feature and one view, found {} features and {} views",
                model.feature_points.len(),
                model.views.len()
            )));
        }
        Ok(model)
    }
}

fn encode_origin(o: &ModelOrigin) -> Vec<u8> {
    let mut out = Vec::new();
    out.extend_from_slice(&o.cell_hash.0);
    out.extend_from_slice(&o.tray_hash.0);
    out.extend_from_slice(&o.seed.to_le_bytes());
    for text in [&o.tray, &o.method, &o.placement] {
        // Names and placements are short; a longer text is cut (at a character) to what reads back.
        let end = (0..=text.len().min(MAX_ORIGIN_TEXT)).rev().find(|&i| text.is_char_boundary(i)).unwrap_or(0);
        put_u32(&mut out, end as u32);
        out.extend_from_slice(&text.as_bytes()[..end]);
    }
    out
}

/// The `ORIG` section: empty for an unknown origin.
fn decode_origin(mut s: Reader<'_>) -> Result<Option<ModelOrigin>> {
    if s.remaining() == 0 {
        return Ok(None);
    }
    let mut hash =
        |what: &str| -> Result<ContentHash> { Ok(ContentHash(s.take(32, what)?.try_into().expect("32 bytes"))) };
    let cell_hash = hash("the cell hash")?;
    let tray_hash = hash("the tray hash")?;
    let seed = u64::from_le_bytes(s.take(8, "the seed")?.try_into().expect("8 bytes"));
    let mut text = |what: &str| -> Result<String> {
        let n = s.u32(what)? as usize;
        if n > MAX_ORIGIN_TEXT {
            return Err(Error::new(
                ErrorKind::Model,
                format!("model: corrupted: expected {what} of at most {MAX_ORIGIN_TEXT} bytes, found length {n}"),
            ));
        }
        let bytes = s.take(n, what)?;
        String::from_utf8(bytes.to_vec())
            .map_err(|_| Error::new(ErrorKind::Model, format!("model: corrupted: expected {what} as UTF-8 text")))
    };
    let tray = text("the tray name")?;
    let method = text("the method")?;
    let placement = text("the placement")?;
    s.finish()?;
    Ok(Some(ModelOrigin { cell_hash, tray, tray_hash, method, seed, placement }))
}

/// The `VRFY` section: empty when no threshold was measured.
fn decode_verification(mut s: Reader<'_>) -> Result<Option<ModelVerification>> {
    if s.remaining() == 0 {
        return Ok(None);
    }
    let threshold = s.f32("the verification threshold")?;
    let max_wrong = s.f32("the verification's max wrong share")?;
    let wrong_upper = s.f32("the verification's upper bound")?;
    let scenes = s.u32("the verification's scenes")?;
    let accepted = s.u32("the verification's accepted poses")?;
    let wrong_accepted = s.u32("the verification's wrong accepted poses")?;
    s.finish()?;
    Ok(Some(ModelVerification { threshold, max_wrong, scenes, accepted, wrong_accepted, wrong_upper }))
}

/// The power of two (mm) that fits every coordinate of `points` into i16 steps, at least
/// 2^-20 mm; 1 for no points. Not finite coordinates leave it finite (validation refuses
/// them).
fn position_step(points: &[Point3<f32>]) -> f32 {
    let largest =
        points.iter().flat_map(|p| p.coords.iter().map(|c| c.abs())).filter(|c| c.is_finite()).fold(0.0f32, f32::max);
    if largest == 0.0 {
        return 1.0;
    }
    let mut exp = (largest / MAX_STEPS).log2().ceil().clamp(MIN_STEP_EXP as f32, MAX_STEP_EXP as f32) as i32;
    // log2 rounds: make sure the largest coordinate fits.
    while exp < MAX_STEP_EXP && largest / 2f32.powi(exp) > MAX_STEPS {
        exp += 1;
    }
    2f32.powi(exp)
}

fn put_point_i16(out: &mut Vec<u8>, p: &Point3<f32>, step: f32) {
    for c in p.coords.iter() {
        let q = (c / step).round().clamp(-MAX_STEPS, MAX_STEPS) as i16;
        out.extend_from_slice(&q.to_le_bytes());
    }
}

/// Octahedral coordinates of a unit normal (Meyer et al. 2010): the normal projected onto the
/// octahedron |x| + |y| + |z| = 1, the lower half folded over the upper, each coordinate in
/// -1..1 as a multiple of 1/32767.
fn put_normal_oct(out: &mut Vec<u8>, n: &Vector3<f32>) {
    let l1 = n.x.abs() + n.y.abs() + n.z.abs();
    let (mut u, mut v) = if l1 > 0.0 && l1.is_finite() { (n.x / l1, n.y / l1) } else { (0.0, 0.0) };
    if n.z < 0.0 {
        (u, v) = ((1.0 - v.abs()) * u.signum(), (1.0 - u.abs()) * v.signum());
    }
    for c in [u, v] {
        let q = (c * MAX_STEPS).round().clamp(-MAX_STEPS, MAX_STEPS) as i16;
        out.extend_from_slice(&q.to_le_bytes());
    }
}

/// The unit normal of octahedral coordinates `u`, `v` (each in -1..1); every pair gives one.
fn normal_from_oct(u: f32, v: f32) -> Vector3<f32> {
    let z = 1.0 - u.abs() - v.abs();
    let (x, y) = if z < 0.0 { ((1.0 - v.abs()) * u.signum(), (1.0 - u.abs()) * v.signum()) } else { (u, v) };
    Vector3::new(x, y, z).normalize()
}

fn finite3(v: &Vector3<f32>) -> bool {
    v.iter().all(|x| x.is_finite())
}

fn section(out: &mut Vec<u8>, tag: [u8; 4], len: usize) {
    out.extend_from_slice(&tag);
    out.extend_from_slice(&(len as u64).to_le_bytes());
}

fn put_u32(out: &mut Vec<u8>, v: u32) {
    out.extend_from_slice(&v.to_le_bytes());
}

fn put_f32(out: &mut Vec<u8>, v: f32) {
    out.extend_from_slice(&v.to_le_bytes());
}

fn put_vec3(out: &mut Vec<u8>, v: &Vector3<f32>) {
    for x in v.iter() {
        put_f32(out, *x);
    }
}

/// A cursor over the body (or one section of it) that names what it expected when it runs out.
struct Reader<'a> {
    bytes: &'a [u8],
    pos: usize,
}

impl<'a> Reader<'a> {
    fn remaining(&self) -> usize {
        self.bytes.len() - self.pos
    }

    fn take(&mut self, n: usize, what: &str) -> Result<&'a [u8]> {
        if self.remaining() < n {
            return Err(Error::new(
                ErrorKind::Model,
                format!(
                    "model: truncated: expected {n} bytes of {what} at offset {}, found {}",
                    self.pos,
                    self.remaining()
                ),
            ));
        }
        let s = &self.bytes[self.pos..self.pos + n];
        self.pos += n;
        Ok(s)
    }

    fn u32(&mut self, what: &str) -> Result<u32> {
        Ok(u32::from_le_bytes(self.take(4, what)?.try_into().expect("4 bytes")))
    }

    fn f32(&mut self, what: &str) -> Result<f32> {
        Ok(f32::from_le_bytes(self.take(4, what)?.try_into().expect("4 bytes")))
    }

    fn vec3(&mut self, what: &str) -> Result<Vector3<f32>> {
        Ok(Vector3::new(self.f32(what)?, self.f32(what)?, self.f32(what)?))
    }

    fn i16(&mut self, what: &str) -> Result<i16> {
        Ok(i16::from_le_bytes(self.take(2, what)?.try_into().expect("2 bytes")))
    }

    /// A 16-bit point's step: a power of two from 2^-20 to 2^20 mm.
    fn step(&mut self, what: &str) -> Result<f32> {
        let step = self.f32(what)?;
        let bits = step.to_bits();
        // A positive normal f32 with an empty mantissa is a power of two; its biased exponent
        // is the power plus 127.
        let exponent = (bits >> 23) as i32 - 127;
        if !(bits >> 31 == 0 && bits & 0x7F_FFFF == 0 && (MIN_STEP_EXP..=MAX_STEP_EXP).contains(&exponent)) {
            return Err(Error::new(
                ErrorKind::Model,
                format!("model: corrupted: expected {what} to be a power of two from 2^-20 to 2^20 mm, found {step}"),
            ));
        }
        Ok(step)
    }

    fn point_i16(&mut self, step: f32, what: &str) -> Result<Point3<f32>> {
        Ok(Point3::new(
            f32::from(self.i16(what)?) * step,
            f32::from(self.i16(what)?) * step,
            f32::from(self.i16(what)?) * step,
        ))
    }

    fn normal_oct(&mut self, what: &str) -> Result<Vector3<f32>> {
        let u = f32::from(self.i16(what)?) / MAX_STEPS;
        let v = f32::from(self.i16(what)?) / MAX_STEPS;
        // -32768 is one step beyond -1; it reads as -1.
        Ok(normal_from_oct(u.max(-1.0), v.max(-1.0)))
    }

    /// The next section, which must carry `tag`, as a reader of its own.
    fn section(&mut self, tag: [u8; 4]) -> Result<Reader<'a>> {
        let name = String::from_utf8_lossy(&tag).into_owned();
        let found = self.take(4, &format!("the tag of section {name}"))?;
        if found != tag {
            return Err(Error::new(
                ErrorKind::Model,
                format!("model: expected section {name}, found tag {:?}", String::from_utf8_lossy(found)),
            ));
        }
        let len = u64::from_le_bytes(self.take(8, &format!("the length of section {name}"))?.try_into().expect("8"));
        let len = usize::try_from(len).unwrap_or(usize::MAX);
        let bytes = self.take(len, &format!("section {name}"))?;
        Ok(Reader { bytes, pos: 0 })
    }

    /// Checks, before allocating, that `count` records of `size` bytes fit in what is left.
    fn expect_len(&self, count: usize, size: usize, what: &str) -> Result<()> {
        match count.checked_mul(size) {
            Some(n) if n == self.remaining() => Ok(()),
            _ => Err(Error::new(
                ErrorKind::Model,
                format!(
                    "model: corrupted: expected {count} {what} of {size} bytes, the section holds {} bytes",
                    self.remaining()
                ),
            )),
        }
    }

    fn finish(&self) -> Result<()> {
        if self.remaining() != 0 {
            return Err(Error::new(
                ErrorKind::Model,
                format!("model: corrupted: {} unread bytes at the end of a section", self.remaining()),
            ));
        }
        Ok(())
    }
}

const CRC_TABLE: [u32; 256] = {
    let mut table = [0u32; 256];
    let mut i = 0;
    while i < 256 {
        let mut c = i as u32;
        let mut k = 0;
        while k < 8 {
            c = if c & 1 != 0 { 0xEDB8_8320 ^ (c >> 1) } else { c >> 1 };
            k += 1;
        }
        table[i] = c;
        i += 1;
    }
    table
};

/// CRC-32 (IEEE 802.3, the one zip and PNG use).
fn crc32(bytes: &[u8]) -> u32 {
    let mut c = !0u32;
    for b in bytes {
        c = CRC_TABLE[((c ^ *b as u32) & 0xFF) as usize] ^ (c >> 8);
    }
    !c
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing;
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn small_model(seed: u64) -> Model {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut p =
            || Point3::new(rng.random_range(-9.0..9.0), rng.random_range(-9.0..9.0), rng.random_range(0.0..9.0));
        let feature_points: Vec<Point3<f32>> = (0..7).map(|_| p()).collect();
        let views = (0..3)
            .map(|k| ModelView {
                view_direction: Vector3::new(k as f32, 1.0, 2.0).normalize(),
                points: (0..5 + k).map(|_| p()).collect(),
                normals: (0..5 + k).map(|i| Vector3::new(0.0, i as f32, 1.0).normalize()).collect(),
            })
            .collect();
        Model {
            surface_resolution: 2.0,
            feature_normals: feature_points.iter().map(|q| q.coords.normalize()).collect(),
            descriptors: (0..7).map(|i| [i as f32 * 0.25; DESCRIPTOR_LEN]).collect(),
            feature_points,
            views,
            symmetries_deg: vec![90.0, 180.0, 270.0],
            origin: Some(ModelOrigin {
                cell_hash: ContentHash::of(&seed.to_le_bytes()),
                tray: "tray-8".to_string(),
                tray_hash: ContentHash::of(b"tray"),
                method: "one-shot".to_string(),
                seed,
                placement: "r=605,alpha=32,baseline=81,vergence=3.5".to_string(),
            }),
            verification: seed.is_multiple_of(2).then_some(ModelVerification {
                threshold: 0.625,
                max_wrong: 0.005,
                scenes: 300,
                accepted: 280,
                wrong_accepted: 1,
                wrong_upper: 0.0166,
            }),
        }
    }

    /// `m` as format version 3 keeps it: points within half a step, normals within 1e-4,
    /// descriptors on the matcher's steps.
    fn assert_close(got: &Model, m: &Model) {
        let points = |a: &[Point3<f32>], b: &[Point3<f32>]| {
            let step = position_step(b);
            assert_eq!(a.len(), b.len());
            for (p, q) in a.iter().zip(b) {
                assert!((p - q).amax() <= 0.5 * step, "{p} against {q}, step {step}");
            }
        };
        let normals = |a: &[Vector3<f32>], b: &[Vector3<f32>]| {
            assert_eq!(a.len(), b.len());
            for (n, o) in a.iter().zip(b) {
                assert!((n - o).norm() < 1e-4 && (n.norm() - 1.0).abs() < 1e-6, "{n} against {o}");
            }
        };
        points(&got.feature_points, &m.feature_points);
        normals(&got.feature_normals, &m.feature_normals);
        assert_eq!(
            got.descriptors.iter().map(quantise).collect::<Vec<_>>(),
            m.descriptors.iter().map(quantise).collect::<Vec<_>>()
        );
        assert_eq!(got.views.len(), m.views.len());
        for (g, v) in got.views.iter().zip(&m.views) {
            assert_eq!(g.view_direction, v.view_direction);
            points(&g.points, &v.points);
            normals(&g.normals, &v.normals);
        }
        assert_eq!(
            (got.surface_resolution, &got.symmetries_deg, &got.origin, &got.verification),
            (m.surface_resolution, &m.symmetries_deg, &m.origin, &m.verification)
        );
    }

    #[test]
    fn bytes_round_trip() {
        let unknown = Model { origin: None, ..small_model(1) };
        for m in (0..5).map(small_model).chain([testing::tray(false, 1), unknown]) {
            let once = Model::from_bytes(&m.to_bytes()).unwrap();
            assert_close(&once, &m);
            // Points and descriptors come back on their steps and stay there.
            let twice = Model::from_bytes(&once.to_bytes()).unwrap();
            assert_eq!((&twice.feature_points, &twice.descriptors), (&once.feature_points, &once.descriptors));
            assert!(twice.views.iter().zip(&once.views).all(|(a, b)| a.points == b.points));
            assert_close(&twice, &m);
            // Versions 1 and 2 hold every number as written, and read as version 3 holds them;
            // versions before 4 carry no verification threshold.
            let without = Model { verification: None, ..once.clone() };
            assert_eq!(Model::from_bytes(&m.encode(2)).unwrap(), without);
            assert_eq!(Model::from_bytes(&m.encode(3)).unwrap(), without);
        }
    }

    #[test]
    fn a_version_3_file_is_a_third_of_version_2() {
        let m = testing::tray(false, 1);
        let (v2, v3) = (m.encode(2).len(), m.to_bytes().len());
        assert!(3 * v3 < v2 + 3 * 1000, "version 3 {v3} bytes against version 2 {v2}");
    }

    #[test]
    fn descriptor_bytes_decode_to_the_matchers_steps() {
        for q in 0..=255u8 {
            let v = f32::from(q) * (std::f32::consts::PI / QUANTISATION_STEPS);
            assert_eq!(quantise(&[v; DESCRIPTOR_LEN]), [f32::from(q); DESCRIPTOR_LEN], "{q}");
        }
    }

    /// Every direction (the poles, the axes, the folded lower half, and random ones) comes
    /// back within 1e-4, and every pair of codes decodes to a unit normal.
    #[test]
    fn octahedral_normals_round_trip() {
        let mut rng = ChaCha8Rng::seed_from_u64(13);
        let mut dirs: Vec<Vector3<f32>> =
            vec![Vector3::x(), -Vector3::x(), Vector3::y(), -Vector3::y(), Vector3::z(), -Vector3::z()];
        dirs.extend((0..20_000).map(|_| {
            Vector3::new(rng.random_range(-1.0..1.0f32), rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0))
        }));
        for n in dirs.into_iter().filter(|n| n.norm() > 1e-3).map(|n| n.normalize()) {
            let mut b = Vec::new();
            put_normal_oct(&mut b, &n);
            let mut r = Reader { bytes: &b, pos: 0 };
            let back = r.normal_oct("normal").unwrap();
            assert!((back - n).norm() < 1e-4, "{n} came back as {back}");
        }
        for _ in 0..20_000 {
            let b: [u8; 4] = rng.random();
            let n = Reader { bytes: &b, pos: 0 }.normal_oct("normal").unwrap();
            assert!((n.norm() - 1.0).abs() < 1e-6, "{b:?} decodes to {n}");
        }
    }

    #[test]
    fn point_steps_fit_the_largest_coordinate() {
        for largest in [1e-9f32, 1e-3, 0.5, 9.0, 300.0, 511.9, 512.0, 32767.0, 1e6, 3e10] {
            let points = [Point3::new(largest, -0.5 * largest, 0.0), Point3::new(0.0, 0.0, -largest)];
            let step = position_step(&points);
            assert_eq!(step.log2().fract(), 0.0, "{largest}: {step}");
            let mut b = Vec::new();
            for p in &points {
                put_point_i16(&mut b, p, step);
            }
            let mut r = Reader { bytes: &b, pos: 0 };
            for p in &points {
                let q = r.point_i16(step, "point").unwrap();
                if largest <= 2f32.powi(MAX_STEP_EXP) * MAX_STEPS {
                    assert!(
                        (q - p).amax() <= 0.5 * step.max(2f32.powi(MIN_STEP_EXP)),
                        "{largest}: {p} came back as {q}"
                    );
                }
            }
        }
        assert!(position_step(&[Point3::new(300.0, 0.0, 0.0)]) <= 1.0 / 64.0);
        assert_eq!(position_step(&[]), 1.0);
    }

    #[test]
    fn a_version_1_file_reads_without_an_origin() {
        let m = Model { origin: None, verification: None, ..small_model(6) };
        let v1 = m.encode(1);
        assert_eq!(Model::from_bytes(&v1).unwrap(), Model::from_bytes(&m.to_bytes()).unwrap());
        for len in 0..v1.len() {
            assert!(Model::from_bytes(&v1[..len]).is_err());
        }
    }

    /// Damage inside the `ORIG` section with the checksum made to fit again: the texts'
    /// lengths and UTF-8 are checked, and nothing panics.
    #[test]
    fn a_damaged_origin_is_an_error_or_another_origin_never_a_panic() {
        let bytes = small_model(7).to_bytes();
        let end = bytes.len() - 4;
        // An empty `VRFY` section (no threshold measured) follows `ORIG`.
        assert!(small_model(7).verification.is_none());
        let orig = end - 12 - 12 - encode_origin(small_model(7).origin.as_ref().unwrap()).len();
        assert_eq!(&bytes[orig..orig + 4], b"ORIG");
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        let mut failures = 0;
        for _ in 0..3000 {
            let mut b = bytes.clone();
            for _ in 0..rng.random_range(1..4) {
                let i = rng.random_range(orig..end);
                b[i] ^= rng.random_range(1..=255u8);
            }
            let crc = crc32(&b[..end]);
            b[end..].copy_from_slice(&crc.to_le_bytes());
            match Model::from_bytes(&b) {
                Ok(m) => assert_close(&Model { origin: small_model(7).origin, ..m }, &small_model(7)),
                Err(e) => {
                    assert_eq!(e.kind(), ErrorKind::Model);
                    failures += 1;
                }
            }
        }
        assert!(failures > 0);
    }

    #[test]
    fn a_file_without_views_or_features_is_refused_as_a_model() {
        let mut m = small_model(3);
        m.views.clear();
        let e = Model::from_bytes(&m.to_bytes()).unwrap_err();
        assert_eq!(e.kind(), ErrorKind::Model);
        assert!(e.to_string().contains("0 views"), "{e}");
        let mut m = small_model(3);
        (m.feature_points, m.feature_normals, m.descriptors) = (vec![], vec![], vec![]);
        let e = Model::from_bytes(&m.to_bytes()).unwrap_err();
        assert!(e.to_string().contains("0 features"), "{e}");
    }

    #[test]
    fn every_truncation_is_an_error() {
        let bytes = small_model(1).to_bytes();
        for len in 0..bytes.len() {
            let e = Model::from_bytes(&bytes[..len]).unwrap_err();
            assert_eq!(e.kind(), ErrorKind::Model);
            assert!(e.to_string().contains("expected"), "{e}");
        }
    }

    #[test]
    fn random_corruptions_are_errors_not_panics() {
        let bytes = small_model(2).to_bytes();
        let mut rng = ChaCha8Rng::seed_from_u64(9);
        for _ in 0..3000 {
            let mut b = bytes.clone();
            for _ in 0..rng.random_range(1..4) {
                let i = rng.random_range(0..b.len());
                b[i] ^= rng.random_range(1..=255u8);
            }
            let e = Model::from_bytes(&b).unwrap_err();
            assert_eq!(e.kind(), ErrorKind::Model);
        }
    }

    /// Corruptions that keep the checksum valid reach the section parser: it must still
    /// refuse them cleanly rather than allocate wildly or panic.
    #[test]
    fn corruptions_with_a_fixed_up_checksum_are_errors_not_panics() {
        let bytes = small_model(3).to_bytes();
        let mut rng = ChaCha8Rng::seed_from_u64(10);
        let end = bytes.len() - 4;
        let mut failures = 0;
        for _ in 0..3000 {
            let mut b = bytes.clone();
            let i = rng.random_range(PREAMBLE_LEN..end);
            b[i] ^= rng.random_range(1..=255u8);
            let crc = crc32(&b[..end]);
            b[end..].copy_from_slice(&crc.to_le_bytes());
            if let Err(e) = Model::from_bytes(&b) {
                assert_eq!(e.kind(), ErrorKind::Model);
                failures += 1;
            }
        }
        // Flips inside float payloads decode to other valid models; flips in tags, lengths
        // and counts must not.
        assert!(failures > 0);
    }

    #[test]
    fn wrong_magic_and_version_are_named() {
        let mut b = small_model(4).to_bytes();
        b[0] = b'X';
        let e = Model::from_bytes(&b).unwrap_err();
        assert!(e.to_string().contains("CPLMODEL"), "{e}");
        let mut b = small_model(4).to_bytes();
        b[8..12].copy_from_slice(&7u32.to_le_bytes());
        let e = Model::from_bytes(&b).unwrap_err();
        assert!(e.to_string().contains("version 1 to 4") && e.to_string().contains("version 7"), "{e}");
        let mut b = small_model(4).to_bytes();
        b.push(0);
        assert_eq!(Model::from_bytes(&b).unwrap_err().kind(), ErrorKind::Model);
    }

    /// A threshold out of [0, 1], or counts that contradict each other, are refused.
    #[test]
    fn a_verification_out_of_range_is_refused() {
        let good = small_model(2);
        assert!(good.validate().is_ok() && good.verification.is_some());
        let v = good.verification.unwrap();
        for bad in [
            ModelVerification { threshold: 1.5, ..v },
            ModelVerification { wrong_upper: f32::NAN, ..v },
            ModelVerification { accepted: v.scenes + 1, ..v },
            ModelVerification { wrong_accepted: v.accepted + 1, ..v },
        ] {
            let m = Model { verification: Some(bad), ..good.clone() };
            assert!(m.validate().unwrap_err().to_string().contains("verification"), "{bad:?}");
        }
    }

    #[test]
    fn inconsistent_models_fail_validation() {
        let mut m = small_model(5);
        m.descriptors.pop();
        assert!(m.validate().is_err());
        let mut m = small_model(5);
        m.views[1].normals.pop();
        assert!(m.validate().is_err());
        let mut m = small_model(5);
        m.views[0].points[2].x = f32::NAN;
        assert!(m.validate().is_err());
        // Version 3 has no NaN to write; the f32 layouts carry it to the reader, which refuses it.
        assert!(Model::from_bytes(&m.encode(2)).is_err());
        let mut m = small_model(5);
        m.views[0].view_direction *= 2.0;
        assert!(m.validate().is_err());
    }

    #[test]
    fn closest_view_matches_brute_force_angles() {
        let model = testing::tray(false, 1);
        let mut rng = ChaCha8Rng::seed_from_u64(6);
        for _ in 0..200 {
            let pose = Isometry3::new(
                nalgebra::Vector3::new(rng.random_range(-200.0..200.0), rng.random_range(-200.0..200.0), 0.0),
                nalgebra::Vector3::z() * rng.random_range(-3.2..3.2),
            );
            let sensor = Point3::new(
                rng.random_range(-500.0..500.0),
                rng.random_range(-500.0..500.0),
                rng.random_range(300.0..900.0),
            );
            let dir = sensor.cast::<f64>().coords - pose.translation.vector;
            let angle = |k: usize| (pose.rotation * model.views[k].view_direction.cast::<f64>()).angle(&dir);
            let k = model.closest_view(&pose, &sensor);
            assert!((0..6).all(|j| angle(k) <= angle(j) + 1e-9));
        }
    }

    #[test]
    fn synthetic_tray_is_seen_from_six_directions() {
        let m = testing::tray(false, 1);
        m.validate().unwrap();
        assert_eq!(m.views.len(), 6);
        for v in &m.views {
            assert!(v.points.len() > 5000, "{}", v.points.len());
            // Every kept sample faces the sensor that saw it.
            let eye = Point3::from(v.view_direction * 800.0);
            assert!(v.points.iter().zip(&v.normals).all(|(p, n)| n.dot(&(eye - p)) > 0.0));
        }
    }
}
