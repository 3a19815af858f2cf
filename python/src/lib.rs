//! camplace for Python (`import camplace`): the deployed estimator on numpy frames, read in
//! place (a 2-D uint8 array's buffer becomes an `ImageView` with its row stride; nothing is
//! copied), the simulator's rendering of one scene with its truth, and a small evaluation of
//! a placement. Bad input, an argument of the wrong type or out of range among it, raises
//! `camplace.Error` (a `ValueError`) with the one-line message the command line prints.

use std::path::{Path, PathBuf};

use camplace_config::{Cell, ImageView, Placement, RigFile};
use camplace_estimator::{
    depth::Method, geometry::sensor_rig, Estimator as Pipeline, EstimatorConfig, Model, PoseEstimate, Rig, StageTimings,
};
use nalgebra::Isometry3;
use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyReadonlyArray2};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

pyo3::create_exception!(
    camplace,
    Error,
    PyValueError,
    "Bad input: the message names the file or argument, the key and what was expected."
);

fn fail(message: impl std::fmt::Display) -> PyErr {
    Error::new_err(message.to_string().split_whitespace().collect::<Vec<_>>().join(" "))
}

/// The error for an argument of the wrong type or out of range: names the argument, what
/// it takes and what it was given, as a `camplace.Error` (PyO3 would raise a `TypeError`
/// or `OverflowError` that names neither).
fn wrong_argument(name: &str, expected: &str, value: &Bound<'_, PyAny>) -> PyErr {
    let kind = value.get_type().name().map(|n| n.to_string()).unwrap_or_else(|_| "?".to_string());
    let shown = value.repr().map(|r| r.to_string()).unwrap_or_default();
    let shown: String =
        if shown.chars().count() > 40 { shown.chars().take(40).chain("…".chars()).collect() } else { shown };
    fail(format!("{name}: expected {expected}, got {shown} ({kind})"))
}

/// One function per argument, as `#[pyo3(from_py_with = ...)]` takes them, extracting the
/// argument's type and raising [`wrong_argument`] when it is another.
macro_rules! argument {
    ($fn:ident, $name:literal, $ty:ty, $expected:literal) => {
        #[doc = concat!("The `", $name, "` argument: ", $expected, ".")]
        fn $fn(value: &Bound<'_, PyAny>) -> PyResult<$ty> {
            value.extract::<$ty>().map_err(|_| wrong_argument($name, $expected, value))
        }
    };
}

argument!(cell_arg, "cell", Option<PathBuf>, "a path (str or os.PathLike) or None");
argument!(model_arg, "model", PathBuf, "a path (str or os.PathLike)");
argument!(rig_arg, "rig", Option<PathBuf>, "a path (str or os.PathLike) or None");
argument!(image_path_arg, "path", PathBuf, "a path (str or os.PathLike)");
argument!(placement_arg, "placement", Option<String>, "a str such as \"r=605,alpha=32\" or None");
argument!(method_arg, "method", String, "a str, \"one-shot\" or \"phase-12\"");
argument!(tray_arg, "tray", Option<String>, "a str naming one of the cell's trays or None");

// The simulator's functions (render, evaluate): a module built without the feature `sim`
// holds the estimator alone, as a cell PC's program needs it.
#[cfg(feature = "sim")]
mod simulated;

/// The cell file at `path` with one tray (`tray` when it lists several), or the built-in
/// default cell.
fn load_cell(path: Option<&Path>, tray: Option<&str>) -> PyResult<Cell> {
    match path {
        Some(path) => {
            let cell = Cell::load(path).map_err(fail)?;
            cell.one_tray(tray).map_err(|e| fail(e.in_file(path)))
        }
        None => Cell::default().one_tray(tray).map_err(fail),
    }
}

fn placement_of(cell: &Cell, placement: Option<&str>) -> PyResult<Placement> {
    match placement {
        Some(text) => cell.placement.with_overrides(text).map_err(|e| fail(format!("placement: {e}"))),
        None => Ok(cell.placement),
    }
}

fn method_of(text: &str) -> PyResult<Method> {
    text.parse().map_err(|e| fail(format!("method: {e}")))
}

/// A 4 x 4 numpy array of a rigid transform.
fn matrix<'py>(py: Python<'py>, t: &Isometry3<f64>) -> Bound<'py, PyAny> {
    let m = t.to_homogeneous();
    Array2::from_shape_fn((4, 4), |(r, c)| m[(r, c)]).into_pyarray(py).into_any()
}

