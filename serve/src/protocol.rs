//! The robot interface's lines (`CAMPLACE/1`, docs/robot-interface.md): one request line
//! parsed, one reply line formatted. No sockets here; `connections` owns those.

/// The protocol's name and version, as `VERSION` replies it.
pub const PROTOCOL: &str = "CAMPLACE/1";

/// The longest request line, bytes, without its line end; a longer one is refused and its
/// connection closed.
pub const MAX_REQUEST_BYTES: usize = 256;

/// The longest trigger id, characters.
pub const MAX_ID_CHARS: usize = 32;

/// One request of a robot.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Request {
    /// Capture, estimate, verify and reply with the pose; the id is echoed.
    Trigger { id: Option<String> },
    /// Answered `PONG` at once.
    Ping,
    /// The counts, latency and drift state on one line.
    Status,
    /// The protocol and program versions.
    Version,
    /// Slot `n`'s frame (0-based, the cell's slot order) under the last accepted pose.
    Slot { n: usize },
}

/// Why a request line was refused (`BAD_REQUEST <reason>`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BadRequest {
    /// Longer than [`MAX_REQUEST_BYTES`]; the connection is closed after the reply.
    TooLong,
    /// A byte outside printable ASCII.
    NotAscii,
    /// Nothing but blanks.
    Empty,
    /// A word the protocol does not know.
    UnknownCommand,
    /// A trigger id that is not 1 to 32 of `A-Z a-z 0-9 _ . -`.
    BadId,
    /// More words than the command takes.
    ExtraWords,
    /// `SLOT` without a slot number of 1 to 4 digits.
    BadSlot,
    /// A slot number past the tray's last slot.
    NoSuchSlot,
}

impl BadRequest {
    /// The reason word of the reply.
    pub fn as_str(self) -> &'static str {
        match self {
            BadRequest::TooLong => "too-long",
            BadRequest::NotAscii => "not-ascii",
            BadRequest::Empty => "empty",
            BadRequest::UnknownCommand => "unknown-command",
            BadRequest::BadId => "bad-id",
            BadRequest::ExtraWords => "extra-words",
            BadRequest::BadSlot => "bad-slot",
            BadRequest::NoSuchSlot => "no-such-slot",
        }
    }
}

/// Parses one request line (without its `\n`; a trailing `\r` is allowed). Commands are
/// case-insensitive.
pub fn parse_request(line: &[u8]) -> Result<Request, BadRequest> {
    let line = line.strip_suffix(b"\r").unwrap_or(line);
    if line.len() > MAX_REQUEST_BYTES {
        return Err(BadRequest::TooLong);
    }
    if line.iter().any(|&b| !(b == b' ' || b == b'\t' || b.is_ascii_graphic())) {
        return Err(BadRequest::NotAscii);
    }
    // Printable ASCII only, so this cannot fail.
    let text = std::str::from_utf8(line).map_err(|_| BadRequest::NotAscii)?;
    let mut words = text.split_ascii_whitespace();
    let Some(command) = words.next() else { return Err(BadRequest::Empty) };
    let rest: Vec<&str> = words.collect();
    let no_more = |r: Request| if rest.is_empty() { Ok(r) } else { Err(BadRequest::ExtraWords) };
    match command.to_ascii_uppercase().as_str() {
        "TRIGGER" => match rest[..] {
            [] => Ok(Request::Trigger { id: None }),
            [id] if valid_id(id) => Ok(Request::Trigger { id: Some(id.to_string()) }),
            [_] => Err(BadRequest::BadId),
            _ => Err(BadRequest::ExtraWords),
        },
        "PING" => no_more(Request::Ping),
        "STATUS" => no_more(Request::Status),
        "VERSION" => no_more(Request::Version),
        "SLOT" => match rest[..] {
            [n] if (1..=4).contains(&n.len()) && n.bytes().all(|b| b.is_ascii_digit()) => {
                n.parse().map(|n| Request::Slot { n }).map_err(|_| BadRequest::BadSlot)
            }
            [_] | [] => Err(BadRequest::BadSlot),
            _ => Err(BadRequest::ExtraWords),
        },
        _ => Err(BadRequest::UnknownCommand),
    }
}

fn valid_id(id: &str) -> bool {
    (1..=MAX_ID_CHARS).contains(&id.len()) && id.bytes().all(|b| b.is_ascii_alphanumeric() || b"_.-".contains(&b))
}

