//! STEP and IFC, read through a converter: a Python script (`cad/convert.py`,
//! carried in the binary) reads STEP with OpenCascade (the `OCP` wheel) and
//! IFC with IfcOpenShell, tessellates in parallel, and writes binary glTF in
//! millimetres with the assembly, instancing, colours and each node's
//! properties (GlobalId, IFC class, STEP product) as node `extras`. The glTF
//! import then reads it like any other file, every reference checked.
//!
//! The script runs with `DMU_PYTHON`, or `python3` on the PATH, which must
//! have the packages (`pip install 'dmu[cad]'`); without them the error names
//! the package and the command that installs it. It writes its glTF into a
//! scratch folder that is removed afterwards, and reports progress, each
//! product it could not tessellate (left out, the rest imported) and a
//! summary as JSON lines on its standard output.

use std::io::{BufRead as _, BufReader, Read as _, Write as _};
use std::ops::RangeInclusive;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

use dmu_scene::FailedProduct;
use serde::{Deserialize, Serialize};

use crate::error::StoreError;

/// The converter, run by the Python interpreter.
const CONVERTER: &str = include_str!("cad/convert.py");

/// Extensions read through the converter (compared without case).
pub const CAD_EXTENSIONS: [&str; 3] = ["step", "stp", "ifc"];

/// Whether `path` names a STEP or IFC file (by its extension).
pub fn is_cad(path: &Path) -> bool {
    path.extension().is_some_and(|e| {
        CAD_EXTENSIONS
            .iter()
            .any(|c| e.eq_ignore_ascii_case(std::ffi::OsStr::new(c)))
    })
}

/// The relative deflections taken: past half a part's size a mesh loses
/// the part; below a millionth it only costs time.
pub const DEFLECTION_RANGE: RangeInclusive<f64> = 1e-6..=0.5;
/// The angular deflections taken, radians.
pub const ANGULAR_DEFLECTION_RANGE: RangeInclusive<f64> = 0.01..=1.5;

/// How CAD files are tessellated and which IFC classes are kept.
#[derive(Clone, Debug, PartialEq)]
pub struct CadOptions {
    /// STEP: the largest distance between a surface and its triangles, as a
    /// fraction of each part's size (OpenCascade's relative deflection).
    pub deflection: f64,
    /// STEP: the largest angle between the normals of neighbouring
    /// triangles of a curved face, radians.
    pub angular_deflection: f64,
    /// IFC classes kept that are left out by default (`IfcSpace`,
    /// `IfcOpeningElement`: volumes that coincide with rooms and walls).
    pub ifc_include: Vec<String>,
    /// Tessellating processes; `None` for one per core.
    pub threads: Option<usize>,
    /// The Python interpreter; `None` for `DMU_PYTHON`, else `python3`.
    pub python: Option<PathBuf>,
}

impl CadOptions {
    /// Whether the deflections are finite and within [`DEFLECTION_RANGE`]
    /// and [`ANGULAR_DEFLECTION_RANGE`]; the error names the one that is not.
    pub fn check(&self) -> Result<(), String> {
        for (name, v, range) in [
            ("deflection", self.deflection, DEFLECTION_RANGE),
            (
                "angular_deflection",
                self.angular_deflection,
                ANGULAR_DEFLECTION_RANGE,
            ),
        ] {
            if !(v.is_finite() && range.contains(&v)) {
                return Err(format!(
                    "{name} {v}: expected {} to {}",
                    dmu_geom::Short(*range.start()),
                    dmu_geom::Short(*range.end())
                ));
            }
        }
        Ok(())
    }
}

impl Default for CadOptions {
    fn default() -> Self {
        Self {
            deflection: 0.001,
            angular_deflection: 0.5,
            ifc_include: Vec::new(),
            threads: None,
            python: None,
        }
    }
}

