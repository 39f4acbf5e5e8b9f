//! A log of the queries a render asks of [`SceneGeometry`](super::SceneGeometry): every closest-hit, occlusion and
//! closest-and-beyond query with its ray, its `t_max` and its answer, and the scene's
//! triangle meshes, so that `benches/ray_casting.rs` and the Embree peer
//! (`tools/peers/embree/`) can time exactly the rays a renderer casts.
//!
//! The file format ([`RayLog::to_bytes`] / [`RayLog::from_bytes`]) is always compiled. The
//! recorder ([`start`], [`finish`], and the hooks at the entry points of [`SceneGeometry`](super::SceneGeometry))
//! exists only with the cargo feature `ray-log`; without it the hooks compile to nothing.
//! With the feature, `velour render` records when `VELOUR_RAY_LOG=path` is set (every
//! `VELOUR_RAY_LOG_EVERY`-th query, default 1, counted over all threads in the order they
//! arrive: render with `--threads 1` for a reproducible log; with `--frames`, each frame's log
//! replaces the previous one's).
//!
//! Format (little-endian): the magic `VRAYLOG1`; `u32` mesh count, then per mesh `u32` shape
//! index, `u32` vertex count, `f32` xyz per vertex, `u32` triangle count, `u32` three indices
//! per triangle; `u64` queries seen, `u32` the sampling stride, `u64` queries recorded, then
//! per query 44 bytes: `u8` kind ([`QueryKind`]), `u8` flags (bit 0 hit, bit 1 clear beyond),
//! two zero bytes, `f32` origin xyz, direction xyz, `t_max`, hit distance (0 without a hit),
//! `u32` hit shape and triangle (`u32::MAX` without a hit).

use crate::math::Vec3;

#[cfg(feature = "ray-log")]
use super::{Hit, SceneGeometry, Shape};

/// The entry point a query was asked at.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum QueryKind {
    /// [`SceneGeometry::intersect`](super::SceneGeometry::intersect): the closest hit.
    Closest = 0,
    /// [`SceneGeometry::occluded`](super::SceneGeometry::occluded): any hit.
    Occluded = 1,
    /// [`SceneGeometry::intersect_and_beyond`](super::SceneGeometry::intersect_and_beyond): the closest hit and whether nothing else
    /// lies before `t_max`.
    Beyond = 2,
}

impl QueryKind {
    fn from_u8(v: u8) -> Option<QueryKind> {
        match v {
            0 => Some(QueryKind::Closest),
            1 => Some(QueryKind::Occluded),
            2 => Some(QueryKind::Beyond),
            _ => None,
        }
    }
}

/// What a query answered.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Answer {
    /// A hit was found (occlusion: the ray is occluded).
    pub hit: bool,
    /// [`QueryKind::Beyond`]: nothing else lies before `t_max` (false for other kinds).
    pub clear: bool,
    /// Hit distance along the ray (0 without a hit, and for occlusion queries).
    pub t: f32,
    /// The shape hit (`u32::MAX` without a hit, and for occlusion queries).
    pub shape: u32,
    /// The triangle of the shape hit (`u32::MAX` likewise; 0 for analytic shapes).
    pub prim: u32,
}

impl Answer {
    /// No hit.
    pub const MISS: Answer = Answer {
        hit: false,
        clear: false,
        t: 0.0,
        shape: u32::MAX,
        prim: u32::MAX,
    };
}

/// One recorded query.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Query {
    /// Where it was asked.
    pub kind: QueryKind,
    /// Ray origin.
    pub origin: Vec3,
    /// Ray direction (unit length, as the entry points require).
    pub dir: Vec3,
    /// The query's upper bound on the hit distance (may be ∞).
    pub t_max: f32,
    /// What the geometry answered.
    pub answer: Answer,
}

/// A triangle mesh of the recorded scene, as [`SceneGeometry`](super::SceneGeometry) holds it (after
/// [`super::TriangleMesh::make_outward`]).
#[derive(Clone, Debug, PartialEq)]
pub struct LoggedMesh {
    /// The mesh's shape index in the scene.
    pub shape: u32,
    /// Vertex positions.
    pub positions: Vec<Vec3>,
    /// Triangles as vertex indices.
    pub indices: Vec<[u32; 3]>,
}

