//! `velour voxelize`: level sets against analytic distances (a box exactly, a sphere within its
//! tessellation error), fog integrals against the mesh's volume, noise, open meshes, bad input;
//! and, with real OpenVDB (Debian's `python3-openvdb`), OpenVDB reads our level set and agrees
//! with its own mesh-to-level-set conversion (skipped with a notice when OpenVDB is missing,
//! a failure under `VELOUR_REQUIRE_EXTERNAL=1`).

mod common;

use common::cli::run_velour;
use common::external;
use common::files::{mesh_path, repo_path, TempDir};
use glam::{DVec3, IVec3, Vec3};
use serde_json::Value;
use velour::geometry::{icosphere, load_ply, write_ply, TriangleMesh};
use velour::procedural::{FbmField, FbmParams};
use velour::vdb::read_vdb;
use velour::voxelize::{
    point_triangle_distance_sq, voxelize, NoiseOptions, VolumeKind, VoxelizeOptions, Voxelized,
};

/// An axis-aligned box mesh (12 triangles, outward), optionally without its −z face.
fn box_mesh(lo: Vec3, hi: Vec3, drop_bottom: bool) -> TriangleMesh {
    let p = |x: bool, y: bool, z: bool| {
        Vec3::new(
            if x { hi.x } else { lo.x },
            if y { hi.y } else { lo.y },
            if z { hi.z } else { lo.z },
        )
    };
    let positions: Vec<Vec3> = (0..8)
        .map(|i| p(i & 1 != 0, i & 2 != 0, i & 4 != 0))
        .collect();
    // Quads (outward, counter-clockwise seen from outside): -x, +x, -y, +y, -z, +z.
    let quads: [[u32; 4]; 6] = [
        [0, 4, 6, 2],
        [1, 3, 7, 5],
        [0, 1, 5, 4],
        [2, 6, 7, 3],
        [0, 2, 3, 1],
        [4, 5, 7, 6],
    ];
    let mut indices = Vec::new();
    for (f, q) in quads.iter().enumerate() {
        if drop_bottom && f == 4 {
            continue;
        }
        indices.push([q[0], q[1], q[2]]);
        indices.push([q[0], q[2], q[3]]);
    }
    TriangleMesh {
        positions,
        indices,
        ..TriangleMesh::default()
    }
}

/// Exact signed distance to an axis-aligned box.
fn box_sdf(p: DVec3, lo: DVec3, hi: DVec3) -> f64 {
    let c = (lo + hi) * 0.5;
    let h = (hi - lo) * 0.5;
    let q = (p - c).abs() - h;
    q.max(DVec3::ZERO).length() + q.max_element().min(0.0)
}

fn sphere_mesh(radius: f32, subdivisions: u32) -> TriangleMesh {
    let mut m = icosphere(subdivisions);
    for p in &mut m.positions {
        *p *= radius;
    }
    m
}

fn level_set(mesh: &TriangleMesh, v: f64, w: f64) -> Voxelized {
    let opts = VoxelizeOptions {
        voxel_size: v,
        kind: VolumeKind::LevelSet { half_width: w },
        noise: None,
    };
    voxelize(mesh, "test mesh", &opts).unwrap()
}

fn fog(mesh: &TriangleMesh, v: f64, band: f64, noise: Option<NoiseOptions>) -> Voxelized {
    let opts = VoxelizeOptions {
        voxel_size: v,
        kind: VolumeKind::Fog { band },
        noise,
    };
    voxelize(mesh, "test mesh", &opts).unwrap()
}

/// Every voxel of the domain.
fn domain_voxels(vol: &Voxelized) -> Vec<IVec3> {
    let (lo, hi) = vol.report.domain;
    let mut out = Vec::new();
    for x in lo.x..=hi.x {
        for y in lo.y..=hi.y {
            for z in lo.z..=hi.z {
                out.push(IVec3::new(x, y, z));
            }
        }
    }
    out
}

