//! The model's binary file: its versioned layout (magic, version, tagged sections, a
//! CRC-32 of everything before it), the encoder of the current version, and a bounded
//! decoder of every version that names what it expected when the bytes are wrong. The
//! model itself is `model.rs`'s; reading a file from disk is `model_load.rs`'s.

use nalgebra::{Point3, Vector3};

use super::model::{Model, ModelOrigin, ModelVerification, ModelView};
use super::slots::{SlotLayout, MAX_FOOTPRINT_CELLS, MAX_SLOTS};
use crate::error::{Error, ErrorKind, Result};
use crate::features::{quantise, ECSAD_DIM, QUANTISATION_STEPS};
use camplace_config::ContentHash;

/// Version of the binary layout written by [`Model::to_bytes`]. Version 5 added the `SLOT`
/// section (the slots' poses and the item's footprint profile); older files read without
/// slots, so their frames carry no slot states. Version 4 added the `VRFY`
/// section (the verification threshold measured in simulation). Version 3 stores points as
/// 16-bit multiples of a power-of-two step, normals in 16-bit octahedral coordinates and
/// descriptors as the bytes the matcher compares; version 2 added the `ORIG` section.
/// Versions 1 to 3 still read (1 and 2 hold everything as `f32`, 1 has no origin); they
/// carry no verification threshold, so the cell's `estimator.verify_threshold` applies.
pub const MODEL_FORMAT_VERSION: u32 = 5;

/// First bytes of every model file.
pub const MODEL_MAGIC: [u8; 8] = *b"CPLMODEL";

const TAG_HEAD: [u8; 4] = *b"HEAD";
const TAG_FEAT: [u8; 4] = *b"FEAT";
const TAG_VIEW: [u8; 4] = *b"VIEW";
const TAG_SYMM: [u8; 4] = *b"SYMM";
const TAG_ORIG: [u8; 4] = *b"ORIG";
const TAG_VRFY: [u8; 4] = *b"VRFY";
const TAG_SLOT: [u8; 4] = *b"SLOT";
/// The `VRFY` payload of a measured threshold: threshold, max wrong, upper bound (f32) and
/// scenes, accepted, wrong accepted (u32).
const VERIFICATION_BYTES: usize = 6 * 4;
/// Longest text an `ORIG` section may hold in one field.
const MAX_ORIGIN_TEXT: usize = 4096;
/// Magic, version and body length.
const PREAMBLE_LEN: usize = 8 + 4 + 8;
/// A feature in versions 1 and 2: point, normal, descriptor, all f32.
const FEATURE_BYTES_F32: usize = 4 * (3 + 3 + ECSAD_DIM);
/// A view point in versions 1 and 2: point and normal, f32.
const VIEW_POINT_BYTES_F32: usize = 4 * 6;
/// A feature in version 3: point i16×3, normal i16×2, descriptor u8×30.
const FEATURE_BYTES: usize = 2 * 3 + 2 * 2 + ECSAD_DIM;
/// A view point in version 3: point i16×3, normal i16×2.
const VIEW_POINT_BYTES: usize = 2 * 3 + 2 * 2;
/// The largest magnitude a 16-bit point coordinate holds, in steps.
const MAX_STEPS: f32 = 32767.0;
/// The smallest step of the 16-bit points, as a power of two (mm).
const MIN_STEP_EXP: i32 = -20;
/// The largest step of the 16-bit points, as a power of two (mm).
const MAX_STEP_EXP: i32 = 20;

impl Model {
    /// The model in its binary file layout (little endian), format version 5:
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

