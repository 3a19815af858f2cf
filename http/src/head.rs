//! A request's head (request line and header fields) parsed from the bytes received so far:
//! pure, bounded, and the only place where a client's head is read.

/// The most bytes of a request line (method, target, version); a longer one is a 414.
pub const MAX_REQUEST_LINE: usize = 4096;

/// The most bytes of a whole head, its blank line included; a longer one is a 431.
pub const MAX_HEAD_BYTES: usize = 8192;

/// A request's head as the server routes it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Head {
    /// The method as sent (`GET`, `POST`, ...); methods are case-sensitive.
    pub method: String,
    /// The target's path, from its leading `/` up to `?` or `#`, not percent-decoded.
    pub path: String,
    /// The target's query, after `?` and before `#` (empty when there is none).
    pub query: String,
    /// The body's length from `Content-Length` (0 when there is none).
    pub content_length: u64,
}

/// Why a head is refused, with the status that says it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Refusal {
    /// The reply's status: 400, 413, 414, 431, 501 or 505.
    pub status: u16,
    /// What was wrong, in a few words (the reply's body).
    pub reason: &'static str,
}

const fn refuse(status: u16, reason: &'static str) -> Refusal {
    Refusal { status, reason }
}

/// Parses the head at the start of `bytes`: `Ok(None)` while it may still be completed,
/// `Ok(Some((head, length)))` with the head's length in bytes (its blank line included; the
/// body starts there), or the refusal. Lines end in CRLF or a bare LF.
pub fn parse_request_head(bytes: &[u8]) -> Result<Option<(Head, usize)>, Refusal> {
    let window = &bytes[..bytes.len().min(MAX_HEAD_BYTES)];
    let Some(line_end) = window.iter().position(|&b| b == b'\n') else {
        return if window.len() > MAX_REQUEST_LINE {
            Err(refuse(414, "request line too long"))
        } else if window.len() == MAX_HEAD_BYTES {
            Err(refuse(431, "request head too large"))
        } else {
            Ok(None)
        };
    };
    if line_end > MAX_REQUEST_LINE {
        return Err(refuse(414, "request line too long"));
    }
    // The head ends at the first empty line (LF LF or LF CR LF).
    let mut start = line_end + 1;
    let mut lines = vec![trim_cr(&window[..line_end])];
    let end = loop {
        let Some(at) = window[start..].iter().position(|&b| b == b'\n') else {
            return if window.len() == MAX_HEAD_BYTES { Err(refuse(431, "request head too large")) } else { Ok(None) };
        };
        let line = trim_cr(&window[start..start + at]);
        start += at + 1;
        if line.is_empty() {
            break start;
        }
        lines.push(line);
    };
    let mut head = request_line(lines[0])?;
    let mut length: Option<u64> = None;
    for &line in &lines[1..] {
        if line[0] == b' ' || line[0] == b'\t' {
            return Err(refuse(400, "folded header line"));
        }
        let colon = line.iter().position(|&b| b == b':').ok_or(refuse(400, "header line without a colon"))?;
        let name = &line[..colon];
        if name.is_empty() || !name.iter().all(|&b| is_token(b)) {
            return Err(refuse(400, "bad header name"));
        }
        let value = trim_spaces(&line[colon + 1..]);
        if value.iter().any(|&b| b == 0 || b == b'\r' || (b < 0x20 && b != b'\t') || b == 0x7f) {
            return Err(refuse(400, "control character in a header value"));
        }
        if name.eq_ignore_ascii_case(b"content-length") {
            let n = content_length(value)?;
            if length.is_some_and(|l| l != n) {
                return Err(refuse(400, "two different Content-Length values"));
            }
            length = Some(n);
        } else if name.eq_ignore_ascii_case(b"transfer-encoding") {
            // Chunked bodies are never needed by these pages; refusing them keeps one way of
            // bounding a body (its announced length, checked before it is read).
            return Err(refuse(501, "Transfer-Encoding not supported; send Content-Length"));
        }
    }
    head.content_length = length.unwrap_or(0);
    Ok(Some((head, end)))
}

