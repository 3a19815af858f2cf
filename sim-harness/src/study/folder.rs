//! A study folder: created, its settings checked (or written) and its results file opened.

use std::path::Path;

use camplace_config::Cell;

use super::results::ResultsStore;
use super::settings::RunSettings;
use crate::render::Method;
use crate::{Error, Result};

/// Creates `dir`, checks (or writes) its settings and opens its results file.
pub fn open_folder(dir: &Path, cell: &Cell, method: Method, seed: u64) -> Result<ResultsStore> {
    std::fs::create_dir_all(dir)
        .map_err(|e| Error::Other(format!("{}: cannot create the folder: {e}", dir.display())))?;
    RunSettings::new(cell, method, seed).check_or_write(dir)?;
    ResultsStore::open(&dir.join("results.jsonl"))
}
