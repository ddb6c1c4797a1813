//! Input of the window loop: the controls from the held keys and the mouse (or the control
//! script), the eye feed, and the quick-look keys (overlay, debug view, fog, anti-aliasing,
//! sun, reset, motion mode, screenshot).

use super::motion::{Controls, Mode};
use super::prepare::EyeSource;
use super::window::App;
use crate::{Error, Result};
use glam::DVec3;
use winit::event_loop::ActiveEventLoop;
use winit::keyboard::KeyCode;

impl App {
    /// Controls from the held keys and the mouse, or the script.
    pub(super) fn controls(&mut self, t: f64) -> Controls {
        let k = |c: KeyCode| f64::from(u8::from(self.keys.contains(&c)));
        let axis = |pos: KeyCode, neg: KeyCode| k(pos) - k(neg);
        let look = std::mem::take(&mut self.look);
        let mut c = match self.prep.motion.mode {
            Mode::Aircraft => Controls {
                throttle_delta: axis(KeyCode::KeyW, KeyCode::KeyS),
                pitch: axis(KeyCode::ArrowDown, KeyCode::ArrowUp),
                roll: axis(KeyCode::ArrowRight, KeyCode::ArrowLeft),
                yaw: axis(KeyCode::KeyD, KeyCode::KeyA),
                ..Controls::default()
            },
            _ => Controls {
                forward: axis(KeyCode::KeyW, KeyCode::KeyS),
                right: axis(KeyCode::KeyD, KeyCode::KeyA),
                up: axis(KeyCode::Space, KeyCode::KeyC),
                yaw: axis(KeyCode::ArrowRight, KeyCode::ArrowLeft),
                pitch: axis(KeyCode::ArrowUp, KeyCode::ArrowDown),
                look,
                fast: k(KeyCode::ShiftLeft) + k(KeyCode::ShiftRight) > 0.0,
                ..Controls::default()
            },
        };
        if let Some(s) = self.prep.script.as_ref().and_then(|s| s.at(t)) {
            c = s;
        }
        c
    }

    /// The eye point of frame `frame` from the eye feed, if there is one.
    pub(super) fn eye_for(&mut self, frame: u64) -> Result<Option<DVec3>> {
        Ok(match &mut self.prep.eyes {
            None => None,
            Some(EyeSource::File(f)) => Some(f.at(frame)),
            Some(EyeSource::Stdin(rx, last)) => {
                while let Ok(r) = rx.try_recv() {
                    *last = Some(r.map_err(|m| Error::invalid("--eye-feed -", m))?);
                }
                *last
            }
        })
    }

    /// A key went down or up: held keys for the controls, and the quick-look keys.
    pub(super) fn on_key(
        &mut self,
        el: &ActiveEventLoop,
        code: KeyCode,
        pressed: bool,
        repeat: bool,
    ) {
        if pressed {
            self.keys.insert(code);
        } else {
            self.keys.remove(&code);
        }
        if !pressed || repeat {
            return;
        }
        let t = self.frame as f64 / self.prep.opts.rate;
        match code {
            KeyCode::Escape => el.exit(),
            KeyCode::KeyH | KeyCode::F1 => self.overlay = !self.overlay,
            KeyCode::KeyV => self.view_mode = self.view_mode.next(),
            KeyCode::KeyF => {
                self.desc.fog.visibility = if self.desc.fog.visibility > 0.0 {
                    0.0
                } else {
                    self.fog_visibility
                };
            }
            KeyCode::KeyE => {
                let a = &mut self.prep.settings.antialias;
                *a = if a.is_on() {
                    crate::gpu::Antialias::OFF
                } else {
                    self.antialias_on
                };
            }
            KeyCode::KeyR => self.prep.motion.reset(t),
            KeyCode::Tab | KeyCode::KeyM => self.prep.motion.cycle_mode(),
            KeyCode::BracketLeft | KeyCode::BracketRight => {
                let h = self
                    .sun_hour
                    .unwrap_or(12.0 + (self.desc.sun.azimuth - 180.0) / 15.0);
                let h = (h + if code == KeyCode::BracketRight {
                    1.0
                } else {
                    -1.0
                })
                .rem_euclid(24.0);
                self.sun_hour = Some(h);
                self.desc.sun.azimuth = (180.0 + 15.0 * (h - 12.0)).rem_euclid(360.0);
                self.desc.sun.elevation =
                    (60.0 * (std::f64::consts::PI * (h - 6.0) / 12.0).sin()).clamp(-89.0, 89.0);
            }
            KeyCode::KeyP | KeyCode::F12 => self.screenshot = true,
            _ => {}
        }
    }
}
