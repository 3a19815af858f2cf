//! `camplace serve` end to end, spoken to over raw `TcpStream`s as a robot would: the poses
//! of 50 triggers in a row equal `replay`'s, and every frame's in every pose format, hostile clients leave it answering,
//! the flight recorder keeps the refused frames for `replay`, the status page shows what was
//! replied in a browser, and the drift watch sees a rig turned 3° and not an unmoved one.

use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::path::Path;
use std::process::Command;
use std::time::Duration;

use camplace_config::{parse_pose, LengthUnit, PoseConvention, RobotPoseFormat};
use camplace_estimator::scoring::FrameRecord;

use crate::browser::{cloud, dom_attr, farthest_from, inline_scene, region, shows_colour};
use crate::camplace_cmd::{camplace, stderr};
use crate::deploy::fixture;
use crate::served::{ask, parse_reply, read, replayed_dataset, Served, TRIGGER_STATUSES};

/// Where a frame of a dataset made for a test comes from.
#[derive(Clone, Copy)]
enum Frame {
    /// That frame of the fixture's rendered dataset.
    Rendered(usize),
    /// The empty cell: the fixture's background images.
    Empty,
}

/// A dataset at `to` with the fixture dataset `from`'s rig and background and `frames` in
/// order (their images only).
fn copy_dataset(from: &Path, to: &Path, frames: &[Frame]) {
    std::fs::create_dir_all(to.join("background")).unwrap();
    std::fs::copy(from.join("rig.json"), to.join("rig.json")).unwrap();
    for side in ["left.png", "right.png"] {
        std::fs::copy(from.join("background").join(side), to.join("background").join(side)).unwrap();
    }
    for (i, frame) in frames.iter().enumerate() {
        let src = match frame {
            Frame::Rendered(k) => from.join("frames").join(format!("{k:04}")),
            Frame::Empty => from.join("background"),
        };
        let dst = to.join("frames").join(format!("{i:04}"));
        std::fs::create_dir_all(&dst).unwrap();
        for side in ["left.png", "right.png"] {
            std::fs::copy(src.join(side), dst.join(side)).unwrap();
        }
    }
}

/// Replays the fixture's dataset under `cell` and returns each frame's record by name.
fn replayed(root: &Path, cell: &str) -> std::collections::BTreeMap<String, FrameRecord> {
    replayed_dataset(root, "data", &["--cell", cell])
}

fn robot_cell(dir: &Path, name: &str, format: Option<RobotPoseFormat>) {
    let t = [[0.0, -1.0, 0.0, 450.0], [1.0, 0.0, 0.0, -120.0], [0.0, 0.0, 1.0, 35.0], [0.0, 0.0, 0.0, 1.0]];
    robot_cell_at(dir, name, &t, format);
}

/// A cell file `name` in `dir` with `[robot] T_robot_world = t` (and `pose_format`).
fn robot_cell_at(dir: &Path, name: &str, t: &[[f64; 4]; 4], format: Option<RobotPoseFormat>) {
    let rows: Vec<String> = t.iter().map(|r| format!("{r:?}")).collect();
    let mut text = format!("[robot]\nT_robot_world = [{}]\n", rows.join(", "));
    if let Some(f) = format {
        text.push_str(&format!("pose_format = \"{f}\"\n"));
    }
    std::fs::write(dir.join(name), text).unwrap();
}

