//! The server against real sockets on 127.0.0.1: every reply status, the body limits, and the
//! clients that would stall a naive server (endless heads, slow senders, pipeliners, clients
//! that never read), each test ending by itself.

use std::io::{Read, Write};
use std::net::{SocketAddr, TcpListener, TcpStream};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{mpsc, Arc};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use crate::{Limits, Request, Response, Server};

/// The most a test waits for a reply before it calls the server hung.
const HANG: Duration = Duration::from_secs(10);

struct Running {
    addr: SocketAddr,
    stop: Arc<AtomicBool>,
    connections: mpsc::Receiver<usize>,
    thread: Option<JoinHandle<()>>,
}

impl Running {
    /// Stops the server and returns how long it took to end.
    fn stop(mut self) -> Duration {
        let asked = Instant::now();
        self.stop.store(true, Ordering::SeqCst);
        let (done, ended) = mpsc::channel();
        let thread = self.thread.take().unwrap();
        std::thread::spawn(move || {
            let _ = thread.join();
            let _ = done.send(());
        });
        ended.recv_timeout(HANG).expect("the server ends once stopped");
        asked.elapsed()
    }

    /// The connections held after the latest turn.
    fn held(&self) -> usize {
        self.connections.try_iter().last().unwrap_or_else(|| self.connections.recv_timeout(HANG).unwrap())
    }

    /// Waits (a bounded number of turns) until the server holds `n` connections.
    fn wait_held(&self, n: usize) -> bool {
        (0..200).any(|_| {
            std::thread::sleep(Duration::from_millis(20));
            self.held() == n
        })
    }
}

