//! Texture parameters in scene files: bad input gives errors naming the file, the object and
//! key, and for bad texels the pixel; textures are shared between parameters; PNG (8 and 16
//! bit, sRGB decoded for colours) and EXR values arrive as written.

mod common;

use std::path::Path;
use std::sync::Arc;

use common::files::TempDir;
use common::textures::{exr_grey, exr_rgb, png_grey16, png_rgb8};
use velour::geometry::{icosphere, write_ply};
use velour::math::Vec2;
use velour::medium::WalkInterior;
use velour::scene::{load_scene_str, ObjectSurface, Scene};
use velour::texture::{srgb_to_linear, ColorParam, ScalarParam};

const HEAD: &str =
    "[camera]\neye = [0, 0, 4]\nlook_at = [0, 0, 0]\n\n[film]\nwidth = 8\nheight = 8\n";

fn load(dir: &TempDir, body: &str) -> Result<Scene, String> {
    let text = format!("{HEAD}{body}");
    load_scene_str(&text, &dir.join("scene.toml")).map_err(|e| e.to_string())
}

fn err(dir: &TempDir, body: &str) -> String {
    match load(dir, body) {
        Ok(_) => panic!("scene loaded but should fail:\n{body}"),
        Err(e) => e,
    }
}

fn assert_mentions(e: &str, needles: &[&str]) {
    for n in needles {
        assert!(e.contains(n), "error does not mention {n:?}: {e}");
    }
}

fn sphere_with(interior: &str) -> String {
    format!(
        "[[object]]\nname = \"ball\"\nshape = \"sphere\"\nsurface = {{ type = \"dielectric\" }}\ninterior = {interior}\n"
    )
}

#[test]
fn a_missing_texture_names_the_file_object_and_key() {
    let dir = TempDir::new("tex-missing");
    let e = err(
        &dir,
        &sphere_with("{ type = \"homogeneous\", albedo = { texture = \"nope.png\" } }"),
    );
    assert_mentions(
        &e,
        &[
            "scene.toml:",
            "ball: interior.albedo",
            "nope.png",
            "cannot read",
        ],
    );
}

#[test]
fn a_corrupt_png_names_the_file() {
    let dir = TempDir::new("tex-corrupt");
    std::fs::write(dir.join("bad.png"), b"\x89PNG\r\n\x1a\nthis is not a png").unwrap();
    let e = err(
        &dir,
        &sphere_with("{ type = \"homogeneous\", albedo = { texture = \"bad.png\" } }"),
    );
    assert_mentions(&e, &["ball: interior.albedo", "bad.png", "corrupt"]);
    // An unknown extension too.
    std::fs::write(dir.join("t.jpg"), b"x").unwrap();
    let e = err(
        &dir,
        &sphere_with("{ type = \"homogeneous\", density = { texture = \"t.jpg\" } }"),
    );
    assert_mentions(&e, &["ball: interior.density", "t.jpg", ".png or .exr"]);
}

#[test]
fn a_texture_on_a_mesh_without_uvs_names_the_object_and_key() {
    let dir = TempDir::new("tex-nouv");
    png_rgb8(&dir.join("c.png"), 2, 2, |_, _| [100, 100, 100]);
    write_ply(&dir.join("ball.ply"), &icosphere(1), false).unwrap();
    let e = err(
        &dir,
        "[[object]]\nname = \"head\"\nshape = \"mesh\"\nfile = \"ball.ply\"\nsurface = { type = \"lambertian\", reflectance = { texture = \"c.png\" } }\n",
    );
    assert_mentions(
        &e,
        &[
            "head: surface.reflectance",
            "c.png",
            "no texture coordinates",
        ],
    );
    let e = err(
        &dir,
        "[[object]]\nname = \"head\"\nshape = \"mesh\"\nfile = \"ball.ply\"\nsurface = { type = \"dielectric\" }\ninterior = { type = \"homogeneous\", albedo = { texture = \"c.png\" } }\n",
    );
    assert_mentions(&e, &["head: interior.albedo", "no texture coordinates"]);
}

