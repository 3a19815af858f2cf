//! The status page of `camplace serve` and the review page of `camplace review --listen`
//! under hostile clients (huge announced bodies, a head without end, hundreds of half-sent
//! requests, a pipeliner that never reads): the process's memory and threads stay bounded,
//! the robot interface and the page keep answering others, and it still stops cleanly.

use std::io::{BufRead, BufReader, Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use crate::deploy::fixture;
use crate::served::{ask, parse_reply, replayed_dataset, Served};

/// The longest any one read waits before the test calls the process hung.
const HANG: Duration = Duration::from_secs(10);

/// The most memory (VmHWM) and threads the process may reach under the hostile set.
const MAX_PEAK_RSS_KB: u64 = 150 * 1024;
const MAX_THREADS: u64 = 64;

/// A copy of the fixture's rendered dataset and model in a folder of its own.
fn dataset() -> tempfile::TempDir {
    let f = fixture();
    let dir = tempfile::tempdir().unwrap();
    copy_tree(&f.root.join("data"), &dir.path().join("data"));
    std::fs::copy(f.root.join("tray.model"), dir.path().join("tray.model")).unwrap();
    dir
}

fn copy_tree(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for e in std::fs::read_dir(from).unwrap() {
        let e = e.unwrap();
        if e.file_type().unwrap().is_dir() {
            copy_tree(&e.path(), &to.join(e.file_name()));
        } else {
            std::fs::copy(e.path(), to.join(e.file_name())).unwrap();
        }
    }
}

/// `VmHWM` (kB) and `Threads` of process `pid`.
fn figures(pid: u32) -> (u64, u64) {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).unwrap();
    let field = |name: &str| -> u64 {
        let line = status.lines().find(|l| l.starts_with(name)).unwrap_or_else(|| panic!("no {name}: {status}"));
        line[name.len()..].trim().trim_end_matches(" kB").trim().parse().unwrap()
    };
    (field("VmHWM:"), field("Threads:"))
}

fn connect(addr: SocketAddr) -> TcpStream {
    let s = TcpStream::connect(addr).unwrap();
    s.set_read_timeout(Some(HANG)).unwrap();
    s.set_write_timeout(Some(HANG)).unwrap();
    s
}

/// One request to the page and its status code and body, with the time the answer took.
fn get(addr: SocketAddr, request: &str) -> (u16, Vec<u8>, Duration) {
    let since = Instant::now();
    let mut s = connect(addr);
    s.write_all(request.as_bytes()).unwrap();
    let mut out = Vec::new();
    s.read_to_end(&mut out).unwrap_or_else(|e| panic!("{request:?}: no answer within {HANG:?}: {e}"));
    let took = since.elapsed();
    let text = String::from_utf8_lossy(&out);
    assert!(text.starts_with("HTTP/1.1 "), "{request:?}: {text:?}");
    let end = out.windows(4).position(|w| w == b"\r\n\r\n").unwrap();
    (text[9..12].parse().unwrap(), out[end + 4..].to_vec(), took)
}

/// The hostile clients, held until dropped.
struct Hostile {
    held: Vec<TcpStream>,
    endless: JoinHandle<usize>,
    pipeliner: JoinHandle<(usize, TcpStream)>,
}

