//! Point-to-plane ICP: refines the tray's pose by pulling the scene cloud onto the closest
//! viewpoint's model cloud, whose normals give the planes. The coarse pose comes from RANSAC.
//!
//! Scene points are taken into the tray frame and matched to a nearest model point through a
//! lookup grid per view, built once; pairs farther than `icp_max_distance` are ignored and the
//! farthest `icp_trim` share of the rest is dropped, so clutter and items absent from the
//! model do not drag the pose. Each step solves the linearised 6×6 normal equations; with
//! `icp_on_table` the tray rests on the table (bottom at z = 0, no tilt) and each step solves
//! the 3×3 part of x, y and the turn about z, since a tray lying on the table has no other
//! freedom and a free fit only adds the reconstruction's tilt to the pose.

use std::sync::Arc;

use camplace_config::EstimatorParams;
use nalgebra::{Isometry3, Matrix6, Point3, Vector3, Vector6};
use rayon::prelude::*;

use crate::error::{Error, ErrorKind, Result};
use crate::pose::alternatives::{Alternatives, MAX_ALTERNATIVES};
use crate::pose::self_occlusion::{HiddenInViews, Occluder};
use crate::spatial::NearestGrid;
use crate::Model;

/// An update smaller than this in translation (mm) and rotation (rad) ends the iterations:
/// a hundredth of a millimetre (and 1e-4 rad, a hundredth of a millimetre at 100 mm) is a
/// hundred times below the sensor's depth noise. Point-to-plane ICP on nearest-point pairs
/// converges linearly, and its last steps shrink slowly as pairs switch between neighbours:
/// a thousandth of a millimetre cost several times the iterations (often all of them) for
/// no change in any pose error worth the name.
const CONVERGED_TRANSLATION: f64 = 1e-2;
const CONVERGED_ROTATION: f64 = 1e-4;
/// Levenberg damping relative to the largest diagonal entry of the normal equations.
const DAMPING: f64 = 1e-9;
/// Fewer pairs than this cannot pin down 6 degrees of freedom with any confidence.
const MIN_PAIRS: usize = 12;

/// The outcome of [`Icp::refine`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IcpResult {
    /// Whether enough scene points lay near the model to fit; when false `t_world_tray` is
    /// the start pose.
    pub refined: bool,
    /// Refined pose of the tray in the world.
    pub t_world_tray: Isometry3<f64>,
    /// Iterations run.
    pub iterations: u32,
    /// Pairs used in the last iteration.
    pub correspondences: u32,
    /// Root mean square point-to-plane distance of those pairs, mm.
    pub rms_mm: f32,
    /// Whether the last update fell below the convergence threshold.
    pub converged: bool,
}

impl Default for IcpResult {
    fn default() -> Self {
        IcpResult {
            refined: false,
            t_world_tray: Isometry3::identity(),
            iterations: 0,
            correspondences: 0,
            rms_mm: 0.0,
            converged: false,
        }
    }
}

/// One scene-model pair of the current iteration.
#[derive(Debug, Clone, Copy)]
struct Pair {
    /// Scene point in the tray frame under the current pose.
    scene: Point3<f32>,
    /// The model point, or [`Pair::NONE`] when the scene point has no partner.
    model: u32,
    distance2: f32,
}

impl Pair {
    const NONE: u32 = u32::MAX;
    const UNPAIRED: Pair = Pair { scene: Point3::new(0.0, 0.0, 0.0), model: Pair::NONE, distance2: 0.0 };
}

/// Scene points per parallel task of an iteration. Fixed, so the sums are taken in the same
/// order, and the pose comes out the same, whatever the number of threads.
const CHUNK: usize = 1024;

/// One chunk's share of the normal equations: JᵀJ by its upper triangle (row by row), which
/// is all a symmetric matrix holds.
#[derive(Debug, Clone, Copy)]
struct Partial {
    jtj: [f64; 21],
    jtr: [f64; 6],
    used: usize,
    sum2: f64,
}

impl Partial {
    fn zero() -> Partial {
        Partial { jtj: [0.0; 21], jtr: [0.0; 6], used: 0, sum2: 0.0 }
    }

    /// Adds one pair's row `j` of the Jacobian and its residual `r`.
    #[inline]
    fn add(&mut self, j: &[f64; 6], r: f64) {
        let mut at = 0;
        for a in 0..6 {
            for b in a..6 {
                self.jtj[at] += j[a] * j[b];
                at += 1;
            }
            self.jtr[a] += j[a] * r;
        }
        self.used += 1;
        self.sum2 += r * r;
    }

    /// Adds this chunk's sums to the whole normal equations (`jtj` filled on both sides).
    fn add_to(&self, jtj: &mut Matrix6<f64>, jtr: &mut Vector6<f64>) {
        let mut at = 0;
        for a in 0..6 {
            for b in a..6 {
                jtj[(a, b)] += self.jtj[at];
                if b != a {
                    jtj[(b, a)] += self.jtj[at];
                }
                at += 1;
            }
            jtr[a] += self.jtr[a];
        }
    }
}