#[test]
fn nan_and_negative_texels_name_the_pixel() {
    let dir = TempDir::new("tex-nan");
    exr_grey(&dir.join("d.exr"), 4, 3, |x, y| {
        if (x, y) == (2, 1) {
            f32::NAN
        } else {
            1.0
        }
    });
    let e = err(
        &dir,
        &sphere_with("{ type = \"homogeneous\", density = { texture = \"d.exr\" } }"),
    );
    assert_mentions(
        &e,
        &["ball: interior.density", "d.exr", "pixel (2, 1)", "NaN"],
    );
    exr_rgb(&dir.join("a.exr"), 3, 3, |x, y| {
        if (x, y) == (0, 2) {
            [1.0, -0.5, 1.0]
        } else {
            [1.0; 3]
        }
    });
    let e = err(
        &dir,
        &sphere_with("{ type = \"homogeneous\", attenuation = { texture = \"a.exr\" } }"),
    );
    assert_mentions(
        &e,
        &[
            "ball: interior.attenuation",
            "a.exr",
            "pixel (0, 2)",
            "negative",
            "channel G",
        ],
    );
}

#[test]
fn values_outside_a_parameter_range_name_the_pixel() {
    let dir = TempDir::new("tex-range");
    exr_grey(&dir.join("m.exr"), 5, 4, |x, y| {
        if (x, y) == (3, 2) {
            1.25
        } else {
            0.5
        }
    });
    let blend = "{ type = \"blend\", mask = { texture = \"m.exr\" }, a = { type = \"homogeneous\" }, b = { type = \"homogeneous\", albedo = 0.2 } }";
    let e = err(&dir, &sphere_with(blend));
    assert_mentions(
        &e,
        &[
            "ball: interior.mask",
            "m.exr",
            "pixel (3, 2)",
            "1.25",
            "[0, 1]",
        ],
    );
    // An albedo texture scaled above 1.
    png_rgb8(&dir.join("c.png"), 2, 2, |_, _| [255, 255, 255]);
    let e = err(
        &dir,
        &sphere_with("{ type = \"homogeneous\", albedo = { texture = \"c.png\", scale = 2.0 } }"),
    );
    assert_mentions(
        &e,
        &["ball: interior.albedo", "pixel (0, 0)", "outside [0, 1]"],
    );
    // A zero attenuation texel.
    exr_grey(&dir.join("z.exr"), 2, 2, |x, _| x as f32);
    let e = err(
        &dir,
        &sphere_with("{ type = \"homogeneous\", attenuation = { texture = \"z.exr\" } }"),
    );
    assert_mentions(&e, &["ball: interior.attenuation", "pixel (0, 0)"]);
    // A constant mask outside [0, 1].
    let e = err(
        &dir,
        &sphere_with("{ type = \"blend\", mask = 1.5, a = { type = \"homogeneous\" }, b = { type = \"homogeneous\" } }"),
    );
    assert_mentions(&e, &["ball: interior.mask = 1.5", "outside [0, 1]"]);
}

