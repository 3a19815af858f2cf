//! docs/cluster.md's small Slurm array, run as the page gives it: the section
//! "A small Slurm array to try" holds two fenced blocks, the job script and the commands
//! that submit it and merge the parts. The test reads both from the page (so the page
//! cannot drift from what is tested), runs the commands in a temporary folder with the
//! built `camplace` first on PATH (sbatch passes the environment on to the job), and
//! checks the merged sweep against the same sweep run in one process without shards.
//!
//! When it runs: only with `CAMPLACE_SLURM=1` in the environment, which `.ci/run` sets
//! after starting a one-node Slurm with `scripts/slurm-one-node.sh`. Then a missing
//! `sbatch`, a failed job or a job not done within 20 minutes fails the test. Without the
//! variable the page's recipe is still read and checked for shape, and the test prints
//! that it skipped the submission; any other value of the variable fails the test.

use std::fs::File;
use std::io::Write;
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use crate::camplace_cmd::{camplace, stderr};
use crate::study_folder::{results_without_timings, summary_without_timings};

/// The page, as the user reads it.
const PAGE: &str = include_str!("../docs/cluster.md");
/// The heading of the recipe's section.
const SECTION: &str = "## A small Slurm array to try";
/// The name the commands give the job script.
const JOB_FILE: &str = "sweep-small.sbatch";
/// The longest the submitted array may take before the test gives up on it.
const JOB_DEADLINE: Duration = Duration::from_secs(20 * 60);

/// The fenced blocks of the section headed `heading`, up to the next heading.
fn fenced_blocks(page: &str, heading: &str) -> Vec<String> {
    let mut lines = page.lines().skip_while(|l| l.trim_end() != heading);
    assert!(lines.next().is_some(), "docs/cluster.md: no heading {heading:?}");
    let mut blocks = Vec::new();
    let mut open: Option<String> = None;
    for line in lines {
        match open.as_mut() {
            None if line.starts_with('#') => break,
            None if line.starts_with("```") => open = Some(String::new()),
            None => {}
            Some(_) if line.starts_with("```") => blocks.push(open.take().unwrap()),
            Some(block) => {
                block.push_str(line);
                block.push('\n');
            }
        }
    }
    assert!(open.is_none(), "docs/cluster.md: a fenced block under {heading:?} is not closed");
    blocks
}

/// The recipe: the job script and the commands, as the page has them.
struct Recipe {
    job: String,
    commands: String,
}

fn recipe() -> Recipe {
    let blocks = fenced_blocks(PAGE, SECTION);
    let [job, commands] = <[String; 2]>::try_from(blocks).unwrap_or_else(|b| {
        panic!("docs/cluster.md {SECTION:?}: expected two blocks (job script, commands), found {}", b.len())
    });
    assert!(job.starts_with("#!/bin/bash\n"), "the job script's first line is #!/bin/bash:\n{job}");
    assert!(
        commands.contains("sbatch --wait") && commands.contains(JOB_FILE),
        "the commands submit {JOB_FILE} with sbatch --wait:\n{commands}"
    );
    Recipe { job, commands }
}

/// The job script's `camplace sweep` as one process: its flags without `--shards`, and
/// `--out` replaced by `out`.
fn one_process_sweep(job: &str, out: &str) -> Vec<String> {
    let joined = job.replace("\\\n", " ");
    let line = joined.lines().map(str::trim).find(|l| l.starts_with("camplace sweep ")).unwrap_or_else(|| {
        panic!("the job script runs no `camplace sweep`:\n{job}");
    });
    let mut words = line.split_whitespace().skip(1);
    let (mut args, mut sharded) = (Vec::new(), false);
    while let Some(w) = words.next() {
        match w {
            "--shards" => {
                sharded = true;
                words.next();
            }
            "--out" => {
                words.next();
                args.extend(["--out".to_string(), out.to_string()]);
            }
            _ => {
                assert!(!w.contains(['$', '"', '\'']), "a flag the test cannot pass on as it is: {w}");
                args.push(w.to_string());
            }
        }
    }
    assert!(sharded, "the job's sweep is not split with --shards: {line}");
    args
}