#[test]
fn triggers_give_replays_poses_in_every_format_fifty_in_a_row_in_one() {
    let f = fixture();
    let dir = tempfile::tempdir().unwrap();
    copy_dataset(
        &f.root.join("data"),
        &dir.path().join("data"),
        &[Frame::Rendered(0), Frame::Rendered(1), Frame::Rendered(2), Frame::Rendered(3)],
    );
    std::fs::copy(f.root.join("tray.model"), dir.path().join("tray.model")).unwrap();
    robot_cell(dir.path(), "serve-robot.toml", None);
    let replay = replayed(dir.path(), "serve-robot.toml");
    let accepted: std::collections::BTreeSet<&String> =
        replay.iter().filter(|(_, r)| r.accepted()).map(|(f, _)| f).collect();
    assert!(accepted.len() >= 2, "replay accepts {accepted:?}");
    for (k, convention) in PoseConvention::ALL.into_iter().enumerate() {
        // Each convention once, in mm and m by turns.
        let unit = if k % 2 == 0 { LengthUnit::Mm } else { LengthUnit::M };
        let format = RobotPoseFormat { convention, unit };
        let cell = dir.path().join(format!("robot-{k}.toml"));
        robot_cell(dir.path(), cell.file_name().unwrap().to_str().unwrap(), Some(format));
        let served = Served::start(
            dir.path(),
            &["--source", "dir:data", "--model", "tray.model", "--cell", cell.to_str().unwrap()],
            &format!("serve-{k}.log"),
            false,
        );
        let mut robot = served.connect();
        // Fifty in a row on one connection in the first format; in each other, every frame
        // twice (the source goes round the four frames).
        let triggers = if k == 0 { 50 } else { 8 };
        let mut sent = std::collections::BTreeSet::new();
        for i in 0..triggers {
            let line = ask(&mut robot, &format!("TRIGGER t{i}"));
            let (status, reason, fields) = parse_reply(&line);
            assert_eq!(fields["id"], format!("t{i}"), "{line}");
            let frame = &fields["frame"];
            let want = &replay[frame];
            match status.as_str() {
                "OK" => {
                    assert!(want.accepted(), "{format}: {line} but replay: {:?}", want.verdict);
                    let pose = parse_pose(&fields["pose"], format).unwrap_or_else(|e| panic!("{format}: {line}: {e}"));
                    let truth = want.t_robot_tray.expect("replay gives an accepted pose in the robot's frame");
                    for r in 0..4 {
                        for c in 0..4 {
                            assert!(
                                (pose[r][c] - truth[r][c]).abs() <= 1e-9,
                                "{format} [{r}][{c}]: {line} vs {truth:?}"
                            );
                        }
                    }
                    sent.insert(frame.clone());
                }
                "NO_POSE" => assert!(!want.found, "{line} vs {:?}", want.verdict),
                "REJECTED" => {
                    let said = format!("rejected: {}", reason.unwrap().replace('-', " "));
                    assert_eq!(want.verdict.as_deref(), Some(said.as_str()), "{line}");
                }
                _ => panic!("{format}: {line}"),
            }
            let score: f32 = fields["score"].parse().unwrap();
            assert!((score - want.verify_score.unwrap()).abs() <= 5e-5, "{line}");
        }
        served.stop();
        // Not vacuous: every frame replay accepts was answered with its pose in this format.
        assert_eq!(sent.iter().collect::<std::collections::BTreeSet<_>>(), accepted, "{format}");
    }
}

/// `a · b` of two row-major 4 × 4 matrices, as written: no conversion to a rotation between.
fn product(a: &[[f64; 4]; 4], b: &[[f64; 4]; 4]) -> [[f64; 4]; 4] {
    std::array::from_fn(|r| std::array::from_fn(|c| (0..4).map(|k| a[r][k] * b[k][c]).sum()))
}

