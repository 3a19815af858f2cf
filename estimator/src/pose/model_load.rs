//! A model file read from disk, and the check that it was built for the tray a cell holds:
//! the one place `estimate`, `replay`, `run`, `serve`, `trial` and embedders load a model. The bytes come
//! through camplace-config's bounded reader (the model's size budget); decoding is
//! `Model::from_bytes`'s.

use std::path::Path;

use camplace_config::{Cell, FileKind};

use crate::{Error, ErrorKind, Model, Result};

fn from_config(e: camplace_config::Error) -> Error {
    Error::with_source(ErrorKind::Model, e.to_string(), e)
}

impl Model {
    /// Reads the model file at `path` for `cell`: checked against the cell's tray
    /// ([`Model::load_for`]) when the cell was read from `cell_file`, as read
    /// ([`Model::load`]) when it is the built-in default.
    pub fn load_checked(path: &Path, cell: &Cell, cell_file: Option<&Path>) -> Result<Model> {
        match cell_file {
            Some(file) => Model::load_for(path, cell, file),
            None => Model::load(path),
        }
    }

    /// Reads and decodes the model file at `path`; errors name the file.
    pub fn load(path: &Path) -> Result<Model> {
        let bytes = camplace_config::read_bounded(path, FileKind::Model).map_err(from_config)?;
        Model::from_bytes(&bytes).map_err(|e| {
            Error::with_source(ErrorKind::Model, format!("{}: not a usable model file: {e}", path.display()), e)
        })
    }

    /// Reads the model file at `path` and checks that it was built for the tray of `cell`
    /// (read from `cell_file`, named in the error): the same tray and items geometry. A
    /// model that records no origin (written by an earlier camplace) is refused too, as it
    /// cannot be checked.
    pub fn load_for(path: &Path, cell: &Cell, cell_file: &Path) -> Result<Model> {
        let model = Model::load(path)?;
        let tray_hash = cell.hashes().map_err(from_config)?.tray;
        let rebuild = format!("rebuild it with camplace model --cell {}", cell_file.display());
        match &model.origin {
            None => Err(Error::new(
                ErrorKind::Model,
                format!(
                    "{}: the model records no tray it was built for (an earlier camplace wrote it); {rebuild}",
                    path.display()
                ),
            )),
            Some(o) if o.tray_hash != tray_hash => Err(Error::new(
                ErrorKind::Model,
                format!(
                    "{}: built for tray {} (geometry {}), but {} has tray {} (geometry {}); {rebuild}",
                    path.display(),
                    o.tray,
                    o.tray_hash.short(),
                    cell_file.display(),
                    cell.tray_name(),
                    tray_hash.short()
                ),
            )),
            Some(_) => Ok(model),
        }
    }
}
