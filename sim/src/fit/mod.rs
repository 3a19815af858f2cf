//! Fitting the simulated sensor to a real one (`camplace fit-sensor`): from a recorded
//! dataset of the empty cell and the tray, with its rig, the cell file's sensor keys as the
//! real sensor shows them — the camera noise (`sensor.noise_amplitude`), the mean filter
//! (`sensor.blur`), the projector's contrast (`sensor.projector_gain`) and dot size on the
//! table (`sensor.dot_size`, one-shot only) and the ambient light (`lighting.ambient`).
//!
//! Noise and filter come from the differences between the background and each frame over
//! the table tiles the tray left alone: the table, the pattern and the rig are the same in
//! both, so what differs is the two images' noise (and a smooth change of light), whose
//! structure function gives the filter's side (where it stops growing) and the noise's
//! variance (its height). The projector's gain and dot size and the table's light are then
//! fitted by synthesis: the empty table is rendered at the dataset's rig with candidate
//! values and the fitted noise, and each value is adjusted until the rendered background's
//! statistics (mean, contrast, fineness) are the real one's. The ambient range is matched
//! to the frames' light levels less the lamp the cell draws.

mod report;
mod stats;
mod synth;

use std::path::{Path, PathBuf};

use camplace_config::{Cell, Frames, GrayImage, RecordedDataset};
use camplace_estimator::geometry::as_built;
use serde::Serialize;

pub use report::{write_fit, FIT_FRAGMENT, FIT_HTML, FIT_JSON};
use stats::{
    amplitude_of_variance, difference_stats, fit_box_noise, pattern_stats, tiles_mean, variance_at, DifferenceStats,
    PatternStats, MAX_LAG, ROUNDING_STRUCTURE,
};
use synth::{EmptyCell, SensorKeys};

use crate::render::Method;
use crate::scene::scenario::draw_scenario;
use crate::seeds::noise_key;
use crate::{Error, Result};

/// Frames read at most (the first ones of the dataset).
pub const MAX_FIT_FRAMES: usize = 200;
/// The least noise variance (grey levels², before the filter) the fit measures the filter
/// and noise on: uniform noise on ±1 has 2/3, so below this the differences are rounding.
const MIN_NOISE_VARIANCE: f64 = 0.25;
/// Renders of the gain and light loop per dot size at most.
const GAIN_ROUNDS: usize = 8;

/// One fitted key: the value written, its estimate and uncertainty, and the statistic it
/// was fitted on, as the real images show it and as the simulation shows it at the fitted
/// value and at the cell's current one.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct KeyFit {
    /// The cell file's key.
    pub key: String,
    /// The value written into the fragment.
    pub value: f64,
    /// The estimate before rounding to the key's steps.
    pub estimate: f64,
    /// Its standard error (same unit), NaN where none is measured.
    pub standard_error: f64,
    /// The cell's current value.
    pub cell_value: f64,
    /// What the statistic is.
    pub statistic: String,
    /// The statistic on the real images.
    pub real: f64,
    /// The statistic simulated with the fitted values.
    pub simulated_fitted: f64,
    /// The statistic simulated with the cell's current values.
    pub simulated_cell: f64,
    /// How well the value is determined, in words.
    pub evidence: String,
}

/// The fitted ambient light range.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct AmbientFit {
    /// `lighting.ambient` as fitted, units of full white.
    pub range: [f64; 2],
    /// The cell's current range.
    pub cell_range: [f64; 2],
    /// Each frame's light on the table besides the projector's, units of full white.
    pub frame_levels: Vec<f64>,
    /// The mean and standard deviation of the lamp's share of that light as the cell
    /// draws its lamp.
    pub lamp_mean: f64,
    /// See `lamp_mean`.
    pub lamp_sd: f64,
    /// How the range was found.
    pub note: String,
}