#[test]
fn a_robot_mounted_upside_down_is_handed_the_pose_in_its_frame_in_every_convention() {
    let f = fixture();
    let dir = tempfile::tempdir().unwrap();
    copy_dataset(&f.root.join("data"), &dir.path().join("data"), &[Frame::Rendered(0), Frame::Rendered(1)]);
    std::fs::copy(f.root.join("tray.model"), dir.path().join("tray.model")).unwrap();
    std::fs::write(dir.path().join("plain.toml"), "").unwrap();
    let replay = replayed(dir.path(), "plain.toml");
    // A robot hung upside down (Ry(180°)), and a half turn about the horizontal axis
    // (0.26, -0.97, 0): an iteration started at the identity cannot leave it for either.
    let n = (0.26f64 * 0.26 + 0.97 * 0.97).sqrt();
    let (x, y) = (0.26 / n, -0.97 / n);
    let half_turns = [
        [[-1.0, 0.0, 0.0, 450.0], [0.0, 1.0, 0.0, -120.0], [0.0, 0.0, -1.0, 1800.0], [0.0, 0.0, 0.0, 1.0]],
        // R = 2·n·nᵀ − I for the unit axis n.
        [
            [2.0 * x * x - 1.0, 2.0 * x * y, 0.0, -300.0],
            [2.0 * x * y, 2.0 * y * y - 1.0, 0.0, 250.0],
            [0.0, 0.0, -1.0, 1650.0],
            [0.0, 0.0, 0.0, 1.0],
        ],
    ];
    let mut oks = 0;
    for (h, t_robot_world) in half_turns.iter().enumerate() {
        for (k, convention) in PoseConvention::ALL.into_iter().enumerate() {
            let unit = if (h + k) % 2 == 0 { LengthUnit::Mm } else { LengthUnit::M };
            let format = RobotPoseFormat { convention, unit };
            let name = format!("upside-down-{h}-{k}.toml");
            robot_cell_at(dir.path(), &name, t_robot_world, Some(format));
            let served = Served::start(
                dir.path(),
                &["--source", "dir:data", "--model", "tray.model", "--cell", &name],
                &format!("upside-down-{h}-{k}.log"),
                false,
            );
            let mut robot = served.connect();
            for i in 0..4 {
                let line = ask(&mut robot, &format!("TRIGGER u{i}"));
                let (status, _, fields) = parse_reply(&line);
                let want = &replay[&fields["frame"]];
                if status != "OK" {
                    assert!(!want.accepted(), "{format}: {line} but replay accepted the frame");
                    continue;
                }
                let pose = parse_pose(&fields["pose"], format).unwrap_or_else(|e| panic!("{format}: {line}: {e}"));
                let truth = product(t_robot_world, &want.t_world_tray);
                for r in 0..4 {
                    for c in 0..4 {
                        assert!(
                            (pose[r][c] - truth[r][c]).abs() <= 1e-9,
                            "{format}, half turn {h} [{r}][{c}]: {line} vs T_robot_world · T_world_tray = {truth:?}"
                        );
                    }
                }
                oks += 1;
            }
            served.stop();
        }
    }
    // Not vacuous: both half turns in every convention were checked on poses.
    assert!(oks >= 2 * 7 * 2, "{oks} poses");
}

/// A connection answered `PONG`, tried again while the service says it has too many clients
/// (bounded: two minutes).
fn connect_when_free(served: &Served) -> TcpStream {
    for _ in 0..240 {
        let mut s = served.connect();
        let _ = s.write_all(b"PING\n");
        let mut reply = String::new();
        // A refused client may find its connection reset before it reads the BUSY line.
        let _ = BufReader::new(s.try_clone().unwrap()).read_line(&mut reply);
        if reply == "PONG\n" {
            return s;
        }
        assert!(reply.is_empty() || reply == "BUSY too-many-clients\n", "{reply:?}");
        std::thread::sleep(Duration::from_millis(500));
    }
    panic!("the service never took another client");
}

