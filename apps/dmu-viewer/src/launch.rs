//! Opening the window before the model: the model loads (and its cell tree
//! builds) on a thread of its own while the window shows the progress, so a
//! large file never leaves a frozen or missing window; then the viewer takes
//! the window over.

use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::mpsc::{Receiver, TryRecvError};
use std::time::{Duration, Instant};

use serde_json::Value;
use winit::application::ApplicationHandler;
use winit::event::WindowEvent;
use winit::event_loop::{ActiveEventLoop, ControlFlow};
use winit::window::WindowId;

use crate::app::{App, Options};
use crate::gfx::Gfx;
use crate::review::Review;

/// How far loading has come: meshes imported of how many (0 of 0 while the
/// total is unknown, or for the built-in plant).
#[derive(Debug, Default)]
pub struct LoadProgress {
    /// Meshes imported.
    pub done: AtomicUsize,
    /// Meshes in the file.
    pub total: AtomicUsize,
}

/// What the loading thread hands over.
#[derive(Debug)]
pub struct Loaded {
    /// The model under review.
    pub review: Review,
    /// The report's facts about the model.
    pub facts: Value,
    /// The model's proxies (merged subtrees), when they were asked for.
    pub proxies: Option<dmu_render::Proxies>,
    /// The store's far fields, with `--far-field on|auto`.
    pub far_fields: Option<dmu_app::farfield::FarFieldSet>,
}

/// The loading thread's result.
pub type LoadResult = anyhow::Result<Loaded>;

/// The loading thread's end and its progress.
#[derive(Debug)]
pub struct Loading {
    /// Receives the result once.
    pub result: Receiver<LoadResult>,
    /// Updated by the thread.
    pub progress: Arc<LoadProgress>,
    /// When loading began.
    pub started: Instant,
    /// What is loading, for the window.
    pub what: String,
}

/// Runs the event loop: the loading screen, then the viewer.
pub struct Launcher {
    instance: wgpu::Instance,
    options: Option<Options>,
    loading: Loading,
    /// The window, opened while the model loads.
    window: Option<(Gfx, egui_winit::State)>,
    egui_ctx: egui::Context,
    app: Option<App>,
    frames_while_loading: u64,
    /// When the loading screen is due to be drawn again.
    next_loading_frame: Instant,
    error: Option<anyhow::Error>,
}

impl std::fmt::Debug for Launcher {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Launcher")
            .field("loading", &self.loading)
            .field("app", &self.app)
            .finish_non_exhaustive()
    }
}

impl Launcher {
    /// A launcher that opens the viewer with `options` once `loading` ends.
    pub fn new(instance: wgpu::Instance, options: Options, loading: Loading) -> Self {
        Self {
            instance,
            options: Some(options),
            loading,
            window: None,
            egui_ctx: egui::Context::default(),
            app: None,
            frames_while_loading: 0,
            next_loading_frame: Instant::now(),
            error: None,
        }
    }

    /// The error that ended the run, if any, and the report of an automated
    /// run (with the frames the window drew while the model loaded).
    pub fn finish(self) -> anyhow::Result<Option<Value>> {
        if let Some(e) = self.error {
            return Err(e);
        }
        let Some(app) = self.app else {
            return Ok(None);
        };
        let frames = self.frames_while_loading;
        Ok(app.finish()?.map(|mut report| {
            report["frames_while_loading"] = frames.into();
            report
        }))
    }

    /// Takes the loading thread's result, if it is in: the viewer then takes
    /// the window over. Returns whether loading is over (or failed).
    fn poll(&mut self, event_loop: &ActiveEventLoop) -> bool {
        let result = match self.loading.result.try_recv() {
            Ok(r) => r,
            Err(TryRecvError::Empty) => return false,
            Err(TryRecvError::Disconnected) => {
                Err(anyhow::anyhow!("the loading thread ended without a model"))
            }
        };
        match result {
            Ok(loaded) => {
                let options = self.options.take().expect("the viewer starts once");
                let mut app = App::new(self.instance.clone(), loaded.review, options, loaded.facts);
                app.proxies = loaded.proxies;
                app.far_field_set = loaded.far_fields;
                if let Some((gfx, state)) = self.window.take() {
                    app.adopt(gfx, state, self.egui_ctx.clone());
                }
                self.app = Some(app);
            }
            Err(e) => {
                self.error = Some(e);
                event_loop.exit();
            }
        }
        true
    }

