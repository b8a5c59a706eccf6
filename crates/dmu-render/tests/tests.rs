mod culling;
mod depth_split;
mod fov;
mod hierarchy;
mod images;
mod proxies;
mod stereo;
mod support;