#[test]
fn unknown_and_misspelt_keys_in_texture_tables_are_errors_with_their_line() {
    let dir = TempDir::new("tex-keys");
    png_rgb8(&dir.join("c.png"), 2, 2, |_, _| [100, 100, 100]);
    let body = "[[object]]\nname = \"ball\"\nshape = \"sphere\"\nsurface = { type = \"dielectric\" }\ninterior = { type = \"homogeneous\",\n  albedo = { texture = \"c.png\", colourspace = \"srgb\" } }\n";
    let e = err(&dir, body);
    // HEAD has 7 lines; the albedo table is on line 13.
    assert_mentions(
        &e,
        &["scene.toml:13", "unknown key `colourspace`", "colorspace"],
    );
    let e = err(
        &dir,
        &sphere_with(
            "{ type = \"homogeneous\", albedo = { texture = \"c.png\", wrap = \"mirror\" } }",
        ),
    );
    assert_mentions(
        &e,
        &[
            "ball: interior.albedo",
            "wrap = \"mirror\"",
            "\"repeat\" or \"clamp\"",
        ],
    );
    let e = err(
        &dir,
        &sphere_with(
            "{ type = \"homogeneous\", density = { texture = \"c.png\", channel = \"alpha\" } }",
        ),
    );
    assert_mentions(
        &e,
        &["ball: interior.density", "channel = \"alpha\"", "luminance"],
    );
    let e = err(
        &dir,
        &sphere_with("{ type = \"homogeneous\", albedo = { file = \"c.png\" } }"),
    );
    assert_mentions(&e, &["unknown key `file`"]);
    // A scalar parameter does not take an array.
    let e = err(
        &dir,
        &sphere_with("{ type = \"homogeneous\", density = [1, 2, 3] }"),
    );
    assert_mentions(&e, &["density", "a number or a texture table"]);
}

#[test]
fn projection_and_blend_keys_are_checked() {
    let dir = TempDir::new("tex-proj");
    png_rgb8(&dir.join("c.png"), 2, 2, |_, _| [100, 100, 100]);
    let e = err(
        &dir,
        &sphere_with("{ type = \"homogeneous\", albedo = { texture = \"c.png\" }, projection = \"surface\" }"),
    );
    assert_mentions(
        &e,
        &[
            "ball: interior.projection = \"surface\"",
            "needs a mesh boundary",
        ],
    );
    let e = err(
        &dir,
        &sphere_with("{ type = \"homogeneous\", projection = \"planar\" }"),
    );
    assert_mentions(&e, &["projection = \"planar\"", "unknown", "\"surface\""]);
    let e = err(
        &dir,
        &sphere_with("{ type = \"blend\", mask = 0.5, a = { type = \"homogeneous\" } }"),
    );
    assert_mentions(&e, &["ball: interior", "needs `b`"]);
    let e = err(
        &dir,
        &sphere_with("{ type = \"blend\", mask = 0.5, a = { type = \"homogeneous\", albdo = 0.5 }, b = { type = \"homogeneous\" } }"),
    );
    assert_mentions(&e, &["ball: interior.a", "unknown key `albdo`", "albedo"]);
    let e = err(
        &dir,
        &sphere_with("{ type = \"blend\", mask = 0.5, a = { type = \"homogeneous\", nee = \"interior\" }, b = { type = \"homogeneous\" } }"),
    );
    assert_mentions(&e, &["ball: interior.a", "`nee` goes on the blend"]);
    let e = err(
        &dir,
        &sphere_with(
            "{ type = \"blend\", a = { type = \"homogeneous\" }, b = { type = \"homogeneous\" } }",
        ),
    );
    assert_mentions(&e, &["needs `mask`"]);
}

/// The texture of a colour parameter.
fn colour_texture(p: &ColorParam) -> &Arc<velour::texture::Texture> {
    match p {
        ColorParam::Texture(t) => t,
        ColorParam::Constant(_) => panic!("not a texture"),
    }
}

#[test]
fn parameters_naming_the_same_file_and_options_share_one_texture() {
    let dir = TempDir::new("tex-share");
    png_rgb8(&dir.join("c.png"), 4, 4, |x, _| {
        [(x * 60 + 10) as u8, 128, 200]
    });
    let body = "[[object]]\nname = \"a\"\nshape = \"sphere\"\nsurface = { type = \"dielectric\", tint = { texture = \"c.png\" } }\ninterior = { type = \"homogeneous\", albedo = { texture = \"c.png\" }, attenuation = { texture = \"c.png\", colorspace = \"linear\" } }\n";
    let scene = load(&dir, body).unwrap();
    let obj = &scene.objects[0];
    let ObjectSurface::Dielectric(d) = &obj.surface else {
        panic!("dielectric")
    };
    let Some(WalkInterior::Entry(e)) = obj.walk.as_deref() else {
        panic!("entry interior")
    };
    let tint = colour_texture(&d.tint);
    assert!(Arc::ptr_eq(tint, colour_texture(&e.albedo)));
    assert!(!Arc::ptr_eq(tint, colour_texture(&e.attenuation)));
    // PNG colours are sRGB-decoded by default, linear on request; texel centre of (1, 0).
    let uv = Vec2::new(1.5 / 4.0, 1.0 - 0.5 / 4.0);
    let srgb = tint.eval(uv, 0.0);
    let lin = colour_texture(&e.attenuation).eval(uv, 0.0);
    assert!(
        (srgb.0[0] - srgb_to_linear(70.0 / 255.0)).abs() < 1e-6,
        "{srgb:?}"
    );
    assert!(
        (srgb.0[2] - srgb_to_linear(200.0 / 255.0)).abs() < 1e-6,
        "{srgb:?}"
    );
    assert!((lin.0[1] - 128.0 / 255.0).abs() < 1e-6, "{lin:?}");
}

