mod culling;
mod images;
mod stereo;
mod support;
