//! What a study folder was run with (`settings.json`: the cell, the method and the seed),
//! so that a re-run or a merge into the same folder cannot mix results of other settings.

use std::path::Path;

use camplace_config::write_atomic;
use camplace_config::Cell;
use serde::{Deserialize, Serialize};

use crate::render::Method;
use crate::{Error, Result};

/// The settings every result line of a folder shares.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RunSettings {
    /// The cell, as used (defaults filled in).
    pub cell: Cell,
    /// `one-shot` or `phase-12`.
    pub method: String,
    /// The study seed.
    pub seed: u64,
}

impl RunSettings {
    /// The settings of a run.
    pub fn new(cell: &Cell, method: Method, seed: u64) -> RunSettings {
        RunSettings { cell: cell.clone(), method: method.to_string(), seed }
    }

    /// The method as a value.
    pub fn method(&self) -> Result<Method> {
        self.method
            .parse()
            .map_err(|_| Error::Other(format!("method: expected one-shot or phase-12, got {}", self.method)))
    }

    /// Reads `dir/settings.json`, if there.
    pub fn load(dir: &Path) -> Result<Option<RunSettings>> {
        let path = dir.join("settings.json");
        if !path.exists() {
            return Ok(None);
        }
        let text = std::fs::read_to_string(&path)
            .map_err(|e| Error::Other(format!("{}: cannot read: {e}", path.display())))?;
        let s = serde_json::from_str(&text).map_err(|e| {
            Error::Other(format!(
                "{}: expected the settings of a study folder (cell, method, seed): {e}",
                path.display()
            ))
        })?;
        Ok(Some(s))
    }

    /// Writes `dir/settings.json` when the folder has none; when it has, checks that they
    /// agree, naming the first difference.
    pub fn check_or_write(&self, dir: &Path) -> Result<()> {
        let path = dir.join("settings.json");
        match RunSettings::load(dir)? {
            None => {
                let text = serde_json::to_string_pretty(self).expect("settings are plain data");
                Ok(write_atomic(&path, text.as_bytes())?)
            }
            Some(old) => self.agrees_with(&old).map_err(|what| {
                Error::Other(format!(
                    "{}: {what}; resume with the same settings or choose another --out",
                    path.display()
                ))
            }),
        }
    }

    /// `Err` with the first difference from `other`, said in words.
    pub fn agrees_with(&self, other: &RunSettings) -> std::result::Result<(), String> {
        if self.seed != other.seed {
            return Err(format!("the folder holds seed {}, this run has seed {}", other.seed, self.seed));
        }
        if self.method != other.method {
            return Err(format!("the folder holds method {}, this run has method {}", other.method, self.method));
        }
        if self.cell != other.cell {
            return Err("the folder holds results of another cell file".to_string());
        }
        Ok(())
    }
}
