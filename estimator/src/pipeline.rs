//! The deployed pipeline (docs/design/estimator-stages.md): every stage joined, from a stereo frame (or a world
//! cloud) to the tray's pose, with its timings. It owns the buffers of all stages; the stages
//! themselves live in their own modules.
//!
//! After reconstruction: down-sampling to SRes, PCA normals, key points every
//! `keypoint_spacing`, ECSAD descriptors, key points without relief dropped, k-NN matching
//! with the height band, prerejective RANSAC (2- or 3-match samples), point-to-plane ICP on
//! the closest view, and last the turn check: a tray is nearly symmetric under a half turn
//! (a square one under quarter turns too), so the pose turned by 90°, 180° and 270° about
//! the tray's z axis is scored too and the one whose whole tray explains most of the scene
//! is kept. Last, the verification scores the pose against the scene cloud and gives it a
//! verdict (`pose/verify.rs`), and each slot of the tray is judged filled, empty or unseen
//! under that pose from the same cloud (`pose/slots.rs`).
//!
//! Allocation policy: `Estimator::new` sizes every buffer for a full camera frame; a frame
//! larger than any seen before may grow one once, after which `process` allocates nothing.

use std::sync::Arc;
use std::time::Instant;

use camplace_config::{AsImageView, EstimatorParams};
use nalgebra::{Isometry3, Point3};

use crate::pose::{lead_sigmas, most_favoured_turn, on_table, turn_favoured, turn_see_through, Weighed};
use crate::{
    Correspondence, DepthEvidence, Error, ErrorKind, EstimatorConfig, FeatureExtractor, FeatureMatcher, Icp, IcpResult,
    Method, Model, Ransac, RansacResult, Reconstruction, Reconstructor, Result, Rig, SlotJudge, SlotReading, Verdict,
    Verification, Verifier, AMBIGUOUS_TURN_SIGMAS,
};

/// Time spent in each stage of the last frame, ms (zero for stages a frame skipped).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct StageTimings {
    /// Rectification of the raw shots.
    pub rectify_ms: f64,
    /// Disparity: one-shot stereo or 12-shot phase decoding.
    pub disparity_ms: f64,
    /// Disparity to world cloud with background removal.
    pub cloud_ms: f64,
    /// Voxel down-sampling to the surface resolution.
    pub downsample_ms: f64,
    /// Neighbour grid and PCA normals.
    pub normals_ms: f64,
    /// Key points and ECSAD descriptors.
    pub features_ms: f64,
    /// k-NN descriptor matching with the height filter, and RANSAC's scene index, built
    /// alongside it.
    pub matching_ms: f64,
    /// Prerejective RANSAC (its sampling, scoring and consensus re-fit).
    pub ransac_ms: f64,
    /// Point-to-plane ICP.
    pub icp_ms: f64,
    /// The verification of the pose.
    pub verify_ms: f64,
    /// The whole frame.
    pub total_ms: f64,
}

impl StageTimings {
    /// The stages' names in pipeline order, as [`StageTimings::by_stage`] gives their times.
    pub const STAGES: [&'static str; 10] =
        ["rectify", "disparity", "cloud", "downsample", "normals", "features", "matching", "ransac", "icp", "verify"];

    /// Each stage's time in pipeline order (the whole frame not included), ms.
    pub fn by_stage(&self) -> [f64; 10] {
        [
            self.rectify_ms,
            self.disparity_ms,
            self.cloud_ms,
            self.downsample_ms,
            self.normals_ms,
            self.features_ms,
            self.matching_ms,
            self.ransac_ms,
            self.icp_ms,
            self.verify_ms,
        ]
    }
}

/// The pose of one frame, as [`Estimator::process`] returns it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PoseEstimate {
    /// Whether a pose passed RANSAC's checks; when false the pose is meaningless.
    pub found: bool,
    /// The verification's score and verdict; only an accepted pose may be handed on.
    pub verification: Verification,
    /// Tray frame -> world frame, after ICP.
    pub t_world_tray: Isometry3<f64>,
    /// RANSAC inliers of the closest view's ICP cloud.
    pub inliers: u32,
    /// Per-stage time of this frame.
    pub timings: StageTimings,
    /// The coarse pose and its counts, for diagnosis.
    pub ransac: RansacResult,
    /// The refinement's counts, for diagnosis.
    pub icp: IcpResult,
    /// Points of the down-sampled scene cloud.
    pub scene_points: u32,
    /// Scene key points described.
    pub keypoints: u32,
    /// Matches that survived the height filter.
    pub matches: u32,
}