/// Everything the fit found.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SensorFit {
    /// The dataset folder.
    pub dataset: PathBuf,
    /// one-shot or phase-12, from the shots per frame.
    pub method: String,
    /// Frames compared with the background.
    pub frames: usize,
    /// Table tiles (32 × 32 px) the noise was measured on, over all frames, shots and cameras.
    pub tiles: usize,
    /// The table's albedo the light levels are read with (the cell's).
    pub table_albedo: f64,
    /// Noise, blur, gain and (one-shot) dot size.
    pub keys: Vec<KeyFit>,
    /// The ambient light.
    pub ambient: AmbientFit,
    /// The difference's structure function, real, lag 1 first.
    pub structure_real: Vec<f64>,
    /// The same simulated at the fitted values.
    pub structure_fitted: Vec<f64>,
    /// The same simulated at the cell's values.
    pub structure_cell: Vec<f64>,
}

impl SensorFit {
    /// The fitted key `key`.
    pub fn key(&self, key: &str) -> Option<&KeyFit> {
        self.keys.iter().find(|k| k.key == key)
    }
}

/// Whether every shot of `frame` is `background`'s, pixel for pixel.
fn equal_images(frame: &Frames, background: &Frames) -> bool {
    let same = |a: &[GrayImage], b: &[GrayImage]| a.len() == b.len() && a.iter().zip(b).all(|(a, b)| a.data == b.data);
    same(&frame.left, &background.left) && same(&frame.right, &background.right)
}

