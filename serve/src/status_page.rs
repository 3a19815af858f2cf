//! The status page over HTTP (camplace-http, so no client can stall or starve it): `/` an
//! HTML page that reloads itself every two seconds (the last left image with the model's
//! outline at the pose, the verdict and score, the scene cloud in 3D with the model's points
//! at the pose, counts by status, the latency histogram, the drift state), `/frame.png` that image and `/status.json` the same figures for programs.

use std::net::TcpListener;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;

use camplace_http::{Limits, Request, Response, Server};
use camplace_plot::{legend_entry, view3d_html, ViewCanvas};
use image::ImageEncoder;

use crate::protocol::Status;
use crate::state::{Shared, State, HISTOGRAM_BARS, HISTOGRAM_STEP_MS};

/// Serves the page until `stop` is set (seen within a tenth of a second).
pub(crate) fn serve_page(listener: TcpListener, shared: Arc<Shared>, stop: Arc<AtomicBool>) {
    // No route takes a body: the server's default body limit (none) stands.
    let Ok(mut server) = Server::new(listener, Limits::default(), move |r: &Request| answer(&shared, r)) else {
        return;
    };
    server.run(&stop);
}

/// The answer to one request.
fn answer(shared: &Shared, request: &Request) -> Response {
    let known = matches!(request.path.as_str(), "/" | "/index.html" | "/status.json" | "/frame.png");
    if request.method != "GET" {
        return if known {
            Response::text(405, "only GET is answered").with_header("Allow", "GET")
        } else {
            Response::text(404, "not found")
        };
    }
    let response = match request.path.as_str() {
        "/" | "/index.html" => Response::new(200, "text/html; charset=utf-8", page(&shared.settled())),
        "/status.json" => {
            Response::new(200, "application/json", serde_json::to_vec(&shared.settled().json()).unwrap_or_default())
        }
        "/frame.png" => match frame_png(shared) {
            Some(png) => Response::new(200, "image/png", png),
            None => Response::text(404, "no frame yet"),
        },
        _ => Response::text(404, "not found"),
    };
    response.with_header("Cache-Control", "no-store")
}

/// The last frame's first left shot as a grey PNG.
fn frame_png(shared: &Shared) -> Option<Vec<u8>> {
    let image = {
        let s = shared.settled();
        if s.image.data.is_empty() {
            return None;
        }
        s.image.clone()
    };
    let mut out = Vec::new();
    image::codecs::png::PngEncoder::new_with_quality(
        &mut out,
        image::codecs::png::CompressionType::Fast,
        image::codecs::png::FilterType::Sub,
    )
    .write_image(&image.data, image.width as u32, image.height as u32, image::ExtendedColorType::L8)
    .ok()?;
    Some(out)
}

fn escape(text: &str) -> String {
    text.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;").replace('"', "&quot;")
}

