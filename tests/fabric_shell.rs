//! Fabric shells (course notes §3.3): a voxelised weave patch tiled over a mesh. The shell map
//! sends world points to the tiled patch exactly on a flat mesh, is periodic over the tiles,
//! conserves the fibre volume (flat and curved meshes), maps fibre tangents with the mesh, and
//! a flat one-tile shell renders like the same patch placed free-standing.

mod common;

use std::collections::BTreeMap;
use std::path::Path;

use common::files::TempDir;
use common::render::{render_finite, scene_from_text};
use common::stats::{difference_z_score, estimate, Estimate};
use glam::{IVec3, Vec2, Vec3};
use velour::fabric::voxelise::{DENSITY, ID, TANGENT};
use velour::fabric::{
    generate_patch, voxelise, FabricShell, ShellParams, VoxeliseOptions, VoxelisedPatch,
    WeaveParams, WeavePattern, YarnParams,
};
use velour::geometry::TriangleMesh;
use velour::image_io::compare::compare;
use velour::sampling::Rng;
use velour::scene::load_scene_str;

fn patch(pattern: WeavePattern, resolution: u32) -> VoxelisedPatch {
    let yarn = YarnParams::preset("cotton1").unwrap();
    let mut p = WeaveParams::new(pattern, yarn);
    p.repeats = [1, 1];
    let fp = generate_patch(&p, 3).unwrap();
    voxelise(&fp, resolution, &VoxeliseOptions::default()).unwrap()
}

/// A grid mesh over `[0, size.x] × [0, size.y]` in the plane spanned by `ex`, `ey` through
/// `origin`, with UV = position / size.
fn plane(origin: Vec3, ex: Vec3, ey: Vec3, size: Vec2, n: u32) -> TriangleMesh {
    let mut positions = Vec::new();
    let mut uvs = Vec::new();
    for j in 0..=n {
        for i in 0..=n {
            let u = i as f32 / n as f32;
            let v = j as f32 / n as f32;
            positions.push(origin + ex * (u * size.x) + ey * (v * size.y));
            uvs.push(Vec2::new(u, v));
        }
    }
    TriangleMesh {
        positions,
        normals: None,
        uvs: Some(uvs),
        indices: grid_triangles(n, n),
    }
}

/// Two triangles per cell of a `(nu + 1) × (nv + 1)` vertex grid (row-major, u fastest).
fn grid_triangles(nu: u32, nv: u32) -> Vec<[u32; 3]> {
    let mut indices = Vec::new();
    for j in 0..nv {
        for i in 0..nu {
            let a = j * (nu + 1) + i;
            indices.push([a, a + 1, a + nu + 2]);
            indices.push([a, a + nu + 2, a + nu + 1]);
        }
    }
    indices
}

/// A half cylinder of radius `r` and length `length` along z, `nu × nv` cells (u around, v
/// along the axis), with texture coordinates in [0, 1]².
fn half_cylinder(r: f32, length: f32, nu: u32, nv: u32) -> TriangleMesh {
    let mut positions = Vec::new();
    let mut uvs = Vec::new();
    for j in 0..=nv {
        for i in 0..=nu {
            let a = std::f32::consts::PI * i as f32 / nu as f32;
            positions.push(Vec3::new(
                r * a.cos(),
                r * a.sin(),
                length * j as f32 / nv as f32,
            ));
            uvs.push(Vec2::new(i as f32 / nu as f32, j as f32 / nv as f32));
        }
    }
    TriangleMesh {
        positions,
        normals: None,
        uvs: Some(uvs),
        indices: grid_triangles(nu, nv),
    }
}

/// The patch's occupied z layers.
fn z_layers(vp: &VoxelisedPatch) -> (i32, i32) {
    let (lo, hi) = vp.grid.active_bbox().unwrap();
    (lo.z, hi.z)
}

/// Periodic trilinear lookup of the patch density (the test's own, from the module docs).
fn periodic_density(vp: &VoxelisedPatch, q: Vec3) -> f32 {
    let mut acc = vp.grid.accessor(DENSITY);
    let f = q.floor();
    let t = q - f;
    let i = f.as_ivec3();
    let n = IVec3::new(vp.dims[0] as i32, vp.dims[1] as i32, 1);
    let mut sum = 0.0;
    for k in 0..8 {
        let d = IVec3::new(k >> 2, (k >> 1) & 1, k & 1);
        let c = i + d;
        let w = (if d.x == 1 { t.x } else { 1.0 - t.x })
            * (if d.y == 1 { t.y } else { 1.0 - t.y })
            * (if d.z == 1 { t.z } else { 1.0 - t.z });
        sum += w * acc.value(IVec3::new(c.x.rem_euclid(n.x), c.y.rem_euclid(n.y), c.z));
    }
    sum
}