/// Fits `cell`'s sensor keys to the recorded dataset `dataset` (its `rig.json`,
/// `background/` and at least two frames of the tray), reading at most `max_frames` frames.
pub fn fit_sensor(dataset: &Path, cell: &Cell, max_frames: usize) -> Result<SensorFit> {
    let rig_path = dataset.join("rig.json");
    if !rig_path.is_file() {
        return Err(Error::Other(format!(
            "{}: missing: expected the rig the frames were captured with (camplace capture --rig)",
            rig_path.display()
        )));
    }
    let source = RecordedDataset::open(dataset)?;
    let rig = source.rig().clone();
    let [w, h] = cell.sensor.camera_resolution;
    for (side, cam) in [("left", &rig.left), ("right", &rig.right)] {
        if (cam.width, cam.height) != (w, h) {
            return Err(Error::Other(format!(
                "{}: {side}.width × {side}.height: expected {w} × {h} (the cell's sensor.camera_resolution), found {} × {}",
                rig_path.display(),
                cam.width,
                cam.height
            )));
        }
    }
    let mut background = Frames::new(1);
    if !source.background(&mut background)? {
        return Err(Error::Other(format!(
            "{}: missing: expected the empty cell's images (camplace capture --background), which the fit compares every frame with",
            dataset.join("background").display()
        )));
    }
    let shots = background.shots();
    let method = match shots {
        1 => Method::OneShot,
        12 => Method::Phase12,
        n => {
            return Err(Error::Other(format!(
                "{}: expected 1 shot (one-shot) or 12 (phase-12) per camera, found {n}",
                dataset.join("background").display()
            )))
        }
    };
    let frames = source.frame_dirs().len().min(max_frames.max(1));
    if frames < 2 {
        return Err(Error::Other(format!(
            "{}: expected at least 2 frames of the tray, found {frames}",
            dataset.join("frames").display()
        )));
    }
    let built = as_built(&camplace_estimator::Rig::from_file(&rig))
        .map_err(|e| Error::Other(format!("{}: left/right: {e}", rig_path.display())))?;
    let mut empty = EmptyCell::new(cell, &rig, built.placement, method);
    let masks = empty.table_masks()?;

    // Noise and mean filter: every frame against the background.
    let mut pooled = DifferenceStats::default();
    let mut per_frame = Vec::with_capacity(frames);
    let mut frame_tiles: Vec<[Vec<(usize, usize)>; 2]> = Vec::with_capacity(frames);
    let mut frame_means: Vec<Vec<[f64; 2]>> = Vec::with_capacity(frames);
    let mut frame = Frames::new(shots);
    let mut tiles = 0;
    let mut copies = Vec::new();
    for i in 0..frames {
        // The background was read with the frames' shots, so both have as many.
        source.read_into(i, &mut frame)?;
        if equal_images(&frame, &background) {
            copies.push(i);
            continue;
        }
        let mut this = DifferenceStats::default();
        let mut kept: [Vec<(usize, usize)>; 2] = Default::default();
        let mut means = Vec::with_capacity(shots);
        for shot in 0..shots {
            let mut m = [0.0; 2];
            for (cam, (bg, img)) in
                [(&background.left[shot], &frame.left[shot]), (&background.right[shot], &frame.right[shot])]
                    .into_iter()
                    .enumerate()
            {
                let d = difference_stats(bg, img, &masks[cam]);
                this.add(&d);
                tiles += d.tiles.len();
                if shot == 0 {
                    kept[cam] = d.tiles.clone();
                }
                m[cam] = tiles_mean(img, &kept[cam]);
            }
            means.push(m);
        }
        pooled.add(&this);
        per_frame.push(this);
        frame_tiles.push(kept);
        frame_means.push(means);
    }
    // Two captures of one scene always differ by the cameras' noise: a frame equal to the
    // background pixel for pixel is a copy of it, and measures no noise, filter or light.
    if copies.len() == frames {
        return Err(Error::Other(format!(
            "{}: all {frames} frames equal the background pixel for pixel (no tray set down, no camera noise between \
             them): nothing to measure the noise, filter and light on; expected frames captured after the background, \
             with the tray set down",
            dataset.display()
        )));
    }
    if let Some(&i) = copies.first() {
        return Err(Error::Other(format!(
            "{}: equals the background pixel for pixel ({} of {frames} frames do): a copy would pull the noise \
             towards zero; expected a frame captured after the background, with the tray set down",
            source.frame_dirs()[i].display(),
            copies.len()
        )));
    }
    if pooled.counts[MAX_LAG - 1] < 1000.0 {
        return Err(Error::Other(format!(
            "{}: too little of the table is seen unsaturated and unchanged by the tray in both the background and the frames \
             ({tiles} tiles of 32 × 32 px): expected the table in view, lit below saturation",
            dataset.display()
        )));
    }
    let structure = pooled.structure();
    let box_fit = fit_box_noise(&structure);
    // Without noise above the rounding's the filter's side is undetermined (every side fits
    // flat differences) and the gain's fit has no noise to hold the contrast against.
    if box_fit.noise_variance < MIN_NOISE_VARIANCE {
        return Err(Error::Other(format!(
            "{}: the frames differ from the background by no noise above the rounding's (variance {:.3} grey levels², \
             at least {MIN_NOISE_VARIANCE} measurable): the filter and noise cannot be measured; expected frames of the \
             real sensor captured after the background",
            dataset.display(),
            box_fit.noise_variance
        )));
    }
    let blur = box_fit.blur;
    let amplitude = amplitude_of_variance(box_fit.noise_variance);
    let frame_amplitudes: Vec<f64> = per_frame
        .iter()
        .filter(|f| f.counts[MAX_LAG - 1] > 0.0)
        .map(|f| amplitude_of_variance(variance_at(&f.structure(), blur).0))
        .collect();
    let amplitude_se = standard_error(&frame_amplitudes);
    let noise_amplitude = amplitude.round().clamp(0.0, 127.0) as u32;
    let filtered_noise = box_fit.noise_variance / (blur * blur) as f64;

    // Projector gain, dot size and the background's light, by synthesis.
    let real_pattern = combined(&[
        pattern_stats(&background.left.iter().collect::<Vec<_>>(), &masks[0]),
        pattern_stats(&background.right.iter().collect::<Vec<_>>(), &masks[1]),
    ]);
    let albedo = cell.table.albedo.max(1e-3);
    let cell_keys = SensorKeys::of(cell);
    let bg_key = noise_key(cell.scenarios.seed, 0, true);
    let dot_sizes: Vec<u32> = match method {
        Method::OneShot => {
            let d = cell.sensor.dot_size.max(1);
            ((d / 2).max(1)..=(2 * d).clamp(2, 32)).collect()
        }
        Method::Phase12 => vec![cell.sensor.dot_size],
    };
    let mut candidates = Vec::new();
    for &dot_size in &dot_sizes {
        let start = SensorKeys {
            noise_amplitude,
            blur,
            projector_gain: if cell.sensor.projector_gain > 0.0 { cell.sensor.projector_gain } else { 0.5 },
            dot_size,
        };
        let (keys, ambient, sim) = fit_gain(&mut empty, &masks, start, &real_pattern, filtered_noise, albedo, bg_key)?;
        let shape: f64 = sim.shape.iter().zip(&real_pattern.shape).map(|(a, b)| (a - b).powi(2)).sum();
        candidates.push((keys, ambient, sim, shape));
    }
    let best = candidates
        .iter()
        .enumerate()
        .min_by(|a, b| a.1 .3.total_cmp(&b.1 .3))
        .map(|(i, _)| i)
        .expect("one dot size at least");
    let (fitted, ambient_bg, fitted_pattern, _) = candidates[best].clone();

    // The light on the table besides the projector's, frame by frame.
    let clean = empty.render(&fitted, 0.0, None)?.shots.clone();
    let mut levels = Vec::with_capacity(frames);
    for (kept, means) in frame_tiles.iter().zip(&frame_means) {
        if kept.iter().any(|t| t.is_empty()) {
            continue;
        }
        let mut sum = 0.0;
        for (shot, m) in means.iter().enumerate() {
            for cam in 0..2 {
                let p = tiles_mean(if cam == 0 { &clean.left[shot] } else { &clean.right[shot] }, &kept[cam]);
                sum += (m[cam] - p) / (255.0 * albedo);
            }
        }
        levels.push(sum / (2 * means.len()) as f64);
    }
    let ambient = fit_ambient(cell, &levels);

    // The statistics simulated at the fitted values and at the cell's.
    let cell_ambient = ambient_bg;
    let structure_fitted = simulated_structure(&mut empty, &fitted, ambient_bg, &masks)?;
    let structure_cell = simulated_structure(&mut empty, &cell_keys, cell_ambient, &masks)?;
    let cell_pattern = simulated_pattern(&mut empty, &cell_keys, cell_ambient, &masks, bg_key)?;
    let noise_sd = |s: &[f64; MAX_LAG]| ((s[MAX_LAG - 1] - ROUNDING_STRUCTURE).max(0.0) / 4.0).sqrt();
    let lag_one = |s: &[f64; MAX_LAG]| s[0] / s[MAX_LAG - 1].max(f64::MIN_POSITIVE);
    let mut residuals = box_fit.residuals.clone();
    residuals.sort_by(|a, b| a.1.total_cmp(&b.1));
    let blur_evidence = match residuals.get(1) {
        Some(&(next, r)) => format!(
            "the structure function fits a {blur}-px mean filter {:.0} times better (squared residual) than the next best, {next} px",
            r / residuals[0].1.max(1e-12)
        ),
        None => String::new(),
    };
    let gain_se = fitted.projector_gain * real_pattern.contrast_rel_se * {
        // The contrast's share of the pattern (the noise's share known) scales the error.
        let c2 = real_pattern.contrast.powi(2);
        c2 / (c2 - filtered_noise).max(1e-9)
    };
    let mut keys = vec![
        KeyFit {
            key: "sensor.noise_amplitude".into(),
            value: noise_amplitude as f64,
            estimate: amplitude,
            standard_error: amplitude_se,
            cell_value: cell.sensor.noise_amplitude as f64,
            statistic: "noise standard deviation after the mean filter, grey levels (from the difference of two images)"
                .into(),
            real: noise_sd(&structure),
            simulated_fitted: noise_sd(&structure_fitted),
            simulated_cell: noise_sd(&structure_cell),
            evidence: format!(
                "uniform noise on ±A before the filter: standard deviation {:.2} grey levels; A's standard error from {} frames",
                box_fit.noise_variance.sqrt(),
                frame_amplitudes.len()
            ),
        },
        KeyFit {
            key: "sensor.blur".into(),
            value: blur as f64,
            estimate: blur as f64,
            standard_error: f64::NAN,
            cell_value: cell.sensor.blur as f64,
            statistic: "lag-1 share of the difference's structure function (1/blur for box-filtered noise)".into(),
            real: lag_one(&structure),
            simulated_fitted: lag_one(&structure_fitted),
            simulated_cell: lag_one(&structure_cell),
            evidence: blur_evidence,
        },
        KeyFit {
            key: "sensor.projector_gain".into(),
            value: round_to(fitted.projector_gain, 3),
            estimate: fitted.projector_gain,
            standard_error: gain_se,
            cell_value: cell.sensor.projector_gain,
            statistic: "the background's contrast on the table, grey levels rms about the 15 × 15 local mean".into(),
            real: real_pattern.contrast,
            simulated_fitted: fitted_pattern.contrast,
            simulated_cell: cell_pattern.contrast,
            evidence: format!(
                "rendered at the rig with the table's albedo {albedo}, the fitted noise and filter, until the contrast and the mean \
                 grey level ({:.1}) matched",
                real_pattern.mean
            ),
        },
    ];
    if method == Method::OneShot {
        let shape_of = |p: &PatternStats| p.shape[0];
        let scores: Vec<String> =
            candidates.iter().map(|c| format!("{}: {:.4}", c.0.dot_size, c.3.sqrt())).collect::<Vec<_>>();
        keys.push(KeyFit {
            key: "sensor.dot_size".into(),
            value: fitted.dot_size as f64,
            estimate: fitted.dot_size as f64,
            standard_error: f64::NAN,
            cell_value: cell.sensor.dot_size as f64,
            statistic: "the background's lag-1 share of its structure function over lags 1–8 (finer dots: higher)"
                .into(),
            real: shape_of(&real_pattern),
            simulated_fitted: shape_of(&fitted_pattern),
            simulated_cell: shape_of(&cell_pattern),
            evidence: format!("misfit of the structure function's shape per dot size: {}", scores.join(", ")),
        });
    }
    Ok(SensorFit {
        dataset: dataset.to_path_buf(),
        method: method.to_string(),
        frames,
        tiles,
        table_albedo: albedo,
        keys,
        ambient,
        structure_real: structure.to_vec(),
        structure_fitted: structure_fitted.to_vec(),
        structure_cell: structure_cell.to_vec(),
    })
}

