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