#[test]
fn flat_shell_maps_world_points_onto_the_tiled_patch() {
    let vp = patch(WeavePattern::from_name("twill").unwrap(), 32);
    let size = Vec2::new(3.0, 2.0);
    let tiles = [4.0f32, 3.0];
    let mesh = plane(Vec3::ZERO, Vec3::X, Vec3::Y, size, 5);
    let shell = FabricShell::new(&vp, &mesh, &ShellParams { tiles }).unwrap();
    let (lo, hi) = z_layers(&vp);
    let layers = (hi - lo + 2) as f32;
    let t = shell.thickness();
    // Voxel size from the tiling: the mean world length per UV is sqrt(6) here.
    let per_uv = (size.x * size.y).sqrt();
    let vx = per_uv / (tiles[0] * vp.dims[0] as f32);
    let vy = per_uv / (tiles[1] * vp.dims[1] as f32);
    let h = vp.voxel_size.as_vec3();
    let expected_t = h.z * ((vx / h.x) * (vy / h.y)).sqrt() * layers;
    assert!(
        (t - expected_t).abs() < 1e-5 * expected_t,
        "thickness {t} vs {expected_t}"
    );
    let mut rng = Rng::new(11, 0);
    let mut hint = u32::MAX;
    let mut nonzero = 0;
    for _ in 0..20_000 {
        let p = Vec3::new(
            rng.next_f32() * size.x,
            rng.next_f32() * size.y,
            (rng.next_f32() - 0.5) * t * 0.999,
        );
        let u = p.x / size.x;
        let v = p.y / size.y;
        let expected = Vec3::new(
            u * tiles[0] * vp.dims[0] as f32 - 0.5,
            v * tiles[1] * vp.dims[1] as f32 - 0.5,
            (lo - 1) as f32 + (p.z / t + 0.5) * layers,
        );
        let q = shell
            .patch_coordinates(p, &mut hint)
            .expect("inside the shell");
        let nx = vp.dims[0] as f32;
        let ny = vp.dims[1] as f32;
        let dq = q - expected;
        // x, y agree modulo the tile.
        let wrap = |d: f32, n: f32| d - (d / n).round() * n;
        assert!(
            wrap(dq.x, nx).abs() < 2e-3 && wrap(dq.y, ny).abs() < 2e-3 && dq.z.abs() < 2e-3,
            "p {p}: q {q} vs expected {expected}"
        );
        let d = shell.density(p, &mut hint);
        let e = periodic_density(&vp, expected);
        assert!(
            (d - e).abs() < 2e-3 * (1.0 + e),
            "density {d} vs {e} at {p}"
        );
        nonzero += usize::from(d > 0.0);
        // Periodic: one tile further along u and v is the same fibre.
        let shifted = p + Vec3::new(size.x / tiles[0], size.y / tiles[1], 0.0);
        if shifted.x < size.x && shifted.y < size.y {
            let ds = shell.density(shifted, &mut hint);
            assert!(
                (d - ds).abs() < 5e-3 * (1.0 + d),
                "not periodic: {d} vs {ds}"
            );
        }
    }
    assert!(nonzero > 2_000, "only {nonzero} samples hit fibres");
    // Outside the shell there is nothing.
    for p in [
        Vec3::new(1.0, 1.0, t * 0.6),
        Vec3::new(1.0, 1.0, -t * 0.6),
        Vec3::new(-0.01, 1.0, 0.0),
        Vec3::new(3.01, 1.0, 0.0),
    ] {
        assert_eq!(shell.density(p, &mut hint), 0.0, "at {p}");
    }
    // The boundary is closed and the shell's volume is area × thickness.
    assert!(shell.boundary_mesh().is_closed());
    let vol = shell.volume();
    let expect = f64::from(size.x * size.y * t);
    assert!(
        (vol / expect - 1.0).abs() < 1e-4,
        "volume {vol} vs {expect}"
    );
}

