//! The pre-rejection checks (Buch et al.'s "prerejective" step): tests a sample must pass
//! before its pose is scored, each a named unit applied at the stage where its inputs exist
//! (the scene key points drawn, then their model features, then the fitted pose). RANSAC
//! takes them as a list; [`RansacCheck::paper`] is the paper's list for 3-match samples,
//! [`RansacCheck::table_pair`] the list for 2-match samples of a level tray and
//! [`RansacCheck::table_point`] the one for 1-match samples with normals. Drawing the
//! samples is `sampling.rs`'s, scoring them `scoring.rs`'s.

use camplace_config::EstimatorParams;
use nalgebra::{Isometry3, Point3, Vector3};

/// The least horizontal length of a unit normal that fixes a level tray's turn (sin 30°): a
/// normal error of e turns the tray by about e over this.
pub const MIN_NORMAL_LEAN: f32 = 0.5;
/// The largest difference of the vertical parts of a match's two unit normals: about 11.5°
/// of lean at a wall, where the parts are near 0.
pub const MAX_LEAN_DIFFERENCE: f32 = 0.2;

/// The largest angle between a match's scene normal and its model feature's normal turned
/// by the fitted pose, deg (Open3D's normal-based correspondence check): a wrong pair of
/// matches rarely turns both model normals onto their key points'. At 30° the noisier
/// normals of a far placement (r=1000, alpha=60, one shot, 300 scenes) lost right pairs:
/// 225 correct poses against 232 without the check (one-sided McNemar p = 0.03); at 45°,
/// 230 (p = 0.34).
pub const MAX_NORMAL_DISAGREEMENT_DEG: f32 = 45.0;

/// Samples whose scene triangle is thinner than this (twice its area over its longest edge
/// squared) fix the rotation about their long side poorly.
const MIN_TRIANGLE_SHAPE: f32 = 0.05;

/// One pre-rejection check.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum RansacCheck {
    /// The scene triangle's edges are each at least `sqrt(min_edge2)` long and it is not a
    /// sliver (3 key points).
    SceneTriangle {
        /// Squared shortest edge, mm².
        min_edge2: f32,
    },
    /// The scene pair lies at least `sqrt(min_edge2)` apart horizontally (2 key points).
    HorizontalSpan {
        /// Squared shortest horizontal distance, mm².
        min_edge2: f32,
    },
    /// Every scene edge and its model counterpart agree in length: shorter over longer at
    /// least `similarity` (the paper's polygonal edge-length ratio).
    EdgeRatio {
        /// The lowest ratio of the shorter to the longer edge.
        similarity: f32,
    },
    /// The pair's horizontal lengths agree to `similarity`, as a level tray's would.
    HorizontalEdgeRatio {
        /// The lowest ratio of the shorter to the longer horizontal length.
        similarity: f32,
    },
    /// The pair's height differences in the scene and the model agree within `max_mm`.
    HeightDifference {
        /// The largest disagreement, mm.
        max_mm: f32,
    },
    /// The scene key point's normal, and its model feature's, each have a horizontal part at
    /// least `min_lean` long (unit normals), enough to fix the turn about z (1 match).
    SteepNormal {
        /// The least horizontal length.
        min_lean: f32,
    },
    /// The match's scene and model normals lean alike from vertical: their vertical parts
    /// differ by at most `max_difference`, as a level tray's would (1 match).
    NormalLean {
        /// The largest difference.
        max_difference: f32,
    },
    /// Each match's model normal, turned by the fitted pose, lies within the angle whose
    /// cosine is `min_cos` of its scene key point's normal (unit normals, both towards the
    /// sensor).
    NormalAgreement {
        /// Cosine of the largest angle.
        min_cos: f32,
    },
    /// The paper's table check on the fitted pose: the tray's bottom within `table_height`
    /// of the table and its z axis within the tilt whose cosine is `cos_tilt` of world z.
    OnTable {
        /// The largest height of the tray's origin above or below the table, mm.
        table_height: f64,
        /// Cosine of the largest tilt.
        cos_tilt: f64,
    },
}

impl RansacCheck {
    /// The checks of `params`' sample size: [`RansacCheck::table_point`] for 1,
    /// [`RansacCheck::table_pair`] for 2, else [`RansacCheck::paper`].
    pub fn for_params(params: &EstimatorParams) -> Vec<RansacCheck> {
        match params.ransac_sample {
            1 => RansacCheck::table_point(params).to_vec(),
            2 => RansacCheck::table_pair(params).to_vec(),
            _ => RansacCheck::paper(params).to_vec(),
        }
    }

