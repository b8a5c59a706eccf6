//! The real `dmu-viewer` binary, run under Xvfb on lavapipe.

mod session;
mod support;
mod xvfb;
