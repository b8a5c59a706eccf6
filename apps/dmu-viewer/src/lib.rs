//! The parts of `dmu-viewer` that need no window, as a library so that tests
//! and the fuzz harness (`fuzz/`) reach them: automation scripts, navigation
//! and the render settings scripts name. The binary (`main.rs`) uses them from
//! here.

pub mod nav;
pub mod script;
pub mod settings;
pub mod xr_script;