/// Point-to-plane ICP with its lookup grids and buffers, built for one model, which it keeps.
#[derive(Clone)]
pub struct Icp {
    model: Arc<Model>,
    iterations: u32,
    max_distance: f32,
    trim: f32,
    /// Whether the tray is kept resting on the table (x, y and yaw refined).
    on_table: bool,
    grids: Vec<NearestGrid>,
    /// Scene points near the tray at the start pose, world frame.
    near: Vec<Point3<f32>>,
    /// One slot per near point.
    pairs: Vec<Pair>,
    distances: Vec<f32>,
    /// One per chunk of near points.
    partials: Vec<Partial>,
    /// Each view's bounding box, tray frame.
    bounds: Vec<(Point3<f32>, Point3<f32>)>,
    /// Every view's points merged at the surface resolution, tray frame, and their grid.
    whole_points: Vec<Point3<f32>>,
    whole: NearestGrid,
    /// The bounding box of `whole_points`, tray frame.
    whole_bounds: (Point3<f32>, Point3<f32>),
    /// The poses the tray can be mistaken for: its quarter turns, and the turns that lay
    /// its slot grid onto itself.
    alternatives: Alternatives,
    /// Per whole-tray point, bit `k` set when the tray at alternative `k` has no point
    /// within `DISTINCT_MARGIN` inlier distances of it: the parts (a tab, a chamfer, a
    /// whole end) where the tray and that alternative to it differ.
    distinct: Vec<u16>,
    /// Per view, the whole-tray points the tray itself hides from that view's direction:
    /// no scene point on them counts for a part.
    hidden: HiddenInViews,
}

/// How far, in inlier distances, a whole-tray point must lie from the turned tray to tell
/// the tray from its turn: beyond twice the reach, a scene point explained near the body the
/// two share cannot count for either, however far (up to a reach) the turn is off.
pub const DISTINCT_MARGIN: f32 = 2.0;

impl std::fmt::Debug for Icp {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Icp").field("iterations", &self.iterations).field("views", &self.grids.len()).finish()
    }
}

impl Icp {
    /// Builds a lookup grid over every view of `model`; fails when a view has too few points.
    /// `sight` is the sensor's distance from the tray (mm), from which the tray's parts
    /// hidden by the tray itself are found for each view.
    pub fn new(params: &EstimatorParams, model: Arc<Model>, sight: f32) -> Result<Self> {
        model.validate()?;
        let occluder = Occluder::of(&model, sight);
        Icp::with_occluder(params, model, &occluder)
    }

    /// [`Icp::new`] with the model already validated and its occluder built (the pipeline
    /// builds it once for ICP and the verifier).
    pub(crate) fn with_occluder(params: &EstimatorParams, model: Arc<Model>, occluder: &Occluder) -> Result<Self> {
        let mut bounds = Vec::with_capacity(model.views.len());
        for (k, view) in model.views.iter().enumerate() {
            if view.points.len() < MIN_PAIRS {
                return Err(Error::new(
                    ErrorKind::Model,
                    format!("model: expected at least {MIN_PAIRS} points in view {k}, found {}", view.points.len()),
                ));
            }
            let mut lo = view.points[0];
            let mut hi = view.points[0];
            for p in &view.points {
                lo = lo.inf(p);
                hi = hi.sup(p);
            }
            bounds.push((lo, hi));
        }
        let all: Vec<Point3<f32>> = model.views.iter().flat_map(|v| v.points.iter().copied()).collect();
        let mut whole_points = Vec::new();
        crate::Downsampler::new().downsample(&all, model.surface_resolution, &mut whole_points)?;
        let first = whole_points.first().copied().unwrap_or_else(Point3::origin);
        let whole_bounds = whole_points.iter().fold((first, first), |(lo, hi), p| (lo.inf(p), hi.sup(p)));
        // The grids are independent: built side by side, each the same whatever the threads.
        let (grids, whole) = rayon::join(
            || {
                model
                    .views
                    .par_iter()
                    .map(|view| {
                        NearestGrid::new(&view.points, model.surface_resolution, params.icp_max_distance as f32)
                    })
                    .collect::<Vec<_>>()
            },
            || NearestGrid::new(&whole_points, model.surface_resolution, params.inlier_distance as f32),
        );
        let margin = DISTINCT_MARGIN * params.inlier_distance as f32;
        let alternatives = Alternatives::of(&model);
        let mut distinct = distinct_parts(&whole_points, model.surface_resolution, margin, &alternatives);
        // A phantom of the capture (smear a view saw past) is no part of the tray's.
        for (bits, p) in distinct.iter_mut().zip(&whole_points) {
            if occluder.phantom(p) {
                *bits = 0;
            }
        }
        let hidden = occluder.hidden(&[&whole_points]).remove(0);
        let capacity = 1 << 15;
        Ok(Icp {
            model,
            alternatives,
            whole_points,
            whole,
            distinct,
            hidden,
            whole_bounds,
            iterations: params.icp_iterations,
            max_distance: params.icp_max_distance as f32,
            trim: params.icp_trim as f32,
            on_table: params.icp_on_table,
            grids,
            near: Vec::with_capacity(capacity),
            pairs: Vec::with_capacity(capacity),
            distances: Vec::with_capacity(capacity),
            partials: Vec::with_capacity(capacity.div_ceil(CHUNK)),
            bounds,
        })
    }

