//! How a voxelised weave patch looks to the renderer (course notes §3.2): the fibre phase
//! function of the yarn family stored in the patch's `id` channel, around the fibre tangent
//! of its `tangent` channel, and extinction that is either isotropic or depends on the angle
//! to the fibres. The density lookups along a ray that fabric needs (fibre-projected
//! extinction in a free-standing patch; the shell map of a draped patch) live here too, so
//! that media only dispatch to them.

use glam::{DMat3, DVec3, IVec3, Mat3, Vec3};

use super::fibre_scattering::extinction_scale;
use super::{FabricShading, FabricShell, FibrePhase, FibreVoxel, ShellCursor, YarnId};
use crate::grid::{floor_frac, trilerp, Accessor, SparseGrid};
use crate::math::{Ray, Vec2};
use crate::spectrum::Rgb;
use crate::texture::ColorParam;

/// How the extinction of a fibre medium depends on the direction of travel.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FibreExtinction {
    /// The same in every direction: σ_t = d·σ_t⁰ with the fibre volume fraction d.
    Isotropic,
    /// The projected width of aligned cylinders (docs/references.md §7.3):
    /// σ_t(ω) = d·σ_t⁰·sin∠(ω, t), so light travelling along the fibres passes. σ_t⁰ is
    /// scaled by [`FibreExtinction::sigma_scale`] so that the extinction averaged over
    /// directions equals the isotropic one at the same attenuation.
    Projected,
}

impl FibreExtinction {
    /// The factor on σ_t⁰ that makes the direction-averaged extinction equal the isotropic
    /// one: [`super::lod::PROJECTED_EXTINCTION_SCALE`] (4/π) for projected extinction, 1 for
    /// isotropic.
    #[must_use]
    pub fn sigma_scale(self) -> f32 {
        match self {
            FibreExtinction::Projected => super::lod::PROJECTED_EXTINCTION_SCALE,
            FibreExtinction::Isotropic => 1.0,
        }
    }
}

/// The fibre shading of a voxelised fabric: the tangent and yarn-id channels of the grid (a
/// free-standing patch) or of the shell's patch, and one fibre phase function per yarn
/// family.
#[derive(Clone, Debug)]
pub struct FabricLook {
    /// Grid channel of the averaged tangent (Vec3).
    pub tangent_channel: usize,
    /// Grid channel of the yarn id (0 warp, 1 weft, 2 pile).
    pub id_channel: usize,
    /// Voxel size of the patch in its own units (the unit the tangents are stored in).
    pub patch_voxel_size: DVec3,
    /// The patch's mip level (0 = full resolution; notes §5.3).
    pub mip_level: u32,
    /// Whether extinction depends on the angle to the fibres.
    pub extinction: FibreExtinction,
    /// One fibre phase function per yarn family.
    pub shading: FabricShading,
}

impl FabricLook {
    /// Patch-unit tangent → world direction for a free-standing patch `grid`: the placement's
    /// linear part after the patch's voxel size.
    #[must_use]
    pub fn tangent_to_world(&self, grid: &SparseGrid) -> DMat3 {
        grid.index_to_world().matrix3 * DMat3::from_diagonal(self.patch_voxel_size.recip())
    }

    /// True when extinction is fibre-projected.
    #[must_use]
    pub fn projects(&self) -> bool {
        self.extinction == FibreExtinction::Projected
    }

    /// The phase function of the yarn family whose id (as stored in the id channel,
    /// trilinearly filtered or not) is `id`: below 0.5 warp, below 1.5 weft, else pile.
    #[must_use]
    pub fn phase_for_id(&self, id: f32) -> &FibrePhase {
        let yarn = if id < 0.5 {
            YarnId::Warp(0)
        } else if id < 1.5 {
            YarnId::Weft(0)
        } else {
            YarnId::Pile
        };
        self.shading.for_yarn(yarn)
    }

    /// The yarn family of id `id`, as [`Self::phase_for_id`] picks it: 0 warp, 1 weft,
    /// 2 pile (the index into [`YarnColours`]).
    #[must_use]
    pub fn family_of_id(id: f32) -> u8 {
        if id < 0.5 {
            0
        } else if id < 1.5 {
            1
        } else {
            2
        }
    }

