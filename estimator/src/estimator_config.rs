//! What the estimator needs to know besides the rig and the model: its own settings, the
//! stereo matcher's and phase decoder's, the projector's fringe periods, the work volume and
//! the cloud's settings. A cell carries all of them (`EstimatorConfig::from(&cell)`); an
//! embedder without a cell file starts from [`EstimatorConfig::default`] and sets fields.

use camplace_config::{Cell, EstimatorParams, PhaseParams, ReconstructionParams, StereoParams, WorkVolume};

/// The estimator's settings, apart from the rig and the model.
///
/// The defaults are the built-in default cell's (the paper's settings; `camplace init`
/// writes them with a comment on every key): ECSAD features at a 5 mm surface resolution,
/// prerejective RANSAC and point-to-plane ICP as `[estimator]` lists them, the ELAS-class
/// stereo of `[stereo]`, the phase decoding of `[phase]` with the sensor's fringe periods,
/// the `[work_volume]` box above the table and `[reconstruction]`'s background margin.
#[derive(Debug, Clone, PartialEq)]
pub struct EstimatorConfig {
    /// Features, matching, RANSAC, ICP and verification (`[estimator]`).
    pub estimator: EstimatorParams,
    /// The one-shot stereo matcher (`[stereo]`).
    pub stereo: StereoParams,
    /// The 12-shot phase decoder (`[phase]`).
    pub phase: PhaseParams,
    /// The projector's fringe periods, px (`[sensor] fringe_periods`): their count sets the
    /// shots of a phase frame (four each).
    pub fringe_periods: Vec<f64>,
    /// The box above the table where the tray can be, world mm (`[work_volume]`).
    pub work_volume: WorkVolume,
    /// Cloud building and background removal (`[reconstruction]`).
    pub reconstruction: ReconstructionParams,
}

impl From<&Cell> for EstimatorConfig {
    fn from(cell: &Cell) -> Self {
        EstimatorConfig {
            estimator: cell.estimator.clone(),
            stereo: cell.stereo.clone(),
            phase: cell.phase.clone(),
            fringe_periods: cell.sensor.fringe_periods.clone(),
            work_volume: cell.work_volume.clone(),
            reconstruction: cell.reconstruction.clone(),
        }
    }
}

impl Default for EstimatorConfig {
    /// The built-in default cell's settings.
    fn default() -> Self {
        EstimatorConfig::from(&Cell::default())
    }
}

impl EstimatorConfig {
    /// Shots per side of a frame captured with `method`.
    pub fn shots(&self, method: crate::Method) -> usize {
        method.shots(self.fringe_periods.len())
    }
}
