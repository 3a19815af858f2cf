//! The event loop: one thread, non-blocking sockets and poll(2) over a bounded set of
//! connections, one request per connection. Nothing a client sends or withholds is waited
//! for: a head is bounded before it is parsed, a body by its route before it is read, each
//! connection has a deadline to send its request and one to take its answer, and answers
//! are written as each socket permits.

use std::io::{ErrorKind, Read, Write};
use std::net::{Shutdown, SocketAddr, TcpListener, TcpStream};
use std::os::fd::AsRawFd;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use crate::head::{parse_request_head, Head, MAX_HEAD_BYTES};

/// The longest a turn of the loop waits, so a stop flag is seen within it.
pub const TURN: Duration = Duration::from_millis(100);

/// How long, and how many bytes, a connection whose answer is written is still read (and
/// the bytes dropped) so that its client sees the answer rather than a reset.
const LINGER: Duration = Duration::from_secs(2);
const LINGER_BYTES: usize = 64 << 10;

/// The bounds that no client can move.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Limits {
    /// Connections held at once; when full, the oldest one still sending its request is
    /// dropped for a newcomer.
    pub max_connections: usize,
    /// From accepting a connection to its request's last byte; then a 408.
    pub receive_timeout: Duration,
    /// From an answer's first byte to its last; then the connection is dropped.
    pub send_timeout: Duration,
    /// Answer bytes buffered for all connections together; past it a request gets a 503.
    pub max_buffered_bytes: usize,
}

impl Default for Limits {
    fn default() -> Limits {
        Limits {
            max_connections: 128,
            receive_timeout: Duration::from_secs(5),
            send_timeout: Duration::from_secs(10),
            max_buffered_bytes: 64 << 20,
        }
    }
}

/// A whole request, as the handler sees it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Request {
    /// The method as sent (`GET`, `POST`, ...).
    pub method: String,
    /// The target's path (from `/` up to `?` or `#`), not percent-decoded.
    pub path: String,
    /// The target's query (after `?`), empty when there is none.
    pub query: String,
    /// The body, within its route's limit.
    pub body: Vec<u8>,
}

/// An answer: a status, a content type, extra header fields and the body.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Response {
    /// The status code.
    pub status: u16,
    content_type: String,
    headers: Vec<(String, String)>,
    /// The body.
    pub body: Vec<u8>,
}

impl Response {
    /// An answer of `status` with `body` of type `content_type`.
    pub fn new(status: u16, content_type: &str, body: impl Into<Vec<u8>>) -> Response {
        Response { status, content_type: content_type.to_string(), headers: Vec::new(), body: body.into() }
    }

    /// A plain-text answer.
    pub fn text(status: u16, body: impl Into<String>) -> Response {
        Response::new(status, "text/plain; charset=utf-8", body.into())
    }

    /// The same answer with one more header field; a name or value that would break the
    /// head (a line end or a colon in the name) is left out.
    pub fn with_header(mut self, name: &str, value: &str) -> Response {
        let clean = |s: &str| !s.bytes().any(|b| b == b'\r' || b == b'\n');
        if !name.is_empty() && !name.contains(':') && clean(name) && clean(value) {
            self.headers.push((name.to_string(), value.to_string()));
        }
        self
    }

    /// The content type as given.
    pub fn content_type(&self) -> &str {
        &self.content_type
    }

    /// The value of the extra header field `name` (case-insensitive), when one was added.
    pub fn header(&self, name: &str) -> Option<&str> {
        self.headers.iter().find(|(n, _)| n.eq_ignore_ascii_case(name)).map(|(_, v)| v.as_str())
    }

    /// The bytes on the wire: always `Connection: close`, since one request is served per
    /// connection.
    fn encode(&self) -> Vec<u8> {
        let mut out = Vec::with_capacity(160 + self.body.len());
        let content_type = if self.content_type.bytes().any(|b| b == b'\r' || b == b'\n') {
            "application/octet-stream"
        } else {
            &self.content_type
        };
        out.extend_from_slice(
            format!(
                "HTTP/1.1 {} {}\r\nContent-Type: {content_type}\r\nContent-Length: {}\r\nConnection: close\r\n",
                self.status,
                reason(self.status),
                self.body.len()
            )
            .as_bytes(),
        );
        for (name, value) in &self.headers {
            out.extend_from_slice(format!("{name}: {value}\r\n").as_bytes());
        }
        out.extend_from_slice(b"\r\n");
        out.extend_from_slice(&self.body);
        out
    }
}

