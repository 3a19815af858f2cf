//! The review page of a dataset without truth: each frame's left image with the tray's
//! outline (the edges of its model's bounding box and its +x axis) drawn where the estimated
//! pose puts it, the frame's scene cloud in 3D with the tray's surface at the pose, the
//! verification's score and verdict, and keys to judge it — c correct,
//! w wrong, u unsure, n / → next, p / ← previous, s sorts by score (lowest first) or by frame.
//! Served by `camplace review --listen`, each mark is POSTed to `/label` and appended to
//! `labels.jsonl` before the page moves on; the page is made afresh from that file each
//! time it is opened, so a review reopened resumes at the first frame still open. Frames
//! with a `truth.json` are judged by the success tolerances and skipped.
//!
//! A `#script=KEYS` fragment (e.g. `#script=cwwu`, with `&quit` to end the server after)
//! makes the page press those keys itself, one real `KeyboardEvent` at a time dispatched to
//! the page's own key handler, each waiting for its mark to be saved: how a scripted
//! reviewer drives the page in a headless browser.

use std::path::Path;

use camplace_config::{image_name, read_cloud, thinned, Cell, SCENE_CLOUD};
use camplace_estimator::{geometry::isometry_from_rows, Rig};
use camplace_plot::{legend_entry, view3d_html, ViewCanvas};
use nalgebra::Point3;
use serde::Serialize;

use super::judge::{frame_names, present_marks, read_labels, read_poses, Mark};
use crate::scene::tray::TrayModel;
use crate::{Error, Result};

/// One frame as the page shows it.
#[derive(Debug, Clone, Serialize)]
struct PageFrame {
    name: String,
    image: String,
    found: bool,
    score: Option<f32>,
    verdict: Option<String>,
    /// Line segments x0 y0 x1 y1 in pixels.
    outline: Vec<[f32; 4]>,
    /// Success by the truth, when the frame has a truth.json.
    truth: Option<bool>,
    /// The scene cloud the pose was sought in (its `scene.ply`, thinned), world mm; empty
    /// when the frame has none.
    cloud: Vec<[f32; 3]>,
    /// The pose's rows (3 x 4, world from tray) when one was found.
    pose: Option<[f64; 12]>,
}

/// The page's data.
#[derive(Debug, Clone, Serialize)]
struct PageData {
    width: u32,
    height: u32,
    frames: Vec<PageFrame>,
    marks: std::collections::BTreeMap<String, Mark>,
    live: bool,
    /// Points on the tray's surface, tray frame, mm: the model drawn at each pose in 3D.
    tray_points: Vec<[f32; 3]>,
}

/// Most scene points a frame's 3D view is handed, and points drawn on the tray.
const CLOUD_POINTS: usize = 1500;
const TRAY_POINTS: usize = 1500;

/// A coordinate to a tenth of a millimetre: what the view resolves, in few characters.
fn tenth(p: [f32; 3]) -> [f32; 3] {
    p.map(|v| (v * 10.0).round() / 10.0)
}

/// The scene cloud `estimate` wrote beside frame `name`'s images, thinned; empty without one.
fn scene_cloud(dir: &Path, name: &str) -> Result<Vec<[f32; 3]>> {
    let path = dir.join("frames").join(name).join(SCENE_CLOUD);
    if !path.is_file() {
        return Ok(Vec::new());
    }
    Ok(thinned(&read_cloud(&path)?.points, CLOUD_POINTS).map(|&p| tenth(p)).collect())
}

/// The edges of `tray`'s bounding box and its +x axis from the top centre, as segments in
/// the tray frame.
fn tray_outline(tray: &TrayModel) -> Vec<[Point3<f64>; 2]> {
    let (lo, hi) = tray.solid.bounds();
    let c = |i: usize| {
        Point3::new(
            if i & 1 == 0 { lo.x } else { hi.x },
            if i & 2 == 0 { lo.y } else { hi.y },
            if i & 4 == 0 { lo.z } else { hi.z },
        )
    };
    let mut edges = Vec::new();
    for i in 0..8usize {
        for bit in [1, 2, 4] {
            if i & bit == 0 {
                edges.push([c(i), c(i | bit)]);
            }
        }
    }
    let top = Point3::new((lo.x + hi.x) / 2.0, (lo.y + hi.y) / 2.0, hi.z);
    edges.push([top, Point3::new(hi.x, top.y, hi.z)]);
    edges
}

