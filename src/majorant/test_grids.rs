//! Test-only sparse grids shared by the majorant modules' bit-for-bit tests.

use glam::{IVec3, Vec3};

use crate::grid::{ChannelKind, SparseGrid, SparseGridBuilder, Storage, TileLevel};

/// A small generator (splitmix64) for the tests' values.
pub(super) struct Mix(pub(super) u64);

impl Mix {
    pub(super) fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in `[0, 1)` with 24 bits.
    pub(super) fn f32(&mut self) -> f32 {
        (self.next() >> 40) as f32 / (1u64 << 24) as f32
    }
}

/// A grid in `storage` with a vector channel (0) before the density (returned with the
/// grid), so that the density is not channel 0 of a one-component layout: a block tile at
/// block key (−1, 0, 0), a brick tile at brick key (1, 1, 1), and 3,000 scattered voxels around
/// them (values 0, 1 or uniform in `[0, 3)`) that leave the brick tile alone.
pub(super) fn mixed_grid(storage: Storage, rng: &mut Mix) -> (SparseGrid, usize) {
    let mut b = SparseGridBuilder::new(storage);
    b.add_channel("colour", ChannelKind::Vec3, Vec3::splat(0.5));
    let density = b.add_channel("density", ChannelKind::Scalar, Vec3::splat(0.0));
    b.set_tile(
        TileLevel::Block,
        IVec3::new(-1, 0, 0),
        &[0.2, 0.3, 0.4, 0.75],
        true,
    )
    .expect("block tile");
    b.set_tile(
        TileLevel::Brick,
        IVec3::new(1, 1, 1),
        &[0.1, 0.1, 0.1, 0.3],
        true,
    )
    .expect("brick tile");
    for _ in 0..3000 {
        let p = IVec3::new(
            (rng.next() % 40) as i32,
            (rng.next() % 24) as i32 - 4,
            (rng.next() % 32) as i32 - 8,
        );
        if (p >> 3) == IVec3::ONE {
            continue;
        }
        let v = match rng.next() % 8 {
            0 => 0.0,
            1 => 1.0,
            _ => rng.f32() * 3.0,
        };
        b.set_value(density, p, v).expect("voxel");
        b.set_value_vec3(0, p, Vec3::new(v, 1.0 - v, 2.0))
            .expect("colour");
    }
    (b.build(), density)
}
