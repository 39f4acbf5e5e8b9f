//! `SceneGeometry::intersect_and_beyond`: one traversal that finds the first hit and proves
//! that nothing lies beyond it (transparent shadow rays leaving a closed mesh). Its hit must be
//! `intersect`'s, and where it says "clear", a search from just past the hit (the shadow
//! ray's next segment) must find nothing; where something does lie beyond, it must not say
//! "clear".

mod common;

use velour::geometry::{icosphere, SceneGeometry, Shape};
use velour::math::{Mat4, Ray, Vec3};
use velour::sampling::{sample_uniform_sphere, Rng};

/// Three closed spheres of triangles in a row, apart from each other.
fn spheres() -> SceneGeometry {
    let shapes = [-2.5f32, 0.0, 2.5]
        .iter()
        .map(|&x| {
            Shape::Mesh(icosphere(3).transformed(Mat4::from_translation(Vec3::new(x, 0.0, 0.0))))
        })
        .collect();
    SceneGeometry::build(shapes).expect("valid meshes")
}

#[test]
fn the_first_hit_is_intersects_and_clear_means_nothing_beyond() {
    let geo = spheres();
    let mut rng = Rng::new(42, 7);
    let (mut clear, mut blocked, mut missed) = (0, 0, 0);
    for _ in 0..20_000 {
        // Origins inside the middle sphere, or anywhere around the row.
        let o = if rng.next_f32() < 0.5 {
            sample_uniform_sphere(rng.next_2d()) * 0.9 * rng.next_f32()
        } else {
            Vec3::new(
                rng.next_f32() * 8.0 - 4.0,
                rng.next_f32() * 3.0 - 1.5,
                rng.next_f32() * 3.0 - 1.5,
            )
        };
        let d = sample_uniform_sphere(rng.next_2d());
        let t_max = if rng.next_f32() < 0.3 {
            rng.next_f32() * 4.0
        } else {
            f32::INFINITY
        };
        let ray = Ray::new(o, d);
        let plain = geo.intersect(&ray, t_max);
        let (hit, is_clear) = geo.intersect_and_beyond(&ray, t_max);
        match (&plain, &hit) {
            (None, None) => {
                missed += 1;
                assert!(!is_clear);
                continue;
            }
            (Some(a), Some(b)) => {
                assert_eq!(a.t.to_bits(), b.t.to_bits(), "t");
                assert_eq!((a.shape, a.prim), (b.shape, b.prim));
                assert_eq!(a.p, b.p);
                assert_eq!(a.ng, b.ng);
            }
            _ => panic!("intersect {plain:?} against {hit:?}"),
        }
        let Some(h) = hit else { continue };
        // The shadow ray's next segment, from just past the hit.
        let next = Ray::new(h.spawn_origin(d), d);
        let beyond = geo.intersect(&next, t_max - h.t);
        if is_clear {
            clear += 1;
            assert!(beyond.is_none(), "clear, but {beyond:?} lies beyond {h:?}");
        } else {
            blocked += 1;
            assert!(
                beyond.is_some(),
                "not proven clear, but nothing lies beyond {h:?} (o {o:?}, d {d:?})"
            );
        }
    }
    eprintln!("clear {clear}, something beyond {blocked}, missed {missed}");
    // Both answers occur (rays leaving the row, rays crossing a second sphere).
    assert!(
        clear > 2_000 && blocked > 2_000,
        "clear {clear}, blocked {blocked}"
    );
}

#[test]
fn analytic_shapes_are_never_proven_clear() {
    let shapes = vec![
        Shape::Mesh(icosphere(2)),
        Shape::Sphere {
            center: Vec3::new(0.0, 0.0, 3.0),
            radius: 0.5,
        },
    ];
    let geo = SceneGeometry::build(shapes).expect("valid shapes");
    let (hit, clear) = geo.intersect_and_beyond(&Ray::new(Vec3::ZERO, Vec3::Z), f32::INFINITY);
    let h = hit.expect("leaves the mesh");
    assert!((h.t - 1.0).abs() < 0.05, "{h:?}");
    assert!(!clear);
}