/// The status word a trigger (or a refused request) ends with; the status page counts them.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Status {
    /// A verified pose.
    Ok,
    /// Nothing in view looked like the tray.
    NoPose,
    /// A pose was found but the verification refused it.
    Rejected,
    /// No frame could be captured (or the frame could not be used).
    CameraError,
    /// Too many triggers waiting, or too many clients.
    Busy,
    /// A request line the protocol does not take.
    BadRequest,
}

impl Status {
    /// Every status, in the order the page and `STATUS` list them.
    pub const ALL: [Status; 6] =
        [Status::Ok, Status::NoPose, Status::Rejected, Status::CameraError, Status::Busy, Status::BadRequest];

    /// The word on the wire.
    pub fn as_str(self) -> &'static str {
        match self {
            Status::Ok => "OK",
            Status::NoPose => "NO_POSE",
            Status::Rejected => "REJECTED",
            Status::CameraError => "CAMERA_ERROR",
            Status::Busy => "BUSY",
            Status::BadRequest => "BAD_REQUEST",
        }
    }

    /// Its place in [`Status::ALL`].
    pub fn index(self) -> usize {
        Status::ALL.iter().position(|&s| s == self).unwrap_or(0)
    }
}

/// What one trigger ended with, ready to be written as its reply.
#[derive(Debug, Clone, PartialEq)]
pub struct TriggerReply {
    /// `Ok`, `NoPose`, `Rejected` or `CameraError`.
    pub status: Status,
    /// The verification's reason word for `Rejected` (`off-table`, `ambiguous`, `poor-fit`).
    pub reason: Option<&'static str>,
    /// The robot's id, echoed.
    pub id: Option<String>,
    /// The frame's name (`0007`); none after a camera error.
    pub frame: Option<String>,
    /// The pose in the cell's format, numbers separated by commas (only with `Ok`).
    pub pose: Option<String>,
    /// The verification's score in [0, 1].
    pub score: Option<f32>,
    /// From the trigger to the frame being in memory, ms.
    pub capture_ms: f64,
    /// The estimator on that frame, ms.
    pub compute_ms: f64,
    /// Each slot's state under the pose, one letter per slot (only with `Ok`, and a model
    /// that carries slots): see [`slot_letters`](camplace_estimator::pose::slot_letters).
    pub slots: Option<String>,
}

impl TriggerReply {
    /// The reply line, without its `\n`: the status (and reason), then `key=value` fields.
    pub fn line(&self) -> String {
        let mut s = String::with_capacity(256);
        s.push_str(self.status.as_str());
        if let Some(reason) = self.reason {
            s.push(' ');
            s.push_str(reason);
        }
        if let Some(id) = &self.id {
            s.push_str(" id=");
            s.push_str(id);
        }
        if let Some(frame) = &self.frame {
            s.push_str(" frame=");
            s.push_str(frame);
        }
        if let Some(pose) = &self.pose {
            s.push_str(" pose=");
            s.push_str(pose);
        }
        if let Some(score) = self.score {
            s.push_str(&format!(" score={score:.4}"));
        }
        s.push_str(&format!(" capture_ms={:.1} compute_ms={:.1}", self.capture_ms, self.compute_ms));
        // Last, so a client that reads the fields before it by position still finds them.
        if let Some(slots) = &self.slots {
            s.push_str(" slots=");
            s.push_str(slots);
        }
        s
    }
}

/// The reply to `SLOT n`: the slot's state and its frame in the robot's format after an
/// accepted pose (`state` as `SlotState::as_str`, `askew` 0 or 1, `frame` the trigger's).
pub fn slot_line(n: usize, state: &str, askew: bool, frame: &str, pose: &str) -> String {
    format!("{} slot={n} state={state} askew={} frame={frame} pose={pose}", Status::Ok.as_str(), u8::from(askew))
}

/// The reply to `SLOT n` when the last trigger gave no accepted pose (or the model carries
/// no slots): there is no frame to give.
pub fn slot_without_pose_line(n: usize) -> String {
    format!("{} slot={n}", Status::NoPose.as_str())
}

/// The reply to a refused request.
pub fn bad_request_line(why: BadRequest) -> String {
    format!("{} {}", Status::BadRequest.as_str(), why.as_str())
}

/// The reply when the service cannot take a trigger or a client now.
pub fn busy_line(why: &str, id: Option<&str>) -> String {
    match id {
        Some(id) => format!("{} {why} id={id}", Status::Busy.as_str()),
        None => format!("{} {why}", Status::Busy.as_str()),
    }
}