/// What the converter made of a file.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct CadSummary {
    /// `STEP`, or the IFC schema (`IFC2X3`, `IFC4`, ...).
    pub format: String,
    /// Products written.
    pub products: u64,
    /// Products left out because they could not be tessellated.
    pub failed: u64,
    /// Triangles, instances counted.
    pub triangles: u64,
    /// Triangles stored once per shape.
    pub unique_triangles: u64,
    /// Distinct shapes (glTF meshes).
    pub meshes: u64,
    /// Seconds the conversion took.
    pub seconds: f64,
    /// The converter's peak resident set, bytes.
    #[serde(default)]
    pub peak_rss_bytes: u64,
}

/// A converted file: the glTF in a scratch folder removed on drop, and what
/// the converter reported.
#[derive(Debug)]
pub struct Converted {
    /// Removed with its contents when dropped.
    _scratch: tempfile::TempDir,
    /// The binary glTF written, named after the input (the scene's name is
    /// the file's stem).
    pub glb: PathBuf,
    /// The summary.
    pub summary: CadSummary,
    /// Products left out.
    pub failed: Vec<FailedProduct>,
}

/// One line of the converter's output.
#[derive(Deserialize)]
#[serde(rename_all = "lowercase")]
enum Line {
    Progress([u64; 2]),
    Failed(FailedProduct),
    Summary(CadSummary),
}

/// Converts the STEP or IFC file `input` to binary glTF in a scratch folder
/// made in `scratch_in` (beside the output, so a large model's glTF lands on
/// the output's disk), telling `progress` the products done and in all.
pub fn convert(
    input: &Path,
    scratch_in: &Path,
    options: &CadOptions,
    progress: Option<&(dyn Fn(usize, usize) + Sync)>,
) -> Result<Converted, StoreError> {
    let failed = |what: String| StoreError::Convert {
        path: input.to_owned(),
        what,
    };
    let io = |what: &str, e: std::io::Error| failed(format!("{what}: {e}"));
    // Read here, once: the converter gets a path it cannot be told apart
    // from, and a folder or a missing file is named as such.
    dmu_scene::open_regular_file(input).map_err(|source| StoreError::Io {
        path: input.to_owned(),
        source,
    })?;
    let scratch = tempfile::Builder::new()
        .prefix(".dmu-convert-")
        .tempdir_in(scratch_in)
        .map_err(|e| {
            io(
                &format!("making a scratch folder in {}", scratch_in.display()),
                e,
            )
        })?;
    let script = scratch.path().join("convert.py");
    let mut name = input
        .file_stem()
        .unwrap_or(std::ffi::OsStr::new("model"))
        .to_os_string();
    name.push(".glb");
    let glb = scratch.path().join(name);
    std::fs::write(&script, CONVERTER).map_err(|e| io("writing the converter", e))?;
    let python = options
        .python
        .clone()
        .or_else(|| {
            std::env::var_os("DMU_PYTHON")
                .filter(|p| !p.is_empty())
                .map(PathBuf::from)
        })
        .unwrap_or_else(|| "python3".into());
    let mut command = Command::new(&python);
    command
        .arg(&script)
        .arg("--deflection")
        .arg(options.deflection.to_string())
        .arg("--angular-deflection")
        .arg(options.angular_deflection.to_string());
    if !options.ifc_include.is_empty() {
        command
            .arg("--ifc-include")
            .arg(options.ifc_include.join(","));
    }
    if let Some(threads) = options.threads {
        command.arg("--threads").arg(threads.to_string());
    }
    // After `--`, a file named `-x.ifc` is a file.
    command.arg("--").arg(input).arg(&glb);
    let child = command
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .map_err(|e| {
            failed(match e.kind() {
                std::io::ErrorKind::NotFound => format!(
                    "reading STEP and IFC needs Python 3 with OCP and ifcopenshell, and {} was not found (set DMU_PYTHON, then pip install 'dmu[cad]')",
                    python.display()
                ),
                _ => format!("starting {}: {e}", python.display()),
            })
        })?;
    let mut running = Running(Some(child));
    let child = running.0.as_mut().expect("just started");
    // Standard error on its own thread, so that neither pipe fills while
    // the other is read; its last lines are kept.
    let stderr = child.stderr.take().expect("piped");
    let errors = std::thread::spawn(move || tail(stderr, ERROR_TAIL_BYTES));
    let output = read_output(child.stdout.take().expect("piped"), progress).map_err(failed)?;
    let status = running
        .wait()
        .map_err(|e| io("waiting for the converter", e))?;
    let errors = errors.join().unwrap_or_default();
    if !status.success() {
        use std::os::unix::process::ExitStatusExt as _;
        // The converter's error is its last line; its own name of the file
        // is replaced by ours.
        let last = errors.lines().rev().find(|l| !l.trim().is_empty());
        let what = match (status.signal(), last) {
            (Some(9), _) => "the converter was killed by signal 9 (out of memory?)".into(),
            (Some(signal), _) => format!("the converter was killed by signal {signal}"),
            (None, Some(line)) => strip_file_name(line, input)
                .chars()
                .map(|c| if c.is_control() { '\u{fffd}' } else { c })
                .collect(),
            (None, None) => format!("the converter failed ({status})"),
        };
        return Err(failed(what));
    }
    let summary = output
        .summary
        .ok_or_else(|| failed("the converter wrote no summary".into()))?;
    Ok(Converted {
        _scratch: scratch,
        glb,
        summary,
        failed: output.failed,
    })
}

