//! The OpenXR session: instance, system, the runtime's wgpu device, a 2-layer
//! swapchain, session states and the frame loop.

use std::time::Duration;

use dmu_geom::Fov;

use crate::error::{XrError, xr_call};
use crate::input::{ControllerInput, Controllers, Hand, ProfileBinding};
use crate::pose::{Pose, fov_from_xr};
use crate::vulkan;

/// What to ask of the runtime.
#[derive(Clone, Debug, PartialEq)]
pub struct XrOptions {
    /// The application's name, as the runtime shows it.
    pub app_name: String,
    /// The longest side of each eye's image, pixels: the runtime's
    /// recommended size is scaled to it (aspect kept), within the runtime's
    /// maximum.
    pub eye_px: u32,
}

impl Default for XrOptions {
    fn default() -> Self {
        Self {
            app_name: "dmu".into(),
            eye_px: 1024,
        }
    }
}

/// A session's state, in the order a session goes through them when it
/// starts (so the highest reached compares as the greatest), then the ways
/// out.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
#[non_exhaustive]
pub enum SessionState {
    /// Before the first state change.
    Unknown,
    /// Created, not ready.
    Idle,
    /// Ready: the application begins the session.
    Ready,
    /// Frames are synchronised with the display, not shown.
    Synchronized,
    /// Shown, without input focus.
    Visible,
    /// Shown with input focus: the session runs fully.
    Focused,
    /// The runtime asks the application to end the session.
    Stopping,
    /// The session will be lost (the device went away).
    LossPending,
    /// The session is over; the application may exit.
    Exiting,
}

impl SessionState {
    fn from_xr(state: openxr::SessionState) -> Self {
        match state {
            openxr::SessionState::IDLE => Self::Idle,
            openxr::SessionState::READY => Self::Ready,
            openxr::SessionState::SYNCHRONIZED => Self::Synchronized,
            openxr::SessionState::VISIBLE => Self::Visible,
            openxr::SessionState::FOCUSED => Self::Focused,
            openxr::SessionState::STOPPING => Self::Stopping,
            openxr::SessionState::LOSS_PENDING => Self::LossPending,
            openxr::SessionState::EXITING => Self::Exiting,
            _ => Self::Unknown,
        }
    }

    /// OpenXR's name without its prefix: `"FOCUSED"`, `"EXITING"`, ...
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Unknown => "UNKNOWN",
            Self::Idle => "IDLE",
            Self::Ready => "READY",
            Self::Synchronized => "SYNCHRONIZED",
            Self::Visible => "VISIBLE",
            Self::Focused => "FOCUSED",
            Self::Stopping => "STOPPING",
            Self::LossPending => "LOSS_PENDING",
            Self::Exiting => "EXITING",
        }
    }
}

/// What the session asks of the application after events are handled.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Status {
    /// Not running yet (or any more): poll again shortly, draw nothing.
    Waiting,
    /// Running: draw a frame.
    Running,
    /// Over (exiting, lost): stop.
    Exit,
}

/// One eye of a frame: its pose in the tracking space and its field of view.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Eye {
    /// Pose (metres, Y up).
    pub pose: Pose,
    /// Asymmetric field of view.
    pub fov: Fov,
}

/// A frame begun with [`XrSession::begin_frame`]: where the eyes are, and the
/// swapchain image to draw them into (layer 0 left, layer 1 right).
pub struct Frame {
    /// Left and right eye.
    pub eyes: [Eye; 2],
    /// The swapchain image, two layers of [`XrSession::eye_size`].
    pub image: wgpu::Texture,
    /// When the runtime predicts the frame is shown, nanoseconds of its clock.
    pub display_time_ns: i64,
    /// The runtime's predicted display period (the time between two
    /// displayed frames), nanoseconds.
    pub display_period_ns: i64,
    views: [openxr::View; 2],
    time: openxr::Time,
}

impl std::fmt::Debug for Frame {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Frame")
            .field("eyes", &self.eyes)
            .field("display_time_ns", &self.display_time_ns)
            .field("display_period_ns", &self.display_period_ns)
            .finish_non_exhaustive()
    }
}