    /// The fibre frame of a free-standing patch `grid` at world point `p`: the world-space
    /// tangent and the yarn id of the nearest voxel. Tangents are stored in patch units and
    /// mapped through the placement, so rotated and sheared patches keep their fibre
    /// directions.
    #[must_use]
    pub fn fibre_in_grid(&self, grid: &SparseGrid, p: Vec3) -> FibreVoxel {
        let q = grid.world_to_index_point(p);
        let mut tangents = grid.accessor(self.tangent_channel);
        let t = super::tangent_near(q, |ijk| tangents.value_vec3(ijk));
        let ijk = (q + Vec3::splat(0.5)).floor().as_ivec3();
        let id = grid.accessor(self.id_channel).value(ijk);
        let world = (self.tangent_to_world(grid) * t.as_dvec3()).as_vec3();
        FibreVoxel {
            tangent: world.try_normalize().unwrap_or(Vec3::X),
            id,
        }
    }
}

/// The yarn colours of a fabric whose `warp_albedo`, `weft_albedo` or `pile_albedo` may be
/// textures (docs/textures.md, "Fabric yarn colours"): read at a walk's entry point, each
/// colour is the multiple-scattering colour of its yarn family's fibres, inverted to fibre
/// absorption per value exactly as a constant colour is ([`super::FibreColour::new`], Chiang et
/// al. 2016 eq. 9).
#[derive(Clone, Debug)]
pub struct YarnColours {
    /// Warp, weft and pile colours, each channel in `[0, 1]`.
    pub maps: [ColorParam; 3],
    /// The shared azimuthal roughness β_n of the fibre phase functions (the inversion
    /// depends on it).
    pub beta_n: f32,
}

impl YarnColours {
    /// True when a colour is a texture.
    #[must_use]
    pub fn is_textured(&self) -> bool {
        self.maps.iter().any(ColorParam::is_textured)
    }

    /// The three colours at texture coordinates `uv` with a footprint `width_uv` wide
    /// (texture units; ∞ gives the textures' means).
    #[must_use]
    pub fn at(&self, uv: Vec2, width_uv: f32) -> [Rgb; 3] {
        [
            self.maps[0].eval(uv, width_uv),
            self.maps[1].eval(uv, width_uv),
            self.maps[2].eval(uv, width_uv),
        ]
    }
}

/// `sin∠(dir, tangent)` for a unit `dir`; 1 when the tangent is zero (no fibre direction).
#[inline(always)]
#[must_use]
pub fn projected_width(dir: Vec3, tangent: Vec3) -> f32 {
    match tangent.try_normalize() {
        Some(t) => extinction_scale(dir, t),
        None => 1.0,
    }
}

/// Density × sin∠(ray, fibre) along a ray through a free-standing fabric grid
/// ([`FibreExtinction::Projected`]).
pub struct FibreGridLookup<'a> {
    /// The density channel, read through its padded bricks
    /// ([`SparseGrid::padded_accessor`]: the plain accessor's values bit for bit, without
    /// the out-of-line gather where a cell's corners straddle bricks).
    density: Accessor<'a>,
    /// The tangent channel (nearest voxel, [`super::tangent_near`]).
    tangent: Accessor<'a>,
    /// The density and tangent channels' padded bricks interleaved
    /// ([`SparseGrid::padded_pairs`]): where a cell's first corner lies in a brick, its
    /// density corners and the tangents [`super::tangent_near`] reads come from one table
    /// (the same values), the brick resolved once.
    pairs: Option<&'a [[f32; 4]]>,
    o: Vec3,
    d: Vec3,
    /// Patch-unit tangent → world direction (the placement's linear part over the voxel size).
    tangent_to_world: Mat3,
    dir: Vec3,
}

impl<'a> FibreGridLookup<'a> {
    /// Prepares lookups along `ray` (world space) in the density channel `channel` of the
    /// free-standing patch `grid` shaded by `look`.
    #[must_use]
    pub fn new(grid: &'a SparseGrid, channel: usize, look: &FabricLook, ray: &Ray) -> Self {
        let w2i = grid.world_to_index();
        let m = look.tangent_to_world(grid);
        FibreGridLookup {
            density: grid.padded_accessor(channel),
            tangent: grid.accessor(look.tangent_channel),
            pairs: grid.padded_pairs(channel, look.tangent_channel),
            o: w2i.transform_point3(ray.o.as_dvec3()).as_vec3(),
            d: w2i.transform_vector3(ray.d.as_dvec3()).as_vec3(),
            tangent_to_world: m.as_mat3(),
            dir: ray.d.normalize_or_zero(),
        }
    }

