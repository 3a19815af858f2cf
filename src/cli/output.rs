//! The command line's printing. Standard output is written through [`out`], which never
//! panics: a reader that went away (a closed pipe, `| head -1`) ends the command quietly
//! with exit code [`CLOSED_PIPE_EXIT`], any other failure (`> /dev/full`) with one line on
//! standard error and exit code 2. Notes on standard error go through [`note`], which drops
//! what cannot be written: there is nowhere left to say it. Commands write their files
//! before they print anything about them, so ending early loses no work.

use std::fmt;
use std::io::{self, Write};

/// The exit code of a command whose standard output was closed by its reader: what a shell
/// reports for a program ended by SIGPIPE (128 + 13).
pub const CLOSED_PIPE_EXIT: i32 = 141;

/// Writes to standard output and flushes; a closed or failing stream ends the process.
pub fn out(args: fmt::Arguments<'_>) {
    let mut stdout = io::stdout().lock();
    if let Err(e) = stdout.write_fmt(args).and_then(|()| stdout.flush()) {
        stdout_failed(&e);
    }
}

/// Writes to standard error; a closed or full stream loses the text and nothing else.
pub fn note(args: fmt::Arguments<'_>) {
    let _ = io::stderr().lock().write_fmt(args);
}

/// Ends the process after standard output failed: quietly when the reader went away, with
/// one line when the stream could not take the text.
pub fn stdout_failed(e: &io::Error) -> ! {
    if e.kind() == io::ErrorKind::BrokenPipe {
        std::process::exit(CLOSED_PIPE_EXIT);
    }
    note(format_args!("error: standard output: cannot write: {e}\n"));
    std::process::exit(2)
}

/// `println!` through [`out`].
macro_rules! outln {
    () => {
        $crate::cli::output::out(format_args!("\n"))
    };
    ($($arg:tt)*) => {
        $crate::cli::output::out(format_args!("{}\n", format_args!($($arg)*)))
    };
}

/// `print!` through [`out`].
macro_rules! out {
    ($($arg:tt)*) => {
        $crate::cli::output::out(format_args!($($arg)*))
    };
}

/// `eprintln!` through [`note`].
macro_rules! noteln {
    ($($arg:tt)*) => {
        $crate::cli::output::note(format_args!("{}\n", format_args!($($arg)*)))
    };
}