fn request_line(line: &[u8]) -> Result<Head, Refusal> {
    let mut parts = line.split(|&b| b == b' ');
    let (Some(method), Some(target), Some(version), None) = (parts.next(), parts.next(), parts.next(), parts.next())
    else {
        return Err(refuse(400, "expected METHOD TARGET HTTP/1.1"));
    };
    if method.is_empty() || !method.iter().all(|&b| is_token(b)) {
        return Err(refuse(400, "bad method"));
    }
    match version {
        b"HTTP/1.1" | b"HTTP/1.0" => {}
        [b'H', b'T', b'T', b'P', b'/', a, b'.', b] if a.is_ascii_digit() && b.is_ascii_digit() => {
            return Err(refuse(505, "HTTP version not supported"));
        }
        _ => return Err(refuse(400, "expected HTTP/1.1")),
    }
    if target.first() != Some(&b'/') || !target.iter().all(|&b| b.is_ascii_graphic()) {
        return Err(refuse(400, "expected a target starting with /"));
    }
    // The checks above leave ASCII only, so these conversions cannot fail.
    let target = std::str::from_utf8(target).map_err(|_| refuse(400, "bad target"))?;
    let target = target.split('#').next().unwrap_or("");
    let (path, query) = target.split_once('?').unwrap_or((target, ""));
    let method = std::str::from_utf8(method).map_err(|_| refuse(400, "bad method"))?;
    Ok(Head { method: method.to_string(), path: path.to_string(), query: query.to_string(), content_length: 0 })
}

/// A Content-Length value: digits only, as a u64; beyond u64 is too large to accept.
fn content_length(value: &[u8]) -> Result<u64, Refusal> {
    if value.is_empty() || !value.iter().all(u8::is_ascii_digit) {
        return Err(refuse(400, "Content-Length is not a number"));
    }
    value
        .iter()
        .try_fold(0u64, |n, &d| n.checked_mul(10)?.checked_add(u64::from(d - b'0')))
        .ok_or(refuse(413, "Content-Length beyond 2^64 - 1"))
}

/// RFC 9110's token characters (methods, header names).
fn is_token(b: u8) -> bool {
    b.is_ascii_alphanumeric() || b"!#$%&'*+-.^_`|~".contains(&b)
}

fn trim_cr(line: &[u8]) -> &[u8] {
    line.strip_suffix(b"\r").unwrap_or(line)
}

fn trim_spaces(mut value: &[u8]) -> &[u8] {
    while let [b' ' | b'\t', rest @ ..] = value {
        value = rest;
    }
    while let [rest @ .., b' ' | b'\t'] = value {
        value = rest;
    }
    value
}

#[cfg(test)]
mod tests {
    use super::*;

    fn head(text: &str) -> Result<Option<(Head, usize)>, Refusal> {
        parse_request_head(text.as_bytes())
    }

    fn status(text: &str) -> u16 {
        head(text).expect_err(text).status
    }

    #[test]
    fn good_heads_give_method_path_query_length_and_where_the_body_starts() {
        let (h, n) = head("GET /frame.png?n=3 HTTP/1.1\r\nHost: x\r\n\r\nrest").unwrap().unwrap();
        assert_eq!(
            (h.method.as_str(), h.path.as_str(), h.query.as_str(), h.content_length),
            ("GET", "/frame.png", "n=3", 0)
        );
        assert_eq!(n, "GET /frame.png?n=3 HTTP/1.1\r\nHost: x\r\n\r\n".len());
        let (h, n) = head("POST /label HTTP/1.0\nContent-Length:  17 \ncontent-length: 17\n\n").unwrap().unwrap();
        assert_eq!(
            (h.method.as_str(), h.path.as_str(), h.query.as_str(), h.content_length),
            ("POST", "/label", "", 17)
        );
        assert_eq!(n, "POST /label HTTP/1.0\nContent-Length:  17 \ncontent-length: 17\n\n".len());
        let (h, _) = head("GET /#top HTTP/1.1\r\n\r\n").unwrap().unwrap();
        assert_eq!((h.path.as_str(), h.query.as_str()), ("/", ""));
        let (h, _) = head(&format!("GET / HTTP/1.1\r\nContent-Length: {}\r\n\r\n", u64::MAX)).unwrap().unwrap();
        assert_eq!(h.content_length, u64::MAX, "2^64 - 1 is a length; the route's limit refuses it");
    }

