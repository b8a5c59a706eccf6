//! Errors of the renderer: what a caller cannot foresee (no adapter, device
//! lost, a failed readback, a file that cannot be written).

/// Errors from device creation, readback and capture.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum RenderError {
    /// No adapter (no Vulkan driver, say).
    #[error("no GPU adapter: {reason}")]
    NoAdapter {
        /// The backend's message.
        reason: String,
    },
    /// The adapter refused the device.
    #[error("requesting a device from {adapter}: {reason}")]
    RequestDevice {
        /// Adapter name.
        adapter: String,
        /// The backend's message.
        reason: String,
    },
    /// The device lacks a feature the call needs (multiview for stereo, say).
    #[error("the device does not support {feature}")]
    Unsupported {
        /// The missing feature.
        feature: &'static str,
    },
    /// Reading a buffer back failed (device lost, typically).
    #[error("reading back {what}: {reason}")]
    Readback {
        /// What was read.
        what: &'static str,
        /// The backend's message.
        reason: String,
    },
    /// Writing an image failed.
    #[error("writing {path}")]
    Image {
        /// The file.
        path: String,
        /// The encoder's error.
        source: image::ImageError,
    },
}