/// The projector gain and ambient light that give the rendered background the real one's
/// contrast and mean, from `start` (its noise, filter and dot size kept): each round scales
/// the gain by the ratio of the pattern's contrasts (the noise's share `filtered_noise`
/// taken off both) and moves the ambient light by the difference of the means.
fn fit_gain(
    empty: &mut EmptyCell,
    masks: &[Vec<bool>; 2],
    start: SensorKeys,
    real: &PatternStats,
    filtered_noise: f64,
    albedo: f64,
    key: u64,
) -> Result<(SensorKeys, f64, PatternStats)> {
    let mut keys = start;
    let mut ambient = 0.2;
    let noise_share = filtered_noise + 1.0 / 12.0;
    let mut last = None;
    for _ in 0..GAIN_ROUNDS {
        let sim = simulated_pattern(empty, &keys, ambient, masks, key)?;
        let done = (sim.contrast / real.contrast - 1.0).abs() < 0.002 && (sim.mean - real.mean).abs() < 0.2;
        let pattern_ratio =
            (real.contrast.powi(2) - noise_share).max(1e-6) / (sim.contrast.powi(2) - noise_share).max(1e-6);
        let next_gain = (keys.projector_gain * pattern_ratio.sqrt()).clamp(1e-4, 10.0);
        let next_ambient = (ambient + (real.mean - sim.mean) / (255.0 * albedo)).clamp(0.0, 10.0);
        last = Some((keys, ambient, sim));
        if done {
            break;
        }
        keys.projector_gain = next_gain;
        ambient = next_ambient;
    }
    Ok(last.expect("one round at least"))
}