    /// The projected density at distance `t`.
    #[inline]
    pub fn at(&mut self, t: f32) -> f32 {
        let p = self.o + self.d * t;
        if let Some(table) = self.pairs {
            let (i, f) = floor_frac(p);
            if let Some(c) = self.density.padded_pair_cell(table, i) {
                let density = trilerp(&c.map(|v| v[0]), f);
                if density.is_nan() || density <= 0.0 {
                    return density;
                }
                let local = tangent_in_cell(&c, p, i, f).unwrap_or_else(|| {
                    super::tangent_near(p, |ijk| self.tangent.value_vec3_hot(ijk))
                });
                return density * projected_width(self.dir, self.tangent_to_world * local);
            }
        }
        let density = self.density.sample_trilinear(p);
        if density.is_nan() || density <= 0.0 {
            return density;
        }
        let local = super::tangent_near(p, |ijk| self.tangent.value_vec3_hot(ijk));
        density * projected_width(self.dir, self.tangent_to_world * local)
    }
}

/// [`super::tangent_near`] at index point `p` from the cell whose first corner is voxel `i`
/// (fraction `f = p − i`), given as its 8 corners' `[density, tangent]` entries `c`
/// ([`Accessor::padded_pair_cell`]): the same voxels in the same order. `None` where the
/// nearest voxel is not one of the corners (`p + 0.5` rounded past `i + 1`).
#[inline(always)]
fn tangent_in_cell(c: &[[f32; 4]; 8], p: Vec3, i: IVec3, f: Vec3) -> Option<Vec3> {
    let n = super::floor_ivec3(p + Vec3::splat(0.5)) - i;
    if !(n.cmpge(IVec3::ZERO) & n.cmple(IVec3::ONE)).all() {
        return None;
    }
    let at = |k: usize| {
        let v = c[k];
        Vec3::new(v[1], v[2], v[3])
    };
    let nearest = at(((n.x << 2) | (n.y << 1) | n.z) as usize);
    if nearest != Vec3::ZERO {
        return Some(nearest);
    }
    let mut best = (0.0f32, Vec3::ZERO);
    for k in 0..8 {
        let w = (if k & 4 != 0 { f.x } else { 1.0 - f.x })
            * (if k & 2 != 0 { f.y } else { 1.0 - f.y })
            * (if k & 1 != 0 { f.z } else { 1.0 - f.z });
        if w > best.0 {
            let v = at(k);
            if v != Vec3::ZERO {
                best = (w, v);
            }
        }
    }
    Some(best.1)
}

/// Density lookups along a ray through a fabric shell (notes §3.3): each point is mapped to
/// the patch; with fibre-projected extinction the density is scaled by sin∠(ray, fibre).
/// Point location goes through a [`ShellCursor`], which a free flight's point bounds share
/// ([`ShellLookup::bound`]).
pub struct ShellLookup<'a> {
    cursor: ShellCursor<'a>,
    /// For fibre-projected extinction: the unit direction of the ray.
    dir: Option<Vec3>,
}

impl<'a> ShellLookup<'a> {
    /// Prepares lookups along `ray` (world space) through `shell`, projected or not.
    #[must_use]
    pub fn new(shell: &'a FabricShell, ray: &Ray, projected: bool) -> Self {
        ShellLookup {
            dir: projected.then(|| ray.d.normalize_or_zero()),
            cursor: ShellCursor::new(shell, ray),
        }
    }

    /// The (projected) density at distance `t`.
    #[inline]
    pub fn at(&self, t: f32) -> f32 {
        let Some(s) = self.cursor.locate(t) else {
            return 0.0;
        };
        let shell = self.cursor.shell();
        match self.dir {
            None => shell.density_at(s),
            Some(dir) => shell.projected_density_at(None, s, dir),
        }
    }

    /// [`ShellLookup::at`], out of line (for trackers that take the lookup as a closure).
    #[inline(never)]
    pub fn at_out_of_line(&self, t: f32) -> f32 {
        self.at(t)
    }

