//! The PLY header: one statement per text line from `ply` to `end_header`, and the check that
//! the element counts it declares can be backed by the bytes that follow it.
//!
//! Accepted statements: `format ascii|binary_little_endian|binary_big_endian <major>.<minor>`,
//! `comment …`, `obj_info …`, `element <name> <count>`, `property <type> <name>` and
//! `property list <count type> <item type> <name>`, with the type names of the PLY
//! specification (`char uchar short ushort int uint float double`) and their sized aliases
//! (`int8 uint8 int16 uint16 int32 uint32 float32 float64`). Lines may end in `\n` or `\r\n`.

/// How the body after `end_header` is encoded.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Format {
    /// One text line per element, values separated by blanks.
    Ascii,
    /// Packed values, least significant byte first.
    BinaryLittleEndian,
    /// Packed values, most significant byte first.
    BinaryBigEndian,
}

/// A scalar type of the PLY specification.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Scalar {
    /// Signed 8-bit integer.
    Char,
    /// Unsigned 8-bit integer.
    UChar,
    /// Signed 16-bit integer.
    Short,
    /// Unsigned 16-bit integer.
    UShort,
    /// Signed 32-bit integer.
    Int,
    /// Unsigned 32-bit integer.
    UInt,
    /// IEEE 754 single precision.
    Float,
    /// IEEE 754 double precision.
    Double,
}

impl Scalar {
    fn from_name(name: &str) -> Option<Scalar> {
        Some(match name {
            "char" | "int8" => Scalar::Char,
            "uchar" | "uint8" => Scalar::UChar,
            "short" | "int16" => Scalar::Short,
            "ushort" | "uint16" => Scalar::UShort,
            "int" | "int32" => Scalar::Int,
            "uint" | "uint32" => Scalar::UInt,
            "float" | "float32" => Scalar::Float,
            "double" | "float64" => Scalar::Double,
            _ => return None,
        })
    }

    /// Size in bytes in a binary body.
    pub(super) fn size(self) -> usize {
        match self {
            Scalar::Char | Scalar::UChar => 1,
            Scalar::Short | Scalar::UShort => 2,
            Scalar::Int | Scalar::UInt | Scalar::Float => 4,
            Scalar::Double => 8,
        }
    }

    /// True for the six integer types.
    pub(super) fn is_integer(self) -> bool {
        !matches!(self, Scalar::Float | Scalar::Double)
    }

    /// The specification's name of the type.
    pub(super) fn name(self) -> &'static str {
        match self {
            Scalar::Char => "char",
            Scalar::UChar => "uchar",
            Scalar::Short => "short",
            Scalar::UShort => "ushort",
            Scalar::Int => "int",
            Scalar::UInt => "uint",
            Scalar::Float => "float",
            Scalar::Double => "double",
        }
    }
}

/// The type of a property: one scalar, or a list prefixed by its length.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Kind {
    /// A single value.
    Scalar(Scalar),
    /// A length of type `len` (an integer type) followed by that many values of type `item`.
    List {
        /// Type of the length prefix.
        len: Scalar,
        /// Type of the items.
        item: Scalar,
    },
}

/// One `property` statement.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(super) struct Property {
    /// Property name.
    pub(super) name: String,
    /// Its type.
    pub(super) kind: Kind,
}

/// One `element` statement with the properties that follow it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(super) struct Element {
    /// Element name.
    pub(super) name: String,
    /// Number of instances declared.
    pub(super) count: u64,
    /// Properties in file order.
    pub(super) properties: Vec<Property>,
    /// Header line of the statement (1-based).
    pub(super) line: usize,
}

impl Element {
    /// The fewest bytes one instance can occupy: in a binary body the scalars and list
    /// lengths (lists may be empty); in an ASCII body one character and one separator per
    /// value (the line break counts as the last separator), or the line break alone.
    fn min_bytes(&self, format: Format) -> u64 {
        match format {
            Format::Ascii => (2 * self.properties.len() as u64).max(1),
            Format::BinaryLittleEndian | Format::BinaryBigEndian => self
                .properties
                .iter()
                .map(|p| match p.kind {
                    Kind::Scalar(s) => s.size() as u64,
                    Kind::List { len, .. } => len.size() as u64,
                })
                .sum(),
        }
    }
}

/// A parsed header.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(super) struct Header {
    /// Body encoding.
    pub(super) format: Format,
    /// Elements in file order.
    pub(super) elements: Vec<Element>,
    /// Byte offset of the body (just after the `end_header` line).
    pub(super) body_offset: usize,
    /// Number of lines in the header, `end_header` included.
    pub(super) lines: usize,
}