/// A recorded set of queries and the meshes they were asked against.
#[derive(Clone, Debug, PartialEq)]
pub struct RayLog {
    /// The scene's triangle meshes (analytic shapes are not recorded).
    pub meshes: Vec<LoggedMesh>,
    /// Queries made while recording (recorded or not).
    pub seen: u64,
    /// Every `every`-th query was recorded.
    pub every: u32,
    /// The recorded queries, in the order they were asked.
    pub queries: Vec<Query>,
}

/// An error reading a ray log.
#[derive(Debug, thiserror::Error)]
pub enum RayLogError {
    /// Not a ray log (wrong magic).
    #[error("not a velour ray log (magic {0:?})")]
    Magic(Vec<u8>),
    /// The file ends early.
    #[error("ray log truncated at byte {0}")]
    Truncated(usize),
    /// An unknown query kind.
    #[error("unknown query kind {kind} at query {index}")]
    Kind {
        /// The byte read.
        kind: u8,
        /// The query's index.
        index: u64,
    },
    /// Bytes left after the last query.
    #[error("{0} bytes after the last query")]
    Trailing(usize),
    /// Reading or writing the file failed.
    #[error("ray log I/O: {0}")]
    Io(#[from] std::io::Error),
    /// `VELOUR_RAY_LOG_EVERY` is not a whole number of at least 1.
    #[error(
        "VELOUR_RAY_LOG_EVERY={0:?}: expected a whole number of at least 1 (keep every k-th query)"
    )]
    Every(String),
}

const MAGIC: &[u8; 8] = b"VRAYLOG1";

struct Reader<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl Reader<'_> {
    fn take<const N: usize>(&mut self) -> Result<[u8; N], RayLogError> {
        let s = self
            .bytes
            .get(self.at..self.at + N)
            .ok_or(RayLogError::Truncated(self.at))?;
        self.at += N;
        let mut a = [0; N];
        a.copy_from_slice(s);
        Ok(a)
    }
    fn u32(&mut self) -> Result<u32, RayLogError> {
        self.take().map(u32::from_le_bytes)
    }
    fn u64(&mut self) -> Result<u64, RayLogError> {
        self.take().map(u64::from_le_bytes)
    }
    fn f32(&mut self) -> Result<f32, RayLogError> {
        self.take().map(f32::from_le_bytes)
    }
    fn vec3(&mut self) -> Result<Vec3, RayLogError> {
        Ok(Vec3::new(self.f32()?, self.f32()?, self.f32()?))
    }
    /// Room for `n` items of `size` bytes left (so that a corrupt count cannot allocate).
    fn check(&self, n: u64, size: u64) -> Result<usize, RayLogError> {
        let left = (self.bytes.len() - self.at) as u64;
        if n.saturating_mul(size) > left {
            return Err(RayLogError::Truncated(self.bytes.len()));
        }
        usize::try_from(n).map_err(|_| RayLogError::Truncated(self.bytes.len()))
    }
}

