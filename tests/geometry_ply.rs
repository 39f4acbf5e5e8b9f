//! PLY reading/writing and mesh topology: round trips, accepted variants, every kind of bad
//! input returning an error (never a panic), closedness, orientation and transforms.

mod common;

use std::path::Path;

use common::files::{mesh_path, TempDir};
use velour::geometry::{load_ply, write_ply, GeometryError, Shape, TriangleMesh};
use velour::math::{Mat4, Vec2, Vec3};

/// A closed, outward-wound octahedron with normals and uvs.
fn octahedron() -> TriangleMesh {
    let positions = vec![Vec3::X, -Vec3::X, Vec3::Y, -Vec3::Y, Vec3::Z, -Vec3::Z];
    let indices = vec![
        [0, 2, 4],
        [2, 1, 4],
        [1, 3, 4],
        [3, 0, 4],
        [2, 0, 5],
        [1, 2, 5],
        [3, 1, 5],
        [0, 3, 5],
    ];
    TriangleMesh {
        normals: Some(positions.clone()),
        uvs: Some(
            positions
                .iter()
                .map(|p| Vec2::new(p.x * 0.5 + 0.5, p.y * 0.25 + 0.125))
                .collect(),
        ),
        positions,
        indices,
    }
}

fn write(path: &Path, bytes: &[u8]) {
    std::fs::write(path, bytes).unwrap();
}

#[test]
fn round_trip_ascii_and_binary() {
    let dir = TempDir::new("ply-round-trip");
    let mut m = octahedron();
    // Values that need all 9 significant digits.
    m.positions[0] = Vec3::new(0.1, 1.0 / 3.0, -1.0e-7);
    m.uvs.as_mut().unwrap()[1] = Vec2::new(0.123_456_79, 7.0e5);
    for binary in [false, true] {
        let p = dir.join(if binary { "rt_bin.ply" } else { "rt_ascii.ply" });
        write_ply(&p, &m, binary).unwrap();
        let back = load_ply(&p).unwrap();
        assert_eq!(back, m, "binary = {binary}");
    }
    // Without normals and uvs.
    let bare = TriangleMesh {
        normals: None,
        uvs: None,
        ..octahedron()
    };
    let p = dir.join("rt_bare.ply");
    write_ply(&p, &bare, true).unwrap();
    assert_eq!(load_ply(&p).unwrap(), bare);
}

#[test]
fn reads_big_endian_doubles_polygons_and_alternative_names() {
    let dir = TempDir::new("ply-variants");
    // Binary big endian, double positions, `s t` texture coordinates, int list named
    // `vertex_index`, one quad and one pentagon (fan triangulated: 2 + 3 triangles).
    let mut b = b"ply\nformat binary_big_endian 1.0\nelement vertex 5\nproperty double x\nproperty double y\nproperty double z\nproperty float s\nproperty float t\nelement face 2\nproperty list uchar int vertex_index\nend_header\n".to_vec();
    let pts: [[f64; 3]; 5] = [
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [1.0, 1.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.5, 1.5, 0.0],
    ];
    for (i, p) in pts.iter().enumerate() {
        for c in p {
            b.extend(c.to_be_bytes());
        }
        b.extend((i as f32).to_be_bytes());
        b.extend((0.5f32).to_be_bytes());
    }
    b.push(4);
    for i in [0i32, 1, 2, 3] {
        b.extend(i.to_be_bytes());
    }
    b.push(5);
    for i in [0i32, 1, 2, 4, 3] {
        b.extend(i.to_be_bytes());
    }
    let p = dir.join("be.ply");
    write(&p, &b);
    let m = load_ply(&p).unwrap();
    assert_eq!(m.positions.len(), 5);
    assert_eq!(m.positions[4], Vec3::new(0.5, 1.5, 0.0));
    assert_eq!(
        m.indices,
        vec![[0, 1, 2], [0, 2, 3], [0, 1, 2], [0, 2, 4], [0, 4, 3]]
    );
    assert_eq!(m.uvs.as_ref().unwrap()[3], Vec2::new(3.0, 0.5));
    assert!(m.normals.is_none());

    // ASCII with texture_u/texture_v, normals, comments and an extra element.
    let a = "ply\nformat ascii 1.0\ncomment hello\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nproperty float nx\nproperty float ny\nproperty float nz\nproperty float texture_u\nproperty float texture_v\nelement face 1\nproperty list uchar uint vertex_indices\nelement material 1\nproperty uchar red\nend_header\n0 0 0 0 0 1 0 0\n1 0 0 0 0 1 1 0\n0 1 0 0 0 1 0 1\n3 0 1 2\n255\n";
    let p = dir.join("alt.ply");
    write(&p, a.as_bytes());
    let m = load_ply(&p).unwrap();
    assert_eq!(m.indices, vec![[0, 1, 2]]);
    assert_eq!(m.normals.as_ref().unwrap()[2], Vec3::Z);
    assert_eq!(m.uvs.as_ref().unwrap()[2], Vec2::new(0.0, 1.0));
}

