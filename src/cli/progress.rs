//! The progress bar on stderr, drawn from the simulator's progress events: one bar per run
//! of scenes, its label in front, the placement being worked on behind, with an ETA.

use std::sync::{Arc, Mutex};

use camplace_sim::ProgressEvent;
use indicatif::{ProgressBar, ProgressStyle};

/// Installs the bar as the process's progress callback.
pub fn install() {
    let bar: Mutex<Option<ProgressBar>> = Mutex::new(None);
    camplace_sim::set_progress(Some(Arc::new(move |event: ProgressEvent<'_>| {
        let mut bar = bar.lock().unwrap_or_else(|e| e.into_inner());
        match event {
            ProgressEvent::Start { label, scenes } => {
                let b = ProgressBar::new(scenes);
                b.set_style(
                    ProgressStyle::with_template(
                        "{prefix} [{bar:30}] {pos}/{len} scenes, {elapsed} elapsed, ETA {eta} {msg}",
                    )
                    .expect("a valid template")
                    .progress_chars("=> "),
                );
                b.set_prefix(label.to_string());
                if let Some(old) = bar.replace(b) {
                    old.finish_and_clear();
                }
            }
            ProgressEvent::Doing(what) => {
                if let Some(b) = bar.as_ref() {
                    b.set_message(what.to_string());
                }
            }
            ProgressEvent::Scene => {
                if let Some(b) = bar.as_ref() {
                    b.inc(1);
                }
            }
            ProgressEvent::Finish => {
                if let Some(b) = bar.take() {
                    b.finish_and_clear();
                }
            }
        }
    })));
}
