//! The robot interface's sockets: the accepting thread and one thread per client up to a
//! cap (a client past it gets one `BUSY` line and is closed). Each client thread reads
//! request lines into a fixed buffer of [`MAX_REQUEST_BYTES`], answers each with one line,
//! and closes the connection after a line too long, after an idle spell, or when the
//! service stops.

use std::io::{ErrorKind as IoKind, Read, Write};
use std::net::{TcpListener, TcpStream};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use crossbeam_channel::{bounded, Sender, TrySendError};

use crate::protocol::{
    bad_request_line, busy_line, parse_request, BadRequest, Request, Status, MAX_REQUEST_BYTES, PROTOCOL,
};
use crate::state::Shared;
use crate::worker::Job;

/// How often a waiting thread looks at the stop flag.
const POLL: Duration = Duration::from_millis(50);

/// How long a trigger in the queue may wait for the stopping worker.
const STOP_GRACE: Duration = Duration::from_secs(10);

/// The limits of the robot interface.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ConnectionLimits {
    /// Clients served at once.
    pub max_clients: usize,
    /// A client that sends no complete line for this long is closed.
    pub idle: Duration,
    /// A reply that cannot be written within this is dropped with its connection.
    pub write: Duration,
}

impl Default for ConnectionLimits {
    fn default() -> Self {
        ConnectionLimits { max_clients: 8, idle: Duration::from_secs(60), write: Duration::from_secs(5) }
    }
}

/// What every client thread shares.
#[derive(Clone)]
pub(crate) struct Context {
    pub(crate) jobs: Sender<Job>,
    pub(crate) shared: Arc<Shared>,
    pub(crate) stop: Arc<AtomicBool>,
    pub(crate) limits: ConnectionLimits,
    pub(crate) active: Arc<AtomicUsize>,
    pub(crate) version: String,
}

/// Accepts clients until the stop flag is set.
pub(crate) fn accept(listener: TcpListener, cx: Context) {
    // Non-blocking so the stop flag is seen between clients.
    if listener.set_nonblocking(true).is_err() {
        return;
    }
    while !cx.stop.load(Ordering::SeqCst) {
        match listener.accept() {
            Ok((stream, _)) => {
                let _ = stream.set_nonblocking(false);
                let _ = stream.set_write_timeout(Some(cx.limits.write));
                if cx.active.load(Ordering::SeqCst) >= cx.limits.max_clients {
                    refuse(stream, &cx);
                    continue;
                }
                cx.active.fetch_add(1, Ordering::SeqCst);
                let client = cx.clone();
                let spawned = std::thread::Builder::new().name("camplace-client".into()).spawn(move || {
                    serve_client(stream, &client);
                    client.active.fetch_sub(1, Ordering::SeqCst);
                });
                if spawned.is_err() {
                    cx.active.fetch_sub(1, Ordering::SeqCst);
                }
            }
            Err(e) if e.kind() == IoKind::WouldBlock => std::thread::sleep(POLL / 5),
            Err(_) => std::thread::sleep(POLL),
        }
    }
}

fn refuse(mut stream: TcpStream, cx: &Context) {
    let _ = stream.write_all(format!("{}\n", busy_line("too-many-clients", None)).as_bytes());
    cx.shared.count(Status::Busy);
    // What the client already sent is read and dropped, so closing does not reset the
    // connection before it reads the line (a request sent later still may).
    let mut sink = [0u8; 512];
    if stream.set_nonblocking(true).is_ok() {
        for _ in 0..4 {
            if !matches!(stream.read(&mut sink), Ok(n) if n > 0) {
                break;
            }
        }
    }
    let _ = stream.shutdown(std::net::Shutdown::Write);
}

/// Reads lines and answers them until the client goes, misbehaves, idles or the service stops.
fn serve_client(mut stream: TcpStream, cx: &Context) {
    if stream.set_read_timeout(Some(POLL)).is_err() {
        return;
    }
    let _ = stream.set_nodelay(true);
    // One line plus its `\r\n`; never grows.
    let mut line = [0u8; MAX_REQUEST_BYTES + 2];
    let mut len = 0usize;
    let mut chunk = [0u8; 512];
    let mut last_line = Instant::now();
    loop {
        if cx.stop.load(Ordering::SeqCst) {
            return;
        }
        let n = match stream.read(&mut chunk) {
            Ok(0) => return,
            Ok(n) => n,
            Err(e) if matches!(e.kind(), IoKind::WouldBlock | IoKind::TimedOut | IoKind::Interrupted) => {
                if last_line.elapsed() > cx.limits.idle {
                    return;
                }
                continue;
            }
            Err(_) => return,
        };
        for &b in &chunk[..n] {
            if b == b'\n' {
                let reply = answer(&line[..len], cx);
                len = 0;
                last_line = Instant::now();
                if stream.write_all(reply.as_bytes()).and_then(|()| stream.write_all(b"\n")).is_err() {
                    return;
                }
                continue;
            }
            if len == line.len() {
                cx.shared.count(Status::BadRequest);
                let _ = stream.write_all(format!("{}\n", bad_request_line(BadRequest::TooLong)).as_bytes());
                let _ = stream.shutdown(std::net::Shutdown::Both);
                return;
            }
            line[len] = b;
            len += 1;
        }
    }
}