    /// The checks of a 1-match sample of a tray lying level on the table: normals that fix
    /// the turn and lean alike, and a pose that rests on the table; for the 2-match sample
    /// a key point whose normal does not fix the turn starts, [`RansacCheck::table_pair`]'s.
    pub fn table_point(params: &EstimatorParams) -> [RansacCheck; 7] {
        let [span, ratio, height, on_table, normals] = RansacCheck::table_pair(params);
        [
            RansacCheck::SteepNormal { min_lean: MIN_NORMAL_LEAN },
            RansacCheck::NormalLean { max_difference: MAX_LEAN_DIFFERENCE },
            span,
            ratio,
            height,
            on_table,
            normals,
        ]
    }

    /// The paper's checks of a 3-match sample: a good scene triangle, edges that agree in
    /// length, a pose that rests on the table.
    pub fn paper(params: &EstimatorParams) -> [RansacCheck; 3] {
        [
            RansacCheck::SceneTriangle { min_edge2: min_edge2(params) },
            RansacCheck::EdgeRatio { similarity: params.edge_similarity as f32 },
            RansacCheck::on_table(params),
        ]
    }

    /// The checks of a 2-match sample of a tray lying level on the table: a pair far enough
    /// apart horizontally, horizontal lengths and height differences that agree, a pose
    /// that rests on the table, and each match's normals in agreement under that pose.
    pub fn table_pair(params: &EstimatorParams) -> [RansacCheck; 5] {
        [
            RansacCheck::HorizontalSpan { min_edge2: min_edge2(params) },
            RansacCheck::HorizontalEdgeRatio { similarity: params.edge_similarity as f32 },
            RansacCheck::HeightDifference { max_mm: 2.0 * params.inlier_distance as f32 },
            RansacCheck::on_table(params),
            RansacCheck::NormalAgreement { min_cos: MAX_NORMAL_DISAGREEMENT_DEG.to_radians().cos() },
        ]
    }

    /// The table check of `params`.
    fn on_table(params: &EstimatorParams) -> RansacCheck {
        RansacCheck::OnTable { table_height: params.table_height, cos_tilt: params.table_tilt.to_radians().cos() }
    }

    /// Whether the scene key points `s` pass (checks of other stages pass everything).
    #[inline]
    pub fn scene(&self, s: &[Point3<f32>]) -> bool {
        match *self {
            RansacCheck::SceneTriangle { min_edge2 } => good_scene_triangle(s, min_edge2),
            RansacCheck::HorizontalSpan { min_edge2 } => {
                let ds = s[1] - s[0];
                ds.x * ds.x + ds.y * ds.y >= min_edge2
            }
            _ => true,
        }
    }

    /// Whether the scene key points `s` and their model features `m` pass.
    #[inline]
    pub fn matched(&self, s: &[Point3<f32>], m: &[Point3<f32>]) -> bool {
        match *self {
            RansacCheck::EdgeRatio { similarity } => edges_agree(s, m, similarity),
            RansacCheck::HorizontalEdgeRatio { similarity } => {
                let (ds, dm) = (s[1] - s[0], m[1] - m[0]);
                let ls2 = ds.x * ds.x + ds.y * ds.y;
                let lm2 = dm.x * dm.x + dm.y * dm.y;
                ls2.min(lm2) >= similarity * similarity * ls2.max(lm2)
            }
            RansacCheck::HeightDifference { max_mm } => ((s[1].z - s[0].z) - (m[1].z - m[0].z)).abs() <= max_mm,
            _ => true,
        }
    }

    /// Whether the scene key point's unit normal `ns` passes (1 match).
    #[inline]
    pub fn scene_normal(&self, ns: &Vector3<f32>) -> bool {
        match *self {
            RansacCheck::SteepNormal { min_lean } => ns.x * ns.x + ns.y * ns.y >= min_lean * min_lean,
            _ => true,
        }
    }

    /// Whether the scene key point's unit normal `ns` and its model feature's `nm` pass
    /// (1 match).
    #[inline]
    pub fn matched_normal(&self, ns: &Vector3<f32>, nm: &Vector3<f32>) -> bool {
        match *self {
            RansacCheck::SteepNormal { min_lean } => nm.x * nm.x + nm.y * nm.y >= min_lean * min_lean,
            RansacCheck::NormalLean { max_difference } => (ns.z - nm.z).abs() <= max_difference,
            _ => true,
        }
    }