/// Opens the hostile set against the page at `addr`; `frame` is a path with a large answer.
fn hostile(addr: SocketAddr, frame: &str) -> Hostile {
    let mut held = Vec::new();
    for length in ["99999999999", "18446744073709551615"] {
        let mut s = connect(addr);
        s.write_all(format!("GET / HTTP/1.1\r\nContent-Length: {length}\r\n\r\n").as_bytes()).unwrap();
        held.push(s);
    }
    // A head without end, streamed until the server closes or 100 MB have gone.
    let endless = std::thread::spawn(move || {
        let mut s = connect(addr);
        let mut sent = 0usize;
        let line = b"X-Endless: aaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaa\r\n";
        let chunk: Vec<u8> = line.iter().copied().cycle().take(line.len() * 800).collect();
        if s.write_all(b"GET / HTTP/1.1\r\n").is_ok() {
            while sent < 100 << 20 && s.write_all(&chunk).is_ok() {
                sent += chunk.len();
            }
        }
        sent
    });
    // 300 requests sent in part and held open.
    for i in 0..300 {
        let mut s = connect(addr);
        s.write_all(format!("GET /?half={i} HTTP/1.1\r\nHost: x\r\n").as_bytes()).unwrap();
        held.push(s);
    }
    // A pipeliner asking for the frame over and over, never reading.
    let frame = frame.to_string();
    let pipeliner = std::thread::spawn(move || {
        let mut s = connect(addr);
        s.set_write_timeout(Some(Duration::from_secs(2))).unwrap();
        let requests = format!("GET {frame} HTTP/1.1\r\nHost: x\r\n\r\n").repeat(200);
        let mut sent = 0;
        while sent < 20_000 && s.write_all(requests.as_bytes()).is_ok() {
            sent += 200;
        }
        (sent, s)
    });
    Hostile { held, endless, pipeliner }
}

impl Hostile {
    /// Ends the set, returning the head bytes streamed before the server closed and the
    /// requests the pipeliner got in.
    fn end(self) -> (usize, usize) {
        let endless = self.endless.join().unwrap();
        let (pipelined, _stream) = self.pipeliner.join().unwrap();
        drop(self.held);
        (endless, pipelined)
    }
}

/// Asks the page `rounds` times while the hostile set holds on; returns each answer's time.
fn page_answers(addr: SocketAddr, request: &str, rounds: usize) -> Vec<Duration> {
    (0..rounds)
        .map(|_| {
            let (code, body, took) = get(addr, request);
            assert_eq!(code, 200, "{}", String::from_utf8_lossy(&body));
            std::thread::sleep(Duration::from_millis(200));
            took
        })
        .collect()
}

fn check_figures(pid: u32, what: &str) {
    let (peak_kb, threads) = figures(pid);
    println!("{what}: peak RSS {:.1} MB, {threads} threads", peak_kb as f64 / 1024.0);
    assert!(peak_kb <= MAX_PEAK_RSS_KB, "{what}: peak RSS {peak_kb} kB");
    assert!(threads <= MAX_THREADS, "{what}: {threads} threads");
}

#[test]
fn the_status_page_and_the_robot_interface_outlast_hostile_clients_and_serve_stops_on_sigterm() {
    let dir = dataset();
    let served = Served::start(dir.path(), &["--source", "dir:data", "--model", "tray.model"], "pages.log", true);
    let page = SocketAddr::from(([127, 0, 0, 1], served.status_port.unwrap()));
    let mut robot = served.connect();
    // A frame first, so that /frame.png is a real image.
    let (status, _, _) = parse_reply(&ask(&mut robot, "TRIGGER first"));
    assert_ne!(status, "BAD_REQUEST");
    assert_eq!(get(page, "GET /frame.png HTTP/1.1\r\n\r\n").0, 200);
    let set = hostile(page, "/frame.png");
    assert_eq!(ask(&mut robot, "PING"), "PONG");
    let (status, _, fields) = parse_reply(&ask(&mut robot, "TRIGGER during"));
    assert_ne!(status, "BAD_REQUEST");
    assert_eq!(fields.get("id").map(String::as_str), Some("during"));
    let latencies = page_answers(page, "GET /status.json HTTP/1.1\r\n\r\n", 5);
    println!("status page answered under the hostile set in {latencies:?}");
    let (body_code, body, _) = get(page, "GET / HTTP/1.1\r\n\r\n");
    assert_eq!(body_code, 200);
    assert!(String::from_utf8_lossy(&body).contains("camplace serve"));
    let pid = served.pid();
    check_figures(pid, "serve under the hostile set");
    let (endless, pipelined) = set.end();
    println!("head without end: {endless} bytes sent before the close; pipeliner: {pipelined} requests sent");
    assert!(endless < 100 << 20, "the head without end was read to its 100 MB");
    assert_eq!(ask(&mut robot, "PING"), "PONG");
    // SIGTERM while clients still hold the page: a new hostile set, not ended.
    let set = hostile(page, "/frame.png");
    check_figures(pid, "serve under a second hostile set");
    let since = Instant::now();
    let (done, ended) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let log = served.stop();
        let _ = done.send(log);
    });
    let log = ended.recv_timeout(HANG).expect("serve ends on SIGTERM");
    let took = since.elapsed();
    println!("serve ended {took:?} after SIGTERM with the hostile set holding on");
    assert!(!log.contains("panicked"), "{log}");
    drop(set);
}