impl Drop for Running {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// The test routes: `/` a greeting, `/big` `big` bytes, `POST /echo` (bodies of up to 64
/// bytes) its body, `/` by POST a 405, anything else a 404.
fn start(limits: Limits, big: usize) -> Running {
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let addr = listener.local_addr().unwrap();
    let stop = Arc::new(AtomicBool::new(false));
    let (report, connections) = mpsc::channel();
    let flag = stop.clone();
    let thread = std::thread::spawn(move || {
        let handler = move |r: &Request| match (r.method.as_str(), r.path.as_str()) {
            ("GET", "/") => Response::text(200, format!("hello {}", r.query)),
            ("GET", "/big") => Response::new(200, "application/octet-stream", vec![7u8; big]),
            ("POST", "/echo") => Response::new(200, "application/octet-stream", r.body.clone()),
            (_, "/" | "/big" | "/echo") => Response::text(405, "method not allowed"),
            _ => Response::text(404, "not found"),
        };
        let mut server = Server::new(listener, limits, handler).unwrap().with_body_limit(|h| {
            if h.method == "POST" && h.path == "/echo" {
                64
            } else {
                0
            }
        });
        while !flag.load(Ordering::SeqCst) {
            server.turn(crate::TURN);
            let _ = report.send(server.connections());
        }
    });
    Running { addr, stop, connections, thread: Some(thread) }
}

fn connect(addr: SocketAddr) -> TcpStream {
    let s = TcpStream::connect(addr).unwrap();
    s.set_read_timeout(Some(HANG)).unwrap();
    s.set_write_timeout(Some(HANG)).unwrap();
    s
}

/// Sends `request` and reads the answer to the server's close.
fn exchange(addr: SocketAddr, request: &[u8]) -> Vec<u8> {
    let mut s = connect(addr);
    s.write_all(request).unwrap();
    read_all(&mut s)
}

/// Reads to the close (a reset after some bytes counts as the end).
fn read_all(s: &mut TcpStream) -> Vec<u8> {
    let mut out = Vec::new();
    let mut chunk = [0u8; 65536];
    loop {
        match s.read(&mut chunk) {
            Ok(0) => return out,
            Ok(n) => out.extend_from_slice(&chunk[..n]),
            Err(e) if e.kind() == std::io::ErrorKind::ConnectionReset => return out,
            Err(e) => panic!("reading an answer: {e}"),
        }
    }
}

/// The status code and body of one answer; panics unless it is exactly one well-formed answer.
fn answer(bytes: &[u8]) -> (u16, Vec<u8>) {
    let text = String::from_utf8_lossy(bytes);
    assert!(text.starts_with("HTTP/1.1 "), "{text:?}");
    let end = bytes.windows(4).position(|w| w == b"\r\n\r\n").unwrap_or_else(|| panic!("no head end: {text:?}"));
    let head = &text[..end];
    let length: usize = head
        .lines()
        .find_map(|l| l.strip_prefix("Content-Length: "))
        .unwrap_or_else(|| panic!("no length: {head}"))
        .parse()
        .unwrap();
    assert!(head.contains("\r\nConnection: close"), "{head}");
    assert_eq!(bytes.len(), end + 4 + length, "one answer, its body whole: {head}");
    (head[9..12].parse().unwrap(), bytes[end + 4..].to_vec())
}

fn status(addr: SocketAddr, request: &[u8]) -> u16 {
    answer(&exchange(addr, request)).0
}

#[test]
fn every_reply_status_through_a_socket() {
    let s = start(Limits::default(), 10);
    let a = s.addr;
    assert_eq!(answer(&exchange(a, b"GET /?x=1 HTTP/1.1\r\nHost: h\r\n\r\n")), (200, b"hello x=1".to_vec()));
    assert_eq!(
        answer(&exchange(a, b"POST /echo HTTP/1.1\r\nContent-Length: 5\r\n\r\nabcde")),
        (200, b"abcde".to_vec())
    );
    assert_eq!(answer(&exchange(a, b"POST /echo HTTP/1.1\r\nContent-Length: 0\r\n\r\n")), (200, vec![]));
    assert_eq!(status(a, b"GET /nowhere HTTP/1.1\r\n\r\n"), 404);
    assert_eq!(status(a, b"POST / HTTP/1.1\r\n\r\n"), 405);
    assert_eq!(status(a, b"GET / HTTP/1.1\r\nContent-Length: x\r\n\r\n"), 400);
    assert_eq!(status(a, b"BREW / HTCPCP/1.0\r\n\r\n"), 400);
    assert_eq!(status(a, b"GET / HTTP/3.0\r\n\r\n"), 505);
    assert_eq!(status(a, b"POST /echo HTTP/1.1\r\nTransfer-Encoding: chunked\r\n\r\n5\r\nabcde\r\n0\r\n\r\n"), 501);
    let long = format!("GET /{} HTTP/1.1\r\n\r\n", "a".repeat(crate::MAX_REQUEST_LINE));
    assert_eq!(status(a, long.as_bytes()), 414);
    let many = format!("GET / HTTP/1.1\r\n{}\r\n", "X-A: b\r\n".repeat(2000));
    assert_eq!(status(a, many.as_bytes()), 431);
    assert!(s.stop() < HANG);
}

#[test]
fn bodies_are_bounded_by_their_route_before_they_are_read() {
    let s = start(Limits::default(), 10);
    let a = s.addr;
    // At the limit and one past it.
    let at = format!("POST /echo HTTP/1.1\r\nContent-Length: 64\r\n\r\n{}", "b".repeat(64));
    assert_eq!(answer(&exchange(a, at.as_bytes())), (200, vec![b'b'; 64]));
    let past = format!("POST /echo HTTP/1.1\r\nContent-Length: 65\r\n\r\n{}", "b".repeat(65));
    assert_eq!(status(a, past.as_bytes()), 413);
    // A GET route takes no body; announced lengths far past memory are refused at once,
    // without a byte of the body being sent.
    assert_eq!(status(a, b"GET / HTTP/1.1\r\nContent-Length: 1\r\n\r\nx"), 413);
    for huge in ["99999999999", "18446744073709551615", "18446744073709551616", "99999999999999999999999999"] {
        let r = format!("POST /echo HTTP/1.1\r\nContent-Length: {huge}\r\n\r\n");
        assert_eq!(status(a, r.as_bytes()), 413, "{huge}");
        let r = format!("GET / HTTP/1.1\r\nContent-Length: {huge}\r\n\r\n");
        assert_eq!(status(a, r.as_bytes()), 413, "{huge}");
    }
    // Still serving.
    assert_eq!(status(a, b"GET / HTTP/1.1\r\n\r\n"), 200);
}

#[test]
fn a_header_without_end_is_cut_at_the_head_limit_and_the_server_keeps_serving() {
    let s = start(Limits::default(), 10);
    let mut endless = connect(s.addr);
    endless.write_all(b"GET / HTTP/1.1\r\n").unwrap();
    let line = b"X-Endless: aaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaa\r\n";
    let mut sent = 0usize;
    // Streamed until the server closes (a write fails); 64 MB would mean it never did.
    let closed = (0..1_000_000).any(|_| {
        sent += line.len();
        endless.write_all(line).is_err()
    });
    assert!(closed, "the server read {sent} bytes of one head");
    assert!(sent < 16 << 20, "closed only after {sent} bytes");
    assert_eq!(status(s.addr, b"GET / HTTP/1.1\r\n\r\n"), 200);
    assert!(s.wait_held(0), "the endless client is let go");
}

#[test]
fn a_slow_client_holds_no_one_up() {
    // A deadline far past the hang guard: were the server waiting on the slow clients, the
    // third one's answer would never come in time.
    let limits = Limits { receive_timeout: Duration::from_secs(60), ..Limits::default() };
    let s = start(limits, 10);
    let mut slow = connect(s.addr);
    slow.write_all(b"GET / HTTP/1.1\r\nHost: x\r\n").unwrap();
    let mut slow_body = connect(s.addr);
    slow_body.write_all(b"POST /echo HTTP/1.1\r\nContent-Length: 10\r\n\r\nabc").unwrap();
    assert_eq!(status(s.addr, b"GET / HTTP/1.1\r\n\r\n"), 200);
    assert!(s.wait_held(2), "both slow clients still held");
}

#[test]
fn a_slow_client_gets_a_408_at_its_deadline() {
    let limits = Limits { receive_timeout: Duration::from_millis(400), ..Limits::default() };
    let s = start(limits, 10);
    let since = Instant::now();
    let mut slow = connect(s.addr);
    slow.write_all(b"GET / HTTP/1.1\r\nHost: x\r\n").unwrap();
    let mut slow_body = connect(s.addr);
    slow_body.write_all(b"POST /echo HTTP/1.1\r\nContent-Length: 10\r\n\r\nabc").unwrap();
    let silent = connect(s.addr);
    assert_eq!(answer(&read_all(&mut slow)).0, 408);
    assert_eq!(answer(&read_all(&mut slow_body)).0, 408);
    assert!(since.elapsed() >= Duration::from_millis(400), "not before the deadline");
    assert!(s.wait_held(0), "the silent one is let go too");
    drop(silent);
}

#[test]
fn a_pipelining_client_gets_one_answer_and_is_closed() {
    let s = start(Limits::default(), 10);
    let mut p = connect(s.addr);
    let many = "GET /?n=1 HTTP/1.1\r\n\r\nGET /?n=2 HTTP/1.1\r\n\r\n".repeat(50);
    p.write_all(many.as_bytes()).unwrap();
    assert_eq!(answer(&read_all(&mut p)), (200, b"hello n=1".to_vec()));
}

#[test]
fn a_client_that_never_reads_blocks_no_one() {
    // A send deadline far past the hang guard, as for the slow clients.
    let limits = Limits { send_timeout: Duration::from_secs(60), ..Limits::default() };
    // Far more than the sockets' buffers hold, so the answer waits on the client.
    let s = start(limits, 32 << 20);
    let mut idle = connect(s.addr);
    idle.write_all(b"GET /big HTTP/1.1\r\n\r\n").unwrap();
    let mut pipeliner = connect(s.addr);
    pipeliner.set_write_timeout(Some(Duration::from_millis(200))).unwrap();
    let request = b"GET /big HTTP/1.1\r\n\r\n".repeat(100);
    let _ = (0..100).try_for_each(|_| pipeliner.write_all(&request));
    assert_eq!(status(s.addr, b"GET / HTTP/1.1\r\n\r\n"), 200);
    assert!(s.wait_held(2), "both answers still wait on their clients");
}

#[test]
fn a_client_that_never_reads_is_dropped_at_its_send_deadline_with_one_cut_answer() {
    let limits = Limits { send_timeout: Duration::from_millis(500), ..Limits::default() };
    let s = start(limits, 32 << 20);
    let mut idle = connect(s.addr);
    idle.write_all(b"GET /big HTTP/1.1\r\n\r\nGET /big HTTP/1.1\r\n\r\n").unwrap();
    assert!(s.wait_held(1));
    assert!(s.wait_held(0), "dropped at its send deadline");
    let got = read_all(&mut idle);
    assert!(got.len() < 32 << 20 && got.starts_with(b"HTTP/1.1 200 OK\r\n"), "{} bytes", got.len());
}

#[test]
fn answers_past_the_buffer_bound_are_503_and_a_full_set_lets_a_newcomer_in() {
    let limits = Limits { max_buffered_bytes: 40 << 20, max_connections: 8, ..Limits::default() };
    let s = start(limits, 32 << 20);
    // 32 MiB that cannot leave (the client does not read, and loopback buffers hold a few
    // MiB): a second 32 MiB answer would pass 40 MiB buffered.
    let mut first = connect(s.addr);
    first.write_all(b"GET /big HTTP/1.1\r\n\r\n").unwrap();
    assert!(s.wait_held(1));
    assert_eq!(status(s.addr, b"GET /big HTTP/1.1\r\n\r\n"), 503);
    assert_eq!(status(s.addr, b"GET / HTTP/1.1\r\n\r\n"), 200, "small answers still fit");
    drop(first);
    // Thirty half-sent requests against eight slots: each newcomer still gets in.
    let held: Vec<TcpStream> = (0..30)
        .map(|_| {
            let mut c = connect(s.addr);
            c.write_all(b"GET / HT").unwrap();
            c
        })
        .collect();
    assert_eq!(status(s.addr, b"GET / HTTP/1.1\r\n\r\n"), 200);
    assert!(s.held() <= 8, "{} connections held", s.held());
    drop(held);
}

#[test]
fn the_stop_flag_ends_the_loop_within_a_turn_or_two_whatever_the_clients_do() {
    let s = start(Limits::default(), 32 << 20);
    let mut half = connect(s.addr);
    half.write_all(b"POST /echo HTTP/1.1\r\nContent-Length: 60\r\n\r\nabc").unwrap();
    let mut idle = connect(s.addr);
    idle.write_all(b"GET /big HTTP/1.1\r\n\r\n").unwrap();
    let _silent = connect(s.addr);
    assert!(s.wait_held(3));
    let took = s.stop();
    // The hang guard in `stop` is the bound; the figure is for the reader.
    println!("stopped in {took:?} with three clients holding on");
}