/// The reason phrase of a status code.
pub fn reason(status: u16) -> &'static str {
    match status {
        200 => "OK",
        400 => "Bad Request",
        404 => "Not Found",
        405 => "Method Not Allowed",
        408 => "Request Timeout",
        413 => "Content Too Large",
        414 => "URI Too Long",
        431 => "Request Header Fields Too Large",
        500 => "Internal Server Error",
        501 => "Not Implemented",
        503 => "Service Unavailable",
        505 => "HTTP Version Not Supported",
        _ => "",
    }
}

enum Phase {
    /// Receiving the head, in `Connection::head` (at most [`MAX_HEAD_BYTES`]).
    Head,
    /// Receiving a body of `length` bytes, its route having allowed that many.
    Body { head: Head, body: Vec<u8>, length: usize },
    /// Writing the answer.
    Answer { out: Vec<u8>, written: usize },
    /// Answer written and our side shut: the client's leftovers are read and dropped, up to
    /// `left` more bytes.
    Linger { left: usize },
    /// To be removed at the end of the turn.
    Closed,
}

struct Connection {
    stream: TcpStream,
    accepted: Instant,
    deadline: Instant,
    head: Vec<u8>,
    phase: Phase,
}

/// What reading a connection came to.
enum Progress {
    Wait,
    Complete(Request),
    Refuse(u16, &'static str),
    Close,
}

impl Connection {
    fn sending_request(&self) -> bool {
        matches!(self.phase, Phase::Head | Phase::Body { .. })
    }

    /// Reads what the socket has, within the head's and the body's bounds.
    fn read(&mut self, body_limit: &dyn Fn(&Head) -> u64) -> Progress {
        let mut chunk = [0u8; 4096];
        loop {
            let want = match &self.phase {
                Phase::Head => (MAX_HEAD_BYTES - self.head.len()).min(chunk.len()),
                Phase::Body { body, length, .. } => (length - body.len()).min(chunk.len()),
                Phase::Linger { left } if *left == 0 => return Progress::Close,
                Phase::Linger { left } => (*left).min(chunk.len()),
                Phase::Answer { .. } | Phase::Closed => return Progress::Wait,
            };
            if want == 0 {
                // The parser refuses a full head buffer and a full body completes at once.
                return Progress::Refuse(431, "request head too large");
            }
            let n = match self.stream.read(&mut chunk[..want]) {
                Ok(0) => return Progress::Close,
                Ok(n) => n,
                Err(e) if e.kind() == ErrorKind::WouldBlock => return Progress::Wait,
                Err(e) if e.kind() == ErrorKind::Interrupted => continue,
                Err(_) => return Progress::Close,
            };
            match &mut self.phase {
                Phase::Head => {
                    self.head.extend_from_slice(&chunk[..n]);
                    let (head, used) = match parse_request_head(&self.head) {
                        Ok(None) => continue,
                        Err(r) => return Progress::Refuse(r.status, r.reason),
                        Ok(Some(parsed)) => parsed,
                    };
                    // The route's limit is checked before the body gets a byte of memory.
                    let length = match usize::try_from(head.content_length) {
                        Ok(l) if head.content_length <= body_limit(&head) => l,
                        _ => return Progress::Refuse(413, "request body too large for this route"),
                    };
                    let mut body = Vec::with_capacity(length);
                    let have = &self.head[used..];
                    body.extend_from_slice(&have[..have.len().min(length)]);
                    self.head = Vec::new();
                    if body.len() == length {
                        return Progress::Complete(request(head, body));
                    }
                    self.phase = Phase::Body { head, body, length };
                }
                Phase::Body { body, length, .. } => {
                    body.extend_from_slice(&chunk[..n]);
                    if body.len() == *length {
                        let Phase::Body { head, body, .. } = std::mem::replace(&mut self.phase, Phase::Closed) else {
                            unreachable!("the phase was just matched as Body")
                        };
                        return Progress::Complete(request(head, body));
                    }
                }
                Phase::Linger { left } => *left -= n,
                Phase::Answer { .. } | Phase::Closed => {}
            }
        }
    }

