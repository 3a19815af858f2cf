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
