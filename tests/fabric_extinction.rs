//! Fibre-projected extinction (docs/references.md §7.3, test idea of §7.6): in a slab of aligned
//! fibres, light travelling along the fibres passes, light crossing them sees the full
//! density; the same through a free-standing fabric grid and through a fabric shell.

use glam::{Vec2, Vec3};
use velour::fabric::voxelise::{DENSITY, ID, TANGENT};
use velour::fabric::{
    generate_patch, voxelise, FabricShading, FabricShell, Fibre, FibreKind, FibrePhaseParams,
    PatchFibre, ShellParams, VoxeliseOptions, VoxelisedPatch, WeaveParams, WeavePattern, YarnId,
    YarnParams,
};
use velour::fabric::{FabricLook, FibreExtinction};
use velour::geometry::TriangleMesh;
use velour::majorant::MajorantPyramid;
use velour::math::{Aabb, Ray};
use velour::medium::{DensityField, HeterogeneousMedium};
use velour::phase::PhaseFunction;
use velour::sampling::Rng;
use velour::spectrum::Rgb;
use velour::tracking::{DensityCoefficients, TrackingStats, TransmittanceMode};

/// A 1 × 1 tile filled with straight fibres along x at z ∈ [0.4, 0.6].
fn slab() -> VoxelisedPatch {
    let yarn = YarnParams::preset("cotton1").unwrap();
    let mut base = generate_patch(&WeaveParams::new(WeavePattern::Plain, yarn), 1).unwrap();
    let mut fibres = Vec::new();
    let r = 0.004;
    let mut bounds = Aabb::EMPTY;
    let mut volume = 0.0;
    for j in 0..40 {
        for k in 0..10 {
            let y = (j as f32 + 0.5) / 40.0;
            let z = 0.4 + (k as f32 + 0.5) * 0.02;
            let points: Vec<Vec3> = (0..=8).map(|s| Vec3::new(s as f32 / 8.0, y, z)).collect();
            for &p in &points {
                bounds = bounds.union_point(p);
            }
            let fibre = Fibre {
                points,
                radius: r,
                kind: FibreKind::Regular,
                ply: 0,
                section_radius: 0.0,
                section_angle: 0.0,
            };
            volume += fibre.volume();
            fibres.push(PatchFibre {
                yarn: YarnId::Weft(0),
                fibre,
            });
        }
    }
    base.fibres = fibres;
    base.tile = Vec2::ONE;
    base.bounds = bounds;
    base.fibre_volume = volume;
    voxelise(&base, 32, &VoxeliseOptions::default()).unwrap()
}

fn medium(vp: &VoxelisedPatch, extinction: FibreExtinction, sigma: f32) -> HeterogeneousMedium {
    let yarn = YarnParams::preset("cotton1").unwrap();
    let patch = generate_patch(&WeaveParams::new(WeavePattern::Plain, yarn), 1).unwrap();
    HeterogeneousMedium {
        field: DensityField::Grid {
            grid: vp.grid.clone(),
            channel: DENSITY,
        },
        pyramid: MajorantPyramid::from_grid(&vp.grid, DENSITY).unwrap(),
        coefficients: DensityCoefficients::new(Rgb::splat(sigma), Rgb::splat(sigma)),
        phase: PhaseFunction::henyey_greenstein(0.0).unwrap(),
        tracking: Default::default(),
        fabric: Some(Box::new(FabricLook {
            tangent_channel: TANGENT,
            id_channel: ID,
            patch_voxel_size: vp.voxel_size,
            mip_level: 0,
            extinction,
            shading: FabricShading::from_patch(&FibrePhaseParams::default(), &patch).unwrap(),
        })),
        mips: None,
    }
}

/// Ratio-tracking transmittance along `ray` over `[0, len]` (mean of `n` estimates) and the
/// optical depth of the plain density by quadrature.
fn transmittance(h: &HeterogeneousMedium, ray: &Ray, len: f32, n: usize) -> f32 {
    let mut rng = Rng::new(5, 9);
    let mut stats = TrackingStats::default();
    let mut sum = 0.0f64;
    for _ in 0..n {
        let mut lookup = h.density_along(ray);
        let mut u = || rng.next_f32();
        let t = velour::tracking::transmittance(
            h.segments_along(ray, 0.0, len),
            &h.coefficients,
            |t| lookup.at(t),
            TransmittanceMode::Ratio,
            &mut u,
            &mut stats,
        );
        sum += f64::from(t[0]);
    }
    (sum / n as f64) as f32
}

