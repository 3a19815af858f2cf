//! Joining the folders of shards (or of any runs with the same settings) into one: the
//! union of their results (a scene found twice is kept once), then the summaries and plots
//! computed again. A study's folder tree is merged folder by folder.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

use super::results::{read_lines, write_lines, ResultLine, ResultsStore};
use super::settings::RunSettings;
use super::summary::Summary;
use super::sweep::load_sweep;
use crate::report::sweep_panels::write_sweep_outputs;
use crate::report::table::{write_summary_csv, write_summary_json, SummaryRow};
use crate::{Error, Result};

/// Merges `dirs` into `out`, recursing where no settings are found; returns scenes joined.
pub fn merge(dirs: &[PathBuf], out: &Path) -> Result<usize> {
    let with_settings: Vec<&PathBuf> = dirs.iter().filter(|d| d.join("settings.json").exists()).collect();
    if !with_settings.is_empty() {
        return merge_leaf(&with_settings, out);
    }
    let mut names = BTreeSet::new();
    for d in dirs {
        let cannot_list = |e: std::io::Error| Error::Other(format!("{}: cannot list: {e}", d.display()));
        for entry in std::fs::read_dir(d).map_err(cannot_list)? {
            let entry = entry.map_err(cannot_list)?;
            if entry.path().is_dir() {
                names.insert(entry.file_name());
            }
        }
    }
    let mut total = 0;
    for name in names {
        let subs: Vec<PathBuf> = dirs.iter().map(|d| d.join(&name)).filter(|p| p.is_dir()).collect();
        total += merge(&subs, &out.join(&name))?;
    }
    Ok(total)
}

fn merge_leaf(dirs: &[&PathBuf], out: &Path) -> Result<usize> {
    let mut settings: Option<RunSettings> = None;
    let mut sweep = None;
    let mut lines: BTreeMap<_, ResultLine> = BTreeMap::new();
    let mut sources: Vec<PathBuf> = dirs.iter().map(|d| d.to_path_buf()).collect();
    if out.join("settings.json").exists() && !sources.iter().any(|s| same(s, out)) {
        sources.push(out.to_path_buf());
    }
    for d in &sources {
        let s =
            RunSettings::load(d)?.ok_or_else(|| Error::Other(format!("{}: expected settings.json", d.display())))?;
        match &settings {
            None => settings = Some(s),
            Some(first) => {
                if let Err(what) = s.agrees_with(first) {
                    return Err(Error::Other(format!(
                        "{}: {what} (the folders were run with other settings)",
                        d.join("settings.json").display()
                    )));
                }
            }
        }
        if sweep.is_none() {
            sweep = load_sweep(d)?;
        }
        let path = d.join("results.jsonl");
        if path.exists() {
            for l in read_lines(&path)? {
                lines.entry(l.key()).or_insert(l);
            }
        }
    }
    let settings = settings.expect("at least one folder");
    std::fs::create_dir_all(out)
        .map_err(|e| Error::Other(format!("{}: cannot create the folder: {e}", out.display())))?;
    let joined: Vec<ResultLine> = lines.into_values().collect();
    write_lines(&out.join("results.jsonl"), &joined)?;
    let text = serde_json::to_string_pretty(&settings).expect("plain data");
    camplace_config::write_atomic(&out.join("settings.json"), text.as_bytes())?;
    let method = settings.method()?;
    let store = ResultsStore::open(&out.join("results.jsonl"))?;
    if let Some((grid, n, base)) = sweep {
        let text = serde_json::to_string_pretty(&(&grid, n, base)).expect("plain data");
        camplace_config::write_atomic(&out.join("sweep.json"), text.as_bytes())?;
        let placements = grid.placements(&base)?;
        write_sweep_outputs(out, &grid, &placements, &store, method, settings.seed, n)?;
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
                summary: Summary::from_records(&records),
            })
            .collect();
        write_summary_json(&out.join("summary.json"), &rows)?;
        write_summary_csv(&out.join("summary.csv"), &rows)?;
    }
    Ok(joined.len())
}

fn same(a: &Path, b: &Path) -> bool {
    match (a.canonicalize(), b.canonicalize()) {
        (Ok(x), Ok(y)) => x == y,
        _ => a == b,
    }
}