/// The HTML page of `s`.
fn page(s: &State) -> String {
    let mut html = String::with_capacity(8192);
    html.push_str(
        "<!DOCTYPE html><html><head><meta charset=\"utf-8\"><meta http-equiv=\"refresh\" content=\"2\">\
         <title>camplace serve</title><style>body{font-family:sans-serif;margin:1em}\
         td,th{padding:2px 8px;text-align:right}.warn{color:#b00;font-weight:bold}\
         #view{position:relative;display:inline-block;max-width:100%}#view img{display:block;max-width:100%}\
         #view svg{position:absolute;left:0;top:0;width:100%;height:100%}</style></head><body>\
         <h1>camplace serve</h1>",
    );
    // The last frame and the outline.
    match &s.last {
        Some(l) => html.push_str(&format!(
            "<p>last trigger: <span id=\"last-status\">{}</span>, frame <span id=\"last-frame\">{}</span>, \
             verdict <span id=\"verdict\">{}</span>, score <span id=\"score\">{:.4}</span>, \
             {:.1} ms</p>",
            escape(&l.status),
            escape(&l.frame),
            escape(&l.verdict),
            l.score,
            l.latency_ms
        )),
        None => html.push_str("<p>no trigger yet</p>"),
    }
    if let Some(e) = &s.camera_error {
        html.push_str(&format!("<p class=\"warn\" id=\"camera-error\">camera: {}</p>", escape(e)));
    }
    if s.image_serial > 0 {
        let (w, h) = (s.image.width, s.image.height);
        let points: Vec<String> = s.outline.iter().map(|[x, y]| format!("{x:.1},{y:.1}")).collect();
        html.push_str(&format!(
            "<div id=\"view\"><img id=\"frame\" src=\"/frame.png?n={}\" width=\"{w}\" height=\"{h}\" alt=\"last left image\">\
             <svg viewBox=\"0 0 {w} {h}\" preserveAspectRatio=\"none\"><polygon id=\"outline\" points=\"{}\" \
             fill=\"none\" stroke=\"#0f0\" stroke-width=\"3\"/></svg></div>",
            s.image_serial,
            points.join(" ")
        ));
    }
    if s.last.is_some() && !s.cloud.is_empty() {
        html.push_str("<h2>in 3D</h2>");
        html.push_str(&view3d(s));
    }
    // Counts by status.
    html.push_str("<h2>replies</h2><table><tr>");
    for status in Status::ALL {
        html.push_str(&format!("<th>{}</th>", status.as_str()));
    }
    html.push_str("</tr><tr>");
    for status in Status::ALL {
        html.push_str(&format!("<td id=\"count-{}\">{}</td>", status.as_str(), s.counts[status.index()]));
    }
    html.push_str("</tr></table>");
    // Latency.
    let p = |q| s.percentile(q).map_or("-".to_string(), |v| format!("{v:.1} ms"));
    html.push_str(&format!(
        "<h2>trigger to reply</h2><p>p50 <span id=\"p50\">{}</span>, p99 <span id=\"p99\">{}</span> \
         (last {} triggers)</p>",
        p(50.0),
        p(99.0),
        s.recent.len()
    ));
    let most = s.histogram.iter().copied().max().unwrap_or(0).max(1);
    html.push_str("<svg id=\"histogram\" width=\"630\" height=\"140\" viewBox=\"0 0 630 140\">");
    for (i, &n) in s.histogram.iter().enumerate() {
        let bar = 100.0 * n as f64 / most as f64;
        html.push_str(&format!(
            "<rect x=\"{}\" y=\"{:.1}\" width=\"26\" height=\"{bar:.1}\" fill=\"#47a\"><title>{} ms: {n}</title></rect>",
            i * 30,
            110.0 - bar,
            if i + 1 == HISTOGRAM_BARS {
                format!("{:.0}+", i as f64 * HISTOGRAM_STEP_MS)
            } else {
                format!("{:.0}–{:.0}", i as f64 * HISTOGRAM_STEP_MS, (i + 1) as f64 * HISTOGRAM_STEP_MS)
            }
        ));
        if i % 5 == 0 {
            html.push_str(&format!(
                "<text x=\"{}\" y=\"130\" font-size=\"11\">{:.0}</text>",
                i * 30,
                i as f64 * HISTOGRAM_STEP_MS
            ));
        }
    }
    html.push_str("</svg>");
    // Drift.
    let d = &s.drift;
    let state = match (d.warning, d.rotation_deg) {
        (true, _) => "<span class=\"warn\" id=\"drift\">warning: the rig has moved</span>".to_string(),
        (false, Some(_)) => "<span id=\"drift\">ok</span>".to_string(),
        (false, None) => "<span id=\"drift\">not checked yet</span>".to_string(),
    };
    html.push_str(&format!("<h2>drift watch</h2><p>{state}"));
    if let (Some(r), Some(t)) = (d.rotation_deg, d.translation_mm) {
        html.push_str(&format!(": turned {r:.2}°, moved {t:.1} mm along the table's normal ({} checks)", d.checks));
    }
    if let Some(l) = &s.drift_limits {
        html.push_str(&format!("; limits {:.2}° and {:.1} mm ({})", l.rotation_deg, l.translation_mm, escape(&l.from)));
    }
    html.push_str(&format!("</p><p>flight recorder: {} frames kept</p></body></html>", s.recorded));
    html
}

/// The colour of the model at a pose handed to the robot, and at one refused.
const MODEL_ACCEPTED: &str = "#2ca02c";
const MODEL_REFUSED: &str = "#d62728";
const SCENE_CLOUD: &str = "#6b6f76";