    /// Writes what the socket takes; the connection lingers once the answer is out.
    fn write(&mut self) {
        let Phase::Answer { out, written } = &mut self.phase else { return };
        while *written < out.len() {
            match self.stream.write(&out[*written..]) {
                Ok(0) => {
                    self.phase = Phase::Closed;
                    return;
                }
                Ok(n) => *written += n,
                Err(e) if e.kind() == ErrorKind::WouldBlock => return,
                Err(e) if e.kind() == ErrorKind::Interrupted => {}
                Err(_) => {
                    self.phase = Phase::Closed;
                    return;
                }
            }
        }
        let _ = self.stream.shutdown(Shutdown::Write);
        self.phase = Phase::Linger { left: LINGER_BYTES };
        self.deadline = Instant::now() + LINGER;
    }

    fn pending(&self) -> usize {
        match &self.phase {
            Phase::Answer { out, written } => out.len() - written,
            _ => 0,
        }
    }
}

fn request(head: Head, body: Vec<u8>) -> Request {
    Request { method: head.method, path: head.path, query: head.query, body }
}

/// A bound HTTP server that answers each request with `handler`; it serves while its owner
/// turns it ([`Server::turn`], [`Server::run`]).
pub struct Server<H> {
    listener: TcpListener,
    limits: Limits,
    handler: H,
    body_limit: Box<dyn Fn(&Head) -> u64 + Send>,
    connections: Vec<Connection>,
    fds: Vec<libc::pollfd>,
    accept_paused_until: Option<Instant>,
}

impl<H: Fn(&Request) -> Response> Server<H> {
    /// Serves `listener` (made non-blocking) with `handler`; no request may have a body
    /// until [`Server::with_body_limit`] allows one.
    pub fn new(listener: TcpListener, limits: Limits, handler: H) -> std::io::Result<Server<H>> {
        listener.set_nonblocking(true)?;
        Ok(Server {
            listener,
            limits: Limits { max_connections: limits.max_connections.max(1), ..limits },
            handler,
            body_limit: Box::new(|_| 0),
            connections: Vec::new(),
            fds: Vec::new(),
            accept_paused_until: None,
        })
    }

    /// The most body bytes each request may send, by its head (method and path); a larger
    /// Content-Length is answered 413 before any of the body is read.
    pub fn with_body_limit(mut self, limit: impl Fn(&Head) -> u64 + Send + 'static) -> Server<H> {
        self.body_limit = Box::new(limit);
        self
    }

    /// The address served.
    pub fn local_addr(&self) -> std::io::Result<SocketAddr> {
        self.listener.local_addr()
    }

    /// Connections held now (for tests and logs).
    pub fn connections(&self) -> usize {
        self.connections.len()
    }

    /// Serves until `stop` is set (seen within [`TURN`]).
    pub fn run(&mut self, stop: &AtomicBool) {
        while !stop.load(Ordering::SeqCst) {
            self.turn(TURN);
        }
    }

    /// One turn of the loop: waits up to `wait` (at most [`TURN`]) for sockets to be ready,
    /// reads, answers, writes, accepts and enforces deadlines. Returns the requests the
    /// handler answered.
    pub fn turn(&mut self, wait: Duration) -> usize {
        let accepting = self.accept_paused_until.is_none_or(|t| Instant::now() >= t);
        self.poll(wait.min(TURN), accepting);
        let mut answered = 0;
        for i in 0..self.connections.len() {
            let revents = self.fds[i + 1].revents;
            if revents == 0 {
                continue;
            }
            let c = &mut self.connections[i];
            if revents & libc::POLLNVAL != 0 {
                c.phase = Phase::Closed;
                continue;
            }
            match c.phase {
                Phase::Answer { .. } => c.write(),
                _ => match c.read(self.body_limit.as_ref()) {
                    Progress::Wait => {}
                    Progress::Close => c.phase = Phase::Closed,
                    Progress::Refuse(status, why) => self.answer(i, Response::text(status, why)),
                    Progress::Complete(request) => {
                        answered += 1;
                        let response = (self.handler)(&request);
                        self.answer(i, response);
                    }
                },
            }
        }
        let now = Instant::now();
        for i in 0..self.connections.len() {
            if now < self.connections[i].deadline {
                continue;
            }
            if self.connections[i].sending_request() {
                // Best effort: a client that is still there reads why it was dropped.
                self.answer(i, Response::text(408, "request not received in time"));
            } else {
                self.connections[i].phase = Phase::Closed;
            }
        }
        if accepting && self.fds[0].revents != 0 {
            self.accept();
        }
        self.connections.retain(|c| !matches!(c.phase, Phase::Closed));
        answered
    }