/// The most bytes one line of the converter's output may hold.
const MAX_LINE_BYTES: u64 = 1 << 20;
/// The bytes kept of the end of the converter's error output.
const ERROR_TAIL_BYTES: usize = 64 << 10;

/// The converter while it runs: killed and reaped if dropped before it
/// ended (an error reading its output leaves no process behind).
struct Running(Option<std::process::Child>);

impl Running {
    /// Waits for it to end.
    fn wait(&mut self) -> std::io::Result<std::process::ExitStatus> {
        let status = self.0.as_mut().expect("not yet waited for").wait()?;
        self.0 = None;
        Ok(status)
    }
}

impl Drop for Running {
    fn drop(&mut self) {
        if let Some(child) = &mut self.0 {
            let _ = child.kill();
            let _ = child.wait();
        }
    }
}

/// What the converter's standard output said.
#[derive(Default)]
struct Output {
    summary: Option<CadSummary>,
    failed: Vec<FailedProduct>,
}

/// Reads the converter's JSON lines (each at most [`MAX_LINE_BYTES`]),
/// telling `progress`; another line a package printed is passed on to
/// standard error, escaped.
fn read_output(
    out: impl std::io::Read,
    progress: Option<&(dyn Fn(usize, usize) + Sync)>,
) -> Result<Output, String> {
    let mut reader = BufReader::new(out);
    let mut output = Output::default();
    let mut line = Vec::new();
    loop {
        line.clear();
        let n = (&mut reader)
            .take(MAX_LINE_BYTES)
            .read_until(b'\n', &mut line)
            .map_err(|e| format!("reading the converter's output: {e}"))?;
        if n == 0 {
            return Ok(output);
        }
        if n as u64 == MAX_LINE_BYTES && line.last() != Some(&b'\n') {
            return Err(format!(
                "the converter wrote a line over {MAX_LINE_BYTES} bytes"
            ));
        }
        let text = String::from_utf8_lossy(&line);
        let text = text.trim_end();
        match serde_json::from_str::<Line>(text) {
            Ok(Line::Progress([done, total])) => {
                if let Some(progress) = progress {
                    progress(done as usize, total as usize);
                }
            }
            Ok(Line::Failed(product)) => output.failed.push(product),
            Ok(Line::Summary(s)) => output.summary = Some(s),
            Err(e) if text.starts_with("{\"summary\"") => {
                return Err(format!("the converter's summary is malformed: {e}"));
            }
            Err(_) => {
                let shown: String = text.chars().take(200).collect();
                let _ = writeln!(
                    std::io::stderr(),
                    "dmu: converter: {}",
                    shown.escape_debug()
                );
            }
        }
    }
}

