//! The parts of `dmu-viewer` that need no window, as a library so that tests
//! and the fuzz harness (`fuzz/`) reach them: the commands every input
//! emits and the one place review commands are applied (`command`), the
//! review (moves, undo, collision, sections, the clash list, viewpoints),
//! the review tools' state (`tools`), the gizmo's geometry,
//! measurement, automation scripts, navigation, the render settings
//! scripts name, and the hands of the VR review (`xr_input`, `xr_script`).
//! The binary (`main.rs`) uses them from here.

pub mod clashes;
pub mod command;
pub mod gizmo;
pub mod issues;
pub mod measure;
pub mod nav;
pub mod on_demand;
pub mod record;
pub mod review;
pub mod script;
pub mod section;
pub mod settings;
pub mod tools;
pub mod viewpoints;
pub mod xr_input;
pub mod xr_script;