impl RayLog {
    /// The log in the file format of the module docs.
    #[must_use]
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut out = Vec::with_capacity(64 + 44 * self.queries.len());
        out.extend_from_slice(MAGIC);
        let u32s = |out: &mut Vec<u8>, v: u32| out.extend_from_slice(&v.to_le_bytes());
        let f32s = |out: &mut Vec<u8>, v: f32| out.extend_from_slice(&v.to_le_bytes());
        u32s(&mut out, self.meshes.len() as u32);
        for m in &self.meshes {
            u32s(&mut out, m.shape);
            u32s(&mut out, m.positions.len() as u32);
            for p in &m.positions {
                for c in p.to_array() {
                    f32s(&mut out, c);
                }
            }
            u32s(&mut out, m.indices.len() as u32);
            for t in &m.indices {
                for i in t {
                    u32s(&mut out, *i);
                }
            }
        }
        out.extend_from_slice(&self.seen.to_le_bytes());
        u32s(&mut out, self.every);
        out.extend_from_slice(&(self.queries.len() as u64).to_le_bytes());
        for q in &self.queries {
            let a = q.answer;
            out.extend_from_slice(&[q.kind as u8, u8::from(a.hit) | u8::from(a.clear) << 1, 0, 0]);
            for c in [q.origin.to_array(), q.dir.to_array()].concat() {
                f32s(&mut out, c);
            }
            f32s(&mut out, q.t_max);
            f32s(&mut out, a.t);
            u32s(&mut out, a.shape);
            u32s(&mut out, a.prim);
        }
        out
    }

    /// Reads a log written by [`RayLog::to_bytes`].
    pub fn from_bytes(bytes: &[u8]) -> Result<RayLog, RayLogError> {
        let mut r = Reader { bytes, at: 0 };
        let magic: [u8; 8] = r.take()?;
        if &magic != MAGIC {
            return Err(RayLogError::Magic(magic.to_vec()));
        }
        let n_meshes = r.u32()?;
        let mut meshes = Vec::with_capacity(r.check(n_meshes.into(), 12)?);
        for _ in 0..n_meshes {
            let shape = r.u32()?;
            let nv = r.u32()?;
            let positions = (0..r.check(nv.into(), 12)?)
                .map(|_| r.vec3())
                .collect::<Result<_, _>>()?;
            let nt = r.u32()?;
            let indices = (0..r.check(nt.into(), 12)?)
                .map(|_| Ok([r.u32()?, r.u32()?, r.u32()?]))
                .collect::<Result<_, RayLogError>>()?;
            meshes.push(LoggedMesh {
                shape,
                positions,
                indices,
            });
        }
        let seen = r.u64()?;
        let every = r.u32()?;
        let n = r.u64()?;
        let mut queries = Vec::with_capacity(r.check(n, 44)?);
        for index in 0..n {
            let [kind, flags, _, _] = r.take::<4>()?;
            let kind = QueryKind::from_u8(kind).ok_or(RayLogError::Kind { kind, index })?;
            let origin = r.vec3()?;
            let dir = r.vec3()?;
            let t_max = r.f32()?;
            let answer = Answer {
                hit: flags & 1 != 0,
                clear: flags & 2 != 0,
                t: r.f32()?,
                shape: r.u32()?,
                prim: r.u32()?,
            };
            queries.push(Query {
                kind,
                origin,
                dir,
                t_max,
                answer,
            });
        }
        if r.at != bytes.len() {
            return Err(RayLogError::Trailing(bytes.len() - r.at));
        }
        Ok(RayLog {
            meshes,
            seen,
            every,
            queries,
        })
    }

    /// Writes the log to `path`.
    pub fn write_file(&self, path: &std::path::Path) -> Result<(), RayLogError> {
        Ok(std::fs::write(path, self.to_bytes())?)
    }

    /// Reads a log from `path`.
    pub fn read_file(path: &std::path::Path) -> Result<RayLog, RayLogError> {
        RayLog::from_bytes(&std::fs::read(path)?)
    }

    /// Every mesh's triangles in one list (the meshes in order; [`RayLog::global_prim`]
    /// numbers them), with their vertices.
    #[must_use]
    pub fn merged_mesh(&self) -> (Vec<Vec3>, Vec<[u32; 3]>) {
        let mut positions = Vec::new();
        let mut indices = Vec::new();
        for m in &self.meshes {
            let base = positions.len() as u32;
            positions.extend_from_slice(&m.positions);
            indices.extend(m.indices.iter().map(|t| t.map(|i| i + base)));
        }
        (positions, indices)
    }

    /// The index in [`RayLog::merged_mesh`] of triangle `prim` of shape `shape`, or `None`
    /// when the shape is not a logged mesh.
    #[must_use]
    pub fn global_prim(&self, shape: u32, prim: u32) -> Option<u32> {
        let mut base = 0;
        for m in &self.meshes {
            if m.shape == shape {
                return Some(base + prim);
            }
            base += m.indices.len() as u32;
        }
        None
    }
}

#[cfg(feature = "ray-log")]
mod recorder {
    use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
    use std::sync::Mutex;

    use super::{Answer, Query, QueryKind};
    use crate::geometry::Hit;
    use crate::math::Ray;

    pub(super) static ON: AtomicBool = AtomicBool::new(false);
    pub(super) static EVERY: AtomicU64 = AtomicU64::new(1);
    pub(super) static SEEN: AtomicU64 = AtomicU64::new(0);
    pub(super) static QUERIES: Mutex<Vec<Query>> = Mutex::new(Vec::new());