    /// The point bound at distance `t` ([`FabricShell::point_bound`]): a lookup at the same
    /// distance next reuses its point location.
    #[inline]
    pub fn bound(&self, t: f32) -> f32 {
        self.cursor.point_bound(t)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fabric::voxelise::{DENSITY, TANGENT};
    use crate::fabric::{
        generate_patch, voxelise, FibrePhaseParams, VoxeliseOptions, WeaveParams, WeavePattern,
        YarnParams,
    };
    use crate::sampling::Rng;
    use glam::DAffine3;

    /// [`FibreGridLookup::at`] (density from the padded bricks, tangents by the inlined vector
    /// read) gives, bit for bit, the projected density written out with the plain accessors
    /// (`sample_trilinear` through the out-of-line gather, `value_vec3`): along random rays
    /// through a twill patch under a rotated, sheared placement, steps of a fraction of a
    /// voxel (cells across brick faces, the fringe where the nearest voxel holds no fibre).
    #[test]
    fn fibre_grid_lookups_match_the_plain_accessors_bit_for_bit() {
        let yarn = YarnParams::preset("cotton1").expect("preset");
        let wp = WeaveParams::new(WeavePattern::from_name("twill").expect("twill"), yarn);
        let fp = generate_patch(&wp, 3).expect("patch");
        let mut vp = voxelise(&fp, 40, &VoxeliseOptions::default()).expect("voxelise");
        let i2w = vp.grid.index_to_world();
        let shear = DMat3::from_cols(
            DVec3::new(1.0, 0.0, 0.0),
            DVec3::new(0.2, 0.9, 0.0),
            DVec3::new(0.0, 0.1, 1.1),
        );
        let m = DAffine3 {
            matrix3: DMat3::from_rotation_z(0.3) * shear * i2w.matrix3,
            translation: i2w.translation,
        };
        vp.grid.set_index_to_world(m).expect("invertible");
        let grid = &vp.grid;
        let look = FabricLook {
            tangent_channel: TANGENT,
            id_channel: crate::fabric::voxelise::ID,
            patch_voxel_size: vp.voxel_size,
            mip_level: 0,
            extinction: FibreExtinction::Projected,
            shading: FabricShading::from_patch(&FibrePhaseParams::default(), &fp).expect("shading"),
        };
        let (lo, hi) = grid.active_bbox().expect("voxels");
        let (lo, hi) = (lo.as_vec3() - 2.0, hi.as_vec3() + 2.0);
        let to_world = |q: Vec3| grid.index_to_world_point(q);
        let mut rng = Rng::new(41, 0);
        let (mut fibres, mut fringe) = (0u32, 0u32);
        for _ in 0..400 {
            let r = |rng: &mut Rng| Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32());
            let a = to_world(lo + (hi - lo) * r(&mut rng));
            let b = to_world(lo + (hi - lo) * r(&mut rng));
            let ray = Ray::new(a, (b - a).normalize());
            let len = (b - a).length();
            let mut new = FibreGridLookup::new(grid, DENSITY, &look, &ray);
            let w2i = grid.world_to_index();
            let o = w2i.transform_point3(ray.o.as_dvec3()).as_vec3();
            let d = w2i.transform_vector3(ray.d.as_dvec3()).as_vec3();
            let to_world_dir = look.tangent_to_world(grid).as_mat3();
            let (mut density, mut tangents) = (grid.accessor(DENSITY), grid.accessor(TANGENT));
            for k in 0..600 {
                let t = len * k as f32 / 600.0;
                let p = o + d * t;
                let dens = density.sample_trilinear(p);
                let want = if dens.is_nan() || dens <= 0.0 {
                    dens
                } else {
                    fibres += 1;
                    let nearest = (p + Vec3::splat(0.5)).floor().as_ivec3();
                    if tangents.value_vec3(nearest) == Vec3::ZERO {
                        fringe += 1;
                    }
                    let local = super::super::tangent_near(p, |ijk| tangents.value_vec3(ijk));
                    dens * projected_width(ray.d.normalize_or_zero(), to_world_dir * local)
                };
                let got = new.at(t);
                assert_eq!(
                    got.to_bits(),
                    want.to_bits(),
                    "t {t} at {p}: {got} vs {want}"
                );
            }
        }
        assert!(
            fibres > 10_000 && fringe > 100,
            "{fibres} in fibres, {fringe} on the fringe"
        );
    }
}
