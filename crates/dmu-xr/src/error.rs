//! What can go wrong with an OpenXR session.

/// Errors of OpenXR sessions: the runtime, its Vulkan device, the swapchain.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum XrError {
    /// The OpenXR loader library could not be loaded.
    #[error("loading the OpenXR loader (libopenxr_loader.so.1): {reason}")]
    Loader {
        /// The loader's message.
        reason: String,
    },
    /// An OpenXR call failed.
    #[error("OpenXR {call} failed: {result}")]
    Runtime {
        /// The call, as OpenXR names it.
        call: &'static str,
        /// The runtime's result code.
        result: String,
    },
    /// The runtime lacks something dmu needs.
    #[error("the OpenXR runtime {runtime:?} has no {what}")]
    Missing {
        /// The runtime's name.
        runtime: String,
        /// What is missing (an extension, a view configuration, a format).
        what: String,
    },
    /// A Vulkan call made on the runtime's behalf failed.
    #[error("Vulkan {call} failed: {reason}")]
    Vulkan {
        /// The call.
        call: &'static str,
        /// Its result or message.
        reason: String,
    },
    /// wgpu refused the device made through the runtime.
    #[error("wgpu could not use the runtime's Vulkan device: {reason}")]
    Wgpu {
        /// wgpu's message.
        reason: String,
    },
}

/// Names an OpenXR call's failure.
pub(crate) fn xr_call(call: &'static str) -> impl FnOnce(openxr::sys::Result) -> XrError {
    move |result| XrError::Runtime {
        call,
        result: format!("{result:?}"),
    }
}

/// Names a Vulkan call's failure.
pub(crate) fn vk_call(call: &'static str) -> impl FnOnce(ash::vk::Result) -> XrError {
    move |result| XrError::Vulkan {
        call,
        reason: format!("{result:?}"),
    }
}
