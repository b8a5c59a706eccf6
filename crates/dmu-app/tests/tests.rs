//! The one test binary of dmu-app.

mod bcf;
mod visibility;