    /// Refines `start` (the tray's pose in the world) against `view` of the model, using the
    /// scene cloud `scene_points` seen from `sensor_position_world` (world frame). The
    /// result's `refined` is false, with the start pose, when too few scene points lie near
    /// the model to fit. With `icp_on_table` the start is first laid on the table (its x, y
    /// and turn about z kept) and stays there.
    pub fn refine(
        &mut self,
        scene_points: &[Point3<f32>],
        view: usize,
        sensor_position_world: &Point3<f32>,
        start: &Isometry3<f64>,
    ) -> Result<IcpResult> {
        let start = if self.on_table { on_table(start) } else { *start };
        let mut out = IcpResult { t_world_tray: start, ..IcpResult::default() };
        let model = Arc::clone(&self.model);
        let Some(model_view) = model.views.get(view) else {
            return Err(Error::new(
                ErrorKind::Input,
                format!("icp: expected a view index below {}, found {view}", self.grids.len()),
            ));
        };

        // Only points that could pair with the model at the start pose take part; a pose
        // that moves far enough to need others has not converged on this tray anyway.
        let margin = Vector3::repeat(2.0 * self.max_distance);
        let (lo, hi) = (self.bounds[view].0 - margin, self.bounds[view].1 + margin);
        let to_tray = start.inverse().cast::<f32>();
        self.near.clear();
        for p in scene_points {
            let q = to_tray * p;
            if (0..3).all(|a| q[a] >= lo[a] && q[a] <= hi[a]) {
                self.near.push(*p);
            }
        }

        let grid = &self.grids[view];
        let max2 = self.max_distance * self.max_distance;
        // The tray-frame pose of the world, refined in place.
        let mut t_tray_world = start.inverse();
        for iteration in 1..=self.iterations {
            let pose = t_tray_world.cast::<f32>();
            let eye = pose * sensor_position_world;
            self.pairs.clear();
            self.pairs.resize(self.near.len(), Pair::UNPAIRED);
            self.pairs.par_chunks_mut(CHUNK).zip(self.near.par_chunks(CHUNK)).for_each(|(pairs, near)| {
                for (pair, p) in pairs.iter_mut().zip(near) {
                    let q = pose * p;
                    let Some(item) = grid.lookup(&q) else { continue };
                    let (m, n) = (&model_view.points[item as usize], &model_view.normals[item as usize]);
                    let distance2 = (q - m).norm_squared();
                    // The view cloud holds surfaces this sensor may not see (and misses some
                    // it does); a scene point cannot lie on a surface turned away from the
                    // sensor, and pairing it there drags thin walls by their thickness.
                    if distance2 <= max2 && n.dot(&(eye - m)) > 0.0 {
                        *pair = Pair { scene: q, model: item, distance2 };
                    }
                }
            });
            let keep2 = trim_threshold(&self.pairs, &mut self.distances, self.trim);
            self.partials.clear();
            self.partials.resize(self.pairs.len().div_ceil(CHUNK), Partial::zero());
            self.partials.par_iter_mut().zip(self.pairs.par_chunks(CHUNK)).for_each(|(partial, pairs)| {
                for pair in pairs {
                    if pair.model == Pair::NONE || pair.distance2 > keep2 {
                        continue;
                    }
                    let m = model_view.points[pair.model as usize].cast::<f64>();
                    let n = model_view.normals[pair.model as usize].cast::<f64>();
                    let q = pair.scene.cast::<f64>();
                    let r = (q - m).dot(&n);
                    let c = q.coords.cross(&n);
                    partial.add(&[c.x, c.y, c.z, n.x, n.y, n.z], r);
                }
            });
            let mut jtj = Matrix6::<f64>::zeros();
            let mut jtr = Vector6::<f64>::zeros();
            let (mut used, mut sum2) = (0usize, 0.0f64);
            for partial in &self.partials {
                partial.add_to(&mut jtj, &mut jtr);
                used += partial.used;
                sum2 += partial.sum2;
            }
            out.iterations = iteration;
            out.correspondences = used as u32;
            out.rms_mm = if used > 0 { (sum2 / used as f64).sqrt() as f32 } else { 0.0 };
            if used < MIN_PAIRS {
                out.refined = iteration > 1;
                return Ok(out);
            }
            // A direction no pair constrains (a view that shows no wall across it) gets a tiny
            // damping term instead of a singular system, so the pose simply stays put along it.
            let damping = DAMPING * jtj.diagonal().max();
            for k in 0..6 {
                jtj[(k, k)] += damping;
            }
            let step = if self.on_table {
                // The turn about the tray's z axis and the shift along its x and y: the tray
                // frame's z is the world's while the tray lies on the table.
                const FREE: [usize; 3] = [2, 3, 4];
                let a = nalgebra::Matrix3::from_fn(|i, j| jtj[(FREE[i], FREE[j])]);
                let b = Vector3::from_fn(|i, _| -jtr[FREE[i]]);
                a.cholesky().map(|c| {
                    let x = c.solve(&b);
                    Vector6::new(0.0, 0.0, x[0], x[1], x[2], 0.0)
                })
            } else {
                jtj.cholesky().map(|c| c.solve(&(-jtr)))
            };
            let Some(step) = step else {
                out.refined = iteration > 1;
                return Ok(out);
            };
            let rotation = Vector3::new(step[0], step[1], step[2]);
            let translation = Vector3::new(step[3], step[4], step[5]);
            t_tray_world = Isometry3::new(translation, rotation) * t_tray_world;
            out.t_world_tray = t_tray_world.inverse();
            if translation.norm() < CONVERGED_TRANSLATION && rotation.norm() < CONVERGED_ROTATION {
                out.converged = true;
                break;
            }
        }
        out.refined = true;
        Ok(out)
    }
}