    #[cold]
    #[inline(never)]
    pub(super) fn record(kind: QueryKind, ray: &Ray, t_max: f32, answer: Answer) {
        let n = SEEN.fetch_add(1, Ordering::Relaxed);
        if !n.is_multiple_of(EVERY.load(Ordering::Relaxed).max(1)) {
            return;
        }
        let q = Query {
            kind,
            origin: ray.o,
            dir: ray.d,
            t_max,
            answer,
        };
        // A poisoned lock only means another thread panicked while pushing: keep recording.
        QUERIES.lock().unwrap_or_else(|e| e.into_inner()).push(q);
    }

    pub(super) fn answer(hit: Option<&Hit>, clear: bool) -> Answer {
        hit.map_or(Answer::MISS, |h| Answer {
            hit: true,
            clear,
            t: h.t,
            shape: h.shape,
            prim: h.prim,
        })
    }
}

/// Starts recording every `every`-th query (from now on, over all threads), dropping any
/// queries recorded before.
#[cfg(feature = "ray-log")]
pub fn start(every: u64) {
    use std::sync::atomic::Ordering;
    recorder::QUERIES
        .lock()
        .unwrap_or_else(|e| e.into_inner())
        .clear();
    recorder::SEEN.store(0, Ordering::Relaxed);
    recorder::EVERY.store(every.max(1), Ordering::Relaxed);
    recorder::ON.store(true, Ordering::Release);
}

/// Stops recording and returns the queries recorded since [`start`] with `geometry`'s
/// triangle meshes.
#[cfg(feature = "ray-log")]
pub fn finish(geometry: &SceneGeometry) -> RayLog {
    use std::sync::atomic::Ordering;
    recorder::ON.store(false, Ordering::Release);
    let queries = std::mem::take(&mut *recorder::QUERIES.lock().unwrap_or_else(|e| e.into_inner()));
    let meshes = (0..geometry.shape_count())
        .filter_map(|i| match geometry.shape(i) {
            Some(Shape::Mesh(m)) => Some(LoggedMesh {
                shape: i as u32,
                positions: m.positions.clone(),
                indices: m.indices.clone(),
            }),
            _ => None,
        })
        .collect();
    RayLog {
        meshes,
        seen: recorder::SEEN.load(Ordering::Relaxed),
        every: u32::try_from(recorder::EVERY.load(Ordering::Relaxed)).unwrap_or(u32::MAX),
        queries,
    }
}

/// `VELOUR_RAY_LOG=path` (and `VELOUR_RAY_LOG_EVERY=k`, default 1): starts recording and
/// returns the path to write the log to at the end, or `None` when the variable is unset.
///
/// # Errors
/// [`RayLogError::Every`] when `VELOUR_RAY_LOG_EVERY` is set but not a whole number ≥ 1
/// (nothing is recorded then).
#[cfg(feature = "ray-log")]
pub fn start_from_env() -> Result<Option<std::path::PathBuf>, RayLogError> {
    let Some(path) = std::env::var_os("VELOUR_RAY_LOG") else {
        return Ok(None);
    };
    let every = match std::env::var("VELOUR_RAY_LOG_EVERY") {
        Err(_) => 1,
        Ok(s) => parse_every(&s)?,
    };
    start(every);
    Ok(Some(path.into()))
}

/// `VELOUR_RAY_LOG_EVERY`'s value: a whole number of at least 1.
#[cfg(any(feature = "ray-log", test))]
fn parse_every(text: &str) -> Result<u64, RayLogError> {
    match text.trim().parse::<u64>() {
        Ok(k) if k >= 1 => Ok(k),
        _ => Err(RayLogError::Every(text.to_string())),
    }
}

/// Hook of [`SceneGeometry::intersect`](super::SceneGeometry::intersect).
#[cfg(feature = "ray-log")]
#[inline(always)]
pub(crate) fn closest(ray: &crate::math::Ray, t_max: f32, hit: Option<&Hit>) {
    if recorder::ON.load(std::sync::atomic::Ordering::Relaxed) {
        recorder::record(QueryKind::Closest, ray, t_max, recorder::answer(hit, false));
    }
}

