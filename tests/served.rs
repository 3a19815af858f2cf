//! A `camplace serve` started for a test and spoken to as a robot would (raw `TcpStream`s,
//! the documented reply lines), shared by the serve tests and the hardware tests.

use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::Duration;

use camplace_estimator::scoring::FrameRecord;

use crate::camplace_cmd::{camplace, stderr};

/// The statuses a trigger reply may start with.
pub(crate) const TRIGGER_STATUSES: [&str; 6] = ["OK", "NO_POSE", "REJECTED", "CAMERA_ERROR", "BUSY", "BAD_REQUEST"];

/// A running `camplace serve`, killed when dropped.
pub(crate) struct Served {
    child: Child,
    pub(crate) port: u16,
    pub(crate) status_port: Option<u16>,
    log: PathBuf,
}

impl Served {
    /// Starts `camplace serve` in `dir` with `args` on free loopback ports; its log goes to `log`.
    pub(crate) fn start(dir: &Path, args: &[&str], log: &str, status_page: bool) -> Served {
        let mut all = vec![];
        if status_page {
            all.extend(["--status", "127.0.0.1:0"]);
        }
        all.extend(args);
        Served::start_with(Command::new(env!("CARGO_BIN_EXE_camplace")), dir, &all, log)
    }

    /// Starts `command` (the camplace binary, with its environment set) as `serve` with
    /// `args` on a free loopback port (and the status page's when `args` ask for it).
    pub(crate) fn start_with(mut command: Command, dir: &Path, args: &[&str], log: &str) -> Served {
        let log = dir.join(log);
        let status_page = args.contains(&"--status");
        let mut all = vec!["serve", "--listen", "127.0.0.1:0"];
        all.extend(args);
        let mut child = command
            .args(&all)
            .current_dir(dir)
            .stdout(Stdio::piped())
            .stderr(std::fs::File::create(&log).unwrap())
            .spawn()
            .expect("camplace serve starts");
        let mut out = BufReader::new(child.stdout.take().unwrap());
        let port_of = |line: &str| -> u16 {
            let at = line.find("127.0.0.1:").unwrap_or_else(|| panic!("no address in {line:?}")) + 10;
            line[at..].split(|c: char| !c.is_ascii_digit()).next().unwrap().parse().unwrap()
        };
        let mut line = String::new();
        out.read_line(&mut line).unwrap();
        assert!(line.starts_with("robot interface CAMPLACE/1 on "), "{line:?}: {}", read(&log));
        let port = port_of(&line);
        let status_port = status_page.then(|| {
            let mut line = String::new();
            out.read_line(&mut line).unwrap();
            port_of(&line)
        });
        Served { child, port, status_port, log }
    }

    /// The process id, for its figures in /proc.
    pub(crate) fn pid(&self) -> u32 {
        self.child.id()
    }

    pub(crate) fn connect(&self) -> TcpStream {
        let s = TcpStream::connect(("127.0.0.1", self.port)).unwrap();
        s.set_read_timeout(Some(Duration::from_secs(60))).unwrap();
        s
    }

    /// Stops the service with SIGTERM and asserts it exits 0 having logged no panic.
    pub(crate) fn stop(mut self) -> String {
        let o = Command::new("kill").args(["-TERM", &self.child.id().to_string()]).output().unwrap();
        assert!(o.status.success());
        let status = self.child.wait().unwrap();
        let log = read(&self.log);
        assert!(status.success(), "serve ended with {status}: {log}");
        assert!(!log.contains("panicked"), "{log}");
        log
    }
}

impl Drop for Served {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

pub(crate) fn read(path: &Path) -> String {
    std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// One request, one reply line (without its line end).
pub(crate) fn ask(stream: &mut TcpStream, request: &str) -> String {
    stream.write_all(format!("{request}\n").as_bytes()).unwrap();
    let mut reply = Vec::new();
    let mut byte = [0u8; 1];
    loop {
        let n = stream.read(&mut byte).unwrap();
        assert!(n == 1, "closed before a reply to {request:?}");
        if byte[0] == b'\n' {
            break;
        }
        reply.push(byte[0]);
        assert!(reply.len() < 4096, "a reply line without end");
    }
    String::from_utf8(reply).expect("an ASCII reply")
}

/// A reply's status word, reason (REJECTED, BUSY, BAD_REQUEST) and key=value fields; panics
/// when the line does not follow docs/robot-interface.md.
pub(crate) fn parse_reply(line: &str) -> (String, Option<String>, std::collections::BTreeMap<String, String>) {
    let mut words = line.split(' ');
    let status = words.next().unwrap().to_string();
    assert!(TRIGGER_STATUSES.contains(&status.as_str()), "status of {line:?}");
    let mut reason = None;
    let mut fields = std::collections::BTreeMap::new();
    for (i, w) in words.enumerate() {
        match w.split_once('=') {
            Some((k, v)) => {
                assert!(!k.is_empty() && !v.is_empty(), "{line:?}");
                fields.insert(k.to_string(), v.to_string());
            }
            None => {
                assert!(i == 0 && ["REJECTED", "BUSY", "BAD_REQUEST"].contains(&status.as_str()), "{line:?}");
                reason = Some(w.to_string());
            }
        }
    }
    (status, reason, fields)
}

/// Replays `dataset` in `root` with `tray.model` and returns each frame's record by name.
pub(crate) fn replayed_dataset(
    root: &Path,
    dataset: &str,
    extra: &[&str],
) -> std::collections::BTreeMap<String, FrameRecord> {
    let mut args = vec!["replay", dataset, "--model", "tray.model"];
    args.extend(extra);
    let o = camplace(root, &args);
    assert!(o.status.success(), "{}", stderr(&o));
    read(&root.join(dataset).join("poses.jsonl"))
        .lines()
        .map(|l| serde_json::from_str::<FrameRecord>(l).unwrap())
        .map(|r| (r.frame.clone(), r))
        .collect()
}
