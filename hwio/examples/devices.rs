//! Prints the cameras this machine has, as `camplace devices` does, without the CLI.

fn main() {
    match camplace_hwio::list_devices() {
        Ok(list) if list.is_empty() => print!("no cameras found\n{list}"),
        Ok(list) => print!("{list}"),
        Err(e) => {
            eprintln!("error: {e}");
            std::process::exit(1);
        }
    }
}