/// The box's level set equals its exact signed distance on the band, is ±background off it,
/// and its active voxels are exactly those closer than W voxels. Reversed winding gives the
/// identical grid (the sign ignores orientation).
#[test]
fn box_level_set_is_the_exact_signed_distance() {
    let (lo, hi) = (
        Vec3::new(-0.313, -0.207, -0.151),
        Vec3::new(0.289, 0.171, 0.263),
    );
    let v = 0.02;
    let w = 3.0;
    let vol = level_set(&box_mesh(lo, hi, false), v, w);
    assert_eq!(vol.class, "level set");
    assert_eq!(vol.name, "surface");
    let bg = (w * v) as f32;
    assert_eq!(vol.grid.background(0), bg);
    let (dlo, dhi) = (lo.as_dvec3(), hi.as_dvec3());
    let mut active = 0u64;
    for ijk in domain_voxels(&vol) {
        let p = ijk.as_dvec3() * v;
        let exact = box_sdf(p, dlo, dhi);
        let value = f64::from(vol.grid.value_at(ijk));
        let is_active = vol.grid.is_active(ijk);
        if exact.abs() < w * v - 1e-9 && exact.abs() > 1e-4 * v {
            assert!(
                is_active,
                "{ijk}: exact {exact} inside the band but inactive"
            );
            // f32 storage of a world distance: 1e-7 relative, far below 1e-5 voxel.
            assert!(
                (value - exact).abs() < 1e-5 * v,
                "{ijk}: {value} vs exact {exact}"
            );
            active += 1;
        } else if exact.abs() > w * v + 1e-9 {
            assert!(
                !is_active,
                "{ijk}: exact {exact} outside the band but active"
            );
            assert_eq!(
                value as f32,
                if exact < 0.0 { -bg } else { bg },
                "{ijk}: off-band value"
            );
        }
    }
    let on_surface = domain_voxels(&vol)
        .iter()
        .filter(|ijk| box_sdf(ijk.as_dvec3() * v, dlo, dhi).abs() <= 1e-4 * v)
        .count() as u64;
    assert_eq!(vol.grid.active_voxels(), active + on_surface);
    assert_eq!(vol.report.active_voxels, active + on_surface);
    // Deep inside: −background, inactive (a constant tile or inactive voxel).
    let centre = ((lo + hi) * 0.5 / v as f32).round().as_ivec3();
    assert_eq!(vol.grid.value_at(centre), -bg);
    assert!(!vol.grid.is_active(centre));

    let mut reversed = box_mesh(lo, hi, false);
    for t in &mut reversed.indices {
        t.swap(1, 2);
    }
    let rev = level_set(&reversed, v, w);
    for ijk in domain_voxels(&vol) {
        assert_eq!(
            rev.grid.value_at(ijk).to_bits(),
            vol.grid.value_at(ijk).to_bits(),
            "{ijk}"
        );
        assert_eq!(rev.grid.is_active(ijk), vol.grid.is_active(ijk), "{ijk}");
    }
}

/// A box whose faces lie exactly on voxel centres (every axis ray passes through edges and
/// vertices of the mesh): the exact parity still gives the right sign everywhere off the
/// surface.
#[test]
fn grid_aligned_box_has_exact_signs() {
    let v = 0.25;
    let (lo, hi) = (Vec3::splat(-2.0), Vec3::new(2.0, 1.5, 3.0));
    let vol = level_set(&box_mesh(lo, hi, false), v, 2.0);
    for ijk in domain_voxels(&vol) {
        let exact = box_sdf(ijk.as_dvec3() * v, lo.as_dvec3(), hi.as_dvec3());
        let value = f64::from(vol.grid.value_at(ijk));
        // Vertices are rounded to 2^-16 voxel for the exact parity: signs hold beyond that.
        if exact.abs() > 1e-4 * v {
            assert_eq!(value < 0.0, exact < 0.0, "{ijk}: {value} vs {exact}");
            if exact.abs() < 2.0 * v - 1e-9 {
                assert!(
                    (value - exact).abs() < 1e-5 * v,
                    "{ijk}: {value} vs {exact}"
                );
            }
        } else {
            assert!(value.abs() < 1e-6 * v, "{ijk} lies on the surface: {value}");
        }
    }
}

