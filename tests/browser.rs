//! Headless Chromium for the pages' tests: finding it (a test without it says so and skips,
//! unless CAMPLACE_BROWSER says CI installed it), a screenshot's pixels, the inline 3D scene
//! of a page and the canvas's colours in a screenshot.

use std::path::Path;

use serde_json::Value;

/// The Chromium on PATH; `None` (after saying that `what` is skipped) without one. Fails
/// when CAMPLACE_BROWSER is set: CI installs it, so a skip there would hide the test.
pub(crate) fn chromium(what: &str) -> Option<&'static str> {
    let found = ["chromium", "chromium-browser"].into_iter().find(|b| which(b));
    if found.is_none() {
        assert!(std::env::var_os("CAMPLACE_BROWSER").is_none(), "CAMPLACE_BROWSER is set but no chromium is installed");
        eprintln!("no chromium: {what} is skipped (CI installs it and sets CAMPLACE_BROWSER)");
    }
    found
}

fn which(program: &str) -> bool {
    std::env::var_os("PATH").is_some_and(|paths| std::env::split_paths(&paths).any(|p| p.join(program).is_file()))
}

/// The (x, y) pixels of a PNG screenshot as RGB, with its width.
pub(crate) fn screenshot_pixels(path: &Path) -> (Vec<[u8; 3]>, usize) {
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(path).unwrap()));
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).unwrap();
    let step = info.color_type.samples();
    let px = buf[..info.buffer_size()].chunks(step).map(|c| [c[0], c[1], c[2]]).collect();
    (px, info.width as usize)
}

/// The pixels of a screenshot inside `[x0, x1) x [y0, y1)`.
pub(crate) fn region(shot: &Path, x: std::ops::Range<usize>, y: std::ops::Range<usize>) -> Vec<[u8; 3]> {
    let (px, width) = screenshot_pixels(shot);
    px.iter()
        .enumerate()
        .filter(|(i, _)| x.contains(&(i % width)) && y.contains(&(i / width)))
        .map(|(_, p)| *p)
        .collect()
}

/// Whether a pixel within 12 of `#rrggbb` in each channel is among `pixels`.
pub(crate) fn shows_colour(pixels: &[[u8; 3]], hex: &str) -> bool {
    let rgb: Vec<u8> = (0..3).map(|i| u8::from_str_radix(&hex[1 + 2 * i..3 + 2 * i], 16).unwrap()).collect();
    pixels.iter().any(|p| p.iter().zip(&rgb).all(|(a, b)| a.abs_diff(*b) <= 12))
}

/// The JSON of `<script type="application/json" id="scene3d">` in a page.
pub(crate) fn inline_scene(html: &str) -> Value {
    let open = "<script type=\"application/json\" id=\"scene3d\">";
    let at = html.find(open).expect("the page holds the scene as inline JSON") + open.len();
    let text = &html[at..at + html[at..].find("</script>").unwrap()];
    serde_json::from_str(&text.replace("<\\/", "</")).expect("the scene parses")
}

/// The value of attribute `name` of the first element that has it in a dumped DOM, unescaped.
pub(crate) fn dom_attr(dom: &str, name: &str) -> Option<String> {
    let at = dom.find(&format!(" {name}=\""))?;
    let v = &dom[at + name.len() + 3..];
    Some(v[..v.find('"')?].replace("&quot;", "\"").replace("&amp;", "&"))
}

/// The points of cloud `name` of a 3D scene.
pub(crate) fn cloud(scene: &Value, name: &str) -> Vec<[f64; 3]> {
    let clouds = scene["clouds"].as_array().expect("the scene's clouds");
    let c = clouds.iter().find(|c| c["name"] == name).unwrap_or_else(|| panic!("no cloud {name} in the scene"));
    c["positions"].as_array().unwrap().iter().map(|p| [0, 1, 2].map(|i| p[i].as_f64().unwrap())).collect()
}

/// The largest distance from a point of `points` to its nearest in `to` (brute force).
pub(crate) fn farthest_from(points: &[[f64; 3]], to: &[[f64; 3]]) -> f64 {
    points
        .iter()
        .map(|p| to.iter().map(|q| (0..3).map(|i| (p[i] - q[i]).powi(2)).sum::<f64>()).fold(f64::INFINITY, f64::min))
        .fold(0.0, f64::max)
        .sqrt()
}
