//! PLY meshes: a reader of our own (ASCII, binary little and big endian) that checks the header
//! against the file's size before allocating anything, and a writer through `ply-rs-bw`.
//!
//! The reader never trusts a number read from the file: the element counts of the header must
//! fit in the bytes after it (at least one byte per binary scalar or list length, two bytes
//! per ASCII value) before any memory is reserved, and every list length is checked against
//! the data left before its items are read. Memory use is therefore bounded by a small
//! multiple of the file's size (the mesh takes at most 12 bytes per byte of file, the buffers
//! that grow while it is read at most twice that), and so is the time.

mod body;
mod header;

use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};

use ply_rs_bw::ply::{
    Addable, DefaultElement, ElementDef, Encoding, Ply, Property, PropertyDef, PropertyType,
    ScalarType,
};
use ply_rs_bw::writer::Writer;

use crate::math::{Vec2, Vec3};

use super::{GeometryError, TriangleMesh};
use body::{AsciiSource, BinarySource, ValueSource};
use header::{Element, Format, Header, Kind};

/// Accepted texture-coordinate property pairs, in order of preference.
const UV_NAMES: [(&str, &str); 4] = [
    ("u", "v"),
    ("s", "t"),
    ("texture_u", "texture_v"),
    ("texture_s", "texture_t"),
];
/// Accepted face index list names.
const FACE_LISTS: [&str; 2] = ["vertex_indices", "vertex_index"];
/// Vertex properties read, in attribute-slot order: position, normal, texture coordinates.
const POSITION: [&str; 3] = ["x", "y", "z"];
const NORMAL: [&str; 3] = ["nx", "ny", "nz"];