#[test]
fn light_along_aligned_fibres_passes_and_across_them_is_attenuated() {
    let vp = slab();
    let h = vp.grid.index_to_world();
    let z_mid = 0.5f32;
    let _ = h;
    let sigma = 40.0;
    let projected = medium(&vp, FibreExtinction::Projected, sigma);
    let isotropic = medium(&vp, FibreExtinction::Isotropic, sigma);
    let along = Ray::new(Vec3::new(0.05, 0.37, z_mid), Vec3::X);
    let across = Ray::new(Vec3::new(0.37, 0.05, z_mid), Vec3::Y);
    // Lookups: along the fibres the projected density nearly vanishes, across it is the
    // density itself.
    let mut la = projected.density_along(&along);
    let mut li = isotropic.density_along(&along);
    let mut lc = projected.density_along(&across);
    let mut lci = isotropic.density_along(&across);
    let (mut sa, mut si, mut sc, mut sci) = (0.0, 0.0, 0.0, 0.0);
    for k in 0..900 {
        let t = k as f32 * 0.001;
        sa += la.at(t);
        si += li.at(t);
        sc += lc.at(t);
        sci += lci.at(t);
    }
    assert!(si > 50.0, "the slab is empty along the ray: {si}");
    assert!(sa < 0.05 * si, "along the fibres: {sa} of {si}");
    assert!((sc - sci).abs() < 1e-3 * sci, "across: {sc} vs {sci}");
    // Transmittance: ≈ 1 along, exp(−σ ∫ d) across (the closed form of the same density).
    let t_along = transmittance(&projected, &along, 0.9, 400);
    let depth = sci * 0.001 * sigma;
    let t_across = transmittance(&projected, &across, 0.9, 4000);
    let t_iso_along = transmittance(&isotropic, &along, 0.9, 400);
    assert!(t_along > 0.8, "along the fibres T = {t_along}");
    assert!(
        t_iso_along < 0.5 * t_along,
        "isotropic along: {t_iso_along}"
    );
    let expected = (-depth).exp();
    assert!(
        (t_across - expected).abs() < 0.03 + 0.05 * expected,
        "across: {t_across} vs exp(−{depth}) = {expected}"
    );
}

#[test]
fn a_shell_projects_its_fibres_like_the_grid() {
    let vp = slab();
    // One tile over a unit plane: the map is a translation in x, y.
    let positions = vec![
        Vec3::new(0.0, 0.0, 0.0),
        Vec3::new(1.0, 0.0, 0.0),
        Vec3::new(1.0, 1.0, 0.0),
        Vec3::new(0.0, 1.0, 0.0),
    ];
    let mesh = TriangleMesh {
        positions,
        normals: None,
        uvs: Some(vec![Vec2::ZERO, Vec2::X, Vec2::ONE, Vec2::Y]),
        indices: vec![[0, 1, 2], [0, 2, 3]],
    };
    let shell = FabricShell::new(&vp, &mesh, &ShellParams { tiles: [1.0, 1.0] }).unwrap();
    let mut tan = shell.tangent_accessor();
    let mut hint = u32::MAX;
    let (mut along, mut plain, mut across) = (0.0, 0.0, 0.0);
    let mut rng = Rng::new(2, 2);
    let t = shell.thickness();
    for _ in 0..20_000 {
        let p = Vec3::new(rng.next_f32(), rng.next_f32(), (rng.next_f32() - 0.5) * t);
        plain += shell.density(p, &mut hint);
        along += shell.projected_density(&mut tan, p, Vec3::X, &mut hint);
        across += shell.projected_density(&mut tan, p, Vec3::Y, &mut hint);
        // Straight up the slab crosses the fibres too.
        let up = shell.projected_density(&mut tan, p, Vec3::Z, &mut hint);
        let d = shell.density(p, &mut hint);
        assert!(up <= d * 1.0001 && up >= d * 0.99, "up {up} vs {d}");
    }
    assert!(plain > 100.0, "slab missed: {plain}");
    assert!(along < 0.05 * plain, "along {along} of {plain}");
    assert!(
        across > 0.99 * plain && across <= plain * 1.0001,
        "across {across} of {plain}"
    );
}
