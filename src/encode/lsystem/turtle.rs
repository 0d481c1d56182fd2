//! The 3D turtle of *The Algorithmic Beauty of Plants* (ABOP §1.5), shared by
//! the writer and the reader so that both compute bit-identical states.
//!
//! The frame is kept as three orthonormal `f64` vectors — heading `H`, left
//! `L`, up `U` with `H × L = U` — and every turn is a rotation of that frame
//! about one of its own axes. No Euler angles about global axes are ever
//! formed, so there is no pole at which a rotation could flip (the flaw of
//! the paper's turtle, lsystem-from-adtree-skeletons §4.4, Figure 4.14).

use glam::DVec3;

use super::format::{Dimensions, Symbol};

/// What a symbol did to the turtle, beyond turning it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Effect {
    /// Turned, set the width, or nothing (rule letters other than `F`).
    Turned,
    /// `F`: moved and drew an internode to a new node.
    Drew,
    /// `[`: the state is to be saved.
    Push,
    /// `]`: the saved state is to be restored.
    Pop,
}

/// Position, frame and width of the turtle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct TurtleState {
    /// Position relative to the trunk anchor, metres.
    pub(crate) position: DVec3,
    /// Heading `H`: the direction `F` moves in.
    pub(crate) heading: DVec3,
    /// Left `L`.
    pub(crate) left: DVec3,
    /// Up `U = H × L`.
    pub(crate) up: DVec3,
    /// Current width: the radius of the next node drawn, metres.
    pub(crate) width_m: f64,
}

impl TurtleState {
    /// The start state: at the anchor, heading +Z (up), left +X, up +Y.
    pub(crate) fn start(width_m: f64) -> Self {
        Self {
            position: DVec3::ZERO,
            heading: DVec3::Z,
            left: DVec3::X,
            up: DVec3::Y,
            width_m,
        }
    }

    /// `+` (positive angle) / `-` (negative): rotation about `U` by `angle`
    /// radians; a positive angle turns the heading towards `L` (left).
    pub(crate) fn yaw(&mut self, angle: f64) {
        let (s, c) = angle.sin_cos();
        let (h, l) = (self.heading, self.left);
        self.heading = h * c + l * s;
        self.left = l * c - h * s;
    }

    /// `&` (positive angle) / `^` (negative): rotation about `L` by `angle`
    /// radians; a positive angle pitches the heading down, away from `U`.
    pub(crate) fn pitch(&mut self, angle: f64) {
        let (s, c) = angle.sin_cos();
        let (h, u) = (self.heading, self.up);
        self.heading = h * c - u * s;
        self.up = u * c + h * s;
    }

    /// `\` (positive angle) / `/` (negative): rotation about `H` by `angle`
    /// radians; a positive angle rolls `L` towards `U` (roll left).
    pub(crate) fn roll(&mut self, angle: f64) {
        let (s, c) = angle.sin_cos();
        let (l, u) = (self.left, self.up);
        self.left = l * c + u * s;
        self.up = u * c - l * s;
    }

    /// Applies one symbol. Angles are degrees when `degrees`, else radians;
    /// a symbol without a parameter takes its default from `dims`. Lengths
    /// (`F`, `!`) are in units of `dims.unit_m` metres; the state is in metres.
    pub(crate) fn apply(&mut self, s: Symbol, dims: &Dimensions, degrees: bool) -> Effect {
        let angle = |default: f64| {
            let a = s.param.unwrap_or(default);
            if degrees { a.to_radians() } else { a }
        };
        match s.ch {
            b'F' => {
                self.forward(s.param.unwrap_or(dims.forward) * dims.unit_m);
                return Effect::Drew;
            }
            b'+' => self.yaw(angle(dims.rotation)),
            b'-' => self.yaw(-angle(dims.rotation)),
            b'|' => self.yaw(std::f64::consts::PI),
            b'&' => self.pitch(angle(dims.rotation)),
            b'^' => self.pitch(-angle(dims.rotation)),
            b'\\' => self.roll(angle(dims.roll)),
            b'/' => self.roll(-angle(dims.roll)),
            b'!' => {
                if let Some(w) = s.param {
                    self.width_m = w * dims.unit_m;
                }
            }
            b'[' => return Effect::Push,
            b']' => return Effect::Pop,
            _ => {}
        }
        Effect::Turned
    }

    /// `F(length)`: moves `length` metres along the heading.
    pub(crate) fn forward(&mut self, length_m: f64) {
        self.position += self.heading * length_m;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::FRAC_PI_2;

    fn close(a: DVec3, b: DVec3) -> bool {
        a.distance(b) < 1e-12
    }

    #[test]
    fn turns_follow_the_documented_conventions() {
        let mut t = TurtleState::start(0.1);
        t.yaw(FRAC_PI_2);
        assert!(close(t.heading, DVec3::X), "+ turns towards left (+X)");
        let mut t = TurtleState::start(0.1);
        t.pitch(FRAC_PI_2);
        assert!(close(t.heading, -DVec3::Y), "& pitches away from up (+Y)");
        let mut t = TurtleState::start(0.1);
        t.roll(FRAC_PI_2);
        assert!(close(t.left, DVec3::Y) && close(t.heading, DVec3::Z));
    }

    #[test]
    fn frame_stays_right_handed() {
        let mut t = TurtleState::start(0.1);
        for i in 0..1000 {
            t.yaw(0.37 * f64::from(i));
            t.pitch(1.1);
            t.roll(-2.3);
        }
        assert!(close(t.heading.cross(t.left), t.up));
        assert!((t.heading.length() - 1.0).abs() < 1e-12);
    }
}
