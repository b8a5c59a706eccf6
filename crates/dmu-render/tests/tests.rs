mod culling;
mod depth_split;
mod fov;
mod hierarchy;
mod images;
mod stereo;
mod support;
