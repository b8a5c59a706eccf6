mod culling;
mod hierarchy;
mod images;
mod stereo;
mod support;
