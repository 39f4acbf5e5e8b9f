//! PLY reading and writing through `ply-rs-bw` (ASCII, binary little and big endian).

use std::fs::File;
use std::io::{BufReader, BufWriter, Read};
use std::path::{Path, PathBuf};

use ply_rs_bw::parser::{Parser, Reader};
use ply_rs_bw::ply::{
    Addable, DefaultElement, ElementDef, Encoding, Ply, Property, PropertyDef, PropertyType,
    ScalarType,
};
use ply_rs_bw::writer::Writer;

use crate::math::{Vec2, Vec3};

use super::{GeometryError, TriangleMesh};

/// Accepted texture-coordinate property pairs, in order of preference.
const UV_NAMES: [(&str, &str); 4] = [
    ("u", "v"),
    ("s", "t"),
    ("texture_u", "texture_v"),
    ("texture_s", "texture_t"),
];
/// Accepted face index list names.
const FACE_LISTS: [&str; 2] = ["vertex_indices", "vertex_index"];

/// Loads a triangle mesh from a PLY file (ASCII, binary little or big endian).
///
/// The `vertex` element must have scalar `x`, `y`, `z`; `nx`, `ny`, `nz` (all three) are
/// read as normals and `u`/`v`, `s`/`t`, `texture_u`/`texture_v` or `texture_s`/`texture_t`
/// as texture coordinates when present. The `face` element must have an integer list
/// `vertex_indices` (or `vertex_index`); polygons are fan-triangulated and triangles with a
/// repeated index (zero area by construction) are dropped. Other elements and
/// properties are ignored. Errors (never panics) name the file and the problem: missing
/// file, malformed or truncated data, data left after the declared counts, missing
/// properties, non-finite values, faces with fewer than 3 or out-of-range indices.
pub fn load_ply(path: &Path) -> Result<TriangleMesh, GeometryError> {
    let pb = || path.to_path_buf();
    let file = File::open(path).map_err(|source| GeometryError::Io { path: pb(), source })?;
    let parser = Parser::<DefaultElement>::new();
    let mut reader = Reader::new(BufReader::new(file));
    let header = parser
        .read_header(&mut reader)
        .map_err(|e| GeometryError::Parse {
            path: pb(),
            message: e.to_string(),
        })?;
    let payload = parser
        .read_payload(&mut reader, &header)
        .map_err(|e| GeometryError::Parse {
            path: pb(),
            message: e.to_string(),
        })?;
    let mut rest = Vec::new();
    reader
        .get_mut()
        .read_to_end(&mut rest)
        .map_err(|source| GeometryError::Io { path: pb(), source })?;
    let trailing = match header.encoding {
        Encoding::Ascii => rest.iter().filter(|b| !b.is_ascii_whitespace()).count(),
        _ => rest.len(),
    };
    if trailing > 0 {
        return Err(GeometryError::TrailingData {
            path: pb(),
            bytes: trailing,
        });
    }

    let missing_el = |e: &str| GeometryError::MissingElement {
        path: pb(),
        element: e.to_string(),
    };
    let vdef = header
        .elements
        .get("vertex")
        .ok_or_else(|| missing_el("vertex"))?;
    let fdef = header
        .elements
        .get("face")
        .ok_or_else(|| missing_el("face"))?;
    let is_scalar = |def: &ElementDef, name: &str| matches!(def.properties.get(name), Some(p) if matches!(p.data_type, PropertyType::Scalar(_)));
    for c in ["x", "y", "z"] {
        if !is_scalar(vdef, c) {
            return Err(GeometryError::MissingProperty {
                path: pb(),
                element: "vertex".to_string(),
                property: c.to_string(),
            });
        }
    }
    let has_normals = ["nx", "ny", "nz"].iter().all(|c| is_scalar(vdef, c));
    let uv_names = UV_NAMES
        .iter()
        .find(|(a, b)| is_scalar(vdef, a) && is_scalar(vdef, b));
    let face_list = FACE_LISTS
        .iter()
        .find(|n| matches!(fdef.properties.get(**n), Some(p) if matches!(p.data_type, PropertyType::List(_, _))))
        .ok_or_else(|| GeometryError::MissingProperty {
            path: pb(),
            element: "face".to_string(),
            property: "vertex_indices (or vertex_index) list".to_string(),
        })?;

    let empty = Vec::new();
    let verts = payload.get("vertex").unwrap_or(&empty);
    let faces = payload.get("face").unwrap_or(&empty);
    let n = verts.len();
    let scalar = |e: &DefaultElement, name: &str| {
        e.get(name)
            .and_then(Property::to_f32_lossy)
            .unwrap_or(f32::NAN)
    };

    let mut positions = Vec::with_capacity(n);
    let mut normals = has_normals.then(|| Vec::with_capacity(n));
    let mut uvs = uv_names.map(|_| Vec::with_capacity(n));
    for (i, e) in verts.iter().enumerate() {
        let p = Vec3::new(scalar(e, "x"), scalar(e, "y"), scalar(e, "z"));
        if !p.is_finite() {
            return Err(GeometryError::NonFinite {
                path: pb(),
                vertex: i,
                what: "position",
            });
        }
        positions.push(p);
        if let Some(ns) = &mut normals {
            let nrm = Vec3::new(scalar(e, "nx"), scalar(e, "ny"), scalar(e, "nz"));
            if !nrm.is_finite() {
                return Err(GeometryError::NonFinite {
                    path: pb(),
                    vertex: i,
                    what: "normal",
                });
            }
            ns.push(nrm);
        }
        if let (Some(uv), Some((a, b))) = (&mut uvs, uv_names) {
            let t = Vec2::new(scalar(e, a), scalar(e, b));
            if !t.is_finite() {
                return Err(GeometryError::NonFinite {
                    path: pb(),
                    vertex: i,
                    what: "uv",
                });
            }
            uv.push(t);
        }
    }

    let mut indices = Vec::with_capacity(faces.len());
    for (f, e) in faces.iter().enumerate() {
        let list = e.get(*face_list).and_then(list_as_i64).ok_or_else(|| {
            GeometryError::MissingProperty {
                path: pb(),
                element: "face".to_string(),
                property: format!("{face_list} (integer list) in face {f}"),
            }
        })?;
        if list.len() < 3 {
            return Err(GeometryError::BadFace {
                path: pb(),
                face: f,
                count: list.len(),
            });
        }
        let mut idx = Vec::with_capacity(list.len());
        for &i in &list {
            if i < 0 || i as u64 >= n as u64 {
                return Err(GeometryError::IndexOutOfRange {
                    path: pb(),
                    face: f,
                    index: i,
                    vertex_count: n,
                });
            }
            idx.push(i as u32);
        }
        for k in 1..idx.len() - 1 {
            let tri = [idx[0], idx[k], idx[k + 1]];
            if tri[0] != tri[1] && tri[1] != tri[2] && tri[0] != tri[2] {
                indices.push(tri);
            }
        }
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

fn list_as_i64(p: &Property) -> Option<Vec<i64>> {
    Some(match p {
        Property::ListChar(v) => v.iter().map(|&x| i64::from(x)).collect(),
        Property::ListUChar(v) => v.iter().map(|&x| i64::from(x)).collect(),
        Property::ListShort(v) => v.iter().map(|&x| i64::from(x)).collect(),
        Property::ListUShort(v) => v.iter().map(|&x| i64::from(x)).collect(),
        Property::ListInt(v) => v.iter().map(|&x| i64::from(x)).collect(),
        Property::ListUInt(v) => v.iter().map(|&x| i64::from(x)).collect(),
        _ => return None,
    })
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
