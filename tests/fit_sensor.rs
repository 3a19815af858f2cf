//! `camplace fit-sensor` on a dataset rendered with known sensor keys (the small cell's
//! 320 × 240 cameras, three frames): each key recovered, the fragment laid over the cell
//! file loads with them; datasets without background, without rig or with a frame of another
//! size refused in one line.

use std::path::{Path, PathBuf};

use camplace_config::Cell;
use serde_json::Value;

use crate::camplace_cmd::{assert_one_line_error, camplace, stderr};

fn small_cell() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/small_cell.toml")
}

/// The "real" sensor: the small cell with noise, filter and projector unlike the default's
/// (10, 3, 0.6).
const REAL_SENSOR: &str =
    "[sensor]\ncamera_resolution = [320, 240]\nnoise_amplitude = 18\nblur = 5\nprojector_gain = 0.3\n";

fn render(dir: &Path, out: &str, frames: &str) {
    std::fs::write(dir.join("real.toml"), REAL_SENSOR).unwrap();
    let o =
        camplace(dir, &["render", "--dataset", "--count", frames, "--cell", "real.toml", "--seed", "31", "--out", out]);
    assert!(o.status.success(), "{}", stderr(&o));
}

#[test]
fn fit_sensor_recovers_the_noise_blur_and_projector_gain_of_a_rendered_dataset() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    render(d, "data", "3");
    let cell = small_cell();
    let o = camplace(
        d,
        &["fit-sensor", "--dataset", "data", "--cell", cell.to_str().unwrap(), "--frames", "3", "--out", "fit"],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let fit: Value = serde_json::from_str(&std::fs::read_to_string(d.join("fit/fit-sensor.json")).unwrap()).unwrap();
    let key = |name: &str| fit["keys"].as_array().unwrap().iter().find(|k| k["key"] == name).unwrap().clone();
    let estimate = |name: &str| key(name)["estimate"].as_f64().unwrap();
    let within = |name: &str, truth: f64| {
        let e = estimate(name);
        assert!((e / truth - 1.0).abs() <= 0.10, "{name}: fitted {e}, rendered with {truth}");
    };
    within("sensor.noise_amplitude", 18.0);
    within("sensor.blur", 5.0);
    within("sensor.projector_gain", 0.3);
    // The simulation at the fitted values shows the real statistic, at the cell's it does not.
    for name in ["sensor.noise_amplitude", "sensor.blur", "sensor.projector_gain"] {
        let k = key(name);
        let (real, fitted, before) = (
            k["real"].as_f64().unwrap(),
            k["simulated_fitted"].as_f64().unwrap(),
            k["simulated_cell"].as_f64().unwrap(),
        );
        assert!((fitted - real).abs() < (before - real).abs(), "{name}: real {real}, fitted {fitted}, cell's {before}");
    }
    // The fragment laid over the cell file loads, with the fitted keys.
    let fragment = std::fs::read_to_string(d.join("fit/fit-sensor.toml")).unwrap();
    let fitted = Cell::load(&cell).unwrap().overlaid(&fragment, d).unwrap();
    assert_eq!(fitted.sensor.blur, 5);
    assert!(fitted.sensor.noise_amplitude.abs_diff(18) <= 1, "{}", fitted.sensor.noise_amplitude);
    assert!((fitted.sensor.projector_gain / 0.3 - 1.0).abs() <= 0.10);
    assert_eq!(fitted.sensor.camera_resolution, [320, 240]);
    let html = std::fs::read_to_string(d.join("fit/fit-sensor.html")).unwrap();
    assert!(html.contains("sensor.projector_gain") && html.contains("simulated, fitted"));
}

#[test]
fn fit_sensor_refuses_a_dataset_without_background_or_rig_or_with_a_frame_of_another_size() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let cell = small_cell();
    let cell = cell.to_str().unwrap();
    let fit = |data: &str| camplace(d, &["fit-sensor", "--dataset", data, "--cell", cell, "--out", "fit"]);
    render(d, "no_background", "2");
    std::fs::remove_dir_all(d.join("no_background/background")).unwrap();
    let o = fit("no_background");
    assert_one_line_error(o.status.code().unwrap(), &stderr(&o), &["no_background/background", "missing"]);
    render(d, "no_rig", "2");
    std::fs::remove_file(d.join("no_rig/rig.json")).unwrap();
    let o = fit("no_rig");
    assert_one_line_error(o.status.code().unwrap(), &stderr(&o), &["no_rig/rig.json", "missing"]);
    render(d, "other_size", "2");
    let small = vec![100u8; 160 * 120];
    camplace_config::write_gray(&d.join("other_size/frames/0001/left.png"), 160, 120, &small).unwrap();
    let o = fit("other_size");
    assert_one_line_error(o.status.code().unwrap(), &stderr(&o), &["other_size/frames/0001/left.png", "320x240"]);
    assert!(!d.join("fit").exists(), "nothing written for a refused dataset");
}

#[test]
fn fit_sensor_refuses_frames_equal_to_the_background_instead_of_fitting_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let cell = small_cell();
    let cell = cell.to_str().unwrap();
    let fit = |data: &str| camplace(d, &["fit-sensor", "--dataset", data, "--cell", cell, "--out", "fit"]);
    // No tray set down and no noise between them: every frame the background's own images.
    render(d, "empty", "3");
    let background = d.join("empty/background");
    for frame in ["0000", "0001", "0002"] {
        let to = d.join("empty/frames").join(frame);
        std::fs::remove_dir_all(&to).unwrap();
        std::fs::create_dir(&to).unwrap();
        for e in std::fs::read_dir(&background).unwrap() {
            let e = e.unwrap();
            std::fs::copy(e.path(), to.join(e.file_name())).unwrap();
        }
    }
    let o = fit("empty");
    assert_one_line_error(o.status.code().unwrap(), &stderr(&o), &["empty", "equal the background", "noise"]);
    // One copied frame among real ones would pull the noise towards zero: refused, named.
    render(d, "one_copy", "3");
    let copy = d.join("one_copy/frames/0001");
    for e in std::fs::read_dir(d.join("one_copy/background")).unwrap() {
        let e = e.unwrap();
        std::fs::copy(e.path(), copy.join(e.file_name())).unwrap();
    }
    let o = fit("one_copy");
    assert_one_line_error(o.status.code().unwrap(), &stderr(&o), &["one_copy/frames/0001", "equals the background"]);
    assert!(!d.join("fit").exists(), "nothing written for a refused dataset");
}
