//! camplace: the command line. Parses, calls the crates, prints; nothing else lives here.
//! Any error ends with one line on stderr naming the file, the key and what was expected,
//! and exit code 2.

mod cli;

use std::process::ExitCode;

fn main() -> ExitCode {
    match cli::dispatch() {
        Ok(code) => code,
        Err(e) => {
            // One line: the chain joined, the innermost cause last; a cause its error's
            // message already ends with is not said twice.
            let mut msg: Vec<String> = Vec::new();
            for cause in e.chain().map(|c| c.to_string()) {
                let words = |t: &str| t.split_whitespace().collect::<Vec<_>>().join(" ");
                if msg.last().is_some_and(|last| words(last).ends_with(&words(&cause))) {
                    continue;
                }
                msg.push(cause);
            }
            eprintln!("error: {}", msg.join(": "));
            ExitCode::from(2)
        }
    }
}
