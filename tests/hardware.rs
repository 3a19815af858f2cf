//! The end-to-end tests whose outcome depends on the hardware features (`display`, `v4l`,
//! `dc1394`): the projector shown in step with a camera under a virtual X server (for
//! `project` and for `serve --project`), and a missing camera, feature or display named in
//! one line. They are a test binary of their own so that the build with every feature
//! (`cargo test -p camplace --all-features --test hardware`) compiles only them again, not
//! every end-to-end test.

mod camplace_cmd;
// The serve tests' harness: this binary uses part of it.
#[cfg(feature = "display")]
#[allow(dead_code)]
mod served;

use camplace_cmd::{camplace, stderr};

/// The paper's optimum placement.
#[cfg(feature = "display")]
const OPTIMUM: &str = "r=605,alpha=32,baseline=81,vergence=3.5";

/// A virtual X server for the projector's tests, killed when dropped.
#[cfg(feature = "display")]
struct Xvfb {
    child: std::process::Child,
    /// Its display name, ":N".
    display: String,
}

#[cfg(feature = "display")]
impl Xvfb {
    /// Starts Xvfb (1280x800) on the first free display number in `numbers`; `None` (after
    /// saying why) when there is none or Xvfb is not installed, a failure instead where
    /// `CAMPLACE_XVFB` is set (CI sets it where it installs Xvfb, so a skip there is seen).
    fn start(numbers: std::ops::Range<u32>) -> Option<Xvfb> {
        use std::path::Path;
        use std::process::{Command, Stdio};
        use std::time::{Duration, Instant};
        let free = |n: &u32| {
            !Path::new(&format!("/tmp/.X11-unix/X{n}")).exists() && !Path::new(&format!("/tmp/.X{n}-lock")).exists()
        };
        let Some(n) = numbers.clone().find(free) else {
            return Xvfb::skipped(&format!("no free X display number in {numbers:?}"));
        };
        let display = format!(":{n}");
        let Ok(child) = Command::new("Xvfb")
            .args([display.as_str(), "-screen", "0", "1280x800x24", "-nolisten", "tcp"])
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
        else {
            return Xvfb::skipped("Xvfb is not installed");
        };
        let start = Instant::now();
        while !Path::new(&format!("/tmp/.X11-unix/X{n}")).exists() && start.elapsed() < Duration::from_secs(10) {
            std::thread::sleep(Duration::from_millis(20));
        }
        Some(Xvfb { child, display })
    }

    /// Says why the display test is skipped, or fails it where the display was promised.
    fn skipped(why: &str) -> Option<Xvfb> {
        assert!(std::env::var_os("CAMPLACE_XVFB").is_none(), "CAMPLACE_XVFB is set but {why}");
        println!("skipped: {why}");
        None
    }
}

