//! The window shell of `hemi view` (feature `view`): a winit window whose events feed a
//! [`Viewer`] and whose frames show its framebuffer through softbuffer (no GPU).

use std::{
    num::NonZeroU32,
    path::PathBuf,
    rc::Rc,
    time::{Duration, Instant},
};

use glam::Vec2;
use softbuffer::{Context, Surface};
use winit::{
    application::ApplicationHandler,
    dpi::PhysicalSize,
    event::{ElementState, MouseButton, MouseScrollDelta, WindowEvent},
    event_loop::{ActiveEventLoop, ControlFlow, EventLoop},
    keyboard::{KeyCode, PhysicalKey},
    window::{Window, WindowId},
};

use super::{Button, InputEvent, Key, Viewer};
use crate::{error::HemiError, film::OutputFile};

/// What the shell does besides showing the view.
#[derive(Clone, Debug, Default)]
pub struct WindowOptions {
    /// Close after this many frames.
    pub quit_after_frames: Option<u64>,
    /// Write what the window showed on its last frame here (PNG).
    pub screenshot: Option<PathBuf>,
    /// Write per-frame statistics here (JSON).
    pub stats_json: Option<PathBuf>,
    /// When the command started (for the time to the first frame).
    pub launched: Option<Instant>,
    /// Seconds the scene took to load.
    pub load_seconds: f64,
}

/// Opens the window and runs the view until it is closed (or `quit_after_frames`).
pub fn run(viewer: Viewer, options: WindowOptions) -> Result<(), HemiError> {
    // Files are created before the window opens: a bad path fails at once.
    let screenshot = options.screenshot.as_deref().map(OutputFile::create).transpose()?;
    let stats = options.stats_json.as_deref().map(OutputFile::create_any).transpose()?;
    let mut builder = EventLoop::builder();
    #[cfg(target_os = "linux")]
    {
        use winit::platform::x11::EventLoopBuilderExtX11;
        builder.with_any_thread(true);
    }
    let event_loop = builder.build().map_err(|e| no_display(&e.to_string()))?;
    let mut app = App {
        viewer,
        options,
        window: None,
        surface: None,
        error: None,
        last_frame: None,
        first_frame_seconds: None,
        pending_input: None,
        frames: 0,
        closed: false,
    };
    event_loop.run_app(&mut app).map_err(|e| HemiError::Window(format!("the window failed: {e}")))?;
    if let Some(e) = app.error.take() {
        return Err(e);
    }
    if let Some(file) = screenshot {
        file.write_rgb8(&app.viewer.screenshot())?;
    }
    if let Some(file) = stats {
        let mut json = app.viewer.stats_json();
        json["summary"]["load_seconds"] = serde_json::json!(app.options.load_seconds);
        json["summary"]["first_frame_seconds"] = serde_json::json!(app.first_frame_seconds);
        file.write_text(&json.to_string())?;
    }
    Ok(())
}

fn no_display(why: &str) -> HemiError {
    let set = |v: &str| std::env::var_os(v).is_some_and(|s| !s.is_empty());
    let why = if !set("DISPLAY") && !set("WAYLAND_DISPLAY") {
        "no display: DISPLAY is not set".to_string()
    } else {
        // winit's errors start with the source location: keep what follows it.
        let tail = why.find(".rs:").and_then(|i| why[i..].find(": ").map(|j| &why[i + j + 2..]));
        tail.unwrap_or(why).trim_end_matches('.').to_string()
    };
    HemiError::Window(format!("cannot open a window ({why}); use `hemi render` to render without a display"))
}

struct App {
    viewer: Viewer,
    options: WindowOptions,
    window: Option<Rc<Window>>,
    surface: Option<Surface<Rc<Window>, Rc<Window>>>,
    error: Option<HemiError>,
    last_frame: Option<Instant>,
    first_frame_seconds: Option<f64>,
    /// When the oldest input not yet shown arrived.
    pending_input: Option<Instant>,
    frames: u64,
    closed: bool,
}

impl App {
    fn fail(&mut self, event_loop: &ActiveEventLoop, e: HemiError) {
        self.error.get_or_insert(e);
        event_loop.exit();
    }

    fn input(&mut self, event: InputEvent) {
        self.pending_input.get_or_insert_with(Instant::now);
        self.viewer.handle(event);
        if let Some(w) = &self.window {
            w.request_redraw();
        }
    }

    fn open(&mut self, event_loop: &ActiveEventLoop) -> Result<(), HemiError> {
        let (w, h) = self.viewer.options().size;
        let attributes = Window::default_attributes()
            .with_title(self.viewer.title())
            .with_inner_size(PhysicalSize::new(w, h))
            .with_resizable(true);
        let window = Rc::new(event_loop.create_window(attributes).map_err(|e| no_display(&e.to_string()))?);
        let context = Context::new(window.clone()).map_err(|e| no_display(&e.to_string()))?;
        let surface = Surface::new(&context, window.clone()).map_err(|e| no_display(&e.to_string()))?;
        self.window = Some(window);
        self.surface = Some(surface);
        Ok(())
    }

