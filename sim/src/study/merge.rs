//! Joining the folders of shards (or of any runs with the same settings) into one: the
//! union of their results (a scene found twice is kept once), then the summaries and plots
//! computed again. A study's folder tree is merged folder by folder. Every folder given must
//! be a study folder (`settings.json`) or hold study folders below it, laid out alike.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

use camplace_config::remove_stale_temp_files;

use super::results::{append_rejected, read_results_unchanged, write_lines, ResultLine, ResultsStore, REJECTED_FILE};
use super::settings::RunSettings;
use super::sweep::load_sweep;
use crate::report::sweep_panels::write_sweep_outputs;
use crate::report::table::{write_summary_csv, write_summary_json, SummaryRow};
use crate::{Error, Result};
use camplace_estimator::scoring::Summary;

/// Merges `dirs` into `out`; returns the scenes joined. Each of `dirs` is a study folder, or
/// a tree of them (a study's `TRAY/METHOD/` folders) merged folder by folder.
pub fn merge(dirs: &[PathBuf], out: &Path) -> Result<usize> {
    let mut leaves: BTreeMap<PathBuf, Vec<PathBuf>> = BTreeMap::new();
    for d in dirs {
        let found = study_folders(d, Path::new(""))?;
        if found.is_empty() {
            return Err(Error::Other(format!(
                "{}: not a study folder: no settings.json in it or in its sub-folders",
                d.display()
            )));
        }
        for rel in found {
            leaves.entry(rel).or_default().push(d.clone());
        }
    }
    // A study folder merged with a tree of them: their results cannot be put side by side.
    if let Some(top) = leaves.get(Path::new("")) {
        if let Some(other) = dirs.iter().find(|d| !top.contains(d)) {
            return Err(Error::Other(format!(
                "{}: expected a study folder (settings.json) like {}, found a folder of study folders",
                other.display(),
                top[0].display()
            )));
        }
    }
    check_out(dirs, out, &leaves)?;
    let mut total = 0;
    for (rel, sources) in leaves {
        let sources: Vec<PathBuf> = sources.iter().map(|d| d.join(&rel)).collect();
        total += merge_leaf(&sources, &out.join(&rel))?;
    }
    Ok(total)
}

/// Refuses an `--out` that would mix or lose data: one that is, holds or lies in a folder
/// merged (a merge never writes into its inputs), one holding results without the settings
/// they were computed with, and one holding study folders laid out unlike the inputs (a
/// study tree where one study folder is merged, or the reverse). Nothing is written first.
fn check_out(dirs: &[PathBuf], out: &Path, leaves: &BTreeMap<PathBuf, Vec<PathBuf>>) -> Result<()> {
    let out_abs = absolute(out);
    for d in dirs {
        let d_abs = absolute(d);
        if out_abs.starts_with(&d_abs) || d_abs.starts_with(&out_abs) {
            return Err(Error::Other(format!(
                "--out {}: is, holds or lies in {}, a folder being merged; a merge never writes into its inputs: give a new folder",
                out.display(),
                d.display()
            )));
        }
    }
    if !out.exists() {
        return Ok(());
    }
    for rel in leaves.keys() {
        let here = out.join(rel);
        if here.join("results.jsonl").exists() && !here.join("settings.json").exists() {
            return Err(Error::Other(format!(
                "--out {}: holds results (results.jsonl) without the settings they were computed with (settings.json); give a new folder",
                here.display()
            )));
        }
    }
    for rel in study_folders(out, Path::new(""))? {
        if !leaves.contains_key(&rel) {
            let (what, expected) = if rel.as_os_str().is_empty() {
                ("is a study folder", "a folder of study folders")
            } else {
                ("holds the study folder", "laid out like the inputs")
            };
            return Err(Error::Other(format!(
                "--out {}: {what} {}, not {expected} (a study tree and a study folder cannot be merged into one another); give a new folder",
                out.display(),
                out.join(&rel).display()
            )));
        }
    }
    Ok(())
}

/// `path` made absolute with its links resolved, as far as it exists.
fn absolute(path: &Path) -> PathBuf {
    if let Ok(p) = path.canonicalize() {
        return p;
    }
    match (path.parent(), path.file_name()) {
        (Some(parent), Some(name)) if !parent.as_os_str().is_empty() => absolute(parent).join(name),
        (_, Some(name)) => std::env::current_dir().map(|d| d.join(name)).unwrap_or_else(|_| path.to_path_buf()),
        _ => path.to_path_buf(),
    }
}