/// The pattern statistics of the empty table rendered with `keys` under `ambient`, both
/// cameras together.
fn simulated_pattern(
    empty: &mut EmptyCell,
    keys: &SensorKeys,
    ambient: f64,
    masks: &[Vec<bool>; 2],
    key: u64,
) -> Result<PatternStats> {
    let frame = &empty.render(keys, ambient, Some(key))?.shots;
    Ok(combined(&[
        pattern_stats(&frame.left.iter().collect::<Vec<_>>(), &masks[0]),
        pattern_stats(&frame.right.iter().collect::<Vec<_>>(), &masks[1]),
    ]))
}

/// The difference's structure function of two renders of the empty table with `keys`
/// under `ambient` and two noise keys.
fn simulated_structure(
    empty: &mut EmptyCell,
    keys: &SensorKeys,
    ambient: f64,
    masks: &[Vec<bool>; 2],
) -> Result<[f64; MAX_LAG]> {
    let a = empty.render(keys, ambient, Some(noise_key(1, 1, false)))?.shots.clone();
    let b = &empty.render(keys, ambient, Some(noise_key(1, 2, false)))?.shots;
    let mut out = DifferenceStats::default();
    let pairs: [(&Vec<GrayImage>, &Vec<GrayImage>); 2] = [(&a.left, &b.left), (&a.right, &b.right)];
    for (cam, (x, y)) in pairs.into_iter().enumerate() {
        for (p, q) in x.iter().zip(y) {
            out.add(&difference_stats(p, q, &masks[cam]));
        }
    }
    Ok(out.structure())
}

