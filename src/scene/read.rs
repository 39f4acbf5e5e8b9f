//! Reading the TOML text into descriptions ([`super::desc`]), with errors that name the line
//! of the offending key.
//!
//! The text is parsed once into toml's spanned document tree. Plain tables (`[camera]`,
//! `[film]`, the common keys of `[[object]]`) are deserialized from it directly. A table whose
//! `type` key picks its description (lights, surfaces, interiors; [`TypedTable`]) is read in
//! two steps: its `type`, then the rest of the table into that type's struct, which denies
//! unknown keys. Both steps deserialize from the spanned tree, so a misspelt key reports its
//! own line even deep inside inline tables. (serde's internally tagged enums would buffer the
//! table first, losing the lines and the unknown-key checks of the variants.)

use std::ops::Range;

use serde::de::{self, Deserialize, Visitor};
use toml::de::{DeTable, DeValue, ValueDeserializer};
use toml::Spanned;

use super::context::Ctx;
use super::desc::{ObjectDesc, SceneFile, TypedTable};
use super::SceneError;
use crate::fabric::lod::MAX_MIP_LEVEL;

/// The top-level keys of a scene file.
const TOP_LEVEL_KEYS: [&str; 4] = ["camera", "film", "light", "object"];

/// Reads the scene file's text into its descriptions.
pub(super) fn read_scene_file(ctx: &Ctx) -> Result<SceneFile, SceneError> {
    let doc = DeTable::parse(ctx.text).map_err(|e| parse_error(ctx, &e))?;
    let mut file = SceneFile::default();
    for (key, value) in doc.into_inner() {
        match key.get_ref().as_ref() {
            "camera" => file.camera = Some(deserialize(ctx, value)?),
            "film" => file.film = Some(deserialize(ctx, value)?),
            "light" => {
                for table in array_of_tables(ctx, "light", value)? {
                    file.light.push(read_typed(ctx, table, "light")?);
                }
            }
            "object" => {
                for (index, table) in array_of_tables(ctx, "object", value)?
                    .into_iter()
                    .enumerate()
                {
                    file.object.push(read_object(ctx, index, table)?);
                }
            }
            other => {
                return Err(ctx.parse(
                    ctx.line_of(key.span().start),
                    unknown_key_message(other, "", &TOP_LEVEL_KEYS),
                ))
            }
        }
    }
    Ok(file)
}

/// Deserializes one value of the document tree.
fn deserialize<'de, T: Deserialize<'de>>(
    ctx: &Ctx,
    value: Spanned<DeValue<'de>>,
) -> Result<T, SceneError> {
    T::deserialize(ValueDeserializer::from(value)).map_err(|e| parse_error(ctx, &e))
}

/// The tables of `[[key]]`.
fn array_of_tables<'i>(
    ctx: &Ctx,
    key: &str,
    value: Spanned<DeValue<'i>>,
) -> Result<Vec<Spanned<DeValue<'i>>>, SceneError> {
    let line = ctx.line_of(value.span().start);
    match value.into_inner() {
        DeValue::Array(tables) => Ok(tables.to_vec()),
        other => Err(ctx.parse(
            line,
            format!(
                "`{key}` must be an array of tables ([[{key}]]), not a {}",
                other.type_str()
            ),
        )),
    }
}

/// One `[[object]]`: its common keys, then its typed `surface` and `interior`.
fn read_object(
    ctx: &Ctx,
    index: usize,
    value: Spanned<DeValue<'_>>,
) -> Result<Spanned<ObjectDesc>, SceneError> {
    let span = value.span();
    let line = ctx.line_of(span.start);
    let DeValue::Table(mut table) = value.into_inner() else {
        return Err(ctx.parse(line, "`object` must be an array of tables ([[object]])"));
    };
    let name = table
        .get("name")
        .and_then(|v| v.get_ref().as_str())
        .map_or_else(|| format!("object {}", index + 1), str::to_string);
    let surface = table.remove("surface");
    let interior = table.remove("interior");
    let own_keys = key_spans(&table);
    let mut desc = ObjectDesc::deserialize(ValueDeserializer::from(Spanned::new(
        span.clone(),
        DeValue::Table(table),
    )))
    .map_err(|e| match unknown_own_key(&e, &own_keys) {
        Some((key, key_span)) => {
            let mut accepted = keys_of(|d| ObjectDesc::deserialize(d).map(Some)).to_vec();
            accepted.extend(ObjectDesc::TYPED_KEYS);
            ctx.parse(
                ctx.line_of(key_span.start),
                format!("{name}: {}", unknown_key_message(key, "", &accepted)),
            )
        }
        None => parse_error(ctx, &e),
    })?;
    if let Some(s) = surface {
        desc.surface = Some(read_typed(ctx, s, &format!("{name}: surface"))?);
    }
    if let Some(i) = interior {
        desc.interior = Some(read_typed(ctx, i, &format!("{name}: interior"))?);
    }
    Ok(Spanned::new(span, desc))
}