impl Icp {
    /// The whole-tray point within `sqrt(reach2)` of `q` (tray frame) that explains it: a
    /// point of any view within reach (up to the lookup grid's half cell). All views together
    /// describe the tray from every side, so two hypotheses are judged against the same
    /// surface.
    fn explainer(&self, q: &Point3<f32>, reach2: f32) -> Option<usize> {
        self.whole
            .lookup(q)
            .map(|item| item as usize)
            .filter(|&item| (q - self.whole_points[item]).norm_squared() <= reach2)
    }

    /// In one pass over the scene cloud (world frame): whether the whole tray at
    /// `t_world_tray` explains each point, and from it (1) among the points inside the whole
    /// tray's bounding box at the pose grown by `reach`, how many the tray explains, and
    /// (2) for each of the alternatives `which` (indices into [`Icp::alternatives`], at most
    /// `MAX_ALTERNATIVES`), the points the pose's distinct parts explain against those the
    /// alternative's distinct parts explain; a distinct part counts only where it is in
    /// sight from `sensor` (world) at its own pose and no phantom of the capture
    /// (`pose/self_occlusion.rs`).
    ///
    /// Scene points beside the tray are no evidence either way; inside its box, each is
    /// either the tray's surface or something where the model says there is free space.
    /// A nearly symmetric tray and its turn differ only in small parts (a tab): only scene
    /// points on the parts one of them has and the other lacks (`DISTINCT_MARGIN` away from
    /// anything of the other) tell them apart. The body the two share counts for neither, so
    /// a turn left a millimetre off (it was not refined) gains or loses nothing by it, and a
    /// scene that does not show the parts gives no evidence for either. Nor do points within
    /// `DISTINCT_MARGIN` reaches of the plane the tray stands on: the table beside a low
    /// tab's foot lies as near the tab as the tab's own points do.
    pub fn explained_near_and_apart(
        &self,
        scene_points: &[Point3<f32>],
        t_world_tray: &Isometry3<f64>,
        which: &[usize],
        reach: f32,
        sensor: &Point3<f32>,
    ) -> ExplainedCounts {
        let which = &which[..which.len().min(MAX_ALTERNATIVES)];
        let pose = t_world_tray.inverse().cast::<f32>();
        // The view the sensor sees the tray from at the pose: a distinct part the tray
        // hides from there holds no evidence, whatever scene points lie on it.
        let view = self.model.closest_view(t_world_tray, sensor);
        // Per alternative: its pose's inverse, the bit of the pose's own distinct parts
        // against it, the bit of the alternative's parts against the pose (its inverse)
        // and the view at the alternative.
        let mut others = [(pose, 0u16, 0u16, view); MAX_ALTERNATIVES];
        let list = self.alternatives.list();
        for (slot, &k) in others.iter_mut().zip(which) {
            let k = k.min(list.len() - 1);
            let back = self.alternatives.inverse_of(k);
            let turned = t_world_tray * list[k].transform();
            *slot = (turned.inverse().cast::<f32>(), 1 << k, 1 << back, self.model.closest_view(&turned, sensor));
        }
        let others = &others[..which.len()];
        let reach2 = reach * reach;
        let grow = Vector3::repeat(reach);
        let (lo, hi) = (self.whole_bounds.0 - grow, self.whole_bounds.1 + grow);
        // Scene points this near the plane the tray stands on are the table's as much as
        // any part's: no evidence for a part (a low tab's edge beside the table).
        let floor = self.whole_bounds.0.z + DISTINCT_MARGIN * reach;
        let sum = |a: ExplainedCounts, b: ExplainedCounts| {
            let mut out = ExplainedCounts { explained: a.explained + b.explained, inside: a.inside + b.inside, ..a };
            for (o, (x, y)) in out.apart.iter_mut().zip(a.apart.iter().zip(&b.apart)) {
                *o = (x.0 + y.0, x.1 + y.1);
            }
            out
        };
        scene_points
            .par_chunks(CHUNK)
            .map(|chunk| {
                let mut counts = ExplainedCounts::default();
                for p in chunk {
                    let q = pose * p;
                    let own = self.explainer(&q, reach2);
                    if (0..3).all(|a| q[a] >= lo[a] && q[a] <= hi[a]) {
                        counts.inside += 1;
                        counts.explained += u32::from(own.is_some());
                    }
                    if q.z <= floor {
                        continue;
                    }
                    let own = own.filter(|&i| !self.hidden.hidden(view, i));
                    for (apart, (other, own_bit, their_bit, their_view)) in counts.apart.iter_mut().zip(others) {
                        apart.0 += u32::from(own.is_some_and(|i| self.distinct[i] & own_bit != 0));
                        let theirs = self.explainer(&(other * p), reach2);
                        let shown =
                            |i: &usize| self.distinct[*i] & their_bit != 0 && !self.hidden.hidden(*their_view, *i);
                        apart.1 += u32::from(theirs.is_some_and(|i| shown(&i)));
                    }
                }
                counts
            })
            .reduce(ExplainedCounts::default, sum)
    }

