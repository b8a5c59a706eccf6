mod import;
mod real_models;
mod support;
