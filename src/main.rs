//! camplace: the command line. Parses, calls the crates, prints; nothing else lives here.
//! Any error ends with one line on stderr naming the file, the key and what was expected,
//! and exit code 2.

mod cli;

use std::process::ExitCode;

fn main() -> ExitCode {
    match cli::dispatch() {
        Ok(code) => code,
        Err(e) => {
            // One line: the context chain joined, down to the first error of a camplace
            // crate, whose message is already complete (its own sources are for programs,
            // and a parser's may span lines); a cause its error's message already ends with
            // is not said twice.
            let mut msg: Vec<String> = Vec::new();
            let words = |t: &str| t.split_whitespace().collect::<Vec<_>>().join(" ");
            for cause in e.chain() {
                let text = words(&cause.to_string());
                if !msg.last().is_some_and(|last| last.ends_with(&text)) {
                    msg.push(text);
                }
                let complete = cause.is::<camplace_config::Error>()
                    || cause.is::<camplace_estimator::Error>()
                    || cause.is::<camplace_hwio::Error>()
                    || cause.is::<camplace_serve::Error>()
                    || is_sim_error(cause);
                if complete {
                    break;
                }
            }
            cli::output::note(format_args!("error: {}\n", msg.join(": ")));
            ExitCode::from(2)
        }
    }
}

/// Whether `cause` is the simulator's error (there is none in a build without it).
fn is_sim_error(cause: &(dyn std::error::Error + 'static)) -> bool {
    #[cfg(feature = "sim")]
    return cause.is::<camplace_sim::Error>();
    #[cfg(not(feature = "sim"))]
    return {
        let _ = cause;
        false
    };
}
