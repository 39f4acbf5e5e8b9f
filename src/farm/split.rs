//! The ways a render is split: `--tile I/N`, `--samples A..B`, `--frames A..B`.

use std::ops::Range;
use std::str::FromStr;

/// Tile `index` of `count` (0-based): a horizontal band of whole rows. Band `i` of an image
/// `h` rows high covers rows `⌊i·h/N⌋ .. ⌊(i+1)·h/N⌋`, so bands differ by at most one row.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TileSpec {
    /// Which band (0-based).
    pub index: u32,
    /// How many bands.
    pub count: u32,
}

impl TileSpec {
    /// The rows of this band in an image `height` rows high. Errors when there are more bands
    /// than rows.
    pub fn rows(&self, height: u32) -> Result<Range<u32>, String> {
        if self.count > height {
            return Err(format!(
                "--tile {}/{}: the image has only {height} rows, so at most {height} tiles",
                self.index, self.count
            ));
        }
        let edge = |i: u32| (u64::from(i) * u64::from(height) / u64::from(self.count)) as u32;
        Ok(edge(self.index)..edge(self.index + 1))
    }
}

impl FromStr for TileSpec {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        let bad = || format!("tile {s:?} is not I/N with 0 <= I < N (for example 0/4)");
        let (i, n) = s.split_once('/').ok_or_else(bad)?;
        let index: u32 = i.trim().parse().map_err(|_| bad())?;
        let count: u32 = n.trim().parse().map_err(|_| bad())?;
        if count == 0 || index >= count {
            return Err(bad());
        }
        Ok(TileSpec { index, count })
    }
}

impl std::fmt::Display for TileSpec {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

/// Parses `A..B` (B excluded) or `A..=B` (B included) into a half-open range of `u32`.
fn parse_range(s: &str, what: &str) -> Result<Range<u32>, String> {
    let bad = || format!("{what} {s:?} is not A..B (B excluded) or A..=B (B included) with A < B");
    let (a, b, inclusive) = if let Some((a, b)) = s.split_once("..=") {
        (a, b, true)
    } else if let Some((a, b)) = s.split_once("..") {
        (a, b, false)
    } else {
        return Err(bad());
    };
    let a: u32 = a.trim().parse().map_err(|_| bad())?;
    let b: u32 = b.trim().parse().map_err(|_| bad())?;
    let end = if inclusive {
        b.checked_add(1).ok_or_else(bad)?
    } else {
        b
    };
    if a >= end {
        return Err(bad());
    }
    Ok(a..end)
}

/// `--samples A..B`: sample indices `A .. B−1` of the deterministic sequence in every pixel.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SampleRange(pub Range<u32>);

impl FromStr for SampleRange {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        parse_range(s, "sample range").map(SampleRange)
    }
}

/// `--frames A..B` (B excluded) or `A..=B` (B included).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FrameRange(pub Range<u32>);

impl FromStr for FrameRange {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        parse_range(s, "frame range").map(FrameRange)
    }
}

/// Replaces `{frame}` by the frame number and `{frame:0N}` by the number zero-padded to N
/// digits (N from 1 to 9). Errors on an unknown `{frame…}` form.
pub fn substitute_frame(text: &str, frame: u32) -> Result<String, String> {
    let mut out = String::with_capacity(text.len());
    let mut rest = text;
    while let Some(i) = rest.find("{frame") {
        out.push_str(&rest[..i]);
        let tail = &rest[i..];
        let end = tail
            .find('}')
            .ok_or_else(|| format!("unclosed {{frame placeholder in {tail:?}"))?;
        let spec = &tail[..=end];
        match spec {
            "{frame}" => out.push_str(&frame.to_string()),
            _ => {
                let width = spec
                    .strip_prefix("{frame:0")
                    .and_then(|w| w.strip_suffix('}'))
                    .and_then(|w| w.parse::<usize>().ok())
                    .filter(|w| (1..=9).contains(w))
                    .ok_or_else(|| {
                        format!("{spec} is not {{frame}} or {{frame:0N}} with N from 1 to 9")
                    })?;
                out.push_str(&format!("{frame:0width$}"));
            }
        }
        rest = &tail[end + 1..];
    }
    out.push_str(rest);
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tiles_cover_every_row_once() {
        for h in [1u32, 7, 100, 1080] {
            for n in 1..=h.min(13) {
                let mut next = 0;
                for i in 0..n {
                    let r = TileSpec { index: i, count: n }.rows(h).unwrap();
                    assert_eq!(r.start, next);
                    assert!(r.end > r.start);
                    next = r.end;
                }
                assert_eq!(next, h);
            }
        }
        assert!(TileSpec { index: 0, count: 8 }.rows(7).is_err());
    }

    #[test]
    fn parses_and_refuses() {
        assert_eq!(
            "2/4".parse::<TileSpec>().unwrap(),
            TileSpec { index: 2, count: 4 }
        );
        for bad in ["4/4", "1/0", "a/2", "3", "-1/2"] {
            assert!(bad.parse::<TileSpec>().is_err(), "{bad}");
        }
        assert_eq!("0..16".parse::<SampleRange>().unwrap().0, 0..16);
        assert_eq!("1..=24".parse::<FrameRange>().unwrap().0, 1..25);
        for bad in ["5..5", "6..2", "..4", "1-4", "a..b"] {
            assert!(bad.parse::<SampleRange>().is_err(), "{bad}");
        }
    }

    #[test]
    fn frame_placeholders() {
        assert_eq!(
            substitute_frame("a{frame}.vdb b{frame:04}.exr", 7).unwrap(),
            "a7.vdb b0007.exr"
        );
        assert!(substitute_frame("x{frame:x}", 1).is_err());
        assert!(substitute_frame("x{frame", 1).is_err());
        assert_eq!(substitute_frame("none", 3).unwrap(), "none");
    }
}