impl PoseEstimate {
    /// Whether the pose may be handed on: found, and accepted by the verification.
    pub fn accepted(&self) -> bool {
        self.found && self.verification.verdict == Verdict::Accepted
    }
}

impl Default for PoseEstimate {
    fn default() -> Self {
        PoseEstimate {
            found: false,
            verification: Verification::default(),
            t_world_tray: Isometry3::identity(),
            inliers: 0,
            timings: StageTimings::default(),
            ransac: RansacResult::default(),
            icp: IcpResult::default(),
            scene_points: 0,
            keypoints: 0,
            matches: 0,
        }
    }
}

/// The stages after reconstruction, with their buffers; apart from the reconstructor so a
/// frame's cloud can be borrowed from it while these run.
#[derive(Clone)]
struct Stages {
    params: EstimatorParams,
    /// Shared with RANSAC and ICP, which were built for it.
    model: Arc<Model>,
    sensor_position: Point3<f32>,
    features: FeatureExtractor,
    heights: Vec<f32>,
    matcher: FeatureMatcher,
    correspondences: Vec<Correspondence>,
    ransac: Ransac,
    icp: Icp,
    verifier: Verifier,
    /// The judge of the model's slots, when it carries them.
    slots: Option<SlotJudge>,
    /// Whether the last frame's slots were judged (a pose was found).
    slots_judged: bool,
}

/// The tray-pose estimator of one rig and model, with every buffer it needs.
#[derive(Clone)]
pub struct Estimator {
    reconstructor: Reconstructor,
    reconstruction: Reconstruction,
    stages: Stages,
    /// Whether the last frame was a stereo frame, whose depth map the verification reads.
    depth_of_last_frame: bool,
}

impl std::fmt::Debug for Estimator {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Estimator")
            .field("method", &self.reconstructor.method())
            .field("features", &self.stages.model.feature_points.len())
            .field("views", &self.stages.model.views.len())
            .finish()
    }
}

/// The last stereo frame's measured depth, as the verification reads it: where the frame
/// was matched in part only, the background's depth outside that part; a phase-12 frame's
/// holes are pixels the projector did not light.
fn depth_evidence<'a>(reconstruction: &'a Reconstruction, reconstructor: &'a Reconstructor) -> DepthEvidence<'a> {
    let beyond = match reconstructor.background() {
        Some(background) if !reconstructor.matched_whole() => Some((reconstructor.last_region(), background.depth())),
        _ => None,
    };
    DepthEvidence {
        disparity: &reconstruction.disparity,
        camera: &reconstructor.rectification().camera,
        beyond,
        holes_unlit: reconstructor.method() == Method::Phase12,
    }
}

fn ms(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}

impl Estimator {
    /// The estimator for `rig` and `model` with `config`'s settings (a cell's, through
    /// `EstimatorConfig::from(&cell)`); allocates every buffer.
    pub fn new(config: &EstimatorConfig, rig: &Rig, model: Model, method: Method) -> Result<Estimator> {
        model.validate()?;
        if model.feature_points.is_empty() {
            return Err(Error::new(ErrorKind::Model, "model: expected at least one feature"));
        }
        let model = Arc::new(model);
        let params = config.estimator.clone();
        let reconstructor = Reconstructor::new(config, rig, method)?;
        let cam = &reconstructor.rectification().camera;
        let (w, h) = (cam.width, cam.height);
        let sensor_position = Point3::from(cam.t_world_rectified.translation.vector.cast::<f32>());
        let pixels = w * h;
        let keypoints = (pixels / 16).max(1024);
        let k = params.k as usize;
        let heights: Vec<f32> = model.feature_points.iter().map(|p| p.z).collect();
        let matcher = FeatureMatcher::new(&model.descriptors, &heights)?;
        let reconstruction = Reconstruction {
            cloud: crate::Cloud::with_capacity(w, h),
            disparity: crate::FloatImage::new(w, h, f32::INFINITY),
            ..Reconstruction::default()
        };
        // The tray lies about the world's origin: its parts the tray itself hides are found
        // from the sensor's distance to it, once for ICP and the verifier (the model was
        // validated above).
        let occluder = crate::pose::Occluder::of(&model, sensor_position.coords.norm());
        let icp = Icp::with_occluder(&params, Arc::clone(&model), &occluder)?;
        let verifier = Verifier::with_occluder(&params, &model, icp.alternatives(), &occluder);
        let slots = model.slots.clone().map(SlotJudge::new).transpose()?;
        let stages = Stages {
            verifier,
            slots,
            slots_judged: false,
            features: FeatureExtractor::new(&params, pixels)?,
            ransac: Ransac::new(&params, Arc::clone(&model))?,
            icp,
            matcher,
            sensor_position,
            heights: Vec::with_capacity(keypoints),
            correspondences: Vec::with_capacity(keypoints * k),
            params,
            model,
        };
        Ok(Estimator { reconstructor, reconstruction, stages, depth_of_last_frame: false })
    }

