//! Deterministic randomness and rotations for the generators.
//!
//! The same seed must give bit-identical trees and scans on every machine.
//! ChaCha8 is a counter-based generator whose output rand documents as
//! portable, and every transcendental function used here comes from the
//! pure-Rust `libm` crate rather than the platform's C library, whose `sin`,
//! `cos` and `log` may differ in the last bit between systems. Square roots
//! and the four basic operations are correctly rounded under IEEE 754 and
//! therefore portable as they are.

use glam::Vec3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Independent random streams, so that e.g. a TLS scan of a tree does not
/// replay the numbers that grew it when both use the same seed.
#[derive(Debug, Clone, Copy)]
pub(crate) enum Stream {
    Tree = 1,
    Tls = 2,
    Als = 3,
    TlsGround = 4,
}

/// A ChaCha8 generator for `seed` on one stream.
pub(crate) fn seeded(seed: u64, stream: Stream) -> ChaCha8Rng {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    rng.set_stream(stream as u64);
    rng
}

/// Uniform in `[0, 1)`.
pub(crate) fn unit(rng: &mut ChaCha8Rng) -> f32 {
    rng.random::<f32>()
}

/// Uniform in `[centre - variation, centre + variation)`: Weber & Penn's
/// "x ± x_v" for every varied parameter.
pub(crate) fn spread(rng: &mut ChaCha8Rng, centre: f32, variation: f32) -> f32 {
    centre + variation * (2.0 * unit(rng) - 1.0)
}

/// A standard normal sample (Box–Muller).
pub(crate) fn gaussian(rng: &mut ChaCha8Rng) -> f32 {
    // 1 - u lies in (0, 1], so the logarithm is finite.
    let u1 = 1.0 - unit(rng);
    let u2 = unit(rng);
    let r = libm::sqrtf(-2.0 * libm::logf(u1));
    r * libm::cosf(std::f32::consts::TAU * u2)
}

/// A vector of three independent normal samples scaled by `sd`.
pub(crate) fn gaussian_vec(rng: &mut ChaCha8Rng, sd: f32) -> Vec3 {
    Vec3::new(gaussian(rng), gaussian(rng), gaussian(rng)) * sd
}

/// Rotates `v` about the unit vector `axis` by `angle_rad` (Rodrigues).
pub(crate) fn rotate(v: Vec3, axis: Vec3, angle_rad: f32) -> Vec3 {
    let (s, c) = libm::sincosf(angle_rad);
    v * c + axis.cross(v) * s + axis * axis.dot(v) * (1.0 - c)
}

/// A unit vector perpendicular to the unit vector `v`.
pub(crate) fn any_perpendicular(v: Vec3) -> Vec3 {
    let helper = if v.x.abs() < 0.9 { Vec3::X } else { Vec3::Y };
    v.cross(helper).normalize()
}
