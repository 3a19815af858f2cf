//! The tray model the estimator loads: features with tray-frame positions for matching, and
//! one ICP cloud per viewpoint for scoring and refinement; its versioned binary encoding.
//! Building a model from rendered views is the simulator's job; `synthetic` makes a box
//! tray and scenes of it analytically, for tests and benches.
//!
//! Points are `f32` like every cloud; poses are `f64` like every calibrated transform.

use nalgebra::{Isometry3, Point3, Vector3};

use crate::error::{Error, ErrorKind, Result};

/// Version of the binary layout written by [`Model::to_bytes`].
pub const MODEL_FORMAT_VERSION: u32 = 1;

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
/// Magic, version and body length.
const PREAMBLE_LEN: usize = 8 + 4 + 8;
const FEATURE_BYTES: usize = 4 * (3 + 3 + DESCRIPTOR_LEN);
const VIEW_POINT_BYTES: usize = 4 * 6;

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

    /// The model in its binary file layout (little endian):
    /// magic `CPLMODEL`, format version (u32), body length (u64), body, CRC-32 of all before.
    /// The body is tagged sections, each `tag[4] length(u64) payload`: `HEAD` (surface
    /// resolution f32, feature, view and symmetry counts u32), `FEAT` (per feature: point,
    /// normal, descriptor as f32), one `VIEW` per viewpoint (direction f32×3, point count u32,
    /// then point and normal f32×6 each) and `SYMM` (angles f32, deg).
    pub fn to_bytes(&self) -> Vec<u8> {
        let view_bytes: usize = self.views.iter().map(|v| 12 + 16 + v.points.len() * VIEW_POINT_BYTES).sum();
        let body_len = (12 + 16)
            + (12 + self.feature_points.len() * FEATURE_BYTES)
            + view_bytes
            + (12 + 4 * self.symmetries_deg.len());
        let mut out = Vec::with_capacity(PREAMBLE_LEN + body_len + 4);
        out.extend_from_slice(&MODEL_MAGIC);
        out.extend_from_slice(&MODEL_FORMAT_VERSION.to_le_bytes());
        out.extend_from_slice(&(body_len as u64).to_le_bytes());

        section(&mut out, TAG_HEAD, 16);
        put_f32(&mut out, self.surface_resolution);
        put_u32(&mut out, self.feature_points.len() as u32);
        put_u32(&mut out, self.views.len() as u32);
        put_u32(&mut out, self.symmetries_deg.len() as u32);

        section(&mut out, TAG_FEAT, self.feature_points.len() * FEATURE_BYTES);
        for ((p, n), d) in self.feature_points.iter().zip(&self.feature_normals).zip(&self.descriptors) {
            put_vec3(&mut out, &p.coords);
            put_vec3(&mut out, n);
            for v in d {
                put_f32(&mut out, *v);
            }
        }
        for view in &self.views {
            section(&mut out, TAG_VIEW, 16 + view.points.len() * VIEW_POINT_BYTES);
            put_vec3(&mut out, &view.view_direction);
            put_u32(&mut out, view.points.len() as u32);
            for (p, n) in view.points.iter().zip(&view.normals) {
                put_vec3(&mut out, &p.coords);
                put_vec3(&mut out, n);
            }
        }
        section(&mut out, TAG_SYMM, 4 * self.symmetries_deg.len());
        for s in &self.symmetries_deg {
            put_f32(&mut out, *s);
        }
        let crc = crc32(&out);
        put_u32(&mut out, crc);
        out
    }

    /// Decodes [`Model::to_bytes`]'s layout; a wrong magic, another version, a truncated or
    /// corrupted file each give an [`ErrorKind::Model`] error saying what was expected.
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
        if version != MODEL_FORMAT_VERSION {
            return Err(err(format!(
                "expected format version {MODEL_FORMAT_VERSION}, found version {version} (rebuild the model with this camplace)"
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

        let mut feat = r.section(TAG_FEAT)?;
        feat.expect_len(n_features, FEATURE_BYTES, "features")?;
        let mut feature_points = Vec::with_capacity(n_features);
        let mut feature_normals = Vec::with_capacity(n_features);
        let mut descriptors = Vec::with_capacity(n_features);
        for _ in 0..n_features {
            feature_points.push(Point3::from(feat.vec3("feature point")?));
            feature_normals.push(feat.vec3("feature normal")?);
            let mut d = [0.0; DESCRIPTOR_LEN];
            for v in &mut d {
                *v = feat.f32("descriptor")?;
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
            s.expect_len(n, VIEW_POINT_BYTES, "view points")?;
            let mut points = Vec::with_capacity(n);
            let mut normals = Vec::with_capacity(n);
            for _ in 0..n {
                points.push(Point3::from(s.vec3("view point")?));
                normals.push(s.vec3("view normal")?);
            }
            s.finish()?;
            views.push(ModelView { view_direction, points, normals });
        }

        let mut symm = r.section(TAG_SYMM)?;
        symm.expect_len(n_symmetries, 4, "symmetries")?;
        let symmetries_deg = (0..n_symmetries).map(|_| symm.f32("symmetry")).collect::<Result<Vec<_>>>()?;
        symm.finish()?;
        if r.remaining() != 0 {
            return Err(err(format!(
                "expected the body to end after section SYMM, found {} more bytes",
                r.remaining()
            )));
        }

        let model = Model { surface_resolution, feature_points, feature_normals, descriptors, views, symmetries_deg };
        model.validate()?;
        Ok(model)
    }
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

/// A box tray made of cuboids and scenes of it with known poses, built analytically so tests
/// and benches can check the pose stages against ground truth without rendering.
pub mod synthetic {
    use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    use super::{Model, ModelView, DESCRIPTOR_LEN};
    use crate::correspondence::Correspondence;

    /// Spacing of surface samples, mm (the paper's surface resolution).
    pub const SPACING: f32 = 2.0;
    /// Spacing of feature key points, mm.
    pub const KEYPOINT_SPACING: f32 = 4.0;
    /// Polar angle of the sensor that built the model's views, deg.
    const VIEW_POLAR_DEG: f32 = 30.0;
    /// Distance of the sensor from the tray origin, mm.
    const SENSOR_DISTANCE: f32 = 800.0;

    /// An axis-aligned cuboid `[min, max]` of the tray, tray frame.
    type Cuboid = ([f32; 3], [f32; 3]);

    /// The tray's solid parts: a 200 × 130 × 30 mm box with 4 mm walls and floor, a low
    /// divider, and (unless `symmetric`) a tab on the +x wall that breaks the 180° symmetry.
    pub fn tray_cuboids(symmetric: bool) -> Vec<Cuboid> {
        let mut c = vec![
            ([-100.0, -65.0, 0.0], [100.0, 65.0, 4.0]),
            ([96.0, -65.0, 4.0], [100.0, 65.0, 30.0]),
            ([-100.0, -65.0, 4.0], [-96.0, 65.0, 30.0]),
            ([-96.0, 61.0, 4.0], [96.0, 65.0, 30.0]),
            ([-96.0, -65.0, 4.0], [96.0, -61.0, 30.0]),
            ([-2.0, -61.0, 4.0], [2.0, 61.0, 18.0]),
        ];
        if !symmetric {
            c.push(([100.0, 15.0, 0.0], [116.0, 45.0, 15.0]));
        }
        c
    }

    /// Surface samples of the cuboids' union at `spacing`, with outward normals, tray frame.
    pub fn surface(cuboids: &[Cuboid], spacing: f32) -> (Vec<Point3<f32>>, Vec<Vector3<f32>>) {
        let mut points = Vec::new();
        let mut normals = Vec::new();
        for (ci, (lo, hi)) in cuboids.iter().enumerate() {
            for axis in 0..3 {
                let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
                let nu = ((hi[u] - lo[u]) / spacing).round().max(1.0) as usize;
                let nv = ((hi[v] - lo[v]) / spacing).round().max(1.0) as usize;
                for (side, plane) in [(-1.0f32, lo[axis]), (1.0, hi[axis])] {
                    for i in 0..nu {
                        for j in 0..nv {
                            let mut p = [0.0; 3];
                            p[axis] = plane;
                            p[u] = lo[u] + (i as f32 + 0.5) * (hi[u] - lo[u]) / nu as f32;
                            p[v] = lo[v] + (j as f32 + 0.5) * (hi[v] - lo[v]) / nv as f32;
                            // A face shared with another part is inside the solid, not on its surface.
                            let buried = cuboids.iter().enumerate().any(|(k, (a, b))| {
                                k != ci && (0..3).all(|d| p[d] >= a[d] - 1e-3 && p[d] <= b[d] + 1e-3)
                            });
                            if buried || (axis == 2 && side < 0.0 && plane <= 0.0) {
                                continue;
                            }
                            let mut n = Vector3::zeros();
                            n[axis] = side;
                            points.push(Point3::from(p));
                            normals.push(n);
                        }
                    }
                }
            }
        }
        (points, normals)
    }

    /// Whether the segment from `p` to `eye` passes through no cuboid.
    fn unoccluded(cuboids: &[Cuboid], p: &Point3<f32>, n: &Vector3<f32>, eye: &Point3<f32>) -> bool {
        let start = p + n * 0.05;
        let d = eye - start;
        cuboids.iter().all(|(lo, hi)| {
            let (mut t0, mut t1) = (0.0f32, 1.0f32);
            for a in 0..3 {
                if d[a].abs() < 1e-9 {
                    if start[a] < lo[a] || start[a] > hi[a] {
                        return true;
                    }
                } else {
                    let (mut ta, mut tb) = ((lo[a] - start[a]) / d[a], (hi[a] - start[a]) / d[a]);
                    if ta > tb {
                        std::mem::swap(&mut ta, &mut tb);
                    }
                    t0 = t0.max(ta);
                    t1 = t1.min(tb);
                    if t0 > t1 {
                        return true;
                    }
                }
            }
            false
        })
    }

    /// Indices of the surface samples an eye at `eye` (tray frame) sees.
    fn visible(cuboids: &[Cuboid], points: &[Point3<f32>], normals: &[Vector3<f32>], eye: &Point3<f32>) -> Vec<usize> {
        (0..points.len())
            .filter(|&i| normals[i].dot(&(eye - points[i])) > 0.0 && unoccluded(cuboids, &points[i], &normals[i], eye))
            .collect()
    }

    /// One point per occupied voxel of size `spacing` (the first one met), as indices.
    fn voxel_subsample(points: &[Point3<f32>], spacing: f32) -> Vec<usize> {
        let mut seen = std::collections::HashSet::new();
        (0..points.len())
            .filter(|&i| {
                let p = points[i];
                let key =
                    ((p.x / spacing).floor() as i32, (p.y / spacing).floor() as i32, (p.z / spacing).floor() as i32);
                seen.insert(key)
            })
            .collect()
    }

    /// The synthetic tray model: 6 viewpoints (the tray turned about z in 60° steps under a
    /// sensor at 30° from vertical), each an ICP cloud at [`SPACING`]; feature key points at
    /// [`KEYPOINT_SPACING`] from every view, with seeded random descriptors.
    pub fn tray(symmetric: bool, seed: u64) -> Model {
        let cuboids = tray_cuboids(symmetric);
        let (points, normals) = surface(&cuboids, SPACING);
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut model = Model {
            surface_resolution: SPACING,
            symmetries_deg: if symmetric { vec![180.0] } else { Vec::new() },
            ..Model::default()
        };
        let polar = VIEW_POLAR_DEG.to_radians();
        for k in 0..6 {
            let turn = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), -(k as f32 * 60.0).to_radians());
            let view_direction = turn * Vector3::new(0.0, -polar.sin(), polar.cos());
            let eye = Point3::from(view_direction * SENSOR_DISTANCE);
            let seen = visible(&cuboids, &points, &normals, &eye);
            let view = ModelView {
                view_direction,
                points: seen.iter().map(|&i| points[i]).collect(),
                normals: seen.iter().map(|&i| normals[i]).collect(),
            };
            for i in voxel_subsample(&view.points, KEYPOINT_SPACING) {
                model.feature_points.push(view.points[i]);
                model.feature_normals.push(view.normals[i]);
                let mut d = [0.0; DESCRIPTOR_LEN];
                d.iter_mut().for_each(|v| *v = rng.random_range(0.0..1.0));
                model.descriptors.push(d);
            }
            model.views.push(view);
        }
        model
    }

    /// How a synthetic scene is drawn.
    #[derive(Debug, Clone)]
    pub struct SceneSpec {
        pub seed: u64,
        /// Uniform noise on each coordinate, ± mm.
        pub noise_mm: f32,
        /// Share of the visible tray cut away by a random vertical plane (0 .. 1).
        pub cut_share: f32,
        /// Matches listed per scene key point.
        pub matches_per_keypoint: usize,
        /// Share of key points on the tray whose matches include the right model feature.
        pub correct_share: f32,
        /// Points of a clutter box beside the tray.
        pub clutter_points: usize,
        /// Whether the tray is in the scene at all.
        pub with_tray: bool,
        /// Tilt of the tray about its x axis, deg (0: resting on the table).
        pub tilt_deg: f32,
        /// Spacing of the scene's key points, mm.
        pub keypoint_spacing_mm: f32,
    }

    impl Default for SceneSpec {
        fn default() -> Self {
            SceneSpec {
                seed: 1,
                noise_mm: 0.3,
                cut_share: 0.2,
                matches_per_keypoint: 5,
                correct_share: 0.5,
                clutter_points: 1000,
                with_tray: true,
                tilt_deg: 0.0,
                keypoint_spacing_mm: KEYPOINT_SPACING,
            }
        }
    }

    /// A scene of the synthetic tray with its ground truth.
    #[derive(Debug, Clone)]
    pub struct Scene {
        /// The true pose of the tray.
        pub t_world_tray: Isometry3<f64>,
        /// Where the sensor is, world frame.
        pub sensor_position: Point3<f32>,
        /// The scene cloud, world frame.
        pub points: Vec<Point3<f32>>,
        /// Feature key points, world frame.
        pub keypoints: Vec<Point3<f32>>,
        /// Matches of key points to model features, most of them wrong.
        pub correspondences: Vec<Correspondence>,
        /// Correspondences that are right under the true pose.
        pub correct: usize,
    }

    impl Scene {
        /// Draws a scene of `model`'s tray (built by [`tray`] with the same symmetry) resting
        /// on the table at a random x, y and yaw, seen from above at 30° from vertical.
        pub fn generate(model: &Model, symmetric: bool, spec: &SceneSpec) -> Scene {
            let mut rng = ChaCha8Rng::seed_from_u64(spec.seed);
            let yaw = rng.random_range(-std::f32::consts::PI..std::f32::consts::PI);
            let (x, y) = (rng.random_range(-100.0..100.0), rng.random_range(-100.0..100.0));
            let tilt = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), spec.tilt_deg.to_radians());
            let rotation = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), yaw) * tilt;
            let lift = if spec.tilt_deg != 0.0 { 40.0 } else { 0.0 };
            let t_world_tray = Isometry3::from_parts(Translation3::new(x, y, lift), rotation).cast::<f64>();
            let polar = VIEW_POLAR_DEG.to_radians();
            let sensor_position = Point3::new(0.0, -polar.sin(), polar.cos()) * SENSOR_DISTANCE;
            let pose = t_world_tray.cast::<f32>();

            let mut points = Vec::new();
            if spec.with_tray {
                let cuboids = tray_cuboids(symmetric);
                let (surface_points, surface_normals) = surface(&cuboids, SPACING);
                let eye = pose.inverse_transform_point(&sensor_position);
                let seen = visible(&cuboids, &surface_points, &surface_normals, &eye);
                let cut_dir = {
                    let a = rng.random_range(0.0..std::f32::consts::TAU);
                    Vector3::new(a.cos(), a.sin(), 0.0)
                };
                let mut order: Vec<(f32, usize)> =
                    seen.iter().map(|&i| (surface_points[i].coords.dot(&cut_dir), i)).collect();
                order.sort_by(|a, b| a.0.total_cmp(&b.0));
                let keep = ((1.0 - spec.cut_share.clamp(0.0, 1.0)) * order.len() as f32) as usize;
                for &(_, i) in &order[..keep] {
                    points.push(pose * surface_points[i]);
                }
            }
            // A box-shaped item lying on the table beside the tray.
            let centre = Vector3::new(x + 190.0 * (yaw + 1.0).cos(), y + 190.0 * (yaw + 1.0).sin(), 0.0);
            for _ in 0..spec.clutter_points {
                let mut p = Vector3::new(rng.random_range(-25.0..25.0), rng.random_range(-25.0..25.0), 35.0);
                match rng.random_range(0..3) {
                    0 => {}
                    1 => p.x = if p.x > 0.0 { 25.0 } else { -25.0 },
                    _ => p.y = if p.y > 0.0 { 25.0 } else { -25.0 },
                }
                if p.z != 35.0 || rng.random_range(0..2) == 0 {
                    p.z = rng.random_range(0.0..35.0);
                }
                points.push(Point3::from(centre + p));
            }
            for p in &mut points {
                for a in 0..3 {
                    p[a] += rng.random_range(-1.0..=1.0) * spec.noise_mm;
                }
            }

            let keypoints: Vec<Point3<f32>> =
                voxel_subsample(&points, spec.keypoint_spacing_mm).into_iter().map(|i| points[i]).collect();
            let mut correspondences = Vec::new();
            let mut correct = 0;
            let n_model = model.feature_points.len() as u32;
            for (si, kp) in keypoints.iter().enumerate() {
                let local = pose.inverse_transform_point(kp);
                let nearest = model
                    .feature_points
                    .iter()
                    .enumerate()
                    .map(|(i, f)| (i, (f - local).norm_squared()))
                    .min_by(|a, b| a.1.total_cmp(&b.1))
                    .filter(|&(_, d2)| spec.with_tray && d2 < 3.0 * 3.0);
                let right = nearest.filter(|_| rng.random_range(0.0..1.0) < spec.correct_share).map(|(i, _)| i as u32);
                let slot = rng.random_range(0..spec.matches_per_keypoint.max(1));
                for m in 0..spec.matches_per_keypoint {
                    let model_index = match right {
                        Some(i) if m == slot => {
                            correct += 1;
                            i
                        }
                        _ => rng.random_range(0..n_model),
                    };
                    let distance2 = rng.random_range(0.0..1.0);
                    correspondences.push(Correspondence { scene: si as u32, model: model_index, distance2 });
                }
            }
            Scene { t_world_tray, sensor_position, points, keypoints, correspondences, correct }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
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
        }
    }

    #[test]
    fn bytes_round_trip() {
        for seed in 0..5 {
            let m = small_model(seed);
            assert_eq!(Model::from_bytes(&m.to_bytes()).unwrap(), m);
        }
        let tray = synthetic::tray(false, 1);
        assert_eq!(Model::from_bytes(&tray.to_bytes()).unwrap(), tray);
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
        assert!(e.to_string().contains("version 1") && e.to_string().contains("version 7"), "{e}");
        let mut b = small_model(4).to_bytes();
        b.push(0);
        assert_eq!(Model::from_bytes(&b).unwrap_err().kind(), ErrorKind::Model);
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
        assert!(Model::from_bytes(&m.to_bytes()).is_err());
        let mut m = small_model(5);
        m.views[0].view_direction *= 2.0;
        assert!(m.validate().is_err());
    }

    #[test]
    fn closest_view_matches_brute_force_angles() {
        let model = synthetic::tray(false, 1);
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
        let m = synthetic::tray(false, 1);
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