    /// Uses `rig` from now on (a recalibrated rig, or the one a study's scenario believes
    /// in); the background must be set again, since it is reconstructed through the rig.
    /// Buffers sized by the rectified image are made again when its size changes.
    pub fn set_rig(&mut self, config: &EstimatorConfig, rig: &Rig) -> Result<()> {
        let old = self.reconstructor.rectification().camera.clone();
        self.reconstructor.set_rig(config, rig)?;
        let new = &self.reconstructor.rectification().camera;
        if (old.width, old.height) != (new.width, new.height) {
            let (w, h) = (new.width, new.height);
            self.reconstruction = Reconstruction {
                cloud: crate::Cloud::with_capacity(w, h),
                disparity: crate::FloatImage::new(w, h, f32::INFINITY),
                ..Reconstruction::default()
            };
            self.stages.features = FeatureExtractor::new(&self.stages.params, w * h)?;
            let keypoints = (w * h / 16).max(1024);
            self.stages.heights = Vec::with_capacity(keypoints);
            self.stages.correspondences = Vec::with_capacity(keypoints * self.stages.params.k as usize);
        }
        self.stages.sensor_position = Point3::from(new.t_world_rectified.translation.vector.cast::<f32>());
        Ok(())
    }

    /// Captures the background (the cell without tray) used to clean every later frame.
    /// The shots are owned images or borrowed views, as for [`Estimator::process`].
    pub fn set_background<S: AsImageView<u8> + Sync>(&mut self, left: &[S], right: &[S]) -> Result<()> {
        self.reconstructor.set_background(left, right)
    }

    /// Estimates the tray's pose from one stereo frame (one or twelve shots per side).
    /// A frame without a recognisable tray gives a pose with `found = false`, not an error.
    ///
    /// Each shot is an owned [`camplace_config::GrayImage`] or a borrowed [`camplace_config::ImageView`] of
    /// someone else's pixels (any row stride): the raw pixels are read in place by the
    /// rectification, never copied.
    ///
    /// The frame runs on rayon's pool: entered once here, the stages' parallel loops (many a
    /// frame: ICP's iterations among them) share work between the pool's threads directly,
    /// where each loop started from another thread would wait for a worker to wake.
    pub fn process<S: AsImageView<u8> + Sync>(&mut self, left: &[S], right: &[S]) -> Result<PoseEstimate> {
        rayon::scope(|_| self.process_on_pool(left, right))
    }

    fn process_on_pool<S: AsImageView<u8> + Sync>(&mut self, left: &[S], right: &[S]) -> Result<PoseEstimate> {
        let start = Instant::now();
        self.reconstructor.process(left, right, &mut self.reconstruction)?;
        let r = self.reconstruction.timings;
        let depth = depth_evidence(&self.reconstruction, &self.reconstructor);
        let mut out = self.stages.run(&self.reconstruction.cloud.points, Some(&depth))?;
        self.depth_of_last_frame = true;
        out.timings.rectify_ms = r.rectify_ms;
        out.timings.disparity_ms = r.disparity_ms;
        out.timings.cloud_ms = r.cloud_ms;
        out.timings.total_ms = ms(start);
        Ok(out)
    }