/// An octahedron with its vertices on voxel centres: lattice lines run through its vertices,
/// along its edges' projections and through points where four faces meet, the cases the exact
/// parity's tie-breaking exists for. Every voxel off the surface gets the right sign, and
/// voxels whose closest feature is a face get the face distance (|x| + |y| + |z| − r) / √3.
#[test]
fn octahedron_on_the_lattice_has_exact_signs() {
    let v = 0.25;
    let r = 2.0f32;
    let positions = vec![
        Vec3::new(r, 0.0, 0.0),
        Vec3::new(-r, 0.0, 0.0),
        Vec3::new(0.0, r, 0.0),
        Vec3::new(0.0, -r, 0.0),
        Vec3::new(0.0, 0.0, r),
        Vec3::new(0.0, 0.0, -r),
    ];
    let mut indices = Vec::new();
    for (x, y, z) in [
        (0u32, 2u32, 4u32),
        (2, 1, 4),
        (1, 3, 4),
        (3, 0, 4),
        (2, 0, 5),
        (1, 2, 5),
        (3, 1, 5),
        (0, 3, 5),
    ] {
        indices.push([x, y, z]);
    }
    let mesh = TriangleMesh {
        positions,
        indices,
        ..TriangleMesh::default()
    };
    assert!(mesh.is_closed());
    let vol = level_set(&mesh, v, 3.0);
    let mut checked = 0;
    let mut on_surface = 0;
    for ijk in domain_voxels(&vol) {
        let p = ijk.as_dvec3() * v;
        let l1 = p.x.abs() + p.y.abs() + p.z.abs() - f64::from(r);
        on_surface += u64::from(l1.abs() <= 1e-9);
        let value = f64::from(vol.grid.value_at(ijk));
        if l1.abs() > 1e-9 {
            assert_eq!(value < 0.0, l1 < 0.0, "{ijk}: {value} vs {l1}");
            checked += 1;
        } else {
            assert!(value.abs() < 1e-6 * v, "{ijk} lies on the surface: {value}");
        }
        // Inside, the closest feature is always a face.
        if l1 < 0.0 && -l1 / 3f64.sqrt() < 3.0 * v {
            assert!(
                (value - l1 / 3f64.sqrt()).abs() < 1e-5 * v,
                "{ijk}: {value} vs {l1}"
            );
        }
    }
    assert!(checked > 1000);
    // Only voxels on the surface can see their six half-rays disagree.
    assert!(vol.report.split_votes <= on_surface, "{:?}", vol.report);
}

/// `--help` gives every flag's unit and default.
#[test]
fn help_names_units_and_defaults() {
    let r = run_velour(["voxelize", "--help"]);
    r.assert_success();
    for needle in [
        "world units",
        "--half-width",
        "in voxels",
        "[default: 3]",
        "--band",
        "1 / world unit",
        "[default: 4]",
        "rest-space",
        "surface",
        "density",
    ] {
        assert!(
            r.stdout.contains(needle),
            "`{needle}` not in --help: {}",
            r.stdout
        );
    }
}

/// Largest distance between a sphere mesh (vertices on the sphere) and the sphere: the deepest
/// face, R − min distance from the centre to a triangle.
fn tessellation_error(mesh: &TriangleMesh, radius: f64) -> f64 {
    mesh.indices
        .iter()
        .map(|t| {
            let tri = t.map(|i| mesh.positions[i as usize].as_dvec3());
            radius - point_triangle_distance_sq(DVec3::ZERO, &tri).sqrt()
        })
        .fold(0.0, f64::max)
}

