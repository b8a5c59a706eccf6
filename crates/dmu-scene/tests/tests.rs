mod import;
mod plant;
mod real_models;
mod support;
