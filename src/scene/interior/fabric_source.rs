//! Where a `fabric` interior's voxelised patch comes from: generated and voxelised at load
//! from the scene's generator keys, or read from a patch file `velour weave` wrote, whose
//! metadata the scene's keys must agree with.

use super::Site;
use crate::fabric::{
    generate_patch, read_patch_file, voxelise, PatchFile, VoxeliseOptions, VoxelisedPatch,
    WeaveParams, WeavePattern, YarnParams,
};
use crate::scene::desc::FabricDesc;
use crate::scene::SceneError;
use crate::spectrum::Rgb;

/// The voxelised patch a fabric interior renders: generated from the scene's keys, or read
/// from a file `velour weave` wrote.
pub(super) enum PatchSource {
    /// Generated and voxelised at load (level 0, with accumulators when coarser levels are
    /// needed; boxed: it is much larger than the file's box).
    Generated(Box<VoxelisedPatch>),
    /// A patch file (its stored levels; missing levels are built from level 0).
    File(Box<PatchFile>),
}

impl PatchSource {
    /// Level 0.
    pub(super) fn base(&self) -> Option<&VoxelisedPatch> {
        match self {
            PatchSource::Generated(vp) => Some(vp.as_ref()),
            PatchSource::File(f) => f.levels.first().and_then(Option::as_ref),
        }
    }

    /// Mip level `l`.
    pub(super) fn level(&self, l: u32) -> Result<VoxelisedPatch, crate::fabric::FabricError> {
        match self {
            PatchSource::Generated(vp) if l == 0 => Ok(vp.as_ref().clone()),
            PatchSource::Generated(vp) => vp.mip(l),
            PatchSource::File(f) => f.level(l),
        }
    }
}

/// The warp and weft yarn names the keys ask for (`warp_yarn` / `weft_yarn`, else `yarn`),
/// with the key each came from; `None` where no key names it.
fn yarn_keys(d: &FabricDesc) -> [Option<(&'static str, &str)>; 2] {
    let yarn = d.yarn.as_deref().map(|n| ("yarn", n));
    [
        d.warp_yarn.as_deref().map(|n| ("warp_yarn", n)).or(yarn),
        d.weft_yarn.as_deref().map(|n| ("weft_yarn", n)).or(yarn),
    ]
}

/// Reads the patch file `file` and checks every generator key the scene gives against the
/// file's metadata: a key that contradicts it is an error naming both values.
pub(super) fn read_file(at: &Site, d: &FabricDesc, file: &str) -> Result<PatchFile, SceneError> {
    let owner = &at.owner;
    let path = at.ctx.resolve(file);
    let pf = read_patch_file(&path).map_err(|e| at.failed(&e))?;
    let r = &pf.record;
    let shown = path.display();
    let contradicts = |key: &str, ours: String, theirs: String| {
        at.invalid(format!(
            "{owner}.{key} = {ours} contradicts the patch file {shown}, whose metadata says {key} = {theirs} (leave the key out to use the file's)"
        ))
    };
    let recorded_pattern = r
        .weave_pattern()
        .map_err(|e| at.invalid(format!("{owner}: {shown}: metadata: pattern: {e}")))?;
    if let Some(name) = d.pattern.as_deref() {
        let ours = WeavePattern::from_name(name).map_err(|e| at.failed(&e))?;
        if ours != recorded_pattern {
            return Err(contradicts(
                "pattern",
                format!("\"{name}\""),
                format!("\"{}\"", r.pattern),
            ));
        }
    }
    let recorded_yarns = r
        .yarns()
        .map_err(|e| at.invalid(format!("{owner}: {shown}: metadata: {e}")))?;
    let recorded_names = [&r.warp_yarn, &r.weft_yarn];
    let family = ["warp_yarn", "weft_yarn"];
    for (i, asked) in yarn_keys(d).into_iter().enumerate() {
        if let Some((key, name)) = asked {
            let ours = YarnParams::preset(name).map_err(|e| at.failed(&e))?;
            if ours != recorded_yarns[i] {
                return Err(at.invalid(format!(
                    "{owner}.{key} = \"{name}\" contradicts the patch file {shown}, whose metadata says {} = \"{}\" (leave the key out to use the file's)",
                    family[i], recorded_names[i]
                )));
            }
        }
    }
    if let Some(v) = d.resolution {
        if v != r.resolution {
            return Err(contradicts(
                "resolution",
                v.to_string(),
                r.resolution.to_string(),
            ));
        }
    }
    if let Some(v) = d.repeats {
        if r.repeats != [v, v] {
            let theirs = if r.repeats[0] == r.repeats[1] {
                r.repeats[0].to_string()
            } else {
                format!("{}x{}", r.repeats[0], r.repeats[1])
            };
            return Err(contradicts("repeats", v.to_string(), theirs));
        }
    }
    if let Some(v) = d.seed {
        if v != r.seed {
            return Err(contradicts("seed", v.to_string(), r.seed.to_string()));
        }
    }
    if let Some(v) = d.flyaways {
        if v != r.flyaways {
            return Err(contradicts(
                "flyaways",
                v.to_string(),
                r.flyaways.to_string(),
            ));
        }
    }
    Ok(pf)
}

/// Generates and voxelises the patch from the scene's generator keys; returns it with its
/// warp, weft and pile albedos.
pub(super) fn generate(
    at: &Site,
    d: &FabricDesc,
    keep_accumulators: bool,
) -> Result<(VoxelisedPatch, [Rgb; 3]), SceneError> {
    let owner = &at.owner;
    let bad = |e: &dyn std::fmt::Display| at.failed(e);
    let pattern =
        WeavePattern::from_name(d.pattern.as_deref().unwrap_or("plain")).map_err(|e| bad(&e))?;
    let [warp, weft] = yarn_keys(d);
    let preset = |k: Option<(&str, &str)>| {
        YarnParams::preset(k.map_or("cotton1", |(_, n)| n)).map_err(|e| bad(&e))
    };
    let (warp, weft) = (preset(warp)?, preset(weft)?);
    let resolution = d.resolution.unwrap_or(128);
    if !(8..=1024).contains(&resolution) {
        return Err(at.invalid(format!(
            "{owner}.resolution = {resolution} is outside [8, 1024]"
        )));
    }
    let repeats = d.repeats.unwrap_or(1);
    if !(1..=16).contains(&repeats) {
        return Err(at.invalid(format!("{owner}.repeats = {repeats} is outside [1, 16]")));
    }
    let flyaways = at.range("flyaways", d.flyaways.unwrap_or(1.0), 0.0, 100.0)?;
    let mut params = WeaveParams::with_yarns(pattern, warp, weft);
    params.repeats = [repeats, repeats];
    params.flyaway_fraction = flyaways;
    let patch = generate_patch(&params, d.seed.unwrap_or(1)).map_err(|e| bad(&e))?;
    let opts = VoxeliseOptions {
        keep_accumulators,
        ..VoxeliseOptions::default()
    };
    let vp = voxelise(&patch, resolution, &opts).map_err(|e| bad(&e))?;
    Ok((
        vp,
        [patch.warp_albedo, patch.weft_albedo, patch.pile_albedo],
    ))
}
