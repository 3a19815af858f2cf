//! The review page served on this machine (`camplace review --listen`): the page, the
//! frames' left images, `POST /label` (each mark appended to `labels.jsonl` as it is made)
//! and `POST /quit`, on camplace-http so that no client can stall or starve it; it stops
//! by itself after an idle time. Binding the address and printing are the CLI's.

use std::cell::Cell as Flag;
use std::net::TcpListener;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use camplace_config::{is_image_name, Cell};
use camplace_http::{Limits, Request, Response, Server, TURN};

use super::judge::{append_label, frame_names, Label};
use super::review_page::review_page;
use crate::{Error, Result};

/// The most bytes a mark's request body may hold (a mark is a frame name and a word).
pub const MAX_LABEL_BYTES: u64 = 4096;

/// Time given to the last answers (the page's "closed") once the page asks to quit.
const LAST_ANSWERS: Duration = Duration::from_secs(2);

/// Why the review server stopped.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ReviewEnd {
    /// The page asked to (`POST /quit`).
    Quit,
    /// No request came within the idle time.
    Idle,
}

/// What a review sitting did.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Reviewed {
    /// Marks saved to `labels.jsonl`.
    pub marks: usize,
    /// Why it stopped.
    pub end: ReviewEnd,
}

/// Serves the review page of the recorded dataset `dir` (its tray outlined from `cell`) on
/// `listener` until the page quits or no request has come for `idle_exit`.
pub fn serve_review(listener: TcpListener, dir: &Path, cell: &Cell, idle_exit: Duration) -> Result<Reviewed> {
    let marks = Flag::new(0usize);
    let quit = Flag::new(false);
    let handler = |r: &Request| answer(r, dir, cell, &marks, &quit);
    let mut server = Server::new(listener, Limits::default(), handler)
        .map_err(|e| Error::Other(format!("the review page cannot be served: {e}")))?
        .with_body_limit(|h| if h.method == "POST" && h.path == "/label" { MAX_LABEL_BYTES } else { 0 });
    let mut last = Instant::now();
    loop {
        if server.turn(TURN) > 0 {
            last = Instant::now();
        }
        if quit.get() {
            server.finish(LAST_ANSWERS);
            return Ok(Reviewed { marks: marks.get(), end: ReviewEnd::Quit });
        }
        if last.elapsed() >= idle_exit {
            return Ok(Reviewed { marks: marks.get(), end: ReviewEnd::Idle });
        }
    }
}

/// The answer to one request; a mark saved counts in `marks`, `POST /quit` sets `quit`.
fn answer(r: &Request, dir: &Path, cell: &Cell, marks: &Flag<usize>, quit: &Flag<bool>) -> Response {
    match (r.method.as_str(), r.path.as_str()) {
        ("GET", "/" | "/index.html") => match review_page(dir, cell, true) {
            Ok(page) => Response::new(200, "text/html; charset=utf-8", page),
            Err(e) => Response::text(500, e.to_string()),
        },
        ("GET", path) => match frame_image(dir, path) {
            Some(file) => match std::fs::read(&file) {
                Ok(bytes) => Response::new(200, "image/png", bytes),
                Err(e) => Response::text(404, format!("{}: {e}", file.display())),
            },
            None => Response::text(404, format!("{path}: not a frame's image")),
        },
        ("POST", "/label") => {
            let label = std::str::from_utf8(&r.body)
                .map_err(|e| format!("expected a mark in UTF-8: {e}"))
                .and_then(|body| serde_json::from_str::<Label>(body).map_err(|e| format!("expected a mark: {e}")));
            let label = match label {
                Ok(label) => label,
                Err(e) => return Response::text(400, e),
            };
            let saved = frame_names(dir).and_then(|names| append_label(dir, &names, &label));
            match saved {
                Ok(_) => {
                    marks.set(marks.get() + 1);
                    Response::text(200, "saved")
                }
                Err(e) => Response::text(400, e.to_string()),
            }
        }
        ("POST", "/quit") => {
            quit.set(true);
            Response::text(200, "closed")
        }
        (_, path) => Response::text(405, format!("{path}: not answered")),
    }
}

/// The file of `/frames/NNNN/IMAGE` when NNNN is a frame folder and IMAGE an image name.
fn frame_image(dir: &Path, path: &str) -> Option<PathBuf> {
    let rest = path.strip_prefix("/frames/")?;
    let (frame, image) = rest.split_once('/')?;
    let digits = !frame.is_empty() && frame.bytes().all(|b| b.is_ascii_digit());
    (digits && is_image_name(image) && !image.contains('/')).then(|| dir.join("frames").join(frame).join(image))
}
