//! The ray log (cargo feature `ray-log`): a tiny render of a skin-like icosphere (rough
//! dielectric around a dense medium, sky and sun, as `tools/peers/bench/skin_icosphere.toml`)
//! recorded, written, read back and replayed. Run with
//! `cargo test --release --features ray-log --test ray_log`.
#![cfg(feature = "ray-log")]

mod common;

use common::render::{render_finite, scene_from_text};
use velour::geometry::ray_log::{self, Answer, QueryKind, RayLog};
use velour::geometry::{icosphere, write_ply, SceneGeometry, Shape, TriangleMesh};
use velour::math::Ray;

fn skin_scene(dir: &std::path::Path) -> velour::scene::Scene {
    let ply = dir.join("icosphere.ply");
    write_ply(&ply, &icosphere(3), true).expect("write the icosphere");
    let text = format!(
        r#"
[camera]
eye = [0.0, 0.5, 3.6]
look_at = [0.0, 0.0, 0.0]
fov = 40
[film]
width = 12
height = 12
spp = 2
seed = 3
max_depth = 1000
[[light]]
type = "environment"
radiance = [0.35, 0.4, 0.5]
[[light]]
type = "distant"
direction = [-0.6, 0.8, 0.5]
irradiance = [4.0, 3.6, 3.1]
[[object]]
name = "skin"
shape = "mesh"
file = "{}"
surface = {{ type = "dielectric", ior = 1.4, roughness = 0.55 }}
interior = {{ type = "homogeneous", albedo = [0.99, 0.95, 0.85], albedo_mode = "single", density = 36.0, attenuation = [2.25, 1.5, 1.0] }}
"#,
        ply.display()
    );
    scene_from_text(&text, dir.join("skin.toml"))
}

/// The answer the geometry gives to `q`'s ray, as the recorder writes it.
fn replay(geometry: &SceneGeometry, log: &RayLog, kind: QueryKind, ray: &Ray, t: f32) -> Answer {
    let record = |h: Option<velour::geometry::Hit>, clear: bool| {
        h.map_or(Answer::MISS, |h| {
            let prim = log.global_prim(h.shape, h.prim).expect("a logged mesh");
            Answer {
                hit: true,
                clear,
                t: h.t,
                // The replay's geometry has one merged mesh: shape 0.
                shape: log.meshes[0].shape,
                prim,
            }
        })
    };
    match kind {
        QueryKind::Closest => record(geometry.intersect(ray, t), false),
        QueryKind::Beyond => {
            let (h, clear) = geometry.intersect_and_beyond(ray, t);
            record(h, clear)
        }
        QueryKind::Occluded => Answer {
            hit: geometry.occluded(ray, t),
            ..Answer::MISS
        },
    }
}

#[test]
fn a_recorded_render_round_trips_and_replays_bit_for_bit() {
    let dir = std::env::temp_dir().join(format!("velour-ray-log-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    let scene = skin_scene(&dir);

    // Every query.
    ray_log::start(1);
    let (_, summary) = render_finite(&scene, 1);
    let all = ray_log::finish(&scene.geometry);
    assert_eq!(all.every, 1);
    assert_eq!(all.seen, all.queries.len() as u64);
    // The render counts the rays it casts; each is one query at an entry point.
    assert_eq!(
        all.seen, summary.rays,
        "queries recorded vs the render's ray count"
    );
    assert!(all.queries.len() > 1000, "{} queries", all.queries.len());
    // The skin's mix (its guided exit connections are closest-hit queries): camera, exit
    // and connection rays (t_max = ∞) and flights clipped to a sampled distance (finite).
    for finite in [false, true] {
        assert!(all
            .queries
            .iter()
            .any(|q| q.kind == QueryKind::Closest && q.t_max.is_finite() == finite));
    }
    assert!(all.queries.iter().any(|q| q.answer.hit));
    assert!(all.queries.iter().any(|q| !q.answer.hit));
    assert_eq!(all.meshes.len(), 1);
    assert_eq!(all.meshes[0].indices.len(), 1280);

    // The file round-trips.
    let path = dir.join("rays.vrl");
    all.write_file(&path).expect("write the log");
    let back = RayLog::read_file(&path).expect("read the log");
    assert_eq!(back, all);

    // Every third query: the same render, the same queries, a third of them.
    ray_log::start(3);
    let _ = render_finite(&scene, 1);
    let third = ray_log::finish(&scene.geometry);
    assert_eq!(third.seen, all.seen);
    assert_eq!(third.every, 3);
    assert_eq!(third.queries.len() as u64, all.seen.div_ceil(3));
    assert!(third
        .queries
        .iter()
        .zip(all.queries.iter().step_by(3))
        .all(|(a, b)| a == b));

    // Replayed on a geometry built from the log's mesh alone (as the bench does), every
    // query gives the recorded answer bit for bit.
    let (positions, indices) = back.merged_mesh();
    let mesh = TriangleMesh {
        positions,
        normals: None,
        uvs: None,
        indices,
    };
    let geometry = SceneGeometry::build(vec![Shape::Mesh(mesh)]).expect("geometry");
    let mut recorded_hits = 0;
    for q in &back.queries {
        let ray = Ray::new(q.origin, q.dir);
        let got = replay(&geometry, &back, q.kind, &ray, q.t_max);
        assert_eq!(got.hit, q.answer.hit, "{q:?}");
        assert_eq!(got.clear, q.answer.clear, "{q:?}");
        assert_eq!(got.t.to_bits(), q.answer.t.to_bits(), "{q:?}");
        assert_eq!(
            (got.shape, got.prim),
            (q.answer.shape, q.answer.prim),
            "{q:?}"
        );
        recorded_hits += usize::from(q.answer.hit);
    }
    assert!(recorded_hits > 0);
    let _ = std::fs::remove_dir_all(&dir);
}