/// Monte-Carlo estimate of ∫ density dV over a box, with its standard error.
fn integrate(shell: &FabricShell, lo: Vec3, hi: Vec3, n: usize, seed: u64) -> Estimate {
    let mut hint = u32::MAX;
    let vol = f64::from((hi - lo).x * (hi - lo).y * (hi - lo).z);
    estimate(n, &mut Rng::new(seed, 1), |rng| {
        let p = lo + (hi - lo) * Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32());
        f64::from(shell.density(p, &mut hint)) * vol
    })
}

/// Σ density × voxel volume of the patch in world units for a shell of `shell`'s scale.
fn patch_volume_world(vp: &VoxelisedPatch, shell: &FabricShell) -> f64 {
    let g = &vp.grid;
    let mut sum = 0.0f64;
    for b in 0..g.brick_count() {
        let d = g.brick_data(DENSITY, b);
        for v in 0..velour::grid::BRICK_VOXELS {
            sum += f64::from(d.get(v, 1, 0));
        }
    }
    // World voxel: scale × patch voxel on every axis.
    let h = vp.voxel_size;
    let scale = f64::from(shell.voxel_world_size()) / h.z;
    sum * h.x * h.y * h.z * scale.powi(3)
}

#[test]
fn shell_conserves_the_fibre_volume_on_flat_and_curved_meshes() {
    let vp = patch(WeavePattern::Plain, 32);
    // Flat: 3 × 2 tiles over a 3 × 2 plane (one world unit per tile).
    let mesh = plane(Vec3::ZERO, Vec3::X, Vec3::Y, Vec2::new(3.0, 2.0), 4);
    let shell = FabricShell::new(&vp, &mesh, &ShellParams { tiles: [3.0, 2.0] }).unwrap();
    let t = shell.thickness();
    let expected = patch_volume_world(&vp, &shell) * 6.0;
    let e = integrate(
        &shell,
        Vec3::new(0.0, 0.0, -t / 2.0),
        Vec3::new(3.0, 2.0, t / 2.0),
        400_000,
        5,
    );
    let (est, se, z) = (e.mean, e.standard_error, e.z_score(expected));
    assert!(
        z.abs() < 4.0 && (est / expected - 1.0).abs() < 0.01,
        "flat: {est} ± {se} vs {expected}"
    );

    // Curved: a half cylinder of radius 20 thicknesses, u around, v along the axis.
    let r = 20.0 * t;
    let mesh = half_cylinder(r, 2.0, 96, 4);
    let area = mesh.area();
    let shell = FabricShell::new(&vp, &mesh, &ShellParams { tiles: [5.0, 3.0] }).unwrap();
    let b = shell.boundary_mesh().bounds();
    let e = integrate(&shell, b.min, b.max, 1_200_000, 9);
    // The tiles cover the mesh once: world area per tile × tiles = area.
    let expected = patch_volume_world(&vp, &shell) * 15.0;
    let (est, se, z) = (e.mean, e.standard_error, e.z_score(expected));
    assert!(
        z.abs() < 4.0 && (est / expected - 1.0).abs() < 0.02,
        "curved: {est} ± {se} vs {expected} (area {area})"
    );
    let vol = shell.volume();
    let expect = f64::from(area * shell.thickness());
    assert!(
        (vol / expect - 1.0).abs() < 2e-3,
        "shell volume {vol} vs {expect}"
    );
}