/// The frame's shots as the caller passed them: one 2-D uint8 array or a list of them.
fn shot_arrays<'py>(side: &str, value: &Bound<'py, PyAny>) -> PyResult<Vec<PyReadonlyArray2<'py, u8>>> {
    let expected = || {
        let kind = value.get_type().name().map(|n| n.to_string()).unwrap_or_else(|_| "?".to_string());
        let dtype = value.getattr("dtype").map(|d| format!(" of {d}")).unwrap_or_default();
        let dims = value.getattr("ndim").map(|d| format!(", {d}-D")).unwrap_or_default();
        fail(format!(
            "{side}: expected a 2-D uint8 numpy array (or a list of them, one per shot), got {kind}{dtype}{dims}"
        ))
    };
    if let Ok(one) = value.extract::<PyReadonlyArray2<'py, u8>>() {
        return Ok(vec![one]);
    }
    let list = value.cast::<PyList>().map_err(|_| expected())?;
    list.iter().map(|item| item.extract::<PyReadonlyArray2<'py, u8>>().map_err(|_| expected())).collect()
}

/// A view of a numpy array's own buffer (no copy): rows of adjacent bytes, any row stride.
fn view<'a>(side: &str, shot: usize, array: &'a PyReadonlyArray2<'_, u8>) -> PyResult<ImageView<'a, u8>> {
    let a = array.as_array();
    let (h, w) = a.dim();
    let strides = a.strides();
    if w > 1 && strides[1] != 1 {
        return Err(fail(format!(
            "{side} shot {shot}: expected rows of adjacent pixels (a column stride of 1 byte), got {} bytes; pass numpy.ascontiguousarray(...)",
            strides[1]
        )));
    }
    if h > 1 && (strides[0] < 0 || (strides[0] as usize) < w) {
        return Err(fail(format!(
            "{side} shot {shot}: expected rows stored top to bottom at least a row apart, got a row stride of {} bytes for {w} pixels",
            strides[0]
        )));
    }
    let stride = if h > 1 { strides[0] as usize } else { w };
    let len = if h == 0 || w == 0 { 0 } else { (h - 1) * stride + w };
    // SAFETY: row y of the array starts `y * stride` bytes after its first pixel and holds
    // `w` adjacent bytes (both checked above), so these `len` bytes lie in the array's
    // buffer; the read-only borrow keeps the array alive and unwritable by Rust code for `'a`.
    let data = unsafe { std::slice::from_raw_parts(a.as_ptr(), len) };
    ImageView::new(data, w, h, stride).map_err(|e| fail(format!("{side} shot {shot}: {e}")))
}

fn views<'a>(side: &str, arrays: &'a [PyReadonlyArray2<'_, u8>]) -> PyResult<Vec<ImageView<'a, u8>>> {
    arrays.iter().enumerate().map(|(i, a)| view(side, i, a)).collect()
}

fn timings<'py>(py: Python<'py>, t: &StageTimings) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    for (name, ms) in StageTimings::STAGES.iter().zip(t.by_stage()) {
        d.set_item(name, ms)?;
    }
    d.set_item("total", t.total_ms)?;
    Ok(d)
}

fn pose_dict<'py>(py: Python<'py>, pose: &PoseEstimate) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("found", pose.found)?;
    d.set_item("pose", matrix(py, &pose.t_world_tray))?;
    d.set_item("score", f64::from(pose.verification.score))?;
    d.set_item("verdict", pose.verification.verdict.as_str())?;
    d.set_item("accepted", pose.found && pose.verification.verdict == camplace_estimator::pose::Verdict::Accepted)?;
    d.set_item("inliers", pose.inliers)?;
    d.set_item("timings_ms", timings(py, &pose.timings)?)?;
    Ok(d)
}

/// Each slot's state and frame as a list of dicts.
fn slot_list<'py>(py: Python<'py>, readings: &[camplace_estimator::pose::SlotReading]) -> PyResult<Bound<'py, PyList>> {
    let list = PyList::empty(py);
    for r in readings {
        let d = PyDict::new(py);
        d.set_item("state", r.state.as_str())?;
        d.set_item("askew", r.askew)?;
        d.set_item("frame", matrix(py, &r.t_world_slot))?;
        list.append(d)?;
    }
    Ok(list)
}

/// The tray-pose estimator of one rig and tray model, as `camplace run` runs it.
///
/// Estimator(cell, model, *, rig=None, placement=None, method="one-shot", tray=None)
///
/// cell: a cell file (TOML) with the estimator's settings, or None for the built-in default
/// cell; with a file, the model must have been built for its tray. model: a model file from
/// `camplace model`. rig: a rig.json (a calibration, or a rendered dataset's); without it the
/// rig is the cell's installed [rig] or the sensor at `placement` (default: the cell's
/// placement, e.g. "r=605,alpha=32,baseline=81,vergence=3.5"). method: "one-shot" (one
/// image a side) or "phase-12". tray: which of the cell's [[trays]] when it lists several.
#[pyclass(module = "camplace")]
struct Estimator {
    inner: Pipeline,
}

