//! What a part file (or a checkpoint, or a final image) says about itself: the EXR string
//! attributes whose names start with `velour:`.

use std::collections::BTreeMap;
use std::ops::Range;

use super::split::TileSpec;

/// The identity and extent of one rendered part.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PartInfo {
    /// velour's version ([`super::version`]).
    pub version: String,
    /// The scene's content hash ([`super::hash::scene_hash`]).
    pub scene_hash: String,
    /// The render seed.
    pub seed: u64,
    /// Full image width, pixels.
    pub width: u32,
    /// Full image height, pixels.
    pub height: u32,
    /// Samples per pixel of the whole render (the parts' sample ranges cover `0..spp`).
    pub spp: u32,
    /// The band this part holds, if the render was split into tiles.
    pub tile: Option<TileSpec>,
    /// The rows this part holds.
    pub rows: Range<u32>,
    /// The sample indices this part holds.
    pub samples: Range<u32>,
}

fn range_text(r: &Range<u32>) -> String {
    format!("{}..{}", r.start, r.end)
}

fn parse_range(s: &str) -> Option<Range<u32>> {
    let (a, b) = s.split_once("..")?;
    let (a, b) = (a.parse().ok()?, b.parse().ok()?);
    (a < b).then_some(a..b)
}

impl PartInfo {
    /// The attributes that identify the part (merged into an image's other attributes).
    #[must_use]
    pub fn to_attributes(&self) -> BTreeMap<String, String> {
        let mut a = BTreeMap::new();
        a.insert("velour:version".into(), self.version.clone());
        a.insert("velour:scene_hash".into(), self.scene_hash.clone());
        a.insert("velour:seed".into(), self.seed.to_string());
        a.insert("velour:width".into(), self.width.to_string());
        a.insert("velour:height".into(), self.height.to_string());
        a.insert("velour:spp".into(), self.spp.to_string());
        if let Some(t) = self.tile {
            a.insert("velour:tile".into(), t.to_string());
        }
        a.insert("velour:rows".into(), range_text(&self.rows));
        a.insert("velour:samples".into(), range_text(&self.samples));
        a
    }

    /// Reads the attributes back; the error names the missing or malformed attribute.
    pub fn from_attributes(a: &BTreeMap<String, String>) -> Result<PartInfo, String> {
        let get = |k: &str| {
            a.get(k)
                .map(String::as_str)
                .ok_or_else(|| format!("attribute {k} is missing"))
        };
        let num = |k: &str| -> Result<u64, String> {
            get(k)?
                .parse()
                .map_err(|_| format!("attribute {k} = {:?} is not a number", a.get(k)))
        };
        let range = |k: &str| -> Result<Range<u32>, String> {
            parse_range(get(k)?)
                .ok_or_else(|| format!("attribute {k} = {:?} is not A..B", a.get(k)))
        };
        let small = |k: &str| -> Result<u32, String> {
            u32::try_from(num(k)?).map_err(|_| format!("attribute {k} is too large"))
        };
        let tile = match a.get("velour:tile") {
            Some(t) => Some(t.parse::<TileSpec>()?),
            None => None,
        };
        Ok(PartInfo {
            version: get("velour:version")?.to_string(),
            scene_hash: get("velour:scene_hash")?.to_string(),
            seed: num("velour:seed")?,
            width: small("velour:width")?,
            height: small("velour:height")?,
            spp: small("velour:spp")?,
            tile,
            rows: range("velour:rows")?,
            samples: range("velour:samples")?,
        })
    }
}
