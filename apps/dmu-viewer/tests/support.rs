//! Running the viewer under Xvfb, the `dmu` command line beside it, and
//! reading screenshots.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::{Mutex, RwLock, RwLockReadGuard, RwLockWriteGuard};

use serde_json::Value;

/// Lavapipe's Vulkan driver: the same CPU renderer everywhere.
pub const LVP_ICD: &str = "/usr/share/vulkan/icd.d/lvp_icd.x86_64.json";

/// `xvfb-run -a` picks a free display racily: viewer runs go one at a time.
static XVFB: Mutex<()> = Mutex::new(());

/// Holds the one-at-a-time lock of viewer runs.
pub fn xvfb_lock() -> std::sync::MutexGuard<'static, ()> {
    XVFB.lock().unwrap_or_else(|e| e.into_inner())
}

/// The tests of this binary share the machine (read), except those that
/// measure a process's resident set over time (write): other tests' runs
/// beside them shift their loads and frames, and a viewer soak that grew
/// under 1.3 % alone grew 7.7 % once beside them.
static MACHINE: RwLock<()> = RwLock::new(());

/// Holds a share of the machine: no soak runs meanwhile.
pub fn sharing_the_machine() -> RwLockReadGuard<'static, ()> {
    MACHINE.read().unwrap_or_else(|e| e.into_inner())
}

/// Holds the machine alone: no other test of this binary runs meanwhile.
pub fn alone_on_the_machine() -> RwLockWriteGuard<'static, ()> {
    MACHINE.write().unwrap_or_else(|e| e.into_inner())
}

/// Runs `body` where the viewer can run (Xvfb and lavapipe); elsewhere the
/// test skips through `dmu_testkit` (a failure under `CI=true`).
pub fn with_viewer(body: impl FnOnce()) {
    let _shared = sharing_the_machine();
    if_viewer_runs(body);
}

/// [`with_viewer`] for a test that measures memory over time: it runs with
/// no other test of this binary beside it.
pub fn with_viewer_alone(body: impl FnOnce()) {
    let _alone = alone_on_the_machine();
    if_viewer_runs(body);
}

fn if_viewer_runs(body: impl FnOnce()) {
    let ready = if Command::new("xvfb-run").arg("--help").output().is_err() {
        Err("xvfb-run (apt-get install xvfb xauth) is missing")
    } else if !Path::new(LVP_ICD).exists() {
        Err("lavapipe (mesa-vulkan-drivers) is missing")
    } else {
        Ok(())
    };
    dmu_testkit::require(ready, |()| body());
}

/// Runs the viewer with `args` in a 1600x1000 virtual screen on lavapipe and
/// returns its JSON report.
pub fn viewer(args: &[&str]) -> Value {
    let _one_at_a_time = xvfb_lock();
    let out = Command::new("xvfb-run")
        .args(["-a", "-s", "-screen 0 1600x1000x24"])
        .arg(env!("CARGO_BIN_EXE_dmu-viewer"))
        .args(args)
        .env("WGPU_BACKEND", "vulkan")
        .env("VK_ICD_FILENAMES", LVP_ICD)
        .output()
        .expect("run xvfb-run");
    json_of("dmu-viewer", args, &out)
}

/// Runs the viewer with `args` in Xvfb on lavapipe, expecting it to fail
/// with exit status 2: its standard error.
pub fn viewer_fails(args: &[&str]) -> String {
    let _one_at_a_time = xvfb_lock();
    let out = Command::new("xvfb-run")
        .args(["-a", "-s", "-screen 0 1600x1000x24"])
        .arg(env!("CARGO_BIN_EXE_dmu-viewer"))
        .args(args)
        .env("WGPU_BACKEND", "vulkan")
        .env("VK_ICD_FILENAMES", LVP_ICD)
        .output()
        .expect("run xvfb-run");
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert_eq!(
        out.status.code(),
        Some(2),
        "dmu-viewer {args:?} should fail:\n{stderr}"
    );
    stderr
}

/// Runs `dmu` with `args` on lavapipe (commands that draw: `dmu farfield
/// build`) and parses its JSON output; it must succeed.
pub fn dmu_on_lavapipe(args: &[&str]) -> Value {
    let out = Command::new(dmu_cli())
        .args(args)
        .env("WGPU_BACKEND", "vulkan")
        .env("VK_ICD_FILENAMES", LVP_ICD)
        .output()
        .expect("run dmu");
    json_of("dmu", args, &out)
}

/// The `dmu` command line of the same build (built here if it is not yet).
pub fn dmu_cli() -> PathBuf {
    let viewer = PathBuf::from(env!("CARGO_BIN_EXE_dmu-viewer"));
    let dmu = viewer.with_file_name(format!("dmu{}", std::env::consts::EXE_SUFFIX));
    let release = viewer
        .parent()
        .and_then(Path::file_name)
        .is_some_and(|d| d == "release");
    let mut build = Command::new(env!("CARGO"));
    build.args(["build", "--quiet", "-p", "dmu", "--bin", "dmu"]);
    if release {
        build.arg("--release");
    }
    let status = build.status().expect("run cargo build -p dmu");
    assert!(status.success(), "cargo build -p dmu failed");
    assert!(dmu.exists(), "{} was not built", dmu.display());
    dmu
}

/// Runs `dmu` with `args` and parses its JSON output; it must succeed.
pub fn dmu(args: &[&str]) -> Value {
    let (status, json) = dmu_status(args);
    assert_eq!(status, Some(0), "dmu {args:?} failed");
    json
}

