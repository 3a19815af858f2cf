//! camplace: the command line. Parses, calls the crates, prints; nothing else lives here.
//! Any error ends with one line on stderr naming the file, the key and what was expected,
//! and exit code 2.

mod cli;

use std::process::ExitCode;

fn main() -> ExitCode {
    match cli::run() {
        Ok(code) => code,
        Err(e) => {
            // One line: the chain joined, the innermost cause last.
            let msg: Vec<String> = e.chain().map(|c| c.to_string()).collect();
            eprintln!("error: {}", msg.join(": "));
            ExitCode::from(2)
        }
    }
}