/// The last `keep` bytes `from` gives before it ends (lossy UTF-8).
fn tail(mut from: impl std::io::Read, keep: usize) -> String {
    let mut kept = Vec::new();
    let mut buf = [0u8; 8192];
    while let Ok(n @ 1..) = from.read(&mut buf) {
        kept.extend_from_slice(&buf[..n]);
        if kept.len() > 2 * keep {
            kept.drain(..kept.len() - keep);
        }
    }
    let start = kept.len().saturating_sub(keep);
    String::from_utf8_lossy(&kept[start..]).into_owned()
}

/// `line` without a leading "<file name>: ", which the caller's error adds.
fn strip_file_name<'a>(line: &'a str, input: &Path) -> &'a str {
    let name = input.file_name().map(|n| n.to_string_lossy().into_owned());
    name.and_then(|n| line.strip_prefix(&format!("{n}: ")).map(str::trim))
        .unwrap_or(line.trim())
}

#[cfg(test)]
mod tests {
    use std::os::unix::fs::PermissionsExt as _;

    use super::*;

    /// `convert` of an empty `m.ifc` with `script` (a shell script) in
    /// place of Python: its error.
    fn converted_by(script: &str) -> String {
        let dir = tempfile::tempdir().unwrap();
        let input = dir.path().join("m.ifc");
        std::fs::write(&input, "").unwrap();
        let python = dir.path().join("python");
        std::fs::write(&python, format!("#!/bin/sh\n{script}\n")).unwrap();
        std::fs::set_permissions(&python, std::fs::Permissions::from_mode(0o755)).unwrap();
        let options = CadOptions {
            python: Some(python),
            ..CadOptions::default()
        };
        let err = convert(&input, dir.path(), &options, None)
            .unwrap_err()
            .to_string();
        let left: Vec<_> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .filter(|n| n.to_string_lossy().starts_with(".dmu-convert-"))
            .collect();
        assert!(left.is_empty(), "scratch folders left: {left:?}");
        err
    }

    #[test]
    fn a_misbehaving_converter_is_one_line_naming_what_it_did() {
        let killed = converted_by("echo 'warning: harmless' >&2; kill -9 $$");
        assert!(
            killed.ends_with("m.ifc: the converter was killed by signal 9 (out of memory?)"),
            "{killed}"
        );
        let long = converted_by("head -c 2000000 /dev/zero | tr '\\0' x");
        assert!(long.contains("a line over 1048576 bytes"), "{long}");
        let garbage = converted_by(r#"echo '{"summary": {"format": 3}}'"#);
        assert!(garbage.contains("summary is malformed"), "{garbage}");
        let silent = converted_by("exit 0");
        assert!(
            silent.ends_with("m.ifc: the converter wrote no summary"),
            "{silent}"
        );
        let failed = converted_by("echo 'm.ifc: not an IFC file (\x1b[2J)' >&2; exit 2");
        assert!(
            failed.ends_with("m.ifc: not an IFC file (\u{fffd}[2J)"),
            "{failed}"
        );
    }

    #[test]
    fn a_converter_whose_output_cannot_be_read_is_not_left_running() {
        let dir = tempfile::tempdir().unwrap();
        let pid = dir.path().join("pid");
        let err = converted_by(&format!(
            "echo $$ > {}; head -c 2000000 /dev/zero; sleep 30",
            pid.display()
        ));
        assert!(err.contains("a line over"), "{err}");
        let pid = std::fs::read_to_string(&pid).unwrap();
        // Killed and reaped: no such process (a zombie would still be there).
        assert!(
            !Path::new(&format!("/proc/{}", pid.trim())).exists(),
            "{pid} still runs"
        );
    }

    #[test]
    fn the_file_comes_after_the_options_and_a_double_dash() {
        let dir = tempfile::tempdir().unwrap();
        let args = dir.path().join("args");
        converted_by(&format!("printf '%s\\n' \"$@\" > {}", args.display()));
        let args = std::fs::read_to_string(&args).unwrap();
        let args: Vec<&str> = args.lines().collect();
        let n = args.len();
        assert_eq!(args[n - 3], "--", "{args:?}");
        assert!(
            args[n - 2].ends_with("m.ifc") && args[n - 1].ends_with("m.glb"),
            "{args:?}"
        );
    }
}