    /// One frame of the loading screen.
    fn draw_loading(&mut self) -> anyhow::Result<()> {
        let Some((gfx, state)) = self.window.as_mut() else {
            return Ok(());
        };
        let start = Instant::now();
        let raw = state.take_egui_input(&gfx.window);
        let (done, total) = (
            self.loading.progress.done.load(Ordering::Relaxed),
            self.loading.progress.total.load(Ordering::Relaxed),
        );
        let seconds = self.loading.started.elapsed().as_secs_f64();
        let what = &self.loading.what;
        let output = self.egui_ctx.run_ui(raw, |ui| {
            egui::CentralPanel::default().show(ui, |ui| {
                ui.vertical_centered(|ui| {
                    ui.add_space(ui.available_height() * 0.4);
                    ui.heading(format!("loading {what}"));
                    let bar = if total > 0 {
                        egui::ProgressBar::new(done as f32 / total as f32)
                            .text(format!("{done} of {total} meshes · {seconds:.1} s"))
                    } else {
                        egui::ProgressBar::new(0.0)
                            .animate(true)
                            .text(format!("{seconds:.1} s"))
                    };
                    ui.add(bar.desired_width(360.0));
                });
            });
        });
        state.handle_platform_output(&gfx.window, output.platform_output.clone());
        gfx.present(&self.egui_ctx, output, false, false)?;
        self.frames_while_loading += 1;
        self.next_loading_frame = Instant::now() + loading_redraw_interval(start.elapsed());
        Ok(())
    }
}

impl ApplicationHandler for Launcher {
    fn resumed(&mut self, event_loop: &ActiveEventLoop) {
        if let Some(app) = self.app.as_mut() {
            return app.resumed(event_loop);
        }
        if self.window.is_some() {
            return;
        }
        let options = self.options.as_ref().expect("the viewer has not started");
        match crate::app::open_window(event_loop, &self.instance, options, &self.egui_ctx) {
            Ok(window) => {
                window.0.window.request_redraw();
                self.window = Some(window);
            }
            Err(e) => {
                self.error = Some(e);
                event_loop.exit();
            }
        }
    }

    fn window_event(&mut self, event_loop: &ActiveEventLoop, id: WindowId, event: WindowEvent) {
        if let Some(app) = self.app.as_mut() {
            return app.window_event(event_loop, id, event);
        }
        let Some((gfx, state)) = self.window.as_mut() else {
            return;
        };
        let _ = state.on_window_event(&gfx.window, &event);
        match event {
            WindowEvent::CloseRequested => event_loop.exit(),
            WindowEvent::Resized(size) => gfx.resize(size.width, size.height),
            WindowEvent::RedrawRequested => {
                if let Err(e) = self.draw_loading() {
                    self.error = Some(e);
                    event_loop.exit();
                }
            }
            _ => {}
        }
    }

    fn about_to_wait(&mut self, event_loop: &ActiveEventLoop) {
        if self.app.is_none() && !self.poll(event_loop) {
            // Redraw the progress until the model is in, at most a few
            // times a second and for at most a tenth of the time: on a
            // software renderer a frame of the window costs as much as
            // the load's work it would take the core from.
            if Instant::now() >= self.next_loading_frame
                && let Some((gfx, _)) = &self.window
            {
                gfx.window.request_redraw();
            }
            // Woken often enough to take the model over as soon as it is in.
            let check = Instant::now() + LOAD_POLL;
            event_loop.set_control_flow(ControlFlow::WaitUntil(check.min(self.next_loading_frame)));
            return;
        }
        if let Some(app) = self.app.as_mut() {
            app.about_to_wait(event_loop);
        }
    }
}

/// How often the event loop checks whether the model is in while it loads.
const LOAD_POLL: Duration = Duration::from_millis(20);

/// How long the loading screen waits between frames after one that took
/// `frame`: nine times the frame, so that drawing it takes at most a tenth
/// of the time, but at least a quarter of a second and at most one (the
/// progress moves at least once a second).
fn loading_redraw_interval(frame: Duration) -> Duration {
    (frame * 9).clamp(Duration::from_millis(250), Duration::from_secs(1))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_loading_screen_takes_a_tenth_of_the_time_and_moves_each_second() {
        for ms in [0, 1, 10, 27, 28, 100, 111, 112, 1_000, 60_000] {
            let frame = Duration::from_millis(ms);
            let interval = loading_redraw_interval(frame);
            assert!(interval >= Duration::from_millis(250), "{ms} ms");
            assert!(interval <= Duration::from_secs(1), "{ms} ms");
            // Frame plus wait: drawing is at most a tenth of the cycle
            // wherever that leaves a redraw each second.
            if 9 * frame <= Duration::from_secs(1) {
                assert!(10 * frame <= frame + interval, "{ms} ms: {interval:?}");
            }
        }
        assert_eq!(
            loading_redraw_interval(Duration::from_millis(100)),
            Duration::from_millis(900)
        );
    }
}