/// `camplace review --listen 127.0.0.1:0` on `dataset`, and the page's address.
fn review(dir: &Path, dataset: &str) -> (Child, SocketAddr) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_camplace"))
        .args(["review", dataset, "--listen", "127.0.0.1:0", "--idle-exit", "120"])
        .current_dir(dir)
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .unwrap();
    let mut line = String::new();
    BufReader::new(child.stdout.as_mut().unwrap()).read_line(&mut line).unwrap();
    let url = line.split_whitespace().find(|w| w.starts_with("http://")).unwrap_or_else(|| panic!("{line}"));
    (child, url.trim_start_matches("http://").trim_end_matches('/').parse().unwrap())
}

#[test]
fn the_review_page_outlasts_hostile_clients_saves_marks_and_quits() {
    let dir = dataset();
    replayed_dataset(dir.path(), "data", &[]);
    let (mut child, page) = review(dir.path(), "data");
    let set = hostile(page, "/frames/0000/left.png");
    let latencies = page_answers(page, "GET / HTTP/1.1\r\n\r\n", 5);
    println!("review page answered under the hostile set in {latencies:?}");
    // A mark is saved; a body past the mark's limit is refused before it is read.
    let mark = r#"{"frame":"0001","mark":"wrong"}"#;
    let (code, body, _) = get(page, &format!("POST /label HTTP/1.1\r\nContent-Length: {}\r\n\r\n{mark}", mark.len()));
    assert_eq!((code, String::from_utf8_lossy(&body).as_ref()), (200, "saved"));
    let saved = std::fs::read_to_string(dir.path().join("data/labels.jsonl")).unwrap();
    let saved: Vec<serde_json::Value> = saved.lines().map(|l| serde_json::from_str(l).unwrap()).collect();
    assert_eq!(saved.len(), 1, "{saved:?}");
    assert_eq!((saved[0]["frame"].as_str(), saved[0]["mark"].as_str()), (Some("0001"), Some("wrong")));
    let (code, _, _) = get(page, "POST /label HTTP/1.1\r\nContent-Length: 99999999999\r\n\r\n");
    assert_eq!(code, 413);
    assert_eq!(get(page, "GET /frames/0000/left.png HTTP/1.1\r\n\r\n").0, 200);
    let pid = child.id();
    check_figures(pid, "review under the hostile set");
    let (endless, pipelined) = set.end();
    println!("head without end: {endless} bytes sent before the close; pipeliner: {pipelined} requests sent");
    assert!(endless < 100 << 20, "the head without end was read to its 100 MB");
    // The page closes the review while a second set holds on.
    let set = hostile(page, "/frames/0000/left.png");
    let since = Instant::now();
    assert_eq!(get(page, "POST /quit HTTP/1.1\r\n\r\n").0, 200);
    let (done, ended) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let status = child.wait().unwrap();
        let mut out = String::new();
        child.stdout.take().unwrap().read_to_string(&mut out).unwrap();
        let _ = done.send((status, out));
    });
    let (status, out) = ended.recv_timeout(HANG).expect("review ends on POST /quit");
    println!("review ended {:?} after POST /quit with the hostile set holding on", since.elapsed());
    assert!(status.success(), "{status}");
    assert!(out.contains("review closed from the page; 1 marks saved"), "{out}");
    drop(set);
}
