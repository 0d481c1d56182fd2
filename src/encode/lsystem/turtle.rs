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

    /// `&` (positive angle) / `^` (negative): rotation about `L` by `angle`
    /// radians; a positive angle pitches the heading down, away from `U`.
    pub(crate) fn pitch(&mut self, angle: f64) {
        self.turn(Turn::new(Axis::Left, angle));
    }

    /// `\` (positive angle) / `/` (negative): rotation about `H` by `angle`
    /// radians; a positive angle rolls `L` towards `U` (roll left).
    pub(crate) fn roll(&mut self, angle: f64) {
        self.turn(Turn::new(Axis::Heading, angle));
    }

    /// Rotates the frame by `turn`: `+`/`-` about `U` (a positive angle
    /// turns the heading towards `L`), `&`/`^` about `L` and `\`/`/` about
    /// `H` as [`pitch`](Self::pitch) and [`roll`](Self::roll).
    #[inline]
    pub(crate) fn turn(&mut self, turn: Turn) {
        let Turn {
            axis,
            sin: s,
            cos: c,
        } = turn;
        match axis {
            Axis::Up => {
                let (h, l) = (self.heading, self.left);
                self.heading = h * c + l * s;
                self.left = l * c - h * s;
            }
            Axis::Left => {
                let (h, u) = (self.heading, self.up);
                self.heading = h * c - u * s;
                self.up = u * c + h * s;
            }
            Axis::Heading => {
                let (l, u) = (self.left, self.up);
                self.left = l * c + u * s;
                self.up = u * c - l * s;
            }
        }
    }

    /// Applies one symbol. Angles are degrees when `degrees`, else radians;
    /// a symbol without a parameter takes its default from `dims`. Lengths
    /// (`F`, `!`) are in units of `dims.unit_m` metres; the state is in metres.
    pub(crate) fn apply(&mut self, s: Symbol, dims: &Dimensions, degrees: bool) -> Effect {
        if let Some(turn) = Turn::of(s, dims, degrees) {
            self.turn(turn);
            return Effect::Turned;
        }
        match s.ch {
            b'F' => {
                self.forward(step_m(s, dims));
                return Effect::Drew;
            }
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
        self.position = self.ahead(length_m);
    }

    /// The position `length_m` metres along the heading.
    pub(crate) fn ahead(&self, length_m: f64) -> DVec3 {
        self.position + self.heading * length_m
    }
}

/// The length in metres of an `F` symbol's step.
pub(crate) fn step_m(s: Symbol, dims: &Dimensions) -> f64 {
    s.param.unwrap_or(dims.forward) * dims.unit_m
}

/// An axis of the turtle's own frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Axis {
    /// `H`, for rolls.
    Heading,
    /// `L`, for pitches.
    Left,
    /// `U`, for yaws.
    Up,
}

/// A rotation of the frame about one of its own axes, by the sine and
/// cosine of its angle: computed once, it turns any number of states
/// exactly as the symbol it comes from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Turn {
    axis: Axis,
    sin: f64,
    cos: f64,
}

impl Turn {
    /// A rotation about `axis` by `angle` radians.
    #[inline]
    pub(crate) fn new(axis: Axis, angle: f64) -> Self {
        let (sin, cos) = angle.sin_cos();
        Self { axis, sin, cos }
    }

    /// The rotation a symbol makes (`+ - | & ^ \ /`), `None` for any other
    /// symbol. Angles are degrees when `degrees`; a symbol without a
    /// parameter takes its default from `dims`.
    #[inline]
    pub(crate) fn of(s: Symbol, dims: &Dimensions, degrees: bool) -> Option<Self> {
        let angle = |default: f64| {
            let a = s.param.unwrap_or(default);
            if degrees { a.to_radians() } else { a }
        };
        let (axis, angle) = match s.ch {
            b'+' => (Axis::Up, angle(dims.rotation)),
            b'-' => (Axis::Up, -angle(dims.rotation)),
            b'|' => (Axis::Up, std::f64::consts::PI),
            b'&' => (Axis::Left, angle(dims.rotation)),
            b'^' => (Axis::Left, -angle(dims.rotation)),
            b'\\' => (Axis::Heading, angle(dims.roll)),
            b'/' => (Axis::Heading, -angle(dims.roll)),
            _ => return None,
        };
        Some(Self::new(axis, angle))
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
        t.turn(Turn::new(Axis::Up, FRAC_PI_2));
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
            t.turn(Turn::new(Axis::Up, 0.37 * f64::from(i)));
            t.pitch(1.1);
            t.roll(-2.3);
        }
        assert!(close(t.heading.cross(t.left), t.up));
        assert!((t.heading.length() - 1.0).abs() < 1e-12);
    }
}