/// Runs `dmu` with `args`: its exit status (`dmu collide` exits 1 on clashes)
/// and its JSON output.
pub fn dmu_status(args: &[&str]) -> (Option<i32>, Value) {
    let out = Command::new(dmu_cli())
        .args(args)
        .output()
        .expect("run dmu");
    let json = serde_json::from_slice(&out.stdout).unwrap_or_else(|e| {
        panic!(
            "dmu {args:?} printed no JSON ({e}, {}):\n{}",
            out.status,
            String::from_utf8_lossy(&out.stderr)
        )
    });
    (out.status.code(), json)
}

/// The 3D view's rectangle in the window, from a report.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Viewport {
    pub x: u32,
    pub y: u32,
    pub width: u32,
    pub height: u32,
}

impl Viewport {
    pub fn from_json(v: &Value) -> Self {
        let get = |k: &str| v[k].as_u64().expect("viewport field") as u32;
        Self {
            x: get("x"),
            y: get("y"),
            width: get("width"),
            height: get("height"),
        }
    }
}

/// An sRGB byte to linear.
fn linear(c: u8) -> f64 {
    let c = f64::from(c) / 255.0;
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// Linear to an sRGB byte value (unrounded).
pub fn srgb(c: f64) -> f64 {
    let c = c.clamp(0.0, 1.0);
    255.0
        * if c <= 0.0031308 {
            c * 12.92
        } else {
            1.055 * c.powf(1.0 / 2.4) - 0.055
        }
}

/// Colours the renderer can give a surface: one of `bases` (linear RGB) lit by
/// the headlight, i.e. times a factor in [0.2, 1] (`shading = base * (0.2 +
/// 0.8 * |n.l|)` in `shaders/mesh.wgsl`).
pub struct Palette {
    bases: Vec<[f64; 3]>,
}

impl Palette {
    /// The materials' colours.
    pub fn new(bases: impl IntoIterator<Item = [f64; 3]>) -> Self {
        Self {
            bases: bases.into_iter().collect(),
        }
    }

    /// The materials' colours mixed with a highlight `[r, g, b, weight]`, as the
    /// renderer shades a selected part.
    pub fn highlighted(&self, highlight: [f32; 4]) -> Self {
        let w = f64::from(highlight[3]);
        Self::new(
            self.bases
                .iter()
                .map(|b| [0, 1, 2].map(|i| b[i] * (1.0 - w) + f64::from(highlight[i]) * w)),
        )
    }

    /// Every colour (index) and lighting factor that give the sRGB pixel within
    /// `tolerance` per 8-bit channel (greys are ambiguous).
    pub fn explain(&self, pixel: [u8; 3], tolerance: f64) -> Vec<(usize, f64)> {
        let p = pixel.map(linear);
        (0..self.bases.len())
            .filter_map(|i| {
                let b = self.bases[i];
                let bb: f64 = b.iter().map(|c| c * c).sum();
                let k = ((p[0] * b[0] + p[1] * b[1] + p[2] * b[2]) / bb).clamp(0.2, 1.0);
                self.matches(i, k, pixel, tolerance).then_some((i, k))
            })
            .collect()
    }

    /// Whether the sRGB pixel is one of these colours at some lighting.
    pub fn explains(&self, pixel: [u8; 3], tolerance: f64) -> bool {
        !self.explain(pixel, tolerance).is_empty()
    }

    /// Whether colour `i` at lighting `k` gives the sRGB pixel within `tolerance`.
    pub fn matches(&self, i: usize, k: f64, pixel: [u8; 3], tolerance: f64) -> bool {
        (0..3).all(|c| (srgb(self.bases[i][c] * k) - f64::from(pixel[c])).abs() <= tolerance)
    }
}

/// The RGB of a pixel.
pub fn rgb(image: &image::RgbaImage, x: u32, y: u32) -> [u8; 3] {
    let p = image.get_pixel(x, y).0;
    [p[0], p[1], p[2]]
}

/// Pixels of the viewport for which `keep` holds.
pub fn count_pixels(
    image: &image::RgbaImage,
    view: Viewport,
    keep: impl Fn([u8; 3]) -> bool,
) -> usize {
    (view.y..view.y + view.height)
        .flat_map(|y| (view.x..view.x + view.width).map(move |x| (x, y)))
        .filter(|&(x, y)| keep(rgb(image, x, y)))
        .count()
}

/// A view pixel in the lower part of the view (clear of the stats overlay)
/// whose 9x9 neighbourhood is all geometry (no background colour), nearest
/// the view's centre: a pick there hits a part.
pub fn solid_pixel(image: &image::RgbaImage, view: Viewport) -> (u32, u32) {
    let background = rgb(image, view.x + 1, view.y + view.height - 2);
    let solid = |x: u32, y: u32| {
        (x - 4..=x + 4).all(|i| (y - 4..=y + 4).all(|j| rgb(image, i, j) != background))
    };
    let (cx, cy) = (view.width / 2, view.height / 2);
    let mut best: Option<((u32, u32), u64)> = None;
    for y in view.height / 3..view.height - 5 {
        for x in 5..view.width - 5 {
            if solid(view.x + x, view.y + y) {
                let d = u64::from(x.abs_diff(cx)).pow(2) + u64::from(y.abs_diff(cy)).pow(2);
                if best.is_none_or(|(_, bd)| d < bd) {
                    best = Some(((x, y), d));
                }
            }
        }
    }
    best.expect("some part fills a 9x9 patch of the view").0
}

/// The JSON a successful run of `program` printed; a failure or no JSON
/// panics with what it printed.
fn json_of(program: &str, args: &[&str], out: &std::process::Output) -> Value {
    assert!(
        out.status.success(),
        "{program} {args:?} failed ({}):\n{}",
        out.status,
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).unwrap_or_else(|e| {
        panic!(
            "{program} {args:?} printed no JSON ({e}):\n{}",
            String::from_utf8_lossy(&out.stdout)
        )
    })
}