/// Loads a triangle mesh from a PLY file (ASCII, binary little or big endian).
///
/// The `vertex` element must have scalar `x`, `y`, `z`; `nx`, `ny`, `nz` (all three) are
/// read as normals and `u`/`v`, `s`/`t`, `texture_u`/`texture_v` or `texture_s`/`texture_t`
/// as texture coordinates when present. The `face` element must have an integer list
/// `vertex_indices` (or `vertex_index`); polygons are fan-triangulated and triangles with a
/// repeated index (zero area by construction) are dropped. Other elements and
/// properties are ignored. Errors (never panics) name the file and the problem: missing
/// file, malformed or truncated data (with the line of an ASCII file or the byte offset of a
/// binary one), element counts the file's size cannot hold, data left after the declared
/// counts, missing properties, non-finite values, faces with fewer than 3 or out-of-range
/// indices. See [`parse_ply`] for the bound on memory.
pub fn load_ply(path: &Path) -> Result<TriangleMesh, GeometryError> {
    let bytes = std::fs::read(path).map_err(|source| GeometryError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    parse_ply(&bytes, path)
}

/// Reads a triangle mesh from the bytes of a PLY file, as [`load_ply`] does; `path` only
/// names the file in errors.
///
/// Nothing is reserved from a count in the header before the counts have been checked
/// against the bytes after it, and every reservation is backed by the bytes it will hold (see
/// the module documentation): a header declaring 10¹¹ vertices over a few bytes of data is
/// refused at once, without allocating.
pub fn parse_ply(bytes: &[u8], path: &Path) -> Result<TriangleMesh, GeometryError> {
    let parse_error = |message: String| GeometryError::Parse {
        path: path.to_path_buf(),
        message,
    };
    let header = header::parse_header(bytes).map_err(parse_error)?;
    let body = bytes.get(header.body_offset..).unwrap_or_default();
    header::check_counts_fit(&header, body.len()).map_err(parse_error)?;
    let layout = Layout::find(&header, path)?;
    match header.format {
        Format::Ascii => read_body(
            &mut AsciiSource::new(body, header.lines + 1),
            &header,
            &layout,
            path,
        ),
        Format::BinaryLittleEndian | Format::BinaryBigEndian => read_body(
            &mut BinarySource::new(
                body,
                header.body_offset,
                header.format == Format::BinaryBigEndian,
            ),
            &header,
            &layout,
            path,
        ),
    }
}

/// Where the mesh's data sits in the elements of a header.
struct Layout {
    /// Index of the `vertex` element.
    vertex: usize,
    /// Index of the `face` element.
    face: usize,
    /// For each vertex property, its attribute slot: 0–2 position, 3–5 normal, 6–7 uv.
    slots: Vec<Option<usize>>,
    has_normals: bool,
    has_uvs: bool,
    /// Index of the index list among the face properties.
    face_list: usize,
    /// Number of vertices declared.
    vertex_count: usize,
}

impl Layout {
    fn find(header: &Header, path: &Path) -> Result<Layout, GeometryError> {
        let element = |name: &str| {
            header
                .elements
                .iter()
                .position(|e| e.name == name)
                .ok_or_else(|| GeometryError::MissingElement {
                    path: path.to_path_buf(),
                    element: name.to_string(),
                })
        };
        let vertex = element("vertex")?;
        let face = element("face")?;
        let (vdef, fdef) = (&header.elements[vertex], &header.elements[face]);
        let scalar = |name: &str| {
            vdef.properties
                .iter()
                .position(|p| p.name == name && matches!(p.kind, Kind::Scalar(_)))
        };
        let mut slots = vec![None; vdef.properties.len()];
        for (slot, name) in POSITION.iter().enumerate() {
            let p = scalar(name).ok_or_else(|| GeometryError::MissingProperty {
                path: path.to_path_buf(),
                element: "vertex".to_string(),
                property: (*name).to_string(),
            })?;
            slots[p] = Some(slot);
        }
        let normal = NORMAL.map(scalar);
        let has_normals = normal.iter().all(Option::is_some);
        if has_normals {
            for (slot, p) in normal.iter().flatten().enumerate() {
                slots[*p] = Some(3 + slot);
            }
        }
        let uv = UV_NAMES.iter().find_map(|(a, b)| scalar(a).zip(scalar(b)));
        if let Some((a, b)) = uv {
            slots[a] = Some(6);
            slots[b] = Some(7);
        }
        let face_list = FACE_LISTS
            .iter()
            .find_map(|name| {
                fdef.properties.iter().position(|p| {
                    p.name == *name
                        && matches!(p.kind, Kind::List { item, .. } if item.is_integer())
                })
            })
            .ok_or_else(|| GeometryError::MissingProperty {
                path: path.to_path_buf(),
                element: "face".to_string(),
                property: "vertex_indices (or vertex_index) integer list".to_string(),
            })?;
        let vertex_count = usize::try_from(vdef.count).map_err(|_| GeometryError::Parse {
            path: path.to_path_buf(),
            message: format!("{} vertices do not fit in memory", vdef.count),
        })?;
        Ok(Layout {
            vertex,
            face,
            slots,
            has_normals,
            has_uvs: uv.is_some(),
            face_list,
            vertex_count,
        })
    }
}

/// Reads the body element by element, building the mesh from the `vertex` and `face`
/// elements and checking every other element's values for syntax only.
fn read_body<S: ValueSource>(
    src: &mut S,
    header: &Header,
    layout: &Layout,
    path: &Path,
) -> Result<TriangleMesh, GeometryError> {
    let pb = || path.to_path_buf();
    let n = layout.vertex_count;
    // Both counts were checked against the file's size, so these reservations are backed.
    let face_count = usize::try_from(header.elements[layout.face].count).unwrap_or(0);
    let mut positions = Vec::with_capacity(n);
    let mut normals = layout.has_normals.then(|| Vec::with_capacity(n));
    let mut uvs = layout.has_uvs.then(|| Vec::with_capacity(n));
    let mut indices: Vec<[u32; 3]> = Vec::with_capacity(face_count);
    let mut polygon: Vec<i64> = Vec::new();
    for (e, element) in header.elements.iter().enumerate() {
        if element.properties.is_empty() && header.format != Format::Ascii {
            // Zero bytes per instance: nothing to read, however large the count.
            continue;
        }
        let slots = (e == layout.vertex).then_some(layout.slots.as_slice());
        let index_list = (e == layout.face).then_some(layout.face_list);
        for i in 0..element.count {
            let mut attributes = [0.0f32; 8];
            read_instance(
                src,
                element,
                slots,
                &mut attributes,
                index_list,
                &mut polygon,
            )
            .map_err(|(property, problem)| {
                let property = property.map_or(String::new(), |p| format!(", property `{p}`"));
                GeometryError::Parse {
                    path: pb(),
                    message: format!(
                        "{}: element `{}` {i} of {}{property}: {problem}",
                        src.location(),
                        element.name,
                        element.count
                    ),
                }
            })?;
            // `i` < the vertex or face count, which fits in usize.
            let index = i as usize;
            if slots.is_some() {
                let attribute =
                    |k: usize| Vec3::new(attributes[k], attributes[k + 1], attributes[k + 2]);
                let non_finite = |what| GeometryError::NonFinite {
                    path: pb(),
                    vertex: index,
                    what,
                };
                let p = attribute(0);
                if !p.is_finite() {
                    return Err(non_finite("position"));
                }
                positions.push(p);
                if let Some(normals) = &mut normals {
                    let nrm = attribute(3);
                    if !nrm.is_finite() {
                        return Err(non_finite("normal"));
                    }
                    normals.push(nrm);
                }
                if let Some(uvs) = &mut uvs {
                    let t = Vec2::new(attributes[6], attributes[7]);
                    if !t.is_finite() {
                        return Err(non_finite("uv"));
                    }
                    uvs.push(t);
                }
            }
            if index_list.is_some() {
                triangulate(&polygon, n, &mut indices).map_err(|problem| match problem {
                    FaceProblem::TooFew(count) => GeometryError::BadFace {
                        path: pb(),
                        face: index,
                        count,
                    },
                    FaceProblem::OutOfRange(bad) => GeometryError::IndexOutOfRange {
                        path: pb(),
                        face: index,
                        index: bad,
                        vertex_count: n,
                    },
                })?;
            }
        }
    }
    let trailing = src.trailing_bytes();
    if trailing > 0 {
        return Err(GeometryError::TrailingData {
            path: pb(),
            bytes: trailing,
        });
    }
    if indices.is_empty() {
        return Err(GeometryError::Empty { path: pb() });
    }
    Ok(TriangleMesh {
        positions,
        normals,
        uvs,
        indices,
    })
}

/// Reads one instance of `element`. With `slots` (the vertex element), scalar values go to
/// `attributes` at their slot; with `index_list` (the face element), the items of that list
/// property go to `polygon`. Errors carry the property concerned, if any.
fn read_instance<S: ValueSource>(
    src: &mut S,
    element: &Element,
    slots: Option<&[Option<usize>]>,
    attributes: &mut [f32; 8],
    index_list: Option<usize>,
    polygon: &mut Vec<i64>,
) -> Result<(), (Option<String>, String)> {
    src.begin_element().map_err(|m| (None, m))?;
    polygon.clear();
    for (p, property) in element.properties.iter().enumerate() {
        let in_property = |m: String| (Some(property.name.clone()), m);
        match property.kind {
            Kind::Scalar(ty) => {
                let value = src.scalar(ty).map_err(in_property)?;
                if let Some(slot) = slots.and_then(|s| s.get(p).copied().flatten()) {
                    attributes[slot] = value.to_f32();
                }
            }
            Kind::List { len, item } => {
                let count = src.list_len(len, item).map_err(in_property)?;
                if index_list == Some(p) {
                    for _ in 0..count {
                        let value = src.scalar(item).map_err(in_property)?;
                        let index = value.as_int().ok_or_else(|| {
                            in_property("vertex index is not an integer".to_string())
                        })?;
                        polygon.push(index);
                    }
                } else {
                    src.skip(item, count).map_err(in_property)?;
                }
            }
        }
    }
    src.end_element().map_err(|m| (None, m))
}

/// Why a face was refused.
enum FaceProblem {
    /// Fewer than three indices (the count found).
    TooFew(usize),
    /// An index outside `0..vertex_count`.
    OutOfRange(i64),
}

/// Checks a polygon's indices against `vertex_count` and appends its fan triangulation to
/// `indices`, dropping triangles with a repeated index.
fn triangulate(
    polygon: &[i64],
    vertex_count: usize,
    indices: &mut Vec<[u32; 3]>,
) -> Result<(), FaceProblem> {
    if polygon.len() < 3 {
        return Err(FaceProblem::TooFew(polygon.len()));
    }
    let index = |i: i64| {
        u32::try_from(i)
            .ok()
            .filter(|&k| (k as usize) < vertex_count)
            .ok_or(FaceProblem::OutOfRange(i))
    };
    let first = index(polygon[0])?;
    let mut previous = index(polygon[1])?;
    for &i in &polygon[2..] {
        let next = index(i)?;
        if first != previous && previous != next && first != next {
            indices.push([first, previous, next]);
        }
        previous = next;
    }
    Ok(())
}

/// Writes `mesh` as PLY (binary little endian when `binary`, else ASCII) with float
/// `x y z`, optional `nx ny nz` and `u v`, and `uchar uint vertex_indices` faces.
pub fn write_ply(path: &Path, mesh: &TriangleMesh, binary: bool) -> Result<(), GeometryError> {
    mesh.validate(0)?;
    let mut ply = Ply::<DefaultElement>::new();
    ply.header.encoding = if binary {
        Encoding::BinaryLittleEndian
    } else {
        Encoding::Ascii
    };
    ply.header.comments.push("written by velour".to_string());
    let float = || PropertyType::Scalar(ScalarType::Float);
    let mut vdef = ElementDef::new("vertex".to_string());
    let mut names: Vec<&str> = vec!["x", "y", "z"];
    if mesh.normals.is_some() {
        names.extend(["nx", "ny", "nz"]);
    }
    if mesh.uvs.is_some() {
        names.extend(["u", "v"]);
    }
    for n in &names {
        vdef.properties
            .add(PropertyDef::new((*n).to_string(), float()));
    }
    ply.header.elements.add(vdef);
    let mut fdef = ElementDef::new("face".to_string());
    fdef.properties.add(PropertyDef::new(
        "vertex_indices".to_string(),
        PropertyType::List(ScalarType::UChar, ScalarType::UInt),
    ));
    ply.header.elements.add(fdef);

    let mut verts = Vec::with_capacity(mesh.positions.len());
    for (i, p) in mesh.positions.iter().enumerate() {
        let mut vals = vec![p.x, p.y, p.z];
        if let Some(ns) = &mesh.normals {
            vals.extend(ns[i].to_array());
        }
        if let Some(uv) = &mesh.uvs {
            vals.extend(uv[i].to_array());
        }
        let mut e = DefaultElement::new();
        for (n, v) in names.iter().zip(vals) {
            e.insert((*n).to_string(), Property::Float(v));
        }
        verts.push(e);
    }
    ply.payload.insert("vertex".to_string(), verts);
    let faces = mesh
        .indices
        .iter()
        .map(|t| {
            let mut e = DefaultElement::new();
            e.insert("vertex_indices".to_string(), Property::ListUInt(t.to_vec()));
            e
        })
        .collect();
    ply.payload.insert("face".to_string(), faces);

    let io = |source: std::io::Error| GeometryError::Io {
        path: PathBuf::from(path),
        source,
    };
    let file = File::create(path).map_err(io)?;
    let mut out = BufWriter::new(file);
    Writer::<DefaultElement>::new()
        .write_ply(&mut out, &mut ply)
        .map_err(io)?;
    Ok(())
}