    #[test]
    fn an_unfinished_head_asks_for_more_at_every_cut() {
        let full = "POST /label HTTP/1.1\r\nContent-Length: 5\r\n\r\n";
        for cut in 0..full.len() {
            assert_eq!(head(&full[..cut]), Ok(None), "cut at {cut}");
        }
        assert!(head(full).unwrap().is_some());
    }

    #[test]
    fn bad_heads_get_their_status() {
        for bad in [
            "GET /\r\n\r\n",
            "GET / HTTP/1.1 extra\r\n\r\n",
            "GET  / HTTP/1.1\r\n\r\n",
            "G(T / HTTP/1.1\r\n\r\n",
            "GET http://x/ HTTP/1.1\r\n\r\n",
            "GET * HTTP/1.1\r\n\r\n",
            "GET /\x7f HTTP/1.1\r\n\r\n",
            "GET / HTTQ/1.1\r\n\r\n",
            "GET / HTTP/1.1\r\nno colon\r\n\r\n",
            "GET / HTTP/1.1\r\n folded: x\r\n\r\n",
            "GET / HTTP/1.1\r\nbad name: x\r\n\r\n",
            "GET / HTTP/1.1\r\n: x\r\n\r\n",
            "GET / HTTP/1.1\r\nX: a\x01b\r\n\r\n",
            "GET / HTTP/1.1\r\nContent-Length: -1\r\n\r\n",
            "GET / HTTP/1.1\r\nContent-Length: 1 2\r\n\r\n",
            "GET / HTTP/1.1\r\nContent-Length: \r\n\r\n",
            "GET / HTTP/1.1\r\nContent-Length: 0x10\r\n\r\n",
            "GET / HTTP/1.1\r\nContent-Length: 3\r\nContent-Length: 4\r\n\r\n",
        ] {
            assert_eq!(status(bad), 400, "{bad:?}");
        }
        assert_eq!(status("GET / HTTP/2.0\r\n\r\n"), 505);
        assert_eq!(status("POST / HTTP/1.1\r\nTransfer-Encoding: chunked\r\n\r\n"), 501);
        // One past 2^64 - 1, and far past it: no wrap to a small number.
        assert_eq!(status("GET / HTTP/1.1\r\nContent-Length: 18446744073709551616\r\n\r\n"), 413);
        assert_eq!(status(&format!("GET / HTTP/1.1\r\nContent-Length: {}\r\n\r\n", "9".repeat(400))), 413);
    }

    #[test]
    fn too_long_lines_and_heads_are_refused_at_the_limit_without_their_end() {
        let long_target = format!("GET /{}", "a".repeat(MAX_REQUEST_LINE));
        assert_eq!(status(&long_target), 414, "a request line past the limit, not yet ended");
        assert_eq!(status(&format!("{long_target} HTTP/1.1\r\n\r\n")), 414);
        // The longest request line allowed (its CR counted) still parses.
        let line = format!("GET /{} HTTP/1.1\r", "a".repeat(MAX_REQUEST_LINE - 15));
        assert_eq!(line.len(), MAX_REQUEST_LINE);
        assert!(head(&format!("{line}\n\r\n")).unwrap().is_some());
        // Header lines without end: the head limit, whatever follows.
        let mut endless = String::from("GET / HTTP/1.1\r\n");
        let filler = "X-Filler: yyyyyyyyyyyyyyyyyyyyyyyy\r\n";
        while endless.len() + filler.len() < MAX_HEAD_BYTES {
            endless.push_str(filler);
        }
        assert_eq!(head(&endless), Ok(None), "below the limit it may still end");
        endless.push_str(&"z".repeat(filler.len()));
        assert_eq!(status(&endless), 431);
        endless.push_str("\r\n\r\n");
        assert_eq!(status(&endless), 431, "an end past the limit is not looked at");
    }
}
