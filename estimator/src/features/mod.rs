//! From a cloud to described key points: down-sampling to SRes, PCA normals facing the
//! sensor, key points every `keypoint_spacing`, ECSAD descriptors, and key points without
//! relief dropped. The deployed pipeline runs it on every scene and the model builder on
//! every capture of the tray, so both describe surfaces alike. Its buffers are kept from
//! call to call; once they have seen a cloud as large as the current one, `extract`
//! allocates nothing.

mod correspondence;
mod downsample;
mod ecsad;
mod keypoints;
mod matching;
mod normals;

pub use correspondence::Correspondence;
pub use downsample::Downsampler;
pub use ecsad::{Descriptor, Ecsad, ECSAD_DIM};
pub use keypoints::KeypointSelector;
pub(crate) use matching::MAX_K;
pub use matching::{quantise, FeatureMatcher, QUANTISATION_STEPS};
pub use normals::{is_valid_normal, NormalEstimator, MIN_NORMAL_NEIGHBOURS};

use std::time::Instant;

use camplace_config::EstimatorParams;
use nalgebra::{Point3, Vector3};

use crate::{Neighbours, Result};
use keypoints::keep_distinctive;

/// Time spent in each step of the last [`FeatureExtractor::extract`], ms.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct FeatureTimings {
    /// Voxel down-sampling to the surface resolution.
    pub downsample_ms: f64,
    /// Neighbour grid and PCA normals.
    pub normals_ms: f64,
    /// Key points and ECSAD descriptors.
    pub features_ms: f64,
}

/// The feature steps with their settings and buffers.
#[derive(Debug, Clone)]
pub struct FeatureExtractor {
    surface_resolution: f32,
    normal_radius: f32,
    keypoint_spacing: f32,
    feature_radius: f32,
    min_relief: f32,
    downsampler: Downsampler,
    cloud: Vec<Point3<f32>>,
    neighbours: Neighbours,
    normal_estimator: NormalEstimator,
    normals: Vec<Vector3<f32>>,
    selector: KeypointSelector,
    keypoints: Vec<u32>,
    keypoint_points: Vec<Point3<f32>>,
    keypoint_normals: Vec<Vector3<f32>>,
    ecsad: Ecsad,
    descriptors: Vec<Descriptor>,
}

impl FeatureExtractor {
    /// An extractor with `params`' settings and room for clouds of `points` points (more
    /// grow the buffers once).
    pub fn new(params: &EstimatorParams, points: usize) -> Result<Self> {
        // Key points are at most one per key-point voxel of the SRes cloud: a generous share.
        let keypoints = (points / 16).max(1024);
        Ok(FeatureExtractor {
            surface_resolution: params.surface_resolution as f32,
            normal_radius: params.normal_radius as f32,
            keypoint_spacing: params.keypoint_spacing as f32,
            feature_radius: params.feature_radius as f32,
            min_relief: params.min_relief as f32,
            downsampler: Downsampler::with_capacity(points),
            cloud: Vec::with_capacity(points),
            neighbours: Neighbours::with_capacity(points),
            normal_estimator: NormalEstimator::new(params.normal_radius as f32, MIN_NORMAL_NEIGHBOURS)?,
            normals: Vec::with_capacity(points),
            selector: KeypointSelector::new(),
            keypoints: Vec::with_capacity(keypoints),
            keypoint_points: Vec::with_capacity(keypoints),
            keypoint_normals: Vec::with_capacity(keypoints),
            ecsad: Ecsad::new(params.feature_radius as f32)?,
            descriptors: Vec::with_capacity(keypoints),
        })
    }

    /// Describes `points` seen from `eye` (same frame); the results stay in the extractor
    /// until the next call.
    pub fn extract(&mut self, points: &[Point3<f32>], eye: &Point3<f32>) -> Result<FeatureTimings> {
        let mut timings = FeatureTimings::default();
        self.keypoints.clear();
        self.keypoint_points.clear();
        self.keypoint_normals.clear();
        self.descriptors.clear();

        let t = Instant::now();
        self.downsampler.downsample(points, self.surface_resolution, &mut self.cloud)?;
        timings.downsample_ms = ms(t);

        let t = Instant::now();
        self.neighbours.build(&self.cloud, 2.0 * self.normal_radius)?;
        self.normal_estimator.compute(&self.cloud, &self.neighbours, eye, &mut self.normals);
        timings.normals_ms = ms(t);

        let t = Instant::now();
        self.selector.select(&self.cloud, &self.normals, self.keypoint_spacing, &mut self.keypoints)?;
        self.neighbours.build(&self.cloud, self.feature_radius / 2.0)?;
        self.ecsad.compute(&self.cloud, &self.normals, &self.neighbours, &self.keypoints, &mut self.descriptors)?;
        keep_distinctive(&mut self.keypoints, &mut self.descriptors, self.min_relief);
        self.keypoint_points.extend(self.keypoints.iter().map(|&i| self.cloud[i as usize]));
        self.keypoint_normals.extend(self.keypoints.iter().map(|&i| self.normals[i as usize]));
        timings.features_ms = ms(t);
        Ok(timings)
    }

    /// The down-sampled cloud.
    pub fn cloud(&self) -> &[Point3<f32>] {
        &self.cloud
    }

    /// Each down-sampled point's normal (NaN where none could be fitted).
    pub fn normals(&self) -> &[Vector3<f32>] {
        &self.normals
    }

    /// The described key points, as indices into [`FeatureExtractor::cloud`].
    pub fn keypoints(&self) -> &[u32] {
        &self.keypoints
    }

    /// The described key points' positions.
    pub fn keypoint_points(&self) -> &[Point3<f32>] {
        &self.keypoint_points
    }

    /// The described key points' normals (each valid: key points are chosen among points
    /// with one).
    pub fn keypoint_normals(&self) -> &[Vector3<f32>] {
        &self.keypoint_normals
    }

    /// One descriptor per key point.
    pub fn descriptors(&self) -> &[Descriptor] {
        &self.descriptors
    }
}

fn ms(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}