/// An OpenXR session rendering through wgpu on the runtime's Vulkan device.
///
/// Field order is drop order: images and the swapchain before the session,
/// the session before the device, the instance last.
pub struct XrSession {
    images: Vec<wgpu::Texture>,
    swapchain: openxr::Swapchain<openxr::Vulkan>,
    controllers: Controllers,
    space: openxr::Space,
    frame_stream: openxr::FrameStream<openxr::Vulkan>,
    frame_waiter: openxr::FrameWaiter,
    session: openxr::Session<openxr::Vulkan>,
    device: wgpu::Device,
    queue: wgpu::Queue,
    adapter: wgpu::AdapterInfo,
    instance: openxr::Instance,
    runtime: String,
    blend_mode: openxr::EnvironmentBlendMode,
    eye_size: (u32, u32),
    recommended_eye_size: (u32, u32),
    color_format: wgpu::TextureFormat,
    events: openxr::EventDataBuffer,
    state: SessionState,
    max_state: SessionState,
    running: bool,
    exit_requested: bool,
    frames_submitted: u64,
}

impl std::fmt::Debug for XrSession {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("XrSession")
            .field("runtime", &self.runtime)
            .field("state", &self.state)
            .field("eye_size", &self.eye_size)
            .field("frames_submitted", &self.frames_submitted)
            .finish_non_exhaustive()
    }
}

/// The colour format of the swapchain: sRGB RGBA8, the renderer's capture
/// format, so frames are copied into it as they are.
const SWAPCHAIN_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8UnormSrgb;
/// `VK_FORMAT_R8G8B8A8_SRGB`.
const VK_FORMAT_R8G8B8A8_SRGB: u32 = 43;
const VIEW_TYPE: openxr::ViewConfigurationType = openxr::ViewConfigurationType::PRIMARY_STEREO;