/// Hook of [`SceneGeometry::occluded`](super::SceneGeometry::occluded).
#[cfg(feature = "ray-log")]
#[inline(always)]
pub(crate) fn occluded(ray: &crate::math::Ray, t_max: f32, hit: bool) {
    if recorder::ON.load(std::sync::atomic::Ordering::Relaxed) {
        let answer = Answer {
            hit,
            ..Answer::MISS
        };
        recorder::record(QueryKind::Occluded, ray, t_max, answer);
    }
}

/// Hook of [`SceneGeometry::intersect_and_beyond`](super::SceneGeometry::intersect_and_beyond).
#[cfg(feature = "ray-log")]
#[inline(always)]
pub(crate) fn beyond(ray: &crate::math::Ray, t_max: f32, hit: Option<&Hit>, clear: bool) {
    if recorder::ON.load(std::sync::atomic::Ordering::Relaxed) {
        recorder::record(QueryKind::Beyond, ray, t_max, recorder::answer(hit, clear));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_sampling_step_must_be_a_whole_number_of_at_least_one() {
        assert_eq!(parse_every("128").ok(), Some(128));
        assert_eq!(parse_every(" 1 ").ok(), Some(1));
        for bad in ["0", "-3", "1.5", "every", ""] {
            let err = parse_every(bad).expect_err(bad).to_string();
            assert!(err.contains("VELOUR_RAY_LOG_EVERY"), "{err}");
        }
    }

    fn sample_log() -> RayLog {
        let q = |kind, i: f32, answer| Query {
            kind,
            origin: Vec3::new(i, -i, 0.5),
            dir: Vec3::new(0.0, 0.6, 0.8),
            t_max: if i > 1.0 { f32::INFINITY } else { i },
            answer,
        };
        RayLog {
            meshes: vec![
                LoggedMesh {
                    shape: 1,
                    positions: vec![Vec3::X, Vec3::Y, Vec3::Z],
                    indices: vec![[0, 1, 2]],
                },
                LoggedMesh {
                    shape: 3,
                    positions: vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::ONE],
                    indices: vec![[0, 1, 2], [1, 3, 2]],
                },
            ],
            seen: 7,
            every: 2,
            queries: vec![
                q(QueryKind::Closest, 0.25, Answer::MISS),
                q(
                    QueryKind::Beyond,
                    2.0,
                    Answer {
                        hit: true,
                        clear: true,
                        t: 1.5,
                        shape: 3,
                        prim: 1,
                    },
                ),
                q(
                    QueryKind::Occluded,
                    0.5,
                    Answer {
                        hit: true,
                        ..Answer::MISS
                    },
                ),
            ],
        }
    }

    #[test]
    fn a_log_round_trips_and_rejects_damage() {
        let log = sample_log();
        let bytes = log.to_bytes();
        assert_eq!(RayLog::from_bytes(&bytes).expect("reads"), log);
        for cut in [0, 7, 8, 20, bytes.len() - 1] {
            assert!(matches!(
                RayLog::from_bytes(&bytes[..cut]),
                Err(RayLogError::Truncated(_) | RayLogError::Magic(_))
            ));
        }
        let mut longer = bytes.clone();
        longer.push(0);
        assert!(matches!(
            RayLog::from_bytes(&longer),
            Err(RayLogError::Trailing(1))
        ));
        let mut bad_kind = bytes.clone();
        let first_query = bytes.len() - 3 * 44;
        bad_kind[first_query] = 9;
        assert!(matches!(
            RayLog::from_bytes(&bad_kind),
            Err(RayLogError::Kind { kind: 9, index: 0 })
        ));
    }

    #[test]
    fn merged_meshes_number_triangles_in_mesh_order() {
        let log = sample_log();
        let (p, t) = log.merged_mesh();
        assert_eq!(p.len(), 7);
        assert_eq!(t, vec![[0, 1, 2], [3, 4, 5], [4, 6, 5]]);
        assert_eq!(log.global_prim(1, 0), Some(0));
        assert_eq!(log.global_prim(3, 1), Some(2));
        assert_eq!(log.global_prim(2, 0), None);
    }
}