/// A sphere's level set agrees with the analytic distance |p| − R on every active voxel within
/// the mesh's own tessellation error (the signed distances to two surfaces differ by at most
/// their Hausdorff distance), and the band is the analytic band up to that error.
#[test]
fn sphere_level_set_matches_the_analytic_distance() {
    let r = 0.5;
    let v = 0.02; // 25 voxels of radius
    let mesh = sphere_mesh(r as f32, 5);
    let tol = tessellation_error(&mesh, r) + 1e-6;
    assert!(tol < 0.05 * v, "tessellation error {tol}");
    let vol = level_set(&mesh, v, 3.0);
    let mut active = 0;
    let mut max_err: f64 = 0.0;
    for ijk in domain_voxels(&vol) {
        let p = ijk.as_dvec3() * v;
        let exact = p.length() - r;
        let value = f64::from(vol.grid.value_at(ijk));
        if vol.grid.is_active(ijk) {
            active += 1;
            max_err = max_err.max((value - exact).abs());
            assert!(exact.abs() < 3.0 * v + tol, "{ijk}: active at {exact}");
        } else {
            assert!(exact.abs() > 3.0 * v - tol, "{ijk}: inactive at {exact}");
            assert_eq!(value.signum(), exact.signum(), "{ijk}");
        }
    }
    assert!(max_err <= tol, "largest error {max_err} > {tol}");
    // The analytic band holds 4π/3 ((R+3V)³ − (R−3V)³) / V³ voxels.
    let expected =
        4.0 / 3.0 * std::f64::consts::PI * ((r + 3.0 * v).powi(3) - (r - 3.0 * v).powi(3))
            / v.powi(3);
    let rel = (f64::from(active) - expected) / expected;
    assert!(rel.abs() < 0.02, "{active} active voxels vs {expected:.0}");
}

/// The fog's integral matches the mesh's volume within 3 % when the ramp is thin against the
/// object (the ramp removes ½ · area · B · V; here 1.5 B V / R = 1.5 %), and matches that
/// prediction (with the sphere's curvature term) within 0.3 %.
#[test]
fn fog_integral_matches_the_mesh_volume() {
    let r = 0.5;
    let v = 0.005; // 100 voxels of radius
    let mesh = sphere_mesh(r as f32, 5);
    let vol = fog(&mesh, v, 1.0, None);
    assert_eq!(vol.class, "fog volume");
    assert_eq!(vol.name, "density");
    assert_eq!(vol.grid.background(0), 0.0);
    let rep = &vol.report;
    let volume = rep.mesh_volume;
    assert!((rep.integral / volume - 1.0).abs() < 0.03, "{rep:?}");
    // Ramp deficit over a sphere: ∫₀^{BV} (1 − t/BV) A (1 − t/R)² dt.
    let bv = v;
    let deficit = rep.mesh_area * bv * (0.5 - bv / (3.0 * r) + bv * bv / (12.0 * r * r));
    let predicted = volume - deficit;
    assert!(
        (rep.integral / predicted - 1.0).abs() < 0.003,
        "integral {} vs predicted {predicted}",
        rep.integral
    );
    // The integral the file holds, counted from the written grid.
    let dir = TempDir::new("voxelize-fog");
    let path = dir.join("fog.vdb");
    let opts = VoxelizeOptions {
        voxel_size: v,
        kind: VolumeKind::Fog { band: 1.0 },
        noise: None,
    };
    velour::voxelize::write(&path, &vol, "sphere", &opts).unwrap();
    let grids = read_vdb(&path).unwrap();
    assert_eq!(grids.len(), 1);
    let s = grids[0].stats();
    assert_eq!(grids[0].class, "fog volume");
    assert!((s.sum[0] * v.powi(3) / rep.integral - 1.0).abs() < 1e-6);
    assert!(s.min[0] >= 0.0 && s.min[0] < 0.01, "{:?}", s.min);
    assert_eq!(s.max[0], 1.0);
}

