//! Where a result file's numbers came from: date, commit (and whether the tree was dirty),
//! CPU model, core count and load average, written into every generated result.

/// Output of a command, trimmed, or `?`.
fn run(cmd: &str, args: &[&str]) -> String {
    std::process::Command::new(cmd)
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .ok()
        .filter(|o| o.status.success())
        .and_then(|o| String::from_utf8(o.stdout).ok())
        .map_or_else(|| "?".to_string(), |s| s.trim().to_string())
}

/// Date, commit, CPU model and load average, for the record.
pub fn note() -> String {
    let date = run("date", &["-u", "+%Y-%m-%d %H:%M UTC"]);
    let commit = run("git", &["rev-parse", "--short", "HEAD"]);
    let dirty = run("git", &["status", "--porcelain", "--untracked-files=no"]);
    let commit = if dirty.is_empty() || dirty == "?" {
        commit
    } else {
        format!("{commit} with uncommitted changes")
    };
    format!("{date}, commit {commit}; {}", machine_cpu())
}

/// CPU model and load average.
fn machine_cpu() -> String {
    let cpu = std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("model name"))
                .and_then(|l| l.split(':').nth(1))
                .map(|s| s.trim().to_string())
        })
        .unwrap_or_else(|| "unknown CPU".into());
    let cores = std::thread::available_parallelism().map_or(0, |n| n.get());
    let load = std::fs::read_to_string("/proc/loadavg")
        .ok()
        .and_then(|s| s.split_whitespace().next().map(str::to_string))
        .unwrap_or_else(|| "?".into());
    format!("{cpu}, {cores} cores, load average {load} at the end")
}
