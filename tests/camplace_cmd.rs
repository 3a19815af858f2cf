//! Running the `camplace` binary from tests.

use std::path::Path;
use std::process::{Command, Output};

/// Runs `camplace` with `args` in `dir`.
pub fn camplace(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_camplace")).args(args).current_dir(dir).output().expect("camplace runs")
}

/// stderr as text.
pub fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Asserts the contract for bad input: exit code 2 and one line on stderr naming each of
/// `must_name`.
pub fn assert_one_line_error(code: i32, err: &str, must_name: &[&str]) {
    assert_eq!(code, 2, "exit code, stderr: {err}");
    assert_eq!(err.trim_end().lines().count(), 1, "one line: {err}");
    for s in must_name {
        assert!(err.contains(s), "{s:?} missing from: {err}");
    }
}

/// A virtual X server for the projector's tests, killed when dropped.
#[cfg(feature = "display")]
pub struct Xvfb {
    child: std::process::Child,
    /// Its display name, ":N".
    pub display: String,
}

#[cfg(feature = "display")]
impl Xvfb {
    /// Starts Xvfb (1280x800) on the first free display number in `numbers`; `None` (after
    /// saying why) when there is none or Xvfb is not installed.
    pub fn start(numbers: std::ops::Range<u32>) -> Option<Xvfb> {
        use std::process::Stdio;
        use std::time::{Duration, Instant};
        let free = |n: &u32| {
            !Path::new(&format!("/tmp/.X11-unix/X{n}")).exists() && !Path::new(&format!("/tmp/.X{n}-lock")).exists()
        };
        let Some(n) = numbers.clone().find(free) else {
            println!("skipped: no free X display number in {numbers:?}");
            return None;
        };
        let display = format!(":{n}");
        let Ok(child) = Command::new("Xvfb")
            .args([display.as_str(), "-screen", "0", "1280x800x24", "-nolisten", "tcp"])
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
        else {
            println!("skipped: Xvfb is not installed");
            return None;
        };
        let start = Instant::now();
        while !Path::new(&format!("/tmp/.X11-unix/X{n}")).exists() && start.elapsed() < Duration::from_secs(10) {
            std::thread::sleep(Duration::from_millis(20));
        }
        Some(Xvfb { child, display })
    }
}

#[cfg(feature = "display")]
impl Drop for Xvfb {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}