/// Parses the header at the start of `bytes`. Errors name the offending line.
pub(super) fn parse_header(bytes: &[u8]) -> Result<Header, String> {
    let mut pos = 0;
    let mut number = 0;
    let mut format = None;
    let mut elements: Vec<Element> = Vec::new();
    loop {
        if pos >= bytes.len() {
            return Err(if number == 0 {
                "the file is empty".to_string()
            } else {
                format!("the header ends at line {number} without `end_header`")
            });
        }
        let end = bytes[pos..]
            .iter()
            .position(|&b| b == b'\n')
            .map_or(bytes.len(), |k| pos + k);
        let raw = &bytes[pos..end];
        pos = (end + 1).min(bytes.len());
        number += 1;
        let text = std::str::from_utf8(raw)
            .map_err(|_| format!("line {number}: the header line is not text"))?;
        let mut words = text.split_ascii_whitespace();
        let keyword = words.next().unwrap_or("");
        if number == 1 {
            if keyword != "ply" || words.next().is_some() {
                return Err("line 1: not a PLY file (it must start with a line `ply`)".to_string());
            }
            continue;
        }
        let at = |message: String| format!("line {number}: {message}");
        match keyword {
            "comment" | "obj_info" => {}
            "format" => {
                let f = parse_format(words.collect::<Vec<_>>().as_slice()).map_err(at)?;
                if format.is_some_and(|g| g != f) {
                    return Err(at("a second, different `format` line".to_string()));
                }
                format = Some(f);
            }
            "element" => {
                let (name, count) = match (words.next(), words.next(), words.next()) {
                    (Some(name), Some(count), None) => (name, count),
                    _ => return Err(at("expected `element <name> <count>`".to_string())),
                };
                let count = parse_count(count).ok_or_else(|| {
                    at(format!(
                        "element `{name}`: count `{}` is not a non-negative integer below 2^64",
                        shorten(count)
                    ))
                })?;
                check_name(name).map_err(at)?;
                if elements.iter().any(|e| e.name == name) {
                    return Err(at(format!("element `{name}` is declared twice")));
                }
                elements.push(Element {
                    name: name.to_string(),
                    count,
                    properties: Vec::new(),
                    line: number,
                });
            }
            "property" => {
                let words: Vec<&str> = words.collect();
                let property = parse_property(&words).map_err(at)?;
                let element = elements.last_mut().ok_or_else(|| {
                    at(format!(
                        "property `{}` comes before any `element`",
                        property.name
                    ))
                })?;
                if element.properties.iter().any(|p| p.name == property.name) {
                    return Err(at(format!(
                        "element `{}` declares property `{}` twice",
                        element.name, property.name
                    )));
                }
                element.properties.push(property);
            }
            "end_header" if words.next().is_none() => break,
            "" => return Err(at("empty header line".to_string())),
            other => return Err(at(format!("unknown header statement `{}`", shorten(other)))),
        }
    }
    let format = format.ok_or_else(|| "the header has no `format` line".to_string())?;
    Ok(Header {
        format,
        elements,
        body_offset: pos,
        lines: number,
    })
}

/// Refuses a header whose element counts need more bytes than the `available` ones after
/// it (see `Element::min_bytes`), so that no count read from the file can make the reader
/// allocate memory or spend time the file's size does not back.
pub(super) fn check_counts_fit(header: &Header, available: usize) -> Result<(), String> {
    // An ASCII body may omit the final line break.
    let slack = u128::from(header.format == Format::Ascii);
    let mut needed: u128 = 0;
    for e in &header.elements {
        needed += u128::from(e.count) * u128::from(e.min_bytes(header.format));
        if needed > available as u128 + slack {
            return Err(format!(
                "line {}: {} `{}` elements need at least {} bytes of data, but only {} bytes follow the header (wrong count or truncated file?)",
                e.line, e.count, e.name, needed, available
            ));
        }
    }
    Ok(())
}

fn parse_format(words: &[&str]) -> Result<Format, String> {
    let usage = "expected `format ascii|binary_little_endian|binary_big_endian 1.0`";
    let [encoding, version] = words else {
        return Err(usage.to_string());
    };
    let format = match *encoding {
        "ascii" => Format::Ascii,
        "binary_little_endian" => Format::BinaryLittleEndian,
        "binary_big_endian" => Format::BinaryBigEndian,
        _ => return Err(format!("unknown format `{}`: {usage}", shorten(encoding))),
    };
    let valid_version = version.split_once('.').is_some_and(|(major, minor)| {
        [major, minor]
            .iter()
            .all(|s| !s.is_empty() && s.bytes().all(|b| b.is_ascii_digit()))
    });
    if !valid_version {
        return Err(format!(
            "format version `{}` is not `<major>.<minor>`",
            shorten(version)
        ));
    }
    Ok(format)
}

