mod culling;
mod images;
mod support;
