//! Input as an ECS resource: what the window (or a test) reports between two frames, gathered
//! into the motions the camera controller reads.

use bevy_ecs::prelude::Resource;
use glam::Vec2;

/// The keys the viewer reacts to (physical positions, so WASD works on any layout).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Key {
    /// Fly forward.
    W,
    /// Fly left.
    A,
    /// Fly back.
    S,
    /// Fly right.
    D,
    /// Fly down.
    Q,
    /// Fly up.
    E,
    /// Frame the whole scene.
    F,
    /// Reset to the file's camera.
    R,
    /// Toggle the overlay.
    H,
    /// Save the current view.
    P,
    /// Play or pause the animation.
    Space,
    /// One animation frame back.
    Left,
    /// One animation frame on.
    Right,
    /// Close the window.
    Escape,
    /// A digit key (1–6 pick the displayed buffer).
    Digit(u8),
    /// `[`: less exposure.
    BracketLeft,
    /// `]`: more exposure.
    BracketRight,
    /// Either shift key (with the left button: pan).
    Shift,
}

/// Mouse buttons.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Button {
    /// Orbit (pan with shift).
    Left,
    /// Pan.
    Middle,
    /// Unused.
    Right,
}

/// One thing the user did.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum InputEvent {
    /// A key went down (repeats included).
    KeyDown(Key),
    /// A key went up.
    KeyUp(Key),
    /// A button went down.
    ButtonDown(Button),
    /// A button went up.
    ButtonUp(Button),
    /// The cursor is now at this window position (pixels, from the top-left corner).
    CursorMoved(Vec2),
    /// The wheel turned by this many lines (positive: away from the user, dolly in).
    Wheel(f32),
}

/// What the user asked of the camera since the last frame: the camera-controller system reads
/// it in [`crate::frame::FrameStage::Animate`]; the viewer clears the motions after each frame.
#[derive(Resource, Clone, Debug, Default)]
pub struct Input {
    held: Vec<Key>,
    buttons: Vec<Button>,
    cursor: Option<Vec2>,
    /// Cursor travel (window pixels) with the left button held: orbit.
    pub orbit: Vec2,
    /// Cursor travel (window pixels) with the middle button, or shift and the left button,
    /// held: pan.
    pub pan: Vec2,
    /// Wheel lines: dolly.
    pub wheel: f32,
    /// Keys that went down since the last frame (once each, in order).
    pub pressed: Vec<Key>,
    /// Wall-clock seconds the coming frame stands for (fly speed).
    pub dt: f32,
    /// Orbit about the vertical through the target, radians, added by the turntable.
    pub turntable: f32,
    /// Height of the window in pixels (pan speed: the target moves with the cursor).
    pub viewport_height: f32,
}

impl Input {
    /// Takes one event in.
    pub fn apply(&mut self, event: InputEvent) {
        match event {
            InputEvent::KeyDown(k) => {
                if !self.held.contains(&k) {
                    self.held.push(k);
                }
                self.pressed.push(k);
            }
            InputEvent::KeyUp(k) => self.held.retain(|&h| h != k),
            InputEvent::ButtonDown(b) => {
                if !self.buttons.contains(&b) {
                    self.buttons.push(b);
                }
            }
            InputEvent::ButtonUp(b) => self.buttons.retain(|&h| h != b),
            InputEvent::CursorMoved(p) => {
                if let Some(last) = self.cursor {
                    let d = p - last;
                    let left = self.buttons.contains(&Button::Left);
                    if self.buttons.contains(&Button::Middle) || (left && self.held(Key::Shift)) {
                        self.pan += d;
                    } else if left {
                        self.orbit += d;
                    }
                }
                self.cursor = Some(p);
            }
            InputEvent::Wheel(lines) => self.wheel += lines,
        }
    }

    /// Whether `key` is held down.
    pub fn held(&self, key: Key) -> bool {
        self.held.contains(&key)
    }

    /// Whether a mouse button is held down.
    pub fn button(&self, button: Button) -> bool {
        self.buttons.contains(&button)
    }

    /// Fly direction from the held keys: (right, up, forward), each −1, 0 or 1.
    pub fn fly(&self) -> glam::Vec3 {
        let axis = |plus: Key, minus: Key| f32::from(self.held(plus)) - f32::from(self.held(minus));
        glam::Vec3::new(axis(Key::D, Key::A), axis(Key::E, Key::Q), axis(Key::W, Key::S))
    }

    /// Whether the coming frame's camera will (probably) move.
    pub fn moves_camera(&self) -> bool {
        self.orbit != Vec2::ZERO
            || self.pan != Vec2::ZERO
            || self.wheel != 0.0
            || self.turntable != 0.0
            || self.fly() != glam::Vec3::ZERO
            || self.pressed.iter().any(|k| matches!(k, Key::F | Key::R))
    }

    /// Clears what one frame consumed (motions and key presses); held keys and buttons stay.
    pub fn end_frame(&mut self) {
        self.orbit = Vec2::ZERO;
        self.pan = Vec2::ZERO;
        self.wheel = 0.0;
        self.pressed.clear();
        self.turntable = 0.0;
    }
}