    /// Whether a match's scene key point normal `ns` and its model feature's normal turned by
    /// the fitted pose, `nm_world`, pass (unit normals).
    #[inline]
    pub fn posed_normal(&self, ns: &Vector3<f32>, nm_world: &Vector3<f32>) -> bool {
        match *self {
            RansacCheck::NormalAgreement { min_cos } => ns.dot(nm_world) >= min_cos,
            _ => true,
        }
    }

    /// Whether the check reads the key points' normals.
    pub fn reads_normals(&self) -> bool {
        matches!(
            self,
            RansacCheck::SteepNormal { .. } | RansacCheck::NormalLean { .. } | RansacCheck::NormalAgreement { .. }
        )
    }

    /// Whether the fitted `pose` passes.
    #[inline]
    pub fn pose(&self, pose: &Isometry3<f64>) -> bool {
        match *self {
            RansacCheck::OnTable { table_height, cos_tilt } => {
                let z_axis = pose.rotation * Vector3::z();
                pose.translation.vector.z.abs() <= table_height && z_axis.z >= cos_tilt
            }
            _ => true,
        }
    }
}

/// Key points closer than a feature's support share most of it, so their matches are not
/// independent evidence, and short edges make a shaky rotation.
fn min_edge2(params: &EstimatorParams) -> f32 {
    (params.feature_radius as f32).powi(2)
}

/// The edges of a sample of `n` points: the pair's one, or a triangle's three.
fn edges(n: usize) -> &'static [(usize, usize)] {
    if n == 2 {
        &[(0, 1)]
    } else {
        &[(0, 1), (1, 2), (2, 0)]
    }
}

/// Scene edges at least `sqrt(min_edge2)` long and a triangle that is not a sliver.
fn good_scene_triangle(s: &[Point3<f32>], min_edge2: f32) -> bool {
    let mut longest2 = 0.0f32;
    for &(i, j) in edges(s.len()) {
        let ls = (s[i] - s[j]).norm_squared();
        if ls < min_edge2 {
            return false;
        }
        longest2 = longest2.max(ls);
    }
    let twice_area = (s[1] - s[0]).cross(&(s[2] - s[0])).norm();
    twice_area >= MIN_TRIANGLE_SHAPE * longest2
}