    /// Estimates the tray's pose from a world cloud (mm) seen from the rig's sensor.
    /// Like [`Estimator::process`], it runs on rayon's pool.
    pub fn process_cloud(&mut self, points: &[Point3<f32>]) -> Result<PoseEstimate> {
        rayon::scope(|_| {
            let start = Instant::now();
            self.depth_of_last_frame = false;
            let mut out = self.stages.run(points, None)?;
            out.timings.total_ms = ms(start);
            Ok(out)
        })
    }

    /// The verification's settings in force (the threshold the model carries, or the
    /// cell's when it carries none).
    pub fn verifier(&self) -> &Verifier {
        &self.stages.verifier
    }

    /// `start` refined against the last frame's scene cloud as the frame's own RANSAC pose
    /// was (ICP from the model view closest to the sensor, no turn check), or `start` itself
    /// where too few scene points lie near it: the pose the pipeline would have handed the
    /// verification had RANSAC found `start` (hard negatives, diagnosis).
    pub fn refine(&mut self, start: &Isometry3<f64>) -> Result<Isometry3<f64>> {
        rayon::scope(|_| {
            let s = &mut self.stages;
            let view = s.model.closest_view(start, &s.sensor_position);
            let out = s.icp.refine(s.features.cloud(), view, &s.sensor_position, start)?;
            Ok(if out.refined { out.t_world_tray } else { *start })
        })
    }

    /// The verification of `t_world_tray` against the last frame's scene cloud, as the
    /// frame's own verification ran (for benches and diagnosis of other poses).
    pub fn verify(&self, t_world_tray: &Isometry3<f64>) -> Verification {
        rayon::scope(|_| {
            let s = &self.stages;
            let depth = depth_evidence(&self.reconstruction, &self.reconstructor);
            s.verifier.verify(
                &s.model,
                &s.icp,
                s.ransac.scene_grid(),
                s.features.cloud(),
                &s.sensor_position,
                t_world_tray,
                None,
                self.depth_of_last_frame.then_some(&depth),
            )
        })
    }

    /// Where the first left shot of the last frame began in memory (0 before any frame):
    /// the address of the pixels the rectification read, so an embedder can check that its
    /// own buffer reached the estimator without a copy.
    pub fn last_left_address(&self) -> usize {
        self.reconstructor.last_left_address()
    }

    /// The model it matches against.
    pub fn model(&self) -> &Model {
        &self.stages.model
    }

    /// The sensor position used to orient normals and pick views (the rectified left
    /// camera's centre), world mm.
    pub fn sensor_position(&self) -> Point3<f32> {
        self.stages.sensor_position
    }

    /// The reconstruction of the last stereo frame (disparity, world cloud).
    pub fn reconstruction(&self) -> &Reconstruction {
        &self.reconstruction
    }

    /// The rectified left camera the disparity is in (intrinsics, baseline, pose in the world).
    pub fn rectified_camera(&self) -> &crate::RectifiedCamera {
        &self.reconstructor.rectification().camera
    }

    /// Whether the last stereo frame was matched over the whole image (a 12-shot frame, a
    /// frame without a background, or one that differs from the background everywhere).
    pub fn matched_whole(&self) -> bool {
        self.reconstructor.matched_whole()
    }

    /// The last stereo frame's disparity over the whole image, with the camera it is in: the
    /// frame's own map, or, when a one-shot frame was matched only where it differs from the
    /// background, the pair matched again whole (a one-shot match's time; what `serve`'s
    /// drift watch reads after the reply, since it needs the table far from the tray).
    pub fn whole_disparity(&mut self) -> Result<(&crate::FloatImage, &crate::RectifiedCamera)> {
        let map = if self.reconstructor.match_whole()? {
            self.reconstructor.whole_map()
        } else {
            &self.reconstruction.disparity
        };
        Ok((map, &self.reconstructor.rectification().camera))
    }

    /// The last frame's slots, judged under its pose from the scene cloud (one reading per
    /// slot, each with its frame in the world); empty when the model carries no slots or the
    /// frame found no pose. Only an accepted pose's readings may be handed on.
    pub fn slots(&self) -> &[SlotReading] {
        match &self.stages.slots {
            Some(judge) if self.stages.slots_judged => judge.readings(),
            _ => &[],
        }
    }