#[test]
fn hostile_clients_leave_the_service_answering() {
    let f = fixture();
    let dir = tempfile::tempdir().unwrap();
    let data = format!("dir:{}", f.root.join("data").display());
    let model = f.root.join("tray.model");
    let served =
        Served::start(dir.path(), &["--source", &data, "--model", model.to_str().unwrap()], "hostile.log", false);
    let port = served.port;
    let mut sent = 0;
    let check = |line: &str| {
        parse_reply(line);
    };
    // 50 clients at once, each one trigger: a reply each (a pose, or BUSY past the cap).
    let clients: Vec<_> = (0..50)
        .map(|i| {
            std::thread::spawn(move || {
                let mut s = TcpStream::connect(("127.0.0.1", port)).unwrap();
                s.set_read_timeout(Some(Duration::from_secs(60))).unwrap();
                let _ = s.write_all(format!("TRIGGER c{i}\n").as_bytes());
                let mut line = String::new();
                // A client past the cap may find its connection closed (reset) instead.
                let _ = BufReader::new(s).read_line(&mut line);
                line
            })
        })
        .collect();
    let mut answered = 0;
    for c in clients {
        let line = c.join().unwrap();
        if !line.is_empty() {
            assert!(line.ends_with('\n'), "{line:?}");
            check(line.trim_end());
            answered += 1;
        }
    }
    assert!(answered >= 8, "{answered} of 50 clients got a reply");
    sent += 50;
    // A 1 MB line: refused as too long, the connection closed.
    {
        let mut s = served.connect();
        let _ = s.write_all(&vec![b'A'; 1 << 20]);
        let mut reply = String::new();
        let _ = BufReader::new(s).read_line(&mut reply);
        assert!(reply.is_empty() || reply.trim_end() == "BAD_REQUEST too-long", "{reply:?}");
        sent += 1;
    }
    // Binary garbage, seeded: every line it makes gets a parsable reply or the connection closes.
    let mut state = 0x9E37_79B9_7F4A_7C15u64;
    for _ in 0..20 {
        let mut bytes = Vec::with_capacity(300);
        for _ in 0..300 {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            bytes.push((state >> 32) as u8);
        }
        let mut s = served.connect();
        s.set_read_timeout(Some(Duration::from_secs(5))).unwrap();
        let _ = s.write_all(&bytes);
        let _ = s.write_all(b"\n");
        let _ = s.shutdown(std::net::Shutdown::Write);
        let mut text = Vec::new();
        let _ = s.read_to_end(&mut text);
        for line in String::from_utf8(text).expect("ASCII replies").lines() {
            check(line);
        }
        sent += 1;
    }
    // A flood: 4 clients each sending 10 triggers in one write.
    let flood: Vec<_> = (0..4)
        .map(|_| {
            std::thread::spawn(move || {
                let mut s = TcpStream::connect(("127.0.0.1", port)).unwrap();
                s.set_read_timeout(Some(Duration::from_secs(60))).unwrap();
                s.write_all("TRIGGER\n".repeat(10).as_bytes()).unwrap();
                let r = BufReader::new(s);
                r.lines().take(10).map(Result::unwrap).collect::<Vec<_>>()
            })
        })
        .collect();
    for c in flood {
        let lines = c.join().unwrap();
        assert_eq!(lines.len(), 10);
        lines.iter().for_each(|l| check(l));
    }
    sent += 40;
    // Clients that leave mid-request and mid-reply.
    for i in 0..20 {
        let mut s = served.connect();
        let _ = s.write_all(if i % 2 == 0 { b"TRIG".as_slice() } else { b"TRIGGER gone\n".as_slice() });
        drop(s);
        sent += 1;
    }
    // Requests the protocol does not take, one connection (once the clients that left are
    // done: each keeps its place under the cap until its trigger is answered).
    let mut s = connect_when_free(&served);
    for (i, bad) in ["FIRE", "PING now", "TRIGGER a=b", "TRIGGER 123456789012345678901234567890123", "", "\u{7f}"]
        .iter()
        .cycle()
        .take(200 - sent - 20)
        .enumerate()
    {
        let reply = ask(&mut s, bad);
        assert!(reply.starts_with("BAD_REQUEST "), "{i}: {bad:?} -> {reply}");
        check(&reply);
    }
    // The rest: valid but unusual (lower case, CR LF).
    for _ in 0..20 {
        assert_eq!(ask(&mut s, "ping\r"), "PONG");
    }
    let mut fresh = connect_when_free(&served);
    let status = ask(&mut fresh, "STATUS");
    assert!(status.starts_with("STATUS triggers="), "{status}");
    let log = served.stop();
    // One log line per trigger that reached the worker, none about a panic.
    assert!(log.lines().filter(|l| l.starts_with("OK ") || l.starts_with("REJECTED ")).count() >= 5, "{log}");
}

/// A private copy of the fixture with `frames`, and the model; returns the folder.
fn dataset_of(frames: &[Frame]) -> tempfile::TempDir {
    let f = fixture();
    let dir = tempfile::tempdir().unwrap();
    copy_dataset(&f.root.join("data"), &dir.path().join("data"), frames);
    std::fs::copy(f.root.join("tray.model"), dir.path().join("tray.model")).unwrap();
    dir
}

/// The fixture's frames `replay` accepts.
fn accepted_frames() -> Vec<usize> {
    let dir = dataset_of(&[Frame::Rendered(0), Frame::Rendered(1), Frame::Rendered(2), Frame::Rendered(3)]);
    let records = replayed_dataset(dir.path(), "data", &[]);
    let accepted: Vec<usize> = records.values().filter(|r| r.accepted()).map(|r| r.frame.parse().unwrap()).collect();
    assert!(!accepted.is_empty(), "no frame of the fixture is accepted: {records:?}");
    accepted
}

