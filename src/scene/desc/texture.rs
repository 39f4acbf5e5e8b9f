//! Parameters that take a texture instead of a constant (docs/textures.md): a colour
//! ([`ColorInput`]) or a scalar ([`ScalarInput`]) written either as before or as a table
//! `{ texture = "file", colorspace, channel, scale, wrap }` ([`TextureDesc`]), whose unknown
//! keys are errors like everywhere else.

use serde::de::{self, Deserializer, MapAccess, SeqAccess, Visitor};
use serde::Deserialize;

use super::ColorValue;

/// `{ texture = "file", ... }`.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TextureDesc {
    /// PNG or EXR file, relative to the scene file (required).
    pub texture: String,
    /// "srgb" or "linear" (default: "srgb" for PNG colour parameters, else "linear").
    pub colorspace: Option<String>,
    /// "r", "g", "b", "a" or "luminance" (default "r" for scalar parameters; RGB for colours).
    pub channel: Option<String>,
    /// Multiplier ≥ 0 (default 1).
    pub scale: Option<f32>,
    /// "repeat" (default) or "clamp".
    pub wrap: Option<String>,
}

/// `{ texture = "file", channel = ... }`: a mask (values in [0, 1]).
pub type MaskDesc = TextureDesc;

/// A colour parameter: a number (grey), `[r, g, b]` or a texture table.
#[derive(Clone, Debug)]
pub enum ColorInput {
    /// A constant.
    Value(ColorValue),
    /// A texture.
    Texture(TextureDesc),
}

/// A scalar parameter: a number or a texture table.
#[derive(Clone, Debug)]
pub enum ScalarInput {
    /// A constant.
    Value(f32),
    /// A texture.
    Texture(TextureDesc),
}

impl ColorInput {
    /// The texture table, if it is one.
    #[must_use]
    pub fn texture(&self) -> Option<&TextureDesc> {
        match self {
            ColorInput::Texture(t) => Some(t),
            ColorInput::Value(_) => None,
        }
    }
}

impl ScalarInput {
    /// The texture table, if it is one.
    #[must_use]
    pub fn texture(&self) -> Option<&TextureDesc> {
        match self {
            ScalarInput::Texture(t) => Some(t),
            ScalarInput::Value(_) => None,
        }
    }
}

/// Reads a number, an array or a table; `colour` says whether arrays are accepted.
struct InputVisitor {
    colour: bool,
}

/// What [`InputVisitor`] read.
enum Read {
    Number(f32),
    Rgb([f32; 3]),
    Texture(TextureDesc),
}

impl<'de> Visitor<'de> for InputVisitor {
    type Value = Read;

    fn expecting(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if self.colour {
            f.write_str(
                "a colour: a number, [r, g, b] or a texture table { texture = \"file\", ... }",
            )
        } else {
            f.write_str("a number or a texture table { texture = \"file\", ... }")
        }
    }

    fn visit_f64<E: de::Error>(self, v: f64) -> Result<Read, E> {
        Ok(Read::Number(v as f32))
    }

    fn visit_i64<E: de::Error>(self, v: i64) -> Result<Read, E> {
        Ok(Read::Number(v as f32))
    }

    fn visit_u64<E: de::Error>(self, v: u64) -> Result<Read, E> {
        Ok(Read::Number(v as f32))
    }

    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Read, A::Error> {
        if !self.colour {
            return Err(de::Error::invalid_type(de::Unexpected::Seq, &self));
        }
        let mut c = [0.0f32; 3];
        for (i, slot) in c.iter_mut().enumerate() {
            *slot = seq
                .next_element()?
                .ok_or_else(|| de::Error::invalid_length(i, &"[r, g, b]"))?;
        }
        if seq.next_element::<de::IgnoredAny>()?.is_some() {
            return Err(de::Error::invalid_length(4, &"[r, g, b]"));
        }
        Ok(Read::Rgb(c))
    }

    fn visit_map<A: MapAccess<'de>>(self, map: A) -> Result<Read, A::Error> {
        TextureDesc::deserialize(de::value::MapAccessDeserializer::new(map)).map(Read::Texture)
    }
}

impl<'de> Deserialize<'de> for ColorInput {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        Ok(match d.deserialize_any(InputVisitor { colour: true })? {
            Read::Number(v) => ColorInput::Value(ColorValue::Scalar(v)),
            Read::Rgb(c) => ColorInput::Value(ColorValue::Rgb(c)),
            Read::Texture(t) => ColorInput::Texture(t),
        })
    }
}

impl<'de> Deserialize<'de> for ScalarInput {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        Ok(match d.deserialize_any(InputVisitor { colour: false })? {
            Read::Number(v) => ScalarInput::Value(v),
            Read::Rgb(_) => return Err(de::Error::custom("expected a number or a texture table")),
            Read::Texture(t) => ScalarInput::Texture(t),
        })
    }
}