/// With the default ramp of 3 voxels and a box 60 voxels wide the deficit is exact: the fog is
/// min(1, d/B) of the distance d to the nearest face, so its integral is the box's volume minus
/// the ramp, computable in closed form voxel by voxel; and every voxel matches it.
#[test]
fn box_fog_is_the_ramp_of_the_exact_distance() {
    let (lo, hi) = (Vec3::new(-0.6, -0.5, -0.4), Vec3::new(0.6, 0.7, 0.5));
    let v = 0.02;
    let band = 3.0;
    let vol = fog(&box_mesh(lo, hi, false), v, band, None);
    for ijk in domain_voxels(&vol) {
        let exact = box_sdf(ijk.as_dvec3() * v, lo.as_dvec3(), hi.as_dvec3());
        let value = f64::from(vol.grid.value_at(ijk));
        if exact > 1e-4 * v {
            assert_eq!(value, 0.0, "{ijk}");
            assert!(!vol.grid.is_active(ijk), "{ijk}");
        } else if exact < -1e-4 * v {
            let expected = (-exact / (band * v)).min(1.0);
            assert!(
                (value - expected).abs() < 1e-5,
                "{ijk}: {value} vs {expected}"
            );
            assert!(vol.grid.is_active(ijk), "{ijk}");
        }
    }
    let volume = f64::from((hi - lo).x * (hi - lo).y * (hi - lo).z);
    assert!((vol.report.mesh_volume / volume - 1.0).abs() < 1e-5);
    // The ramp's integral in closed form: the fog is ∫₀¹ [d > t B V] dt, so its integral is
    // (1/b) ∫₀^b Π (L_i − 2s) ds with b = B V (Simpson's rule is exact for this cubic).
    let l = (hi - lo).as_dvec3();
    let b = band * v;
    let inner = |s: f64| (l.x - 2.0 * s) * (l.y - 2.0 * s) * (l.z - 2.0 * s);
    let predicted = (inner(0.0) + 4.0 * inner(b / 2.0) + inner(b)) / 6.0;
    assert!(
        (vol.report.integral / predicted - 1.0).abs() < 0.002,
        "{} vs {predicted}",
        vol.report.integral
    );
    // 3 voxels of ramp over a box 45–60 voxels wide removes about 15 %: the 3 % figure needs a
    // thinner ramp or a larger object (docs/voxelize.md).
    let deficit = 1.0 - vol.report.integral / volume;
    assert!(deficit > 0.1, "{deficit}");
}

/// Noise multiplies the fog by max(0, 1 + A fbm(F p)) at the voxel's rest-space position.
#[test]
fn noise_multiplies_the_fog_in_rest_space() {
    let mesh = sphere_mesh(0.5, 4);
    let v = 0.02;
    let n = NoiseOptions {
        frequency: 3.0,
        amplitude: 0.7,
        octaves: 3,
        seed: 5,
    };
    let plain = fog(&mesh, v, 3.0, None);
    let noisy = fog(&mesh, v, 3.0, Some(n));
    let field = FbmField::new(
        FbmParams {
            frequency: 3.0,
            octaves: 3,
            lacunarity: 2.0,
            gain: 0.5,
            amplitude: 0.7,
            offset: 1.0,
            min: 0.0,
            max: 1.7,
            seed: 5,
        },
        glam::DAffine3::IDENTITY,
    )
    .unwrap();
    let mut varied = 0;
    for ijk in domain_voxels(&plain) {
        let a = plain.grid.value_at(ijk);
        let b = noisy.grid.value_at(ijk);
        assert_eq!(
            plain.grid.is_active(ijk),
            noisy.grid.is_active(ijk),
            "{ijk}"
        );
        let f = field.density_rest(ijk.as_dvec3() * v);
        assert!((b - a * f).abs() <= 1e-6, "{ijk}: {b} vs {a} × {f}");
        if (f - 1.0).abs() > 0.1 && a > 0.0 {
            varied += 1;
        }
    }
    assert!(varied > 1000, "the noise barely varies: {varied}");
}

/// An open box (one face missing) converts with a warning naming the mesh; its inside is
/// decided by the six-ray vote (5 of 6 half-rays still cross one face), so away from the hole
/// it is the closed box's level set.
#[test]
fn open_mesh_warns_and_keeps_its_inside() {
    let dir = TempDir::new("voxelize-open");
    let (lo, hi) = (Vec3::splat(-0.5), Vec3::splat(0.5));
    let open = dir.join("open_box.ply");
    write_ply(&open, &box_mesh(lo, hi, true), false).unwrap();
    let out = dir.join("open.vdb");
    let r = run_velour([
        "voxelize",
        open.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--voxel-size",
        "0.05",
        "--levelset",
    ]);
    r.assert_success();
    assert!(
        r.stderr.contains("warning:") && r.stderr.contains("open_box.ply"),
        "{}",
        r.stderr
    );
    assert!(r.stderr.contains("4 boundary edges"), "{}", r.stderr);
    let g = read_vdb(&out).unwrap();
    let closed = level_set(&box_mesh(lo, hi, false), 0.05, 3.0);
    let grid = &g[0].grid;
    // Voxels above the lower third: the missing face at z = −0.5 is farther than the band.
    for ijk in domain_voxels(&closed) {
        let c = closed.grid.value_at(ijk);
        if ijk.z >= -6 && c.abs() > 1e-6 {
            assert_eq!(grid.value_at(ijk), c, "{ijk}");
        }
    }
    assert_eq!(grid.value_at(IVec3::ZERO), -0.15f32);
}