const GOOD_ASCII: &str = "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\nelement face 2\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n3 0 1 2\n3 0 2 3\n";

/// Writes `s` to `dir/name` and loads it.
fn load_str(dir: &TempDir, name: &str, s: &str) -> Result<TriangleMesh, GeometryError> {
    let p = dir.join(name);
    write(&p, s.as_bytes());
    load_ply(&p)
}

#[test]
fn bad_input_is_an_error_naming_the_file() {
    let dir = TempDir::new("ply-bad-input");
    assert!(load_str(&dir, "good.ply", GOOD_ASCII).is_ok());
    let missing = dir.join("does_not_exist.ply");
    let e = load_ply(&missing).unwrap_err();
    assert!(matches!(e, GeometryError::Io { .. }));
    assert!(e.to_string().contains("does_not_exist.ply"), "{e}");

    let cases: Vec<(&str, String)> = vec![
        ("not_ply", "hello world\n".to_string()),
        ("empty", String::new()),
        (
            "more_vertices_declared",
            GOOD_ASCII.replace("element vertex 4", "element vertex 5"),
        ),
        (
            "fewer_vertices_declared",
            GOOD_ASCII.replace("element vertex 4", "element vertex 3"),
        ),
        (
            "more_faces_declared",
            GOOD_ASCII.replace("element face 2", "element face 3"),
        ),
        (
            "fewer_faces_declared",
            GOOD_ASCII.replace("element face 2", "element face 1"),
        ),
        ("nan_vertex", GOOD_ASCII.replace("1 1 0\n", "1 nan 0\n")),
        ("inf_vertex", GOOD_ASCII.replace("1 1 0\n", "1 inf 0\n")),
        (
            "index_out_of_range",
            GOOD_ASCII.replace("3 0 2 3", "3 0 2 4"),
        ),
        ("negative_index", GOOD_ASCII.replace("3 0 2 3", "3 0 -1 3")),
        ("short_list", GOOD_ASCII.replace("3 0 2 3", "3 0 2")),
        ("two_vertex_face", GOOD_ASCII.replace("3 0 2 3", "2 0 2")),
        (
            "missing_z",
            GOOD_ASCII
                .replace("property float z\n", "")
                .replace(" 0\n", "\n"),
        ),
        (
            "no_faces_element",
            GOOD_ASCII
                .replace(
                    "element face 2\nproperty list uchar int vertex_indices\n",
                    "",
                )
                .replace("3 0 1 2\n3 0 2 3\n", ""),
        ),
        (
            "zero_faces",
            GOOD_ASCII
                .replace("element face 2", "element face 0")
                .replace("3 0 1 2\n3 0 2 3\n", ""),
        ),
        (
            "list_x",
            GOOD_ASCII.replace("property float x", "property list uchar float x"),
        ),
        ("bad_number", GOOD_ASCII.replace("1 0 0\n", "1 zero 0\n")),
        (
            "huge_count",
            GOOD_ASCII.replace("element vertex 4", "element vertex 4000000000"),
        ),
        (
            "bad_format",
            GOOD_ASCII.replace("format ascii 1.0", "format pdf 1.0"),
        ),
        ("no_end_header", GOOD_ASCII.replace("end_header\n", "")),
    ];
    for (name, text) in &cases {
        let file = format!("{name}.ply");
        let r = load_str(&dir, &file, text);
        let e = r.expect_err(name);
        let msg = e.to_string();
        assert!(
            msg.contains(&file),
            "{name}: message does not name the file: {msg}"
        );
    }
    // "nan"/"inf" are either rejected by the parser or reported as non-finite.
    for i in [6, 7] {
        let r = load_str(&dir, "a.ply", &cases[i].1);
        assert!(
            matches!(
                r,
                Err(GeometryError::NonFinite { vertex: 2, .. }) | Err(GeometryError::Parse { .. })
            ),
            "{r:?}"
        );
    }
    assert!(matches!(
        load_str(&dir, "b.ply", &cases[8].1),
        Err(GeometryError::IndexOutOfRange {
            face: 1,
            index: 4,
            vertex_count: 4,
            ..
        })
    ));
    assert!(matches!(
        load_str(&dir, "c.ply", &cases[9].1),
        Err(GeometryError::IndexOutOfRange { index: -1, .. })
    ));
    assert!(matches!(
        load_str(&dir, "d.ply", &cases[11].1),
        Err(GeometryError::BadFace {
            face: 1,
            count: 2,
            ..
        })
    ));
    assert!(matches!(
        load_str(&dir, "e.ply", &cases[12].1),
        Err(GeometryError::MissingProperty { .. })
    ));
    assert!(matches!(
        load_str(&dir, "f.ply", &cases[13].1),
        Err(GeometryError::MissingElement { .. })
    ));
    assert!(matches!(
        load_str(&dir, "g.ply", &cases[14].1),
        Err(GeometryError::Empty { .. })
    ));
    assert!(matches!(
        load_str(&dir, "h.ply", &cases[5].1),
        Err(GeometryError::TrailingData { .. })
    ));
}

