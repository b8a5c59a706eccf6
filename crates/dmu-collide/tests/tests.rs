mod analytic;
mod continuous;
mod property;
mod record;
mod support;
mod triangles;