/// A table whose `type` key picks its description `T`; `owner` names it in messages
/// (`light`, `skin: surface`).
fn read_typed<T: TypedTable>(
    ctx: &Ctx,
    value: Spanned<DeValue<'_>>,
    owner: &str,
) -> Result<Spanned<T>, SceneError> {
    let span = value.span();
    let line = ctx.line_of(span.start);
    let types = quoted_list(T::TYPES);
    let DeValue::Table(mut table) = value.into_inner() else {
        return Err(ctx.parse(
            line,
            format!("{owner} must be a table with a `type` ({types})"),
        ));
    };
    let Some(kind_value) = table.remove("type") else {
        return Err(ctx.parse(
            line,
            format!("{owner}: missing key `type` (expected {types})"),
        ));
    };
    let kind_line = ctx.line_of(kind_value.span().start);
    let Some(kind) = kind_value.get_ref().as_str().map(str::to_string) else {
        return Err(ctx.parse(
            kind_line,
            format!("{owner}.type must be a string (expected {types})"),
        ));
    };
    let nested: Vec<(&str, Spanned<DeValue<'_>>)> = T::nested_keys(&kind)
        .iter()
        .filter_map(|&k| table.remove(k).map(|v| (k, v)))
        .collect();
    let own_keys = key_spans(&table);
    let keys = ValueDeserializer::from(Spanned::new(span.clone(), DeValue::Table(table)));
    match T::read(&kind, keys) {
        Ok(Some(mut desc)) => {
            for (key, value) in nested {
                if T::nested_list_keys(&kind).contains(&key) {
                    let list_line = ctx.line_of(value.span().start);
                    let DeValue::Array(items) = value.into_inner() else {
                        return Err(ctx.parse(
                            list_line,
                            format!("{owner}.{key} must be an array of tables"),
                        ));
                    };
                    for (i, item) in items.into_iter().enumerate() {
                        let inner = read_typed::<T>(ctx, item, &format!("{owner}.{key}[{i}]"))?;
                        desc.set_nested(key, inner);
                    }
                    continue;
                }
                let inner = read_typed::<T>(ctx, value, &format!("{owner}.{key}"))?;
                desc.set_nested(key, inner);
            }
            Ok(Spanned::new(span, desc))
        }
        Ok(None) => Err(ctx.invalid(
            kind_line,
            format!("{owner}.type = \"{kind}\" is unknown (expected {types})"),
        )),
        Err(e) => Err(match unknown_own_key(&e, &own_keys) {
            Some((key, key_span)) => {
                let users: Vec<&str> = T::TYPES
                    .iter()
                    .copied()
                    .filter(|&t| t != kind && keys_of(|d| T::read(t, d)).contains(&key))
                    .collect();
                let message = if users.is_empty() {
                    let accepted = keys_of(|d| T::read(&kind, d));
                    let of_type = format!(" for type \"{kind}\"");
                    format!("{owner}: {}", unknown_key_message(key, &of_type, accepted))
                } else {
                    format!(
                        "{owner}: key `{key}` is not used by type \"{kind}\" (only by {})",
                        quoted_list(&users)
                    )
                };
                ctx.parse(ctx.line_of(key_span.start), message)
            }
            None => parse_error(ctx, &e),
        }),
    }
}

/// The keys of a table with their places in the text.
fn key_spans(table: &DeTable<'_>) -> Vec<(String, Range<usize>)> {
    table
        .keys()
        .map(|k| (k.get_ref().to_string(), k.span()))
        .collect()
}

/// The key of an "unknown field" error when it is one of `own_keys` (a key of the table being
/// read, not of a table nested in it), with its place in the text.
fn unknown_own_key<'k>(
    e: &toml::de::Error,
    own_keys: &'k [(String, Range<usize>)],
) -> Option<(&'k str, Range<usize>)> {
    let key = unknown_field(e.message())?;
    let span = e.span()?;
    own_keys
        .iter()
        .find(|(k, s)| k == key && *s == span)
        .map(|(k, s)| (k.as_str(), s.clone()))
}

/// The key named by serde's "unknown field `key`, expected ..." message.
fn unknown_field(message: &str) -> Option<&str> {
    message
        .trim()
        .strip_prefix("unknown field `")?
        .split('`')
        .next()
}

