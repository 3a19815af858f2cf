//! `camplace review`: the review page of a recorded dataset (`review.html` beside its
//! frames), or with `--listen` the same page served on this machine, each mark appended to
//! `labels.jsonl` as it is made (the server is camplace-sim's `serve_review`; this file
//! parses the flags, binds the address and prints).

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;

use anyhow::{bail, Context};
use camplace_config::{write_atomic, Cell};
use camplace_sim::{review_page, serve_review, ReviewEnd};

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
    let cell = Cell::load_one(a.cell.as_deref(), a.tray.as_deref())?;
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
    let listener =
        std::net::TcpListener::bind(addr).with_context(|| format!("--listen {listen}: cannot listen there"))?;
    let bound = listener.local_addr().map_or_else(|_| listen.clone(), |a| a.to_string());
    outln!("reviewing {} at http://{bound}/ (stops after {} s without a request)", a.dataset.display(), a.idle_exit);
    let reviewed = serve_review(listener, &a.dataset, &cell, Duration::from_secs(a.idle_exit))?;
    match reviewed.end {
        ReviewEnd::Idle => outln!("no request for {} s; {} marks saved", a.idle_exit, reviewed.marks),
        ReviewEnd::Quit => outln!("review closed from the page; {} marks saved", reviewed.marks),
    }
    Ok(ExitCode::SUCCESS)
}