#[test]
fn shell_tangents_follow_the_mesh_and_the_yarn_directions() {
    // A plane in x–z (normal −y for this winding): patch x → world x, patch y → world z.
    let vp = patch(WeavePattern::Plain, 48);
    let mesh = plane(Vec3::ZERO, Vec3::X, Vec3::Z, Vec2::new(2.0, 2.0), 4);
    let shell = FabricShell::new(&vp, &mesh, &ShellParams { tiles: [2.0, 2.0] }).unwrap();
    let t = shell.thickness();
    let mut rng = Rng::new(3, 2);
    let mut hint = u32::MAX;
    let (mut warp, mut warp_ok, mut weft, mut weft_ok) = (0, 0, 0, 0);
    let mut exact = 0;
    for _ in 0..40_000 {
        let p = Vec3::new(
            rng.next_f32() * 2.0,
            (rng.next_f32() - 0.5) * t,
            rng.next_f32() * 2.0,
        );
        if shell.density(p, &mut hint) < 0.2 {
            continue;
        }
        let f = shell.fibre_at(p).expect("inside");
        assert!((f.tangent.length() - 1.0).abs() < 1e-4);
        // The nearest voxel's own tangent, mapped by the known affine map (x: 2 tiles over
        // 2 units, z: 2 tiles over 2 units, y: the thickness over the patch's layers).
        let q = shell.patch_coordinates(p, &mut hint).unwrap();
        let n = IVec3::new(vp.dims[0] as i32, vp.dims[1] as i32, 1);
        let ijk = (q + Vec3::splat(0.5)).floor().as_ivec3();
        let ijk = IVec3::new(ijk.x.rem_euclid(n.x), ijk.y.rem_euclid(n.y), ijk.z);
        let tp = vp.grid.accessor(TANGENT).value_vec3(ijk);
        let id = vp.grid.accessor(ID).value(ijk);
        assert_eq!(f.id, id);
        let h = vp.voxel_size.as_vec3();
        let (lo, hi) = z_layers(&vp);
        let idx = tp / h; // patch index direction
        let world = Vec3::new(
            idx.x * 2.0 / (2.0 * n.x as f32),
            // Height runs along the mesh normal, here −y.
            -idx.z * t / (hi - lo + 2) as f32,
            idx.y * 2.0 / (2.0 * n.y as f32),
        )
        .normalize();
        if f.tangent.dot(world).abs() > 0.9999 {
            exact += 1;
        }
        if id == 0.0 {
            warp += 1;
            warp_ok += usize::from(f.tangent.z.abs() > f.tangent.x.abs());
        } else if id == 1.0 {
            weft += 1;
            weft_ok += usize::from(f.tangent.x.abs() > f.tangent.z.abs());
        }
    }
    assert!(warp > 500 && weft > 500, "warp {warp}, weft {weft} samples");
    let total = warp + weft;
    assert!(
        exact * 100 >= total * 99,
        "{exact} of {total} tangents map exactly"
    );
    // Warps run along v (world z), wefts along u (world x): in the plane of the cloth each
    // is closer to its own direction than to the other's (the crimp tilts them out of the
    // plane, the fibre twist a little sideways). Isotropic tiles: a rotation and a scale.
    assert!(
        warp_ok * 10 > warp * 9,
        "warp aligned {warp_ok}/{warp}, weft {weft_ok}/{weft}"
    );
    assert!(weft_ok * 10 > weft * 9, "weft aligned {weft_ok}/{weft}");
}

#[test]
fn shell_errors_name_the_problem() {
    let vp = patch(WeavePattern::Plain, 16);
    let mut mesh = plane(Vec3::ZERO, Vec3::X, Vec3::Y, Vec2::ONE, 2);
    let err = FabricShell::new(&vp, &mesh, &ShellParams { tiles: [0.0, 1.0] })
        .unwrap_err()
        .to_string();
    assert!(err.contains("tiles[0]"), "{err}");
    let err = FabricShell::new(
        &vp,
        &mesh,
        &ShellParams {
            tiles: [1.0, f32::NAN],
        },
    )
    .unwrap_err()
    .to_string();
    assert!(err.contains("tiles[1]"), "{err}");
    let flat_uv = vec![Vec2::ZERO; mesh.positions.len()];
    mesh.uvs = Some(flat_uv);
    let err = FabricShell::new(&vp, &mesh, &ShellParams { tiles: [1.0, 1.0] })
        .unwrap_err()
        .to_string();
    assert!(err.contains("uv"), "{err}");
    mesh.uvs = None;
    let err = FabricShell::new(&vp, &mesh, &ShellParams { tiles: [1.0, 1.0] })
        .unwrap_err()
        .to_string();
    assert!(err.contains("texture coordinates"), "{err}");
}

/// A scene with the twill patch either free-standing (`shape = "bounds"`) or as a one-tile
/// shell over `mesh` (a PLY path).
fn twill_scene(shape: &str, centre: f32) -> String {
    format!(
        r#"
[camera]
eye = [{centre}, {centre}, 1.6]
look_at = [{centre}, {centre}, 0.0]
up = [0.0, 1.0, 0.0]
fov = 7
[film]
width = 16
height = 16
spp = 96
max_depth = 64
[[light]]
type = "environment"
radiance = [0.4, 0.4, 0.45]
[[light]]
type = "distant"
direction = [-0.3, -0.4, 0.9]
irradiance = [3.0, 2.9, 2.7]
angular_radius = 4.0
[[object]]
name = "twill"
{shape}
interior = {{ type = "fabric", pattern = "twill", yarn = "cotton1", resolution = 32, flyaways = 0, warp_albedo = [0.8, 0.2, 0.1], weft_albedo = [0.85, 0.85, 0.8], attenuation = 0.004, nee = "interior" }}
"#
    )
}

