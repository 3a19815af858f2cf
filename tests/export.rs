//! `camplace export`: the .glb read back byte by byte (header, chunks, JSON), its nodes and
//! camera centres against the rig's own, and the Khronos glTF validator's verdict.

use std::path::{Path, PathBuf};
use std::process::Command;

use camplace_config::{Cell, Placement};
use serde_json::Value;

use crate::browser::{inline_scene, screenshot_pixels};
use crate::camplace_cmd::{assert_one_line_error, camplace, stderr};

/// A .glb's JSON and BIN chunks, after checking its header and chunk lengths.
pub fn read_glb(path: &Path) -> (Value, Vec<u8>) {
    let b = std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let u32_at = |i: usize| u32::from_le_bytes(b[i..i + 4].try_into().unwrap()) as usize;
    assert_eq!(&b[0..4], b"glTF", "magic");
    assert_eq!(u32_at(4), 2, "version");
    assert_eq!(u32_at(8), b.len(), "the header's length is the file's");
    let json_len = u32_at(12);
    assert_eq!(&b[16..20], b"JSON");
    assert_eq!(json_len % 4, 0, "the JSON chunk is padded to 4 bytes");
    let doc: Value = serde_json::from_slice(&b[20..20 + json_len]).expect("the JSON chunk parses");
    let bin_at = 20 + json_len;
    let bin_len = u32_at(bin_at);
    assert_eq!(&b[bin_at + 4..bin_at + 8], b"BIN\0");
    assert_eq!(bin_at + 8 + bin_len, b.len(), "the BIN chunk ends the file");
    assert_eq!(doc["buffers"][0]["byteLength"].as_u64().unwrap() as usize, bin_len);
    (doc, b[bin_at + 8..].to_vec())
}

/// A node's translation back in the world frame, mm (glTF: metres, y up; see docs/formats.md).
fn world_mm(node: &Value) -> [f64; 3] {
    let t = |i: usize| node["translation"][i].as_f64().unwrap();
    [1000.0 * t(0), -1000.0 * t(2), 1000.0 * t(1)]
}

/// The direction a glTF camera node looks (its −z turned by its rotation), in the world frame.
fn looks_along(node: &Value) -> [f64; 3] {
    let q: Vec<f64> = (0..4).map(|i| node["rotation"][i].as_f64().unwrap()).collect();
    let (x, y, z, w) = (q[0], q[1], q[2], q[3]);
    // The rotation matrix's third column, negated.
    let col = [2.0 * (x * z + w * y), 2.0 * (y * z - w * x), 1.0 - 2.0 * (x * x + y * y)];
    let g = [-col[0], -col[1], -col[2]];
    [g[0], -g[2], g[1]]
}

fn node<'a>(doc: &'a Value, name: &str) -> &'a Value {
    doc["nodes"].as_array().unwrap().iter().find(|n| n["name"] == name).unwrap_or_else(|| panic!("no node {name}"))
}

/// Checks the file's nodes and that each camera and the projector sits and looks where
/// `rig` (a rig.json's value) says, to 0.01 mm and 1e-6.
fn check_against_rig(doc: &Value, rig: &Value) {
    let names: Vec<&str> = doc["nodes"].as_array().unwrap().iter().map(|n| n["name"].as_str().unwrap()).collect();
    for want in ["table", "tray", "lamp", "camera_left", "camera_right", "projector"] {
        assert!(names.contains(&want), "{want} missing from {names:?}");
    }
    assert!(names.iter().any(|n| n.starts_with("item_")), "no item in {names:?}");
    for (node_name, key) in [("camera_left", "left"), ("camera_right", "right"), ("projector", "projector")] {
        let n = node(doc, node_name);
        let t = &rig[key]["T_world_camera"];
        let at = |r: usize, c: usize| t[r][c].as_f64().unwrap();
        let got = world_mm(n);
        for i in 0..3 {
            assert!((got[i] - at(i, 3)).abs() < 0.01, "{node_name} centre {got:?} against {t}");
        }
        let axis = looks_along(n);
        for i in 0..3 {
            assert!((axis[i] - at(i, 2)).abs() < 1e-6, "{node_name} looks along {axis:?} against {t}");
        }
    }
    assert_eq!(doc["cameras"].as_array().unwrap().len(), 2, "a glTF camera for each camera");
    assert!(node(doc, "camera_left")["camera"].is_u64());
}