/// Two cameras' pattern statistics as one, weighted by their pixels.
fn combined(parts: &[PatternStats; 2]) -> PatternStats {
    let n: f64 = parts.iter().map(|p| p.pixels as f64).sum::<f64>().max(1.0);
    let weight = |p: &PatternStats| p.pixels as f64 / n;
    let mut shape = [0.0; stats::PATTERN_LAGS];
    for p in parts {
        for (s, v) in shape.iter_mut().zip(&p.shape) {
            *s += weight(p) * v;
        }
    }
    PatternStats {
        mean: parts.iter().map(|p| weight(p) * p.mean).sum(),
        contrast: parts.iter().map(|p| weight(p) * p.contrast.powi(2)).sum::<f64>().sqrt(),
        shape,
        contrast_rel_se: parts.iter().map(|p| (weight(p) * p.contrast_rel_se).powi(2)).sum::<f64>().sqrt(),
        pixels: parts.iter().map(|p| p.pixels).sum(),
    }
}

/// The ambient range whose uniform draws, plus the lamp's share as the cell draws its lamp
/// (its strength times the cosine of its angle at the table's centre, over 1000 of the
/// cell's scenarios), have the mean and the variance of the frames' light `levels`.
fn fit_ambient(cell: &Cell, levels: &[f64]) -> AmbientFit {
    let lamp: Vec<f64> = (0..1000)
        .map(|i| {
            let s = draw_scenario(cell, cell.scenarios.seed, i);
            let p = s.lamp_position.coords;
            s.lamp_strength * (p.z / p.norm().max(1e-9)).max(0.0)
        })
        .collect();
    let (lamp_mean, lamp_var) = mean_var(&lamp);
    let (mean, var) = mean_var(levels);
    let centre = mean - lamp_mean;
    let (half, note) = if var > lamp_var {
        ((3.0 * (var - lamp_var)).sqrt(), "the frames' mean and variance".to_string())
    } else {
        // The frames vary less than the lamp alone would make them vary: their spread tells
        // nothing of the ambient light's, and the cell's width is kept.
        (
            (cell.lighting.ambient[1] - cell.lighting.ambient[0]) / 2.0,
            format!(
                "the frames' mean, and the cell's width: the frames vary less (sd {:.3}) than the cell's lamp alone \
                 would make them",
                var.max(0.0).sqrt()
            ),
        )
    };
    let lo = round_to((centre - half).max(0.0), 3);
    let hi = round_to((centre + half).max(lo), 3);
    AmbientFit {
        range: [lo, hi],
        cell_range: cell.lighting.ambient,
        frame_levels: levels.to_vec(),
        lamp_mean,
        lamp_sd: lamp_var.sqrt(),
        note,
    }
}

fn mean_var(v: &[f64]) -> (f64, f64) {
    if v.is_empty() {
        return (f64::NAN, f64::NAN);
    }
    let m = v.iter().sum::<f64>() / v.len() as f64;
    let var = if v.len() > 1 { v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (v.len() - 1) as f64 } else { 0.0 };
    (m, var)
}

/// The standard error of the mean of `v` (NaN below two values).
fn standard_error(v: &[f64]) -> f64 {
    if v.len() < 2 {
        return f64::NAN;
    }
    (mean_var(v).1 / v.len() as f64).sqrt()
}

fn round_to(v: f64, digits: i32) -> f64 {
    let s = 10f64.powi(digits);
    (v * s).round() / s
}