/// Two boxes welded along one edge (four triangles on that edge: non-manifold) convert with a
/// warning, and parity gives their union: both insides negative, the gap between them outside.
#[test]
fn non_manifold_mesh_warns_and_gives_the_union() {
    let dir = TempDir::new("voxelize-nonmanifold");
    let a = box_mesh(Vec3::new(-1.0, -1.0, -0.5), Vec3::new(0.0, 0.0, 0.5), false);
    let b = box_mesh(Vec3::new(0.0, 0.0, -0.5), Vec3::new(1.0, 1.0, 0.5), false);
    let mut mesh = a.clone();
    let offset = a.positions.len() as u32;
    mesh.positions.extend(b.positions.iter().copied());
    mesh.indices
        .extend(b.indices.iter().map(|t| t.map(|i| i + offset)));
    let topo = mesh.topology();
    assert!(topo.non_manifold_edges > 0, "{topo}");
    let path = dir.join("two_boxes.ply");
    write_ply(&path, &mesh, false).unwrap();
    let out = dir.join("two_boxes.vdb");
    let r = run_velour([
        "voxelize",
        path.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--voxel-size",
        "0.1",
        "--levelset",
    ]);
    r.assert_success();
    assert!(
        r.stderr.contains("warning:")
            && r.stderr.contains("two_boxes.ply")
            && r.stderr
                .contains(&format!("{} non-manifold edges", topo.non_manifold_edges)),
        "{}",
        r.stderr
    );
    let g = &read_vdb(&out).unwrap()[0].grid;
    assert!(g.value_at(IVec3::new(-5, -5, 0)) < 0.0);
    assert!(g.value_at(IVec3::new(5, 5, 0)) < 0.0);
    assert!(g.value_at(IVec3::new(-5, 5, 0)) > 0.0);
    assert!(g.value_at(IVec3::new(5, -5, 0)) > 0.0);
}

