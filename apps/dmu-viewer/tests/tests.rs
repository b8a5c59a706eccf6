//! The real `dmu-viewer` binary, run under Xvfb on lavapipe.

mod support;
mod xvfb;