/// The reason word of a verdict that refused a found pose.
pub fn rejected_reason(verdict: camplace_estimator::pose::Verdict) -> &'static str {
    use camplace_estimator::pose::Verdict;
    match verdict {
        Verdict::Accepted => "accepted",
        Verdict::NoTray => "no-tray",
        Verdict::OffTable => "off-table",
        Verdict::Ambiguous => "ambiguous",
        Verdict::PoorFit => "poor-fit",
        Verdict::SeenThrough => "seen-through",
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn requests_parse_and_bad_ones_say_why() {
        assert_eq!(parse_request(b"TRIGGER"), Ok(Request::Trigger { id: None }));
        assert_eq!(parse_request(b"trigger 17\r"), Ok(Request::Trigger { id: Some("17".into()) }));
        assert_eq!(parse_request(b"  PING  "), Ok(Request::Ping));
        assert_eq!(parse_request(b"STATUS"), Ok(Request::Status));
        assert_eq!(parse_request(b"VERSION"), Ok(Request::Version));
        assert_eq!(parse_request(b""), Err(BadRequest::Empty));
        assert_eq!(parse_request(b"FIRE"), Err(BadRequest::UnknownCommand));
        assert_eq!(parse_request(b"PING now"), Err(BadRequest::ExtraWords));
        assert_eq!(parse_request(b"TRIGGER a b"), Err(BadRequest::ExtraWords));
        assert_eq!(parse_request(b"TRIGGER a=b"), Err(BadRequest::BadId));
        assert_eq!(
            parse_request(&[b'T'; 40].iter().chain(b" ").chain(&[b'1'; 33]).copied().collect::<Vec<_>>()),
            Err(BadRequest::UnknownCommand)
        );
        assert_eq!(parse_request(format!("TRIGGER {}", "1".repeat(33)).as_bytes()), Err(BadRequest::BadId));
        assert_eq!(parse_request(b"PING\x00"), Err(BadRequest::NotAscii));
        assert_eq!(parse_request("TRIGGER é".as_bytes()), Err(BadRequest::NotAscii));
        assert_eq!(parse_request(&[b'P'; MAX_REQUEST_BYTES + 1]), Err(BadRequest::TooLong));
        assert_eq!(parse_request(b"SLOT 3"), Ok(Request::Slot { n: 3 }));
        assert_eq!(parse_request(b"slot 0012\r"), Ok(Request::Slot { n: 12 }));
        assert_eq!(parse_request(b"SLOT"), Err(BadRequest::BadSlot));
        assert_eq!(parse_request(b"SLOT -1"), Err(BadRequest::BadSlot));
        assert_eq!(parse_request(b"SLOT 12345"), Err(BadRequest::BadSlot));
        assert_eq!(parse_request(b"SLOT 1 2"), Err(BadRequest::ExtraWords));
    }

    #[test]
    fn a_reply_is_one_line_of_words_and_key_values() {
        let r = TriggerReply {
            status: Status::Rejected,
            reason: Some("poor-fit"),
            id: Some("9".into()),
            frame: Some("0003".into()),
            pose: None,
            score: Some(0.25),
            capture_ms: 1.25,
            compute_ms: 40.0,
            slots: None,
        };
        assert_eq!(r.line(), "REJECTED poor-fit id=9 frame=0003 score=0.2500 capture_ms=1.2 compute_ms=40.0");
        let ok = TriggerReply { status: Status::Ok, reason: None, pose: Some("1,2,3,0,0,0".into()), ..r };
        assert_eq!(ok.line(), "OK id=9 frame=0003 pose=1,2,3,0,0,0 score=0.2500 capture_ms=1.2 compute_ms=40.0");
        let slots = TriggerReply { slots: Some("FA?E".into()), ..ok };
        assert_eq!(
            slots.line(),
            "OK id=9 frame=0003 pose=1,2,3,0,0,0 score=0.2500 capture_ms=1.2 compute_ms=40.0 slots=FA?E"
        );
        assert_eq!(
            slot_line(2, "filled", true, "0003", "1,2,3"),
            "OK slot=2 state=filled askew=1 frame=0003 pose=1,2,3"
        );
        assert_eq!(slot_without_pose_line(5), "NO_POSE slot=5");
        assert_eq!(bad_request_line(BadRequest::TooLong), "BAD_REQUEST too-long");
        assert_eq!(busy_line("queue-full", Some("4")), "BUSY queue-full id=4");
    }

    #[test]
    fn every_refusal_has_its_own_reason_word_on_a_bad_request_line() {
        let all = [
            BadRequest::TooLong,
            BadRequest::NotAscii,
            BadRequest::Empty,
            BadRequest::UnknownCommand,
            BadRequest::BadId,
            BadRequest::ExtraWords,
            BadRequest::BadSlot,
            BadRequest::NoSuchSlot,
        ];
        let words: std::collections::BTreeSet<&str> = all.iter().map(|b| b.as_str()).collect();
        assert_eq!(words.len(), all.len());
        for b in all {
            let line = bad_request_line(b);
            assert_eq!(line.split(' ').collect::<Vec<_>>(), ["BAD_REQUEST", b.as_str()]);
        }
    }

    #[test]
    fn every_status_has_its_own_word_and_place() {
        for (i, s) in Status::ALL.iter().enumerate() {
            assert_eq!(s.index(), i);
            assert!(s.as_str().bytes().all(|b| b.is_ascii_uppercase() || b == b'_'), "{}", s.as_str());
        }
        let words: std::collections::BTreeSet<&str> = Status::ALL.iter().map(|s| s.as_str()).collect();
        assert_eq!(words.len(), Status::ALL.len());
    }

    #[test]
    fn each_refusing_verdict_has_a_reason_of_its_own() {
        use camplace_estimator::pose::Verdict;
        let refusing = [Verdict::NoTray, Verdict::OffTable, Verdict::Ambiguous, Verdict::PoorFit, Verdict::SeenThrough];
        let words: std::collections::BTreeSet<&str> = refusing.iter().map(|&v| rejected_reason(v)).collect();
        assert_eq!(words.len(), refusing.len());
        assert!(!words.contains(rejected_reason(Verdict::Accepted)));
    }

    fn reply(status: Status) -> TriggerReply {
        TriggerReply {
            status,
            reason: None,
            id: None,
            frame: None,
            pose: None,
            score: None,
            capture_ms: 0.04,
            compute_ms: 0.0,
            slots: None,
        }
    }

    #[test]
    fn a_camera_error_reply_carries_no_frame_pose_or_score() {
        assert_eq!(reply(Status::CameraError).line(), "CAMERA_ERROR capture_ms=0.0 compute_ms=0.0");
        let with_id = TriggerReply { id: Some("a.b-c_1".into()), capture_ms: 5000.0, ..reply(Status::CameraError) };
        assert_eq!(with_id.line(), "CAMERA_ERROR id=a.b-c_1 capture_ms=5000.0 compute_ms=0.0");
    }

    #[test]
    fn a_no_pose_reply_names_its_frame_and_times() {
        let r = TriggerReply { frame: Some("0042".into()), compute_ms: 18.26, ..reply(Status::NoPose) };
        assert_eq!(r.line(), "NO_POSE frame=0042 capture_ms=0.0 compute_ms=18.3");
    }

    #[test]
    fn busy_lines_say_why_with_and_without_an_id() {
        assert_eq!(busy_line("stopping", None), "BUSY stopping");
        assert_eq!(busy_line("too-many-clients", None), "BUSY too-many-clients");
        assert_eq!(busy_line("queue-full", Some("x")), "BUSY queue-full id=x");
    }

    #[test]
    fn requests_at_their_limits_are_taken() {
        // Case and blanks: any case, tabs and spaces between words.
        assert_eq!(parse_request(b"PiNg"), Ok(Request::Ping));
        assert_eq!(parse_request(b"\tTRIGGER\t \tz\r"), Ok(Request::Trigger { id: Some("z".into()) }));
        // An id of 32 characters of every kind allowed.
        let id = "aZ09_.-".repeat(5)[..MAX_ID_CHARS].to_string();
        assert_eq!(parse_request(format!("TRIGGER {id}").as_bytes()), Ok(Request::Trigger { id: Some(id) }));
        // A line of exactly the limit is parsed (an unknown word), one byte more is too long;
        // its `\r` does not count.
        let mut line = vec![b'X'; MAX_REQUEST_BYTES];
        assert_eq!(parse_request(&line), Err(BadRequest::UnknownCommand));
        line.push(b'\r');
        assert_eq!(parse_request(&line), Err(BadRequest::UnknownCommand));
        line.insert(0, b'X');
        assert_eq!(parse_request(&line), Err(BadRequest::TooLong));
        assert_eq!(parse_request(b"SLOT 9999"), Ok(Request::Slot { n: 9999 }));
        assert_eq!(parse_request(b"SLOT 1a"), Err(BadRequest::BadSlot));
        assert_eq!(parse_request(b"SLOT +1"), Err(BadRequest::BadSlot));
        assert_eq!(parse_request(b"   "), Err(BadRequest::Empty));
        assert_eq!(parse_request(b"\r"), Err(BadRequest::Empty));
    }
}