#[test]
fn truncated_files_are_errors_at_every_offset() {
    let dir = TempDir::new("ply-truncated");
    // Binary: every strict prefix must fail.
    let m = octahedron();
    let p = dir.join("full.ply");
    write_ply(&p, &m, true).unwrap();
    let full = std::fs::read(&p).unwrap();
    let q = dir.join("truncated.ply");
    for len in 0..full.len() {
        write(&q, &full[..len]);
        assert!(
            load_ply(&q).is_err(),
            "binary prefix of {len} of {} bytes loaded",
            full.len()
        );
    }
    // Binary NaN position.
    let mut bad = full.clone();
    let body = bad.len() - 8 * 13 - 6 * 32; // start of vertex data
    bad[body + 4..body + 8].copy_from_slice(&f32::NAN.to_le_bytes());
    write(&q, &bad);
    assert!(matches!(
        load_ply(&q),
        Err(GeometryError::NonFinite {
            vertex: 0,
            what: "position",
            ..
        })
    ));
    // Binary out-of-range index in the last face.
    let mut bad = full.clone();
    let n = bad.len();
    bad[n - 4..].copy_from_slice(&77u32.to_le_bytes());
    write(&q, &bad);
    assert!(matches!(
        load_ply(&q),
        Err(GeometryError::IndexOutOfRange {
            index: 77,
            face: 7,
            ..
        })
    ));
    // Extra bytes after the declared data.
    let mut extra = full.clone();
    extra.extend([0u8; 5]);
    write(&q, &extra);
    assert!(matches!(
        load_ply(&q),
        Err(GeometryError::TrailingData { bytes: 5, .. })
    ));

    // ASCII: no prefix may panic; prefixes that cut before the last line must fail.
    let pa = dir.join("full_ascii.ply");
    write_ply(&pa, &m, false).unwrap();
    let text = std::fs::read(&pa).unwrap();
    let last_line = text[..text.len() - 1]
        .iter()
        .rposition(|&c| c == b'\n')
        .unwrap()
        + 1;
    for len in 0..text.len() {
        write(&q, &text[..len]);
        let r = load_ply(&q);
        if len < last_line {
            assert!(r.is_err(), "ascii prefix of {len} bytes loaded");
        }
    }
}

#[test]
fn committed_meshes_are_valid() {
    let skin = load_ply(&mesh_path("creature_skin.ply")).unwrap();
    let bones = load_ply(&mesh_path("creature_skeleton.ply")).unwrap();
    let back = load_ply(&mesh_path("backdrop.ply")).unwrap();
    for m in [&skin, &bones, &back] {
        assert!(m.normals.is_some() && m.uvs.is_some());
    }
    assert!(skin.is_closed() && bones.is_closed());
    assert!(!back.is_closed());
    assert!(skin.signed_volume() > 0.0 && bones.signed_volume() > 0.0);
    assert!(bones.signed_volume() < skin.signed_volume() * 0.6);
    assert!(
        (10_000..=30_000).contains(&skin.indices.len()),
        "{}",
        skin.indices.len()
    );
    let b = skin.bounds();
    assert!((b.extent().y - 1.0).abs() < 1e-3, "{:?}", b);
    assert!(b.center().length() < 0.05);
    // Bones inside the skin's box; backdrop below the skin.
    let bb = bones.bounds();
    assert!(bb.min.cmpgt(b.min).all() && bb.max.cmplt(b.max).all());
    assert!(back.bounds().min.y < b.min.y);
    for name in [
        "creature_skin.ply",
        "creature_skeleton.ply",
        "backdrop.ply",
        "sphere.ply",
    ] {
        let size = std::fs::metadata(mesh_path(name)).unwrap().len();
        assert!(size < 1_500_000, "{name} is {size} bytes");
    }
}