    /// Writes the answers in hand for up to `within`, reading and accepting nothing more
    /// (for a server about to stop).
    pub fn finish(&mut self, within: Duration) {
        self.connections.retain(|c| matches!(c.phase, Phase::Answer { .. }));
        let until = Instant::now() + within;
        while !self.connections.is_empty() && Instant::now() < until {
            self.poll(TURN.min(until - Instant::now()), false);
            for c in &mut self.connections {
                c.write();
            }
            self.connections.retain(|c| matches!(c.phase, Phase::Answer { .. }));
        }
    }

    /// Waits for readiness; `self.fds[0]` is the listener, `self.fds[i + 1]` connection `i`.
    fn poll(&mut self, wait: Duration, accepting: bool) {
        self.fds.clear();
        let fd = |fd, events| libc::pollfd { fd, events, revents: 0 };
        self.fds.push(fd(self.listener.as_raw_fd(), if accepting { libc::POLLIN } else { 0 }));
        for c in &self.connections {
            let events = if matches!(c.phase, Phase::Answer { .. }) { libc::POLLOUT } else { libc::POLLIN };
            self.fds.push(fd(c.stream.as_raw_fd(), events));
        }
        let timeout = wait.as_millis().min(TURN.as_millis()) as libc::c_int;
        // SAFETY: `fds` is a live, initialised array of `fds.len()` pollfd structs that poll
        // only writes `revents` of, and every fd in it is owned by a socket alive for the call.
        let ready = unsafe { libc::poll(self.fds.as_mut_ptr(), self.fds.len() as libc::nfds_t, timeout) };
        if ready < 0 {
            // EINTR (a signal) or a transient failure: nothing is ready this turn.
            for f in &mut self.fds {
                f.revents = 0;
            }
        }
    }

    /// Turns connection `i` to writing `response` (a 503 when the answers buffered would
    /// pass their bound).
    fn answer(&mut self, i: usize, response: Response) {
        let mut out = response.encode();
        let buffered: usize = self.connections.iter().map(Connection::pending).sum();
        if buffered + out.len() > self.limits.max_buffered_bytes {
            out = Response::text(503, "too many answers waiting to be read").encode();
        }
        let c = &mut self.connections[i];
        c.head = Vec::new();
        c.phase = Phase::Answer { out, written: 0 };
        c.deadline = Instant::now() + self.limits.send_timeout;
        c.write();
    }

    /// Accepts what the listener holds; a full set drops its oldest connection still
    /// sending (or lingering) so that a newcomer always gets in.
    fn accept(&mut self) {
        // Bounded so that a flood of connections cannot keep one turn from ending.
        for _ in 0..256 {
            let stream = match self.listener.accept() {
                Ok((stream, _)) => stream,
                Err(e) if e.kind() == ErrorKind::WouldBlock => return,
                Err(e) if e.kind() == ErrorKind::Interrupted => continue,
                Err(_) => {
                    // Out of file descriptors or memory: poll would report the listener
                    // ready at once again, so accepting rests for a turn.
                    self.accept_paused_until = Some(Instant::now() + TURN);
                    return;
                }
            };
            if stream.set_nonblocking(true).is_err() {
                continue;
            }
            let live = self.connections.iter().filter(|c| !matches!(c.phase, Phase::Closed)).count();
            if live >= self.limits.max_connections {
                let lingering = self.connections.iter().position(|c| matches!(c.phase, Phase::Linger { .. }));
                let oldest = || {
                    (0..self.connections.len())
                        .filter(|&i| self.connections[i].sending_request())
                        .min_by_key(|&i| self.connections[i].accepted)
                };
                match lingering.or_else(oldest) {
                    Some(i) => self.connections[i].phase = Phase::Closed,
                    None => {
                        // Every slot is writing an answer: this one is told so, once.
                        let mut stream = stream;
                        let _ = stream.write(&Response::text(503, "too many connections").encode());
                        continue;
                    }
                }
            }
            let _ = stream.set_nodelay(true);
            let now = Instant::now();
            self.connections.push(Connection {
                stream,
                accepted: now,
                deadline: now + self.limits.receive_timeout,
                head: Vec::with_capacity(1024),
                phase: Phase::Head,
            });
        }
    }
}