/// The review page of dataset `dir` (with its `poses.jsonl`), the marks of its
/// `labels.jsonl` in it; `live` when served (marks can be saved).
pub fn review_page(dir: &Path, cell: &Cell, live: bool) -> Result<String> {
    let names = frame_names(dir)?;
    if names.is_empty() {
        return Err(Error::Other(format!("{}: no frames to review", dir.join("frames").display())));
    }
    let rig_path = dir.join("rig.json");
    let rig_file = camplace_config::RigFile::load(&rig_path)?;
    let rig = Rig::from_file(&rig_file);
    let poses = read_poses(dir)?;
    let labels = read_labels(dir, &names)?;
    let tray = TrayModel::from_cell(cell)?;
    let outline = tray_outline(&tray);
    let tray_points =
        tray.solid.surface_points(TRAY_POINTS).iter().map(|p| tenth([p.x as f32, p.y as f32, p.z as f32])).collect();
    let first = dir.join("frames").join(&names[0]);
    let shots = if first.join("left.png").is_file() { 1 } else { 12 };
    let mut frames = Vec::with_capacity(names.len());
    for name in &names {
        let Some(pose) = poses.iter().find(|p| &p.frame == name) else {
            return Err(Error::Other(format!(
                "{}: frame: expected a pose line for frame {name}; estimate the dataset again",
                dir.join("poses.jsonl").display()
            )));
        };
        let t = isometry_from_rows(&pose.t_world_tray);
        let segments = if pose.found {
            outline
                .iter()
                .filter_map(|[a, b]| {
                    let pa = rig.left.project(&(t * a))?;
                    let pb = rig.left.project(&(t * b))?;
                    Some([pa.x as f32, pa.y as f32, pb.x as f32, pb.y as f32])
                })
                .collect()
        } else {
            Vec::new()
        };
        frames.push(PageFrame {
            name: name.clone(),
            image: format!("frames/{name}/{}", image_name("left", 0, shots)),
            found: pose.found,
            score: pose.verify_score,
            verdict: pose.verdict.clone(),
            outline: segments,
            truth: pose.score.map(|s| s.success),
            cloud: scene_cloud(dir, name)?,
            pose: pose.found.then(|| {
                let r = &pose.t_world_tray;
                std::array::from_fn(|i| r[i / 4][i % 4])
            }),
        });
    }
    // Marks made on earlier poses judge nothing now: their frames open again.
    let marks = present_marks(&labels, &poses).0.into_iter().collect();
    let data = PageData { width: rig_file.left.width, height: rig_file.left.height, frames, marks, live, tray_points };
    // Inside a <script>, "</" would end it early.
    let json = serde_json::to_string(&data).expect("page data is plain").replace("</", "<\\/");
    let legend = [
        (SCENE_COLOUR, "the frame's scene cloud (scene.ply, written by estimate)"),
        (ACCEPTED_COLOUR, "the tray at an accepted pose"),
        (REFUSED_COLOUR, "the tray at a refused pose"),
    ]
    .map(|(c, l)| legend_entry(c, l))
    .concat();
    let view = view3d_html(
        "",
        &format!("<ul style=\"list-style:none;padding:0\">{legend}</ul><p id=\"view3d-note\"></p>"),
        ViewCanvas { size: [720, 480], persist: Some("review") },
    );
    Ok(PAGE
        .replace("__VIEW3D__", &view)
        .replace(
            "__COLOURS__",
            &format!("{{scene: '{SCENE_COLOUR}', accepted: '{ACCEPTED_COLOUR}', refused: '{REFUSED_COLOUR}'}}"),
        )
        .replace("__DATA__", &json)
        .replace("__TITLE__", &crate::report::html::escape(&dir.display().to_string())))
}

/// The 3D view's colours: the scene cloud, the tray at an accepted and at a refused pose.
const SCENE_COLOUR: &str = "#6b6f76";
const ACCEPTED_COLOUR: &str = "#2ca02c";
const REFUSED_COLOUR: &str = "#d62728";