#[test]
fn sixteen_bit_pngs_and_exrs_are_read_as_written() {
    let dir = TempDir::new("tex-16");
    png_grey16(&dir.join("r.png"), 3, 2, |x, y| {
        (x * 20000 + y * 1000) as u16
    });
    exr_rgb(&dir.join("s.exr"), 2, 2, |x, y| {
        [0.1 + x as f32, 0.5, 2.0 + y as f32]
    });
    let body = "[[object]]\nname = \"a\"\nshape = \"sphere\"\nsurface = { type = \"conductor\", roughness = { texture = \"r.png\", scale = 0.5 } }\n[[object]]\nname = \"b\"\nshape = \"sphere\"\nsurface = { type = \"dielectric\" }\ninterior = { type = \"homogeneous\", density = { texture = \"s.exr\", channel = \"b\" } }\n";
    let scene = load(&dir, body).unwrap();
    let ObjectSurface::Textured(t) = &scene.objects[0].surface else {
        panic!("textured")
    };
    let velour::scene::TexturedKind::Conductor {
        roughness: ScalarParam::Texture(r),
        ..
    } = &t.kind
    else {
        panic!("conductor with a roughness texture")
    };
    // Pixel (2, 1) = 41000 / 65535, linear (a scalar), times 0.5.
    let v = r.eval_scalar(Vec2::new(2.5 / 3.0, 0.25), 0.0);
    assert!((v - 0.5 * 41000.0 / 65535.0).abs() < 1e-6, "{v}");
    let Some(WalkInterior::Entry(e)) = scene.objects[1].walk.as_deref() else {
        panic!("entry")
    };
    let ScalarParam::Texture(d) = &e.density else {
        panic!("density texture")
    };
    // Pixel (1, 1) (bottom right): blue 3.0.
    let v = d.eval_scalar(Vec2::new(0.75, 0.25), 0.0);
    assert!((v - 3.0).abs() < 1e-6, "{v}");
}

#[test]
fn untextured_scenes_have_no_per_walk_interiors() {
    let scene = velour::scene::default_scene().unwrap();
    assert!(scene
        .objects
        .iter()
        .all(|o| o.walk.is_none() && !o.surface.is_textured()));
    let _ = Path::new("");
}

