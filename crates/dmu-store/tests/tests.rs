mod files;
mod residency;
mod round_trip;
mod support;