#[test]
fn the_flight_recorder_keeps_the_refused_frames_for_replay() {
    let accepted = accepted_frames();
    // 20 frames, every fourth the empty cell.
    let frames: Vec<Frame> = (0..20)
        .map(|i| if i % 4 == 3 { Frame::Empty } else { Frame::Rendered(accepted[i % accepted.len()]) })
        .collect();
    let dir = dataset_of(&frames);
    let served = Served::start(
        dir.path(),
        &["--source", "dir:data", "--model", "tray.model", "--record", "kept"],
        "recorder.log",
        false,
    );
    let mut robot = served.connect();
    let mut refused = Vec::new();
    for i in 0..20 {
        let line = ask(&mut robot, &format!("TRIGGER {i}"));
        let (status, reason, fields) = parse_reply(&line);
        match status.as_str() {
            "OK" => {}
            "NO_POSE" => refused.push((fields["frame"].clone(), "rejected: no tray".to_string())),
            "REJECTED" => {
                refused.push((fields["frame"].clone(), format!("rejected: {}", reason.unwrap().replace('-', " "))))
            }
            _ => panic!("{line}"),
        }
    }
    let log = served.stop();
    assert_eq!(refused.len(), 5, "the 5 empty-cell frames and no other: {refused:?}\n{log}");
    for (frame, _) in &refused {
        assert_eq!(frame.parse::<usize>().unwrap() % 4, 3, "{refused:?}");
    }
    assert_eq!(log.matches(" recorded=").count(), 5, "{log}");
    // The kept dataset replays unchanged, with the verdicts the service gave.
    let kept = replayed_dataset(dir.path(), "kept", &[]);
    assert_eq!(kept.len(), 5, "{kept:?}");
    for (record, (frame, verdict)) in kept.values().zip(&refused) {
        assert_eq!(record.verdict.as_deref(), Some(verdict.as_str()), "kept {} from frame {frame}", record.frame);
    }
}

/// The body of an HTTP GET of `path` on `port`.
fn http_get(port: u16, path: &str) -> Vec<u8> {
    let mut s = TcpStream::connect(("127.0.0.1", port)).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(30))).unwrap();
    s.write_all(format!("GET {path} HTTP/1.0\r\nHost: 127.0.0.1\r\n\r\n").as_bytes()).unwrap();
    let mut all = Vec::new();
    s.read_to_end(&mut all).unwrap();
    let at = all.windows(4).position(|w| w == b"\r\n\r\n").expect("an HTTP response") + 4;
    assert!(all.starts_with(b"HTTP/1.") && all[9..12] == *b"200", "{}", String::from_utf8_lossy(&all[..at]));
    all[at..].to_vec()
}