#[test]
fn surface_blends_check_their_looks() {
    let dir = TempDir::new("tex-surface-blend");
    let obj = |surface: &str| {
        format!("[[object]]\nname = \"ball\"\nshape = \"sphere\"\nsurface = {surface}\ninterior = {{ type = \"homogeneous\" }}\n")
    };
    let e = err(
        &dir,
        &obj("{ type = \"blend\", mask = 0.5, a = { type = \"dielectric\", ior = 1.4 }, b = { type = \"dielectric\", ior = 1.5 } }"),
    );
    assert_mentions(&e, &["ball: surface", "same `ior`"]);
    let e = err(
        &dir,
        &obj("{ type = \"blend\", mask = 0.5, a = { type = \"dielectric\" }, b = { type = \"lambertian\" } }"),
    );
    assert_mentions(&e, &["ball: surface", "must both be dielectrics"]);
    let e = err(
        &dir,
        &obj("{ type = \"blend\", mask = 0.5, a = { type = \"dielectric\", roughnes = 0.3 }, b = { type = \"dielectric\" } }"),
    );
    assert_mentions(&e, &["ball: surface.a", "unknown key `roughnes`"]);
    let e = err(
        &dir,
        &obj("{ type = \"blend\", mask = 1.2, a = { type = \"dielectric\" }, b = { type = \"dielectric\" } }"),
    );
    assert_mentions(&e, &["ball: surface.mask = 1.2", "outside [0, 1]"]);
    let e = err(
        &dir,
        &obj("{ type = \"blend\", mask = 0.2, a = { type = \"dielectric\", tint = 2.0 }, b = { type = \"dielectric\" } }"),
    );
    assert_mentions(&e, &["ball: surface.a.tint"]);
    let scene = load(
        &dir,
        &obj("{ type = \"blend\", mask = 0.2, a = { type = \"dielectric\", roughness = 0.1 }, b = { type = \"dielectric\", roughness = 0.7 } }"),
    )
    .unwrap();
    assert!(matches!(scene.objects[0].surface, ObjectSurface::Blend(_)));
    assert_eq!(scene.objects[0].ior, 1.4);
}

/// `projection = "surface"` needs a mesh with texture coordinates: a mesh without them is an
/// error naming the object and key (a sphere: `projection_and_blend_keys_are_checked`); on a
/// mesh with them it builds a
/// projected medium whose majorant is the textures' largest extinction.
#[test]
fn surface_projection_needs_a_mesh_with_texture_coordinates() {
    let dir = TempDir::new("tex-proj-surface");
    png_rgb8(&dir.join("c.png"), 2, 2, |_, _| [100, 100, 100]);
    exr_grey(
        &dir.join("d.exr"),
        2,
        2,
        |x, _| if x == 0 { 1.0 } else { 3.0 },
    );
    let mut bare = icosphere(1);
    write_ply(&dir.join("bare.ply"), &bare, false).unwrap();
    bare.uvs = Some(vec![Vec2::new(0.5, 0.5); bare.positions.len()]);
    write_ply(&dir.join("uv.ply"), &bare, false).unwrap();
    let mesh_with = |file: &str, interior: &str| {
        format!("[[object]]\nname = \"skin\"\nshape = \"mesh\"\nfile = \"{file}\"\nsurface = {{ type = \"dielectric\" }}\ninterior = {interior}\n")
    };
    let e = err(
        &dir,
        &mesh_with(
            "bare.ply",
            "{ type = \"homogeneous\", attenuation = 0.5, projection = \"surface\" }",
        ),
    );
    assert_mentions(
        &e,
        &[
            "scene.toml:",
            "skin: interior.projection = \"surface\"",
            "no texture coordinates",
        ],
    );
    let e = err(
        &dir,
        &mesh_with(
            "bare.ply",
            "{ type = \"absorption\", density = { texture = \"d.exr\" }, projection = \"surface\" }",
        ),
    );
    assert_mentions(&e, &["skin: interior", "texture coordinates"]);
    let scene = load(
        &dir,
        &mesh_with(
            "uv.ply",
            "{ type = \"homogeneous\", albedo = { texture = \"c.png\" }, density = { texture = \"d.exr\" }, attenuation = [0.5, 1.0, 2.0], projection = \"surface\" }",
        ),
    )
    .unwrap();
    let m = scene.objects[0].medium.unwrap() as usize;
    match &scene.media[m] {
        velour::medium::Medium::Projected(p) => {
            // max density 3 / min attenuation 0.5.
            assert!((p.majorant() - 6.0).abs() < 1e-5, "{}", p.majorant());
            assert!((p.sigma_t_max.0[2] - 1.5).abs() < 1e-5);
        }
        other => panic!("not a projected medium: {other:?}"),
    }
    assert!(scene.objects[0].walk.is_none());
}