/// A PLY with vertices and no faces, and every bad flag, give a clear error and write nothing.
#[test]
fn bad_input_is_refused_and_nothing_is_written() {
    let dir = TempDir::new("voxelize-bad");
    let empty = dir.join("no_faces.ply");
    std::fs::write(
        &empty,
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 0\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n",
    )
    .unwrap();
    let sphere = mesh_path("sphere.ply");
    let out = dir.join("out.vdb");
    let o = out.to_str().unwrap();
    let cases: Vec<(Vec<String>, Vec<&str>)> = vec![
        (
            vec![
                empty.display().to_string(),
                "--voxel-size".into(),
                "0.1".into(),
                "--levelset".into(),
            ],
            vec!["no_faces.ply", "no faces"],
        ),
        (
            vec![
                dir.join("missing.ply").display().to_string(),
                "--voxel-size".into(),
                "0.1".into(),
                "--fog".into(),
            ],
            vec!["missing.ply"],
        ),
        (
            vec![
                sphere.display().to_string(),
                "--voxel-size".into(),
                "0".into(),
                "--levelset".into(),
            ],
            vec!["--voxel-size", "world units"],
        ),
        (
            vec![
                sphere.display().to_string(),
                "--voxel-size".into(),
                "NaN".into(),
                "--fog".into(),
            ],
            vec!["--voxel-size"],
        ),
        (
            vec![
                sphere.display().to_string(),
                "--voxel-size".into(),
                "-0.1".into(),
                "--fog".into(),
            ],
            vec!["--voxel-size"],
        ),
        (
            vec![
                sphere.display().to_string(),
                "--voxel-size".into(),
                "0.1".into(),
                "--levelset".into(),
                "--half-width".into(),
                "0.5".into(),
            ],
            vec!["--half-width", "voxels"],
        ),
        (
            vec![
                sphere.display().to_string(),
                "--voxel-size".into(),
                "0.1".into(),
                "--fog".into(),
                "--band".into(),
                "0".into(),
            ],
            vec!["--band"],
        ),
        (
            vec![
                sphere.display().to_string(),
                "--voxel-size".into(),
                "0.1".into(),
                "--fog".into(),
                "--noise-octaves".into(),
                "0".into(),
            ],
            vec!["--noise-octaves"],
        ),
        (
            vec![
                sphere.display().to_string(),
                "--voxel-size".into(),
                "0.1".into(),
                "--fog".into(),
                "--noise-amplitude".into(),
                "1".into(),
                "--noise-frequency".into(),
                "-2".into(),
            ],
            vec!["--noise-frequency"],
        ),
        (
            vec![
                sphere.display().to_string(),
                "--voxel-size".into(),
                "0.1".into(),
                "--levelset".into(),
                "--noise-amplitude".into(),
                "1".into(),
            ],
            vec!["--noise-amplitude"],
        ),
        (
            vec![
                sphere.display().to_string(),
                "--voxel-size".into(),
                "0.1".into(),
            ],
            vec!["--levelset", "--fog"],
        ),
        (
            vec![
                sphere.display().to_string(),
                "--voxel-size".into(),
                "0.1".into(),
                "--levelset".into(),
                "--fog".into(),
            ],
            vec!["--fog"],
        ),
        (
            vec![
                sphere.display().to_string(),
                "--voxel-size".into(),
                "1e-6".into(),
                "--levelset".into(),
            ],
            vec!["sphere.ply", "voxels along x", "larger --voxel-size"],
        ),
    ];
    for (args, needles) in cases {
        let mut a = vec!["voxelize".to_string()];
        a.extend(args);
        a.extend(["-o".to_string(), o.to_string()]);
        run_velour(&a).assert_failure_mentioning(&needles);
        assert!(!out.exists(), "{a:?} wrote {}", out.display());
    }
}

/// Writes `mesh` as PLY for velour and as JSON (points, triangles, voxel size, half width) for
/// the OpenVDB script.
fn write_mesh_files(
    dir: &TempDir,
    name: &str,
    mesh: &TriangleMesh,
    v: f64,
    w: f64,
) -> (std::path::PathBuf, std::path::PathBuf) {
    let ply = dir.join(format!("{name}.ply"));
    write_ply(&ply, mesh, true).unwrap();
    let json = dir.join(format!("{name}.json"));
    let points: Vec<[f32; 3]> = mesh.positions.iter().map(|p| p.to_array()).collect();
    let text = serde_json::json!({
        "points": points,
        "triangles": mesh.indices,
        "voxel_size": v,
        "half_width": w,
        "band": w,
    });
    std::fs::write(&json, text.to_string()).unwrap();
    (ply, json)
}