    /// The poses the tray can be mistaken for ([`Alternatives::of`] its model).
    pub fn alternatives(&self) -> &Alternatives {
        &self.alternatives
    }
}

/// [`Icp`]'s `distinct` bits of `points` (the whole tray, tray frame): bit `k` of a point
/// set when no point lies within `margin` of it taken back by alternative `k`, that is
/// when the tray at that alternative has nothing near it.
fn distinct_parts(points: &[Point3<f32>], resolution: f32, margin: f32, alternatives: &Alternatives) -> Vec<u16> {
    let grid = NearestGrid::new(points, resolution, margin);
    let margin2 = margin * margin;
    points
        .par_iter()
        .map(|p| {
            let mut bits = 0u16;
            for (k, a) in alternatives.list().iter().enumerate() {
                let back = a.back(p);
                let near = grid.lookup(&back).is_some_and(|i| (back - points[i as usize]).norm_squared() <= margin2);
                bits |= u16::from(!near) << k;
            }
            bits
        })
        .collect()
}

/// The counts of [`Icp::explained_near_and_apart`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct ExplainedCounts {
    /// Points inside the tray's grown box at the pose that the tray explains there.
    pub explained: u32,
    /// Points inside the tray's grown box at the pose.
    pub inside: u32,
    /// Per alternative weighed: (points the pose's distinct parts explain, points the
    /// alternative's distinct parts explain).
    pub apart: [(u32, u32); MAX_ALTERNATIVES],
}

/// `t_world_tray` laid on the table: the same x, y and turn about z (of the tray's x axis
/// seen from above), its bottom at z = 0 and no tilt.
pub fn on_table(t_world_tray: &Isometry3<f64>) -> Isometry3<f64> {
    let x_axis = t_world_tray.rotation * Vector3::x();
    let yaw = x_axis.y.atan2(x_axis.x);
    let t = t_world_tray.translation.vector;
    Isometry3::new(Vector3::new(t.x, t.y, 0.0), Vector3::new(0.0, 0.0, yaw))
}

