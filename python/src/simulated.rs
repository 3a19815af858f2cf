//! The simulator in Python (with the feature `sim`, on by default): one scene rendered with
//! its truth, and a small evaluation of a placement.

use std::path::PathBuf;

use camplace_sim::{acceptance_summary, background_scene, draw_scenario, noise_key, Frame, Scenario, Simulator};
use numpy::ndarray::Array2;
use numpy::IntoPyArray;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

use crate::{cell_arg, fail, load_cell, matrix, method_arg, method_of, placement_arg, placement_of, wrong_argument};

argument!(seed_arg, "seed", Option<u64>, "a whole number from 0 to 18446744073709551615 or None");
argument!(scenario_arg, "scenario", Option<u64>, "a whole number from 0 to 18446744073709551615 or None");
argument!(scenarios_arg, "scenarios", u64, "a whole number from 0 to 18446744073709551615");

fn image<'py>(py: Python<'py>, img: &camplace_config::GrayImage) -> PyResult<Bound<'py, PyAny>> {
    let a = Array2::from_shape_vec((img.height, img.width), img.data.clone()).map_err(fail)?;
    Ok(a.into_pyarray(py).into_any())
}

fn float_image<'py>(py: Python<'py>, img: &camplace_config::FloatImage) -> PyResult<Bound<'py, PyAny>> {
    let a = Array2::from_shape_vec((img.height, img.width), img.data.clone()).map_err(fail)?;
    Ok(a.into_pyarray(py).into_any())
}

fn shots<'py>(py: Python<'py>, images: &[camplace_config::GrayImage]) -> PyResult<Bound<'py, PyAny>> {
    if let [one] = images {
        return image(py, one);
    }
    let list = PyList::empty(py);
    for img in images {
        list.append(image(py, img)?)?;
    }
    Ok(list.into_any())
}

/// render(cell=None, placement=None, seed=None, scenario=0, method="one-shot") -> dict
///
/// One simulated scene, as `camplace render` writes it: scenario `scenario` of `seed`
/// (default: the cell's scenarios.seed) at `placement` (default: the cell's), or with
/// scenario=None the empty cell (the background). Returns {"left", "right" (2-D uint8
/// arrays, lists of them for phase-12), "depth_left", "depth_right" (float32, mm along each
/// camera's axis, inf where nothing is seen), "T_world_tray" (4 x 4, None for the
/// background), "filled" (the slots holding an item)}.
#[pyfunction]
#[pyo3(signature = (cell=None, placement=None, seed=None, scenario=Some(0), method=String::from("one-shot")), text_signature = "(cell=None, placement=None, seed=None, scenario=0, method='one-shot')")]
pub(crate) fn render<'py>(
    py: Python<'py>,
    #[pyo3(from_py_with = cell_arg)] cell: Option<PathBuf>,
    #[pyo3(from_py_with = placement_arg)] placement: Option<String>,
    #[pyo3(from_py_with = seed_arg)] seed: Option<u64>,
    #[pyo3(from_py_with = scenario_arg)] scenario: Option<u64>,
    #[pyo3(from_py_with = method_arg)] method: String,
) -> PyResult<Bound<'py, PyDict>> {
    let placement = placement.as_deref();
    let method = method_of(&method)?;
    let cell = load_cell(cell.as_deref(), None)?;
    let placement = placement_of(&cell, placement)?;
    let seed = seed.unwrap_or(cell.scenarios.seed);
    let rendered = py.detach(|| -> Result<(Frame, Option<Scenario>), String> {
        let mut sim = Simulator::new(&cell, &placement, seed).map_err(|e| e.to_string())?;
        let mut frame = Frame::default();
        let drawn = scenario.map(|i| draw_scenario(&cell, seed, i));
        match (&drawn, scenario) {
            (Some(s), Some(i)) => sim.render(&s.scene(), method, noise_key(seed, i, false), &mut frame),
            _ => sim.render(&background_scene(&cell, seed), method, noise_key(seed, 0, true), &mut frame),
        }
        Ok((frame, drawn))
    });
    let (frame, drawn) = rendered.map_err(fail)?;
    let d = PyDict::new(py);
    d.set_item("left", shots(py, &frame.shots.left)?)?;
    d.set_item("right", shots(py, &frame.shots.right)?)?;
    d.set_item("depth_left", float_image(py, &frame.depth_left)?)?;
    d.set_item("depth_right", float_image(py, &frame.depth_right)?)?;
    match &drawn {
        Some(s) => {
            d.set_item("T_world_tray", matrix(py, &s.t_world_tray))?;
            d.set_item("filled", s.filled.clone())?;
        }
        None => {
            d.set_item("T_world_tray", py.None())?;
            d.set_item("filled", PyList::empty(py))?;
        }
    }
    Ok(d)
}

/// evaluate(cell=None, placement=None, scenarios=20, seed=None, method="one-shot") -> dict
///
/// The success of one placement over scenarios 0 … scenarios-1 of `seed` (default: the
/// cell's scenarios.seed), as `camplace evaluate` measures it but in memory: the tray model
/// built for the placement, each scene rendered and estimated. Returns the summary
/// (summary.json's fields: "success_rate", "success_interval", "successes", "scored",
/// median errors and timings, and "verification" with the verified figures).
#[pyfunction]
#[pyo3(
    signature = (cell=None, placement=None, scenarios=20, seed=None, method=String::from("one-shot")),
    text_signature = "(cell=None, placement=None, scenarios=20, seed=None, method='one-shot')"
)]
pub(crate) fn evaluate<'py>(
    py: Python<'py>,
    #[pyo3(from_py_with = cell_arg)] cell: Option<PathBuf>,
    #[pyo3(from_py_with = placement_arg)] placement: Option<String>,
    #[pyo3(from_py_with = scenarios_arg)] scenarios: u64,
    #[pyo3(from_py_with = seed_arg)] seed: Option<u64>,
    #[pyo3(from_py_with = method_arg)] method: String,
) -> PyResult<Bound<'py, PyAny>> {
    let placement = placement.as_deref();
    let method = method_of(&method)?;
    let cell = load_cell(cell.as_deref(), None)?;
    let placement = placement_of(&cell, placement)?;
    if scenarios == 0 {
        return Err(fail("scenarios: expected at least 1"));
    }
    let seed = seed.unwrap_or(cell.scenarios.seed);
    let summary = py
        .detach(|| acceptance_summary(None, &cell, &placement, method, seed, scenarios).map_err(|e| e.to_string()))
        .map_err(fail)?;
    let json = serde_json::to_string(&summary).map_err(fail)?;
    py.import("json")?.call_method1("loads", (json,))
}
