//! Output that cannot fail loudly: a closed standard output ends a command quietly with
//! exit 141, a full one with one line and exit 2, never a panic; files are written before
//! anything is printed about them.

use std::process::{Command, Stdio};

use crate::camplace_cmd::{assert_one_line_error, stderr};

fn camplace() -> Command {
    Command::new(env!("CARGO_BIN_EXE_camplace"))
}

#[test]
fn a_closed_pipe_ends_quietly_after_the_files_are_written() {
    let dir = tempfile::tempdir().unwrap();
    for args in [
        vec!["init", "cell.toml"],
        vec!["--help"],
        vec!["optimize", "--test-function", "branin", "--seed", "1", "--budget", "20"],
    ] {
        // The reader is gone before the command starts, so every write finds the pipe closed
        // whatever the scheduler does.
        let (reader, writer) = std::io::pipe().unwrap();
        drop(reader);
        let o = camplace()
            .args(&args)
            .current_dir(dir.path())
            .stdout(Stdio::from(writer))
            .stderr(Stdio::piped())
            .output()
            .unwrap();
        assert_eq!(o.status.code(), Some(141), "{args:?}: {}", stderr(&o));
        assert_eq!(stderr(&o), "", "{args:?}: quiet");
    }
    assert!(camplace_config::Cell::load(&dir.path().join("cell.toml")).is_ok(), "written before printing");
}

#[test]
fn a_full_output_is_one_line_and_exit_2_after_the_files_are_written() {
    let dir = tempfile::tempdir().unwrap();
    let Ok(full) = std::fs::OpenOptions::new().write(true).open("/dev/full") else { return };
    let o = camplace().args(["init", "cell.toml"]).current_dir(dir.path()).stdout(Stdio::from(full)).output().unwrap();
    assert_one_line_error(o.status.code().unwrap(), &stderr(&o), &["standard output", "No space"]);
    assert!(camplace_config::Cell::load(&dir.path().join("cell.toml")).is_ok(), "written before printing");
}