/// The study folders at or below `dir`, relative to it (`""` for `dir` itself); a study
/// folder's own sub-folders (its model cache) are not searched.
fn study_folders(dir: &Path, rel: &Path) -> Result<Vec<PathBuf>> {
    let here = dir.join(rel);
    if here.join("settings.json").exists() {
        return Ok(vec![rel.to_path_buf()]);
    }
    let cannot_list = |e: std::io::Error| Error::Other(format!("{}: cannot list: {e}", here.display()));
    let mut names = BTreeSet::new();
    for entry in std::fs::read_dir(&here).map_err(cannot_list)? {
        let entry = entry.map_err(cannot_list)?;
        if entry.path().is_dir() {
            names.insert(entry.file_name());
        }
    }
    let mut found = Vec::new();
    for name in names {
        found.extend(study_folders(dir, &rel.join(name))?);
    }
    Ok(found)
}

fn merge_leaf(dirs: &[PathBuf], out: &Path) -> Result<usize> {
    let mut settings: Option<(PathBuf, RunSettings)> = None;
    let mut sweep = None;
    let mut lines: BTreeMap<_, ResultLine> = BTreeMap::new();
    let mut sources: Vec<PathBuf> = dirs.to_vec();
    // An earlier merge's folder keeps its scenes (check_out made sure it is no input).
    if out.join("settings.json").exists() {
        sources.push(out.to_path_buf());
    }
    let rejected_to = out.join(REJECTED_FILE);
    let mut rejected = Vec::new();
    for d in &sources {
        let s = RunSettings::load(d)?
            .ok_or_else(|| Error::Other(format!("{}: expected a study folder (settings.json)", d.display())))?;
        match &mut settings {
            None => settings = Some((d.clone(), s)),
            Some((first_dir, first)) => {
                if let Some(d2) = first.difference(&s) {
                    return Err(Error::Other(d2.between(first_dir, d)));
                }
                // Keep settings that record the cell's hash, if any folder has them.
                if first.cell_hash.is_none() && s.cell_hash.is_some() {
                    *first = s;
                }
            }
        }
    }
    // The settings agree: the output is held (created if new) while it is read and written.
    let _lock = super::lock::lock_folder(out)?;
    for d in &sources {
        if sweep.is_none() {
            sweep = load_sweep(d)?;
        }
        let path = d.join("results.jsonl");
        if path.exists() {
            let read = read_results_unchanged(&path)?;
            if !read.rejected.is_empty() {
                rejected.push((path, read.clone()));
            }
            for l in read.lines {
                lines.entry(l.key()).or_insert(l);
            }
        }
    }
    let (_, settings) = settings.expect("at least one folder");
    std::fs::create_dir_all(out)
        .map_err(|e| Error::Other(format!("{}: cannot create the folder: {e}", out.display())))?;
    remove_stale_temp_files(out)?;
    for (path, read) in &rejected {
        append_rejected(&rejected_to, read)?;
        let became = format!("copied to {}; their scenes are left out of the merge", rejected_to.display());
        eprintln!("{}", read.rejected_note(path, &became));
    }
    let joined: Vec<ResultLine> = lines.into_values().collect();
    write_lines(&out.join("results.jsonl"), &joined)?;
    settings.save(out)?;
    let method = settings.method()?;
    let store = ResultsStore::open(&out.join("results.jsonl"))?;
    if let Some((grid, n, base)) = sweep {
        let text = serde_json::to_string_pretty(&(&grid, n, base)).expect("plain data");
        camplace_config::write_atomic(&out.join("sweep.json"), text.as_bytes())?;
        let placements = grid.placements(&base)?;
        write_sweep_outputs(out, &settings.cell, &grid, &placements, &store, method, settings.seed, n)?;
    } else {
        // One row per placement and seed, over every scene found.
        let mut groups: BTreeMap<(String, u64), Vec<_>> = BTreeMap::new();
        for l in &joined {
            groups.entry((l.placement.clone(), l.seed)).or_default().push(l.record.clone());
        }
        let rows: Vec<SummaryRow> = groups
            .into_iter()
            .map(|((placement, seed), records)| SummaryRow {
                placement,
                method: method.to_string(),
                seed,
                summary: Summary::from_records(&records).verified(
                    &records,
                    settings.cell.estimator.verify_max_wrong,
                    &settings.cell.metrics,
                ),
            })
            .collect();
        write_summary_json(&out.join("summary.json"), &rows)?;
        write_summary_csv(&out.join("summary.csv"), &rows)?;
    }
    Ok(joined.len())
}