fn parse_property(words: &[&str]) -> Result<Property, String> {
    let scalar = |w: &str| {
        Scalar::from_name(w).ok_or_else(|| format!("unknown property type `{}`", shorten(w)))
    };
    let (kind, name) = match words {
        ["list", len, item, name] => {
            let len = scalar(len)?;
            if !len.is_integer() {
                return Err(format!(
                    "list `{name}`: the length type must be an integer type, not `{}`",
                    len.name()
                ));
            }
            (
                Kind::List {
                    len,
                    item: scalar(item)?,
                },
                name,
            )
        }
        [ty, name] if *ty != "list" => (Kind::Scalar(scalar(ty)?), name),
        _ => return Err(
            "expected `property <type> <name>` or `property list <count type> <item type> <name>`"
                .to_string(),
        ),
    };
    check_name(name)?;
    Ok(Property {
        name: (*name).to_string(),
        kind,
    })
}

/// Element and property names: printable ASCII (no control or non-ASCII characters).
fn check_name(name: &str) -> Result<(), String> {
    if name.bytes().all(|b| b.is_ascii_graphic()) {
        Ok(())
    } else {
        Err(format!(
            "name `{}` holds a control or non-ASCII character",
            shorten(&name.escape_default().to_string())
        ))
    }
}

/// Parses an element count: ASCII digits only (no sign).
fn parse_count(s: &str) -> Option<u64> {
    if s.bytes().all(|b| b.is_ascii_digit()) {
        s.parse().ok()
    } else {
        None
    }
}

/// At most 40 characters of `s`, for messages quoting file content.
pub(super) fn shorten(s: &str) -> String {
    match s.char_indices().nth(40) {
        Some((cut, _)) => format!("{}…", &s[..cut]),
        None => s.to_string(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    // Tests return `Result` rather than unwrap (the project counts unwraps in `src/`).

    #[test]
    fn parses_statements_and_body_offset() -> Result<(), String> {
        let text = b"ply\r\nformat binary_big_endian 1.0\ncomment x y\nelement vertex 2\nproperty float32 x\nproperty list uint8 int vertex_indices\nelement face 0\nend_header\nBODY";
        let h = parse_header(text)?;
        assert_eq!(h.format, Format::BinaryBigEndian);
        assert_eq!(h.lines, 8);
        assert_eq!(&text[h.body_offset..], b"BODY");
        assert_eq!(h.elements.len(), 2);
        let v = &h.elements[0];
        assert_eq!((v.count, v.line), (2, 4));
        assert_eq!(
            v.properties[1].kind,
            Kind::List {
                len: Scalar::UChar,
                item: Scalar::Int
            }
        );
        assert_eq!(v.min_bytes(Format::BinaryBigEndian), 5);
        assert_eq!(v.min_bytes(Format::Ascii), 4);
        Ok(())
    }

    #[test]
    fn counts_must_fit_the_bytes_after_the_header() -> Result<(), String> {
        let h = parse_header(
            b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nend_header\n",
        )?;
        // Three lines of at least 2 bytes, the last line break optional.
        assert!(check_counts_fit(&h, 5).is_ok());
        let e = check_counts_fit(&h, 4).err().ok_or("4 bytes accepted")?;
        assert!(e.contains("line 3") && e.contains("3 `vertex`"), "{e}");
        let huge = parse_header(
            b"ply\nformat binary_little_endian 1.0\nelement vertex 18446744073709551615\nproperty double x\nend_header\n",
        )?;
        assert!(check_counts_fit(&huge, usize::MAX).is_err());
        Ok(())
    }

    #[test]
    fn malformed_headers_name_the_line() {
        let cases: [(&[u8], &str); 10] = [
            (b"", "empty"),
            (b"plyx\n", "line 1"),
            (b"ply\nformat ascii 1.0\n", "without `end_header`"),
            (b"ply\nformat ascii\nend_header\n", "line 2"),
            (
                b"ply\nformat ascii 1.0\nelement v -1\nend_header\n",
                "line 3",
            ),
            (
                b"ply\nformat ascii 1.0\nproperty float x\nend_header\n",
                "line 3",
            ),
            (
                b"ply\nformat ascii 1.0\nelement v 1\nproperty list float int i\nend_header\n",
                "line 4",
            ),
            (
                b"ply\nformat ascii 1.0\nelement v 1\nelement v 2\nend_header\n",
                "twice",
            ),
            (b"ply\nend_header\n", "no `format`"),
            (
                b"ply\nformat ascii 1.0\nelement v\x01 1\nend_header\n",
                "`v\\u{1}`",
            ),
        ];
        for (text, want) in cases {
            let outcome = parse_header(text);
            assert!(
                outcome.as_ref().is_err_and(|e| e.contains(want)),
                "{:?}: {outcome:?}",
                String::from_utf8_lossy(text)
            );
        }
    }
}
