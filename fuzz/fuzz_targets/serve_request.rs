//! A robot's request line to `camplace serve` (`CAMPLACE/1`): a request or a refusal with
//! its one-word reason, never a panic; an accepted request written in its canonical form
//! (in lower case, to try the case-insensitive commands) reads back the same.
#![no_main]

use camplace_serve::{parse_request, Request, MAX_REQUEST_BYTES};

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    match parse_request(data) {
        Ok(request) => {
            assert!(data.len() <= MAX_REQUEST_BYTES + 1, "an accepted line of {} bytes", data.len());
            let line = match &request {
                Request::Trigger { id: None } => "trigger".to_string(),
                Request::Trigger { id: Some(id) } => format!("trigger {id}"),
                Request::Ping => "ping".to_string(),
                Request::Status => "status".to_string(),
                Request::Version => "version".to_string(),
            };
            assert_eq!(parse_request(line.as_bytes()), Ok(request));
        }
        Err(reason) => {
            let word = reason.as_str();
            assert!(!word.is_empty() && word.bytes().all(|b| b.is_ascii_lowercase() || b == b'-'), "{word:?}");
        }
    }
});