    /// Renders a frame and presents it.
    fn redraw(&mut self, event_loop: &ActiveEventLoop) -> Result<(), HemiError> {
        let (Some(window), Some(surface)) = (&self.window, &mut self.surface) else { return Ok(()) };
        let size = window.inner_size();
        let (w, h) = (size.width.max(1), size.height.max(1));
        if (w, h) != self.viewer.options().size {
            self.viewer.resize(w, h);
        }
        let now = Instant::now();
        let dt = self.last_frame.map_or(Duration::ZERO, |t| now - t);
        self.last_frame = Some(now);
        let input_at = self.pending_input.take();
        self.viewer.frame(dt)?;
        for m in self.viewer.take_messages() {
            crate::cli::console::note(&format!("hemi: {m}"));
        }
        let fail = |e: softbuffer::SoftBufferError| HemiError::Window(format!("cannot show the frame: {e}"));
        let (nw, nh) = (NonZeroU32::new(w).expect("w ≥ 1"), NonZeroU32::new(h).expect("h ≥ 1"));
        surface.resize(nw, nh).map_err(fail)?;
        let mut buffer = surface.buffer_mut().map_err(fail)?;
        let fb = self.viewer.framebuffer();
        let n = buffer.len().min(fb.len());
        buffer[..n].copy_from_slice(&fb[..n]);
        buffer.present().map_err(fail)?;
        if let Some(at) = input_at {
            self.viewer.set_latency(at.elapsed().as_secs_f64() * 1e3);
        }
        if self.first_frame_seconds.is_none() {
            self.first_frame_seconds = self.options.launched.map(|l| l.elapsed().as_secs_f64());
        }
        window.set_title(&self.viewer.title());
        self.frames += 1;
        if self.options.quit_after_frames.is_some_and(|n| self.frames >= n) {
            self.closed = true;
            event_loop.exit();
        }
        Ok(())
    }
}

impl ApplicationHandler for App {
    fn resumed(&mut self, event_loop: &ActiveEventLoop) {
        if self.window.is_none()
            && let Err(e) = self.open(event_loop)
        {
            self.fail(event_loop, e);
        }
    }

    fn window_event(&mut self, event_loop: &ActiveEventLoop, _id: WindowId, event: WindowEvent) {
        if self.closed {
            return;
        }
        match event {
            WindowEvent::CloseRequested | WindowEvent::Destroyed => {
                self.closed = true;
                event_loop.exit();
            }
            WindowEvent::RedrawRequested => {
                if let Err(e) = self.redraw(event_loop) {
                    self.fail(event_loop, e);
                }
            }
            WindowEvent::Resized(_) => {
                if let Some(w) = &self.window {
                    w.request_redraw();
                }
            }
            WindowEvent::KeyboardInput { event, .. } => {
                let PhysicalKey::Code(code) = event.physical_key else { return };
                if code == KeyCode::Escape && event.state == ElementState::Pressed {
                    self.closed = true;
                    event_loop.exit();
                    return;
                }
                if let Some(key) = key_of(code) {
                    self.input(match event.state {
                        ElementState::Pressed => InputEvent::KeyDown(key),
                        ElementState::Released => InputEvent::KeyUp(key),
                    });
                }
            }
            WindowEvent::MouseInput { state, button, .. } => {
                let button = match button {
                    MouseButton::Left => Button::Left,
                    MouseButton::Middle => Button::Middle,
                    MouseButton::Right => Button::Right,
                    _ => return,
                };
                self.input(match state {
                    ElementState::Pressed => InputEvent::ButtonDown(button),
                    ElementState::Released => InputEvent::ButtonUp(button),
                });
            }
            WindowEvent::CursorMoved { position, .. } => {
                self.input(InputEvent::CursorMoved(Vec2::new(position.x as f32, position.y as f32)))
            }
            WindowEvent::MouseWheel { delta, .. } => {
                let lines = match delta {
                    MouseScrollDelta::LineDelta(_, y) => y,
                    MouseScrollDelta::PixelDelta(p) => p.y as f32 / 40.0,
                };
                self.input(InputEvent::Wheel(lines));
            }
            _ => {}
        }
    }

    fn about_to_wait(&mut self, event_loop: &ActiveEventLoop) {
        if self.closed {
            return;
        }
        let busy = self.viewer.needs_frame() || self.options.quit_after_frames.is_some();
        if busy {
            event_loop.set_control_flow(ControlFlow::Poll);
            if let Some(w) = &self.window {
                w.request_redraw();
            }
        } else {
            event_loop.set_control_flow(ControlFlow::Wait);
        }
    }
}

/// The viewer's key at a physical key position.
fn key_of(code: KeyCode) -> Option<Key> {
    Some(match code {
        KeyCode::KeyW => Key::W,
        KeyCode::KeyA => Key::A,
        KeyCode::KeyS => Key::S,
        KeyCode::KeyD => Key::D,
        KeyCode::KeyQ => Key::Q,
        KeyCode::KeyE => Key::E,
        KeyCode::KeyF => Key::F,
        KeyCode::KeyR => Key::R,
        KeyCode::KeyH => Key::H,
        KeyCode::KeyP => Key::P,
        KeyCode::Space => Key::Space,
        KeyCode::ArrowLeft => Key::Left,
        KeyCode::ArrowRight => Key::Right,
        KeyCode::BracketLeft => Key::BracketLeft,
        KeyCode::BracketRight => Key::BracketRight,
        KeyCode::ShiftLeft | KeyCode::ShiftRight => Key::Shift,
        KeyCode::Digit1 => Key::Digit(1),
        KeyCode::Digit2 => Key::Digit(2),
        KeyCode::Digit3 => Key::Digit(3),
        KeyCode::Digit4 => Key::Digit(4),
        KeyCode::Digit5 => Key::Digit(5),
        KeyCode::Digit6 => Key::Digit(6),
        _ => return None,
    })
}
