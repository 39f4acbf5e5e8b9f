//! Fuzzing the PLY reader with byte-level mutations of small seed files (ASCII, binary little
//! and big endian; `tests/data/fuzz/ply/`): it must return a mesh that satisfies the mesh
//! invariants or an error naming the file, never panic, and never allocate more than the
//! input's size backs (no single allocation above 64 KiB + 64 × the input's size, no more
//! than 1 MiB + 256 × the size in all). Inputs that failed once live in
//! `tests/data/fuzz/ply/regressions/` and are replayed on every run. See docs/fuzzing.md for
//! longer runs.

#[path = "fuzz_support/mod.rs"]
mod fuzz_support;

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use fuzz_support::{
    catch_panic, files_with_extension, fuzz, measure_allocations, mutate, mutations, AllocStats,
    Budget, CountingAlloc, FuzzTarget,
};
use velour::geometry::{parse_ply, GeometryError, TriangleMesh};

#[global_allocator]
static ALLOC: CountingAlloc = CountingAlloc;

/// The name inputs are parsed under; every error message must contain it.
const NAME: &str = "fuzz-input.ply";

fn data_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/fuzz/ply")
}

/// The seed files plus the small shipped ASCII mesh.
fn seeds() -> Vec<Vec<u8>> {
    let mut files = files_with_extension(&data_dir(), "ply");
    files.push(Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/meshes/ocean_box.ply"));
    files
        .iter()
        .map(|p| std::fs::read(p).unwrap_or_else(|e| panic!("{}: {e}", p.display())))
        .collect()
}

/// Largest single allocation allowed for an input of `len` bytes.
fn single_bound(len: usize) -> usize {
    64 * 1024 + 64 * len
}

/// Largest total of allocations allowed for an input of `len` bytes.
fn total_bound(len: usize) -> usize {
    (1 << 20) + 256 * len
}

/// Parses `bytes` under [`NAME`], catching a panic and measuring allocations.
fn parse(
    bytes: &[u8],
) -> (
    Result<Result<TriangleMesh, GeometryError>, String>,
    AllocStats,
) {
    measure_allocations(|| catch_panic(|| parse_ply(bytes, Path::new(NAME))))
}

/// The invariants every mesh the reader returns must satisfy.
fn check_mesh(mesh: &TriangleMesh) -> Result<(), String> {
    let n = mesh.positions.len();
    if mesh.indices.is_empty() {
        return Err("Ok mesh without triangles".to_string());
    }
    if let Some(t) = mesh
        .indices
        .iter()
        .find(|t| t.iter().any(|&i| i as usize >= n))
    {
        return Err(format!("Ok mesh with triangle {t:?} beyond {n} vertices"));
    }
    if let Some(t) = mesh
        .indices
        .iter()
        .find(|t| t[0] == t[1] || t[1] == t[2] || t[0] == t[2])
    {
        return Err(format!("Ok mesh with degenerate triangle {t:?}"));
    }
    if !mesh.positions.iter().all(|p| p.is_finite()) {
        return Err("Ok mesh with a non-finite position".to_string());
    }
    if let Some(ns) = &mesh.normals {
        if ns.len() != n || !ns.iter().all(|v| v.is_finite()) {
            return Err("Ok mesh with bad normals".to_string());
        }
    }
    if let Some(uv) = &mesh.uvs {
        if uv.len() != n || !uv.iter().all(|v| v.is_finite()) {
            return Err("Ok mesh with bad uvs".to_string());
        }
    }
    Ok(())
}

/// `Ok` when the reader behaved on `bytes`.
fn check(bytes: &[u8]) -> Result<(), String> {
    let (outcome, stats) = parse(bytes);
    let result = outcome.map_err(|m| format!("parse_ply panicked: {m}"))?;
    if stats.largest > single_bound(bytes.len()) {
        return Err(format!(
            "an allocation of {} bytes for a {}-byte input (bound {})",
            stats.largest,
            bytes.len(),
            single_bound(bytes.len())
        ));
    }
    if stats.total > total_bound(bytes.len()) {
        return Err(format!(
            "{} bytes allocated in all for a {}-byte input (bound {})",
            stats.total,
            bytes.len(),
            total_bound(bytes.len())
        ));
    }
    match result {
        Ok(mesh) => check_mesh(&mesh),
        Err(e) => {
            let message = e.to_string();
            if message.contains(NAME) {
                Ok(())
            } else {
                Err(format!("error does not name the file: {message}"))
            }
        }
    }
}

#[test]
fn seeds_are_valid_meshes_of_every_encoding() {
    let seeds = seeds();
    assert!(seeds.len() >= 6, "{} seeds", seeds.len());
    for format in ["ascii", "binary_little_endian", "binary_big_endian"] {
        let tag = format!("format {format} ");
        assert!(
            seeds
                .iter()
                .any(|s| s.windows(tag.len()).any(|w| w == tag.as_bytes())),
            "no {format} seed"
        );
    }
    for (i, s) in seeds.iter().enumerate() {
        let (outcome, _) = parse(s);
        let mesh = outcome
            .expect("no panic")
            .unwrap_or_else(|e| panic!("seed {i}: {e}"));
        check_mesh(&mesh).unwrap();
    }
}

#[test]
fn mutated_seeds_never_panic_or_overallocate() {
    let seeds = seeds();
    let input = |case: &(usize, Vec<fuzz_support::Mutation>)| mutate(&seeds, case.0, &case.1);
    fuzz(
        Budget::from_env(100_000, 20.0, 0x504c_5946_555a),
        FuzzTarget {
            name: "fuzz_ply",
            strategy: mutations(seeds.len(), 6),
            input: &input,
            check: &check,
            regressions: &data_dir().join("regressions"),
            ext: "ply",
            save_current: false,
        },
    );
}

#[test]
fn regressions_replay() {
    let files = files_with_extension(&data_dir().join("regressions"), "ply");
    println!("{} regression inputs", files.len());
    for f in files {
        let bytes = std::fs::read(&f).unwrap();
        if let Err(e) = check(&bytes) {
            panic!("{}: {e}", f.display());
        }
    }
}

/// A binary header declaring `count` vertices and one face over `body`.
fn binary_header(count: &str, face_list: &str) -> Vec<u8> {
    format!(
        "ply\nformat binary_little_endian 1.0\nelement vertex {count}\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty {face_list} vertex_indices\nend_header\n"
    )
    .into_bytes()
}

fn expect_refused(bytes: &[u8], wanted: &[&str]) -> GeometryError {
    let start = Instant::now();
    let (outcome, stats) = parse(bytes);
    let elapsed = start.elapsed();
    let e = outcome
        .expect("no panic")
        .expect_err("the input must be refused");
    let message = e.to_string();
    for w in wanted.iter().chain(&[NAME]) {
        assert!(message.contains(w), "`{w}` missing from: {message}");
    }
    assert!(
        stats.largest < 4096 && stats.total < 64 * 1024,
        "{stats:?} allocated refusing: {message}"
    );
    assert!(elapsed < Duration::from_secs(1), "{elapsed:?}: {message}");
    e
}

#[test]
fn header_claiming_1e11_vertices_is_refused_before_allocating() {
    // Binary: 12 bytes per vertex, 36 bytes of data.
    let mut b = binary_header("100000000000", "list uchar uint");
    b.extend([0u8; 36]);
    let e = expect_refused(&b, &["100000000000 `vertex`", "line 3", "36 bytes"]);
    assert!(matches!(e, GeometryError::Parse { .. }));
    // ASCII: at least 2 bytes per value.
    let a = "ply\nformat ascii 1.0\nelement vertex 100000000000\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
    expect_refused(a.as_bytes(), &["100000000000 `vertex`", "line 3"]);
    // Largest count a header can state, and one past it.
    let mut b = binary_header("18446744073709551615", "list uchar uint");
    b.extend([0u8; 36]);
    expect_refused(&b, &["18446744073709551615 `vertex`"]);
    let b = binary_header("18446744073709551616", "list uchar uint");
    expect_refused(&b, &["line 3", "18446744073709551616"]);
    // A second element that only the cumulative count of bytes refuses.
    let mut b = binary_header("3", "list uchar uint");
    let b_text = String::from_utf8(b.clone())
        .unwrap()
        .replace("face 1", "face 20");
    b = b_text.into_bytes();
    b.extend([0u8; 36 + 13]);
    expect_refused(
        &b,
        &[
            "line 7: 20 `face` elements need at least 56 bytes",
            "49 bytes",
        ],
    );
}

#[test]
fn absurd_list_lengths_are_refused_and_empty_elements_cost_nothing() {
    let vertices: Vec<u8> = [[0.0f32, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]
        .iter()
        .flatten()
        .flat_map(|c| c.to_le_bytes())
        .collect();
    // A uint list length of 2^32 − 1 with 12 bytes of items.
    let mut b = binary_header("3", "list uint uint");
    b.extend(&vertices);
    b.extend(u32::MAX.to_le_bytes());
    b.extend([0u8; 12]);
    expect_refused(
        &b,
        &["4294967295 uints", "only 12", "`face` 0", "vertex_indices"],
    );
    // A negative int list length.
    let mut b = binary_header("3", "list int uint");
    b.extend(&vertices);
    b.extend((-3i32).to_le_bytes());
    b.extend([0u8; 12]);
    expect_refused(&b, &["negative list length -3"]);
    // ASCII: a list longer than its line.
    let a = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uint int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n4294967295 0 1 2\n";
    expect_refused(a.as_bytes(), &["line 13", "the line ends"]);
    // A binary element without properties occupies no bytes: any count is read at once.
    let header = "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement nothing 18446744073709551615\nelement face 1\nproperty list uchar uint vertex_indices\nend_header\n";
    let mut b = header.as_bytes().to_vec();
    b.extend(&vertices);
    b.push(3);
    for i in 0u32..3 {
        b.extend(i.to_le_bytes());
    }
    let start = Instant::now();
    let (outcome, stats) = parse(&b);
    let mesh = outcome.unwrap().unwrap();
    assert_eq!(mesh.indices, vec![[0, 1, 2]]);
    assert!(start.elapsed() < Duration::from_secs(1));
    assert!(stats.largest < 1024, "{stats:?}");
    // In ASCII each instance is a line, so the same count is refused.
    let a = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement nothing 18446744073709551615\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
    expect_refused(a.as_bytes(), &["`nothing`", "line 7"]);
}

#[test]
fn errors_are_clear_and_name_the_line_or_byte() {
    let good = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
    assert!(parse(good.as_bytes()).0.unwrap().is_ok());
    let cases = [
        (
            good.replace("1 0 0\n", "1 x 0\n"),
            "line 11: element `vertex` 1 of 3, property `y`: `x` is not a valid float",
        ),
        (
            good.replace("1 0 0\n", "1 0\n"),
            "line 11: element `vertex` 1 of 3, property `z`: the line ends",
        ),
        (
            good.replace("1 0 0\n", "1 0 0 5\n"),
            "line 11: element `vertex` 1 of 3: unexpected value `5`",
        ),
        (
            good.replace("3 0 1 2\n", "3 0 1 2.5\n"),
            "line 13: element `face` 0 of 1, property `vertex_indices`: `2.5` is not a valid int",
        ),
        (
            good.replace("3 0 1 2\n", "300 0 1 2\n"),
            "`300` is not a valid uchar",
        ),
        (
            good.replace("property float y", "property flaot y"),
            "line 5: unknown property type `flaot`",
        ),
        (
            good.replace("end_header\n", "end_header\n0 0 0\n"),
            "line 13: element `face` 0 of 1: unexpected value `1`",
        ),
        // Wrong property types, non-finite values, bad indices and faces.
        (
            good.replace("property float x", "property list uchar float x"),
            "element `vertex` has no usable property `x`",
        ),
        (
            good.replace(
                "list uchar int vertex_indices",
                "list uchar float vertex_indices",
            ),
            "element `face` has no usable property `vertex_indices (or vertex_index) integer list`",
        ),
        (
            good.replace("0 1 0\n", "0 -inf 0\n"),
            "vertex 2 has a non-finite position",
        ),
        (
            good.replace("3 0 1 2\n", "3 0 1 3\n"),
            "face 0 refers to vertex 3 but there are only 3 vertices",
        ),
        (
            good.replace("3 0 1 2\n", "2 0 1\n"),
            "face 0 has 2 vertices (at least 3 needed)",
        ),
    ];
    for (text, want) in &cases {
        let e = parse(text.as_bytes()).0.unwrap().unwrap_err().to_string();
        assert!(
            e.contains(want) && e.contains(NAME),
            "want `{want}`, got: {e}"
        );
    }
    // Binary: a truncated face list names the byte offset.
    let mut b = binary_header("3", "list uchar uint");
    let body = b.len();
    b.extend([0u8; 36]);
    b.push(3);
    b.extend([0u8; 9]);
    let e = parse(&b).0.unwrap().unwrap_err().to_string();
    let want = format!("byte {}: element `face` 0 of 1, property `vertex_indices`: a list of 3 uints needs 12 bytes but only 9 are left", body + 37);
    assert!(e.contains(&want), "{e}");
}
