mod culling;
mod fov;
mod hierarchy;
mod images;
mod stereo;
mod support;
