//! The 3D view the pages share (the study's report, the review page, the status page): a
//! canvas, a reset button, a side panel the page fills (its legend), the scene as an inline
//! JSON block (`#scene3d`) and the viewer script, inlined too: no request leaves the page.
//! The scene's format is the script's (`view3d.js`) header: world mm, z up; solid parts
//! (each optionally placed by a pose), point clouds and markers.

/// The view's canvas.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ViewCanvas {
    /// Width and height, pixels.
    pub size: [u32; 2],
    /// A name under which the viewer's orbit, pan and zoom are kept in the browser's session,
    /// so a page that reloads itself keeps the view its reader turned to; `None` starts each
    /// load from the reset view. Letters, digits, `-` and `_` only.
    pub persist: Option<&'static str>,
}

/// The view's markup: the canvas, the reset button and `side` (HTML, the page's legend) beside
/// it, the scene `scene_json` (the scene's JSON text; empty for none yet: the page then draws
/// one with `window.camplaceView3d.show(scene)`) and the script.
pub fn view3d_html(scene_json: &str, side: &str, canvas: ViewCanvas) -> String {
    // "</" inside the JSON would end its script element early.
    let data = scene_json.replace("</", "<\\/");
    let persist = canvas
        .persist
        .filter(|p| p.bytes().all(|b| b.is_ascii_alphanumeric() || b == b'-' || b == b'_'))
        .map_or(String::new(), |p| format!(" data-persist=\"{p}\""));
    format!(
        "<div id=\"view3d\" style=\"display:flex;gap:1em;flex-wrap:wrap;align-items:flex-start\">\
<canvas id=\"view3d-canvas\" width=\"{}\" height=\"{}\"{persist} style=\"border:1px solid #bbb;cursor:grab\"></canvas>\
<div style=\"font-size:0.9em;max-width:330px\"><button id=\"view3d-reset\" type=\"button\">reset view</button>\
<p>Left drag turns, right (or shift) drag moves, the wheel zooms.</p>{side}</div></div>\n\
<style>.sw{{display:inline-block;width:14px;height:14px;margin-right:6px;vertical-align:middle;border:1px solid #666}}</style>\n\
<script type=\"application/json\" id=\"scene3d\">{data}</script>\n<script>{}</script>\n",
        canvas.size[0],
        canvas.size[1],
        include_str!("view3d.js")
    )
}

/// A legend's entry: a swatch of `colour` (`#rrggbb`) and `label` (escaped here).
pub fn legend_entry(colour: &str, label: &str) -> String {
    format!("<li><span class=\"sw\" style=\"background:{}\"></span>{}</li>", escape(colour), escape(label))
}

/// `text` safe inside HTML text and attribute values.
fn escape(text: &str) -> String {
    text.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;").replace('"', "&quot;")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_scene_cannot_end_its_script_and_a_bad_persist_name_is_left_out() {
        let html = view3d_html(
            r#"{"parts":[{"name":"</script><b>"}]}"#,
            "",
            ViewCanvas { size: [10, 20], persist: Some("a\" onload=\"x") },
        );
        let at = html.find("id=\"scene3d\">").unwrap();
        let block = &html[at..at + html[at..].find("</script>").unwrap()];
        assert!(block.contains(r#"<\/script><b>"#), "{block}");
        assert!(!html.contains("data-persist="), "an unsafe name went into the attribute");
        assert!(html.contains("width=\"10\" height=\"20\""));
        let kept = view3d_html("", "", ViewCanvas { size: [1, 1], persist: Some("status-page") });
        assert!(kept.contains(" data-persist=\"status-page\""));
        assert_eq!(
            legend_entry("#123456", "a<b"),
            "<li><span class=\"sw\" style=\"background:#123456\"></span>a&lt;b</li>"
        );
    }
}
