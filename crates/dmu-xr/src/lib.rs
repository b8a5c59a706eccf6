//! OpenXR sessions for dmu: a wgpu device made through the runtime, a
//! 2-layer swapchain, the session's states and frame loop, and eye poses as
//! dmu cameras with asymmetric fields of view.
//!
//! Design choices:
//! - Vulkan through `XR_KHR_vulkan_enable2`: the runtime creates the
//!   VkInstance and VkDevice (at API 1.2, which wgpu-hal is told too) and
//!   wgpu-hal adopts them, so the runtime's swapchain images are textures of
//!   the same device the renderer draws with. They are wrapped with a no-op
//!   drop: the runtime owns them.
//! - The crate owns the session, not the drawing: [`XrSession::begin_frame`]
//!   hands out the eyes and the image, the application draws with
//!   `dmu-render` (which owns no window or session) and submits, and
//!   [`XrSession::end_frame`] releases the image and submits a projection
//!   layer of both eyes. The viewer's `--xr` mode is one such application.
//! - One swapchain of 2-layer images (layer 0 the left eye), as multiview
//!   draws; its size is the runtime's recommended aspect at a chosen
//!   resolution ([`XrOptions::eye_px`]), because a CPU rasterizer pays for
//!   every pixel and a runtime may recommend a small image.
//! - The OpenXR loader is loaded at run time (`openxr`'s `loaded` feature), so
//!   dmu builds and runs without it; only `--xr` needs one.
//! - Controllers through OpenXR actions: one action set (aim pose, trigger,
//!   undo button, thumbstick, haptic output; subaction paths for both hands)
//!   with bindings suggested for the simple controller and the common
//!   controllers; [`XrSession::controllers`] syncs it only while the session
//!   is focused and returns a plain [`ControllerInput`], the type a script
//!   injects too, so one input-handling function serves both.
//! - Session states are a total order up to [`SessionState::Focused`], so
//!   "the furthest state reached" ([`XrSession::max_state`]) is a maximum.
//!
//! Conventions: the tracking space is OpenXR's (metres, right-handed, Y up,
//! -Z forward); a [`Placement`] puts it in the model world (model units, Z
//! up, f64). Fields of view are OpenXR's four angles ([`dmu_geom::Fov`]:
//! left and down negative).
//!
//! ```
//! use dmu_geom::Fov;
//! use dmu_geom::glam::DVec3;
//! use dmu_xr::{Placement, Pose};
//!
//! // A head 1.7 m above a point of the plant (millimetres), looking ahead.
//! let placement = Placement {
//!     origin: DVec3::new(4.5e6, 5.3e6, 1.2e4),
//!     heading_rad: 0.0,
//!     units_per_metre: 1000.0,
//! };
//! let head = Pose { position: DVec3::new(0.0, 1.7, 0.0), ..Pose::IDENTITY };
//! let fov = Fov { left: -0.742, right: 0.742, down: -0.779, up: 0.779 };
//! let camera = placement.eye_camera(&head, &fov, 10.0);
//! assert_eq!(camera.eye, DVec3::new(4.5e6, 5.3e6, 1.2e4 + 1700.0));
//! // Forward (-Z in the tracking space) is world +Y with no heading.
//! assert!((camera.target - camera.eye).normalize().abs_diff_eq(DVec3::Y, 1e-12));
//! ```
//!
//! Without a runtime (`XR_RUNTIME_JSON` unset and none installed)
//! [`XrSession::new`] fails with an [`XrError`] naming the step.

mod error;
mod input;
mod pose;
mod session;
mod vulkan;

pub use error::XrError;
pub use input::{ControllerInput, Hand, HandInput, ProfileBinding, suggested_profiles};
pub use pose::{Placement, Pose, eye_pixel, eye_ray, fov_from_xr};
pub use session::{Eye, Frame, SessionState, Status, XrOptions, XrSession, eye_size};