/// The squared distance at or below which pairs are kept once the farthest `trim` share of
/// them is dropped.
fn trim_threshold(pairs: &[Pair], distances: &mut Vec<f32>, trim: f32) -> f32 {
    if trim <= 0.0 {
        return f32::INFINITY;
    }
    distances.clear();
    distances.extend(pairs.iter().filter(|p| p.model != Pair::NONE).map(|p| p.distance2));
    let drop = (trim * distances.len() as f32) as usize;
    if drop == 0 {
        return f32::INFINITY;
    }
    let keep = distances.len() - drop;
    *distances.select_nth_unstable_by(keep - 1, f32::total_cmp).1
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::{self, Scene, SceneSpec};
    use crate::Ransac;
    use camplace_config::Cell;
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// The normal equations summed by their upper triangle equal, to the bit, the full outer
    /// products summed in the same order (the slow, obvious version), chunk by chunk and
    /// merged.
    #[test]
    fn half_of_jtj_sums_to_the_full_outer_products() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let (mut jtj, mut jtr) = (Matrix6::<f64>::zeros(), Vector6::<f64>::zeros());
        let (mut want_jtj, mut want_jtr) = (Matrix6::<f64>::zeros(), Vector6::<f64>::zeros());
        for _ in 0..4 {
            let mut partial = Partial::zero();
            let (mut full, mut full_r) = (Matrix6::<f64>::zeros(), Vector6::<f64>::zeros());
            for _ in 0..300 {
                let j: [f64; 6] = std::array::from_fn(|_| rng.random_range(-500.0..500.0));
                let r = rng.random_range(-3.0..3.0);
                partial.add(&j, r);
                let v = Vector6::from_column_slice(&j);
                full += v * v.transpose();
                full_r += v * r;
            }
            partial.add_to(&mut jtj, &mut jtr);
            want_jtj += full;
            want_jtr += full_r;
            assert_eq!(partial.used, 300);
        }
        assert_eq!(jtj, want_jtj);
        assert_eq!(jtr, want_jtr);
    }

    fn pose_error(a: &Isometry3<f64>, b: &Isometry3<f64>) -> (f64, f64) {
        ((a.translation.vector - b.translation.vector).norm(), (a.inverse() * b).rotation.angle().to_degrees())
    }

    /// From a start a few mm and degrees off, ICP lands within a fraction of a mm.
    #[test]
    fn converges_from_a_perturbed_start() {
        let model = Arc::new(testing::tray(false, 1));
        let params = Cell::default().estimator;
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        for seed in 0..8 {
            let mut params = params.clone();
            params.icp_trim = if seed % 2 == 0 { 0.0 } else { 0.1 };
            let mut icp = Icp::new(&params, model.clone(), testing::SENSOR_DISTANCE).unwrap();
            let scene = Scene::generate(&model, false, &SceneSpec { seed, ..SceneSpec::default() });
            let nudge = Isometry3::new(
                Vector3::new(rng.random_range(-2.5..2.5), rng.random_range(-2.5..2.5), rng.random_range(-1.5..1.5)),
                Vector3::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0), rng.random_range(-2.0..2.0))
                    * 1f64.to_radians(),
            );
            let start = scene.t_world_tray * nudge;
            let view = model.closest_view(&start, &scene.sensor_position);
            let out = icp.refine(&scene.points, view, &scene.sensor_position, &start).unwrap();
            assert!(out.refined);
            let (dt, dr) = pose_error(&out.t_world_tray, &scene.t_world_tray);
            assert!(dt < 0.5 && dr < 0.25, "seed {seed}: {dt} mm {dr} deg {out:?}");
            assert!(out.converged, "{out:?}");
        }
    }

    /// The whole pose stage on a noisy, partly hidden, cluttered scene with 90 % wrong
    /// matches: within 1 mm and 0.5 degree of the truth.
    #[test]
    fn ransac_then_icp_recovers_the_pose() {
        let model = Arc::new(testing::tray(false, 1));
        let params = Cell::default().estimator;
        let mut ransac = Ransac::new(&params, model.clone()).unwrap();
        let mut icp = Icp::new(&params, model.clone(), testing::SENSOR_DISTANCE).unwrap();
        for seed in 10..14 {
            let spec =
                SceneSpec { seed, noise_mm: 0.5, correct_share: 0.5, matches_per_keypoint: 5, ..SceneSpec::default() };
            let scene = Scene::generate(&model, false, &spec);
            let coarse = ransac
                .estimate(
                    &scene.points,
                    &scene.keypoints,
                    &scene.keypoint_normals,
                    &scene.correspondences,
                    &scene.sensor_position,
                )
                .unwrap();
            assert!(coarse.found);
            let fine = icp.refine(&scene.points, coarse.view, &scene.sensor_position, &coarse.t_world_tray).unwrap();
            assert!(fine.refined);
            let (dt, dr) = pose_error(&fine.t_world_tray, &scene.t_world_tray);
            assert!(dt < 1.0 && dr < 0.5, "seed {seed}: {dt} mm {dr} deg {fine:?}");
        }
    }

    /// On the table, a start tilted by a degree and lifted by 2 mm comes back flat on the
    /// table with x, y and the turn refined (the free fit's errors printed beside).
    #[test]
    fn on_the_table_only_x_y_and_the_turn_are_refined() {
        let model = Arc::new(testing::tray(false, 1));
        let mut params = Cell::default().estimator;
        assert!(!params.icp_on_table, "off by default, as in the paper");
        params.icp_on_table = true;
        let mut on_table = Icp::new(&params, model.clone(), testing::SENSOR_DISTANCE).unwrap();
        params.icp_on_table = false;
        let mut free = Icp::new(&params, model.clone(), testing::SENSOR_DISTANCE).unwrap();
        for seed in 20..24 {
            let spec = SceneSpec { seed, noise_mm: 0.5, ..SceneSpec::default() };
            let scene = Scene::generate(&model, false, &spec);
            let nudge = Isometry3::new(Vector3::new(1.5, -2.0, 2.0), Vector3::new(1.0, -0.5, 1.5) * 1f64.to_radians());
            let start = scene.t_world_tray * nudge;
            let view = model.closest_view(&start, &scene.sensor_position);
            let out = on_table.refine(&scene.points, view, &scene.sensor_position, &start).unwrap();
            assert!(out.refined && out.converged, "{out:?}");
            let pose = out.t_world_tray;
            assert_eq!(pose.translation.vector.z, 0.0, "seed {seed}");
            assert!((pose.rotation * Vector3::z()).z > 1.0 - 1e-12, "seed {seed}: {pose:?}");
            let (dt, dr) = pose_error(&pose, &scene.t_world_tray);
            let (ft, fr) = pose_error(
                &free.refine(&scene.points, view, &scene.sensor_position, &start).unwrap().t_world_tray,
                &scene.t_world_tray,
            );
            eprintln!("seed {seed}: on the table {dt:.3} mm {dr:.4} deg, free {ft:.3} mm {fr:.4} deg");
            assert!(dt < 0.5 && dr < 0.1, "seed {seed}: {dt} mm {dr} deg");
        }
    }

    #[test]
    fn too_few_scene_points_keep_the_start() {
        let model = Arc::new(testing::tray(false, 1));
        let mut icp = Icp::new(&Cell::default().estimator, model.clone(), testing::SENSOR_DISTANCE).unwrap();
        let start = Isometry3::translation(10.0, 0.0, 0.0);
        let far = [Point3::new(900.0, 900.0, 0.0); 50];
        let out = icp.refine(&far, 0, &Point3::new(0.0, 0.0, 800.0), &start).unwrap();
        assert!(!out.refined);
        assert_eq!(out.t_world_tray, start);
        assert_eq!(icp.refine(&far, 6, &Point3::new(0.0, 0.0, 800.0), &start).unwrap_err().kind(), ErrorKind::Input);
    }

    /// The half turn's index among the alternatives.
    const HALF: usize = 1;

    /// The distinct bits as a search over every point finds them: set where the turned tray
    /// (or the tray turned and shifted onto its own slot grid) has no point within the
    /// margin, clear where it has one, but for points whose nearest turned neighbour lies
    /// within the grid's rounding (a cell's diagonal) of the margin.
    #[test]
    fn distinct_parts_are_where_the_turned_tray_has_nothing() {
        let params = Cell::default().estimator;
        let margin = DISTINCT_MARGIN * params.inlier_distance as f32;
        for symmetric in [false, true] {
            let mut model = testing::tray(symmetric, 1);
            // Six slots, 3 x 2 at 60 mm both ways: a quarter turn moved (±30, ±30) mm and a
            // half turn moved (±60, 0) mm lay four of them onto slots.
            let slots = (0..6).map(|n| [-60.0 + 60.0 * (n % 3) as f64, -30.0 + 60.0 * (n / 3) as f64, 6.0, 0.0]);
            model.slots = Some(crate::pose::SlotLayout {
                slots: slots.collect(),
                footprint_min_mm: [-20.0, -20.0],
                cell_mm: [10.0, 10.0],
                cols: 4,
                rows: 4,
                top_mm: vec![10.0; 16],
            });
            let model = Arc::new(model);
            let icp = Icp::new(&params, model.clone(), testing::SENSOR_DISTANCE).unwrap();
            let alternatives = icp.alternatives().list();
            // The symmetric tray lists its half turn: shifted, that is a shift, not weighed.
            let shifted_half_turns = if symmetric { 0 } else { 2 };
            assert_eq!(alternatives.len(), 3 + 8 + shifted_half_turns, "{alternatives:?}");
            let points = &icp.whole_points;
            let slack = model.surface_resolution * 3f32.sqrt();
            let mut set = vec![0usize; alternatives.len()];
            for (p, &bits) in points.iter().zip(&icp.distinct) {
                for (k, a) in alternatives.iter().enumerate() {
                    let back = a.transform().cast::<f32>().inverse_transform_point(p);
                    let nearest = points.iter().map(|w| (back - w).norm()).fold(f32::INFINITY, f32::min);
                    let bit = bits & (1 << k) != 0;
                    set[k] += usize::from(bit);
                    if (nearest - margin).abs() > slack {
                        assert_eq!(bit, nearest > margin, "{p:?} at {a:?}: nearest {nearest} mm");
                    }
                }
            }
            // The shifted alternatives leave whole ends and sides apart.
            for (k, a) in alternatives.iter().enumerate().skip(3) {
                assert!(set[k] * 10 > points.len(), "{a:?}: {} of {}", set[k], points.len());
            }
            // The half turn: only the tab differs, and a tray without one has nothing apart.
            // The quarter turns of a 200 x 130 mm tray leave whole ends apart.
            if symmetric {
                assert!(set[1] * 200 < points.len(), "{set:?} of {}", points.len());
            } else {
                assert!(set[1] > 20 && set[1] * 10 < points.len(), "{set:?} of {}", points.len());
            }
            assert!(set[0] * 5 > points.len() && set[2] * 5 > points.len(), "{set:?}");
        }
    }

    /// The table beside a low tab, where the tray stands and where its half turn would put
    /// the tab, is no evidence for either; the tab's top is, for the pose that has it.
    #[test]
    fn the_table_beside_a_tab_tells_nothing() {
        let params = Cell::default().estimator;
        let reach = params.inlier_distance as f32;
        let model = Arc::new(testing::tray(false, 1));
        let icp = Icp::new(&params, model, testing::SENSOR_DISTANCE).unwrap();
        let pose = Isometry3::identity();
        // Above the tray, on the tab's side: the tab's top in sight.
        let sensor = Point3::new(400.0, 0.0, 700.0);
        // The table (the tray's bottom plane, a few tenths of a millimetre of noise above
        // it) around both ends' tab places, at half a millimetre.
        let table: Vec<Point3<f32>> = (0..60)
            .flat_map(|i| (0..100).map(move |j| (i, j)))
            .flat_map(|(i, j)| {
                let (x, y) = (95.0 + 0.5 * i as f32, 5.0 + 0.5 * j as f32);
                let z = 0.1 * ((i + j) % 4) as f32;
                [Point3::new(x, y, z), Point3::new(-x, -y, z)]
            })
            .collect();
        // Both tab places hold points the distinct parts would explain, but for the floor.
        let near_tab = table.iter().filter(|p| p.x > 100.0 && p.x < 118.0 && p.y > 13.0 && p.y < 47.0).count();
        assert!(near_tab > 500, "{near_tab}");
        let apart = icp.explained_near_and_apart(&table, &pose, &[HALF], reach, &sensor).apart[0];
        assert_eq!(apart, (0, 0), "the table counted for a part");
        // The tab's top at the pose: its points speak for the pose alone.
        let top: Vec<Point3<f32>> =
            (0..12).flat_map(|i| (0..26).map(move |j| Point3::new(102.0 + i as f32, 17.0 + j as f32, 15.0))).collect();
        let apart = icp.explained_near_and_apart(&top, &pose, &[HALF], reach, &sensor).apart[0];
        // (Those within the margin of the +x wall, which the half turn also has, are not.)
        assert!(apart.1 == 0 && apart.0 as usize * 2 > top.len(), "the tab's top: {apart:?} of {}", top.len());
    }

    /// The scene's tab speaks for the pose that has it there and against its half turn,
    /// whichever of the two the counts start from; a tray without a tab gives neither any
    /// evidence.
    #[test]
    fn the_tab_alone_tells_a_pose_from_its_half_turn() {
        let params = Cell::default().estimator;
        let reach = params.inlier_distance as f32;
        let half = Isometry3::rotation(Vector3::z() * std::f64::consts::PI);
        let mut seen = 0;
        for seed in 0..12 {
            let model = Arc::new(testing::tray(false, 1));
            let icp = Icp::new(&params, model.clone(), testing::SENSOR_DISTANCE).unwrap();
            let scene = Scene::generate(&model, false, &SceneSpec { seed, ..SceneSpec::default() });
            let right = icp
                .explained_near_and_apart(&scene.points, &scene.t_world_tray, &[HALF], reach, &scene.sensor_position)
                .apart[0];
            let turned = scene.t_world_tray * half;
            let wrong =
                icp.explained_near_and_apart(&scene.points, &turned, &[HALF], reach, &scene.sensor_position).apart[0];
            // Counted from either side, the same points on the same parts.
            assert_eq!(right, (wrong.1, wrong.0), "seed {seed}");
            // The scene points on the tab's outer part (the tab spans x 100..116 mm, y 15..45
            // mm), counted in the tray's frame without the model.
            let to_tray = scene.t_world_tray.inverse().cast::<f32>();
            let on_tab = scene
                .points
                .iter()
                .map(|p| to_tray * p)
                .filter(|q| q.x > 100.0 + DISTINCT_MARGIN * reach && q.x < 117.0 && q.y > 14.0 && q.y < 46.0)
                .count();
            if on_tab >= 20 {
                let lead = (right.0 as f32 - right.1 as f32) / ((right.0 + right.1) as f32).sqrt();
                assert!(right.0 >= 20 && lead >= 3.0, "seed {seed}: {right:?} with {on_tab} points on the tab");
                seen += 1;
            } else {
                // A hidden tab leaves only the rare stray point on either's parts.
                assert!(
                    right.0 as usize + right.1 as usize <= on_tab + 2,
                    "seed {seed}: {right:?} with {on_tab} points on the tab"
                );
            }

            let model = Arc::new(testing::tray(true, 1));
            let icp = Icp::new(&params, model.clone(), testing::SENSOR_DISTANCE).unwrap();
            let scene = Scene::generate(&model, true, &SceneSpec { seed, ..SceneSpec::default() });
            let none = icp
                .explained_near_and_apart(&scene.points, &scene.t_world_tray, &[HALF], reach, &scene.sensor_position)
                .apart[0];
            assert!(none.0 + none.1 <= 2, "seed {seed}: {none:?}");
        }
        // Not vacuous: most scenes show the tab.
        assert!(seen >= 6, "{seen} of 12 scenes showed the tab");
    }
}