#[test]
fn the_status_page_shows_the_last_frame_the_outline_the_counts_and_the_cloud_in_3d() {
    let accepted = accepted_frames();
    let dir = dataset_of(&[Frame::Empty, Frame::Rendered(accepted[0])]);
    let served = Served::start(dir.path(), &["--source", "dir:data", "--model", "tray.model"], "page.log", true);
    let mut robot = served.connect();
    let mut counts = std::collections::BTreeMap::<String, u64>::new();
    // Empty, tray, empty, tray: the last reply has a pose to outline.
    for i in 0..4 {
        let (status, _, _) = parse_reply(&ask(&mut robot, &format!("TRIGGER {i}")));
        *counts.entry(status).or_default() += 1;
    }
    for bad in ["HELLO", "TRIGGER !"] {
        let (status, _, _) = parse_reply(&ask(&mut robot, bad));
        *counts.entry(status).or_default() += 1;
    }
    assert_eq!(counts.get("OK"), Some(&2), "{counts:?}");
    let port = served.status_port.unwrap();
    // The page waits for the work after the last reply (outline, recorder, drift watch), so
    // it shows trigger 3, the last one answered.
    let json: serde_json::Value = serde_json::from_slice(&http_get(port, "/status.json")).unwrap();
    assert_eq!(json["last"]["id"], "3", "the page shows the last trigger: {json}");
    let png = http_get(port, "/frame.png");
    assert!(png.starts_with(b"\x89PNG\r\n\x1a\n"), "a PNG");
    let html = String::from_utf8(http_get(port, "/")).unwrap();
    assert!(html.contains("http-equiv=\"refresh\""), "the page refreshes itself");
    for status in TRIGGER_STATUSES {
        assert_eq!(json["counts"][status].as_u64(), Some(counts.get(status).copied().unwrap_or(0)), "{status}: {json}");
    }
    assert!(json["outline"].as_array().unwrap().len() >= 3, "{json}");
    let scene = inline_scene(&html);
    let (scene_points, model_points) = (cloud(&scene, "scene"), cloud(&scene, "model"));

    let Some(browser) = crate::browser::chromium("the status page's browser test") else {
        return;
    };
    // The page as served, with the server as its base and a probe that marks, once loaded,
    // whether the image loaded and how large the outline is drawn over it.
    let probe = "<script>window.addEventListener('load',()=>{const im=document.getElementById('frame');\
        const o=document.getElementById('outline').getBoundingClientRect();\
        const r=im.getBoundingClientRect();\
        document.body.dataset.loaded=(im.complete&&im.naturalWidth>0)?1:0;\
        document.body.dataset.outlineWidth=Math.round(o.width);\
        document.body.dataset.outlineInside=(o.left>=r.left-1&&o.right<=r.right+1&&o.top>=r.top-1&&o.bottom<=r.bottom+1)?1:0;});</script>";
    let page = html
        .replace("<head>", &format!("<head><base href=\"http://127.0.0.1:{port}/\">"))
        .replace("<meta http-equiv=\"refresh\" content=\"2\">", "")
        .replace("</body>", &format!("{probe}</body>"));
    let file = dir.path().join("page.html");
    std::fs::write(&file, &page).unwrap();
    let chromium = |extra: &[String], file: &Path| {
        Command::new(browser)
            .args(["--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars", "--window-size=1280,1000"])
            .arg("--virtual-time-budget=5000")
            .args(extra)
            .arg(format!("file://{}", file.display()))
            .output()
            .expect("chromium runs")
    };
    let o = chromium(&["--dump-dom".into()], &file);
    let dom = String::from_utf8_lossy(&o.stdout).into_owned();
    let attr = |name: &str| -> i64 {
        let at = dom.find(&format!("{name}=\"")).unwrap_or_else(|| panic!("no {name} on the page: {}", stderr(&o)));
        let v = &dom[at + name.len() + 2..];
        v[..v.find('"').unwrap()].parse().unwrap()
    };
    assert_eq!(attr("data-loaded"), 1, "the frame loads");
    assert!(attr("data-outline-width") >= 10, "the outline is drawn");
    assert_eq!(attr("data-outline-inside"), 1, "the outline lies over the frame");
    for status in TRIGGER_STATUSES {
        let cell = format!("id=\"count-{status}\">");
        let at = dom.find(&cell).unwrap_or_else(|| panic!("no count of {status}")) + cell.len();
        let shown: u64 = dom[at..dom[at..].find('<').unwrap() + at].parse().unwrap();
        assert_eq!(shown, counts.get(status).copied().unwrap_or(0), "{status}");
    }
    // The 3D view drew both clouds, all of their points.
    let drawn: serde_json::Value =
        serde_json::from_str(&dom_attr(&dom, "data-clouds").expect("the view's counts")).unwrap();
    assert_eq!(drawn, serde_json::json!({"scene": scene_points.len(), "model": model_points.len()}));
    // And as a screenshot, the view alone at the top: grey scene, green model (the pose sent).
    let top = dir.path().join("top.html");
    let style = "<style>#view3d{position:fixed;top:0;left:0;z-index:9;background:#fff}</style>";
    std::fs::write(&top, page.replace("</body>", &format!("{style}</body>"))).unwrap();
    let shot = dir.path().join("shot.png");
    chromium(&[format!("--screenshot={}", shot.display())], &top);
    let canvas = region(&shot, 2..638, 2..418);
    let drawn = canvas.iter().filter(|p| **p != [0xf4, 0xf6, 0xf8]).count();
    assert!(drawn > 500, "{drawn} pixels of the 3D view drawn");
    assert!(shows_colour(&canvas, "#6b6f76") && shows_colour(&canvas, "#2ca02c"), "the scene and the model are drawn");
    served.stop();

    // Against replay (the slow, obvious way) of the same frames: the model's points are the
    // model's own at the pose sent, the scene's those of the cloud the pose was sought in.
    let records = replayed_dataset(dir.path(), "data", &[]);
    let t = camplace_estimator::geometry::isometry_from_rows(&records["0001"].t_world_tray);
    let model = camplace_estimator::Model::load(&dir.path().join("tray.model")).unwrap();
    let placed: Vec<[f64; 3]> = model
        .views
        .iter()
        .flat_map(|v| v.points.iter())
        .chain(&model.feature_points)
        .map(|p| (t * p.cast::<f64>()).coords.into())
        .collect();
    assert!(model_points.len() >= 500, "{} model points", model_points.len());
    // Each coordinate is written to 0.1 mm: at most 0.087 mm from where it was.
    let off = farthest_from(&model_points, &placed);
    assert!(off < 0.09, "a drawn model point is {off} mm from the model at the pose");
    let written = camplace_config::read_cloud(&dir.path().join("data/frames/0001/scene.ply")).unwrap().points;
    assert!(written.len() < camplace_config::SCENE_CLOUD_POINTS, "scene.ply holds the whole cloud here");
    let written: Vec<[f64; 3]> = written.iter().map(|p| p.map(f64::from)).collect();
    let off = farthest_from(&scene_points, &written);
    assert!(off < 0.09, "a drawn scene point is {off} mm from the frame's scene cloud");
    // Thinned by a whole step: at least half of 3 000 (or all of a smaller cloud).
    assert!(scene_points.len() >= written.len().min(3000) / 2, "{} of {}", scene_points.len(), written.len());
}

