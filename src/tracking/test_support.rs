//! Shared fixtures of the trackers' unit tests: a counted stream of uniform numbers, a ray's
//! segments with every kind of bound, a density and point bounds around it.

use super::PointBounds;
use crate::majorant::{Bounds, MajorantSegment};

/// A fixed stream of uniform numbers (an LCG), counting its draws.
pub(super) struct Stream {
    state: u64,
    pub(super) draws: u32,
}

impl Stream {
    pub(super) fn new(seed: u64) -> Self {
        Stream {
            state: seed.wrapping_mul(0x9e37_79b9_7f4a_7c15) | 1,
            draws: 0,
        }
    }
    pub(super) fn next(&mut self) -> f32 {
        self.draws += 1;
        self.state = self
            .state
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        (self.state >> 40) as f32 / (1u64 << 24) as f32
    }
}

/// Segments over [0, 3] with tight, loose, violated (estimated) and constant bounds.
pub(super) fn test_segments() -> Vec<MajorantSegment> {
    let b = |min, max, mean| Bounds { min, max, mean };
    vec![
        MajorantSegment::new(0.0, 0.4, b(0.0, 0.3, 0.1), true),
        MajorantSegment::constant(0.4, 0.6, 0.5),
        MajorantSegment::new(0.6, 1.3, b(0.2, 0.9, 0.5), true),
        // Estimated bounds the density violates (weighted tracking).
        MajorantSegment::new(1.3, 2.0, b(0.4, 0.5, 0.45), false),
        MajorantSegment::new(2.0, 3.0, b(0.0, 1.0, 0.5), true),
    ]
}

/// A density in [0, 1] with structure on the scale of the segments.
pub(super) fn test_density(t: f32) -> f32 {
    (0.5 + 0.45 * (7.3 * t).sin() * (2.1 * t + 0.4).cos()).clamp(0.0, 1.0)
}

/// Point bounds around the density: tight, loose, and violated in places.
pub(super) struct TestBounds;

impl PointBounds for TestBounds {
    fn at(&mut self, t: f32) -> Option<(f32, f32)> {
        let d = test_density(t);
        match ((t * 13.0) as i32).rem_euclid(4) {
            0 => None,
            1 => Some(((d - 0.05).max(0.0), (d + 0.05).min(1.0))),
            2 => Some((0.0, 1.0)),
            // Violated: the density lies above the bound.
            _ => Some(((d - 0.2).max(0.0), (d - 0.01).max(0.0))),
        }
    }
}