/// "unknown key `key`{context} (expected one of `a`, `b`; did you mean `c`?)".
fn unknown_key_message(key: &str, context: &str, accepted: &[&str]) -> String {
    let list = accepted
        .iter()
        .map(|k| format!("`{k}`"))
        .collect::<Vec<_>>()
        .join(", ");
    let expected = match accepted.len() {
        0 => "it takes no keys".to_string(),
        1 => format!("expected {list}"),
        _ => format!("expected one of {list}"),
    };
    let suggestion = if accepted.len() > 1 {
        closest(key, accepted)
    } else {
        None
    };
    match suggestion {
        Some(near) => format!("unknown key `{key}`{context} ({expected}; did you mean `{near}`?)"),
        None => format!("unknown key `{key}`{context} ({expected})"),
    }
}

/// The accepted key nearest to a misspelt `key`, when it is within a couple of edits.
fn closest<'a>(key: &str, accepted: &[&'a str]) -> Option<&'a str> {
    let limit = (key.chars().count() / 3).clamp(1, 3);
    accepted
        .iter()
        .map(|&k| (edit_distance(key, k), k))
        .filter(|&(d, _)| d <= limit)
        .min_by_key(|&(d, _)| d)
        .map(|(_, k)| k)
}

/// Edit distance between two strings counting insertions, deletions, substitutions and
/// swaps of neighbouring characters (the optimal-string-alignment distance).
fn edit_distance(a: &str, b: &str) -> usize {
    let (a, b): (Vec<char>, Vec<char>) = (a.chars().collect(), b.chars().collect());
    // d[i][j]: distance between the first i characters of a and the first j of b.
    let mut d = vec![vec![0usize; b.len() + 1]; a.len() + 1];
    for (i, row) in d.iter_mut().enumerate() {
        row[0] = i;
    }
    for (j, cell) in d[0].iter_mut().enumerate() {
        *cell = j;
    }
    for i in 1..=a.len() {
        for j in 1..=b.len() {
            let substitute = d[i - 1][j - 1] + usize::from(a[i - 1] != b[j - 1]);
            let mut best = substitute.min(d[i - 1][j] + 1).min(d[i][j - 1] + 1);
            if i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1] {
                best = best.min(d[i - 2][j - 2] + 1);
            }
            d[i][j] = best;
        }
    }
    d[a.len()][b.len()]
}

/// `"a"`, `"a" or "b"`, `"a", "b" or "c"`.
fn quoted_list(items: &[&str]) -> String {
    let quoted: Vec<String> = items.iter().map(|s| format!("\"{s}\"")).collect();
    match quoted.split_last() {
        None => String::new(),
        Some((last, [])) => last.clone(),
        Some((last, rest)) => format!("{} or {last}", rest.join(", ")),
    }
}

/// The keys a serde struct accepts: `read` deserializes it (or a [`TypedTable`] kind) from
/// the deserializer it is given, which records the struct's field list and stops.
fn keys_of<T>(
    read: impl FnOnce(KeyList) -> Result<Option<T>, KeyListEnd>,
) -> &'static [&'static str] {
    match read(KeyList) {
        Err(KeyListEnd::Keys(keys)) => keys,
        _ => &[],
    }
}

/// A deserializer that answers a struct request with the struct's field list (as an error,
/// so that nothing is built).
struct KeyList;

/// How a [`KeyList`] run ends.
#[derive(Debug)]
enum KeyListEnd {
    /// The field list of the struct asked for.
    Keys(&'static [&'static str]),
    /// Anything but a struct was asked for.
    NotAStruct,
}

impl std::fmt::Display for KeyListEnd {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            KeyListEnd::Keys(keys) => write!(f, "keys {keys:?}"),
            KeyListEnd::NotAStruct => f.write_str("not a struct"),
        }
    }
}

impl std::error::Error for KeyListEnd {}

impl de::Error for KeyListEnd {
    fn custom<T: std::fmt::Display>(_msg: T) -> Self {
        KeyListEnd::NotAStruct
    }
}

impl<'de> de::Deserializer<'de> for KeyList {
    type Error = KeyListEnd;

    fn deserialize_any<V: Visitor<'de>>(self, _visitor: V) -> Result<V::Value, KeyListEnd> {
        Err(KeyListEnd::NotAStruct)
    }

    fn deserialize_struct<V: Visitor<'de>>(
        self,
        _name: &'static str,
        fields: &'static [&'static str],
        _visitor: V,
    ) -> Result<V::Value, KeyListEnd> {
        Err(KeyListEnd::Keys(fields))
    }

    serde::forward_to_deserialize_any! {
        bool i8 i16 i32 i64 i128 u8 u16 u32 u64 u128 f32 f64 char str string bytes byte_buf
        option unit unit_struct newtype_struct seq tuple tuple_struct map enum identifier
        ignored_any
    }
}

