//! `blend` interiors: two looks `a` and `b` (any interior type but another blend) and a mask;
//! each walk entering the object picks `a` with probability mask(uv) at its entry point, else
//! `b` (docs/textures.md). Untextured looks are ordinary media of the scene; textured ones are
//! read at the entry point like any entry-projected interior.

use super::{build_medium, BuiltInterior, Placement, Site};
use crate::medium::{Medium, WalkInterior, WalkLook};
use crate::scene::desc::{BlendDesc, InteriorDesc, ScalarInput};
use crate::scene::SceneError;

/// The medium of a `blend` interior; the looks' media go to `media`.
pub(super) fn build(
    at: &Site,
    d: &BlendDesc,
    placement: &Placement<'_>,
    media: &mut Vec<Medium>,
) -> Result<BuiltInterior, SceneError> {
    let owner = &at.owner;
    let mask_input = d.mask.as_ref().ok_or_else(|| {
        at.invalid(format!(
            "{owner}: a blend needs `mask` (a number in [0, 1] or {{ texture = \"file\", channel = ... }})"
        ))
    })?;
    let mask = at
        .params()
        .scalar("mask", Some(mask_input), 0.5, 0.0, 1.0)?;
    if let ScalarInput::Texture(t) = mask_input {
        if t.colorspace.as_deref() == Some("srgb") {
            return Err(at.invalid(format!(
                "{owner}.mask: a mask is data; colorspace = \"srgb\" does not apply"
            )));
        }
    }
    let (_, _, nee) = super::extinction_and_nee(at, None, None, d.nee.as_deref())?;
    let mut look = |key: &str, desc: Option<&toml::Spanned<InteriorDesc>>| {
        let desc = desc.ok_or_else(|| {
            at.invalid(format!(
                "{owner}: a blend needs `{key}` (an interior table with a `type`)"
            ))
        })?;
        let line = at.ctx.line_of(desc.span().start);
        let inner = desc.get_ref();
        let inner_owner = format!("{owner}.{key}");
        if matches!(inner, InteriorDesc::Blend(_)) {
            return Err(at.ctx.invalid(
                line,
                format!("{inner_owner}: a blend's looks cannot be blends"),
            ));
        }
        if inner.nee().is_some() {
            return Err(at.ctx.invalid(
                line,
                format!("{inner_owner}: `nee` goes on the blend itself (both looks share it)"),
            ));
        }
        let built = build_medium(at.ctx, line, at.name, inner_owner, inner, placement, media)?;
        Ok::<_, SceneError>(match built.walk {
            Some(WalkInterior::Entry(e)) => (WalkLook::Entry(e), built.medium),
            Some(WalkInterior::Field(f)) => (WalkLook::Field(f), built.medium),
            Some(WalkInterior::Mixture(m)) => (WalkLook::Mixture(m), built.medium),
            Some(WalkInterior::Fabric(f)) => (WalkLook::Fabric(f), built.medium),
            Some(WalkInterior::Blend { .. }) => unreachable_blend(at)?,
            None => {
                media.push(built.medium.clone());
                (WalkLook::Medium((media.len() - 1) as u32), built.medium)
            }
        })
    };
    let (a, medium_a) = look("a", d.a.as_deref())?;
    let (b, _) = look("b", d.b.as_deref())?;
    Ok(BuiltInterior {
        medium: medium_a,
        nee,
        walk: Some(WalkInterior::Blend { mask, a, b }),
    })
}

/// A nested blend (refused before it is built).
fn unreachable_blend(at: &Site) -> Result<(WalkLook, Medium), SceneError> {
    Err(at.invalid(format!("{}: a blend's looks cannot be blends", at.owner)))
}