/// The glTF validator's folder (node_modules/gltf-validator): CAMPLACE_GLTF_VALIDATOR, else
/// target/gltf/node_modules/gltf-validator; `None` (the test says why) when neither is there.
fn validator() -> Option<PathBuf> {
    let named = std::env::var_os("CAMPLACE_GLTF_VALIDATOR").map(PathBuf::from);
    let path = named
        .clone()
        .unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("target/gltf/node_modules/gltf-validator"));
    let has_node = Command::new("node").arg("--version").output().is_ok_and(|o| o.status.success());
    if has_node && path.join("package.json").is_file() {
        return Some(path);
    }
    assert!(named.is_none(), "CAMPLACE_GLTF_VALIDATOR={} but node or the validator is missing", path.display());
    eprintln!(
        "no node or no gltf-validator at {}: the glTF validation is skipped (npm install --prefix target/gltf \
         gltf-validator@2.0.0-dev.3.10 installs it, or set CAMPLACE_GLTF_VALIDATOR)",
        path.display()
    );
    None
}

/// The validator's issues of `file`: (errors, warnings, the report's messages).
fn validate(validator: &Path, file: &Path) -> (u64, u64, String) {
    let script = "const fs=require('fs');const v=require(process.argv[1]);\
        v.validateBytes(new Uint8Array(fs.readFileSync(process.argv[2]))).then(r=>{\
        console.log(JSON.stringify(r.issues));}).catch(e=>{console.error(String(e));process.exit(3);});";
    let o = Command::new("node")
        .args(["-e", script, &validator.display().to_string(), &file.display().to_string()])
        .output()
        .unwrap();
    assert!(o.status.success(), "the validator runs: {}", stderr(&o));
    let issues: Value = serde_json::from_slice(&o.stdout).expect("the validator's issues as JSON");
    (issues["numErrors"].as_u64().unwrap(), issues["numWarnings"].as_u64().unwrap(), issues["messages"].to_string())
}