/// Every scene edge and its model counterpart agree to `similarity` (shorter over longer).
fn edges_agree(s: &[Point3<f32>], m: &[Point3<f32>], similarity: f32) -> bool {
    let sim2 = similarity * similarity;
    edges(s.len()).iter().all(|&(i, j)| {
        let ls = (s[i] - s[j]).norm_squared();
        let lm = (m[i] - m[j]).norm_squared();
        ls.min(lm) >= sim2 * ls.max(lm)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Buch et al.'s polygonal pre-rejection: the scene triangle is usable and every edge of
    /// it and its model counterpart agree to `similarity` (shorter over longer).
    fn similar_triangles(s: &[Point3<f32>; 3], m: &[Point3<f32>; 3], similarity: f32, min_edge2: f32) -> bool {
        let checks = [RansacCheck::SceneTriangle { min_edge2 }, RansacCheck::EdgeRatio { similarity }];
        checks.iter().all(|c| c.scene(s) && c.matched(s, m))
    }

    #[test]
    fn triangle_check_follows_edge_ratios() {
        let s = [Point3::new(0.0, 0.0, 0.0), Point3::new(100.0, 0.0, 0.0), Point3::new(0.0, 80.0, 0.0)];
        let same = s.map(|p| p + Vector3::new(5.0, -3.0, 2.0));
        assert!(similar_triangles(&s, &same, 0.9, 400.0));
        let stretched = [s[0], Point3::new(115.0, 0.0, 0.0), s[2]];
        assert!(!similar_triangles(&s, &stretched, 0.9, 400.0));
        assert!(similar_triangles(&s, &stretched, 0.8, 400.0));
        let small = s.map(|p| p * 0.1);
        assert!(!similar_triangles(&small, &small, 0.9, 400.0));
        let sliver = [s[0], s[1], Point3::new(50.0, 1.0, 0.0)];
        assert!(!similar_triangles(&sliver, &sliver, 0.9, 400.0));
    }

    /// A pair is judged by its horizontal span and lengths and its height difference; a
    /// level pose passes the table check, a tilted or lifted one does not.
    #[test]
    fn pair_and_table_checks_follow_their_limits() {
        let mut p = camplace_config::Cell::default().estimator;
        p.feature_radius = 20.0;
        p.edge_similarity = 0.9;
        p.inlier_distance = 2.0;
        let [span, ratio, height, table, normals] = RansacCheck::table_pair(&p);
        let s = [Point3::new(0.0, 0.0, 0.0), Point3::new(30.0, 0.0, 5.0)];
        assert!(span.scene(&s) && !span.scene(&[s[0], Point3::new(10.0, 10.0, 50.0)]));
        let m = [Point3::new(1.0, 1.0, 0.0), Point3::new(1.0, 30.0, 3.0)];
        assert!(ratio.matched(&s, &m) && height.matched(&s, &m));
        assert!(!ratio.matched(&s, &[m[0], Point3::new(1.0, 20.0, 3.0)]));
        assert!(!height.matched(&s, &[m[0], Point3::new(1.0, 30.0, 0.5)]));
        let level = Isometry3::new(Vector3::new(10.0, 20.0, 0.0), Vector3::z() * 1.0);
        assert!(table.pose(&level));
        let lifted = Isometry3::new(Vector3::new(10.0, 20.0, 10.0 + p.table_height), Vector3::z() * 1.0);
        assert!(!table.pose(&lifted));
        let tilted = Isometry3::new(Vector3::zeros(), Vector3::x() * (p.table_tilt + 1.0).to_radians());
        assert!(!table.pose(&tilted));
        // A match's normals agree under the pose up to the largest disagreement.
        let wall = Vector3::new(0.0, -1.0, 0.0);
        let turned = |deg: f32| Vector3::new(deg.to_radians().sin(), -deg.to_radians().cos(), 0.0);
        assert!(normals.posed_normal(&wall, &turned(MAX_NORMAL_DISAGREEMENT_DEG - 0.5)));
        assert!(!normals.posed_normal(&wall, &turned(MAX_NORMAL_DISAGREEMENT_DEG + 0.5)));
        assert!(!normals.posed_normal(&wall, &-wall));
        // Checks of other stages pass everything.
        assert!(span.matched(&s, &m) && ratio.scene(&s) && span.pose(&lifted));
        assert!(span.posed_normal(&wall, &-wall) && normals.pose(&lifted) && normals.matched(&s, &m));
    }

    /// A match's normals pass when both lean enough to fix a turn and lean alike.
    #[test]
    fn point_checks_follow_the_normals_lean() {
        let p = camplace_config::Cell::default().estimator;
        let [steep, lean, ..] = RansacCheck::table_point(&p);
        let wall = Vector3::new(0.0, -1.0, 0.0);
        let flat = Vector3::new(0.2, 0.0, 0.98).normalize();
        assert!(steep.scene_normal(&wall) && !steep.scene_normal(&flat));
        let chamfer = Vector3::new(0.7, 0.0, 0.7).normalize();
        let turned = Vector3::new(0.0, 0.7, 0.7).normalize();
        assert!(steep.matched_normal(&chamfer, &turned) && lean.matched_normal(&chamfer, &turned));
        assert!(!steep.matched_normal(&chamfer, &flat));
        assert!(!lean.matched_normal(&chamfer, &wall));
        // At the limits.
        let leaning = |h: f32| Vector3::new(h, 0.0, (1.0 - h * h).sqrt());
        assert!(steep.scene_normal(&leaning(MIN_NORMAL_LEAN + 1e-3)));
        assert!(!steep.scene_normal(&leaning(MIN_NORMAL_LEAN - 1e-3)));
        let (a, b) = (Vector3::new(1.0, 0.0, 0.0), Vector3::new(0.0, 1.0, MAX_LEAN_DIFFERENCE - 1e-3));
        assert!(lean.matched_normal(&a, &b));
        assert!(!lean.matched_normal(&a, &Vector3::new(0.0, 1.0, MAX_LEAN_DIFFERENCE + 1e-3)));
        // Checks of other stages pass everything.
        assert!(lean.scene_normal(&flat) && RansacCheck::on_table(&p).matched_normal(&a, &flat));
    }
}