/// Submits only with `CAMPLACE_SLURM=1`, and then fails if Slurm cannot run the array;
/// unset, it checks the recipe's shape and says it skipped.
#[test]
fn the_small_slurm_array_merges_to_the_sweep_run_in_one_process() {
    let recipe = recipe();
    let whole_args = one_process_sweep(&recipe.job, "whole");
    match std::env::var("CAMPLACE_SLURM").as_deref() {
        Ok("1") => {}
        Err(std::env::VarError::NotPresent) => {
            // Straight to stderr: the harness keeps eprintln! of a passing test to itself.
            let _ = writeln!(
                std::io::stderr(),
                "cluster: Slurm array not submitted: CAMPLACE_SLURM is not set (set it to 1 with \
                 Slurm up, e.g. after scripts/slurm-one-node.sh)"
            );
            return;
        }
        Ok(other) => panic!("CAMPLACE_SLURM={other:?}: expected 1 (submit the array) or unset (skip)"),
        Err(e) => panic!("CAMPLACE_SLURM: {e}"),
    }
    if let Err(e) = Command::new("sbatch").arg("--version").output() {
        panic!("CAMPLACE_SLURM=1 but sbatch cannot be run ({e}); start Slurm with scripts/slurm-one-node.sh");
    }

    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join(JOB_FILE), &recipe.job).unwrap();
    run_commands(d, &recipe.commands);

    let o = camplace(d, &whole_args.iter().map(String::as_str).collect::<Vec<_>>());
    assert!(o.status.success(), "camplace {}: {}", whole_args.join(" "), stderr(&o));
    let merged = summary_without_timings(&d.join("sweep/summary.json"));
    let whole = summary_without_timings(&d.join("whole/summary.json"));
    assert!(merged.as_array().is_some_and(|rows| !rows.is_empty()), "{merged}");
    assert_eq!(merged, whole, "summaries: merged array, then one process");
    let merged = results_without_timings(&d.join("sweep/results.jsonl"));
    let whole = results_without_timings(&d.join("whole/results.jsonl"));
    assert_eq!(merged.len(), whole.len(), "scenes: merged array, then one process");
    assert_eq!(merged, whole);
}

/// Runs the page's commands with bash in `dir`, `camplace` on PATH; panics with their
/// output and the jobs' logs when they fail or outlast [`JOB_DEADLINE`].
fn run_commands(dir: &Path, commands: &str) {
    let bin_dir = Path::new(env!("CARGO_BIN_EXE_camplace")).parent().unwrap();
    let path = std::env::join_paths(
        std::iter::once(bin_dir.to_path_buf())
            .chain(std::env::split_paths(&std::env::var_os("PATH").unwrap_or_default())),
    )
    .unwrap();
    let out = dir.join("commands.out");
    let mut child = Command::new("bash")
        .args(["-e", "-c", commands])
        .current_dir(dir)
        .env("PATH", path)
        .stdin(Stdio::null())
        .stdout(File::create(&out).unwrap())
        .stderr(File::create(dir.join("commands.err")).unwrap())
        .spawn()
        .expect("bash runs");
    let start = Instant::now();
    let status = loop {
        if let Some(status) = child.try_wait().unwrap() {
            break Some(status);
        }
        if start.elapsed() > JOB_DEADLINE {
            child.kill().unwrap();
            child.wait().unwrap();
            break None;
        }
        std::thread::sleep(Duration::from_millis(200));
    };
    if status.is_some_and(|s| s.success()) {
        return;
    }
    let stdout = std::fs::read_to_string(&out).unwrap_or_default();
    // sbatch prints "Submitted batch job N" as it submits; a job left behind is cancelled.
    let job_id = stdout.lines().find_map(|l| l.strip_prefix("Submitted batch job ")).map(str::trim);
    let queue = Command::new("squeue")
        .output()
        .map(|o| format!("{}{}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr)));
    if let (None, Some(id)) = (status, job_id) {
        let _ = Command::new("scancel").arg(id).status();
    }
    let mut logs = String::new();
    if let Ok(entries) = std::fs::read_dir(dir.join("logs")) {
        for e in entries.flatten() {
            let text = std::fs::read_to_string(e.path()).unwrap_or_default();
            logs.push_str(&format!("--- {}\n{text}", e.path().display()));
        }
    }
    panic!(
        "the page's commands {} (job {}):\n{commands}\n--- stdout\n{stdout}--- stderr\n{}--- squeue\n{}\n{logs}",
        match status {
            Some(s) => format!("failed: {s}"),
            None => format!("did not finish within {} s", JOB_DEADLINE.as_secs()),
        },
        job_id.unwrap_or("not submitted"),
        std::fs::read_to_string(dir.join("commands.err")).unwrap_or_default(),
        queue.unwrap_or_else(|e| format!("squeue: {e}")),
    );
}