#[test]
fn topology_closed_open_inconsistent_and_welded() {
    let m = octahedron();
    assert!(m.is_closed());
    let t = m.topology();
    assert_eq!(
        (
            t.edges,
            t.boundary_edges,
            t.inconsistent_edges,
            t.non_manifold_edges
        ),
        (12, 0, 0, 0)
    );

    let mut open = m.clone();
    open.indices.pop();
    assert!(!open.is_closed());
    assert_eq!(open.topology().boundary_edges, 3);
    let msg = open.topology().to_string();
    assert!(
        msg.starts_with("open") && msg.contains("3 boundary edges"),
        "{msg}"
    );

    let mut flipped = m.clone();
    flipped.indices[0].swap(1, 2);
    assert!(!flipped.is_closed());
    assert_eq!(flipped.topology().inconsistent_edges, 3);

    let mut fin = m.clone();
    fin.indices.push([0, 2, 4]);
    assert!(!fin.is_closed());

    // Split a vertex (as at a UV seam) with the same position: still watertight.
    let mut split = m.clone();
    split.positions.push(split.positions[4]);
    split.normals.as_mut().unwrap().push(Vec3::Z);
    split.uvs.as_mut().unwrap().push(Vec2::ZERO);
    split.indices[0][2] = 6;
    split.indices[1][2] = 6;
    assert!(split.is_closed());
}

#[test]
fn volume_orientation_and_transforms() {
    let m = octahedron();
    assert!((m.signed_volume() - 4.0 / 3.0).abs() < 1e-6);
    let mut inv = m.clone();
    for t in &mut inv.indices {
        t.swap(0, 1);
    }
    assert!((inv.signed_volume() + 4.0 / 3.0).abs() < 1e-6);
    inv.make_outward();
    assert!((inv.signed_volume() - 4.0 / 3.0).abs() < 1e-6);

    // Non-uniform scale: volume scales by det, normals by the inverse transpose.
    let s = Mat4::from_scale(Vec3::new(2.0, 3.0, 0.5));
    let mut t = m.clone();
    t.transform(s);
    assert!((t.signed_volume() - 4.0 / 3.0 * 3.0).abs() < 1e-5);
    let n = Vec3::new(1.0, 1.0, 1.0).normalize();
    let mut m2 = m.clone();
    m2.normals.as_mut().unwrap()[0] = n;
    m2.transform(s);
    let want = Vec3::new(n.x / 2.0, n.y / 3.0, n.z / 0.5).normalize();
    assert!((m2.normals.as_ref().unwrap()[0] - want).length() < 1e-6);
    assert!(m2.is_closed());

    // Mirror: winding flips so the volume stays positive.
    let mut r = m.clone();
    r.transform(
        Mat4::from_scale(Vec3::new(-1.0, 1.0, 1.0))
            * Mat4::from_translation(Vec3::new(5.0, 0.0, 0.0)),
    );
    assert!(r.signed_volume() > 1.3);
    assert!((r.bounds().center() - Vec3::new(-5.0, 0.0, 0.0)).length() < 1e-6);

    // Shapes: spheres accept similarities, reject non-uniform scale.
    let mut sph = Shape::Sphere {
        center: Vec3::X,
        radius: 1.0,
    };
    sph.transform(Mat4::from_scale_rotation_translation(
        Vec3::splat(2.0),
        glam::Quat::from_rotation_z(0.7),
        Vec3::Y,
    ))
    .unwrap();
    match sph {
        Shape::Sphere { center, radius } => {
            assert!((radius - 2.0).abs() < 1e-5);
            let want = Vec3::Y + glam::Quat::from_rotation_z(0.7) * Vec3::new(2.0, 0.0, 0.0);
            assert!((center - want).length() < 1e-5);
        }
        _ => unreachable!(),
    }
    assert!(sph
        .transform(Mat4::from_scale(Vec3::new(1.0, 2.0, 1.0)))
        .is_err());
    // Axis-aligned boxes take scales (also negative) and translations, not rotations.
    let mut aabox = Shape::Box {
        min: Vec3::new(-1.0, 0.0, 1.0),
        max: Vec3::new(1.0, 2.0, 3.0),
    };
    aabox
        .transform(Mat4::from_scale_rotation_translation(
            Vec3::new(2.0, -1.0, 1.0),
            glam::Quat::IDENTITY,
            Vec3::X,
        ))
        .unwrap();
    match aabox {
        Shape::Box { min, max } => {
            assert_eq!(min, Vec3::new(-1.0, -2.0, 1.0));
            assert_eq!(max, Vec3::new(3.0, 0.0, 3.0));
        }
        _ => unreachable!(),
    }
    assert!(aabox.transform(Mat4::from_rotation_z(0.3)).is_err());
    assert!(sph.transform(Mat4::from_scale(Vec3::ZERO)).is_err());
    let mut mesh = Shape::Mesh(m);
    assert!(mesh
        .transform(Mat4::from_cols_array(&[f32::NAN; 16]))
        .is_err());
}