/// The error message of a scene that must fail to load.
fn scene_error(text: &str, name: &str) -> String {
    load_scene_str(text, Path::new(name))
        .expect_err("the scene should be rejected")
        .to_string()
}

fn write_plane_ply(path: &Path, z: f32, size: Vec2) {
    let mut s = String::from("ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\nproperty float u\nproperty float v\nelement face 2\nproperty list uchar int vertex_indices\nend_header\n");
    for (u, v) in [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)] {
        s += &format!("{} {} {z} {u} {v}\n", u * size.x, v * size.y);
    }
    s += "3 0 1 2\n3 0 2 3\n";
    std::fs::write(path, s).unwrap();
}

#[test]
fn a_flat_one_tile_shell_renders_like_the_free_standing_patch() {
    // The patch the scene builds (same generator parameters and seed as scene::build).
    let yarn = YarnParams::preset("cotton1").unwrap();
    let mut p = WeaveParams::new(WeavePattern::from_name("twill").unwrap(), yarn);
    p.repeats = [1, 1];
    p.flyaway_fraction = 0.0;
    let fp = generate_patch(&p, 1).unwrap();
    let vp = voxelise(
        &fp,
        32,
        &VoxeliseOptions {
            keep_accumulators: false,
            ..VoxeliseOptions::default()
        },
    )
    .unwrap();
    // The shell's mid-plane is the middle of its layers [lo − 1, hi + 1] (index space).
    let (lo, hi) = z_layers(&vp);
    let mid = vp
        .grid
        .index_to_world_point(Vec3::new(0.0, 0.0, (lo + hi) as f32 * 0.5));
    let origin = vp.grid.index_to_world_point(Vec3::new(-0.5, -0.5, 0.0));
    assert!(
        origin.x.abs() < 1e-6 && origin.y.abs() < 1e-6,
        "patch origin {origin}"
    );
    let dir = TempDir::new("fabric-shell");
    let ply = dir.join("tile.ply");
    write_plane_ply(&ply, mid.z, Vec2::new(fp.tile.x, fp.tile.y));

    // The camera sees the middle of the tile (the free-standing patch does not wrap at the
    // tile's edges, the shell does).
    let c = fp.tile.x * 0.5;
    assert!(
        (fp.tile.x - fp.tile.y).abs() < 1e-6 && fp.tile.x > 0.3,
        "tile {}",
        fp.tile
    );
    let free = twill_scene(r#"shape = "bounds""#, c);
    let shell = twill_scene(
        &format!("shape = \"mesh\"\nfile = \"{}\"", ply.display()),
        c,
    );
    let run = |text: &str, seed: u64| {
        let mut scene = scene_from_text(text, "test.toml");
        scene.film.seed = seed;
        let (film, summary) = render_finite(&scene, 0);
        assert!(summary.tracking.real_collisions > 0);
        (film.to_exr_image(&BTreeMap::new()), film)
    };
    let (a, fa) = run(&free, 1);
    let (b, fb) = run(&shell, 2);
    let z = compare(&a, &b).expect("compare").z_test.expect("variance");
    assert!(z.consistent, "free-standing vs shell: {z:?}");
    // Not a vacuous agreement: the cloth is visible and red (warp) in places.
    let mut red = 0;
    for y in 0..16 {
        for x in 0..16 {
            let (ma, mb) = (fa.mean(x, y), fb.mean(x, y));
            red += usize::from(ma[0] > 1.5 * ma[1] && mb[0] > 1.5 * mb[1]);
        }
    }
    assert!(red > 10, "only {red} red pixels in both");
}

#[test]
fn scene_errors_for_fabric_shells() {
    let dir = TempDir::new("fabric-shell-errors");
    // A mesh without texture coordinates.
    let ply = dir.join("nouv.ply");
    std::fs::write(
        &ply,
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n",
    )
    .unwrap();
    let text = twill_scene(
        &format!("shape = \"mesh\"\nfile = \"{}\"", ply.display()),
        0.5,
    );
    let err = scene_error(&text, "s.toml");
    assert!(
        err.contains("texture coordinates") && err.contains("s.toml:"),
        "{err}"
    );
    // `tiles` on a free-standing patch, and absurd tiles on a shell.
    let text =
        twill_scene("shape = \"bounds\"", 0.5).replace("flyaways = 0", "flyaways = 0, tiles = 4");
    let err = scene_error(&text, "s.toml");
    assert!(err.contains("tiles"), "{err}");
    let good = dir.join("uv.ply");
    write_plane_ply(&good, 0.0, Vec2::ONE);
    let text = twill_scene(
        &format!("shape = \"mesh\"\nfile = \"{}\"", good.display()),
        0.5,
    )
    .replace("flyaways = 0", "flyaways = 0, tiles = -3");
    let err = scene_error(&text, "s.toml");
    assert!(err.contains("tiles"), "{err}");
    // A sphere cannot carry a fabric shell.
    let text = twill_scene("shape = \"sphere\"", 0.5);
    let err = scene_error(&text, "s.toml");
    assert!(err.contains("fabric"), "{err}");
}

#[test]
fn mip_levels_conserve_the_tiled_fibre_volume() {
    let yarn = YarnParams::preset("cotton1").unwrap();
    let mut p = WeaveParams::new(WeavePattern::Plain, yarn);
    p.repeats = [1, 1];
    let fp = generate_patch(&p, 3).unwrap();
    let vp0 = voxelise(&fp, 32, &VoxeliseOptions::default()).unwrap();
    let vp1 = vp0.mip(1).unwrap();
    let mesh = plane(Vec3::ZERO, Vec3::X, Vec3::Y, Vec2::new(2.0, 2.0), 2);
    let tiles = ShellParams { tiles: [2.0, 2.0] };
    let s0 = FabricShell::new(&vp0, &mesh, &tiles).unwrap();
    let s1 = FabricShell::new(&vp1, &mesh, &tiles).unwrap();
    assert!((s1.voxel_world_size() / s0.voxel_world_size() - 2.0).abs() < 1e-4);
    let box_of = |s: &FabricShell| {
        let t = s.thickness();
        (Vec3::new(0.0, 0.0, -t / 2.0), Vec3::new(2.0, 2.0, t / 2.0))
    };
    let (a0, b0) = box_of(&s0);
    let (a1, b1) = box_of(&s1);
    let level0 = integrate(&s0, a0, b0, 400_000, 21);
    let level1 = integrate(&s1, a1, b1, 400_000, 22);
    let z = difference_z_score(&level0, &level1);
    let (v0, e0, v1, e1) = (
        level0.mean,
        level0.standard_error,
        level1.mean,
        level1.standard_error,
    );
    assert!(z.abs() < 4.0, "level 0 {v0} ± {e0} vs level 1 {v1} ± {e1}");
    let expected = patch_volume_world(&vp0, &s0) * 4.0;
    assert!(
        (v1 / expected - 1.0).abs() < 0.02,
        "level 1 {v1} vs {expected}"
    );
}

#[test]
fn scenes_choose_fabric_mip_levels_from_the_pixel_footprint() {
    let dir = TempDir::new("fabric-shell-mip");
    let ply = dir.join("cloth.ply");
    // A 4 × 4 cloth with 8 × 8 tiles: level-0 voxels are 4/(8·32) = 0.0156 wide.
    write_plane_ply(&ply, 0.0, Vec2::new(4.0, 4.0));
    let scene = |eye_z: f32, mip: &str| {
        format!(
            r#"
[camera]
eye = [2.0, 2.0, {eye_z}]
look_at = [2.0, 2.0, 0.0]
up = [0.0, 1.0, 0.0]
fov = 40
[film]
width = 64
height = 64
[[light]]
type = "environment"
radiance = 1.0
[[object]]
name = "cloth"
shape = "mesh"
file = "{}"
interior = {{ type = "fabric", pattern = "plain", resolution = 32, tiles = 8, mip = {mip}, attenuation = 0.01 }}
"#,
            ply.display()
        )
    };
    let level = |text: &str| {
        let s = scene_from_text(text, "m.toml");
        let note = s
            .notes
            .iter()
            .find(|n| n.contains("mip level"))
            .expect("note")
            .clone();
        note.rsplit(' ').next().unwrap().parse::<u32>().unwrap()
    };
    // `"auto"` picks the level per ray: the level of the camera ray through the centre.
    let auto_level = |eye_z: f32| {
        let s = scene_from_text(&scene(eye_z, "\"auto\""), "m.toml");
        let velour::medium::Medium::Heterogeneous(h) = &s.media[0] else {
            panic!("a heterogeneous medium");
        };
        let chain = h.mips.as_ref().expect("levels chosen per ray");
        let ray = velour::math::Ray::new(Vec3::new(2.0, 2.0, eye_z), Vec3::new(0.0, 0.0, -1.0));
        let cone = velour::medium::RayFootprint {
            width: 0.0,
            spread: s.camera.pixel_spread_angle(),
        };
        chain.level_for_ray(&ray, cone)
    };
    // Pixel spread atan(2 tan 20° / 64) = 0.0114 rad: at distance 1 the footprint is 0.7
    // voxels (level 0), at 12 it is 8.8 voxels (level 3), at 1000 it is capped by the 32
    // voxels across (5).
    assert_eq!(auto_level(1.0), 0);
    assert_eq!(auto_level(12.0), 3);
    assert_eq!(auto_level(1000.0), 5);
    assert_eq!(level(&scene(1.0, "2")), 2);
    for (bad, what) in [
        ("7", "mip = 7"),
        ("\"fine\"", "\"fine\""),
        ("-1", "mip = -1"),
        ("[1, 2]", "`mip` expects"),
    ] {
        let err = scene_error(&scene(1.0, bad), "m.toml");
        assert!(err.contains(what), "{bad}: {err}");
    }
    // Level 3 cannot halve 36 voxels three times.
    let text = scene(1.0, "3").replace("resolution = 32", "resolution = 36");
    let err = scene_error(&text, "m.toml");
    assert!(err.contains("multiple of 8"), "{err}");
}

#[test]
fn tilings_too_fine_for_f32_are_refused() {
    let vp = patch(WeavePattern::Plain, 32);
    let mesh = plane(Vec3::ZERO, Vec3::X, Vec3::Y, Vec2::ONE, 1);
    let err = FabricShell::new(
        &vp,
        &mesh,
        &ShellParams {
            tiles: [100_000.0, 100_000.0],
        },
    )
    .unwrap_err()
    .to_string();
    assert!(err.contains("tiles") && err.contains("subdivide"), "{err}");
    // The same tiling over a finer mesh is fine as far as precision goes.
    assert!(FabricShell::new(
        &vp,
        &mesh,
        &ShellParams {
            tiles: [1000.0, 1000.0]
        }
    )
    .is_ok());
}

/// Point bounds of a shell (the per-voxel maxima that let free flights reject tentative
/// collisions without a lookup): at random points of a curved twill shell, plain and
/// fibre-projected lookups never exceed the bound, and the bound is much tighter than the
/// patch's maximum where it matters.
#[test]
fn shell_point_bounds_bound_every_lookup_and_are_tight() {
    let vp = patch(WeavePattern::from_name("twill").unwrap(), 32);
    let mesh = half_cylinder(1.0, 1.0, 48, 6);
    let shell = FabricShell::new(&vp, &mesh, &ShellParams { tiles: [6.0, 2.0] }).unwrap();
    let b = shell.boundary_mesh().bounds();
    let mut tangents = shell.tangent_accessor();
    let mut rng = Rng::new(17, 0);
    let (mut inside, mut sum_bound, mut sum_density) = (0u32, 0.0f64, 0.0f64);
    let global = shell.density_bounds().max;
    for _ in 0..200_000 {
        let p = b.min + (b.max - b.min) * Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32());
        let dir = Vec3::new(
            rng.next_f32() - 0.5,
            rng.next_f32() - 0.5,
            rng.next_f32() - 0.5,
        )
        .normalize_or_zero();
        let bound = shell.point_bound(p, &mut u32::MAX.clone());
        let d = shell.density(p, &mut u32::MAX.clone());
        let projected = shell.projected_density(&mut tangents, p, dir, &mut u32::MAX.clone());
        assert!(
            d <= bound && projected <= bound,
            "at {p}: density {d}, projected {projected} above the point bound {bound}"
        );
        assert!(
            bound <= global,
            "bound {bound} above the patch maximum {global}"
        );
        if shell.patch_coordinates(p, &mut u32::MAX.clone()).is_some() {
            inside += 1;
            sum_bound += f64::from(bound);
            sum_density += f64::from(d);
        }
    }
    assert!(inside > 10_000, "{inside} points inside the shell");
    let mean_bound = sum_bound / f64::from(inside);
    let mean_density = sum_density / f64::from(inside);
    // The layer maxima bound a point by up to `global`; the voxel maxima sit far closer to
    // the density (measured: 0.30 of the patch maximum on average, 1.8× the mean density).
    assert!(
        mean_bound < 0.5 * f64::from(global) && mean_bound < 3.0 * mean_density,
        "mean point bound {mean_bound}, mean density {mean_density}, patch maximum {global}"
    );
}

