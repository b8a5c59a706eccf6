//! The one test binary of dmu-xr.

mod pose;