/// OpenVDB reads our level set (class, background, transform) and its own
/// `createLevelSetFromPolygons` of the same mesh at the same voxel size agrees: active voxels
/// within 5 %, values within 0.1 voxel RMS on the common band, the same signs, the same
/// inactive interior. OpenVDB's band is slightly narrower than the exact one (its shell of
/// 0.87 voxel grown by face-neighbour dilation stops short of W near axis-aligned faces): every
/// voxel of its band is in ours, and ours adds only voxels more than W − 0.5 voxels away.
/// A box with axis-aligned faces shows that most (about 5 % more active voxels), so the 5 %
/// bound is asserted on the curved meshes; the box is checked for values, signs and inclusion.
#[test]
fn openvdb_agrees_with_our_level_sets() {
    if !external::require_python_openvdb() {
        return;
    }
    let dir = TempDir::new("voxelize-ovdb");
    let creature = load_ply(&mesh_path("creature_skin.ply")).unwrap();
    let cases = [
        ("sphere", sphere_mesh(0.5, 4), 0.02, 3.0, true),
        (
            "box",
            box_mesh(
                Vec3::new(-0.31, -0.2, -0.15),
                Vec3::new(0.29, 0.17, 0.26),
                false,
            ),
            0.02,
            3.0,
            false,
        ),
        ("creature", creature.clone(), 0.015, 3.0, true),
        ("creature_w2", creature, 0.02, 2.0, true),
    ];
    for (name, mesh, v, w, count_bound) in cases {
        let (ply, json) = write_mesh_files(&dir, name, &mesh, v, w);
        let out = dir.join(format!("{name}.vdb"));
        run_velour([
            "voxelize",
            ply.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
            "--voxel-size",
            &v.to_string(),
            "--levelset",
            "--half-width",
            &w.to_string(),
        ])
        .assert_success();
        let script = repo_path("tools/vdb/ovdb_mesh_levelset.py");
        // The fog of the same mesh, ramp W voxels wide, against OpenVDB's sdfToFogVolume rules.
        let fog_out = dir.join(format!("{name}_fog.vdb"));
        run_velour([
            "voxelize",
            ply.to_str().unwrap(),
            "-o",
            fog_out.to_str().unwrap(),
            "--voxel-size",
            &v.to_string(),
            "--fog",
            "--band",
            &w.to_string(),
        ])
        .assert_success();
        let text = external::run_python([
            script.as_os_str(),
            json.as_os_str(),
            out.as_os_str(),
            fog_out.as_os_str(),
        ]);
        let r: Value = serde_json::from_str(text.trim()).unwrap();
        let num = |k: &str| {
            r[k].as_f64()
                .unwrap_or_else(|| panic!("{name}: {k} in {r}"))
        };
        eprintln!("{name}: {r}");
        assert_eq!(r["class"], "level set", "{name}");
        assert!((num("background") - w * v).abs() < 1e-7, "{name}: {r}");
        assert!(
            (num("ref_background") - num("background")).abs() < 1e-7,
            "{name}"
        );
        assert_eq!(r["voxel_size"][0].as_f64().unwrap(), v, "{name}");
        assert_eq!(
            r["index_to_world_1"][2].as_f64().unwrap(),
            3.0 * v,
            "{name}"
        );
        let ours = num("ours_active");
        let theirs = num("ref_active");
        if count_bound {
            assert!(
                (ours / theirs - 1.0).abs() < 0.05,
                "{name}: {ours} vs {theirs} active"
            );
        }
        assert!(num("common") > 0.99 * theirs, "{name}: {r}");
        assert!(num("ours_only_min_voxels") > w - 0.5, "{name}: {r}");
        assert!(num("rms_voxels") < 0.1, "{name}: {r}");
        assert_eq!(num("sign_mismatch"), 0.0, "{name}: {r}");
        // −background on both sides (f32 products of W and V may round differently).
        assert!(
            (num("ours_centre") - num("ref_centre")).abs() < 1e-6 * w * v,
            "{name}: {r}"
        );
        assert!(
            (num("ours_centre") + w * v).abs() < 1e-6 * w * v,
            "{name}: {r}"
        );
        // Fog: OpenVDB reads it as a fog volume; the same inside voxels (off the surface) within
        // 0.5 %, the same integral within 0.5 % and the same ramp within 0.02 RMS (a 0.1-voxel
        // distance error moves the ramp by 0.1 / W at most).
        assert_eq!(r["fog_class"], "fog volume", "{name}");
        assert_eq!(num("fog_background"), 0.0, "{name}");
        let (oi, ri) = (num("fog_ours_inside"), num("fog_ref_inside"));
        assert!(
            (oi / ri - 1.0).abs() < 0.005,
            "{name}: {oi} vs {ri} inside voxels"
        );
        let (os, rs) = (num("fog_ours_sum"), num("fog_ref_sum"));
        assert!(
            (os / rs - 1.0).abs() < 0.005,
            "{name}: fog integral {os} vs {rs}"
        );
        assert!(num("fog_ramp_rms") < 0.02, "{name}: {r}");
    }
}