#[pymethods]
impl Estimator {
    #[new]
    #[pyo3(
        signature = (cell, model, *, rig=None, placement=None, method=String::from("one-shot"), tray=None),
        text_signature = "(cell, model, *, rig=None, placement=None, method='one-shot', tray=None)"
    )]
    fn new(
        #[pyo3(from_py_with = cell_arg)] cell: Option<PathBuf>,
        #[pyo3(from_py_with = model_arg)] model: PathBuf,
        #[pyo3(from_py_with = rig_arg)] rig: Option<PathBuf>,
        #[pyo3(from_py_with = placement_arg)] placement: Option<String>,
        #[pyo3(from_py_with = method_arg)] method: String,
        #[pyo3(from_py_with = tray_arg)] tray: Option<String>,
    ) -> PyResult<Self> {
        let (placement, tray) = (placement.as_deref(), tray.as_deref());
        let method = method_of(&method)?;
        let cell_value = load_cell(cell.as_deref(), tray)?;
        let model = Model::load_checked(&model, &cell_value, cell.as_deref()).map_err(fail)?;
        let rig = match &rig {
            Some(path) => Rig::from_file(&RigFile::load(path).map_err(fail)?),
            None => sensor_rig(&cell_value, &placement_of(&cell_value, placement)?),
        };
        let inner = Pipeline::new(&EstimatorConfig::from(&cell_value), &rig, model, method).map_err(fail)?;
        Ok(Estimator { inner })
    }

    /// set_background(left, right): the empty cell's frame, removed from every later frame.
    /// Shots as for process().
    fn set_background(&mut self, py: Python<'_>, left: &Bound<'_, PyAny>, right: &Bound<'_, PyAny>) -> PyResult<()> {
        let (l, r) = (shot_arrays("left", left)?, shot_arrays("right", right)?);
        let (lv, rv) = (views("left", &l)?, views("right", &r)?);
        let inner = &mut self.inner;
        py.detach(|| inner.set_background(&lv, &rv)).map_err(fail)
    }

    /// process(left, right) -> dict: the tray's pose in one stereo frame.
    ///
    /// left, right: 2-D uint8 numpy arrays (height x width, C-contiguous or with padded
    /// rows, e.g. a crop of a wider array), or lists of them for a phase-12 frame. They are
    /// read in place, never copied, and the interpreter runs other threads meanwhile.
    /// Returns {"found", "pose" (4 x 4 T_world_tray, mm), "score", "verdict", "accepted",
    /// "inliers", "timings_ms" (each stage and "total"), "slots" (per slot {"state":
    /// "filled" | "empty" | "unseen", "askew", "frame" (4 x 4 T_world_slot, mm)}; empty for a
    /// model without slots or a frame without a pose)}. Only an accepted pose is meant for a
    /// robot.
    fn process<'py>(
        &mut self,
        py: Python<'py>,
        left: &Bound<'py, PyAny>,
        right: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let (l, r) = (shot_arrays("left", left)?, shot_arrays("right", right)?);
        let (lv, rv) = (views("left", &l)?, views("right", &r)?);
        let inner = &mut self.inner;
        let pose = py.detach(|| inner.process(&lv, &rv)).map_err(fail)?;
        let d = pose_dict(py, &pose)?;
        d.set_item("slots", slot_list(py, self.inner.slots())?)?;
        Ok(d)
    }

    /// The address of the first left shot's pixels the last process() read: equal to
    /// that array's `ctypes.data` when the frame was read in place.
    #[getter]
    fn last_left_address(&self) -> usize {
        self.inner.last_left_address()
    }

    fn __repr__(&self) -> String {
        format!("{:?}", self.inner)
    }
}

/// read_image(path) -> 2-D uint8 array: an image file (PNG, or any common format) as grey,
/// within the pixel budget (8192 x 8192), as every camplace command reads one.
#[pyfunction]
fn read_image<'py>(
    py: Python<'py>,
    #[pyo3(from_py_with = image_path_arg)] path: PathBuf,
) -> PyResult<Bound<'py, PyAny>> {
    let gray = camplace_config::read_gray(&path).map_err(fail)?;
    let a = Array2::from_shape_vec((gray.height, gray.width), gray.data).map_err(fail)?;
    Ok(a.into_pyarray(py).into_any())
}

/// camplace: where to mount a stereo camera and projector above a robot cell, and the
/// tray-pose estimator that runs there. Estimator(...).process(left, right) estimates the
/// tray's pose on numpy frames without copying them; render(...) simulates one scene with
/// its truth; evaluate(...) measures a placement's success rate; read_image(path) reads an
/// image file as the commands do. Bad input raises
/// camplace.Error.
#[pymodule]
fn camplace(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<Estimator>()?;
    #[cfg(feature = "sim")]
    m.add_function(wrap_pyfunction!(simulated::render, m)?)?;
    #[cfg(feature = "sim")]
    m.add_function(wrap_pyfunction!(simulated::evaluate, m)?)?;
    m.add_function(wrap_pyfunction!(read_image, m)?)?;
    m.add("Error", m.py().get_type::<Error>())?;
    Ok(())
}