    /// The last frame's down-sampled scene cloud, world mm.
    pub fn scene_cloud(&self) -> &[Point3<f32>] {
        self.stages.features.cloud()
    }

    /// The last frame's scene key points, world mm (indexed by `Correspondence::scene`).
    pub fn scene_keypoints(&self) -> &[Point3<f32>] {
        self.stages.features.keypoint_points()
    }

    /// The last frame's feature matches after the height filter.
    pub fn correspondences(&self) -> &[Correspondence] {
        &self.stages.correspondences
    }
}

impl Stages {
    fn run(&mut self, points: &[Point3<f32>], depth: Option<&DepthEvidence>) -> Result<PoseEstimate> {
        let p = &self.params;
        let mut out = PoseEstimate::default();
        self.correspondences.clear();
        self.slots_judged = false;

        let f = self.features.extract(points, &self.sensor_position)?;
        out.timings.downsample_ms = f.downsample_ms;
        out.timings.normals_ms = f.normals_ms;
        out.timings.features_ms = f.features_ms;
        out.scene_points = self.features.cloud().len() as u32;
        out.keypoints = self.features.keypoints().len() as u32;
        self.heights.clear();
        // The table is z = 0 in the world and the tray's bottom is z = 0 in its frame, so
        // world z and tray-frame z are both heights above the table.
        self.heights.extend(self.features.keypoint_points().iter().map(|q| q.z));

        // RANSAC's scene index needs only the cloud: it is built on one core while the
        // matcher starts on the other (and takes both once it is done).
        let t = Instant::now();
        let (matched, ()) = rayon::join(
            || {
                self.matcher.match_into(
                    self.features.descriptors(),
                    &self.heights,
                    p.k as usize,
                    p.height_band as f32,
                    &mut self.correspondences,
                )
            },
            || self.ransac.index_scene(self.features.cloud()),
        );
        matched?;
        out.timings.matching_ms = ms(t);
        out.matches = self.correspondences.len() as u32;

        let t = Instant::now();
        out.ransac = self.ransac.estimate_indexed(
            self.features.keypoint_points(),
            self.features.keypoint_normals(),
            &self.correspondences,
            &self.sensor_position,
        )?;
        out.timings.ransac_ms = ms(t);
        if !out.ransac.found {
            return Ok(out);
        }

        let t = Instant::now();
        let coarse = out.ransac.t_world_tray;
        // RANSAC scored the hypothesis against the view closest to the sensor under it.
        let view = out.ransac.view;
        out.icp = self.icp.refine(self.features.cloud(), view, &self.sensor_position, &coarse)?;
        let mut refined = out.icp.refined;
        // A rectangular tray is nearly symmetric under a half turn about its z axis, a square
        // one under quarter turns too: only a small part (a chamfer, a tab) tells the turned
        // poses apart, and RANSAC's inlier count often cannot. So the scene points on the
        // parts that differ are counted for the pose and for each quarter turn of it, the
        // body the two share counting for neither (`Icp::explained_near_and_apart`): a turn
        // whose parts the scene shows more than the pose's own, by the deviations that make
        // a pose ambiguous, is refined and, when its parts still win against the pose's,
        // kept. (Turning on any lead flipped right poses whose tab the camera barely saw:
        // 190 correct of 300 at r=1000, alpha=60 against 196; two deviations, 188. Falling
        // back on the whole tray's count where the parts cannot tell: 194, with 35 half
        // turns against 28.)
        let reach = p.inlier_distance as f32;
        let pose = if refined { out.icp.t_world_tray } else { coarse };
        // The pose's counts against its alternatives and their see-through evidence, which
        // the verification reuses while the pose stands.
        let mut weighed = None;
        // Whether a turn of the pose was taken instead of it.
        let mut refined_turn = false;
        if p.turn_check {
            // The verifier's alternatives are the model's, as ICP's are.
            let alternatives = &self.verifier.turn_parts.alternatives;
            let every = alternatives.every();
            let counts =
                self.icp.explained_near_and_apart(self.features.cloud(), &pose, every, reach, &self.sensor_position);
            let lead = |(own, theirs): (u32, u32)| lead_sigmas(theirs, own);
            // What the camera saw past of the pose's and each turn's distinct parts, taken
            // once. A turn whose parts it saw past, where it did not past the pose's, is no
            // candidate however the few points on either's parts fall.
            let evidence = depth.map(|d| self.verifier.turn_evidences(&self.model, d, &self.sensor_position, &pose));
            weighed = Some(Weighed { counts, evidence });
            let seen_past_turn = |k: usize| {
                depth.zip(evidence).is_some_and(|(d, e)| {
                    // A listed turn is not in the evidence: counted here when the scene's
                    // points favour it.
                    let (own, theirs) = e[k].unwrap_or_else(|| {
                        turn_see_through(&self.model, &self.verifier.turn_parts, d, &self.sensor_position, &pose, k)
                    });
                    turn_favoured(theirs, own)
                })
            };
            // The alternative (a quarter turn, or a turn laying the slot grid onto itself
            // shifted) the scene's distinct parts favour most over the pose, if any.
            let favoured = counts
                .apart
                .into_iter()
                .enumerate()
                .take(every.len())
                .filter(|&(k, c)| lead(c) >= AMBIGUOUS_TURN_SIGMAS && !seen_past_turn(k))
                .max_by(|a, b| lead(a.1).total_cmp(&lead(b.1)));
            if let Some((k, _)) = favoured {
                let turned = pose * alternatives.list()[k].transform();
                let turned_view = self.model.closest_view(&turned, &self.sensor_position);
                let other = self.icp.refine(self.features.cloud(), turned_view, &self.sensor_position, &turned)?;
                if other.refined {
                    // Weighed again from the refined alternative, against its way back to the
                    // pose.
                    let again = self.icp.explained_near_and_apart(
                        self.features.cloud(),
                        &other.t_world_tray,
                        &[alternatives.inverse_of(k)],
                        reach,
                        &self.sensor_position,
                    );
                    let (theirs, own) = again.apart[0];
                    if theirs > own {
                        out.icp = other;
                        refined = true;
                        weighed = None;
                        refined_turn = true;
                    }
                }
            }
            // Where the scene's points cannot tell (the telling part hidden or out of view),
            // what the camera saw past can: a turn whose distinct parts it saw past less
            // than the pose's, by the verification's measure, is refined and kept when the
            // evidence still favours it from there.
            if let (Some(depth), Some(evidence), false) = (depth, &evidence, refined_turn) {
                let model = &self.model;
                let (seen, own, theirs) = most_favoured_turn(evidence);
                if let Some(k) = seen.filter(|_| turn_favoured(own, theirs)) {
                    let turned = pose * alternatives.list()[k].transform();
                    let turned_view = model.closest_view(&turned, &self.sensor_position);
                    let other = self.icp.refine(self.features.cloud(), turned_view, &self.sensor_position, &turned)?;
                    if other.refined {
                        let (theirs, back) = turn_see_through(
                            model,
                            &self.verifier.turn_parts,
                            depth,
                            &self.sensor_position,
                            &other.t_world_tray,
                            alternatives.inverse_of(k),
                        );
                        if turn_favoured(back, theirs) {
                            out.icp = other;
                            refined = true;
                            weighed = None;
                        }
                    }
                }
            }
        }
        out.timings.icp_ms = ms(t);
        out.found = true;
        out.inliers = out.ransac.inliers;
        out.t_world_tray = if refined { out.icp.t_world_tray } else { coarse };

        let t = Instant::now();
        out.verification = self.verifier.verify(
            &self.model,
            &self.icp,
            self.ransac.scene_grid(),
            self.features.cloud(),
            &self.sensor_position,
            &out.t_world_tray,
            weighed.as_ref(),
            depth,
        );
        // The rig's calibration error moves the whole measured cloud, table and tray alike,
        // so a fit's height and tilt above the table are that error's: a tray that rests on
        // the table is handed on laid on it (its x, y and turn kept). The verification
        // judged the fit itself, which is what the data shows.
        if p.pose_on_table && out.verification.rests_on_table() {
            out.t_world_tray = on_table(&out.t_world_tray);
        }
        out.timings.verify_ms = ms(t);
        // Each slot's floor and the item's top are read under the pose handed on; the time
        // counts in the frame's total.
        if let Some(judge) = &mut self.slots {
            judge.judge(self.features.cloud(), &out.t_world_tray);
            self.slots_judged = true;
        }
        Ok(out)
    }
}