/// `rows` (a rig.json camera's T_world_camera) turned by `deg` about the world x axis
/// through `centre`.
fn turned(rows: &serde_json::Value, deg: f64, centre: [f64; 3]) -> serde_json::Value {
    let (s, c) = deg.to_radians().sin_cos();
    let r = [[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]];
    let t: Vec<Vec<f64>> = (0..4).map(|i| (0..4).map(|j| rows[i][j].as_f64().unwrap()).collect()).collect();
    let mut out = t.clone();
    for i in 0..3 {
        for j in 0..4 {
            out[i][j] = (0..3).map(|k| r[i][k] * (t[k][j] - if j == 3 { centre[k] } else { 0.0 })).sum::<f64>()
                + if j == 3 { centre[i] } else { 0.0 };
        }
    }
    serde_json::to_value(out).unwrap()
}

/// Sends triggers until STATUS says the drift watch warns; returns how many it took.
fn triggers_until_warning(served: &Served, most: usize) -> Option<usize> {
    let mut robot = served.connect();
    for n in 1..=most {
        parse_reply(&ask(&mut robot, "TRIGGER"));
        let status = ask(&mut robot, "STATUS");
        assert!(status.contains(" drift="), "{status}");
        if status.contains(" drift=warning") {
            return Some(n);
        }
    }
    None
}

#[test]
fn the_drift_watch_sees_a_turned_rig_and_not_an_unmoved_one() {
    let f = fixture();
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // The rig turned 3° about the world x axis through its left camera; the scenes rendered
    // by it while the service believes the calibration.
    let mut rig: serde_json::Value = serde_json::from_str(&read(&f.root.join("data/rig.json"))).unwrap();
    let left = &rig["left"]["T_world_camera"];
    let centre = [0, 1, 2].map(|i| left[i][3].as_f64().unwrap());
    for camera in ["left", "right", "projector"] {
        if rig[camera].is_object() {
            rig[camera]["T_world_camera"] = turned(&rig[camera]["T_world_camera"], 3.0, centre);
        }
    }
    let o = camplace(d, &["init", "cell.toml"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let mut cell: toml::Table = read(&d.join("cell.toml")).parse().unwrap();
    cell.insert("rig".into(), toml::Value::try_from(rig).unwrap());
    std::fs::write(d.join("cell.toml"), toml::to_string(&cell).unwrap()).unwrap();
    let o =
        camplace(d, &["render", "--dataset", "--count", "3", "--cell", "cell.toml", "--seed", "1", "--out", "turned"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let nominal = f.root.join("data/rig.json");
    let model = f.root.join("tray.model");
    let served = Served::start(
        d,
        &["--source", "dir:turned", "--rig", nominal.to_str().unwrap(), "--model", model.to_str().unwrap()],
        "turned.log",
        false,
    );
    // docs/robot-interface.md: a move is reported by the third trigger after it.
    let n = triggers_until_warning(&served, 3);
    let log = served.stop();
    assert!(n.is_some(), "no warning in 3 triggers: {log}");

    // The unmoved rig: no warning over 200 triggers of the fixture's frames, cycled.
    let data = format!("dir:{}", f.root.join("data").display());
    let served = Served::start(d, &["--source", &data, "--model", model.to_str().unwrap()], "unmoved.log", false);
    assert_eq!(triggers_until_warning(&served, 200), None);
    served.stop();
}
