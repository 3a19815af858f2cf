//! camplace's simulator and placement study: the scene, a CPU renderer of the stereo
//! camera and projector, scenarios with common random numbers, model building, evaluation,
//! search and reports. It feeds rendered frames to the same estimator the cell PC runs.
//!
//! The stages are private modules — `scene` (scene, trays, scenarios, placement geometry),
//! `render` (rasterizer, shading, patterns, noise, frame files), `study` (evaluation, jobs,
//! results, sweep, search, merge, the study), `search` (the surrogate optimizer) and
//! `report` (plots, tables, report.html), `trial` (the real-world trial), `fit` (the
//! simulated sensor fitted to a real one) — with `seeds` keying every random stream; what
//! other crates use is exported here.

mod error;
mod export;
mod fit;
mod model_builder;
mod progress;
mod render;
mod report;
mod scene;
mod search;
mod seeds;
mod study;
mod trial;
mod workers;

pub use error::{Error, Result};
pub use export::{cell_parts, glb_bytes, write_cell_glb, CellPart, GlbSummary, Primitive};
pub use fit::{fit_sensor, write_fit, AmbientFit, KeyFit, SensorFit, FIT_FRAGMENT, FIT_HTML, FIT_JSON, MAX_FIT_FRAMES};
pub use model_builder::{build_model, model_origin, model_points};
pub use progress::{set_progress, ProgressCallback, ProgressEvent};
pub use render::render_files::{clear_dataset, render_dataset, render_scene};
pub use render::{
    render_board_views, render_hand_eye_views, simulated_robot_base, BoardTruth, Frame, HandEyeOptions, HandEyePoses,
    HandEyeTruth, Method, Simulator, HAND_EYE_TRUTH_FILE, ROBOT_POSES_FILE,
};
pub use report::recommended::Recommended;
pub use report::study_report::write_report;
pub use report::sweep_panels::SweepResult;
pub use report::tolerance_plot::write_tolerance_plots;
pub use scene::scenario::{background_scene, draw_scenario, Scenario};
pub use scene::SceneSpec;
pub use search::test_functions::{run_test_function, test_function};
pub use seeds::noise_key;
pub use study::ablation::{ablate, ablation_markdown, AblationRow};
pub use study::findings::{drop_detection_power, scenes_for_power};
pub use study::folder::open_folder;
pub use study::lock::{lock_folder, FolderLock, LOCK_FILE};
pub use study::merge::merge;
pub use study::negatives::{hard_negatives, weigh_negatives};
pub use study::one_placement::{acceptance_summary, evaluate_placement, measure_verification};
pub use study::optimize::{SearchParameter, SearchPlan};
pub use study::placement_search::optimize;
pub use study::placement_study::{run_study, tolerance_dir, Preset, StudyOutcome, StudyRequest};
pub use study::shard::Shard;
pub use study::sweep::sweep;
pub use study::tolerance::{
    measure_tolerance, tolerance_parameter, ToleranceParameter, ToleranceRequest, TOLERANCE_LEVEL,
    TOLERANCE_PARAMETERS, TOLERANCE_POWER,
};
pub use study::Evaluator;
pub use trial::judge::{
    append_label, frame_names, parse_labels, pose_fingerprint, present_marks, read_labels, read_poses,
    tie_marks_to_poses, JudgedDataset, Judgement, Label, Mark, LABELS_FILE,
};
pub use trial::layout::check_placement_rig;
pub use trial::mock::{hidden_truth_path, make_mock_trial, scripted_marks};
pub use trial::plan::make_plan;
pub use trial::rank::{spearman, RankCorrelation};
pub use trial::report::{
    rho_text, study_grid, sweep_folder, trial_report, PlacementRow, TrialReport, REPORT_HTML, REPORT_JSON,
};
pub use trial::review_page::review_page;
pub use trial::review_server::{serve_review, ReviewEnd, Reviewed, MAX_LABEL_BYTES};