impl XrSession {
    /// Loads the OpenXR loader (the runtime from `XR_RUNTIME_JSON` or the
    /// system's active one), makes an instance with `XR_KHR_vulkan_enable2`,
    /// the head-mounted system, a wgpu device through the runtime, the
    /// session, a local reference space, a 2-layer swapchain, and the
    /// controllers' action set (bindings suggested for
    /// [`crate::suggested_profiles`], attached to the session).
    ///
    /// # Errors
    /// [`XrError`] naming the step and the runtime's answer.
    #[expect(
        unsafe_code,
        reason = "loading the OpenXR loader and creating a session on raw Vulkan handles"
    )]
    pub fn new(options: &XrOptions) -> Result<Self, XrError> {
        // SAFETY: loads libopenxr_loader.so.1, whose initialisers are the
        // loader's own.
        let entry = unsafe { openxr::Entry::load(&()) }.map_err(|e| XrError::Loader {
            reason: e.to_string(),
        })?;
        let available = entry
            .enumerate_extensions()
            .map_err(xr_call("xrEnumerateInstanceExtensionProperties"))?;
        if !available.khr_vulkan_enable2 {
            return Err(XrError::Missing {
                runtime: "(active runtime)".into(),
                what: "XR_KHR_vulkan_enable2 extension".into(),
            });
        }
        let mut extensions = openxr::ExtensionSet::default();
        extensions.khr_vulkan_enable2 = true;
        let instance = entry
            .create_instance(
                &openxr::ApplicationInfo {
                    application_name: &options.app_name,
                    application_version: 1,
                    engine_name: "dmu",
                    engine_version: 1,
                    api_version: openxr::Version::new(1, 0, 0),
                },
                &extensions,
                &[],
                &(),
            )
            .map_err(xr_call("xrCreateInstance"))?;
        let properties = instance
            .properties()
            .map_err(xr_call("xrGetInstanceProperties"))?;
        let runtime = format!("{} {}", properties.runtime_name, properties.runtime_version);
        let system = instance
            .system(openxr::FormFactor::HEAD_MOUNTED_DISPLAY)
            .map_err(xr_call("xrGetSystem"))?;
        let blend_mode = instance
            .enumerate_environment_blend_modes(system, VIEW_TYPE)
            .map_err(xr_call("xrEnumerateEnvironmentBlendModes"))?
            .first()
            .copied()
            .ok_or_else(|| XrError::Missing {
                runtime: runtime.clone(),
                what: "environment blend mode".into(),
            })?;
        let config_views = instance
            .enumerate_view_configuration_views(system, VIEW_TYPE)
            .map_err(xr_call("xrEnumerateViewConfigurationViews"))?;
        if config_views.len() != 2 {
            return Err(XrError::Missing {
                runtime,
                what: format!(
                    "stereo view configuration (it has {} views)",
                    config_views.len()
                ),
            });
        }
        let recommended_eye_size = (
            config_views[0].recommended_image_rect_width,
            config_views[0].recommended_image_rect_height,
        );
        let eye_size = eye_size(
            recommended_eye_size,
            (
                config_views[0].max_image_rect_width,
                config_views[0].max_image_rect_height,
            ),
            options.eye_px,
        );
        let gpu = vulkan::create(&instance, system, &runtime)?;
        // SAFETY: the binding's handles are the runtime's own instance,
        // physical device and device, alive as long as `gpu.device`, which
        // the session outlives not (field order).
        let (session, frame_waiter, frame_stream) =
            unsafe { instance.create_session::<openxr::Vulkan>(system, &gpu.binding) }
                .map_err(xr_call("xrCreateSession"))?;
        let space = session
            .create_reference_space(openxr::ReferenceSpaceType::LOCAL, openxr::Posef::IDENTITY)
            .map_err(xr_call("xrCreateReferenceSpace"))?;
        let controllers = Controllers::new(&instance, &session)?;
        let formats = session
            .enumerate_swapchain_formats()
            .map_err(xr_call("xrEnumerateSwapchainFormats"))?;
        if !formats.contains(&VK_FORMAT_R8G8B8A8_SRGB) {
            return Err(XrError::Missing {
                runtime,
                what: format!(
                    "R8G8B8A8_SRGB swapchain format (it offers Vulkan formats {formats:?})"
                ),
            });
        }
        let swapchain = session
            .create_swapchain(&openxr::SwapchainCreateInfo {
                create_flags: openxr::SwapchainCreateFlags::EMPTY,
                usage_flags: openxr::SwapchainUsageFlags::COLOR_ATTACHMENT
                    | openxr::SwapchainUsageFlags::TRANSFER_DST,
                format: VK_FORMAT_R8G8B8A8_SRGB,
                sample_count: 1,
                width: eye_size.0,
                height: eye_size.1,
                face_count: 1,
                array_size: 2,
                mip_count: 1,
            })
            .map_err(xr_call("xrCreateSwapchain"))?;
        let raw_images = swapchain
            .enumerate_images()
            .map_err(xr_call("xrEnumerateSwapchainImages"))?;
        let images = vulkan::wrap_images(
            &gpu.device,
            &raw_images,
            &wgpu::TextureDescriptor {
                label: Some("dmu xr swapchain"),
                size: wgpu::Extent3d {
                    width: eye_size.0,
                    height: eye_size.1,
                    depth_or_array_layers: 2,
                },
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format: SWAPCHAIN_FORMAT,
                usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_DST,
                view_formats: &[],
            },
        )?;
        Ok(Self {
            images,
            swapchain,
            controllers,
            space,
            frame_stream,
            frame_waiter,
            session,
            device: gpu.device,
            queue: gpu.queue,
            adapter: gpu.adapter,
            instance,
            runtime,
            blend_mode,
            eye_size,
            recommended_eye_size,
            color_format: SWAPCHAIN_FORMAT,
            events: openxr::EventDataBuffer::new(),
            state: SessionState::Unknown,
            max_state: SessionState::Unknown,
            running: false,
            exit_requested: false,
            frames_submitted: 0,
        })
    }

    /// The device to render with (the runtime's Vulkan device).
    pub fn device(&self) -> &wgpu::Device {
        &self.device
    }

    /// Its queue.
    pub fn queue(&self) -> &wgpu::Queue {
        &self.queue
    }

    /// The adapter under the device.
    pub fn adapter(&self) -> &wgpu::AdapterInfo {
        &self.adapter
    }

    /// The runtime's name and version.
    pub fn runtime(&self) -> &str {
        &self.runtime
    }

    /// Each eye's image size, pixels.
    pub fn eye_size(&self) -> (u32, u32) {
        self.eye_size
    }

    /// The eye size the runtime recommends, pixels.
    pub fn recommended_eye_size(&self) -> (u32, u32) {
        self.recommended_eye_size
    }

    /// The swapchain images' format.
    pub fn color_format(&self) -> wgpu::TextureFormat {
        self.color_format
    }

    /// The session's present state.
    pub fn state(&self) -> SessionState {
        self.state
    }

    /// The furthest state of the start-up sequence reached so far
    /// ([`SessionState::Focused`] for a session that ran fully).
    pub fn max_state(&self) -> SessionState {
        self.max_state
    }

    /// Frames ended with a projection layer.
    pub fn frames_submitted(&self) -> u64 {
        self.frames_submitted
    }

    /// The interaction profiles bindings were suggested for, each with the
    /// runtime's answer.
    pub fn bindings(&self) -> &[ProfileBinding] {
        &self.controllers.bindings
    }

    /// The interaction profile the runtime bound for each hand (left, right;
    /// `None` where none is bound, e.g. no controller).
    ///
    /// # Errors
    /// A failing OpenXR call.
    pub fn interaction_profiles(&self) -> Result<[Option<String>; 2], XrError> {
        let profile = |hand| {
            self.controllers
                .profile(&self.instance, &self.session, hand)
        };
        Ok([profile(Hand::Left)?, profile(Hand::Right)?])
    }

    /// Syncs the controllers' actions (`xrSyncActions`) and reads both hands
    /// at `frame`'s display time, aim poses in the tracking space. Only while
    /// the session has input focus ([`SessionState::Focused`]): `None`
    /// otherwise, with nothing synced.
    ///
    /// # Errors
    /// A failing OpenXR call.
    pub fn controllers(&self, frame: &Frame) -> Result<Option<ControllerInput>, XrError> {
        if self.state != SessionState::Focused {
            return Ok(None);
        }
        self.controllers
            .sync(&self.session, &self.space, frame.time)
            .map(Some)
    }

    /// A haptic pulse on `hand`'s controller (`xrApplyHapticFeedback`):
    /// `duration_s` seconds at `amplitude` (0 to 1).
    ///
    /// # Errors
    /// A failing OpenXR call.
    pub fn haptic_pulse(&self, hand: Hand, duration_s: f64, amplitude: f32) -> Result<(), XrError> {
        self.controllers
            .pulse(&self.session, hand, duration_s, amplitude)
    }

    /// Handles the runtime's events: begins the session when it is ready,
    /// ends it when it stops, and says what to do next. After
    /// [`XrSession::request_exit`], polls until the session is over.
    ///
    /// # Errors
    /// A failing OpenXR call.
    pub fn poll(&mut self) -> Result<Status, XrError> {
        let mut exit = false;
        while let Some(event) = self
            .instance
            .poll_event(&mut self.events)
            .map_err(xr_call("xrPollEvent"))?
        {
            match event {
                openxr::Event::SessionStateChanged(change) => {
                    let state = SessionState::from_xr(change.state());
                    self.state = state;
                    if state <= SessionState::Focused {
                        self.max_state = self.max_state.max(state);
                    }
                    match state {
                        SessionState::Ready => {
                            self.session
                                .begin(VIEW_TYPE)
                                .map_err(xr_call("xrBeginSession"))?;
                            self.running = true;
                        }
                        SessionState::Stopping => {
                            self.session.end().map_err(xr_call("xrEndSession"))?;
                            self.running = false;
                        }
                        SessionState::Exiting | SessionState::LossPending => exit = true,
                        _ => {}
                    }
                }
                openxr::Event::InstanceLossPending(_) => exit = true,
                _ => {}
            }
        }
        Ok(if exit {
            Status::Exit
        } else if self.running {
            Status::Running
        } else {
            Status::Waiting
        })
    }

    /// Asks the runtime to end the session; [`XrSession::poll`] then sees it
    /// stop and exit.
    ///
    /// # Errors
    /// A failing OpenXR call.
    pub fn request_exit(&mut self) -> Result<(), XrError> {
        if self.running && !self.exit_requested {
            self.session
                .request_exit()
                .map_err(xr_call("xrRequestExitSession"))?;
        }
        self.exit_requested = true;
        Ok(())
    }

    /// Waits for the runtime's frame timing, begins a frame and locates the
    /// eyes. `None` when the runtime wants nothing drawn this time (the frame
    /// is ended here with no layers); otherwise draw into
    /// [`Frame::image`], submit, and call [`XrSession::end_frame`].
    ///
    /// # Errors
    /// A failing OpenXR call.
    pub fn begin_frame(&mut self) -> Result<Option<Frame>, XrError> {
        let timing = self.frame_waiter.wait().map_err(xr_call("xrWaitFrame"))?;
        self.frame_stream.begin().map_err(xr_call("xrBeginFrame"))?;
        let time = timing.predicted_display_time;
        if !timing.should_render {
            self.frame_stream
                .end(time, self.blend_mode, &[])
                .map_err(xr_call("xrEndFrame"))?;
            return Ok(None);
        }
        let (_, views) = self
            .session
            .locate_views(VIEW_TYPE, time, &self.space)
            .map_err(xr_call("xrLocateViews"))?;
        let views: [openxr::View; 2] = views.try_into().map_err(|v: Vec<_>| XrError::Missing {
            runtime: self.runtime.clone(),
            what: format!("two located views (it gave {})", v.len()),
        })?;
        let index = self
            .swapchain
            .acquire_image()
            .map_err(xr_call("xrAcquireSwapchainImage"))?;
        self.swapchain
            .wait_image(openxr::Duration::INFINITE)
            .map_err(xr_call("xrWaitSwapchainImage"))?;
        let eye = |v: &openxr::View| Eye {
            pose: Pose::from_xr(&v.pose),
            fov: fov_from_xr(&v.fov),
        };
        Ok(Some(Frame {
            eyes: [eye(&views[0]), eye(&views[1])],
            image: self.images[index as usize].clone(),
            display_time_ns: time.as_nanos(),
            display_period_ns: timing.predicted_display_period.as_nanos(),
            views,
            time,
        }))
    }

    /// Releases the frame's image (its drawing must be submitted) and ends
    /// the frame with a projection layer of both eyes, as located.
    ///
    /// # Errors
    /// A failing OpenXR call.
    pub fn end_frame(&mut self, frame: Frame) -> Result<(), XrError> {
        self.swapchain
            .release_image()
            .map_err(xr_call("xrReleaseSwapchainImage"))?;
        let rect = openxr::Rect2Di {
            offset: openxr::Offset2Di { x: 0, y: 0 },
            extent: openxr::Extent2Di {
                width: self.eye_size.0 as i32,
                height: self.eye_size.1 as i32,
            },
        };
        let view = |layer: u32| {
            let v = &frame.views[layer as usize];
            openxr::CompositionLayerProjectionView::new()
                .pose(v.pose)
                .fov(v.fov)
                .sub_image(
                    openxr::SwapchainSubImage::new()
                        .swapchain(&self.swapchain)
                        .image_array_index(layer)
                        .image_rect(rect),
                )
        };
        let views = [view(0), view(1)];
        let layer = openxr::CompositionLayerProjection::new()
            .space(&self.space)
            .views(&views);
        self.frame_stream
            .end(frame.time, self.blend_mode, &[&layer])
            .map_err(xr_call("xrEndFrame"))?;
        self.frames_submitted += 1;
        Ok(())
    }

    /// Polls until the session is over after [`XrSession::request_exit`]
    /// (at most `timeout`); whether it reached [`SessionState::Exiting`].
    ///
    /// # Errors
    /// A failing OpenXR call.
    pub fn finish(&mut self, timeout: Duration) -> Result<bool, XrError> {
        self.request_exit()?;
        let start = std::time::Instant::now();
        while start.elapsed() < timeout {
            match self.poll()? {
                Status::Exit => return Ok(self.state == SessionState::Exiting),
                // Frames go on until the runtime stops the session.
                Status::Running => {
                    if let Some(frame) = self.begin_frame()? {
                        self.end_frame_empty(frame)?;
                    }
                }
                Status::Waiting => std::thread::sleep(Duration::from_millis(5)),
            }
        }
        Ok(false)
    }

    /// Releases the image and ends the frame with no layers (while exiting).
    fn end_frame_empty(&mut self, frame: Frame) -> Result<(), XrError> {
        self.swapchain
            .release_image()
            .map_err(xr_call("xrReleaseSwapchainImage"))?;
        self.frame_stream
            .end(frame.time, self.blend_mode, &[])
            .map_err(xr_call("xrEndFrame"))
    }
}

/// The runtime's recommended eye size scaled (aspect kept) so that its
/// longest side is `longest_px`, or less where the runtime's `max` is
/// smaller (at least 1 pixel each way).
pub fn eye_size(recommended: (u32, u32), max: (u32, u32), longest_px: u32) -> (u32, u32) {
    let (w, h) = (
        f64::from(recommended.0.max(1)),
        f64::from(recommended.1.max(1)),
    );
    let scale = (f64::from(longest_px) / w.max(h))
        .min(f64::from(max.0.max(1)) / w)
        .min(f64::from(max.1.max(1)) / h);
    let side = |v: f64| ((v * scale).round() as u32).max(1);
    (side(w), side(h))
}