/// The shell's tetrahedra know their face neighbours, which point location walks across
/// from the last tetrahedron a ray found: on a curved shell every link is mutual and joins
/// two faces with the same three corners, the only unlinked faces are the shell's boundary
/// (bottom and top of every triangle, two per side quad on the mesh's rim), and lookups that
/// carry their last tetrahedron along a ray find the same patch point as a fresh search.
#[test]
fn shell_tetrahedra_are_linked_across_their_faces() {
    let vp = patch(WeavePattern::from_name("twill").unwrap(), 32);
    let (nu, nv) = (48u32, 6u32);
    let mesh = half_cylinder(1.0, 1.0, nu, nv);
    let shell = FabricShell::new(&vp, &mesh, &ShellParams { tiles: [6.0, 2.0] }).unwrap();
    assert_eq!(shell.tet_count(), 3 * mesh.indices.len());
    let face = |c: [Vec3; 4], opp: usize| -> Vec<Vec3> {
        (0..4).filter(|&k| k != opp).map(|k| c[k]).collect()
    };
    let mut unlinked = 0usize;
    for i in 0..shell.tet_count() {
        let ci = shell.tet_corners(i).unwrap();
        for (k, n) in shell.face_neighbours(i).unwrap().into_iter().enumerate() {
            let Some(j) = n else {
                unlinked += 1;
                continue;
            };
            assert_ne!(i, j, "tetrahedron {i} is its own neighbour");
            let back = shell.face_neighbours(j).unwrap();
            let kj = back
                .iter()
                .position(|&b| b == Some(i))
                .unwrap_or_else(|| panic!("{i} → {j} across face {k}, but not {j} → {i}"));
            let (fi, fj) = (face(ci, k), face(shell.tet_corners(j).unwrap(), kj));
            for a in &fi {
                assert!(
                    fj.iter().any(|b| a.distance(*b) < 1e-4),
                    "faces of {i} and {j} differ: {fi:?} against {fj:?}"
                );
            }
        }
    }
    let rim_edges = 2 * (nu + nv) as usize;
    assert_eq!(unlinked, 2 * mesh.indices.len() + 2 * rim_edges);
    assert!(shell.face_neighbours(shell.tet_count()).is_none());

    // Rays in small steps through the shell, with and without the last tetrahedron.
    let b = shell.boundary_mesh().bounds();
    let mut rng = Rng::new(5, 0);
    let mut found = 0u32;
    for _ in 0..2_000 {
        let o = b.min + (b.max - b.min) * Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32());
        let d = Vec3::new(
            rng.next_f32() - 0.5,
            rng.next_f32() - 0.5,
            rng.next_f32() - 0.5,
        )
        .normalize_or_zero();
        let mut hint = u32::MAX;
        for s in 0..100 {
            let p = o + d * (0.004 * s as f32);
            let walked = shell.patch_coordinates(p, &mut hint);
            let fresh = shell.patch_coordinates(p, &mut u32::MAX.clone());
            match (walked, fresh) {
                (Some(a), Some(f)) => {
                    found += 1;
                    let (a, f) = (a.to_array(), f.to_array());
                    // x and y may differ by whole tiles (32 voxels) across a UV seam.
                    let dz = (a[2] - f[2]).abs();
                    let dx = (a[0] - f[0])
                        .rem_euclid(32.0)
                        .min((f[0] - a[0]).rem_euclid(32.0));
                    let dy = (a[1] - f[1])
                        .rem_euclid(32.0)
                        .min((f[1] - a[1]).rem_euclid(32.0));
                    assert!(
                        dx < 1e-2 && dy < 1e-2 && dz < 1e-2,
                        "at {p}: {a:?} against {f:?}"
                    );
                }
                (None, None) => {}
                (w, f) => panic!("at {p}: walked {w:?}, fresh search {f:?}"),
            }
        }
    }
    assert!(found > 10_000, "{found} points inside the shell");
}