    /// The layout of format `version` (1 to 5); versions 1 to 4 for tests of old files.
    fn encode(&self, version: u32) -> Vec<u8> {
        let compact = version >= 3;
        let (feature_bytes, point_bytes, step_bytes) =
            if compact { (FEATURE_BYTES, VIEW_POINT_BYTES, 4) } else { (FEATURE_BYTES_F32, VIEW_POINT_BYTES_F32, 0) };
        let view_bytes: usize = self.views.iter().map(|v| 12 + 16 + step_bytes + v.points.len() * point_bytes).sum();
        let origin = self.origin.as_ref().map(encode_origin).unwrap_or_default();
        let origin_bytes = if version >= 2 { 12 + origin.len() } else { 0 };
        let verification_len = if self.verification.is_some() { VERIFICATION_BYTES } else { 0 };
        let verification_bytes = if version >= 4 { 12 + verification_len } else { 0 };
        let slots = self.slots.as_ref().map(encode_slots).unwrap_or_default();
        let slot_bytes = if version >= 5 { 12 + slots.len() } else { 0 };
        let body_len = (12 + 16)
            + (12 + step_bytes + self.feature_points.len() * feature_bytes)
            + view_bytes
            + (12 + 4 * self.symmetries_deg.len())
            + origin_bytes
            + verification_bytes
            + slot_bytes;
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
        if version >= 5 {
            section(&mut out, TAG_SLOT, slots.len());
            out.extend_from_slice(&slots);
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
            let mut d = [0.0; ECSAD_DIM];
            if compact {
                feature_points.push(feat.point_i16(step, "feature point")?);
                feature_normals.push(feat.normal_oct("feature normal")?);
                for (v, &q) in d.iter_mut().zip(feat.take(ECSAD_DIM, "descriptor")?) {
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
        let slots = if version >= 5 { decode_slots(r.section(TAG_SLOT)?)? } else { None };
        if r.remaining() != 0 {
            let last = match version {
                5.. => "SLOT",
                4 => "VRFY",
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
            slots,
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

fn encode_slots(l: &SlotLayout) -> Vec<u8> {
    let mut out = Vec::with_capacity(4 + 32 * l.slots.len() + 24 + 4 * l.top_mm.len());
    put_u32(&mut out, l.slots.len() as u32);
    for s in &l.slots {
        for v in s {
            out.extend_from_slice(&v.to_le_bytes());
        }
    }
    for v in l.footprint_min_mm.iter().chain(&l.cell_mm) {
        put_f32(&mut out, *v);
    }
    put_u32(&mut out, l.cols);
    put_u32(&mut out, l.rows);
    for v in &l.top_mm {
        put_f32(&mut out, *v);
    }
    out
}

/// The `SLOT` section: empty for a model without slots. Counts are checked against the
/// section's length before anything is allocated.
fn decode_slots(mut s: Reader<'_>) -> Result<Option<SlotLayout>> {
    if s.remaining() == 0 {
        return Ok(None);
    }
    let n = s.u32("the slot count")? as usize;
    if n > MAX_SLOTS || n * 32 > s.remaining() {
        return Err(Error::new(
            ErrorKind::Model,
            format!("model: corrupted: expected at most {MAX_SLOTS} slots in the section's bytes, found count {n}"),
        ));
    }
    let mut slots = Vec::with_capacity(n);
    for _ in 0..n {
        let mut pose = [0.0; 4];
        for v in &mut pose {
            *v = f64::from_le_bytes(s.take(8, "a slot pose")?.try_into().expect("8 bytes"));
        }
        slots.push(pose);
    }
    let footprint_min_mm = [s.f32("the footprint corner")?, s.f32("the footprint corner")?];
    let cell_mm = [s.f32("the footprint cell size")?, s.f32("the footprint cell size")?];
    let cols = s.u32("the footprint columns")?;
    let rows = s.u32("the footprint rows")?;
    let cells = (cols as usize).saturating_mul(rows as usize);
    if cells > MAX_FOOTPRINT_CELLS {
        return Err(Error::new(
            ErrorKind::Model,
            format!("model: corrupted: expected at most {MAX_FOOTPRINT_CELLS} footprint cells, found {cols} x {rows}"),
        ));
    }
    s.expect_len(cells, 4, "footprint cells")?;
    let top_mm = (0..cells).map(|_| s.f32("a footprint cell")).collect::<Result<Vec<_>>>()?;
    s.finish()?;
    Ok(Some(SlotLayout { slots, footprint_min_mm, cell_mm, cols, rows, top_mm }))
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

/// CRC-32/ISO-HDLC (the one zip and PNG use) of `bytes`.
fn crc32(bytes: &[u8]) -> u32 {
    crc32fast::hash(bytes)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pose::model::tests::small_model;
    use crate::testing;
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// CRC-32/ISO-HDLC bit by bit, as its definition reads.
    fn crc32_bitwise(bytes: &[u8]) -> u32 {
        let mut c = !0u32;
        for &b in bytes {
            c ^= u32::from(b);
            for _ in 0..8 {
                c = if c & 1 != 0 { 0xEDB8_8320 ^ (c >> 1) } else { c >> 1 };
            }
        }
        !c
    }

    #[test]
    fn the_checksum_is_crc32_iso_hdlc() {
        assert_eq!(crc32(b"123456789"), 0xCBF4_3926, "the catalogue's check value");
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let noise: Vec<u8> = (0..100_003).map(|_| rng.random_range(0..=255u8)).collect();
        for b in [&b""[..], b"CPLMODEL", &small_model(2).to_bytes(), &noise, &noise[1..]] {
            assert_eq!(crc32(b), crc32_bitwise(b), "{} bytes", b.len());
        }
    }

    /// Files of each version written before the checksum came from `crc32fast` (by its own
    /// table-driven CRC): each still reads, and the current version is written again byte
    /// for byte.
    #[test]
    fn model_files_written_before_still_load() {
        let files: [&[u8]; 4] = [
            include_bytes!("../../tests/data/small_model_v1.model"),
            include_bytes!("../../tests/data/small_model_v2.model"),
            include_bytes!("../../tests/data/small_model_v3.model"),
            include_bytes!("../../tests/data/small_model_v4.model"),
        ];
        let m = small_model(2);
        for (v, bytes) in (1..).zip(files) {
            let read = Model::from_bytes(bytes).unwrap_or_else(|e| panic!("version {v}: {e}"));
            assert_eq!(m.encode(v), bytes, "version {v} is encoded as before");
            let expected = if v == 1 {
                Model { origin: None, ..Model::from_bytes(&m.encode(3)).unwrap() }
            } else if v < 4 {
                Model::from_bytes(&m.encode(3)).unwrap()
            } else {
                Model::from_bytes(&m.to_bytes()).unwrap()
            };
            assert_eq!(read, expected, "version {v}");
        }
        assert_eq!(m.encode(4), files[3]);
    }

    /// A version 5 file carries the slots as written, bit for bit; a version 4 file of the
    /// same model reads without them.
    #[test]
    fn slots_round_trip_and_older_files_have_none() {
        let m = small_model(3);
        let slots = m.slots.clone().expect("small_model(3) has slots");
        let back = Model::from_bytes(&m.to_bytes()).unwrap();
        assert_eq!(back.slots.as_ref(), Some(&slots));
        assert_eq!(Model::from_bytes(&m.encode(4)).unwrap(), Model { slots: None, ..back.clone() });
        // A corrupted slot count or grid is refused by name, not allocated.
        let bytes = m.to_bytes();
        let end = bytes.len() - 4;
        let section = end - encode_slots(&slots).len();
        assert_eq!(&bytes[section - 12..section - 8], b"SLOT");
        for (offset, value) in [(0usize, u32::MAX), (0, 3), (4 + 64 + 16, 1 << 20)] {
            let mut b = bytes.clone();
            b[section + offset..section + offset + 4].copy_from_slice(&value.to_le_bytes());
            let crc = crc32(&b[..end]);
            b[end..].copy_from_slice(&crc.to_le_bytes());
            let e = Model::from_bytes(&b).unwrap_err();
            assert_eq!(e.kind(), ErrorKind::Model, "{e}");
            assert!(e.to_string().contains("expected"), "{e}");
        }
    }

    /// Version 3 has no NaN to write; the f32 layouts carry it to the reader, which refuses it.
    #[test]
    fn a_nan_in_an_f32_file_is_refused() {
        let mut m = small_model(5);
        m.views[0].points[2].x = f32::NAN;
        assert!(Model::from_bytes(&m.encode(2)).is_err());
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
            (got.surface_resolution, &got.symmetries_deg, &got.origin, &got.verification, &got.slots),
            (m.surface_resolution, &m.symmetries_deg, &m.origin, &m.verification, &m.slots)
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
            let without = Model { verification: None, slots: None, ..once.clone() };
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
            assert_eq!(quantise(&[v; ECSAD_DIM]), [f32::from(q); ECSAD_DIM], "{q}");
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
        let m = Model { origin: None, verification: None, slots: None, ..small_model(6) };
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
        // An empty `VRFY` section (no threshold measured) and an empty `SLOT` section follow
        // `ORIG`.
        assert!(small_model(7).verification.is_none() && small_model(7).slots.is_none());
        let orig = end - 12 - 12 - 12 - encode_origin(small_model(7).origin.as_ref().unwrap()).len();
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
        assert!(e.to_string().contains("version 1 to 5") && e.to_string().contains("version 7"), "{e}");
        let mut b = small_model(4).to_bytes();
        b.push(0);
        assert_eq!(Model::from_bytes(&b).unwrap_err().kind(), ErrorKind::Model);
    }
}