/// The 3D view of the last frame: its scene cloud and the model's points at its pose, world mm.
fn view3d(s: &State) -> String {
    let points = |pts: &[[f32; 3]]| {
        let mut out = String::with_capacity(pts.len() * 24 + 2);
        out.push('[');
        for (i, p) in pts.iter().enumerate() {
            if i > 0 {
                out.push(',');
            }
            out.push_str(&format!("[{:.1},{:.1},{:.1}]", p[0], p[1], p[2]));
        }
        out.push(']');
        out
    };
    let model_colour = if s.pose_accepted { MODEL_ACCEPTED } else { MODEL_REFUSED };
    let mut clouds =
        vec![format!("{{\"name\":\"scene\",\"colour\":\"{SCENE_CLOUD}\",\"positions\":{}}}", points(&s.cloud))];
    let mut legend = legend_entry(SCENE_CLOUD, "the scene cloud the pose was sought in");
    if !s.model_at_pose.is_empty() {
        clouds.push(format!(
            "{{\"name\":\"model\",\"colour\":\"{model_colour}\",\"positions\":{}}}",
            points(&s.model_at_pose)
        ));
        legend.push_str(&legend_entry(
            model_colour,
            if s.pose_accepted { "the model at the pose sent" } else { "the model at the pose refused" },
        ));
    }
    let scene = format!("{{\"frame\":\"world: mm, z up\",\"clouds\":[{}]}}", clouds.join(","));
    let side = format!("<ul style=\"list-style:none;padding:0\">{legend}</ul>");
    view3d_html(&scene, &side, ViewCanvas { size: [640, 420], persist: Some("status") })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::protocol::Status;
    use crate::state::LastTrigger;

    fn get(shared: &Shared, method: &str, path: &str) -> Response {
        answer(shared, &Request { method: method.into(), path: path.into(), query: String::new(), body: Vec::new() })
    }

    #[test]
    fn only_get_is_answered_on_the_page_s_routes() {
        let shared = Shared::default();
        for path in ["/", "/index.html", "/status.json", "/frame.png"] {
            let r = get(&shared, "POST", path);
            assert_eq!((r.status, r.header("Allow")), (405, Some("GET")), "{path}");
        }
        assert_eq!(get(&shared, "DELETE", "/nope").status, 404);
        assert_eq!(get(&shared, "GET", "/nope").status, 404);
        assert_eq!(get(&shared, "GET", "/status.json/").status, 404);
    }

    #[test]
    fn the_page_and_the_json_show_the_counts_and_are_never_cached() {
        let shared = Shared::default();
        shared.count(Status::Ok);
        shared.count(Status::Ok);
        shared.count(Status::CameraError);
        let html = get(&shared, "GET", "/");
        assert_eq!((html.status, html.content_type()), (200, "text/html; charset=utf-8"));
        assert_eq!(html.header("cache-control"), Some("no-store"));
        assert!(String::from_utf8(html.body).unwrap().contains("camplace serve"));
        let json = get(&shared, "GET", "/status.json");
        assert_eq!((json.status, json.content_type()), (200, "application/json"));
        let v: serde_json::Value = serde_json::from_slice(&json.body).unwrap();
        assert_eq!((v["counts"]["OK"].as_u64(), v["counts"]["CAMERA_ERROR"].as_u64()), (Some(2), Some(1)));
    }

    #[test]
    fn the_frame_is_the_last_left_shot_as_a_png_once_there_is_one() {
        let shared = Shared::default();
        assert_eq!(get(&shared, "GET", "/frame.png").status, 404);
        let image = camplace_config::GrayImage { width: 7, height: 3, data: (0..21u8).map(|v| v * 12).collect() };
        shared.lock().image = image.clone();
        let r = get(&shared, "GET", "/frame.png");
        assert_eq!((r.status, r.content_type()), (200, "image/png"));
        let decoded = camplace_config::decode_gray(&r.body).unwrap();
        assert_eq!(decoded, image);
    }

    /// The JSON of the page's inline 3D scene.
    fn scene_of(html: &str) -> Option<serde_json::Value> {
        let open = "<script type=\"application/json\" id=\"scene3d\">";
        let at = html.find(open)? + open.len();
        serde_json::from_str(&html[at..at + html[at..].find("</script>")?]).ok()
    }

    #[test]
    fn the_page_shows_the_scene_cloud_and_the_model_at_the_pose_in_3d() {
        let mut s = State {
            last: Some(LastTrigger::default()),
            cloud: vec![[1.0, 2.0, 3.0], [-4.5, 5.04, 6.06]],
            model_at_pose: vec![[7.0, 8.0, 9.0]],
            pose_accepted: true,
            ..State::default()
        };
        let scene = scene_of(&page(&s)).expect("a 3D scene on the page");
        let want = serde_json::json!([
            {"name": "scene", "colour": SCENE_CLOUD, "positions": [[1.0, 2.0, 3.0], [-4.5, 5.0, 6.1]]},
            {"name": "model", "colour": MODEL_ACCEPTED, "positions": [[7.0, 8.0, 9.0]]},
        ]);
        assert_eq!(scene["clouds"], want);
        // A refused pose is drawn in the refused colour; no pose, no model; no trigger, no view.
        s.pose_accepted = false;
        assert_eq!(scene_of(&page(&s)).unwrap()["clouds"][1]["colour"], MODEL_REFUSED);
        s.model_at_pose.clear();
        assert_eq!(scene_of(&page(&s)).unwrap()["clouds"].as_array().unwrap().len(), 1);
        s.last = None;
        assert!(scene_of(&page(&s)).is_none(), "a view before any trigger");
    }

    #[test]
    fn text_on_the_page_is_escaped() {
        assert_eq!(escape(r#"<b a="1">&</b>"#), "&lt;b a=&quot;1&quot;&gt;&amp;&lt;/b&gt;");
        let s = State { camera_error: Some("<script>alert(1)</script>".into()), ..State::default() };
        let html = page(&s);
        assert!(!html.contains("<script>alert"), "the camera's error went onto the page unescaped");
    }
}