/// The edge counts on a large mesh (a 60 × 40 grid of quads with split seam vertices, flipped
/// and repeated triangles, ±0 coordinates and degenerate triangles) equal a reference count
/// over ordered maps: the topology's hashed maps neither lose nor merge keys.
#[test]
fn topology_of_a_large_welded_grid_equals_an_ordered_count() {
    use std::collections::BTreeMap;
    let (nx, ny) = (60u32, 40u32);
    let mut m = TriangleMesh::default();
    // Each row's vertices twice (a seam split along every row), the copies at equal positions.
    for copy in 0..2 {
        for y in 0..=ny {
            for x in 0..=nx {
                let px = if x == 0 && copy == 1 {
                    -0.0
                } else {
                    x as f32 * 0.37
                };
                m.positions
                    .push(Vec3::new(px, (y as f32 * 0.21).sin(), y as f32 * 0.5));
            }
        }
    }
    let v = |copy: u32, x: u32, y: u32| copy * (nx + 1) * (ny + 1) + y * (nx + 1) + x;
    let mut state = 99u64;
    let mut next = move || {
        state = state
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1);
        state >> 33
    };
    for y in 0..ny {
        for x in 0..nx {
            let c = (next() % 2) as u32;
            let (a, b, d, e) = (
                v(c, x, y),
                v(1 - c, x + 1, y),
                v(c, x + 1, y + 1),
                v(c, x, y + 1),
            );
            match next() % 16 {
                0 => m.indices.push([a, d, b]),
                1 => {
                    m.indices.push([a, b, d]);
                    m.indices.push([a, b, d]);
                }
                2 => m.indices.push([a, a, d]),
                _ => m.indices.push([a, b, d]),
            }
            if next() % 9 != 0 {
                m.indices.push([a, d, e]);
            }
        }
    }
    // The reference: weld by exact position (±0 together), count directed edges per
    // undirected edge in ordered maps.
    let key = |p: Vec3| p.to_array().map(|c| if c == 0.0 { 0 } else { c.to_bits() });
    let mut weld = BTreeMap::new();
    let canon: Vec<u32> = (0..m.positions.len())
        .map(|i| *weld.entry(key(m.positions[i])).or_insert(i as u32))
        .collect();
    let mut edges: BTreeMap<(u32, u32), (u32, u32)> = BTreeMap::new();
    let mut degenerate = 0;
    for t in &m.indices {
        let w = t.map(|i| canon[i as usize]);
        if w[0] == w[1] || w[1] == w[2] || w[0] == w[2] {
            degenerate += 1;
            continue;
        }
        for k in 0..3 {
            let (a, b) = (w[k], w[(k + 1) % 3]);
            let e = edges.entry((a.min(b), a.max(b))).or_insert((0, 0));
            if a < b {
                e.0 += 1;
            } else {
                e.1 += 1;
            }
        }
    }
    let boundary = edges.values().filter(|&&(f, b)| f + b == 1).count();
    let inconsistent = edges
        .values()
        .filter(|&&(f, b)| f + b == 2 && f != 1)
        .count();
    let non_manifold = edges.values().filter(|&&(f, b)| f + b > 2).count();
    let t = m.topology();
    assert!(edges.len() > 5000 && boundary > 100 && inconsistent > 10 && non_manifold > 10);
    assert_eq!(
        (
            t.edges,
            t.boundary_edges,
            t.inconsistent_edges,
            t.non_manifold_edges,
            t.degenerate_triangles
        ),
        (
            edges.len(),
            boundary,
            inconsistent,
            non_manifold,
            degenerate
        )
    );
}
