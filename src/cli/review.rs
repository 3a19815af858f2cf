//! `camplace review`: the review page of a recorded dataset (`review.html` beside its
//! frames), or with `--listen` the same page served on this machine, each mark appended to
//! `labels.jsonl` as it is made. The server answers only the page, the frames' left images,
//! `POST /label` and `POST /quit`, and stops by itself after `--idle-exit` seconds without a
//! request.

use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Duration;

use anyhow::{bail, Context};
use camplace_config::{is_image_name, write_atomic, Cell};
use camplace_sim::{append_label, frame_names, review_page, Label};
use tiny_http::{Header, Method, Request, Response, Server};

/// The most bytes a mark's request body may hold.
const MAX_BODY_BYTES: u64 = 4096;

/// Flags of `camplace review`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The recorded dataset (estimated: poses.jsonl beside its frames).
    #[arg(value_name = "DATASET")]
    dataset: PathBuf,
    /// Cell file whose tray is outlined; the built-in default when not given.
    #[arg(long, value_name = "FILE")]
    cell: Option<PathBuf>,
    /// Which of the cell's listed trays.
    #[arg(long, value_name = "NAME")]
    tray: Option<String>,
    /// Serve the page at this address of this machine (e.g. 127.0.0.1:8040; port 0 picks a
    /// free one) and save each mark to labels.jsonl.
    #[arg(long, value_name = "ADDR")]
    listen: Option<String>,
    /// With --listen: stop after this many seconds without a request, 1 to 86400.
    #[arg(long, value_name = "SECONDS", default_value_t = 3600, value_parser = clap::value_parser!(u64).range(1..=86_400))]
    idle_exit: u64,
}

/// Runs `camplace review`.
pub fn run(a: Args) -> anyhow::Result<ExitCode> {
    let cell = match &a.cell {
        Some(p) => Cell::load(p)?.one_tray(a.tray.as_deref()).map_err(|e| e.in_file(p))?,
        None => Cell::default(),
    };
    let Some(listen) = &a.listen else {
        let page = review_page(&a.dataset, &cell, false)?;
        let path = a.dataset.join("review.html");
        write_atomic(&path, page.as_bytes())?;
        outln!("wrote {} (marks are saved only when served: camplace review --listen 127.0.0.1:8040)", path.display());
        return Ok(ExitCode::SUCCESS);
    };
    let addr: std::net::SocketAddr =
        listen.parse().with_context(|| format!("--listen {listen}: expected an address such as 127.0.0.1:8040"))?;
    if !addr.ip().is_loopback() {
        bail!("--listen {listen}: expected an address of this machine only (127.0.0.1 or ::1)");
    }
    // Checked before serving: a dataset the page cannot be made of is refused at once.
    review_page(&a.dataset, &cell, true)?;
    let server = Server::http(addr).map_err(|e| anyhow::anyhow!("--listen {listen}: cannot listen: {e}"))?;
    let bound = server.server_addr().to_ip().map_or_else(|| listen.clone(), |a| a.to_string());
    outln!("reviewing {} at http://{bound}/ (stops after {} s without a request)", a.dataset.display(), a.idle_exit);
    let mut marks = 0usize;
    loop {
        let Some(request) =
            server.recv_timeout(Duration::from_secs(a.idle_exit)).context("--listen: the server failed")?
        else {
            outln!("no request for {} s; {marks} marks saved", a.idle_exit);
            break;
        };
        match answer(request, &a.dataset, &cell)? {
            Served::Marked => marks += 1,
            Served::Quit => {
                outln!("review closed from the page; {marks} marks saved");
                break;
            }
            Served::Other => {}
        }
    }
    Ok(ExitCode::SUCCESS)
}

enum Served {
    Marked,
    Quit,
    Other,
}

fn header(name: &str, value: &str) -> Header {
    Header::from_bytes(name.as_bytes(), value.as_bytes()).expect("ASCII header")
}

/// Answers one request; a failure to answer (the browser went away) loses that answer only.
fn answer(mut request: Request, dir: &Path, cell: &Cell) -> anyhow::Result<Served> {
    let url = request.url().split(['?', '#']).next().unwrap_or("/").to_string();
    let method = request.method().clone();
    let text = |code: u16, body: String| Response::from_string(body).with_status_code(code);
    let (response, served) = match (method, url.as_str()) {
        (Method::Get, "/") | (Method::Get, "/index.html") => match review_page(dir, cell, true) {
            Ok(page) => {
                (text(200, page).with_header(header("Content-Type", "text/html; charset=utf-8")), Served::Other)
            }
            Err(e) => (text(500, e.to_string()), Served::Other),
        },
        (Method::Get, path) => match frame_image(dir, path) {
            Some(file) => match std::fs::read(&file) {
                Ok(bytes) => {
                    (Response::from_data(bytes).with_header(header("Content-Type", "image/png")), Served::Other)
                }
                Err(e) => (text(404, format!("{}: {e}", file.display())), Served::Other),
            },
            None => (text(404, format!("{path}: not a frame's image")), Served::Other),
        },
        (Method::Post, "/label") => {
            let mut body = String::new();
            let read = request.as_reader().take(MAX_BODY_BYTES).read_to_string(&mut body);
            let label = read
                .map_err(|e| e.to_string())
                .and_then(|_| serde_json::from_str::<Label>(&body).map_err(|e| format!("expected a mark: {e}")));
            match label {
                Ok(label) => {
                    let names = frame_names(dir)?;
                    match append_label(dir, &names, &label) {
                        Ok(_) => (text(200, "saved".into()), Served::Marked),
                        Err(e) => (text(400, e.to_string()), Served::Other),
                    }
                }
                Err(e) => (text(400, e), Served::Other),
            }
        }
        (Method::Post, "/quit") => (text(200, "closed".into()), Served::Quit),
        (_, path) => (text(405, format!("{path}: not answered")), Served::Other),
    };
    if let Err(e) = request.respond(response) {
        noteln!("note: the page went away before its answer: {e}");
    }
    Ok(served)
}

/// The file of `/frames/NNNN/IMAGE` when NNNN is a frame folder and IMAGE an image name.
fn frame_image(dir: &Path, path: &str) -> Option<PathBuf> {
    let rest = path.strip_prefix("/frames/")?;
    let (frame, image) = rest.split_once('/')?;
    let digits = !frame.is_empty() && frame.bytes().all(|b| b.is_ascii_digit());
    (digits && is_image_name(image) && !image.contains('/')).then(|| dir.join("frames").join(frame).join(image))
}