#[cfg(feature = "display")]
impl Drop for Xvfb {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// The contract for bad input: exit code 2 and one line on stderr naming each of `must_name`.
fn assert_one_line_error(o: &std::process::Output, must_name: &[&str]) {
    let code = o.status.code().unwrap_or(-1);
    camplace_cmd::assert_one_line_error(code, &stderr(o), must_name);
    assert!(!stderr(o).contains("panicked"), "{}", stderr(o));
}

#[test]
fn missing_cameras_are_clear_errors() {
    let dir = tempfile::tempdir().unwrap();
    let o = camplace(dir.path(), &["run", "--source", "v4l2:/dev/video0", "--model", "tray.model"]);
    assert_one_line_error(&o, &["v4l2:/dev/video0", "expected"]);
    let dev = "/dev/video-camplace-missing";
    let o = camplace(dir.path(), &["run", "--source", &format!("v4l2-sbs:{dev}"), "--model", "tray.model"]);
    assert_one_line_error(&o, &[if cfg!(feature = "v4l") { dev } else { "--features v4l" }]);
    let o = camplace(dir.path(), &["run", "--source", "dc1394", "--model", "tray.model"]);
    assert_one_line_error(&o, &[if cfg!(feature = "dc1394") { "dc1394" } else { "--features dc1394" }]);

    let o = camplace(dir.path(), &["devices"]);
    if camplace_hwio::list_devices().unwrap().is_empty() {
        assert_one_line_error(&o, &["no camera found"]);
    } else {
        assert!(o.status.success(), "{}", stderr(&o));
    }
}

#[cfg(not(feature = "display"))]
#[test]
fn project_without_the_display_feature_says_how_to_build_it() {
    let dir = tempfile::tempdir().unwrap();
    let o = camplace(dir.path(), &["project", "--method", "phase-12"]);
    assert_one_line_error(&o, &["`display`", "--features display"]);
}

/// `project --source dir:` under a virtual X server: the pattern is shown, then the source
/// read, and the frame lands in the dataset as the next frame folder with the source's
/// images. Skips (saying why) without Xvfb.
#[cfg(feature = "display")]
#[test]
fn project_captures_a_frame_in_step_under_xvfb() {
    use std::process::Command;

    let Some(xvfb) = Xvfb::start(300..400) else { return };
    let display = xvfb.display.clone();
    // A dataset of its own: the model of the shared fixture is not needed here.
    let out = tempfile::tempdir().unwrap();
    let o = camplace(out.path(), &["render", "--dataset", "--count", "1", "--placement", OPTIMUM, "--out", "data"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let rec = out.path().join("rec");
    let data = out.path().join("data");
    let run = || {
        Command::new(env!("CARGO_BIN_EXE_camplace"))
            .args(["project", "--method", "one-shot", "--settle-ms", "50", "--skip", "0"])
            .arg("--source")
            .arg(format!("dir:{}", data.display()))
            .arg("--out")
            .arg(&rec)
            .arg("--rig")
            .arg(data.join("rig.json"))
            .env("DISPLAY", &display)
            .output()
            .unwrap()
    };
    let (first, second) = (run(), run());
    drop(xvfb);
    for o in [&first, &second] {
        assert!(o.status.success(), "{}", stderr(o));
    }
    // Each call reads the recording from its start and adds the next frame folder.
    for frame in ["0000", "0001"] {
        for side in ["left.png", "right.png"] {
            let want = camplace_config::read_gray(&data.join("frames/0000").join(side)).unwrap();
            let got = camplace_config::read_gray(&rec.join("frames").join(frame).join(side)).unwrap();
            assert_eq!((got.width, got.height, got.data), (want.width, want.height, want.data), "{frame}/{side}");
        }
    }
    assert_eq!(std::fs::read(rec.join("rig.json")).unwrap(), std::fs::read(data.join("rig.json")).unwrap());
}

#[cfg(not(feature = "display"))]
#[test]
fn serve_project_without_the_display_feature_says_how_to_build_it() {
    let dir = tempfile::tempdir().unwrap();
    let o = camplace(
        dir.path(),
        &["serve", "--source", "dir:none", "--model", "none.model", "--listen", "127.0.0.1:0", "--project", "phase-12"],
    );
    let code = o.status.code().unwrap_or(-1);
    crate::camplace_cmd::assert_one_line_error(code, &stderr(&o), &["--project", "`display`", "--features display"]);
}

/// `serve --project phase-12` under a virtual X server: the 12 fringes are shown on the
/// projector window one by one and each is read in step from a one-image camera. The camera
/// here is a recording whose consecutive frames are the shots of a rendered phase-12 frame,
/// so the frame put together in step is that frame, and its reply must be `replay`'s of the
/// phase-12 recording. Skips (saying why) without Xvfb.
#[cfg(feature = "display")]
#[test]
fn projected_phase_12_triggers_give_replays_poses() {
    use crate::served::{ask, parse_reply, replayed_dataset, Served};
    use camplace_config::{parse_pose, LengthUnit, PoseConvention, RobotPoseFormat};
    use std::process::Command;

    let Some(xvfb) = Xvfb::start(400..500) else { return };
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let common = ["--method", "phase-12", "--placement", OPTIMUM, "--seed", "1"];
    let o = camplace(d, &[&["render", "--dataset", "--count", "1"][..], &common, &["--out", "data"]].concat());
    assert!(o.status.success(), "{}", stderr(&o));
    let o = camplace(d, &[&["model"][..], &common, &["--verify-scenes", "0", "--out", "tray.model"]].concat());
    assert!(o.status.success(), "{}", stderr(&o));
    let replay = replayed_dataset(d, "data", &[]);
    let want = &replay["0000"];
    assert!(want.found, "{want:?}");
    // The camera: shot i of frame 0000 as one-image frame i.
    let shots = d.join("camera");
    std::fs::create_dir_all(&shots).unwrap();
    std::fs::copy(d.join("data/rig.json"), shots.join("rig.json")).unwrap();
    for i in 0..12 {
        let to = shots.join("frames").join(format!("{i:04}"));
        std::fs::create_dir_all(&to).unwrap();
        for side in ["left", "right"] {
            let from = d.join("data/frames/0000").join(format!("{side}_{i:02}.png"));
            std::fs::copy(from, to.join(format!("{side}.png"))).unwrap();
        }
    }
    let mut command = Command::new(env!("CARGO_BIN_EXE_camplace"));
    command.env("DISPLAY", &xvfb.display);
    let served = Served::start_with(
        command,
        d,
        &[
            "--source",
            "dir:camera",
            "--model",
            "tray.model",
            "--background",
            "data/background",
            "--project",
            "phase-12",
            "--settle-ms",
            "5",
            "--skip",
            "0",
        ],
        "projected.log",
    );
    let mut robot = served.connect();
    // The camera recording ends after its 12th frame and is opened again from its start, in
    // step again: each trigger puts frame 0000 together anew.
    for k in 0..2 {
        let line = ask(&mut robot, &format!("TRIGGER p{k}"));
        let (status, reason, fields) = parse_reply(&line);
        assert_eq!(fields["frame"], "0000", "{line}");
        let score: f32 = fields["score"].parse().unwrap();
        assert!((score - want.verify_score.unwrap()).abs() <= 5e-5, "{line} vs {:?}", want.verify_score);
        match status.as_str() {
            "OK" => {
                let format = RobotPoseFormat { convention: PoseConvention::Matrix, unit: LengthUnit::Mm };
                let pose = parse_pose(&fields["pose"], format).unwrap();
                let truth = want.t_robot_tray.unwrap_or(want.t_world_tray);
                for r in 0..4 {
                    for c in 0..4 {
                        assert!((pose[r][c] - truth[r][c]).abs() <= 1e-9, "[{r}][{c}]: {line} vs {truth:?}");
                    }
                }
            }
            "REJECTED" => {
                let said = format!("rejected: {}", reason.unwrap().replace('-', " "));
                assert_eq!(want.verdict.as_deref(), Some(said.as_str()), "{line}");
            }
            _ => panic!("{line} vs replay's {want:?}"),
        }
    }
    served.stop();
}