/// The reply line (without `\n`) to one request line.
fn answer(line: &[u8], cx: &Context) -> String {
    match parse_request(line) {
        Err(why) => {
            cx.shared.count(Status::BadRequest);
            bad_request_line(why)
        }
        Ok(Request::Ping) => "PONG".to_string(),
        Ok(Request::Version) => format!("VERSION {PROTOCOL} camplace={}", cx.version),
        Ok(Request::Status) => cx.shared.settled().status_line(),
        Ok(Request::Trigger { id }) => trigger(id, None, cx),
        // The worker holds the last pose's slots: it answers in turn with the triggers.
        Ok(Request::Slot { n }) => trigger(None, Some(n), cx),
    }
}

fn trigger(id: Option<String>, slot: Option<usize>, cx: &Context) -> String {
    let (reply, replied) = bounded(1);
    let job = Job { id: id.clone(), at: Instant::now(), reply, slot };
    match cx.jobs.try_send(job) {
        Ok(()) => {}
        Err(TrySendError::Full(_)) => {
            cx.shared.count(Status::Busy);
            return busy_line("queue-full", id.as_deref());
        }
        Err(TrySendError::Disconnected(_)) => {
            cx.shared.count(Status::Busy);
            return busy_line("stopping", id.as_deref());
        }
    }
    // The worker answers every job it takes, stopping or not; one queued as it ended is
    // told so after a grace period.
    let mut stopping_since: Option<Instant> = None;
    loop {
        match replied.recv_timeout(POLL) {
            Ok(line) => return line,
            Err(crossbeam_channel::RecvTimeoutError::Timeout) => {
                if cx.stop.load(Ordering::SeqCst)
                    && stopping_since.get_or_insert_with(Instant::now).elapsed() > STOP_GRACE
                {
                    break;
                }
            }
            Err(crossbeam_channel::RecvTimeoutError::Disconnected) => break,
        }
    }
    cx.shared.count(Status::Busy);
    busy_line("stopping", id.as_deref())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crossbeam_channel::Receiver;

    fn context(queue: usize) -> (Context, Receiver<Job>) {
        let (jobs, taken) = bounded(queue);
        let cx = Context {
            jobs,
            shared: Arc::new(Shared::default()),
            stop: Arc::new(AtomicBool::new(false)),
            limits: ConnectionLimits::default(),
            active: Arc::new(AtomicUsize::new(0)),
            version: "9.9.9".into(),
        };
        (cx, taken)
    }

    fn counts(cx: &Context) -> [u64; 6] {
        cx.shared.lock().counts
    }

    #[test]
    fn ping_version_and_status_are_answered_without_the_worker() {
        let (cx, _taken) = context(1);
        assert_eq!(answer(b"PING", &cx), "PONG");
        assert_eq!(answer(b"version\r", &cx), "VERSION CAMPLACE/1 camplace=9.9.9");
        assert!(answer(b"STATUS", &cx).starts_with("STATUS triggers=0 ok=0 "));
        assert_eq!(counts(&cx), [0; 6]);
    }

    #[test]
    fn a_refused_line_is_answered_and_counted_as_a_bad_request() {
        let (cx, _taken) = context(1);
        assert_eq!(answer(b"FIRE", &cx), "BAD_REQUEST unknown-command");
        assert_eq!(answer(b"TRIGGER a b", &cx), "BAD_REQUEST extra-words");
        assert_eq!(counts(&cx)[Status::BadRequest.index()], 2);
    }

    #[test]
    fn a_trigger_past_a_full_queue_is_busy_and_counted() {
        // A queue of one, already holding a trigger no worker takes.
        let (cx, _taken) = context(1);
        let (reply, _replied) = bounded(1);
        cx.jobs.try_send(Job { id: None, at: Instant::now(), reply, slot: None }).unwrap();
        assert_eq!(answer(b"TRIGGER 7", &cx), "BUSY queue-full id=7");
        assert_eq!(answer(b"SLOT 0", &cx), "BUSY queue-full");
        assert_eq!(counts(&cx)[Status::Busy.index()], 2);
    }

    #[test]
    fn a_trigger_after_the_worker_has_gone_is_told_the_service_is_stopping() {
        let (cx, taken) = context(1);
        drop(taken);
        assert_eq!(answer(b"TRIGGER", &cx), "BUSY stopping");
        assert_eq!(counts(&cx)[Status::Busy.index()], 1);
    }

    #[test]
    fn a_job_the_worker_drops_unanswered_is_told_stopping() {
        let (cx, taken) = context(1);
        let worker = std::thread::spawn(move || drop(taken.recv().unwrap()));
        assert_eq!(answer(b"TRIGGER q", &cx), "BUSY stopping id=q");
        worker.join().unwrap();
    }

    #[test]
    fn the_worker_s_reply_is_passed_on_and_slot_requests_reach_it_in_turn() {
        let (cx, taken) = context(2);
        let worker = std::thread::spawn(move || {
            for _ in 0..2 {
                let job = taken.recv().unwrap();
                let line = match job.slot {
                    Some(n) => format!("OK slot={n}"),
                    None => format!("OK id={}", job.id.unwrap_or_default()),
                };
                job.reply.send(line).unwrap();
            }
        });
        assert_eq!(answer(b"TRIGGER r2", &cx), "OK id=r2");
        assert_eq!(answer(b"SLOT 0003", &cx), "OK slot=3");
        worker.join().unwrap();
        // The worker counts what it answers; the connection counted nothing.
        assert_eq!(counts(&cx), [0; 6]);
    }
}
