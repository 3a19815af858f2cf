//! A request head sent to the status or review page (`camplace_http::parse_request_head`):
//! more bytes wanted, a head, or a refusal with an HTTP error status, never a panic; a head
//! is found only within the head limit, and a complete head parses the same whatever
//! follows it.
#![no_main]

use camplace_http::{parse_request_head, MAX_HEAD_BYTES};

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    match parse_request_head(data) {
        Ok(None) => assert!(data.len() < MAX_HEAD_BYTES, "{} bytes still wanted more", data.len()),
        Ok(Some((head, used))) => {
            assert!(used <= data.len() && used <= MAX_HEAD_BYTES, "{used} of {} bytes", data.len());
            assert!(data[..used].ends_with(b"\n"), "a head ends at its blank line");
            assert!(head.path.starts_with('/') && !head.path.contains(['?', '#']), "{:?}", head.path);
            assert!(!head.method.is_empty() && head.method.is_ascii());
            // What follows the head is the body's, never the head's.
            let mut longer = data[..used].to_vec();
            longer.extend_from_slice(b"GET / HTTP/1.1\r\n\r\n");
            assert_eq!(parse_request_head(&longer), Ok(Some((head.clone(), used))));
            assert_eq!(parse_request_head(&data[..used]), Ok(Some((head, used))));
        }
        Err(refusal) => {
            assert!([400, 413, 414, 431, 501, 505].contains(&refusal.status), "{refusal:?}");
            assert!(!refusal.reason.is_empty());
        }
    }
});
