//! How far a run of scenes has come, told to whoever listens: the library draws nothing.
//! The program installs one callback for the process ([`set_progress`], as a logger is
//! installed once); the command line draws a progress bar from it, an embedder may log it
//! or ignore it. Without a callback nothing is reported.

use std::sync::{Arc, RwLock};

/// One step of a run of scenes, in the order a run reports them.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ProgressEvent<'a> {
    /// A run of `scenes` scenes begins; `label` names it (`sweep`, `search`, `evaluate` ...).
    Start { label: &'a str, scenes: u64 },
    /// What the run is doing now (the placement, or its model being built).
    Doing(&'a str),
    /// One scene finished (from any worker thread).
    Scene,
    /// The run ended.
    Finish,
}

/// A progress callback; called from the worker threads too.
pub type ProgressCallback = Arc<dyn Fn(ProgressEvent<'_>) + Send + Sync>;

static PROGRESS: RwLock<Option<ProgressCallback>> = RwLock::new(None);

/// Installs `callback` for every later run of scenes in this process (`None`: report
/// nothing).
pub fn set_progress(callback: Option<ProgressCallback>) {
    *PROGRESS.write().unwrap_or_else(|e| e.into_inner()) = callback;
}

/// Tells the installed callback, if any, about `event`.
pub(crate) fn report(event: ProgressEvent<'_>) {
    let callback = PROGRESS.read().unwrap_or_else(|e| e.into_inner()).clone();
    if let Some(callback) = callback {
        callback(event);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::Mutex;

    #[test]
    fn the_installed_callback_hears_every_event_and_none_after_removal() {
        let heard: Arc<Mutex<Vec<String>>> = Arc::default();
        let sink = Arc::clone(&heard);
        set_progress(Some(Arc::new(move |e: ProgressEvent<'_>| sink.lock().unwrap().push(format!("{e:?}")))));
        report(ProgressEvent::Start { label: "sweep", scenes: 2 });
        report(ProgressEvent::Scene);
        report(ProgressEvent::Finish);
        set_progress(None);
        report(ProgressEvent::Scene);
        assert_eq!(*heard.lock().unwrap(), ["Start { label: \"sweep\", scenes: 2 }", "Scene", "Finish"]);
    }
}