/// Turns a toml/serde error into one naming its line (the line of the key for an unknown key,
/// of the value for a wrong value, of the table for a missing key).
fn parse_error(ctx: &Ctx, e: &toml::de::Error) -> SceneError {
    let message = e.message().trim().to_string();
    let line = e.span().map_or(1, |s| ctx.line_of(s.start));
    if let Some(key) = unknown_field(&message) {
        // serde lists the accepted keys after "expected": "one of `a`, `b`" or "`a`".
        let accepted: Vec<&str> = message
            .split_once(", expected ")
            .map(|(_, list)| list.split('`').skip(1).step_by(2).collect())
            .unwrap_or_default();
        return ctx.parse(line, unknown_key_message(key, "", &accepted));
    }
    // serde's untagged enums say only "data did not match any variant": say what fits.
    let message = match message
        .strip_prefix("data did not match any variant of untagged enum ")
        .map(str::trim)
    {
        Some("ColorValue") => "expected a colour: a number or [r, g, b] (textures are accepted only by the parameters docs/scene-format.md marks as texturable)".to_string(),
        Some("ScaleValue") => "expected a scale: a number or [x, y, z]".to_string(),
        Some("TilesValue") => "`tiles` expects a number or [u, v]".to_string(),
        Some("MipValue") => format!("`mip` expects a level 0–{MAX_MIP_LEVEL} or \"auto\""),
        _ => message,
    };
    // A value of the wrong type: name the key it was given for.
    let message = match e.span().and_then(|s| key_before(ctx.text, s.start)) {
        Some(key) if !message.contains(&format!("`{key}`")) => format!("`{key}`: {message}"),
        _ => message,
    };
    ctx.parse(line, message)
}

/// The key of the `key = value` whose value starts at byte `offset` of `text` (plain or
/// inline-table keys; the last segment of a dotted key).
fn key_before(text: &str, offset: usize) -> Option<&str> {
    let head = text.get(..offset)?;
    let before_eq = head.trim_end().strip_suffix('=')?.trim_end();
    let start = before_eq
        .rfind(|c: char| !(c.is_alphanumeric() || c == '_' || c == '-'))
        .map_or(0, |i| i + 1);
    let key = &before_eq[start..];
    (!key.is_empty()).then_some(key)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_key_of_a_value_is_found_before_its_equals_sign() {
        let text = "[film]\nwidth = \"wide\"\nx = { a = 1, b_c = [1] }\n";
        let at = |needle: &str| text.find(needle).map(|i| key_before(text, i));
        assert_eq!(at("\"wide\""), Some(Some("width")));
        assert_eq!(at("1,"), Some(Some("a")));
        assert_eq!(at("[1]"), Some(Some("b_c")));
        assert_eq!(at("[film]"), Some(None));
    }

    #[test]
    fn lists_and_distances() {
        assert_eq!(quoted_list(&["a"]), "\"a\"");
        assert_eq!(quoted_list(&["a", "b", "c"]), "\"a\", \"b\" or \"c\"");
        assert_eq!(edit_distance("albdo", "albedo"), 1);
        assert_eq!(edit_distance("kitten", "sitting"), 3);
        assert_eq!(edit_distance("shpae", "shape"), 1);
        assert_eq!(edit_distance("", "abc"), 3);
        assert_eq!(closest("albdo", &["attenuation", "albedo"]), Some("albedo"));
        assert_eq!(closest("xyz", &["attenuation", "albedo"]), None);
    }

    #[test]
    fn key_lists_come_from_the_structs() {
        use super::super::desc::{InteriorDesc, LightDesc, SurfaceDesc};
        assert_eq!(
            keys_of(|d| LightDesc::read("envmap", d)),
            ["name", "file", "scale", "rotation"]
        );
        for kind in SurfaceDesc::TYPES.iter().filter(|k| **k != "blend") {
            assert!(
                keys_of(|d| SurfaceDesc::read(kind, d)).contains(&"coat"),
                "{kind}"
            );
        }
        for kind in InteriorDesc::TYPES {
            assert!(
                keys_of(|d| InteriorDesc::read(kind, d)).contains(&"nee"),
                "{kind}"
            );
        }
        assert!(keys_of(|d| InteriorDesc::read("nebula", d)).is_empty());
    }
}