#[test]
fn a_placement_and_a_rig_export_with_their_cameras_where_the_rig_has_them() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let p = "r=700,alpha=40,baseline=90,vergence=4,azimuth=25";
    // The rig a render at this placement writes, and the rig of the placement itself.
    let o = camplace(d, &["render", "--placement", p, "--out", "r"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let rig: Value = serde_json::from_slice(&std::fs::read(d.join("r/rig.json")).unwrap()).unwrap();
    let o = camplace(d, &["export", "--placement", p, "--scenario", "2", "--out", "placement.glb"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let (at_placement, _) = read_glb(&d.join("placement.glb"));
    // The placement's rig as planned (a render's rig.json carries the simulated calibration
    // error in its projector, which the plan has not).
    let placement: Placement = Cell::default().placement.with_overrides(p).unwrap();
    let planned = camplace_estimator::geometry::rig_for(&placement, &Cell::default().sensor);
    check_against_rig(&at_placement, &serde_json::to_value(planned.to_file()).unwrap());

    // A calibrated rig moved off the plan: its own cameras and projector are drawn.
    let mut moved = rig.clone();
    for key in ["left", "right", "projector"] {
        let v = moved[key]["T_world_camera"][0][3].as_f64().unwrap();
        moved[key]["T_world_camera"][0][3] = (v + 12.5).into();
    }
    std::fs::write(d.join("moved.json"), moved.to_string()).unwrap();
    let o = camplace(d, &["export", "--rig", "moved.json", "--out", "rig.glb"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let (from_rig, _) = read_glb(&d.join("rig.glb"));
    check_against_rig(&from_rig, &moved);
    // Without a projector in the file, one is drawn beside the cameras (where the rig's
    // as-built placement puts it), the cameras still the file's.
    let mut bare = moved.clone();
    bare["projector"] = Value::Null;
    std::fs::write(d.join("bare.json"), bare.to_string()).unwrap();
    let o = camplace(d, &["export", "--rig", "bare.json", "--out", "bare.glb"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let (bare_glb, _) = read_glb(&d.join("bare.glb"));
    let (a, b) = (world_mm(node(&bare_glb, "projector")), world_mm(node(&from_rig, "projector")));
    assert!((0..3).all(|i| (a[i] - b[i]).abs() < 50.0), "{a:?} far from the rig's own projector {b:?}");
    let (a, b) = (world_mm(node(&bare_glb, "camera_right")), world_mm(node(&from_rig, "camera_right")));
    assert!((0..3).all(|i| (a[i] - b[i]).abs() < 0.01), "{a:?} against {b:?}");

    let Some(validator) = validator() else { return };
    for file in ["placement.glb", "rig.glb"] {
        let (errors, warnings, messages) = validate(&validator, &d.join(file));
        eprintln!("{file}: {errors} errors, {warnings} warnings");
        assert_eq!(errors, 0, "{file}: {messages}");
    }
    // The check can fail: a position accessor whose min is wrong is an error to the validator.
    let bytes = std::fs::read(d.join("placement.glb")).unwrap();
    let json_len = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
    let text = String::from_utf8(bytes[20..20 + json_len].to_vec()).unwrap();
    let at = text.find("\"min\":[").unwrap() + 7;
    let mut broken = bytes.clone();
    // A digit of the first minimum turned into another keeps the length and the JSON valid.
    let digit = (at..at + 12).find(|&i| bytes[20 + i].is_ascii_digit() && bytes[20 + i] != b'0').unwrap();
    broken[20 + digit] = if bytes[20 + digit] == b'9' { b'1' } else { b'9' };
    std::fs::write(d.join("broken.glb"), &broken).unwrap();
    let (errors, _, messages) = validate(&validator, &d.join("broken.glb"));
    assert!(errors > 0, "a wrong accessor minimum passed the validator: {messages}");
}

#[test]
fn a_frames_cloud_is_exported_as_points_in_metres_y_up() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let o = camplace(d, &["render", "--dataset", "--count", "2", "--out", "data"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let points: Vec<[f32; 3]> = vec![[10.0, 20.0, 30.0], [-100.0, 50.0, 0.5], [0.0, 0.0, 0.0]];
    camplace_config::write_cloud(&d.join("data/frames/0001/cloud.ply"), &points, None).unwrap();
    let o = camplace(d, &["export", "--dataset", "data", "--frame", "1", "--out", "cloud.glb"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let (doc, bin) = read_glb(&d.join("cloud.glb"));
    let mesh = &doc["meshes"][node(&doc, "cloud")["mesh"].as_u64().unwrap() as usize];
    let prim = &mesh["primitives"][0];
    assert_eq!(prim["mode"], 0, "POINTS");
    let acc = &doc["accessors"][prim["attributes"]["POSITION"].as_u64().unwrap() as usize];
    assert_eq!(acc["count"], 3);
    let view = &doc["bufferViews"][acc["bufferView"].as_u64().unwrap() as usize];
    let off = view["byteOffset"].as_u64().unwrap() as usize;
    let f = |i: usize| f32::from_le_bytes(bin[off + 4 * i..off + 4 * i + 4].try_into().unwrap());
    for (k, p) in points.iter().enumerate() {
        let want = [p[0] / 1000.0, p[2] / 1000.0, -p[1] / 1000.0];
        for i in 0..3 {
            assert!((f(3 * k + i) - want[i]).abs() < 1e-7, "point {k}: {} against {want:?}", f(3 * k + i));
        }
    }
    if let Some(validator) = validator() {
        let (errors, _, messages) = validate(&validator, &d.join("cloud.glb"));
        assert_eq!(errors, 0, "{messages}");
    }

    // Bad input: one line naming what is wrong, exit 2.
    let bad = |args: &[&str], names: &[&str]| {
        let o = camplace(d, args);
        assert_one_line_error(o.status.code().unwrap(), &stderr(&o), names);
    };
    bad(
        &["export", "--dataset", "data", "--frame", "0", "--out", "x.glb"],
        &["frames/0000", "cloud.ply", "reconstruct"],
    );
    bad(&["export", "--dataset", "data", "--frame", "7", "--out", "x.glb"], &["--frame 7", "0 to 1"]);
    bad(&["export", "--out", "cell.gltf"], &["--out", ".glb"]);
    bad(&["export", "--rig", "nowhere.json", "--out", "x.glb"], &["nowhere.json"]);
    bad(&["export", "--study", "nowhere", "--out", "x.glb"], &["nowhere", "recommended.json"]);
    bad(&["export", "--placement", "r=5", "--out", "x.glb"], &["--placement", "r"]);
    assert!(!d.join("x.glb").exists(), "nothing written on bad input");
}

/// Every URL the page itself asked for, from Chromium's net log: the requests whose initiator
/// is the file page (an opaque origin, "null"); the browser's own background requests have
/// none and are left out.
fn page_requests(log: &Path) -> Vec<String> {
    let text = std::fs::read_to_string(log).unwrap_or_else(|e| panic!("{}: {e}", log.display()));
    let net: Value = serde_json::from_str(&text).expect("the net log parses");
    let events = net["events"].as_array().expect("the net log's events");
    let from_page: std::collections::HashSet<u64> = events
        .iter()
        .filter(|e| e["params"]["initiator"] == "null")
        .filter_map(|e| e["source"]["id"].as_u64())
        .collect();
    let mut urls: Vec<String> = events
        .iter()
        .filter(|e| e["source"]["id"].as_u64().is_some_and(|id| from_page.contains(&id)))
        .filter_map(|e| e["params"]["url"].as_str())
        .filter(|u| !u.starts_with("file:") && !u.starts_with("data:"))
        .map(str::to_string)
        .collect();
    urls.dedup();
    urls
}

#[test]
fn the_reports_3d_view_draws_the_recommended_rig_offline() {
    let Some(browser) = crate::browser::chromium("the 3D view's browser test") else {
        return;
    };
    let out = crate::own_cell::study();
    let html = std::fs::read_to_string(out.join("report.html")).unwrap();
    let rec: Value = serde_json::from_slice(&std::fs::read(out.join("recommended.json")).unwrap()).unwrap();
    let scene = inline_scene(&html);
    eprintln!("report.html: {} bytes, of which the 3D view's scene {} bytes", html.len(), scene.to_string().len());
    let dir = tempfile::tempdir().unwrap();
    let run = |page: &Path, extra: &[String]| {
        let mut args: Vec<String> =
            // No name resolves, and the browser's own background traffic is off: nothing
            // leaves the machine whatever the page asks for.
            [
                "--headless",
                "--no-sandbox",
                "--disable-gpu",
                "--hide-scrollbars",
                "--window-size=1280,800",
                "--disable-background-networking",
                "--disable-component-update",
                "--host-resolver-rules=MAP * ~NOTFOUND",
            ]
                .iter()
                .map(|s| s.to_string())
                .collect();
        args.extend_from_slice(extra);
        args.push(format!("file://{}", page.display()));
        Command::new(browser).args(&args).current_dir(dir.path()).output().expect("chromium runs")
    };

    // The view alone at the top of the window, as a screenshot: the canvas is drawn.
    let top = dir.path().join("top.html");
    let style = "<style>#view3d{position:fixed;top:0;left:0;z-index:9;background:#fff}</style>";
    std::fs::write(&top, html.replace("</body>", &format!("{style}</body>"))).unwrap();
    let shot = dir.path().join("shot.png");
    let o = run(&top, &["--virtual-time-budget=5000".into(), format!("--screenshot={}", shot.display())]);
    assert!(shot.is_file(), "no screenshot: {}", stderr(&o));
    let (px, width) = screenshot_pixels(&shot);
    let canvas: Vec<[u8; 3]> = px
        .iter()
        .enumerate()
        .filter(|(i, _)| i % width >= 2 && i % width < 820 && i / width >= 2 && i / width < 560)
        .map(|(_, p)| *p)
        .collect();
    let mut colours: Vec<[u8; 3]> = canvas.clone();
    colours.sort_unstable();
    colours.dedup();
    let background = [0xf4, 0xf6, 0xf8];
    let drawn = canvas.iter().filter(|p| **p != background).count();
    assert!(colours.len() > 20, "the canvas holds {} colours", colours.len());
    assert!(drawn > canvas.len() / 20, "{drawn} of {} canvas pixels drawn", canvas.len());
    // Every sensor's colour is somewhere in the picture (its frustum's edges).
    for part in ["camera_left", "camera_right", "projector"] {
        let c = scene["parts"].as_array().unwrap().iter().find(|p| p["name"] == part).unwrap()["colour"].clone();
        let hex = c.as_str().unwrap();
        let rgb: Vec<u8> = (0..3).map(|i| u8::from_str_radix(&hex[1 + 2 * i..3 + 2 * i], 16).unwrap()).collect();
        let near = |p: &[u8; 3]| p.iter().zip(&rgb).all(|(a, b)| a.abs_diff(*b) <= 12);
        assert!(canvas.iter().any(near), "{part}'s colour {hex} is nowhere on the canvas");
    }

    // The page as loaded, with the network logged: what it drew and where from.
    let page = dir.path().join("report.html");
    std::fs::write(&page, &html).unwrap();
    let log = dir.path().join("net.json");
    let o = run(
        &page,
        &["--virtual-time-budget=5000".into(), "--dump-dom".into(), format!("--log-net-log={}", log.display())],
    );
    let dom = String::from_utf8_lossy(&o.stdout).into_owned();
    let attr = |name: &str| -> String {
        let at = dom.find(&format!("{name}=\"")).unwrap_or_else(|| panic!("no {name} on the canvas: {}", stderr(&o)));
        let v = &dom[at + name.len() + 2..];
        v[..v.find('"').unwrap()].replace("&quot;", "\"")
    };
    assert!(attr("data-drawn").parse::<usize>().unwrap() > 10, "the view drew its scene");
    let apexes: Value = serde_json::from_str(&attr("data-apexes")).unwrap();
    for (part, key) in [("camera_left", "left_camera"), ("camera_right", "right_camera"), ("projector", "projector")] {
        let want = &rec["world_mm"][key];
        for i in 0..3 {
            let w = want[i].as_f64().unwrap();
            let drawn = apexes[part][i].as_f64().unwrap();
            let listed = scene["sensors"][part]["centre"][i].as_f64().unwrap();
            assert!((drawn - w).abs() < 0.01, "{part} drawn at {} against recommended.json {want}", apexes[part]);
            assert!((listed - w).abs() < 0.01, "{part} in the scene at {} against {want}", scene["sensors"][part]);
        }
    }
    let markers = scene["markers"].as_array().unwrap();
    assert!(markers.iter().filter(|m| m["from"] == "grid").count() >= 4, "the grid's placements are marked");
    let urls = page_requests(&log);
    assert!(urls.is_empty(), "the report asked the network for {urls:?}");
    // The log does show a request when there is one: an image from 127.0.0.1 (refused, port 9).
    let leaky = dir.path().join("leaky.html");
    std::fs::write(&leaky, html.replace("</body>", "<img src=\"http://127.0.0.1:9/x.png\"></body>")).unwrap();
    let leak_log = dir.path().join("leak.json");
    run(
        &leaky,
        &["--virtual-time-budget=3000".into(), "--dump-dom".into(), format!("--log-net-log={}", leak_log.display())],
    );
    let leaked = page_requests(&leak_log);
    assert!(leaked.iter().any(|u| u.starts_with("http://127.0.0.1:9/")), "the net log misses a request: {leaked:?}");

    // Time to interactive (the view drawn and its handlers set), in real time: reported only.
    let o = run(&page, &["--dump-dom".into()]);
    let dom = String::from_utf8_lossy(&o.stdout);
    if let Some(at) = dom.find("data-ready-ms=\"") {
        let v = &dom[at + 15..];
        eprintln!("the 3D view was interactive {} ms after navigation (headless chromium)", &v[..v.find('"').unwrap()]);
    }
}