const PAGE: &str = r##"<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>review __TITLE__</title>
<style>
body{font-family:sans-serif;margin:1em;color:#222}
#view{position:relative;display:inline-block}
#view img{display:block;max-width:100%}
#view svg{position:absolute;left:0;top:0;width:100%;height:100%}
#status{margin:0.5em 0;font-size:1.1em}
.keys{color:#555}
</style></head><body>
<h1>review __TITLE__</h1>
<p class="keys">c correct · w wrong · u unsure · n / → next · p / ← previous · s sort by score / by frame</p>
<div id="status"></div>
<div id="view"><img id="image" alt="left image"><svg id="outline" xmlns="http://www.w3.org/2000/svg"></svg></div>
<p id="progress"></p>
<h2>in 3D</h2>
__VIEW3D__
<script>
const data = __DATA__;
const marks = data.marks;
let byScore = false;
let order = [];
let at = 0;
window.lastPost = Promise.resolve();
function judged(f) { return f.truth !== null || marks[f.name] !== undefined; }
function sortFrames() {
  order = data.frames.map((f, i) => i);
  if (byScore) order.sort((a, b) => (data.frames[a].score ?? -1) - (data.frames[b].score ?? -1));
}
function firstOpen(from) {
  for (let k = from; k < order.length; k++) if (!judged(data.frames[order[k]])) return k;
  return -1;
}
function show() {
  const f = data.frames[order[at]];
  document.getElementById('image').src = f.image;
  const svg = document.getElementById('outline');
  svg.setAttribute('viewBox', `-0.5 -0.5 ${data.width} ${data.height}`);
  svg.innerHTML = f.outline.map(s => `<line x1="${s[0]}" y1="${s[1]}" x2="${s[2]}" y2="${s[3]}" stroke="#0f0" stroke-width="2"/>`).join('');
  const state = f.truth !== null ? `judged by its truth: ${f.truth ? 'correct' : 'wrong'}` : (marks[f.name] ? `marked ${marks[f.name]}` : 'open');
  const score = f.score === null ? '-' : f.score.toFixed(3);
  document.getElementById('status').textContent =
    `frame ${f.name} (${at + 1} of ${order.length}${byScore ? ', by score' : ''}): ${f.found ? 'pose found' : 'no pose'}, score ${score}, ${f.verdict ?? '-'}; ${state}`;
  const done = data.frames.filter(judged).length;
  document.getElementById('progress').textContent = `${done} of ${data.frames.length} frames judged` + (data.live ? '' : ' (not served: marks are not saved; open it with camplace review --listen)');
  const colours = __COLOURS__;
  const clouds = [{name: 'scene', colour: colours.scene, positions: f.cloud}];
  if (f.pose !== null) clouds.push({name: 'model', colour: f.verdict === 'accepted' ? colours.accepted : colours.refused, positions: data.tray_points, pose: f.pose});
  window.camplaceView3d.show({frame: 'world: mm, z up', clouds: clouds});
  document.getElementById('view3d-note').textContent = f.cloud.length ? '' : 'no scene cloud for this frame: estimate the dataset again to write frames/' + f.name + '/scene.ply';
  document.body.dataset.frame = f.name;
  document.body.dataset.judged = done;
}
async function mark(m) {
  const f = data.frames[order[at]];
  if (f.truth !== null) return;
  if (data.live) {
    const r = await fetch('/label', {method: 'POST', headers: {'Content-Type': 'application/json'}, body: JSON.stringify({frame: f.name, mark: m})});
    if (!r.ok) { document.getElementById('status').textContent = 'not saved: ' + await r.text(); return; }
  }
  marks[f.name] = m;
  const next = firstOpen(at + 1);
  if (next >= 0) at = next; else if (at + 1 < order.length) at += 1;
  show();
}
function onKey(e) {
  const k = e.key;
  if (k === 'c') window.lastPost = mark('correct');
  else if (k === 'w') window.lastPost = mark('wrong');
  else if (k === 'u') window.lastPost = mark('unsure');
  else if (k === 'n' || k === 'ArrowRight') { if (at + 1 < order.length) { at += 1; show(); } }
  else if (k === 'p' || k === 'ArrowLeft') { if (at > 0) { at -= 1; show(); } }
  else if (k === 's') { const name = data.frames[order[at]].name; byScore = !byScore; sortFrames(); at = order.findIndex(i => data.frames[i].name === name); show(); }
}
document.addEventListener('keydown', onKey);
sortFrames();
at = Math.max(0, firstOpen(0));
document.body.dataset.start = data.frames[order[at]].name;
show();
async function runScript() {
  const m = location.hash.match(/script=([a-zA-Z]*)/);
  if (!m) return;
  for (const key of m[1]) {
    document.dispatchEvent(new KeyboardEvent('keydown', {key: key, bubbles: true}));
    await window.lastPost;
  }
  document.body.dataset.marks = data.frames.map(f => marks[f.name] ? marks[f.name][0] : '-').join('');
  if (/[#&]quit/.test(location.hash) && data.live) await fetch('/quit', {method: 'POST'});
  document.body.dataset.scriptDone = '1';
}
runScript();
</script>
</body></html>
"##;
