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
        .map_err(|e| io("making a scratch folder", e))?;
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
        .or_else(|| std::env::var_os("DMU_PYTHON").map(PathBuf::from))
        .unwrap_or_else(|| "python3".into());
    let mut command = Command::new(&python);
    command
        .arg(&script)
        .arg(input)
        .arg(&glb)
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
    let mut child = command
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
    // Standard error on its own thread, so that neither pipe fills while
    // the other is read.
    let mut stderr = child.stderr.take().expect("piped");
    let errors = std::thread::spawn(move || {
        let mut text = String::new();
        let _ = stderr.read_to_string(&mut text);
        text
    });
    let mut summary = None;
    let mut products = Vec::new();
    for line in BufReader::new(child.stdout.take().expect("piped")).lines() {
        let line = line.map_err(|e| io("reading the converter's output", e))?;
        match serde_json::from_str::<Line>(&line) {
            Ok(Line::Progress([done, total])) => {
                if let Some(progress) = progress {
                    progress(done as usize, total as usize);
                }
            }
            Ok(Line::Failed(product)) => products.push(product),
            Ok(Line::Summary(s)) => summary = Some(s),
            // Anything else a package printed is passed on.
            Err(_) => {
                let _ = writeln!(std::io::stderr(), "{line}");
            }
        }
    }
    let status = child
        .wait()
        .map_err(|e| io("waiting for the converter", e))?;
    let errors = errors.join().unwrap_or_default();
    if !status.success() {
        // The converter's error is its last line; its own name of the file
        // is replaced by ours.
        let last = errors.lines().rev().find(|l| !l.trim().is_empty());
        let what = match last {
            Some(line) => strip_file_name(line, input).to_owned(),
            None => format!("the converter failed ({status})"),
        };
        return Err(failed(what));
    }
    let summary = summary.ok_or_else(|| failed("the converter wrote no summary".into()))?;
    Ok(Converted {
        _scratch: scratch,
        glb,
        summary,
        failed: products,
    })
}

/// `line` without a leading "<file name>: ", which the caller's error adds.
fn strip_file_name<'a>(line: &'a str, input: &Path) -> &'a str {
    let name = input.file_name().map(|n| n.to_string_lossy().into_owned());
    name.and_then(|n| line.strip_prefix(&format!("{n}: ")).map(str::trim))
        .unwrap_or(line.trim())
}
