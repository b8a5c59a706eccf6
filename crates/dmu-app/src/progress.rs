//! Reporting long work alike in every dmu application: the progress bars'
//! styles (an import's meshes, an input read as it is processed) and the
//! process's peak memory.

use indicatif::{ProgressBar, ProgressStyle};

/// Styles the progress bar of an import's meshes (`pos` meshes of `len`).
pub fn style_mesh_bar(bar: &ProgressBar) {
    bar.set_style(
        ProgressStyle::with_template("{spinner} importing meshes {pos}/{len} [{bar:30}] {elapsed}")
            .expect("static template")
            .progress_chars("=> "),
    );
}

/// Styles the progress bar of an input read as it is processed (`pos` bytes
/// read): a bar of the input's length when `known_length`, else (standard
/// input) a spinner with the bytes read so far.
pub fn style_input_bar(bar: &ProgressBar, what: &str, known_length: bool) {
    let template = if known_length {
        "{spinner} {msg} {bytes}/{total_bytes} [{bar:30}] {elapsed}, {eta} left"
    } else {
        "{spinner} {msg} {bytes} read {elapsed}"
    };
    bar.set_style(
        ProgressStyle::with_template(template)
            .expect("static template")
            .progress_chars("=> "),
    );
    bar.set_message(what.to_owned());
}

/// The process's peak resident set size in bytes (Linux `VmHWM`), or `None`
/// where the kernel does not report it.
pub fn peak_rss_bytes() -> Option<u64> {
    status_bytes("VmHWM:")
}

/// The process's resident set size now in bytes (Linux `VmRSS`), or `None`
/// where the kernel does not report it.
pub fn rss_bytes() -> Option<u64> {
    status_bytes("VmRSS:")
}

/// The memory the system can give without swapping, in bytes (Linux
/// `MemAvailable`), or `None` where the kernel does not report it.
pub fn available_memory_bytes() -> Option<u64> {
    kib_line("/proc/meminfo", "MemAvailable:")
}

/// A `/proc/self/status` line in KiB, as bytes.
fn status_bytes(key: &str) -> Option<u64> {
    kib_line("/proc/self/status", key)
}

/// The line of `file` starting with `key`, its number in KiB, as bytes.
fn kib_line(file: &str, key: &str) -> Option<u64> {
    let text = std::fs::read_to_string(file).ok()?;
    let line = text.lines().find(|l| l.starts_with(key))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    kib.checked_mul(1024)
}

/// Makes the proxies of every subtree of `tree` (`dmu_render::Proxies`) from
/// the chunks in `source`, with a progress bar on standard error unless
/// `quiet`.
pub fn build_proxies(
    scene: &dmu_scene::Scene,
    tree: &dmu_tree::Tree,
    source: &dyn dmu_render::GeometrySource,
    quiet: bool,
) -> dmu_render::Proxies {
    let bar = if quiet {
        ProgressBar::hidden()
    } else {
        ProgressBar::new(0)
    };
    bar.set_style(
        ProgressStyle::with_template("{spinner} merging subtrees {pos}/{len} [{bar:30}] {elapsed}")
            .expect("static template")
            .progress_chars("=> "),
    );
    let proxies = dmu_render::Proxies::build(
        scene,
        tree,
        source,
        dmu_render::ProxyOptions::default(),
        &mut |done, total| {
            bar.set_length(total as u64);
            bar.set_position(done as u64);
        },
    );
    bar.finish_and_clear();
    proxies
}

/// A proxy build's figures as JSON: current proxies, their triangles and
/// bytes, and the build time.
pub fn proxies_json(stats: &dmu_render::ProxyStats) -> serde_json::Value {
    serde_json::json!({
        "proxies": stats.proxies,
        "stale": stats.stale,
        "solid": stats.solid,
        "triangles": stats.triangles,
        "bytes": stats.bytes,
        "made": stats.made,
        "ms": stats.ms,
    })
}
