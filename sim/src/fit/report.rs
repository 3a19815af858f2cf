//! What the sensor fit writes: the cell fragment (`fit-sensor.toml`: only the fitted keys,
//! each with a comment giving its uncertainty and evidence, to paste or merge into the cell
//! file), `fit-sensor.json` (every statistic, real and simulated) and `fit-sensor.html`
//! (the same side by side).

use std::path::Path;

use camplace_config::write_atomic_all;

use super::{KeyFit, SensorFit};
use crate::report::html::HtmlPage;
use crate::Result;

/// The cell fragment's file name.
pub const FIT_FRAGMENT: &str = "fit-sensor.toml";
/// The fit's statistics, JSON.
pub const FIT_JSON: &str = "fit-sensor.json";
/// The fit's report page.
pub const FIT_HTML: &str = "fit-sensor.html";

/// Writes the fragment, the JSON and the page into `out` (made when missing): all three or,
/// when one cannot be written, none.
pub fn write_fit(fit: &SensorFit, out: &Path) -> Result<()> {
    std::fs::create_dir_all(out).map_err(|e| camplace_config::Error::io(out, &e))?;
    let json = serde_json::to_string_pretty(fit).expect("a fit is plain data");
    let (fragment, json, html) = (fragment(fit), format!("{json}\n"), page(fit).html());
    let (fragment_path, json_path, html_path) = (out.join(FIT_FRAGMENT), out.join(FIT_JSON), out.join(FIT_HTML));
    Ok(write_atomic_all(&[
        (&fragment_path, fragment.as_bytes()),
        (&json_path, json.as_bytes()),
        (&html_path, html.as_bytes()),
    ])?)
}

/// A number in a comment: NaN as "not measured".
fn or_none(v: f64, digits: usize) -> String {
    if v.is_finite() {
        format!("{v:.digits$}")
    } else {
        "not measured".to_string()
    }
}

/// The cell fragment: `[sensor]` and `[lighting]` with the fitted keys only.
pub fn fragment(fit: &SensorFit) -> String {
    let mut t = String::new();
    t.push_str(&format!(
        "# The sensor as fitted by camplace fit-sensor to {} ({} frames, {}), read against the\n\
         # cell's table albedo {}. Paste or merge into the cell file: a key here replaces the cell's.\n",
        fit.dataset.display(),
        fit.frames,
        fit.method,
        fit.table_albedo
    ));
    t.push_str("[sensor]\n");
    for k in &fit.keys {
        let name = k.key.strip_prefix("sensor.").unwrap_or(&k.key);
        t.push_str(&comment(k));
        if name == "projector_gain" {
            t.push_str(&format!("{name} = {}\n", k.value));
        } else {
            t.push_str(&format!("{name} = {}\n", k.value as u64));
        }
    }
    let a = &fit.ambient;
    let (mean, sd) = mean_sd(&a.frame_levels);
    t.push_str(&format!(
        "\n[lighting]\n# The frames' light on the table besides the projector's: mean {} sd {} (units of full\n\
         # white, {} frames), less the cell's lamp share (mean {:.3}, sd {:.3}); was [{}, {}];\n# {}.\n",
        or_none(mean, 3),
        or_none(sd, 3),
        a.frame_levels.len(),
        a.lamp_mean,
        a.lamp_sd,
        a.cell_range[0],
        a.cell_range[1],
        a.note
    ));
    t.push_str(&format!("ambient = [{}, {}]\n", a.range[0], a.range[1]));
    t
}

fn comment(k: &KeyFit) -> String {
    let mut c = format!(
        "# {}: estimate {} (standard error {}), was {}; {}: real {:.3}, simulated {:.3} (was {:.3}).\n",
        k.key,
        or_none(k.estimate, 3),
        or_none(k.standard_error, 3),
        k.cell_value,
        k.statistic,
        k.real,
        k.simulated_fitted,
        k.simulated_cell
    );
    if !k.evidence.is_empty() {
        c.push_str(&format!("# {}.\n", k.evidence));
    }
    c
}

fn mean_sd(v: &[f64]) -> (f64, f64) {
    let (m, var) = super::mean_var(v);
    (m, var.sqrt())
}

fn page(fit: &SensorFit) -> HtmlPage {
    let mut page = HtmlPage::new("camplace fit-sensor");
    page.paragraph(&format!(
        "Dataset {}: {} frames ({}) compared with its background over {} table tiles of 32 × 32 px; light levels read \
         with the cell's table albedo {}.",
        fit.dataset.display(),
        fit.frames,
        fit.method,
        fit.tiles,
        fit.table_albedo
    ));
    page.heading(2, "Fitted keys");
    let rows: Vec<Vec<String>> = fit
        .keys
        .iter()
        .map(|k| {
            vec![
                k.key.clone(),
                format!("{}", k.value),
                or_none(k.estimate, 3),
                or_none(k.standard_error, 3),
                format!("{}", k.cell_value),
                k.statistic.clone(),
                format!("{:.3}", k.real),
                format!("{:.3}", k.simulated_fitted),
                format!("{:.3}", k.simulated_cell),
            ]
        })
        .collect();
    page.table(
        &[
            "key",
            "fitted",
            "estimate",
            "standard error",
            "cell's value",
            "statistic",
            "real",
            "simulated, fitted",
            "simulated, cell's",
        ],
        &rows,
    );
    page.list(
        &fit.keys
            .iter()
            .filter(|k| !k.evidence.is_empty())
            .map(|k| format!("{}: {}", k.key, k.evidence))
            .collect::<Vec<_>>(),
    );
    page.heading(2, "Ambient light");
    let a = &fit.ambient;
    let (mean, sd) = mean_sd(&a.frame_levels);
    page.paragraph(&format!(
        "lighting.ambient fitted [{}, {}] (the cell's [{}, {}]): the frames' light on the table besides the projector's has \
         mean {} and sd {} over {} frames; the cell's lamp adds mean {:.3}, sd {:.3} at the table's centre. The fitted \
         range, with that lamp added, has {}.",
        a.range[0],
        a.range[1],
        a.cell_range[0],
        a.cell_range[1],
        or_none(mean, 3),
        or_none(sd, 3),
        a.frame_levels.len(),
        a.lamp_mean,
        a.lamp_sd,
        a.note
    ));
    page.heading(2, "The noise's structure function");
    page.paragraph(
        "The mean of (Δ(p + d) − Δ(p))² for the difference Δ of two images of the empty table, by lag d: real (background \
         against each frame, the tray's tiles left out) and simulated (two renders with other noise). Box-filtered noise \
         grows linearly up to the filter's side and is flat beyond.",
    );
    let rows: Vec<Vec<String>> = (0..fit.structure_real.len())
        .map(|i| {
            vec![
                format!("{}", i + 1),
                format!("{:.2}", fit.structure_real[i]),
                format!("{:.2}", fit.structure_fitted[i]),
                format!("{:.2}", fit.structure_cell[i]),
            ]
        })
        .collect();
    page.table(&["lag, px", "real", "simulated, fitted", "simulated, cell's"], &rows);
    page.heading(2, "Cell fragment");
    page.pre(&fragment(fit));
    page
}
