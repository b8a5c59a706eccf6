//! Reporting long work alike in every dmu application: the import progress
//! bar's style and the process's peak memory.

use indicatif::{ProgressBar, ProgressStyle};

/// Styles the progress bar of an import's meshes (`pos` meshes of `len`).
pub fn style_mesh_bar(bar: &ProgressBar) {
    bar.set_style(
        ProgressStyle::with_template("{spinner} importing meshes {pos}/{len} [{bar:30}] {elapsed}")
            .expect("static template")
            .progress_chars("=> "),
    );
}

/// The process's peak resident set size in bytes (Linux `VmHWM`), or `None`
/// where the kernel does not report it.
pub fn peak_rss_bytes() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
}
