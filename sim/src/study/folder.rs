//! A study folder: created, its settings checked (or written), the temporary files of a
//! killed run removed, and its results file opened.

use std::path::Path;

use camplace_config::{remove_stale_temp_files, Cell};

use super::lock::lock_folder;
use super::results::ResultsStore;
use super::settings::RunSettings;
use crate::render::Method;
use crate::{Error, Result};

/// The sub-folder of a study folder that caches its models.
pub const MODELS_FOLDER: &str = "models";

/// Creates `dir`, checks (or writes) its settings, removes stale temporary files from it and
/// its model cache, and opens its results file. A folder that holds results but no
/// `settings.json` is refused: nothing says what they were computed for. The folder is
/// locked first ([`lock_folder`]): a folder another run works in is refused naming it.
pub fn open_folder(dir: &Path, cell: &Cell, method: Method, seed: u64) -> Result<ResultsStore> {
    let _lock = lock_folder(dir)?;
    for d in [dir.to_path_buf(), dir.join(MODELS_FOLDER)] {
        remove_stale_temp_files(&d)?;
    }
    let results = dir.join("results.jsonl");
    let has_results = std::fs::metadata(&results).is_ok_and(|m| m.len() > 0);
    if has_results && !dir.join("settings.json").exists() {
        return Err(Error::Other(format!(
            "{}: missing, but the folder holds results (results.jsonl) of unknown settings; restore settings.json or use a new folder",
            dir.join("settings.json").display()
        )));
    }
    RunSettings::new(cell, method, seed)?.check_or_write(dir)?;
    ResultsStore::open(&results)
}
